//! VTU / PVD output, read back with vtkio.

use std::path::Path;

use fdem_mesh::{
    CellNodes, ElementOrder, MeshAssembly, MeshError, Placement, Sizing, SphereSpec, VtuField,
    VtuFrame, sphere_mesh, write_pvd, write_vtu,
};
use vtkio::Vtk;
use vtkio::model::{
    Attribute, CellType, DataSet, IOBuffer, Piece, UnstructuredGridPiece, VertexNumbers,
};

fn read_piece(path: &Path) -> UnstructuredGridPiece {
    let vtk = Vtk::import(path).expect("vtkio reads the file back");
    match vtk.data {
        DataSet::UnstructuredGrid { pieces, .. } => match pieces.into_iter().next() {
            Some(Piece::Inline(p)) => *p,
            other => panic!("expected one inline piece, got {other:?}"),
        },
        other => panic!("expected an UnstructuredGrid, got {other:?}"),
    }
}

fn f64_values(attrs: &[Attribute], name: &str) -> Vec<f64> {
    let a = attrs
        .iter()
        .find(|a| a.name() == name)
        .unwrap_or_else(|| panic!("no field {name}"));
    match a {
        Attribute::DataArray(d) => match &d.data {
            IOBuffer::F64(v) => v.clone(),
            other => panic!("field {name} is not Float64: {other:?}"),
        },
        other => panic!("field {name} is not a data array: {other:?}"),
    }
}

fn no_temporary_files(dir: &Path) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let name = entry.unwrap().file_name();
        assert!(
            !name.to_string_lossy().ends_with(".part"),
            "temporary file {name:?} left behind"
        );
    }
}

#[test]
fn particle_vtu_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    for order in [ElementOrder::Linear, ElementOrder::Quadratic] {
        let m = sphere_mesh(&SphereSpec {
            level: 1,
            order,
            diameter: 0.015,
            sizing: Sizing::Inscribed,
        })
        .unwrap();
        let path = dir.path().join(format!("particle_{order:?}.vtu"));
        m.write_vtu(&path).unwrap();
        let p = read_piece(&path);
        assert_eq!(p.num_points(), m.n_nodes());
        assert_eq!(p.cells.num_cells(), 80);
        let expected_type = match order {
            ElementOrder::Linear => CellType::Tetra,
            ElementOrder::Quadratic => CellType::QuadraticTetra,
        };
        assert!(p.cells.types.iter().all(|&t| t == expected_type));
        // Connectivity comes back exactly.
        let conn: Vec<u64> = match p.cells.cell_verts.clone() {
            VertexNumbers::XML { connectivity, .. } => connectivity,
            legacy => legacy.into_xml().0,
        };
        assert!(
            conn.iter()
                .map(|&i| i as usize)
                .eq(m.elements.iter().copied())
        );
        // Points come back bit for bit (Float64, base64).
        match &p.points {
            IOBuffer::F64(v) => assert!(v.iter().copied().eq(m.nodes.iter().flatten().copied())),
            other => panic!("points not Float64: {other:?}"),
        }
        // Point field: 1 on the surface nodes, 0 elsewhere.
        let is_surface = f64_values(&p.data.point, "is_surface");
        assert_eq!(is_surface.len(), m.n_nodes());
        let n_s = m.surface.nodes.len();
        assert!(is_surface[..n_s].iter().all(|&v| v == 1.0));
        assert!(is_surface[n_s..].iter().all(|&v| v == 0.0));
        assert_eq!(is_surface.iter().sum::<f64>(), n_s as f64);
        let ids = f64_values(&p.data.cell, "element_id");
        assert!(ids.iter().copied().eq((0..80).map(|e| e as f64)));
    }
    no_temporary_files(dir.path());
}

#[test]
fn generic_frame_with_vector_field_and_triangles() {
    let dir = tempfile::tempdir().unwrap();
    let m = sphere_mesh(&SphereSpec::paper(0.03)).unwrap();
    let tris: Vec<usize> = m.surface.triangles.iter().flatten().copied().collect();
    let velocity: Vec<f64> = m.nodes.iter().flat_map(|p| [p[1], -p[0], 0.0]).collect();
    let frame = VtuFrame {
        points: &m.nodes,
        cells: &tris,
        cell_nodes: CellNodes::Uniform(3),
        point_fields: vec![VtuField {
            name: "velocity",
            components: 3,
            values: &velocity,
        }],
        cell_fields: vec![],
    };
    let path = dir.path().join("surface.vtu");
    write_vtu(&path, &frame).unwrap();
    let p = read_piece(&path);
    assert_eq!(p.cells.num_cells(), 320);
    assert!(p.cells.types.iter().all(|&t| t == CellType::Triangle));
    assert_eq!(f64_values(&p.data.point, "velocity"), velocity);

    // An assembly writes too.
    let mut a = MeshAssembly::new();
    a.push_instance(&m, &Placement::identity()).unwrap();
    a.push_instance(&m, &Placement::at([0.05, 0.0, 0.0]))
        .unwrap();
    let path = dir.path().join("assembly.vtu");
    a.write_vtu(&path).unwrap();
    let p = read_piece(&path);
    assert_eq!((p.num_points(), p.cells.num_cells()), (410, 160));
    let body = f64_values(&p.data.cell, "body_id");
    assert_eq!((body[79], body[80]), (0.0, 1.0));
    no_temporary_files(dir.path());
}

/// A frame that mixes a linear tetrahedron, a quadratic one and a triangle is written with
/// one type and offset per cell, read back as such.
#[test]
fn a_frame_of_mixed_cell_types_is_written_cell_by_cell() {
    let dir = tempfile::tempdir().unwrap();
    let q = sphere_mesh(&SphereSpec {
        level: 0,
        order: ElementOrder::Quadratic,
        diameter: 1.0,
        sizing: Sizing::Inscribed,
    })
    .unwrap();
    let mut cells: Vec<usize> = q.elements[..10].to_vec();
    cells.extend_from_slice(&q.elements[..4]);
    cells.extend_from_slice(&q.surface.triangles[0]);
    let sizes = [10, 4, 3];
    let body = [0.0, 1.0, 2.0];
    let frame = VtuFrame {
        points: &q.nodes,
        cells: &cells,
        cell_nodes: CellNodes::PerCell(&sizes),
        point_fields: vec![],
        cell_fields: vec![VtuField {
            name: "body",
            components: 1,
            values: &body,
        }],
    };
    let path = dir.path().join("mixed.vtu");
    write_vtu(&path, &frame).unwrap();
    let p = read_piece(&path);
    assert_eq!(
        p.cells.types,
        [
            CellType::QuadraticTetra,
            CellType::Tetra,
            CellType::Triangle
        ]
    );
    match p.cells.cell_verts {
        VertexNumbers::XML {
            connectivity,
            offsets,
        } => {
            assert_eq!(offsets, [10, 14, 17]);
            assert_eq!(
                connectivity,
                cells.iter().map(|&i| i as u64).collect::<Vec<_>>()
            );
        }
        other => panic!("expected XML cells, got {other:?}"),
    }
    assert_eq!(f64_values(&p.data.cell, "body"), body);
    no_temporary_files(dir.path());
}

#[test]
fn inconsistent_frames_are_rejected_without_writing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.vtu");
    let points = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let one = [1.0];
    let cases: Vec<(VtuFrame, &str)> = vec![
        (
            VtuFrame {
                points: &points,
                cells: &[0, 1, 2, 3],
                cell_nodes: CellNodes::Uniform(5),
                point_fields: vec![],
                cell_fields: vec![],
            },
            "nodes_per_cell is 5",
        ),
        (
            VtuFrame {
                points: &points,
                cells: &[0, 1, 2],
                cell_nodes: CellNodes::Uniform(4),
                point_fields: vec![],
                cell_fields: vec![],
            },
            "not a multiple",
        ),
        (
            VtuFrame {
                points: &points,
                cells: &[0, 1, 2, 4],
                cell_nodes: CellNodes::Uniform(4),
                point_fields: vec![],
                cell_fields: vec![],
            },
            "refers to point 4",
        ),
        (
            VtuFrame {
                points: &points,
                cells: &[0, 1, 2, 3],
                cell_nodes: CellNodes::Uniform(4),
                point_fields: vec![VtuField {
                    name: "p",
                    components: 1,
                    values: &one,
                }],
                cell_fields: vec![],
            },
            "expected 1 components x 4 points = 4",
        ),
        (
            VtuFrame {
                points: &points,
                cells: &[0, 1, 2, 3],
                cell_nodes: CellNodes::Uniform(4),
                point_fields: vec![],
                cell_fields: vec![VtuField {
                    name: "a<b",
                    components: 1,
                    values: &one,
                }],
            },
            "field name",
        ),
        (
            VtuFrame {
                points: &points,
                cells: &[0, 1, 2, 3],
                cell_nodes: CellNodes::PerCell(&[4, 5]),
                point_fields: vec![],
                cell_fields: vec![],
            },
            "cell 1 has 5 nodes",
        ),
        (
            VtuFrame {
                points: &points,
                cells: &[0, 1, 2, 3],
                cell_nodes: CellNodes::PerCell(&[4, 3]),
                point_fields: vec![],
                cell_fields: vec![],
            },
            "add up to 7",
        ),
        (
            VtuFrame {
                points: &points,
                cells: &[0, 1, 2, 0, 1, 2, 4],
                cell_nodes: CellNodes::PerCell(&[3, 4]),
                point_fields: vec![],
                cell_fields: vec![],
            },
            "cell 1 refers to point 4",
        ),
    ];
    for (frame, needle) in &cases {
        let err = write_vtu(&path, frame).unwrap_err();
        assert!(matches!(err, MeshError::InvalidFrame { .. }));
        assert!(err.to_string().contains(needle), "{err} lacks {needle:?}");
    }
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);

    // A missing directory is an I/O error naming the path, and leaves nothing behind.
    let m = sphere_mesh(&SphereSpec::paper(0.015)).unwrap();
    let err = m.write_vtu(&dir.path().join("missing/p.vtu")).unwrap_err();
    assert!(matches!(err, MeshError::Io { .. }));
    assert!(err.to_string().contains("missing"));
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn pvd_collection() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.pvd");
    let entries = vec![
        (0.0, "frame_0000.vtu".to_string()),
        (1.5e-6, "frames/frame_0001.vtu".to_string()),
        (3e-6, "a&b.vtu".to_string()),
    ];
    write_pvd(&path, &entries).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("type=\"Collection\""));
    assert_eq!(text.matches("<DataSet ").count(), 3);
    assert!(
        text.contains("timestep=\"1.5e-6\" group=\"\" part=\"0\" file=\"frames/frame_0001.vtu\"")
    );
    assert!(text.contains("file=\"a&amp;b.vtu\""));
    no_temporary_files(dir.path());

    let err = write_pvd(&path, &[(f64::NAN, "x.vtu".into())]).unwrap_err();
    assert!(matches!(err, MeshError::InvalidTime { index: 0, .. }));
    // The earlier file is untouched by the failed write.
    assert_eq!(std::fs::read_to_string(&path).unwrap(), text);
}
