//! `fdem run SCENE.toml --out DIR`: run a scene file.

use fdem_solver::{Observer, RunOptions, RunPlan, Scene, check_memory, run as run_scene};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;

/// Arguments of `fdem run`.
#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// Scene file (TOML, schema in docs/SCENES.md).
    scene: PathBuf,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Also write VTU frames and a ParaView collection (frames.pvd).
    #[arg(long)]
    vtk: bool,
    /// Also write node- and pair-level contact snapshots (contacts/*.csv) at every output.
    #[arg(long)]
    contacts: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub(crate) threads: Option<usize>,
}

/// Progress on stderr: the plan up front, a bar on a terminal, nothing more otherwise.
struct Progress {
    bar: Option<ProgressBar>,
}

impl Observer for Progress {
    fn start(&mut self, plan: &RunPlan) {
        eprintln!(
            "run {}: {} bodies, {} nodes, {} elements; {} steps of dt = {:.3e} s to t = {:.3e} s",
            plan.run_id, plan.bodies, plan.nodes, plan.elements, plan.steps, plan.dt, plan.duration
        );
        if std::io::stderr().is_terminal() {
            let bar = ProgressBar::new(plan.steps);
            if let Ok(style) = ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:40} step {pos}/{len} ({per_sec}, eta {eta}) {msg}",
            ) {
                bar.set_style(style);
            }
            self.bar = Some(bar);
        }
    }

    fn progress(&mut self, time: f64, step: u64) {
        if let Some(bar) = &self.bar {
            bar.set_position(step);
            bar.set_message(format!("t = {time:.3e} s"));
        }
    }
}

/// Loads, runs and reports.
pub fn run(args: &RunArgs) -> anyhow::Result<()> {
    // `run_scene` builds (and so validates) everything before it creates any output.
    let scene = Scene::load(&args.scene)?;
    let options = RunOptions {
        out_dir: args.out.clone(),
        vtk: args.vtk,
        contacts: args.contacts,
    };
    // A scene that cannot fit is refused before any mesh but the templates is built.
    check_memory(&scene, &options, fdem_core::fs::available_memory())?;
    // Every `auto` decision, once per kind of particle.
    let mut decisions: Vec<String> = Vec::new();
    for (_, estimate) in scene.resolved_models()? {
        if let Some(line) = estimate.map(|e| format!("auto: {e}"))
            && !decisions.contains(&line)
        {
            eprintln!("{line}");
            decisions.push(line);
        }
    }
    let interrupt = super::interrupt_flag();
    let mut progress = Progress { bar: None };
    let result = run_scene(&scene, &options, &mut progress, &interrupt);
    if let Some(bar) = &progress.bar {
        bar.finish_and_clear();
    }
    let summary = result?;
    eprintln!(
        "done: {} steps, t = {:.3e} s, {:.2} s wall, {:.2} s CPU, max energy balance error {:.2e}; outputs in {}",
        summary.steps,
        summary.time,
        summary.wall_seconds,
        summary.cpu_seconds,
        summary.max_relative_balance_error,
        args.out.display()
    );
    Ok(())
}
