//! Running a scene to its end with outputs, progress and interruption.

use crate::SolverError;
use crate::engine::Simulation;
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

/// `summary.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunSummary {
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
    /// The smallest stable bound (s).
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

/// Number of steps to cover `duration` with step `dt` (the last step may end up to one
/// step past the duration; 1e-9 relative slack so that `duration = n dt` gives `n`).
pub fn step_count(duration: f64, dt: f64) -> u64 {
    ((duration / dt) * (1.0 - 1e-9)).ceil().max(1.0) as u64
}

/// Runs `scene` to its duration, writing outputs into `options.out_dir`.
///
/// Outputs are at `t = 0` and every output interval (the first step at or past each
/// output time) and at the end. On an instability, an interruption or an I/O error the
/// outputs written so far are completed (renamed into place) with a summary whose status
/// says what happened, and the error is returned.
pub fn run(
    scene: &Scene,
    options: &RunOptions,
    observer: &mut dyn Observer,
    interrupt: &AtomicBool,
) -> Result<RunSummary, SolverError> {
    let mut sim = scene.build()?;
    let dir = &options.out_dir;
    std::fs::create_dir_all(dir).map_err(|e| SolverError::io("creating directory", dir, e))?;
    let steps = step_count(scene.simulation.duration, sim.dt());
    let plan = RunPlan {
        duration: scene.simulation.duration,
        dt: sim.dt(),
        steps,
        bodies: sim.bodies().len(),
        nodes: sim.state().len(),
        elements: sim.bodies().iter().map(|b| b.elements.len()).sum(),
    };
    observer.start(&plan);
    let mut energy = CsvSeries::create(dir, "energy.csv", ENERGY_HEADER)?;
    let mut bodies = CsvSeries::create(dir, "bodies.csv", BODIES_HEADER)?;
    let mut walls = CsvSeries::create(dir, "walls.csv", WALLS_HEADER)?;
    let mut vtk = if options.vtk {
        Some(VtkSeries::create(dir)?)
    } else {
        None
    };

    let interval = scene.output_interval();
    let wall = Instant::now();
    let cpu = cpu_time::ProcessTime::try_now().ok();
    let mut outputs = 0usize;
    let mut max_rel = 0.0f64;
    let mut next_output = 0.0;
    let contacts = options.contacts;
    let mut write_output = |sim: &Simulation,
                            energy: &mut CsvSeries,
                            bodies: &mut CsvSeries,
                            walls: &mut CsvSeries,
                            vtk: &mut Option<VtkSeries>|
     -> Result<(), SolverError> {
        let e = sim.check_energy()?;
        max_rel = max_rel.max(sim.relative_balance_error(&e));
        energy.row(&energy_row(&e))?;
        body_rows(sim, bodies)?;
        wall_rows(sim, walls)?;
        if contacts {
            contact_snapshot(sim, dir, outputs)?;
        }
        if let Some(v) = vtk.as_mut() {
            v.frame(sim)?;
        }
        outputs += 1;
        Ok(())
    };

    let mut outcome: Result<(), SolverError> = Ok(());
    // Output at t = 0, then step.
    outcome =
        outcome.and_then(|_| write_output(&sim, &mut energy, &mut bodies, &mut walls, &mut vtk));
    next_output += interval;
    while outcome.is_ok() && sim.step() < steps {
        if interrupt.load(Ordering::Relaxed) {
            outcome = Err(SolverError::Interrupted {
                time: sim.time(),
                step: sim.step(),
            });
            break;
        }
        outcome = sim.advance();
        if outcome.is_err() {
            break;
        }
        let last = sim.step() == steps;
        if last || sim.time() >= next_output - 0.5 * sim.dt() {
            outcome = write_output(&sim, &mut energy, &mut bodies, &mut walls, &mut vtk);
            while next_output <= sim.time() + 0.5 * sim.dt() {
                next_output += interval;
            }
            observer.progress(sim.time(), sim.step());
        }
    }
    let wall_seconds = wall.elapsed().as_secs_f64();
    let cpu_seconds = cpu.map_or(f64::NAN, |c| c.elapsed().as_secs_f64());
    let status = match &outcome {
        Ok(()) => "completed",
        Err(SolverError::Unstable { .. }) => "unstable",
        Err(SolverError::Interrupted { .. }) => "interrupted",
        Err(_) => "failed",
    };
    let summary = RunSummary {
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
        outputs,
        max_relative_balance_error: max_rel,
        wall_seconds,
        cpu_seconds,
        threads: rayon::current_num_threads(),
    };
    energy.finish()?;
    bodies.finish()?;
    walls.finish()?;
    let json = serde_json::to_string_pretty(&summary)
        .map_err(|e| SolverError::InvalidScene(format!("serializing the summary: {e}")))?;
    write_atomically(&dir.join("summary.json"), &json)?;
    outcome.map(|()| summary)
}
