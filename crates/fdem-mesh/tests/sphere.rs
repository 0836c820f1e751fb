//! Sphere meshes: counts, volumes, orientation, surfaces, quality, errors.

use std::collections::HashMap;
use std::f64::consts::PI;

use approx::assert_relative_eq;
use fdem_mesh::geometry::{cross, distance, dot, sub, tet_signed_volume, triangle_area};
use fdem_mesh::{ElementOrder, MeshError, Sizing, SphereSpec, TET_EDGES, TetMesh, sphere_mesh};

const D: f64 = 0.015; // the paper's E1 particle diameter (m)
const ORDERS: [ElementOrder; 2] = [ElementOrder::Linear, ElementOrder::Quadratic];

fn mesh(level: u32, order: ElementOrder, sizing: Sizing) -> TetMesh {
    sphere_mesh(&SphereSpec {
        level,
        order,
        diameter: D,
        sizing,
    })
    .expect("valid spec")
}

fn all_meshes() -> impl Iterator<Item = (u32, ElementOrder, Sizing, TetMesh)> {
    (0..=4).flat_map(|level| {
        ORDERS.into_iter().flat_map(move |order| {
            [Sizing::Inscribed, Sizing::VolumeEquivalent]
                .into_iter()
                .map(move |sizing| (level, order, sizing, mesh(level, order, sizing)))
        })
    })
}

/// Volume enclosed by the surface, by the divergence theorem with a reference point away
/// from the centre: V = sum over triangles of ((a + b + c)/3 - p) · n_area / 3.
fn divergence_volume(m: &TetMesh) -> f64 {
    let p = [0.3 * D, -0.2 * D, 0.45 * D];
    m.surface
        .triangles
        .iter()
        .map(|&[a, b, c]| {
            let (xa, xb, xc) = (m.nodes[a], m.nodes[b], m.nodes[c]);
            let centroid = [
                (xa[0] + xb[0] + xc[0]) / 3.0,
                (xa[1] + xb[1] + xc[1]) / 3.0,
                (xa[2] + xb[2] + xc[2]) / 3.0,
            ];
            let n = cross(sub(xb, xa), sub(xc, xa)); // twice the area vector
            dot(sub(centroid, p), n) / 6.0
        })
        .sum()
}

#[test]
fn counts_for_every_level_and_order() {
    // (tets, linear nodes, quadratic nodes) from the spec / docs/MODEL.md section 7.
    let expected = [
        (20, 13, 55),
        (80, 43, 205),
        (320, 163, 805),
        (1280, 643, 3205),
        (5120, 2563, 12805),
    ];
    for (level, &(tets, lin, quad)) in expected.iter().enumerate() {
        let level = level as u32;
        let nv = 10 * 4usize.pow(level) + 2; // icosphere vertices
        let lm = mesh(level, ElementOrder::Linear, Sizing::Inscribed);
        assert_eq!(lm.n_elements(), tets, "level {level} linear tets");
        assert_eq!(lm.n_nodes(), lin, "level {level} linear nodes");
        assert_eq!(lm.elements.len(), 4 * tets);
        assert_eq!(
            lm.surface.triangles.len(),
            tets,
            "level {level} linear triangles"
        );
        assert_eq!(
            lm.surface.nodes.len(),
            nv,
            "level {level} linear surface nodes"
        );

        let qm = mesh(level, ElementOrder::Quadratic, Sizing::Inscribed);
        assert_eq!(qm.n_elements(), tets, "level {level} quadratic tets");
        assert_eq!(qm.n_nodes(), quad, "level {level} quadratic nodes");
        assert_eq!(qm.elements.len(), 10 * tets);
        assert_eq!(
            qm.surface.triangles.len(),
            4 * tets,
            "level {level} quadratic triangles"
        );
        // Surface vertices plus one mid-node per surface edge (3/2 per face).
        assert_eq!(
            qm.surface.nodes.len(),
            nv + 3 * tets / 2,
            "level {level} quadratic surface nodes"
        );

        for m in [&lm, &qm] {
            assert_eq!(m.surface.control_areas.len(), m.surface.nodes.len());
            // Documented numbering: surface nodes are exactly 0..n_surface.
            let n_s = m.surface.nodes.len();
            assert!(m.surface.nodes.iter().copied().eq(0..n_s));
            m.validate().expect("consistent arrays");
        }
    }
    let paper = sphere_mesh(&SphereSpec::paper(D)).unwrap();
    assert_eq!((paper.n_elements(), paper.n_nodes()), (80, 205));
    let lin1 = mesh(1, ElementOrder::Linear, Sizing::Inscribed);
    assert_eq!((lin1.n_elements(), lin1.n_nodes()), (80, 43));
}

#[test]
fn inscribed_volume_matches_divergence_theorem() {
    for (_, _, sizing, m) in all_meshes() {
        let v = m.volume();
        let vd = divergence_volume(&m);
        assert!(vd > 0.0);
        assert_relative_eq!(v, vd, max_relative = 1e-12);
        if sizing == Sizing::VolumeEquivalent {
            // Tolerance 1e-12 relative: only round-off separates them.
            assert_relative_eq!(v, PI * D.powi(3) / 6.0, max_relative = 1e-12);
        }
    }
}

#[test]
fn level0_volume_matches_icosahedron_closed_form() {
    let r = D / 2.0;
    let a = r / (2.0 * PI / 5.0).sin(); // edge of the icosahedron of circumradius r
    let closed = 5.0 / 12.0 * (3.0 + 5f64.sqrt()) * a.powi(3);
    for order in ORDERS {
        let m = mesh(0, order, Sizing::Inscribed);
        assert_relative_eq!(m.volume(), closed, max_relative = 1e-12);
        // Every surface edge of level 0 has length a (1e-12 relative).
        let q = m.quality();
        assert_relative_eq!(q.max_edge, a, max_relative = 1e-12);
        assert_relative_eq!(q.min_edge, r, max_relative = 1e-12); // radial edges
    }
}

#[test]
fn inscribed_volume_ratios() {
    let sphere = PI * D.powi(3) / 6.0;
    // Level 1 holds 0.8735 of the sphere (docs/MODEL.md section 7), to 4 digits; levels 0 and
    // 2 are the values quoted in the `Sizing` docs, also to 4 digits.
    for (level, ratio) in [(0, 0.6055), (1, 0.8735), (2, 0.9662)] {
        let m = mesh(level, ElementOrder::Quadratic, Sizing::Inscribed);
        let got = m.volume() / sphere;
        assert!(
            (got - ratio).abs() < 5e-5,
            "level {level}: ratio {got}, expected {ratio}"
        );
    }
}

#[test]
fn all_elements_positively_oriented() {
    for (level, order, sizing, m) in all_meshes() {
        for e in 0..m.n_elements() {
            let [a, b, c, d] = m.corners(e);
            let v = tet_signed_volume(a, b, c, d);
            assert!(
                v > 0.0,
                "level {level} {order:?} {sizing:?}: element {e} volume {v}"
            );
        }
    }
}

#[test]
fn surface_is_closed_and_outward() {
    for (level, order, sizing, m) in all_meshes() {
        // Each directed edge exactly once and its reverse exactly once: the surface is
        // closed (every edge shared by two triangles) and consistently oriented.
        let mut directed: HashMap<(usize, usize), usize> = HashMap::new();
        for &[a, b, c] in &m.surface.triangles {
            for e in [(a, b), (b, c), (c, a)] {
                *directed.entry(e).or_default() += 1;
            }
        }
        for (&(a, b), &n) in &directed {
            assert_eq!(
                n, 1,
                "level {level} {order:?}: edge {a}-{b} used {n} times one way"
            );
            assert_eq!(directed.get(&(b, a)), Some(&1), "edge {a}-{b} not shared");
        }
        // Each triangle's normal points away from the centre (the origin).
        for &[a, b, c] in &m.surface.triangles {
            let (xa, xb, xc) = (m.nodes[a], m.nodes[b], m.nodes[c]);
            let n = cross(sub(xb, xa), sub(xc, xa));
            assert!(
                dot(n, xa) > 0.0,
                "level {level} {order:?} {sizing:?}: triangle inward"
            );
        }
    }
}

#[test]
fn control_areas_sum_to_surface_area() {
    for (_, _, _, m) in all_meshes() {
        let geometric: f64 = m
            .surface
            .triangles
            .iter()
            .map(|&[a, b, c]| triangle_area(m.nodes[a], m.nodes[b], m.nodes[c]))
            .sum();
        let controls: f64 = m.surface.control_areas.iter().sum();
        assert_relative_eq!(controls, geometric, max_relative = 1e-12);
        assert_relative_eq!(m.surface.area(), geometric, max_relative = 1e-12);
        assert_relative_eq!(m.quality().surface_area, geometric, max_relative = 1e-12);
        assert!(m.surface.control_areas.iter().all(|&a| a > 0.0));
    }
    // Quadratic faces split into 4 flat triangles tile the same flat faces.
    for level in 0..=4 {
        let l = mesh(level, ElementOrder::Linear, Sizing::Inscribed);
        let q = mesh(level, ElementOrder::Quadratic, Sizing::Inscribed);
        assert_relative_eq!(l.surface.area(), q.surface.area(), max_relative = 1e-12);
    }
}

#[test]
fn mid_edge_nodes_are_unique_midpoints() {
    for level in 0..=4 {
        let m = mesh(level, ElementOrder::Quadratic, Sizing::Inscribed);
        // At the midpoint of the straight edge (not projected): 1e-15 relative to D.
        for e in 0..m.n_elements() {
            let el = m.element(e);
            for (k, &(i, j)) in TET_EDGES.iter().enumerate() {
                let (xi, xj, xm) = (m.nodes[el[i]], m.nodes[el[j]], m.nodes[el[4 + k]]);
                let mid = [
                    (xi[0] + xj[0]) / 2.0,
                    (xi[1] + xj[1]) / 2.0,
                    (xi[2] + xj[2]) / 2.0,
                ];
                assert!(distance(mid, xm) <= 1e-15 * D, "element {e} node {}", 4 + k);
            }
        }
        // No two nodes at the same position (sweep over nodes sorted by x).
        let mut order: Vec<usize> = (0..m.n_nodes()).collect();
        order.sort_by(|&a, &b| m.nodes[a][0].total_cmp(&m.nodes[b][0]));
        let tol = 1e-9 * D;
        for (k, &a) in order.iter().enumerate() {
            for &b in &order[k + 1..] {
                if m.nodes[b][0] - m.nodes[a][0] > tol {
                    break;
                }
                assert!(
                    distance(m.nodes[a], m.nodes[b]) > tol,
                    "nodes {a} and {b} coincide"
                );
            }
        }
        // Every mid-edge node is shared by all elements around its edge: the number of
        // distinct mid-edge ids equals the number of distinct corner edges.
        let mut edges = std::collections::HashSet::new();
        let mut mids = std::collections::HashSet::new();
        for e in 0..m.n_elements() {
            let el = m.element(e);
            for (k, &(i, j)) in TET_EDGES.iter().enumerate() {
                edges.insert((el[i].min(el[j]), el[i].max(el[j])));
                mids.insert(el[4 + k]);
            }
        }
        assert_eq!(edges.len(), mids.len());
        let corners = 10 * 4usize.pow(level) + 3;
        assert_eq!(m.n_nodes(), corners + mids.len());
    }
}

#[test]
fn surface_vertices_on_sphere_and_centre_at_origin() {
    let r = D / 2.0;
    for level in 0..=4 {
        for order in ORDERS {
            let m = mesh(level, order, Sizing::Inscribed);
            let nv = 10 * 4usize.pow(level) + 2;
            for (i, p) in m.nodes[..nv].iter().enumerate() {
                let d = dot(*p, *p).sqrt();
                assert!(
                    (d - r).abs() <= 1e-12 * r,
                    "vertex {i} at radius {d}, not {r}"
                );
            }
            // The centre is corner 0 of every element and sits at the origin.
            let centre = m.element(0)[0];
            assert_eq!(m.nodes[centre], [0.0; 3]);
            assert!((0..m.n_elements()).all(|e| m.element(e)[0] == centre));
        }
    }
    // Volume-equivalent vertices lie on a sphere slightly larger than the nominal one.
    let m = mesh(1, ElementOrder::Linear, Sizing::VolumeEquivalent);
    let expected = r / 0.8735f64.cbrt();
    let d = dot(m.nodes[0], m.nodes[0]).sqrt();
    assert!(
        (d / expected - 1.0).abs() < 1e-4,
        "radius {d}, expected about {expected}"
    );
}

#[test]
fn quality_figures_are_sane() {
    for level in 0..=4 {
        let m = mesh(level, ElementOrder::Quadratic, Sizing::Inscribed);
        let q = m.quality();
        assert_relative_eq!(q.volume, m.volume(), max_relative = 1e-14);
        assert!(q.min_edge > 0.0 && q.min_edge <= q.max_edge && q.max_edge < D);
        assert!(q.min_altitude > 0.0 && q.min_altitude < q.min_edge);
        assert!(q.min_dihedral_deg > 0.0 && q.min_dihedral_deg <= q.max_dihedral_deg);
        assert!(q.max_dihedral_deg < 180.0);
        // The dihedral angles of a tet around a corner's three edges exceed 180 deg in sum,
        // so the largest one is above 60 deg.
        assert!(q.max_dihedral_deg > 60.0);
    }
    // A regular tetrahedron has dihedral angles acos(1/3) = 70.5288 deg and altitude
    // sqrt(2/3) times its edge (exact formulas).
    let s = fdem_mesh::Surface::from_triangles(vec![], &[]);
    let m = TetMesh {
        order: ElementOrder::Linear,
        nodes: vec![
            [1.0, 1.0, 1.0],
            [1.0, -1.0, -1.0],
            [-1.0, 1.0, -1.0],
            [-1.0, -1.0, 1.0],
        ],
        elements: vec![0, 1, 2, 3],
        surface: s,
    };
    let q = m.quality();
    let edge = 8f64.sqrt();
    let angle = (1.0f64 / 3.0).acos().to_degrees();
    assert_relative_eq!(q.min_dihedral_deg, angle, max_relative = 1e-12);
    assert_relative_eq!(q.max_dihedral_deg, angle, max_relative = 1e-12);
    assert_relative_eq!(q.max_aspect_ratio, 1.0, max_relative = 1e-12);
    assert_relative_eq!(
        q.min_altitude,
        (2.0f64 / 3.0).sqrt() * edge,
        max_relative = 1e-12
    );
    assert_relative_eq!(
        q.volume.abs(),
        edge.powi(3) / (6.0 * 2f64.sqrt()),
        max_relative = 1e-12
    );
}

#[test]
fn level_and_diameter_errors() {
    let spec = |level, diameter| SphereSpec {
        level,
        order: ElementOrder::Quadratic,
        diameter,
        sizing: Sizing::Inscribed,
    };
    let err = sphere_mesh(&spec(5, D)).unwrap_err();
    assert!(matches!(
        err,
        MeshError::LevelOutOfRange { level: 5, max: 4 }
    ));
    assert_eq!(
        err.to_string(),
        "subdivision level 5 is out of range 0..=4; use a level from 0 to 4"
    );
    assert!(sphere_mesh(&spec(u32::MAX, D)).is_err());
    for d in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let err = sphere_mesh(&spec(1, d)).unwrap_err();
        assert!(
            matches!(err, MeshError::InvalidDiameter { .. }),
            "diameter {d}"
        );
        assert!(err.to_string().contains("greater than 0"));
    }
}

#[test]
fn serde_names() {
    assert_eq!(
        serde_json::to_string(&ElementOrder::Quadratic).unwrap(),
        "\"quadratic\""
    );
    assert_eq!(
        serde_json::to_string(&ElementOrder::Linear).unwrap(),
        "\"linear\""
    );
    assert_eq!(
        serde_json::to_string(&Sizing::VolumeEquivalent).unwrap(),
        "\"volume_equivalent\""
    );
    assert_eq!(Sizing::default(), Sizing::Inscribed);
    let spec: SphereSpec =
        serde_json::from_str(r#"{"level":1,"order":"quadratic","diameter":0.015}"#).unwrap();
    assert_eq!(spec, SphereSpec::paper(0.015));
    assert_eq!(ElementOrder::Linear.nodes_per_element(), 4);
    assert_eq!(ElementOrder::Quadratic.nodes_per_element(), 10);
    let q =
        serde_json::to_value(mesh(0, ElementOrder::Linear, Sizing::Inscribed).quality()).unwrap();
    assert!(q.get("min_dihedral_deg").is_some());
}
