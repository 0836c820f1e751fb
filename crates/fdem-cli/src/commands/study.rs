//! `fdem study`: a coarse-graining study (docs/STUDY.md): series of triaxial tests over
//! seeds, each run reused when finished, then `RESULTS.md`, `results/runs.csv` and the
//! charts.

use crate::commands::progress::duration;
use crate::commands::specimen::{ModelArg, OrderArg, PreparationProgress};
use crate::commands::triaxial::{TestProgress, check_strain};
use anyhow::bail;
use fdem_study::run::PlannedRun;
use fdem_study::{
    OrderChoice, Provenance, RunDef, RunRecord, StudyObserver, StudyOptions, StudyPlan,
    StudyPreset, expand, gather, load_series, run_study, write_results,
};
use fdem_triaxial::{Observer, TestObserver};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// Arguments of `fdem study`.
#[derive(clap::Args, Debug)]
pub struct StudyArgs {
    /// A built-in series set: quick, equal (E1-E4s), binary (B1-B3s) or paper (both).
    #[arg(long, value_name = "NAME", conflicts_with = "series")]
    preset: Option<String>,
    /// A custom series file (TOML; docs/STUDY.md).
    #[arg(long, value_name = "FILE")]
    series: Option<PathBuf>,
    /// Particle model of every run.
    #[arg(long, value_enum, default_value = "auto")]
    model: ModelArg,
    /// Element order of every run (default: linear surfaces for rigid and auto
    /// particles, the specimen's own order for deformable ones).
    #[arg(long, value_enum)]
    order: Option<OrderArg>,
    /// Independent packings per test (placement seeds 1 to N).
    #[arg(long, default_value_t = 1)]
    seeds: u32,
    /// Only these tests (comma-separated, e.g. E1,E4s).
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    tests: Option<Vec<String>>,
    /// Target axial strain of every run (default the specimens' own, 0.15).
    #[arg(long)]
    strain: Option<f64>,
    /// Study directory: one directory per run under runs/ (created).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Where RESULTS.md goes (its data and charts in results/ beside it); default the
    /// study directory.
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
    /// Print the plan and stop.
    #[arg(long, conflicts_with = "report_only")]
    plan: bool,
    /// Run nothing: write the results of the runs finished so far.
    #[arg(long)]
    report_only: bool,
    /// Run again the runs that failed with the same definition (by default a failure is
    /// reported, not repeated).
    #[arg(long)]
    retry_failed: bool,
    /// How the command is named in RESULTS.md (set by `cargo xtask study`).
    #[arg(long, hide = true, value_name = "TEXT")]
    invoked_as: Option<String>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub(crate) threads: Option<usize>,
}

/// Prints the study's plan and progress on stderr and lends the bars of each run.
pub(crate) struct StudyProgress {
    preparation: PreparationProgress,
    test: TestProgress,
    start: Instant,
    remaining: f64,
    done: usize,
}

impl StudyProgress {
    /// A reporter with bars on a terminal, stopping when `interrupt` is set.
    pub(crate) fn new(interrupt: &Arc<AtomicBool>) -> Self {
        StudyProgress {
            preparation: PreparationProgress::new(
                std::io::stderr().is_terminal(),
                Arc::clone(interrupt),
            ),
            test: TestProgress::new(Arc::clone(interrupt)),
            start: Instant::now(),
            remaining: 0.0,
            done: 0,
        }
    }
}

impl StudyObserver for StudyProgress {
    fn plan(&mut self, plan: &StudyPlan) {
        print_plan(plan);
        self.remaining = plan.total_seconds;
    }

    fn run_started(&mut self, index: usize, total: usize, run: &RunDef, estimate: f64) {
        eprintln!(
            "[{}/{total}] {}: h = {}, {}, seed {}; estimated {} (study: {} done, {} elapsed, about {} left)",
            index + 1,
            run.label(),
            run.h(),
            if run.exact_scaling() {
                "exact scaling"
            } else {
                "plain"
            },
            run.seed,
            duration(estimate),
            self.done,
            duration(self.start.elapsed().as_secs_f64()),
            duration(self.remaining),
        );
        self.remaining -= estimate;
    }

    fn run_ended(&mut self, index: usize, total: usize, record: &RunRecord, reused: bool) {
        self.preparation.finish();
        self.test.finish();
        self.done += 1;
        if reused {
            eprintln!(
                "[{}/{total}] {}: finished earlier, reused",
                index + 1,
                record.label
            );
        } else {
            eprintln!(
                "[{}/{total}] {}: {} in {} ({} steps, model used: {})",
                index + 1,
                record.label,
                record.status,
                duration(record.wall_seconds()),
                record.steps(),
                record.model_used
            );
        }
    }

    fn preparation(&mut self) -> &mut dyn Observer {
        &mut self.preparation
    }

    fn test(&mut self) -> &mut dyn TestObserver {
        &mut self.test
    }
}

fn print_plan(plan: &StudyPlan) {
    eprintln!("study plan: {} runs", plan.runs.len());
    for PlannedRun {
        label,
        particles,
        steps,
        seconds,
        state,
        ..
    } in &plan.runs
    {
        eprintln!(
            "  {label:<32} {particles:>7} particles {steps:>9} steps  {state:<8} {}",
            if *state == "finished" {
                String::new()
            } else {
                duration(*seconds)
            }
        );
    }
    eprintln!(
        "estimated {} in all ({:.2e} s per unit-step, {:.1} / {:.1} steps per planned step for \
         rigid / deformable particles, from {}; cheapest runs first; docs/STUDY.md)",
        duration(plan.total_seconds),
        plan.seconds_per_unit_step,
        plan.steps_per_planned[0],
        plan.steps_per_planned[1],
        plan.throughput_source
    );
}

fn options(args: &StudyArgs) -> anyhow::Result<StudyOptions> {
    check_strain(args.strain)?;
    Ok(StudyOptions {
        model: args.model.model(),
        order: args
            .order
            .map_or(OrderChoice::Auto, |o| OrderChoice::Fixed(o.order())),
        seeds: args.seeds,
        tests: args.tests.clone(),
        strain: args.strain,
    })
}

/// Plans, runs what is not finished, and writes the results.
pub fn run(args: &StudyArgs) -> anyhow::Result<()> {
    let series = match (&args.preset, &args.series) {
        (Some(name), None) => StudyPreset::find(name)?.series()?,
        (None, Some(path)) => load_series(path)?,
        _ => bail!("give one of --preset NAME (quick, equal, binary, paper) or --series FILE"),
    };
    let options = options(args)?;
    super::check_output_dir(&args.out)?;
    let report_dir = args.report.clone().unwrap_or_else(|| args.out.clone());
    super::check_output_dir(&report_dir)?;
    let runs = expand(&series, &options, false)?;
    if args.plan {
        print_plan(&fdem_study::plan(&runs, &args.out, args.retry_failed)?);
        return Ok(());
    }
    let mut outcome = Ok(());
    if !args.report_only {
        let interrupt: Arc<AtomicBool> = super::interrupt_flag();
        let mut progress = StudyProgress::new(&interrupt);
        match run_study(
            &runs,
            &args.out,
            &mut progress,
            &interrupt,
            args.retry_failed,
        ) {
            Ok(records) => {
                let failed: Vec<&str> = records
                    .iter()
                    .filter(|r| !r.completed())
                    .map(|r| r.label.as_str())
                    .collect();
                if !failed.is_empty() {
                    outcome = Err(anyhow::anyhow!(
                        "{} run(s) did not complete: {} (their run.json and summary.json say why)",
                        failed.len(),
                        failed.join(", ")
                    ));
                }
            }
            Err(e) => outcome = Err(e.into()),
        }
    }
    let results = gather(&series, &options, &args.out)?;
    if results.entries.is_empty() {
        outcome?;
        bail!("no finished runs in {} to report", args.out.display());
    }
    let command = super::command_line(args.invoked_as.as_deref(), "fdem study");
    let finished: Vec<String> = results
        .entries
        .iter()
        .map(|e| e.record.label.clone())
        .collect();
    let mut pending = Vec::new();
    let mut failed = Vec::new();
    for run in expand(&series, &options, true)? {
        if finished.contains(&run.label()) {
            continue;
        }
        match fdem_study::failed_record(&args.out, &run)? {
            Some(record) => failed.push((run.label(), record.failure.unwrap_or_default())),
            None => pending.push(run.label()),
        }
    }
    let provenance = Provenance {
        command: &command,
        pending: &pending,
        failed: &failed,
    };
    let written = write_results(&results, &report_dir, &provenance)?;
    let (wall, cpu) = results.total_cost();
    println!(
        "{} finished runs ({} wall, {} CPU in all); wrote {}",
        results.entries.len(),
        duration(wall),
        duration(cpu),
        written
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    outcome
}
