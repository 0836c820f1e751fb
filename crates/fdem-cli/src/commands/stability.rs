//! `fdem stability`: stability maps of the step, the penalty and the damping for rigid,
//! linear and quadratic particles (docs/STABILITY.md).

use crate::commands::progress::duration;
use crate::commands::specimen::PreparationProgress;
use crate::commands::study::StudyProgress;
use fdem_study::limits::{compare_elements, run_limits};
use fdem_study::stability::{MapSpec, run_map, write_stability};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// Arguments of `fdem stability`.
#[derive(clap::Args, Debug)]
pub struct StabilityArgs {
    /// The small map of the test suite (rigid and linear particles, 0.9 and 2 times the
    /// bound at the paper's penalty).
    #[arg(long)]
    quick: bool,
    /// Map directory: the packings and stability.csv (created; an interrupted map resumes).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Where STABILITY.md goes (its data and charts in results/ beside it); default the
    /// map directory.
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
    /// How the command is named in STABILITY.md (set by `cargo xtask stability`).
    #[arg(long, hide = true, value_name = "TEXT")]
    invoked_as: Option<String>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub(crate) threads: Option<usize>,
}

/// Runs the map (or what is left of it) and writes its report.
pub fn run(args: &StabilityArgs) -> anyhow::Result<()> {
    super::check_output_dir(&args.out)?;
    let report = args.report.clone().unwrap_or_else(|| args.out.clone());
    super::check_output_dir(&report)?;
    let spec = if args.quick {
        MapSpec::quick()
    } else {
        MapSpec::full()
    };
    let interrupt = super::interrupt_flag();
    let mut preparation =
        PreparationProgress::new(std::io::stderr().is_terminal(), Arc::clone(&interrupt));
    let start = Instant::now();
    let mut progress = |i: usize, n: usize, row: &fdem_study::stability::MapRow| {
        eprintln!(
            "[{}/{n}] {} p_n = {:.1e} beta = {} membrane {} MPa dt = {} x bound: {} after {} steps (energy error {:.1e}; {} elapsed)",
            i + 1,
            row.model,
            row.normal_penalty,
            row.damping,
            row.membrane_modulus / 1e6,
            row.dt_factor,
            row.class,
            row.steps,
            row.max_energy_error,
            duration(start.elapsed().as_secs_f64())
        );
    };
    eprintln!(
        "stability map: {} probes of {} steps",
        spec.points().len(),
        spec.steps
    );
    let rows = run_map(
        &spec,
        &args.out,
        &mut preparation,
        &mut progress,
        &interrupt,
    )?;
    preparation.finish();
    // The limits of the rigid model: quick tests over the particles' modulus.
    let limits = if args.quick {
        None
    } else {
        let mut study = StudyProgress::new(&interrupt);
        let dir = args.out.join("limits");
        let points = run_limits(&dir, &mut study, &interrupt)?;
        Some((points, compare_elements(&dir)?))
    };
    let command = super::command_line(args.invoked_as.as_deref(), "fdem stability");
    let written = write_stability(
        &rows,
        &spec,
        limits.as_ref().map(|(p, e)| (p.as_slice(), e)),
        &report,
        &command,
    )?;
    println!(
        "{} probes; wrote {}",
        rows.len(),
        written
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}
