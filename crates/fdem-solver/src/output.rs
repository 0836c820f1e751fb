//! Run outputs: CSV series, the JSON summary and VTU frames, each written to a temporary
//! name and renamed into place when complete.

use crate::SolverError;
use crate::engine::{EnergyReport, Simulation};
use fdem_mesh::vtu::{VtuField, VtuFrame, write_pvd, write_vtu};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// A CSV file written under `NAME.part` and renamed to `NAME` by [`CsvSeries::finish`].
pub struct CsvSeries {
    writer: BufWriter<File>,
    partial: PathBuf,
    path: PathBuf,
}

impl CsvSeries {
    /// Creates `dir/name.part` and writes the header row.
    pub fn create(dir: &Path, name: &str, header: &str) -> Result<Self, SolverError> {
        let path = dir.join(name);
        let partial = dir.join(format!("{name}.part"));
        let file = File::create(&partial).map_err(|e| SolverError::io("creating", &partial, e))?;
        let mut series = CsvSeries {
            writer: BufWriter::new(file),
            partial,
            path,
        };
        series.row(header)?;
        Ok(series)
    }

    /// Appends one row (without the newline).
    pub fn row(&mut self, line: &str) -> Result<(), SolverError> {
        writeln!(self.writer, "{line}").map_err(|e| SolverError::io("writing", &self.partial, e))
    }

    /// Flushes and renames the file into place.
    pub fn finish(mut self) -> Result<(), SolverError> {
        self.writer
            .flush()
            .map_err(|e| SolverError::io("writing", &self.partial, e))?;
        std::fs::rename(&self.partial, &self.path)
            .map_err(|e| SolverError::io("renaming", &self.partial, e))
    }
}

/// Writes `text` to `path` through a temporary file and a rename.
pub fn write_atomically(path: &Path, text: &str) -> Result<(), SolverError> {
    let partial = path.with_extension("part");
    std::fs::write(&partial, text).map_err(|e| SolverError::io("writing", &partial, e))?;
    std::fs::rename(&partial, path).map_err(|e| SolverError::io("renaming", &partial, e))
}

/// Header of `energy.csv`.
pub const ENERGY_HEADER: &str = "time,kinetic,strain,external_work,dissipated,balance_error";
/// Header of `bodies.csv`.
pub const BODIES_HEADER: &str = "time,body,x,y,z,vx,vy,vz,wx,wy,wz";

/// One `energy.csv` row. Values use Rust's shortest round-trip float formatting.
pub fn energy_row(e: &EnergyReport) -> String {
    format!(
        "{:e},{:e},{:e},{:e},{:e},{:e}",
        e.time,
        e.kinetic,
        e.strain + e.other_potential,
        e.external_work,
        e.dissipated,
        e.balance_error
    )
}

/// Appends one row per body to `bodies.csv`.
pub fn body_rows(sim: &Simulation, series: &mut CsvSeries) -> Result<(), SolverError> {
    for (id, body) in sim.bodies.iter().enumerate() {
        let m = body.motion(&sim.state);
        let (c, v, w) = (m.centroid, m.velocity, m.angular_velocity);
        series.row(&format!(
            "{:e},{id},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e}",
            sim.time, c[0], c[1], c[2], v[0], v[1], v[2], w[0], w[1], w[2]
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
    /// element) and rewrites the collection so that it always lists complete frames.
    pub fn frame(&mut self, sim: &Simulation) -> Result<(), SolverError> {
        let s = &sim.state;
        let (connectivity, npe) = (&sim.connectivity, sim.nodes_per_element);
        let displacement: Vec<f64> = s
            .positions
            .iter()
            .zip(&s.reference)
            .flat_map(|(x, x0)| [x[0] - x0[0], x[1] - x0[1], x[2] - x0[2]])
            .collect();
        let velocity: Vec<f64> = s.velocities.iter().flatten().copied().collect();
        let mut node_body = vec![0.0; s.len()];
        let mut cell_body = Vec::with_capacity(connectivity.len() / npe.max(1));
        for (id, b) in sim.bodies.iter().enumerate() {
            node_body[b.nodes.clone()].fill(id as f64);
            cell_body.extend(std::iter::repeat_n(id as f64, b.elements.len()));
        }
        // Full symmetric tensor, 9 components row by row, as ParaView expects.
        let stress: Vec<f64> = sim
            .elastic
            .stresses(&s.positions)?
            .iter()
            .flat_map(|t| {
                let [xx, yy, zz, yz, xz, xy] = *t;
                [xx, xy, xz, xy, yy, yz, xz, yz, zz]
            })
            .collect();
        let name = format!("frame_{:06}.vtu", self.entries.len());
        let frame = VtuFrame {
            points: &s.positions,
            cells: connectivity,
            nodes_per_cell: npe,
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
            cell_fields: vec![
                VtuField {
                    name: "stress",
                    components: 9,
                    values: &stress,
                },
                VtuField {
                    name: "body",
                    components: 1,
                    values: &cell_body,
                },
            ],
        };
        write_vtu(&self.dir.join("frames").join(&name), &frame)?;
        self.entries.push((sim.time, format!("frames/{name}")));
        write_pvd(&self.dir.join("frames.pvd"), &self.entries)?;
        Ok(())
    }
}
