//! `fdem triaxial`: the numerical triaxial test end to end (docs/TRIAXIAL.md): prepare
//! the specimen (or reuse a prepared one), consolidate, shear, write the outputs.

use crate::commands::progress::{Pace, duration, phase_bar, steps_done};
use crate::commands::specimen::{ModelArg, OrderArg, PreparationProgress, preset_spec};
use anyhow::{Context, bail};
use fdem_triaxial::{
    Cached, PreparedSpecimen, SpecimenSpec, TestObserver, TestOptions, TestPhase, TestPlan,
    TestStatus, prepare, quick_spec, run_test, specimen_time_step,
};
use indicatif::ProgressBar;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// File name of the prepared specimen kept in the output directory for reuse.
const PREPARED_FILE: &str = "specimen.fdemspec";

/// Arguments of `fdem triaxial`.
#[derive(clap::Args, Debug)]
pub struct TriaxialArgs {
    /// A test of the paper's Table 4 (E1 ... B3s).
    #[arg(long, value_name = "NAME")]
    test: Option<String>,
    /// A user specimen and test definition (TOML, docs/SPECIMENS.md and docs/TRIAXIAL.md).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// The quick test: a small, coarse specimen that runs end to end in a short time.
    #[arg(long)]
    quick: bool,
    /// A prepared specimen file to test instead of preparing one (its own definition is
    /// used; --model tests its packing in another model).
    #[arg(
        long,
        value_name = "FILE",
        conflicts_with_all = ["test", "config", "quick", "order", "level", "fresh"]
    )]
    specimen: Option<PathBuf>,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Override the element order of the particle meshes (without it, a preset in the
    /// rigid or auto model gets linear surfaces).
    #[arg(long, value_enum)]
    order: Option<OrderArg>,
    /// Override the mesh subdivision level (0 to 4).
    #[arg(long)]
    level: Option<u32>,
    /// Override the particle model (with --specimen: test its packing in this model).
    #[arg(long, value_enum)]
    model: Option<ModelArg>,
    /// Override the target axial strain.
    #[arg(long)]
    strain: Option<f64>,
    /// Prepare again even if DIR/specimen.fdemspec holds this specimen.
    #[arg(long)]
    fresh: bool,
    /// Also write ParaView frames of particles, membrane and platens.
    #[arg(long)]
    vtk: bool,
    /// Log every contact whose stored energy jumps by more than this many joules in one
    /// step, with its cause, to energy_jumps.csv (totals in summary.json)
    #[arg(long, value_name = "J")]
    energy_jumps: Option<f64>,
    /// Write a checkpoint to DIR/checkpoint.fdemckpt every this many seconds of wall
    /// time and when interrupted (0: none; not with --vtk or --energy-jumps).
    #[arg(long, value_name = "SECONDS", default_value_t = 600.0)]
    checkpoint_interval: f64,
    /// Continue the test from DIR/checkpoint.fdemckpt (written by an interrupted run of
    /// the same definition), bit for bit as if it had not stopped.
    #[arg(long)]
    resume: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub(crate) threads: Option<usize>,
}

/// The definition named by --test, --config or --quick with the overrides applied.
fn definition(args: &TriaxialArgs) -> anyhow::Result<SpecimenSpec> {
    let mut spec = match (&args.test, &args.config, args.quick) {
        (Some(name), None, false) => preset_spec(name, args.model, args.order)?,
        (None, Some(path), false) => SpecimenSpec::load(path)?,
        (None, None, true) => quick_spec(),
        _ => bail!("give exactly one of --test NAME, --config FILE, --quick or --specimen FILE"),
    };
    if let Some(order) = args.order {
        spec.mesh.order = order.order();
    }
    if let Some(level) = args.level {
        spec.mesh.level = level;
    }
    if let Some(model) = args.model {
        spec.model = model.model();
    }
    if let Some(strain) = args.strain {
        spec.test.target_strain = strain;
    }
    let origin = args.config.as_ref().map_or_else(
        || format!("preset {}", spec.name),
        |p| p.display().to_string(),
    );
    spec.validate(&origin)?;
    Ok(spec)
}

/// Progress of the test on stderr: the plan, one line per phase, a bar on a terminal and
/// otherwise a line every [`crate::commands::progress::LINE_INTERVAL`] with an estimate
/// from the phase's steps since the last line ([`Pace`]).
pub(crate) struct TestProgress {
    bar: Option<ProgressBar>,
    terminal: bool,
    interrupt: Arc<AtomicBool>,
    /// The phase's first report (steps then, when) and the last line printed.
    pace: Option<Pace>,
}

impl TestProgress {
    /// A reporter that draws bars on a terminal and stops when `interrupt` is set.
    pub(crate) fn new(interrupt: Arc<AtomicBool>) -> Self {
        TestProgress {
            bar: None,
            terminal: std::io::stderr().is_terminal(),
            interrupt,
            pace: None,
        }
    }

    /// A line above the bar, or on stderr without one.
    fn println(&self, line: String) {
        match &self.bar {
            Some(bar) => bar.println(line),
            None => eprintln!("{line}"),
        }
    }

    /// Clears the bar.
    pub(crate) fn finish(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}

impl TestObserver for TestProgress {
    fn plan(&mut self, plan: &TestPlan) {
        let line = format!(
            "test: {} particles, {} + {} membrane nodes; dt = {:.3e} s (bound {:.3e} s, {}); \
             v = {:.4} m/s, I = {:.2e}; shear {} steps, consolidation at most {}; \
             {:.2} ms/step: shear about {}, at most {} with consolidation",
            plan.particles,
            plan.particle_nodes,
            plan.membrane_nodes,
            plan.dt,
            plan.dt_bound,
            plan.dt_bound_source,
            plan.loading_velocity,
            plan.inertial_number,
            plan.shear_steps,
            plan.consolidation_steps_max,
            1e3 * plan.seconds_per_step,
            duration(plan.estimated_shear_seconds),
            duration(plan.estimated_seconds_max),
        );
        self.println(line);
    }

    fn shear_plan(&mut self, plan: &TestPlan) {
        // A test resumed in its shear timed no consolidation steps: no plan to compare with.
        let versus = if plan.seconds_per_step.is_finite() {
            format!(
                " (the plan's {:.2} ms/step came from the first consolidation steps)",
                1e3 * plan.seconds_per_step
            )
        } else {
            String::new()
        };
        self.println(format!(
            "shear: {:.2} ms/step over its first steps{versus}: shear about {}",
            1e3 * plan.shear_seconds_per_step,
            duration(plan.reestimated_shear_seconds),
        ));
    }

    fn phase(&mut self, phase: TestPhase, planned_steps: u64) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
        eprintln!("{}: up to {planned_steps} steps", phase.name());
        self.pace = None;
        if self.terminal {
            self.bar = Some(phase_bar(planned_steps, phase.name()));
        }
    }

    fn progress(&mut self, status: &TestStatus) -> bool {
        let state = match status.phase {
            TestPhase::Consolidation => {
                format!("sigma_a/sigma_0 = {:.4}", status.stress_ratio)
            }
            TestPhase::Shear => format!(
                "eps_a = {:.2} %, eta = {:.3}",
                100.0 * status.eps_a,
                status.eta
            ),
        };
        let pace = match &mut self.pace {
            Some(pace) => pace,
            None => {
                // The first report of the phase (after a resume, its steps are those of
                // the checkpoint): the bar's estimate starts here.
                if let Some(bar) = &self.bar {
                    bar.set_position(status.steps);
                    bar.reset_eta();
                }
                self.pace.insert(Pace::new(status.steps))
            }
        };
        if let Some(bar) = &self.bar {
            bar.set_position(status.steps);
            bar.set_message(state);
        } else if let Some(line) = progress_line(status, pace, &state) {
            eprintln!("{line}");
        }
        !self.interrupt.load(Ordering::SeqCst)
    }
}

/// `shear: 45000 / 58384 steps (77 %), eps_a = 11.6 %, eta = 0.712; 0.21 s/step here,
/// about 47 min left` (for consolidation, `at most` that long), when a line is due.
fn progress_line(status: &TestStatus, pace: &mut Pace, state: &str) -> Option<String> {
    let bound = match status.phase {
        TestPhase::Consolidation => "at most ",
        TestPhase::Shear => "about ",
    };
    let tail = pace.line(status.steps, status.planned_steps, bound)?;
    Some(format!(
        "{}, {state}{tail}",
        steps_done(status.phase.name(), status.steps, status.planned_steps),
    ))
}

/// The prepared specimen: the given file, the reusable one in the output directory, or a
/// new preparation saved there.
fn prepared(args: &TriaxialArgs, interrupt: &Arc<AtomicBool>) -> anyhow::Result<PreparedSpecimen> {
    if let Some(path) = &args.specimen {
        if args.test.is_some() || args.config.is_some() || args.quick {
            bail!(
                "--specimen brings its own definition; it does not go with --test, --config or --quick"
            );
        }
        let mut s = PreparedSpecimen::load(path)?;
        if let Some(model) = args.model
            && model.model() != s.spec.model
        {
            eprintln!(
                "the {} packing of {} in the {} model (same places, at rest)",
                s.spec.model.name(),
                path.display(),
                model.model().name()
            );
            s = s.in_model(model.model())?;
        }
        if let Some(strain) = args.strain {
            s.spec.test.target_strain = strain;
            s.spec.validate(&path.display().to_string())?;
        }
        return Ok(s);
    }
    let spec = definition(args)?;
    let cache = args.out.join(PREPARED_FILE);
    if !args.fresh {
        match PreparedSpecimen::cached(&cache, &spec) {
            Cached::Reusable(s) => {
                eprintln!(
                    "reusing the prepared specimen {} (--fresh prepares again)",
                    cache.display()
                );
                return Ok(*s);
            }
            Cached::Other => eprintln!(
                "{} holds another specimen; preparing this one",
                cache.display()
            ),
            Cached::Unreadable(e) => eprintln!("{e}; preparing again"),
            Cached::Missing => {}
        }
    }
    let counts = spec.counts()?;
    let (dt, _, source) = specimen_time_step(&spec)?;
    eprintln!(
        "prepare {}: {} particles ({} rigid), {} elements, {} nodes; dt = {dt:.3e} s ({source})",
        spec.name, counts.particles, counts.rigid_particles, counts.elements, counts.nodes
    );
    for line in counts.model_report() {
        eprintln!("  {line}");
    }
    let mut progress =
        PreparationProgress::new(std::io::stderr().is_terminal(), Arc::clone(interrupt));
    let result = prepare(&spec, &mut progress);
    progress.finish();
    let prepared = result?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    prepared.save(&cache)?;
    let r = &prepared.report;
    eprintln!(
        "prepared in {:.1} s ({} + {} steps): solid fraction {:.3} nominal, {:.3} of the meshes; \
         coordination {:.2}; saved to {}",
        r.wall_seconds,
        r.compact_steps,
        r.settle_steps,
        r.solid_fraction_nominal,
        r.solid_fraction_real,
        r.coordination_number,
        cache.display()
    );
    if !r.checks.failures.is_empty() {
        bail!(
            "the prepared specimen failed its checks: {}",
            r.checks.failures.join("; ")
        );
    }
    Ok(prepared)
}

/// Refuses a `--strain` outside `(0, MAX_TARGET_STRAIN]`.
pub(crate) fn check_strain(strain: Option<f64>) -> anyhow::Result<()> {
    if let Some(strain) = strain
        && !(strain > 0.0 && strain <= fdem_triaxial::MAX_TARGET_STRAIN)
    {
        bail!(
            "--strain must lie in (0, {}], got {}",
            fdem_triaxial::MAX_TARGET_STRAIN,
            fdem_core::number::Number(strain)
        );
    }
    Ok(())
}

/// Prepares (or reuses), tests and reports.
pub fn run(args: &TriaxialArgs) -> anyhow::Result<()> {
    check_strain(args.strain)?;
    if let Some(j) = args.energy_jumps
        && !(j.is_finite() && j >= 0.0)
    {
        bail!(
            "--energy-jumps must be a finite energy >= 0 (J), got {}",
            fdem_core::number::Number(j)
        );
    }
    if !(args.checkpoint_interval.is_finite() && args.checkpoint_interval >= 0.0) {
        bail!(
            "--checkpoint-interval must be a finite number of seconds >= 0, got {}",
            fdem_core::number::Number(args.checkpoint_interval)
        );
    }
    if args.resume {
        let path = args.out.join(fdem_triaxial::CHECKPOINT_FILE);
        if !path.is_file() {
            bail!(
                "--resume: there is no checkpoint {}; run without --resume to start the test",
                path.display()
            );
        }
        if args.vtk || args.energy_jumps.is_some() || args.fresh {
            bail!(
                "--resume continues a test as it was run: drop --vtk, --energy-jumps and --fresh"
            );
        }
    }
    super::check_output_dir(&args.out)?;
    let interrupt = super::interrupt_flag();
    let start = Instant::now();
    let prepared = prepared(args, &interrupt)?;
    let mut progress = TestProgress::new(Arc::clone(&interrupt));
    let options = TestOptions {
        out_dir: args.out.clone(),
        vtk: args.vtk,
        dt: None,
        energy_jumps: args.energy_jumps,
        checkpoint_interval: (args.checkpoint_interval > 0.0).then_some(args.checkpoint_interval),
        resume: args.resume,
    };
    let result = run_test(&prepared, &options, &mut progress, &interrupt);
    progress.finish();
    let summary = result?;
    report(&summary, &args.out, start.elapsed().as_secs_f64());
    if summary.status == "interrupted" {
        bail!(
            "interrupted: the outputs in {} hold the test up to the interruption (summary.json \
             says `interrupted`)",
            args.out.display()
        );
    }
    Ok(())
}

fn report(s: &fdem_triaxial::TestSummary, out: &Path, seconds: f64) {
    let c = &s.consolidation;
    println!(
        "{} ({}): consolidation {} after {} steps: sigma_a/sigma_0 = {:.4}, unbalanced {:.2e}, \
         kinetic ratio {:.2e}, volume rate {:.2e}, eps_v {:.2} % (specimen {:.2} %, membrane \
         penetration {:.2} %); sheared {} steps",
        s.test,
        s.status,
        if c.reached { "reached" } else { "not reached" },
        c.cost.steps,
        c.stress_ratio,
        c.unbalanced_force,
        c.kinetic_ratio,
        c.volume_rate,
        100.0 * c.eps_v,
        100.0 * c.eps_v_specimen,
        100.0 * (c.eps_v - c.eps_v_specimen),
        s.shear.steps
    );
    if let Some(curve) = &s.curve {
        println!(
            "peak eta = {:.4} at eps_a = {:.2} %; residual eta = {:.4}; max contraction eps_v = \
             {:.3} %; max dilation rate = {:.3}; final eps_v = {:.3} % (specimen {:.3} %)",
            curve.peak_eta,
            100.0 * curve.eps_a_at_peak,
            curve.residual_eta,
            100.0 * curve.max_contraction,
            curve.max_dilation_rate,
            100.0 * curve.final_eps_v,
            100.0 * curve.final_eps_v_specimen,
        );
    }
    println!(
        "inertial number {:.2e}; wall time {}; outputs in {}",
        s.plan.inertial_number,
        duration(seconds),
        out.display()
    );
}
