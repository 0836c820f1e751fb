//! The triaxial test, end to end: consolidation under the confining pressure with a
//! servo-controlled top platen, shear at constant platen velocity to the target axial
//! strain, and the outputs (docs/TRIAXIAL.md): `consolidation.csv`, `curve.csv`,
//! `summary.json`, `contacts_peak.csv`, `pairs_peak.csv`, `eta.svg`, `eps_v.svg` and,
//! on request, ParaView frames.

use crate::checkpoint::{CHECKPOINT_FILE, Stage, TestCheckpoint};
use crate::jumps::{JumpTally, JumpTotal};
use crate::loading::{TEST_WALL_MEMBRANE, TestModel};
use crate::measure::{
    CurvePoint, CurveSummary, CurveWriter, LateralSummary, Measurement, PeakTracker, Reference,
    hoop_strain, membrane_radial_force, summarize, summarize_lateral,
};
use crate::plot::{CurvePlot, CurveSeries, plot_curves};
use crate::{PreparedSpecimen, TriaxialError, reference_force, unbalanced_force_ratio};
use fdem_core::number::Number;
use fdem_mesh::vtu::{CellNodes, VtuField, VtuFrame, write_pvd, write_vtu};
use fdem_solver::output::{BoundaryBody, VtkSeries, contact_snapshot_text, write_atomically};
use fdem_solver::{EnergyReport, Simulation};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Steps timed before the cost estimate is made.
const CALIBRATION_STEPS: u64 = 200;
/// Curve rows between two ParaView frames (with `vtk`).
const ROWS_PER_FRAME: usize = 10;
/// Steps between two progress reports.
const PROGRESS_STEPS: u64 = 250;

/// Where and what to write.
#[derive(Clone, Debug)]
pub struct TestOptions {
    /// Output directory (created).
    pub out_dir: PathBuf,
    /// Write ParaView frames of particles, membrane and platens.
    pub vtk: bool,
    /// Time step (s); default the preparation's.
    pub dt: Option<f64>,
    /// Log every contact whose stored energy jumps by more than this (J) in one step to
    /// `energy_jumps.csv`, with totals per phase and cause in the summary
    /// (docs/TRIAXIAL.md, "Energy balance"); `None` (the default) logs nothing.
    pub energy_jumps: Option<f64>,
    /// Write a checkpoint ([`CHECKPOINT_FILE`] in `out_dir`) every this many wall-clock
    /// seconds and when interrupted, so that [`TestOptions::resume`] continues the test
    /// bit for bit; `None` writes none. Ignored with `vtk` or `energy_jumps`, whose
    /// outputs a resumed run does not continue.
    pub checkpoint_interval: Option<f64>,
    /// Continue from the checkpoint in `out_dir` when there is one (of this definition;
    /// one of another is an error); without one the test starts from its beginning.
    pub resume: bool,
}

impl TestOptions {
    /// Test into `out_dir` with the defaults: no frames, the preparation's step, no
    /// jump log, no checkpoints, no resume.
    pub fn new(out_dir: impl Into<PathBuf>) -> TestOptions {
        TestOptions {
            out_dir: out_dir.into(),
            vtk: false,
            dt: None,
            energy_jumps: None,
            checkpoint_interval: None,
            resume: false,
        }
    }

    /// The checkpoint interval (s) when checkpoints can be written.
    fn checkpoints(&self) -> Option<f64> {
        self.checkpoint_interval
            .filter(|_| !self.vtk && self.energy_jumps.is_none())
    }
}

/// The two stages of the test.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TestPhase {
    /// Step 1: isotropic consolidation to sigma_0.
    Consolidation,
    /// Step 2: shear at constant platen velocity.
    Shear,
}

impl TestPhase {
    /// Name used in reports.
    pub fn name(self) -> &'static str {
        match self {
            TestPhase::Consolidation => "consolidation",
            TestPhase::Shear => "shear",
        }
    }
}

/// What the test will cost, announced before the long work starts.
#[derive(Clone, Debug, Default, Serialize)]
pub struct TestPlan {
    /// Particles, particle nodes and elements.
    pub particles: usize,
    /// Nodes of the particles.
    pub particle_nodes: usize,
    /// Elements of the particles.
    pub elements: usize,
    /// Nodes of the membrane.
    pub membrane_nodes: usize,
    /// Time step (s) and the bound it respects.
    pub dt: f64,
    /// Smallest stable bound of the assembled test (s) and what sets it.
    pub dt_bound: f64,
    /// What sets the bound.
    pub dt_bound_source: String,
    /// Contact margin (m): Verlet skin and tunnelling scale against the membrane.
    pub contact_margin: f64,
    /// Contact depth limit (m) at the start; a contact deeper than half of it grows it
    /// (within its cap; the summary's `final_depth_limit`).
    pub depth_limit: f64,
    /// Platen velocity of the shear (m/s).
    pub loading_velocity: f64,
    /// Inertial number of the shear with the specimen's largest size.
    pub inertial_number: f64,
    /// Most steps consolidation may take.
    pub consolidation_steps_max: u64,
    /// Steps of the shear.
    pub shear_steps: u64,
    /// Measured wall-clock seconds per step (first steps of consolidation).
    pub seconds_per_step: f64,
    /// Estimated wall-clock seconds of the shear plus the longest consolidation.
    pub estimated_seconds_max: f64,
    /// Estimated wall-clock seconds of the shear alone.
    pub estimated_shear_seconds: f64,
    /// Measured wall-clock seconds per step over the shear's first steps: the consolidated
    /// specimen's contact network, which a loose packing's first steps do not yet carry
    /// (null until measured, and after a resume past those steps).
    pub shear_seconds_per_step: f64,
    /// The shear's estimate from `shear_seconds_per_step`.
    pub reestimated_shear_seconds: f64,
}

/// Progress of a phase.
#[derive(Clone, Debug)]
pub struct TestStatus {
    /// The phase.
    pub phase: TestPhase,
    /// Steps done in the phase.
    pub steps: u64,
    /// Steps planned for the phase (the most it may take for consolidation).
    pub planned_steps: u64,
    /// Axial strain from the start of shear (0 during consolidation).
    pub eps_a: f64,
    /// Axial stress over sigma_0.
    pub stress_ratio: f64,
    /// Stress ratio eta (shear).
    pub eta: f64,
}

/// Receives the plan and progress of a test; returning `false` from `progress` stops the
/// test as interrupted.
pub trait TestObserver {
    /// The test's run identifier, once, when the model is built and the outputs are
    /// about to start. The default writes `run ID` on stderr (the line `fdem triaxial`
    /// shows); [`SilentTest`] says nothing.
    fn run_id(&mut self, run_id: &str) {
        eprintln!("run {run_id}");
    }
    /// The cost estimate, once, after the first steps.
    fn plan(&mut self, _plan: &TestPlan) {}
    /// The shear's estimate again, once, after its own first steps
    /// (`shear_seconds_per_step`, `reestimated_shear_seconds`).
    fn shear_plan(&mut self, _plan: &TestPlan) {}
    /// A phase starts.
    fn phase(&mut self, _phase: TestPhase, _planned_steps: u64) {}
    /// Progress, every few hundred steps.
    fn progress(&mut self, _status: &TestStatus) -> bool {
        true
    }
}

/// An observer that ignores everything.
#[derive(Clone, Copy, Debug, Default)]
pub struct SilentTest;

impl TestObserver for SilentTest {
    fn run_id(&mut self, _run_id: &str) {}
}

/// Cost of one phase.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PhaseCost {
    /// Steps taken.
    pub steps: u64,
    /// Simulated time (s).
    pub simulated_time: f64,
    /// Wall-clock seconds.
    pub wall_seconds: f64,
    /// CPU seconds of the process (all threads), when the platform reports them.
    pub cpu_seconds: Option<f64>,
}

/// How consolidation ended.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ConsolidationResult {
    /// The criterion held.
    pub reached: bool,
    /// Axial stress over sigma_0 at the end.
    pub stress_ratio: f64,
    /// Unbalanced-force ratio at the end.
    pub unbalanced_force: f64,
    /// Kinetic over stored energy at the end.
    pub kinetic_ratio: f64,
    /// Criterion: `|sigma_l / sigma_0 - 1| <=` this.
    pub stress_tolerance: f64,
    /// Criterion: unbalanced-force ratio limit.
    pub unbalanced_force_limit: f64,
    /// Criterion: kinetic-energy ratio limit.
    pub kinetic_ratio_limit: f64,
    /// Volumetric strain rate at the end over the shear's axial strain rate v / H.
    pub volume_rate: f64,
    /// Criterion: volume-rate limit.
    pub volume_rate_limit: f64,
    /// Largest overshoot of the axial stress above sigma_0, over sigma_0.
    pub max_overshoot: f64,
    /// Lateral stress the membrane applies (measured from its contacts with the
    /// particles) over sigma_0 at the end.
    pub lateral_stress_ratio: f64,
    /// Volumetric strain of the consolidation at its end (eq 13 from its start).
    pub eps_v: f64,
    /// The specimen's own part of it, inside the envelope of its outermost particles;
    /// `eps_v - eps_v_specimen` is the membrane's penetration into the surface voids
    /// (docs/TRIAXIAL.md, "Membrane penetration").
    pub eps_v_specimen: f64,
    /// Relative energy-balance error at the end of consolidation (the balance is rebased
    /// at the start of each phase).
    pub energy_balance_error: f64,
    /// Phase cost.
    pub cost: PhaseCost,
}

/// The `summary.json` of a test: it names the run, and the files beside it belong to
/// that run.
#[derive(Clone, Debug, Serialize)]
pub struct TestSummary {
    /// The run's identifier: `YYYYMMDDTHHMMSSZ-hhhhhhhh`, its UTC start and the hash of
    /// the specimen and test definition ([`fdem_core::run_id`]).
    pub run_id: String,
    /// `completed`, `interrupted` or `failed`.
    pub status: String,
    /// The failure, if any.
    pub failure: Option<String>,
    /// Test name.
    pub test: String,
    /// Particles (the key `fdem micro` reads the particle count from).
    pub bodies: usize,
    /// Coarse-graining factor h.
    pub coarse_graining: f64,
    /// Exact scaling applied.
    pub exact_scaling: bool,
    /// The specimen's particle model as asked for: `deformable`, `rigid` or `auto`.
    pub model: String,
    /// Per size class: diameter, count, the model used (`auto` resolved) and, for
    /// `auto`, the estimate behind the choice.
    pub classes: Vec<crate::ClassCount>,
    /// Counts and step.
    pub plan: TestPlan,
    /// Membrane divisions (around, along) and triangles.
    pub membrane_divisions: [usize; 2],
    /// The membrane's stress-free radius (m): the equal-area radius of its reference mesh.
    pub membrane_radius: f64,
    /// Confining pressure sigma_0 (Pa).
    pub confining_pressure: f64,
    /// Target axial strain.
    pub target_strain: f64,
    /// Consolidation.
    pub consolidation: ConsolidationResult,
    /// Shear cost.
    pub shear: PhaseCost,
    /// Peak, residual, contraction and dilation of the curve (None before any row).
    pub curve: Option<CurveSummary>,
    /// The measured lateral stress `sigma_r / sigma_0` over the shear (None before any row).
    pub lateral_stress: Option<LateralSummary>,
    /// Axial strain of the contact snapshot at the peak.
    pub peak_snapshot_eps_a: Option<f64>,
    /// Escape checks made (one per output row) and the most particles found outside.
    pub escape_checks: u64,
    /// Particles found outside the membrane at any check (the run stops at the first).
    pub particles_outside: usize,
    /// Node-to-membrane hits discarded as fold artefacts (deeper than half the contact
    /// margin), summed over the evaluations at the outputs, and the most in one of them.
    pub discarded_membrane_hits: u64,
    /// The most discarded hits in one output's evaluation.
    pub discarded_membrane_hits_max: u64,
    /// Deepest contact seen at the outputs (m), against half the depth limit.
    pub max_contact_depth: f64,
    /// The depth limit at the end (m): the plan's, or larger where a deeper contact grew
    /// it (up to `TEST_DEPTH_LIMIT_CAP_DIAMETERS` of the smallest particle diameter).
    #[serde(default)]
    pub final_depth_limit: f64,
    /// The step at the end (s): the plan's, or smaller where the rigid bodies' contact
    /// network lowered it (`fdem_solver::Simulation::network_bound`), and what set it.
    #[serde(default)]
    pub final_dt: f64,
    /// What set `final_dt`: the plan's bound or the contact network.
    #[serde(default)]
    pub final_dt_source: String,
    /// Relative energy-balance error at the end.
    pub energy_balance_error: f64,
    /// With `TestOptions::energy_jumps`: the stored-energy jumps per phase and cause.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy_jumps: Option<Vec<JumpTotal>>,
    /// The energy balance at the end (J): kinetic, strain, other stored (contact springs,
    /// membrane), dissipated by damping and friction, external work, balance error.
    pub energy: EnergyReport,
    /// Worker threads.
    pub threads: usize,
    /// Files written.
    pub outputs: Vec<String>,
}

fn cpu_now() -> Option<cpu_time::ProcessTime> {
    cpu_time::ProcessTime::try_now().ok()
}

/// A stage's cost: `steps` over simulated `time`, the seconds since `wall` and `cpu`
/// plus the `prior` wall and CPU seconds of the stage before a resume.
fn cost(
    steps: u64,
    time: f64,
    (wall, cpu): (Instant, Option<cpu_time::ProcessTime>),
    prior: [f64; 2],
) -> PhaseCost {
    PhaseCost {
        steps,
        simulated_time: time,
        wall_seconds: prior[0] + wall.elapsed().as_secs_f64(),
        cpu_seconds: cpu
            .and_then(|c| c.try_elapsed().ok())
            .map(|d| prior[1] + d.as_secs_f64()),
    }
}

/// The consolidation's result as numbers, for a checkpoint (the limits come from the
/// definition).
fn consolidation_numbers(r: &ConsolidationResult) -> Vec<f64> {
    vec![
        f64::from(u8::from(r.reached)),
        r.stress_ratio,
        r.unbalanced_force,
        r.kinetic_ratio,
        r.volume_rate,
        r.max_overshoot,
        r.lateral_stress_ratio,
        r.eps_v,
        r.eps_v_specimen,
        r.energy_balance_error,
        r.cost.steps as f64,
        r.cost.simulated_time,
        r.cost.wall_seconds,
        r.cost.cpu_seconds.unwrap_or(f64::NAN),
    ]
}

/// Restores [`consolidation_numbers`] into `r`.
fn restore_consolidation(r: &mut ConsolidationResult, n: &[f64]) -> Result<(), String> {
    let [
        reached,
        stress,
        unbalanced,
        kinetic,
        volume,
        overshoot,
        lateral,
        eps_v,
        eps_v_specimen,
        balance,
        steps,
        time,
        wall,
        cpu,
    ] = <[f64; 14]>::try_from(n).map_err(|_| "section `test.consolidation` is not a result")?;
    r.reached = reached != 0.0;
    (r.stress_ratio, r.unbalanced_force, r.kinetic_ratio) = (stress, unbalanced, kinetic);
    (r.volume_rate, r.max_overshoot) = (volume, overshoot);
    (r.lateral_stress_ratio, r.energy_balance_error) = (lateral, balance);
    (r.eps_v, r.eps_v_specimen) = (eps_v, eps_v_specimen);
    r.cost = PhaseCost {
        steps: steps as u64,
        simulated_time: time,
        wall_seconds: wall,
        cpu_seconds: cpu.is_finite().then_some(cpu),
    };
    Ok(())
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> TriaxialError + '_ {
    move |e| TriaxialError::io("writing", path, e)
}

fn out(e: fdem_solver::SolverError) -> TriaxialError {
    TriaxialError::Test {
        phase: "output",
        message: e.to_string(),
    }
}

/// The running test: model, outputs and bookkeeping.
struct Run<'a> {
    model: TestModel,
    prepared: &'a PreparedSpecimen,
    options: &'a TestOptions,
    sigma_0: f64,
    reference_force: f64,
    vtk: Option<VtkSeries>,
    boundary_frames: Vec<(f64, String)>,
    escape_checks: u64,
    discarded: (u64, u64),
    max_depth: f64,
    energy: EnergyWindows,
    jumps: Option<JumpTally>,
    /// The definition as TOML (what a checkpoint belongs to).
    definition: String,
    /// When the last checkpoint was written (or the run started).
    last_checkpoint: Instant,
    /// Wall and CPU seconds the current stage took before this process (a resumed run).
    prior_seconds: [f64; 2],
}

/// The energy balance of a phase, checked by the solver's guard over windows (between
/// two outputs) and accumulated here (docs/TRIAXIAL.md, "Energy balance").
#[derive(Clone, Copy, Debug, Default)]
struct EnergyWindows {
    /// Kinetic plus stored energy at the start of the phase (J).
    initial: f64,
    /// Sums over the closed windows (J).
    error: f64,
    work: f64,
    damping: f64,
    friction: f64,
}

impl EnergyWindows {
    /// The sums as numbers (initial, error, work, damping, friction), for a checkpoint.
    fn numbers(&self) -> [f64; 5] {
        [
            self.initial,
            self.error,
            self.work,
            self.damping,
            self.friction,
        ]
    }

    /// The windows of [`EnergyWindows::numbers`].
    fn from_numbers([initial, error, work, damping, friction]: [f64; 5]) -> EnergyWindows {
        EnergyWindows {
            initial,
            error,
            work,
            damping,
            friction,
        }
    }

    /// Starts a phase: the guard's reference is the current state.
    fn start(sim: &mut Simulation) -> EnergyWindows {
        sim.reset_energy_reference();
        let e = sim.energy();
        EnergyWindows {
            initial: e.kinetic + e.strain + e.other_potential,
            ..EnergyWindows::default()
        }
    }

    /// Closes a window: adds its terms, and the guard measures from the current state on.
    fn close(&mut self, sim: &mut Simulation) {
        let e = sim.energy();
        self.error += e.balance_error;
        self.work += e.external_work;
        self.damping += e.damping_dissipated;
        self.friction += e.friction_dissipated;
        sim.reset_energy_reference();
    }

    /// The phase's accumulated balance error over its energy scale (the largest of the
    /// initial energy, the external work and the dissipation), as the guard measures one
    /// window.
    fn relative(&self) -> f64 {
        let scale = self
            .initial
            .abs()
            .max(self.work.abs())
            .max((self.damping + self.friction).abs())
            .max(f64::MIN_POSITIVE);
        self.error.abs() / scale
    }

    /// The phase's accumulated balance, with the current energies of `sim`.
    fn report(&self, sim: &Simulation) -> EnergyReport {
        let e = sim.energy();
        EnergyReport {
            damping_dissipated: self.damping + e.damping_dissipated,
            friction_dissipated: self.friction + e.friction_dissipated,
            external_work: self.work + e.external_work,
            dissipated: self.damping + self.friction + e.dissipated,
            balance_error: self.error + e.balance_error,
            ..e
        }
    }
}

impl Run<'_> {
    /// Writes a checkpoint of the test at `stage` with the stage's CSV `rows` so far,
    /// when checkpoints are on and `now` or the interval since the last one has passed.
    fn checkpoint(
        &mut self,
        summary: &TestSummary,
        stage: Stage,
        rows: &[CurvePoint],
        peak: Option<&(String, String)>,
        started: (Instant, Option<cpu_time::ProcessTime>),
        now: bool,
    ) -> Result<(), TriaxialError> {
        let Some(interval) = self.options.checkpoints() else {
            return Ok(());
        };
        if !now && self.last_checkpoint.elapsed().as_secs_f64() < interval {
            return Ok(());
        }
        let spent = cost(0, 0.0, started, self.prior_seconds);
        let checkpoint = TestCheckpoint {
            definition: self.definition.clone(),
            sim: self.model.sim.checkpoint(),
            pressure: self.model.pressure(),
            stage,
            rows: rows.to_vec(),
            outputs: [
                self.escape_checks as f64,
                self.discarded.0 as f64,
                self.discarded.1 as f64,
                self.max_depth,
            ],
            energy: self.energy.numbers(),
            consolidation: consolidation_numbers(&summary.consolidation),
            seconds: [spent.wall_seconds, spent.cpu_seconds.unwrap_or(0.0)],
            peak: peak.map(|(n, p)| {
                (
                    n.clone(),
                    p.clone(),
                    summary.peak_snapshot_eps_a.unwrap_or(f64::NAN),
                )
            }),
        };
        checkpoint.write(&self.options.out_dir.join(CHECKPOINT_FILE))?;
        self.last_checkpoint = Instant::now();
        Ok(())
    }

    /// Restores the bookkeeping and the simulation of checkpoint `c` (its stage is
    /// continued by the stage's loop).
    fn restore(
        &mut self,
        c: &TestCheckpoint,
        summary: &mut TestSummary,
    ) -> Result<(), TriaxialError> {
        let path = self.options.out_dir.join(CHECKPOINT_FILE);
        let bad = |why: String| {
            TriaxialError::file(
                &path,
                format!("{why}; delete it to run the test from its start"),
            )
        };
        self.model
            .sim
            .restore_checkpoint(&c.sim)
            .map_err(|e| bad(e.to_string()))?;
        self.model.set_pressure(c.pressure);
        self.model.follow_platens()?;
        let [checks, discarded, most, depth] = c.outputs;
        self.escape_checks = checks as u64;
        self.discarded = (discarded as u64, most as u64);
        self.max_depth = depth;
        self.energy = EnergyWindows::from_numbers(c.energy);
        restore_consolidation(&mut summary.consolidation, &c.consolidation).map_err(bad)?;
        self.prior_seconds = c.seconds;
        Ok(())
    }

    /// Moves the contact model's logged stored-energy jumps of the last step into the
    /// tally, while the log is on.
    fn log_jumps(&mut self, phase: &'static str) -> Result<(), TriaxialError> {
        let Some(tally) = self.jumps.as_mut() else {
            return Ok(());
        };
        let time = self.model.sim.time();
        let Some(contact) = self.model.sim.contact_mut() else {
            return Ok(());
        };
        let jumps = contact.model_mut().take_energy_jumps();
        if jumps.is_empty() {
            return Ok(());
        }
        let path = self.options.out_dir.join("energy_jumps.csv");
        tally.add(phase, time, &jumps).map_err(io(&path))
    }

    fn measurement(&self) -> Measurement {
        let sim = &self.model.sim;
        let energy = sim.energy();
        Measurement {
            time: sim.time(),
            height: self.model.height(),
            volume: self.model.volume(),
            axial_force: self.model.axial_force(),
            kinetic_energy: energy.kinetic,
            unbalanced_force: unbalanced_force_ratio(sim, self.reference_force),
            energy_error: self.energy.relative(),
            max_depth: sim.contact().map_or(0.0, |c| c.last_report().max_depth),
            contacts: sim.contact().map_or(0, |c| c.model().node_contacts().len()) as u64,
            step: sim.step(),
            lateral_force: sim.contact().map_or(0.0, |c| {
                membrane_radial_force(c.model().node_contacts(), self.model.membrane_body())
            }),
            hoop_strain: self.hoop_strain(),
            draped_volume: self.draped_volume(),
        }
    }

    /// The membrane's draped volume with the specimen's largest simulated diameter as
    /// the window: the widest surface void the sheet can sink into is between particles
    /// about that far apart (docs/TRIAXIAL.md, "Membrane penetration").
    fn draped_volume(&self) -> f64 {
        self.model
            .draped_volume(self.prepared.spec.largest_simulated_size())
    }

    /// Mean hoop strain of the membrane's free rings (all but the two held by the
    /// platens) from its stress-free mesh.
    fn hoop_strain(&self) -> f64 {
        let (membrane, spec) = (self.model.membrane(), &self.model.membrane_spec);
        let first = membrane.first_node();
        let nodes = &self.model.sim.state().positions[first..first + membrane.n_nodes()];
        let around = spec.divisions_around;
        let reference =
            2.0 * around as f64 * spec.node_radius() * (std::f64::consts::PI / around as f64).sin();
        hoop_strain(nodes, around, 1..spec.divisions_along, reference)
    }

    /// Axial stress over sigma_0 from the platen force and the current V/H.
    fn stress_ratio(&self) -> f64 {
        let sigma = crate::measure::axial_stress(
            self.model.axial_force(),
            self.model.volume(),
            self.model.height(),
        );
        sigma / self.sigma_0
    }

    fn check_escape(&mut self, phase: &'static str) -> Result<(), TriaxialError> {
        self.escape_checks += 1;
        if let Some(c) = self.model.sim.contact() {
            let report = c.last_report();
            let n = report.discarded_sheet_hits as u64;
            self.discarded = (self.discarded.0 + n, self.discarded.1.max(n));
            self.max_depth = self.max_depth.max(report.max_depth);
        }
        let outside = self.model.particles_outside();
        if let Some(first) = outside.first() {
            return Err(TriaxialError::Test {
                phase,
                message: format!(
                    "{} particle(s) left the membrane (first: particle {first}) at step {}, \
                     time {:e} s; refine the membrane (membrane.divisions_around) or raise \
                     contact.normal_penalty",
                    outside.len(),
                    self.model.sim.step(),
                    self.model.sim.time()
                ),
            });
        }
        Ok(())
    }

    fn frame(&mut self) -> Result<(), TriaxialError> {
        let Some(vtk) = self.vtk.as_mut() else {
            return Ok(());
        };
        vtk.frame(&self.model.sim).map_err(out)?;
        // Membrane and platens as triangles in one file per frame.
        let sim = &self.model.sim;
        let mut points: Vec<[f64; 3]> = Vec::new();
        let mut cells: Vec<usize> = Vec::new();
        let mut part: Vec<f64> = Vec::new();
        let first = self.model.membrane().first_node();
        let n = self.model.membrane().n_nodes();
        points.extend_from_slice(&sim.state().positions[first..first + n]);
        for t in &self.model.membrane_triangles {
            cells.extend(t.iter().map(|i| i - first));
            part.push(0.0);
        }
        let r = 1.05 * self.model.membrane_spec.radius;
        for (k, z) in [
            self.model.platen_z(crate::loading::TEST_WALL_BOTTOM),
            self.model.platen_z(crate::loading::TEST_WALL_TOP),
        ]
        .into_iter()
        .enumerate()
        {
            let centre = points.len();
            points.push([0.0, 0.0, z]);
            let segments = 48;
            for s in 0..segments {
                let a = std::f64::consts::TAU * s as f64 / segments as f64;
                points.push([r * a.cos(), r * a.sin(), z]);
            }
            for s in 0..segments {
                cells.extend([centre, centre + 1 + s, centre + 1 + (s + 1) % segments]);
                part.push(1.0 + k as f64);
            }
        }
        let dir = self.options.out_dir.join("frames");
        let name = format!("boundary_{:06}.vtu", self.boundary_frames.len());
        let frame = VtuFrame {
            points: &points,
            cells: &cells,
            cell_nodes: CellNodes::Uniform(3),
            point_fields: vec![],
            cell_fields: vec![VtuField {
                name: "part",
                components: 1,
                values: &part,
            }],
        };
        let err = |e: fdem_mesh::MeshError| TriaxialError::Test {
            phase: "output",
            message: e.to_string(),
        };
        write_vtu(&dir.join(&name), &frame).map_err(err)?;
        self.boundary_frames
            .push((sim.time(), format!("frames/{name}")));
        write_pvd(
            &self.options.out_dir.join("boundary.pvd"),
            &self.boundary_frames,
        )
        .map_err(err)
    }

    fn snapshot(&self) -> Option<(String, String)> {
        contact_snapshot_text(
            &self.model.sim,
            Some(BoundaryBody {
                body: self.model.membrane_body(),
                as_wall: TEST_WALL_MEMBRANE,
            }),
        )
    }
}

/// Refuses a plan of more steps than a run may take ([`fdem_solver::MAX_STEPS`], as for
/// scenes), before the first step: a step far below the stable bound (a tiny
/// `test.dt_safety`) would otherwise plan up to 2^64 steps.
fn check_plan(plan: &TestPlan) -> Result<(), TriaxialError> {
    let steps = plan
        .consolidation_steps_max
        .saturating_add(plan.shear_steps);
    if steps <= fdem_solver::MAX_STEPS {
        return Ok(());
    }
    Err(TriaxialError::Test {
        phase: "plan",
        message: format!(
            "the test would take {steps} steps of {:e} s (more than the {} a run may plan); \
             the step is test.dt_safety times the stable bound {:e} s set by {}: raise \
             test.dt_safety (default {})",
            plan.dt,
            fdem_solver::MAX_STEPS,
            plan.dt_bound,
            plan.dt_bound_source,
            crate::TEST_DT_SAFETY
        ),
    })
}

/// The summary before the first step: the plan (steps, step, bound, contact lengths) and
/// the test's settings; the results are filled in as the test runs.
fn initial_summary(run: &Run<'_>, run_id: String) -> TestSummary {
    let (spec, model, sigma_0) = (&run.prepared.spec, &run.model, run.sigma_0);
    let test = &spec.test;
    let velocity = spec.loading_velocity();
    let dt = model.sim.dt();
    let height = spec.height;
    let consolidation_time = test.consolidation_time.unwrap_or(0.1 * height / velocity);
    let consolidation_steps_max = (consolidation_time / dt).ceil() as u64;
    let shear_steps = spec.shear_steps(dt);
    let membrane = &model.membrane_spec;
    let bound = model.sim.network_bound().unwrap_or(model.sim.bound());
    TestSummary {
        run_id,
        status: "running".into(),
        failure: None,
        test: spec.name.clone(),
        bodies: model.particles,
        coarse_graining: spec.coarse_graining,
        exact_scaling: spec.exact_scaling,
        model: spec.model.name().into(),
        // The counts were computed when the model was built.
        classes: spec.counts().map(|c| c.classes).unwrap_or_default(),
        plan: TestPlan {
            particles: model.particles,
            particle_nodes: model.membrane().first_node(),
            elements: model.elements,
            membrane_nodes: model.membrane().n_nodes(),
            dt,
            // What sets the step: the contact network of the rigid bodies where it lowered
            // the step below the model's bound, else that bound.
            dt_bound: bound.dt,
            dt_bound_source: bound.source.clone(),
            contact_margin: model.sim.contact().map_or(f64::NAN, |c| c.model().margin()),
            depth_limit: model
                .sim
                .contact()
                .map_or(f64::NAN, |c| c.model().depth_limit()),
            loading_velocity: velocity,
            inertial_number: spec.inertial_number(),
            consolidation_steps_max,
            shear_steps,
            seconds_per_step: f64::NAN,
            estimated_seconds_max: f64::NAN,
            estimated_shear_seconds: f64::NAN,
            shear_seconds_per_step: f64::NAN,
            reestimated_shear_seconds: f64::NAN,
        },
        membrane_divisions: [membrane.divisions_around, membrane.divisions_along],
        membrane_radius: membrane.radius,
        confining_pressure: sigma_0,
        target_strain: test.target_strain,
        consolidation: ConsolidationResult {
            stress_tolerance: test.stress_tolerance,
            unbalanced_force_limit: test.unbalanced_force,
            kinetic_ratio_limit: test.kinetic_ratio,
            volume_rate_limit: test.volume_rate,
            ..ConsolidationResult::default()
        },
        shear: PhaseCost::default(),
        curve: None,
        lateral_stress: None,
        peak_snapshot_eps_a: None,
        escape_checks: 0,
        particles_outside: 0,
        discarded_membrane_hits: 0,
        discarded_membrane_hits_max: 0,
        max_contact_depth: 0.0,
        final_depth_limit: f64::NAN,
        final_dt: f64::NAN,
        final_dt_source: String::new(),
        energy_balance_error: 0.0,
        energy_jumps: None,
        energy: EnergyReport::default(),
        threads: rayon::current_num_threads(),
        outputs: Vec::new(),
    }
}

/// The files a test writes into its directory, cleared at its start.
const TEST_OUTPUTS: &[&str] = &[
    CHECKPOINT_FILE,
    "consolidation.csv",
    "curve.csv",
    "energy_jumps.csv",
    "contacts_peak.csv",
    "pairs_peak.csv",
    "eta.svg",
    "eps_v.svg",
    "frames.pvd",
    "boundary.pvd",
    "summary.json",
];

/// The numbered series a test writes, `(folder, file prefix)`, cleared at its start.
const TEST_SERIES: &[(&str, &str)] = &[("frames", "frame_"), ("frames", "boundary_")];

/// Runs the triaxial test on a prepared specimen (consolidation, then shear) and writes
/// its outputs into `options.out_dir`. Stops early, with complete outputs and a summary
/// marked `interrupted`, when `interrupt` is set or the observer asks to.
///
/// # Errors
/// A set-up the membrane or step refuses, a solver error, a particle escaping the
/// membrane, a consolidation that does not reach its criterion in time, or an output that
/// cannot be written. Outputs written so far stay complete, and the summary records the
/// failure.
pub fn run_test(
    prepared: &PreparedSpecimen,
    options: &TestOptions,
    observer: &mut dyn TestObserver,
    interrupt: &AtomicBool,
) -> Result<TestSummary, TriaxialError> {
    let spec = &prepared.spec;
    // The definition as TOML, every key written out: the same test gives the same hash.
    let definition = spec.to_toml_string()?;
    let run_id = fdem_core::run_id::run_id(definition.as_bytes(), std::time::SystemTime::now());
    let dir = &options.out_dir;
    std::fs::create_dir_all(dir).map_err(|e| TriaxialError::io("creating directory", dir, e))?;
    let saved = saved_checkpoint(options, &definition)?;
    let model = TestModel::build(prepared, options.dt)?;
    if saved.is_none() {
        // The directory is this test's: an earlier test's outputs go (the prepared
        // specimen kept there for reuse stays).
        fdem_core::fs::clear_outputs(dir, TEST_OUTPUTS, TEST_SERIES)
            .map_err(|e| TriaxialError::io("clearing the earlier outputs of", dir, e))?;
    }
    let sigma_0 = spec.confining_pressure;
    let d_min = spec.smallest_simulated_size();
    let mut model = model;
    let jumps = match options.energy_jumps {
        Some(threshold) => {
            if let Some(c) = model.sim.contact_mut() {
                c.model_mut()
                    .set_energy_jump_log(Some(threshold))
                    .map_err(|e| TriaxialError::Test {
                        phase: "setup",
                        message: e.to_string(),
                    })?;
            }
            let path = dir.join("energy_jumps.csv");
            Some(JumpTally::create(&path).map_err(io(&path))?)
        }
        None => None,
    };
    let vtk = if options.vtk {
        Some(VtkSeries::create(dir).map_err(out)?)
    } else {
        None
    };
    let mut run = Run {
        model,
        prepared,
        options,
        sigma_0,
        reference_force: reference_force(sigma_0, d_min),
        vtk,
        boundary_frames: Vec::new(),
        escape_checks: 0,
        discarded: (0, 0),
        max_depth: 0.0,
        energy: EnergyWindows::default(),
        jumps,
        definition,
        last_checkpoint: Instant::now(),
        prior_seconds: [0.0; 2],
    };
    let mut summary = initial_summary(&run, run_id);
    check_plan(&summary.plan)?;
    observer.run_id(&summary.run_id);
    let mut points: Vec<CurvePoint> = Vec::new();
    let mut peak: Option<(String, String)> = None;
    let resume = match saved {
        Some(c) => {
            run.restore(&c, &mut summary)?;
            if let Stage::Shear { .. } = c.stage {
                points.clone_from(&c.rows);
                summary.peak_snapshot_eps_a = c.peak.as_ref().map(|p| p.2);
                peak = c.peak.map(|(nodes, pairs, _)| (nodes, pairs));
            }
            Some((c.stage, c.rows))
        }
        None => None,
    };
    let result = stages(
        &mut run,
        &mut summary,
        (&mut points, &mut peak),
        observer,
        interrupt,
        resume,
    );
    // Whatever happened, finish the outputs so far.
    run.escape_checks = run.escape_checks.max(summary.escape_checks);
    summary.escape_checks = run.escape_checks;
    (
        summary.discarded_membrane_hits,
        summary.discarded_membrane_hits_max,
    ) = run.discarded;
    summary.max_contact_depth = run.max_depth;
    summary.final_depth_limit = run
        .model
        .sim
        .contact()
        .map_or(f64::NAN, |c| c.model().depth_limit());
    summary.final_dt = run.model.sim.dt();
    summary.final_dt_source = run
        .model
        .sim
        .network_bound()
        .unwrap_or(run.model.sim.bound())
        .source
        .clone();
    if let Some(tally) = run.jumps.as_mut() {
        let path = run.options.out_dir.join("energy_jumps.csv");
        summary.energy_jumps = Some(tally.finish().map_err(io(&path))?);
        summary.outputs.push("energy_jumps.csv".into());
    }
    summary.energy = run.energy.report(&run.model.sim);
    summary.energy_balance_error = {
        let mut windows = run.energy;
        windows.close(&mut run.model.sim);
        windows.relative()
    };
    if let Ok(true) = result {
        // Finished: nothing to resume.
        let path = dir.join(CHECKPOINT_FILE);
        if path.exists() {
            std::fs::remove_file(&path).map_err(|e| TriaxialError::io("removing", &path, e))?;
        }
    }
    match &result {
        Ok(true) => summary.status = "completed".into(),
        Ok(false) => summary.status = "interrupted".into(),
        Err(e) => {
            summary.status = "failed".into();
            summary.failure = Some(e.to_string());
        }
    }
    finish(&run, &mut summary, &points, peak.as_ref())?;
    result.map(|_| summary)
}

/// The checkpoint to resume from: with [`TestOptions::resume`], the one in the output
/// directory, which must be of `definition`; `None` when there is none.
fn saved_checkpoint(
    options: &TestOptions,
    definition: &str,
) -> Result<Option<TestCheckpoint>, TriaxialError> {
    let path = options.out_dir.join(CHECKPOINT_FILE);
    if !options.resume || !path.exists() {
        return Ok(None);
    }
    let saved = TestCheckpoint::read(&path)?;
    if saved.definition != definition {
        return Err(TriaxialError::file(
            &path,
            "is a checkpoint of another specimen or test definition; resume with the \
             definition that wrote it, or delete it to run this test from its start",
        ));
    }
    Ok(Some(saved))
}

/// Consolidation then shear, or the rest of a resumed stage (`resume`: the stage and
/// its CSV rows so far); `Ok(false)` when interrupted.
fn stages(
    run: &mut Run<'_>,
    summary: &mut TestSummary,
    (points, peak): (&mut Vec<CurvePoint>, &mut Option<(String, String)>),
    observer: &mut dyn TestObserver,
    interrupt: &AtomicBool,
    resume: Option<(Stage, Vec<CurvePoint>)>,
) -> Result<bool, TriaxialError> {
    let stop = |observer_ok: bool| !observer_ok || interrupt.load(Ordering::Relaxed);
    let shear_from = match resume {
        Some((stage @ Stage::Shear { .. }, _)) => {
            summary.outputs.push("consolidation.csv".into());
            Some(stage)
        }
        consolidation => {
            if !consolidate(run, summary, observer, &stop, consolidation)? {
                return Ok(false);
            }
            run.prior_seconds = [0.0; 2];
            None
        }
    };
    shear(run, summary, (points, peak), observer, &stop, shear_from)
}

fn solver(phase: &'static str) -> impl Fn(fdem_solver::SolverError) -> TriaxialError {
    move |e| TriaxialError::Test {
        phase,
        message: e.to_string(),
    }
}

/// The consolidation's target pressure: from the lateral stress the preparation left (at
/// most sigma_0) to sigma_0 over the ramp; the servo follows the same target.
#[derive(Clone, Copy, Debug)]
struct Ramp {
    t_start: f64,
    ramp_time: f64,
    start_pressure: f64,
    sigma_0: f64,
}

impl Ramp {
    fn at(&self, t: f64) -> f64 {
        let f = ((t - self.t_start) / self.ramp_time).clamp(0.0, 1.0);
        self.start_pressure + f * (self.sigma_0 - self.start_pressure)
    }
}

/// The consolidation's equilibrium measures between checks.
struct Equilibrium {
    ramp: Ramp,
    reference: Reference,
    strain_rate: f64,
    /// Time and volume of the previous check.
    last_volume: (f64, f64),
}

impl Equilibrium {
    /// The checkpoint stage of a consolidation at `steps`.
    fn stage(&self, steps: u64) -> Stage {
        let r = &self.ramp;
        Stage::Consolidation {
            steps,
            ramp: [r.t_start, r.ramp_time, r.start_pressure, r.sigma_0],
            last_volume: [self.last_volume.0, self.last_volume.1],
            reference: [self.reference.h0, self.reference.v0, self.reference.draped0],
        }
    }
}

/// Step 1: the pressure ramps up while a proportional servo on the top platen holds the
/// axial stress at the target; ends when every equilibrium criterion holds (`Ok(true)`),
/// when interrupted (`Ok(false)`) or when the planned steps run out (an error). `resume`
/// continues a checkpoint's consolidation (its stage and rows).
fn consolidate(
    run: &mut Run<'_>,
    summary: &mut TestSummary,
    observer: &mut dyn TestObserver,
    stop: &dyn Fn(bool) -> bool,
    resume: Option<(Stage, Vec<CurvePoint>)>,
) -> Result<bool, TriaxialError> {
    let test = run.prepared.spec.test.clone();
    let v_max = test.servo_speed * run.prepared.spec.loading_velocity();
    let started = (Instant::now(), cpu_now());
    let planned = summary.plan.consolidation_steps_max;
    observer.phase(TestPhase::Consolidation, planned);
    let log_path = run.options.out_dir.join("consolidation.csv");
    summary.outputs.push("consolidation.csv".into());
    let (mut watch, mut log, first_step) = match resume {
        Some((
            Stage::Consolidation {
                steps,
                ramp,
                last_volume,
                reference,
            },
            rows,
        )) => {
            let log = CurveWriter::with_rows(&log_path, &rows).map_err(io(&log_path))?;
            let watch = equilibrium_watch(run, ramp, reference, last_volume);
            (watch, ConsolidationLog { writer: log, rows }, steps)
        }
        _ => {
            let (log, watch) = start_consolidation(run, &log_path)?;
            (watch, log, 0)
        }
    };
    let mut steps = first_step;
    let outcome = loop {
        let pressure = watch.ramp.at(run.model.sim.time());
        run.model.set_pressure(pressure);
        let ratio = run.stress_ratio();
        let result = &mut summary.consolidation;
        result.max_overshoot = result.max_overshoot.max(ratio - 1.0);
        // Proportional servo, saturated: full speed at `servo_band` relative error.
        let error = (pressure / run.sigma_0 - ratio) / test.servo_band;
        run.model
            .set_top_velocity(-v_max * error.clamp(-1.0, 1.0))?;
        run.model.sim.advance().map_err(solver("consolidation"))?;
        run.log_jumps("consolidation")?;
        steps += 1;
        if steps == first_step + CALIBRATION_STEPS {
            calibrate(&mut summary.plan, started.0, steps - first_step);
            observer.plan(&summary.plan);
        }
        let check = steps.is_multiple_of(test.check_interval) || steps >= planned;
        if !check && !steps.is_multiple_of(PROGRESS_STEPS) {
            continue;
        }
        let ok = if check {
            let ok = check_equilibrium(
                run, &mut watch, summary, &mut log, &log_path, observer, steps,
            )?;
            if summary.consolidation.reached {
                break Ok(true);
            }
            ok
        } else {
            true
        };
        let stopping = stop(ok);
        let stage = watch.stage(steps);
        run.checkpoint(summary, stage, &log.rows, None, started, stopping)?;
        if stopping {
            break Ok(false);
        }
        if steps >= planned {
            break Err(no_equilibrium(
                &summary.consolidation,
                &test,
                steps,
                run.model.sim.dt(),
            ));
        }
    };
    summary.consolidation.cost = cost(
        steps,
        steps as f64 * run.model.sim.dt(),
        started,
        run.prior_seconds,
    );
    if let Ok(true) = outcome {
        run.energy.close(&mut run.model.sim);
        summary.consolidation.energy_balance_error = run.energy.relative();
    }
    outcome
}

/// The consolidation log: `consolidation.csv` and its rows so far (for checkpoints).
struct ConsolidationLog {
    writer: CurveWriter,
    rows: Vec<CurvePoint>,
}

/// The start of a consolidation: the first containment check and frame, the ramp from
/// the preparation's lateral stress, the forces and the energy reference at the
/// starting pressure, and the log.
fn start_consolidation(
    run: &mut Run<'_>,
    log_path: &Path,
) -> Result<(ConsolidationLog, Equilibrium), TriaxialError> {
    let spec = &run.prepared.spec;
    let velocity = spec.loading_velocity();
    run.check_escape("consolidation")?;
    run.frame()?;
    let log = CurveWriter::new(log_path).map_err(io(log_path))?;
    let ramp = [
        run.model.sim.time(),
        spec.test.ramp_time.unwrap_or(0.01 * spec.height / velocity),
        run.prepared.report.cylinder_stress.clamp(0.0, run.sigma_0),
        run.sigma_0,
    ];
    let (height, volume) = (run.model.height(), run.model.volume());
    let draped = run.draped_volume();
    let watch = equilibrium_watch(run, ramp, [height, volume, draped], [ramp[0], volume]);
    run.model.set_pressure(watch.ramp.at(watch.ramp.t_start));
    run.model
        .sim
        .rebase_energy()
        .map_err(solver("consolidation"))?;
    run.energy = EnergyWindows::start(&mut run.model.sim);
    let log = ConsolidationLog {
        writer: log,
        rows: Vec::new(),
    };
    Ok((log, watch))
}

/// The consolidation's watch from its numbers (a checkpoint's or a fresh start's): the
/// ramp (start, duration, start pressure, sigma_0), the height and volume at its start,
/// the time and volume of the last check.
fn equilibrium_watch(
    run: &Run<'_>,
    [t_start, ramp_time, start_pressure, sigma_0]: [f64; 4],
    [h0, v0, draped0]: [f64; 3],
    last_volume: [f64; 2],
) -> Equilibrium {
    let spec = &run.prepared.spec;
    Equilibrium {
        ramp: Ramp {
            t_start,
            ramp_time,
            start_pressure,
            sigma_0,
        },
        reference: Reference {
            h0,
            v0,
            sigma_0: run.sigma_0,
            draped0,
        },
        strain_rate: spec.loading_velocity() / spec.height,
        last_volume: (last_volume[0], last_volume[1]),
    }
}

/// The shear's estimate from its first `steps` steps' wall time.
fn recalibrate_shear(plan: &mut TestPlan, wall: Instant, steps: u64) {
    plan.shear_seconds_per_step = wall.elapsed().as_secs_f64() / steps as f64;
    plan.reestimated_shear_seconds = plan.shear_seconds_per_step * plan.shear_steps as f64;
}

/// The plan's cost estimate from the first `steps` steps' wall time.
fn calibrate(plan: &mut TestPlan, wall: Instant, steps: u64) {
    let per_step = wall.elapsed().as_secs_f64() / steps as f64;
    plan.seconds_per_step = per_step;
    plan.estimated_shear_seconds = per_step * plan.shear_steps as f64;
    plan.estimated_seconds_max =
        per_step * (plan.shear_steps + plan.consolidation_steps_max) as f64;
}

/// One consolidation check: closes the energy window, logs a row, checks containment and
/// evaluates the equilibrium criteria into `summary.consolidation`; returns whether the
/// observer wants to go on.
fn check_equilibrium(
    run: &mut Run<'_>,
    watch: &mut Equilibrium,
    summary: &mut TestSummary,
    log: &mut ConsolidationLog,
    log_path: &Path,
    observer: &mut dyn TestObserver,
    steps: u64,
) -> Result<bool, TriaxialError> {
    let test = &run.prepared.spec.test;
    run.energy.close(&mut run.model.sim);
    let m = run.measurement();
    let point = CurvePoint::from_measurement(&m, &watch.reference);
    log.writer.push(&point).map_err(io(log_path))?;
    log.rows.push(point);
    run.check_escape("consolidation")?;
    let e = run.model.sim.energy();
    let stored = e.strain + e.other_potential;
    let result = &mut summary.consolidation;
    result.stress_ratio = point.sigma_a / run.sigma_0;
    result.lateral_stress_ratio = point.sigma_r / run.sigma_0;
    (result.eps_v, result.eps_v_specimen) = (point.eps_v, point.eps_v_specimen);
    result.unbalanced_force = m.unbalanced_force;
    result.kinetic_ratio = if stored > 0.0 {
        e.kinetic / stored
    } else {
        f64::INFINITY
    };
    let (t_prev, v_prev) = watch.last_volume;
    let elapsed = (m.time - t_prev).max(f64::MIN_POSITIVE);
    result.volume_rate = (m.volume / v_prev).ln().abs() / elapsed / watch.strain_rate;
    watch.last_volume = (m.time, m.volume);
    result.reached = run.model.sim.time() - watch.ramp.t_start >= watch.ramp.ramp_time
        && result.volume_rate <= test.volume_rate
        && (result.stress_ratio - 1.0).abs() <= test.stress_tolerance
        && result.unbalanced_force <= test.unbalanced_force
        && result.kinetic_ratio <= test.kinetic_ratio;
    Ok(observer.progress(&TestStatus {
        phase: TestPhase::Consolidation,
        steps,
        planned_steps: summary.plan.consolidation_steps_max,
        eps_a: 0.0,
        stress_ratio: result.stress_ratio,
        eta: point.eta,
    }))
}

/// The error of a consolidation that found no equilibrium in its planned steps.
fn no_equilibrium(
    result: &ConsolidationResult,
    test: &crate::TestSection,
    steps: u64,
    dt: f64,
) -> TriaxialError {
    TriaxialError::Test {
        phase: "consolidation",
        message: format!(
            "no equilibrium after {steps} steps ({:e} s): axial stress {:.4} x \
             sigma_0 (tolerance {}), unbalanced force {:.3e} (limit {}), kinetic \
             ratio {:.3e} (limit {}), volume rate {:.3e} (limit {}); raise \
             test.consolidation_time or relax the limits",
            steps as f64 * dt,
            Number(result.stress_ratio),
            Number(test.stress_tolerance),
            result.unbalanced_force,
            Number(test.unbalanced_force),
            result.kinetic_ratio,
            Number(test.kinetic_ratio),
            result.volume_rate,
            Number(test.volume_rate)
        ),
    }
}

/// The shear's progress between outputs.
struct ShearCurve {
    reference: Reference,
    writer: CurveWriter,
    path: std::path::PathBuf,
    tracker: PeakTracker,
    /// Axial strain of the next output row.
    next_output: f64,
}

/// Step 2: shear at constant velocity to the target strain, a curve row every
/// `test.output_strain`; `Ok(false)` when interrupted. `resume` continues a
/// checkpoint's shear (`points` and `peak` then hold its rows and snapshot).
fn shear(
    run: &mut Run<'_>,
    summary: &mut TestSummary,
    (points, peak): (&mut Vec<CurvePoint>, &mut Option<(String, String)>),
    observer: &mut dyn TestObserver,
    stop: &dyn Fn(bool) -> bool,
    resume: Option<Stage>,
) -> Result<bool, TriaxialError> {
    let test = run.prepared.spec.test.clone();
    let started = (Instant::now(), cpu_now());
    let planned = summary.plan.shear_steps;
    let path = run.options.out_dir.join("curve.csv");
    summary.outputs.push("curve.csv".into());
    let (mut curve, first_step, t0) = match resume {
        Some(Stage::Shear {
            steps,
            t0,
            reference: [h0, v0, draped0],
            next_output,
        }) => {
            let mut tracker = PeakTracker::new();
            for p in points.iter() {
                tracker.observe(p.eta);
            }
            let curve = ShearCurve {
                writer: CurveWriter::with_rows(&path, points).map_err(io(&path))?,
                path,
                reference: Reference {
                    h0,
                    v0,
                    sigma_0: run.sigma_0,
                    draped0,
                },
                tracker,
                next_output,
            };
            (curve, steps, t0)
        }
        _ => {
            let curve = start_shear(run, summary, (points, peak), path)?;
            (curve, 0, run.model.sim.time())
        }
    };
    observer.phase(TestPhase::Shear, planned);
    let timed = Instant::now();
    let mut steps = first_step;
    let reference = curve.reference;
    // Errors leave the loop with the cost of the steps taken recorded.
    let outcome: Result<bool, TriaxialError> = loop {
        if let Err(e) = run.model.sim.advance() {
            break Err(solver("shear")(e));
        }
        if let Err(e) = run.log_jumps("shear") {
            break Err(e);
        }
        steps += 1;
        if steps == first_step + CALIBRATION_STEPS {
            recalibrate_shear(&mut summary.plan, timed, steps - first_step);
            observer.shear_plan(&summary.plan);
        }
        let eps_a = crate::measure::axial_strain(reference.h0, run.model.height());
        let done = eps_a >= test.target_strain;
        let status = if eps_a >= curve.next_output || done {
            match shear_output(run, &mut curve, summary, points, peak, eps_a) {
                Ok(point) => Some((point.sigma_a / run.sigma_0, point.eta)),
                Err(e) => break Err(e),
            }
        } else if steps.is_multiple_of(PROGRESS_STEPS) {
            Some((f64::NAN, points.last().map_or(f64::NAN, |p| p.eta)))
        } else {
            None
        };
        if let Some((stress_ratio, eta)) = status {
            let ok = observer.progress(&TestStatus {
                phase: TestPhase::Shear,
                steps,
                planned_steps: planned,
                eps_a,
                stress_ratio,
                eta,
            });
            // `done` always comes with an output row.
            if done {
                break Ok(true);
            }
            let stopping = stop(ok);
            let stage = Stage::Shear {
                steps,
                t0,
                reference: [reference.h0, reference.v0, reference.draped0],
                next_output: curve.next_output,
            };
            if let Err(e) = run.checkpoint(summary, stage, points, peak.as_ref(), started, stopping)
            {
                break Err(e);
            }
            if stopping {
                break Ok(false);
            }
        }
    };
    summary.shear = cost(steps, run.model.sim.time() - t0, started, run.prior_seconds);
    let completed = outcome?;
    if completed {
        run.frame()?;
    }
    Ok(completed)
}

/// The start of shear: the platen at the loading velocity, the balance afresh, the
/// reference state, the first curve row and the peak snapshot there.
fn start_shear(
    run: &mut Run<'_>,
    summary: &mut TestSummary,
    (points, peak): (&mut Vec<CurvePoint>, &mut Option<(String, String)>),
    path: PathBuf,
) -> Result<ShearCurve, TriaxialError> {
    run.model
        .set_top_velocity(-run.prepared.spec.loading_velocity())?;
    // The shear's balance starts afresh (docs/TRIAXIAL.md, "Energy balance").
    run.energy = EnergyWindows::start(&mut run.model.sim);
    let reference = Reference {
        h0: run.model.height(),
        v0: run.model.volume(),
        sigma_0: run.sigma_0,
        draped0: run.draped_volume(),
    };
    let mut curve = ShearCurve {
        writer: CurveWriter::new(&path).map_err(io(&path))?,
        path,
        reference,
        tracker: PeakTracker::new(),
        next_output: run.prepared.spec.test.output_strain,
    };
    let first = CurvePoint::from_measurement(&run.measurement(), &reference);
    curve.writer.push(&first).map_err(io(&curve.path))?;
    points.push(first);
    curve.tracker.observe(first.eta);
    *peak = run.snapshot();
    summary.peak_snapshot_eps_a = Some(first.eps_a);
    Ok(curve)
}

/// One shear output: closes the energy window, writes the curve row, follows the peak
/// (and its contact snapshot), checks containment and writes a frame every
/// [`ROWS_PER_FRAME`] rows.
fn shear_output(
    run: &mut Run<'_>,
    curve: &mut ShearCurve,
    summary: &mut TestSummary,
    points: &mut Vec<CurvePoint>,
    peak: &mut Option<(String, String)>,
    eps_a: f64,
) -> Result<CurvePoint, TriaxialError> {
    run.energy.close(&mut run.model.sim);
    let point = CurvePoint::from_measurement(&run.measurement(), &curve.reference);
    curve.writer.push(&point).map_err(io(&curve.path))?;
    points.push(point);
    if curve.tracker.observe(point.eta) {
        *peak = run.snapshot();
        summary.peak_snapshot_eps_a = Some(point.eps_a);
    }
    run.check_escape("shear")?;
    if points.len().is_multiple_of(ROWS_PER_FRAME) {
        run.frame()?;
    }
    while curve.next_output <= eps_a {
        curve.next_output += run.prepared.spec.test.output_strain;
    }
    Ok(point)
}

/// Writes the summary, the plots and the peak snapshot.
fn finish(
    run: &Run<'_>,
    summary: &mut TestSummary,
    points: &[CurvePoint],
    peak: Option<&(String, String)>,
) -> Result<(), TriaxialError> {
    let dir = &run.options.out_dir;
    summary.curve = summarize(points, run.prepared.spec.test.residual_window);
    summary.lateral_stress = summarize_lateral(points, run.sigma_0);
    if let Some((nodes, pairs)) = peak {
        write_atomically(&dir.join("contacts_peak.csv"), nodes).map_err(out)?;
        write_atomically(&dir.join("pairs_peak.csv"), pairs).map_err(out)?;
        summary.outputs.push("contacts_peak.csv".into());
        summary.outputs.push("pairs_peak.csv".into());
    }
    let name = &run.prepared.spec.name;
    let series = [CurveSeries {
        label: name,
        points,
    }];
    for (file, kind, title) in [
        ("eta.svg", CurvePlot::StressRatio, "stress ratio"),
        (
            "eps_v.svg",
            CurvePlot::VolumetricStrain,
            "volumetric strain",
        ),
    ] {
        let path = dir.join(file);
        plot_curves(&path, kind, &format!("{name}: {title}"), &series).map_err(|e| {
            TriaxialError::Test {
                phase: "output",
                message: e.to_string(),
            }
        })?;
        summary.outputs.push(file.into());
    }
    if run.vtk.is_some() {
        summary.outputs.push("frames.pvd".into());
        summary.outputs.push("boundary.pvd".into());
    }
    summary.outputs.push("summary.json".into());
    let text = serde_json::to_string_pretty(summary).map_err(|e| TriaxialError::Test {
        phase: "output",
        message: format!("summary.json: {e}"),
    })?;
    write_atomically(&dir.join("summary.json"), &(text + "\n")).map_err(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plans_beyond_the_step_limit_are_refused_naming_the_safety_factor() {
        let plan = |consolidation: u64, shear: u64| TestPlan {
            consolidation_steps_max: consolidation,
            shear_steps: shear,
            dt: 1e-300,
            dt_bound: 1e-5,
            dt_bound_source: "contact".into(),
            ..TestPlan::default()
        };
        assert!(check_plan(&plan(1000, 2000)).is_ok());
        assert!(check_plan(&plan(0, fdem_solver::MAX_STEPS)).is_ok());
        let e = check_plan(&plan(1, fdem_solver::MAX_STEPS))
            .unwrap_err()
            .to_string();
        assert!(e.contains("test.dt_safety") && e.contains("plan"), "{e}");
        assert!(check_plan(&plan(u64::MAX, u64::MAX)).is_err());
    }
}
