//! Run outputs: CSV series, the JSON summary and VTU frames, each written to a temporary
//! name (`NAME.part`) and renamed into place when complete (`fdem_core::fs`).

use crate::SolverError;
use crate::engine::{EnergyReport, Simulation};
use fdem_core::fs::AtomicFile;
use fdem_core::snapshot;
use fdem_mesh::vtu::{CellNodes, VtuField, VtuFrame, write_pvd, write_vtu};
use std::io::Write;
use std::path::{Path, PathBuf};

/// A CSV file written under `NAME.part` and renamed to `NAME` by [`CsvSeries::finish`];
/// dropped unfinished, it leaves no file.
pub struct CsvSeries {
    file: AtomicFile,
}

impl CsvSeries {
    /// Creates `dir/name.part` and writes the header row.
    pub fn create(dir: &Path, name: &str, header: &str) -> Result<Self, SolverError> {
        let path = dir.join(name);
        let file = AtomicFile::create(&path).map_err(|e| SolverError::io("creating", &path, e))?;
        let mut series = CsvSeries { file };
        series.row(header)?;
        Ok(series)
    }

    /// Appends one row (without the newline).
    pub fn row(&mut self, line: &str) -> Result<(), SolverError> {
        writeln!(self.file, "{line}").map_err(|e| SolverError::io("writing", self.file.path(), e))
    }

    /// Flushes and renames the file into place.
    pub fn finish(self) -> Result<(), SolverError> {
        let path = self.file.path().to_path_buf();
        self.file
            .finish()
            .map_err(|e| SolverError::io("writing", path, e))
    }
}

/// Writes `text` to `path` through a temporary file and a rename.
pub fn write_atomically(path: &Path, text: &str) -> Result<(), SolverError> {
    fdem_core::fs::write_atomically(path, text).map_err(|e| SolverError::io("writing", path, e))
}

/// Header of `energy.csv`.
pub const ENERGY_HEADER: &str = "time,kinetic,strain,external_work,dissipated,balance_error,contact,damping_dissipated,friction_dissipated";
/// Header of `walls.csv`.
pub const WALLS_HEADER: &str = "time,wall,fx,fy,fz";
/// Header of the node-level contact snapshots `contacts/nodes_NNNNNN.csv` (the shared
/// format of `fdem_core::snapshot`).
pub use fdem_core::snapshot::NODES_HEADER as NODE_CONTACTS_HEADER;
/// Header of the pair-level contact snapshots `contacts/pairs_NNNNNN.csv` (the shared
/// format of `fdem_core::snapshot`).
pub use fdem_core::snapshot::PAIRS_HEADER as PAIR_CONTACTS_HEADER;
/// Header of `bodies.csv`.
pub const BODIES_HEADER: &str = "time,body,x,y,z,vx,vy,vz,wx,wy,wz";

/// One `energy.csv` row. Values use Rust's shortest round-trip float formatting.
pub fn energy_row(e: &EnergyReport) -> String {
    format!(
        "{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e}",
        e.time,
        e.kinetic,
        e.strain,
        e.external_work,
        e.dissipated,
        e.balance_error,
        e.other_potential,
        e.damping_dissipated,
        e.friction_dissipated
    )
}

/// Appends one row per body to `bodies.csv`.
pub fn body_rows(sim: &Simulation, series: &mut CsvSeries) -> Result<(), SolverError> {
    for id in 0..sim.bodies().len() {
        let m = sim.body_motion(id);
        let (c, v, w) = (m.centroid, m.velocity, m.angular_velocity);
        series.row(&format!(
            "{:e},{id},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e}",
            sim.time(),
            c[0],
            c[1],
            c[2],
            v[0],
            v[1],
            v[2],
            w[0],
            w[1],
            w[2]
        ))?;
    }
    Ok(())
}

/// VTU frames and their `.pvd` collection.
pub struct VtkSeries {
    dir: PathBuf,
    entries: Vec<(f64, String)>,
}

impl VtkSeries {
    /// Frames go to `dir/frames/`, the collection to `dir/frames.pvd`.
    pub fn create(dir: &Path) -> Result<Self, SolverError> {
        let frames = dir.join("frames");
        std::fs::create_dir_all(&frames)
            .map_err(|e| SolverError::io("creating directory", &frames, e))?;
        Ok(VtkSeries {
            dir: dir.to_path_buf(),
            entries: Vec::new(),
        })
    }

    /// Writes one frame (displacement, velocity, body id per node; stress and body per
    /// cell) and rewrites the collection so that it always lists complete frames. The
    /// cells are the deformable particles' elements and the rigid particles' surface
    /// triangles, whose stress is written as zero.
    pub fn frame(&mut self, sim: &Simulation) -> Result<(), SolverError> {
        let s = &sim.state();
        let displacement: Vec<f64> = s
            .positions
            .iter()
            .zip(&s.reference)
            .flat_map(|(x, x0)| [x[0] - x0[0], x[1] - x0[1], x[2] - x0[2]])
            .collect();
        let velocity: Vec<f64> = s.velocities.iter().flatten().copied().collect();
        let mut node_body = vec![0.0; s.len()];
        for (id, b) in sim.bodies().iter().enumerate() {
            node_body[b.nodes.clone()].fill(id as f64);
        }
        let cells = frame_cells(sim)?;
        let mut cell_fields = Vec::with_capacity(2);
        if let Some(stress) = &cells.stress {
            cell_fields.push(VtuField {
                name: "stress",
                components: 9,
                values: stress,
            });
        }
        cell_fields.push(VtuField {
            name: "body",
            components: 1,
            values: &cells.body,
        });
        let name = format!("frame_{:06}.vtu", self.entries.len());
        let frame = VtuFrame {
            points: &s.positions,
            cells: &cells.connectivity,
            cell_nodes: CellNodes::PerCell(&cells.sizes),
            point_fields: vec![
                VtuField {
                    name: "displacement",
                    components: 3,
                    values: &displacement,
                },
                VtuField {
                    name: "velocity",
                    components: 3,
                    values: &velocity,
                },
                VtuField {
                    name: "body",
                    components: 1,
                    values: &node_body,
                },
            ],
            cell_fields,
        };
        write_vtu(&self.dir.join("frames").join(&name), &frame)?;
        self.entries.push((sim.time(), format!("frames/{name}")));
        write_pvd(&self.dir.join("frames.pvd"), &self.entries)?;
        Ok(())
    }
}

/// The cells of a frame.
struct Cells {
    connectivity: Vec<usize>,
    /// Node count per cell (4 or 10 for elements, 3 for rigid surface triangles).
    sizes: Vec<usize>,
    /// Body id per cell.
    body: Vec<f64>,
    /// Cauchy stress per cell, 9 components row by row; `None` without elements.
    stress: Option<Vec<f64>>,
}

/// The frame's cells: the elements of the deformable particles with the stress tensor of
/// each (9 components row by row, as ParaView expects), then the surface triangles of the
/// rigid particles, whose stress is written as zero (a rigid body has no strain). A model
/// without elements has no stress field.
fn frame_cells(sim: &Simulation) -> Result<Cells, SolverError> {
    let elements = sim.connectivity();
    let mut cells = Cells {
        connectivity: elements.flat().to_vec(),
        sizes: elements.node_counts(),
        body: Vec::with_capacity(elements.len()),
        stress: None,
    };
    for (id, b) in sim.bodies().iter().enumerate() {
        cells
            .body
            .extend(std::iter::repeat_n(id as f64, b.elements.len()));
    }
    if !elements.is_empty() {
        let stress: Vec<f64> = sim
            .elastic()
            .stresses(&sim.state().positions)?
            .iter()
            .flat_map(|t| {
                let [xx, yy, zz, yz, xz, xy] = *t;
                [xx, xy, xz, xy, yy, yz, xz, yz, zz]
            })
            .collect();
        cells.stress = Some(stress);
    }
    let triangles = push_rigid_triangles(sim, &mut cells);
    if let Some(stress) = &mut cells.stress {
        stress.resize(stress.len() + 9 * triangles, 0.0);
    }
    Ok(cells)
}

/// Appends the surface triangles of the rigid bodies to `cells`, with the body of each;
/// returns how many.
fn push_rigid_triangles(sim: &Simulation, cells: &mut Cells) -> usize {
    let Some(contact) = sim.contact() else {
        return 0;
    };
    let surface = contact.model().surface();
    let bodies = sim.bodies();
    let mut count = 0;
    for (t, &b) in surface.triangles.iter().zip(&surface.triangle_body) {
        if bodies[b as usize].kind == crate::BodyKind::Rigid {
            cells.connectivity.extend_from_slice(t);
            cells.sizes.push(3);
            cells.body.push(f64::from(b));
            count += 1;
        }
    }
    count
}

/// Appends one row per wall to `walls.csv`: the force the particles exert on it (N).
pub fn wall_rows(sim: &Simulation, series: &mut CsvSeries) -> Result<(), SolverError> {
    if let Some(contact) = sim.contact() {
        for (w, f) in contact.model().wall_forces().iter().enumerate() {
            series.row(&format!(
                "{:e},{w},{:e},{:e},{:e}",
                sim.time(),
                f[0],
                f[1],
                f[2]
            ))?;
        }
    }
    Ok(())
}

fn snapshot_counterpart(c: fdem_contact::Counterpart) -> snapshot::Counterpart {
    match c {
        fdem_contact::Counterpart::Body(b) => snapshot::Counterpart::Body(b),
        fdem_contact::Counterpart::Wall(w) => snapshot::Counterpart::Wall(w),
    }
}

/// A body of the contact surface that is a boundary, not a particle (a membrane): its
/// contacts are reported as contacts with wall `as_wall`, and its own nodes' rows are left
/// out (the particle side of each contact is kept).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BoundaryBody {
    /// Body id in the contact surface.
    pub body: u32,
    /// Wall index reported for it.
    pub as_wall: u32,
}

/// The node-level and pair-level contact snapshot of `sim` as CSV text
/// (`NODE_CONTACTS_HEADER` and `PAIR_CONTACTS_HEADER` rows, docs/MICRO.md), or `None`
/// without a contact model.
pub fn contact_snapshot_text(
    sim: &Simulation,
    boundary: Option<BoundaryBody>,
) -> Option<(String, String)> {
    let contact = sim.contact()?;
    let remap = |c: fdem_contact::Counterpart| match (c, boundary) {
        (fdem_contact::Counterpart::Body(b), Some(bb)) if b == bb.body => {
            snapshot::Counterpart::Wall(bb.as_wall)
        }
        _ => snapshot_counterpart(c),
    };
    let is_boundary = |b: u32| boundary.is_some_and(|bb| bb.body == b);
    let node_contacts = contact.model().node_contacts().iter();
    let nodes = node_contacts
        .filter(|c| !is_boundary(c.body))
        .map(|c| snapshot::NodeRow {
            node: c.node as u64,
            body: c.body,
            counterpart: remap(c.counterpart),
            position: c.position,
            depth: c.depth,
            normal_force: c.normal_force,
            tangential_force: c.tangential_force,
            sliding: c.sliding,
        });
    let nodes = snapshot::nodes_text(sim.time(), nodes);
    let mut pairs = contact.model().pair_sums();
    pairs.retain(|p| !is_boundary(p.body));
    let pairs = pairs.into_iter().map(|p| snapshot::PairRow {
        body: p.body,
        counterpart: remap(p.counterpart),
        normal_force: p.normal_force,
        tangential_force: p.tangential_force,
        nodes: p.nodes,
    });
    let pairs = snapshot::pairs_text(sim.time(), pairs);
    Some((nodes, pairs))
}

/// Writes the node-level and pair-level contact snapshot of output number `index` into
/// `dir/contacts/` (each file atomically).
pub fn contact_snapshot(sim: &Simulation, dir: &Path, index: usize) -> Result<(), SolverError> {
    let Some((nodes, pairs)) = contact_snapshot_text(sim, None) else {
        return Ok(());
    };
    let folder = dir.join("contacts");
    std::fs::create_dir_all(&folder)
        .map_err(|e| SolverError::io("creating directory", &folder, e))?;
    write_atomically(&folder.join(format!("nodes_{index:06}.csv")), &nodes)?;
    write_atomically(&folder.join(format!("pairs_{index:06}.csv")), &pairs)
}
