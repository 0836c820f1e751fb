//! Running a scene to its end with outputs, progress and interruption.

use crate::SolverError;
use crate::engine::Simulation;
use crate::memory::bytes_text;
use crate::output::{
    BODIES_HEADER, CsvSeries, ENERGY_HEADER, VtkSeries, WALLS_HEADER, body_rows, contact_snapshot,
    energy_row, wall_rows, write_atomically,
};
use crate::scene::Scene;
use serde::Serialize;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// What a run writes and how.
#[derive(Clone, Debug, PartialEq)]
pub struct RunOptions {
    /// Output directory (created if missing).
    pub out_dir: PathBuf,
    /// Write VTU frames and a `.pvd` collection.
    pub vtk: bool,
    /// Write node- and pair-level contact snapshots at every output.
    pub contacts: bool,
}

/// Receives progress reports; the CLI draws a progress bar from them.
pub trait Observer {
    /// Called once before the first step with the run's size and cost.
    fn start(&mut self, _plan: &RunPlan) {}
    /// Called at every output with the simulated time reached.
    fn progress(&mut self, _time: f64, _step: u64) {}
}

/// An observer that ignores everything.
pub struct Silent;
impl Observer for Silent {}

/// What a run will cost, known before the first step.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunPlan {
    /// The run's identifier ([`fdem_core::run_id`]), also in its `summary.json`.
    pub run_id: String,
    /// Simulated duration (s).
    pub duration: f64,
    /// Time step (s).
    pub dt: f64,
    /// Steps to take.
    pub steps: u64,
    /// Bodies, nodes, elements.
    pub bodies: usize,
    /// Nodes.
    pub nodes: usize,
    /// Elements.
    pub elements: usize,
}

/// `summary.json`: it names the run, and the files beside it belong to that run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunSummary {
    /// The run's identifier: `YYYYMMDDTHHMMSSZ-hhhhhhhh`, its UTC start and the hash of
    /// the scene as parsed ([`fdem_core::run_id`]).
    pub run_id: String,
    /// `completed`, `unstable`, `interrupted` or `failed`.
    pub status: String,
    /// The error message when the run did not complete.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Steps taken.
    pub steps: u64,
    /// Simulated time reached (s).
    pub time: f64,
    /// Step size used (s).
    pub dt: f64,
    /// `fixed` or `automatic`.
    pub dt_mode: String,
    /// The smallest stable bound (s); left out of `summary.json` when nothing bounds the
    /// step (infinite: a lone rigid particle with a fixed step, `dt_bound_source` says
    /// so), which JSON cannot write as a number.
    #[serde(skip_serializing_if = "is_unbounded")]
    pub dt_bound: f64,
    /// What sets the bound.
    pub dt_bound_source: String,
    /// Bodies.
    pub bodies: usize,
    /// Nodes.
    pub nodes: usize,
    /// Elements.
    pub elements: usize,
    /// Outputs written.
    pub outputs: usize,
    /// Largest |balance error| / energy scale seen at the outputs.
    pub max_relative_balance_error: f64,
    /// Wall-clock seconds of the time loop.
    pub wall_seconds: f64,
    /// CPU seconds of the process during the time loop (all threads).
    pub cpu_seconds: f64,
    /// Rayon worker threads.
    pub threads: usize,
}

/// Whether a bound is no bound (not finite).
fn is_unbounded(bound: &f64) -> bool {
    !bound.is_finite()
}

/// The files a run writes into its directory, cleared at its start.
const RUN_OUTPUTS: &[&str] = &[
    "energy.csv",
    "bodies.csv",
    "walls.csv",
    "summary.json",
    "frames.pvd",
];

/// The numbered series a run writes, `(folder, file prefix)`, cleared at its start.
const RUN_SERIES: &[(&str, &str)] = &[
    ("frames", "frame_"),
    ("contacts", "nodes_"),
    ("contacts", "pairs_"),
];

/// The most steps a run may plan: about a year of steps at 30 microseconds each; a plan
/// beyond it is a mistake in the scene's duration or step, refused before any work.
pub const MAX_STEPS: u64 = 1_000_000_000_000;

/// The most outputs a run may plan (`duration / output_interval`).
pub const MAX_OUTPUTS: f64 = 1.0e6;

/// Number of steps to cover `duration` with step `dt` (the last step may end up to one
/// step past the duration; 1e-9 relative slack so that `duration = n dt` gives `n`).
pub fn step_count(duration: f64, dt: f64) -> u64 {
    ((duration / dt) * (1.0 - 1e-9)).ceil().max(1.0) as u64
}

/// Refuses, before anything is allocated, a run of `scene` with `options` whose
/// estimated memory exceeds `available` (bytes; `None` when the platform does not say),
/// in one line with the estimate, what is available and what to change; returns the
/// estimate (bytes). The estimate is the model's ([`crate::ModelSize::bytes`], the rule of a
/// specimen's preparation) plus, with `options.vtk`, one VTU frame and, with
/// `options.contacts`, one contact snapshot.
///
/// # Errors
/// [`SolverError::InvalidScene`] when the run cannot fit; a mesh that cannot be built.
pub fn check_memory(
    scene: &Scene,
    options: &RunOptions,
    available: Option<u64>,
) -> Result<u64, SolverError> {
    let size = scene.model_size()?;
    let model = size.bytes();
    let mut outputs = Vec::new();
    if options.vtk {
        outputs.push(("a VTU frame", size.frame_bytes(), "--vtk"));
    }
    if options.contacts {
        outputs.push(("a contact snapshot", size.snapshot_bytes(), "--contacts"));
    }
    let need = outputs
        .iter()
        .fold(model, |sum, (_, bytes, _)| sum.saturating_add(*bytes));
    let Some(have) = available.filter(|&have| need > have) else {
        return Ok(need);
    };
    let mut parts = format!("{} for the model", bytes_text(model));
    let mut flags = Vec::new();
    for (what, bytes, flag) in outputs {
        parts.push_str(&format!(", {} for {what}", bytes_text(bytes)));
        flags.push(flag);
    }
    let without = if flags.is_empty() {
        String::new()
    } else {
        format!(", or run without {}", flags.join(" and "))
    };
    Err(SolverError::InvalidScene(format!(
        "{} particles with {} nodes and {} elements need about {} ({parts}), but {} are \
         available; use fewer particles, a lower mesh.level, linear elements, fewer \
         mesh.shells or model = \"rigid\"{without}",
        size.particles,
        size.nodes,
        size.elements(),
        bytes_text(need),
        bytes_text(have)
    )))
}

/// Runs `scene` to its duration, writing outputs into `options.out_dir`.
///
/// Outputs are at `t = 0` and every output interval (the first step at or past each
/// output time) and at the end. On an instability, an interruption or an I/O error the
/// outputs written so far are completed (renamed into place) with a summary whose status
/// says what happened, and the error is returned. A run the memory the system reports
/// available cannot hold is refused first ([`check_memory`]).
pub fn run(
    scene: &Scene,
    options: &RunOptions,
    observer: &mut dyn Observer,
    interrupt: &AtomicBool,
) -> Result<RunSummary, SolverError> {
    // The scene as parsed, every key written back (comments and layout aside): the same
    // definition gives the same hash.
    let run_id = fdem_core::run_id::run_id(
        scene.to_toml_string()?.as_bytes(),
        std::time::SystemTime::now(),
    );
    check_memory(scene, options, fdem_core::fs::available_memory())?;
    let mut sim = scene.build()?;
    let steps = step_count(scene.simulation.duration, sim.dt());
    if steps > MAX_STEPS {
        return Err(SolverError::InvalidScene(format!(
            "{steps} steps of {:e} s to {:e} s are more than the {MAX_STEPS} a run may plan; \
             shorten simulation.duration or lengthen the step",
            sim.dt(),
            scene.simulation.duration
        )));
    }
    let dir = &options.out_dir;
    std::fs::create_dir_all(dir).map_err(|e| SolverError::io("creating directory", dir, e))?;
    fdem_core::fs::clear_outputs(dir, RUN_OUTPUTS, RUN_SERIES)
        .map_err(|e| SolverError::io("clearing the earlier outputs of", dir, e))?;
    let plan = RunPlan {
        run_id: run_id.clone(),
        duration: scene.simulation.duration,
        dt: sim.dt(),
        steps,
        bodies: sim.bodies().len(),
        nodes: sim.state().len(),
        elements: sim.n_elements(),
    };
    observer.start(&plan);
    let mut outputs = Outputs::create(options)?;
    let wall = Instant::now();
    let cpu = cpu_time::ProcessTime::try_now().ok();
    let outcome = time_loop(
        &mut sim,
        scene,
        plan.steps,
        &mut outputs,
        observer,
        interrupt,
    );
    let wall_seconds = wall.elapsed().as_secs_f64();
    let cpu_seconds = cpu.map_or(f64::NAN, |c| c.elapsed().as_secs_f64());
    let status = match &outcome {
        Ok(()) => "completed",
        Err(SolverError::Unstable { .. }) => "unstable",
        Err(SolverError::Interrupted { .. }) => "interrupted",
        Err(_) => "failed",
    };
    let summary = RunSummary {
        run_id,
        status: status.into(),
        error: outcome.as_ref().err().map(|e| e.to_string()),
        steps: sim.step(),
        time: sim.time(),
        dt: sim.dt(),
        dt_mode: match scene.simulation.dt {
            Some(_) => "fixed".into(),
            None => "automatic".into(),
        },
        dt_bound: sim.bound().dt,
        dt_bound_source: sim.bound().source.clone(),
        bodies: plan.bodies,
        nodes: plan.nodes,
        elements: plan.elements,
        outputs: outputs.written,
        max_relative_balance_error: outputs.max_relative_error,
        wall_seconds,
        cpu_seconds,
        threads: rayon::current_num_threads(),
    };
    outputs.finish()?;
    let json = serde_json::to_string_pretty(&summary)
        .map_err(|e| SolverError::InvalidScene(format!("serializing the summary: {e}")))?;
    write_atomically(&dir.join("summary.json"), &json)?;
    outcome.map(|()| summary)
}

/// Steps `sim` to `steps` with an output at `t = 0`, at the first step at or past each
/// output time and at the end; stops at an interruption or an error.
fn time_loop(
    sim: &mut Simulation,
    scene: &Scene,
    steps: u64,
    outputs: &mut Outputs,
    observer: &mut dyn Observer,
    interrupt: &AtomicBool,
) -> Result<(), SolverError> {
    let interval = scene.output_interval();
    outputs.write(sim)?;
    // Output k is due at k * interval; counting k (not adding up times) always moves on,
    // even where an interval is below the resolution of the time.
    let mut next: u64 = 1;
    while sim.step() < steps {
        if interrupt.load(Ordering::Relaxed) {
            return Err(SolverError::Interrupted {
                time: sim.time(),
                step: sim.step(),
            });
        }
        sim.advance()?;
        let last = sim.step() == steps;
        let reached = sim.time() + 0.5 * sim.dt();
        if last || reached >= next as f64 * interval {
            outputs.write(sim)?;
            // The first output time after this step (the cast saturates, the sums too).
            next = next
                .saturating_add(1)
                .max(((reached / interval).floor() as u64).saturating_add(1));
            observer.progress(sim.time(), sim.step());
        }
    }
    Ok(())
}

/// The output series of a run: `energy.csv`, `bodies.csv`, `walls.csv`, optional VTU
/// frames and contact snapshots.
struct Outputs {
    dir: PathBuf,
    energy: CsvSeries,
    bodies: CsvSeries,
    walls: CsvSeries,
    vtk: Option<VtkSeries>,
    contacts: bool,
    written: usize,
    max_relative_error: f64,
}

impl Outputs {
    fn create(options: &RunOptions) -> Result<Self, SolverError> {
        let dir = &options.out_dir;
        Ok(Outputs {
            dir: dir.clone(),
            energy: CsvSeries::create(dir, "energy.csv", ENERGY_HEADER)?,
            bodies: CsvSeries::create(dir, "bodies.csv", BODIES_HEADER)?,
            walls: CsvSeries::create(dir, "walls.csv", WALLS_HEADER)?,
            vtk: if options.vtk {
                Some(VtkSeries::create(dir)?)
            } else {
                None
            },
            contacts: options.contacts,
            written: 0,
            max_relative_error: 0.0,
        })
    }

    /// One output of every series, after the energy check.
    fn write(&mut self, sim: &Simulation) -> Result<(), SolverError> {
        let e = sim.check_energy()?;
        self.max_relative_error = self.max_relative_error.max(sim.relative_balance_error(&e));
        self.energy.row(&energy_row(&e))?;
        body_rows(sim, &mut self.bodies)?;
        wall_rows(sim, &mut self.walls)?;
        if self.contacts {
            contact_snapshot(sim, &self.dir, self.written)?;
        }
        if let Some(v) = self.vtk.as_mut() {
            v.frame(sim)?;
        }
        self.written += 1;
        Ok(())
    }

    /// Completes the CSV series (renamed into place).
    fn finish(self) -> Result<(), SolverError> {
        self.energy.finish()?;
        self.bodies.finish()?;
        self.walls.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A lone rigid particle with a fixed step has no stable bound: its summary leaves the
    /// bound out (JSON would write it as `null`) and says what sets it.
    #[test]
    fn an_unbounded_step_is_left_out_of_the_summary() {
        let text = "[simulation]\nduration = 1e-5\ndt = 1e-6\n\
            [material]\ndensity = 2650.0\nyoungs_modulus = 40.0e9\npoisson_ratio = 0.2\n\
            [[particle]]\ndiameter = 0.015\ncenter = [0.0, 0.0, 0.0]\nmodel = \"rigid\"\n";
        let scene = Scene::from_toml_str(text, "s.toml").unwrap();
        let dir = tempfile::tempdir().unwrap();
        let options = RunOptions {
            out_dir: dir.path().to_path_buf(),
            vtk: false,
            contacts: false,
        };
        let summary = run(&scene, &options, &mut Silent, &AtomicBool::new(false)).unwrap();
        assert_eq!(summary.dt_bound, f64::INFINITY);
        let json = std::fs::read_to_string(dir.path().join("summary.json")).unwrap();
        assert!(
            !json.contains("null") && !json.contains("\"dt_bound\""),
            "{json}"
        );
        assert!(json.contains("\"dt_bound_source\": \"nothing"), "{json}");
    }
}
