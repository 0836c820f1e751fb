//! VTK XML output: UnstructuredGrid (`.vtu`) frames and ParaView collections (`.pvd`).
//!
//! Frames are written with the `vtkio` crate as VTK XML version 1.0, little endian,
//! `header_type="UInt64"`, inline base64 binary data (no appended data, no compression).
//! Points and fields are `Float64`, connectivity and offsets `UInt64`, cell types `UInt8`.
//!
//! Every file is first written to a temporary file in the same directory (`NAME.part`, the
//! project's convention: `fdem_core::fs`) and renamed to its final name when complete, so a
//! reader never sees a half-written file and an interrupted run leaves no truncated output
//! under the final name.

use fdem_core::fs::AtomicFile;
use std::io::Write;
use std::path::Path;

use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataArray, DataSet, ElementType, IOBuffer,
    UnstructuredGridPiece, Version, VertexNumbers, Vtk,
};

use crate::{MeshAssembly, MeshError, TetMesh};

/// One named data array of a frame: `components` values per point (or per cell), stored
/// point after point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VtuField<'a> {
    /// Array name shown in ParaView; non-empty, without `< > & " '` or control characters.
    pub name: &'a str,
    /// Values per point or cell (1 for a scalar, 3 for a vector, 9 for a tensor).
    pub components: usize,
    /// `components * count` values, where count is the number of points or cells.
    pub values: &'a [f64],
}

/// How many nodes each cell of a frame has: 3 (VTK_TRIANGLE = 5), 4 (VTK_TETRA = 10) or
/// 10 (VTK_QUADRATIC_TETRA = 24).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CellNodes<'a> {
    /// Every cell has this many nodes.
    Uniform(usize),
    /// The node count of each cell in turn (a frame that mixes cell types, for example
    /// linear and quadratic tetrahedra beside surface triangles).
    PerCell(&'a [usize]),
}

/// One unstructured-grid frame to write.
#[derive(Clone, Debug, PartialEq)]
pub struct VtuFrame<'a> {
    /// Point positions.
    pub points: &'a [[f64; 3]],
    /// Flat cell connectivity: the point ids of each cell in turn.
    pub cells: &'a [usize],
    /// The node count of the cells.
    pub cell_nodes: CellNodes<'a>,
    /// Fields with one entry per point.
    pub point_fields: Vec<VtuField<'a>>,
    /// Fields with one entry per cell.
    pub cell_fields: Vec<VtuField<'a>>,
}

impl VtuFrame<'_> {
    /// Number of cells (0 for a uniform node count of 0).
    pub fn n_cells(&self) -> usize {
        match self.cell_nodes {
            CellNodes::Uniform(npc) => self.cells.len().checked_div(npc).unwrap_or(0),
            CellNodes::PerCell(sizes) => sizes.len(),
        }
    }

    /// The node count of every cell, checked against the connectivity's length.
    fn cell_sizes(&self) -> Result<Vec<usize>, MeshError> {
        let bad = |reason: String| Err(MeshError::InvalidFrame { reason });
        let sizes = match self.cell_nodes {
            CellNodes::Uniform(npc) => {
                if cell_type(npc).is_none() {
                    return bad(format!(
                        "nodes_per_cell is {npc}; use 4 (linear tetra), 10 (quadratic tetra) or 3 (triangle)"
                    ));
                }
                if !self.cells.len().is_multiple_of(npc) {
                    return bad(format!(
                        "the cell array has {} entries, which is not a multiple of nodes_per_cell = {npc}",
                        self.cells.len()
                    ));
                }
                vec![npc; self.cells.len() / npc]
            }
            CellNodes::PerCell(sizes) => {
                if let Some(c) = sizes.iter().position(|&n| cell_type(n).is_none()) {
                    return bad(format!(
                        "cell {c} has {} nodes; use 4 (linear tetra), 10 (quadratic tetra) or 3 (triangle)",
                        sizes[c]
                    ));
                }
                let total: usize = sizes.iter().sum();
                if total != self.cells.len() {
                    return bad(format!(
                        "the cells' node counts add up to {total}, but the cell array has {} entries",
                        self.cells.len()
                    ));
                }
                sizes.to_vec()
            }
        };
        Ok(sizes)
    }

    /// Checks that the arrays fit together.
    ///
    /// # Errors
    /// [`MeshError::InvalidFrame`] naming the inconsistency.
    pub fn validate(&self) -> Result<(), MeshError> {
        self.checked_sizes().map(|_| ())
    }

    /// [`VtuFrame::validate`], giving the node count of every cell.
    fn checked_sizes(&self) -> Result<Vec<usize>, MeshError> {
        let bad = |reason: String| Err(MeshError::InvalidFrame { reason });
        let sizes = self.cell_sizes()?;
        let n_points = self.points.len();
        if let Some(k) = self.cells.iter().position(|&i| i >= n_points) {
            let cell = sizes
                .iter()
                .scan(0, |end, &n| {
                    *end += n;
                    Some(*end)
                })
                .position(|end| end > k)
                .unwrap_or(0);
            return bad(format!(
                "cell {cell} refers to point {}, but the frame has only {n_points} points",
                self.cells[k]
            ));
        }
        let n_cells = sizes.len();
        for (kind, fields, count) in [
            ("point", &self.point_fields, n_points),
            ("cell", &self.cell_fields, n_cells),
        ] {
            let mut names: Vec<&str> = Vec::new();
            for f in fields {
                if f.name.is_empty()
                    || f.name
                        .chars()
                        .any(|c| c.is_control() || matches!(c, '<' | '>' | '&' | '"' | '\''))
                {
                    return bad(format!(
                        "{kind} field name {:?} is empty or holds a character that XML would need escaped; use letters, digits, '_' or '-'",
                        f.name
                    ));
                }
                if names.contains(&f.name) {
                    return bad(format!(
                        "{kind} field name {:?} is used twice; give every {kind} field a distinct name",
                        f.name
                    ));
                }
                names.push(f.name);
                if f.components == 0 || u32::try_from(f.components).is_err() {
                    return bad(format!(
                        "{kind} field {:?} has {} components; give at least 1",
                        f.name, f.components
                    ));
                }
                let expected = f.components.saturating_mul(count);
                if f.values.len() != expected {
                    return bad(format!(
                        "{kind} field {:?} has {} values, expected {} components x {count} {kind}s = {expected}",
                        f.name,
                        f.values.len(),
                        f.components
                    ));
                }
            }
        }
        Ok(sizes)
    }
}

/// VTK cell type for a number of nodes per cell.
fn cell_type(nodes_per_cell: usize) -> Option<CellType> {
    match nodes_per_cell {
        3 => Some(CellType::Triangle),
        4 => Some(CellType::Tetra),
        10 => Some(CellType::QuadraticTetra),
        _ => None,
    }
}

fn attribute(f: &VtuField<'_>) -> Attribute {
    let num_comp = u32::try_from(f.components).unwrap_or(u32::MAX); // validated before
    let elem = if num_comp == 1 {
        ElementType::Scalars {
            num_comp,
            lookup_table: None,
        }
    } else {
        ElementType::Generic(num_comp)
    };
    Attribute::DataArray(DataArray {
        name: f.name.to_string(),
        elem,
        data: IOBuffer::F64(f.values.to_vec()),
    })
}

/// Writes one frame as a VTK XML UnstructuredGrid file (`.vtu`).
///
/// The frame is validated first (see [`VtuFrame::validate`]); the file is written to a
/// temporary name in the same directory and renamed when complete.
///
/// # Errors
/// [`MeshError::InvalidFrame`] for inconsistent arrays, [`MeshError::NoFileName`],
/// [`MeshError::Io`] if the file cannot be written, [`MeshError::Vtk`] if encoding fails.
pub fn write_vtu(path: &Path, frame: &VtuFrame) -> Result<(), MeshError> {
    let sizes = frame.checked_sizes()?;
    let offsets = sizes
        .iter()
        .scan(0u64, |end, &n| {
            *end += n as u64;
            Some(*end)
        })
        .collect();
    // Every size was checked to have a type.
    let types = sizes.iter().filter_map(|&n| cell_type(n)).collect();
    let piece = UnstructuredGridPiece {
        points: IOBuffer::F64(frame.points.iter().flatten().copied().collect()),
        cells: Cells {
            cell_verts: VertexNumbers::XML {
                connectivity: frame.cells.iter().map(|&i| i as u64).collect(),
                offsets,
            },
            types,
        },
        data: Attributes {
            point: frame.point_fields.iter().map(attribute).collect(),
            cell: frame.cell_fields.iter().map(attribute).collect(),
        },
    };
    let vtk = Vtk {
        version: Version::new((1, 0)),
        title: String::new(),
        byte_order: ByteOrder::LittleEndian,
        data: DataSet::inline(piece),
        file_path: None,
    };
    write_atomically(path, |w| {
        vtk.write_xml(&mut *w).map_err(|e| MeshError::Vtk {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        w.write_all(b"\n").map_err(|source| MeshError::Io {
            path: path.to_path_buf(),
            source,
        })
    })
}

/// Writes a ParaView collection file (`.pvd`) listing `(time, file)` pairs, where `file`
/// is the path of a frame relative to the `.pvd` file. Times are written in full
/// precision; file names are XML-escaped.
///
/// # Errors
/// [`MeshError::InvalidTime`] for a non-finite time, [`MeshError::NoFileName`],
/// [`MeshError::Io`] if the file cannot be written.
pub fn write_pvd(path: &Path, entries: &[(f64, String)]) -> Result<(), MeshError> {
    if let Some((index, &(time, _))) = entries.iter().enumerate().find(|(_, e)| !e.0.is_finite()) {
        return Err(MeshError::InvalidTime { index, time });
    }
    let mut text = String::from(
        "<?xml version=\"1.0\"?>\n\
         <VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n",
    );
    for (time, file) in entries {
        text.push_str(&format!(
            "    <DataSet timestep=\"{time:?}\" group=\"\" part=\"0\" file=\"{}\"/>\n",
            xml_escape(file)
        ));
    }
    text.push_str("  </Collection>\n</VTKFile>\n");
    write_atomically(path, |w| {
        w.write_all(text.as_bytes())
            .map_err(|source| MeshError::Io {
                path: path.to_path_buf(),
                source,
            })
    })
}

/// Escapes the five XML special characters for use in an attribute value.
fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// Runs `body` on a buffered writer to the temporary of `path`, then renames it to `path`.
/// The temporary file is removed on any error.
fn write_atomically(
    path: &Path,
    body: impl FnOnce(&mut AtomicFile) -> Result<(), MeshError>,
) -> Result<(), MeshError> {
    if path.file_name().is_none() {
        return Err(MeshError::NoFileName {
            path: path.to_path_buf(),
        });
    }
    let io_err = |source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut file = AtomicFile::create(path).map_err(io_err)?;
    body(&mut file)?;
    file.finish().map_err(io_err)
}

impl TetMesh {
    /// Writes the mesh as a `.vtu` file with a point field `is_surface` (1 on surface
    /// nodes, 0 elsewhere) and a cell field `element_id`.
    ///
    /// # Errors
    /// As [`write_vtu`].
    pub fn write_vtu(&self, path: &Path) -> Result<(), MeshError> {
        let mut is_surface = vec![0.0; self.nodes.len()];
        for &i in &self.surface.nodes {
            if let Some(s) = is_surface.get_mut(i) {
                *s = 1.0;
            }
        }
        let element_id: Vec<f64> = (0..self.n_elements()).map(|e| e as f64).collect();
        write_vtu(
            path,
            &VtuFrame {
                points: &self.nodes,
                cells: &self.elements,
                cell_nodes: CellNodes::Uniform(self.order.nodes_per_element()),
                point_fields: vec![VtuField {
                    name: "is_surface",
                    components: 1,
                    values: &is_surface,
                }],
                cell_fields: vec![VtuField {
                    name: "element_id",
                    components: 1,
                    values: &element_id,
                }],
            },
        )
    }
}

impl MeshAssembly {
    /// Writes all bodies' elements as a `.vtu` file with a point field `body_id` and cell
    /// fields `body_id` and `element_id` (global element id).
    ///
    /// # Errors
    /// As [`write_vtu`]; an empty assembly gives [`MeshError::InvalidFrame`].
    pub fn write_vtu(&self, path: &Path) -> Result<(), MeshError> {
        let mut point_body = vec![0.0; self.nodes.len()];
        let mut cell_body = vec![0.0; self.n_elements()];
        for (b, range) in self.bodies.iter().enumerate() {
            for v in point_body
                .get_mut(range.nodes.clone())
                .into_iter()
                .flatten()
            {
                *v = b as f64;
            }
            for v in cell_body
                .get_mut(range.elements.clone())
                .into_iter()
                .flatten()
            {
                *v = b as f64;
            }
        }
        let element_id: Vec<f64> = (0..self.n_elements()).map(|e| e as f64).collect();
        write_vtu(
            path,
            &VtuFrame {
                points: &self.nodes,
                cells: &self.elements,
                cell_nodes: CellNodes::Uniform(self.nodes_per_element()),
                point_fields: vec![VtuField {
                    name: "body_id",
                    components: 1,
                    values: &point_body,
                }],
                cell_fields: vec![
                    VtuField {
                        name: "body_id",
                        components: 1,
                        values: &cell_body,
                    },
                    VtuField {
                        name: "element_id",
                        components: 1,
                        values: &element_id,
                    },
                ],
            },
        )
    }
}
