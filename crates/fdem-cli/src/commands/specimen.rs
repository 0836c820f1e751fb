//! `fdem specimen`: the paper's test catalogue and user specimens: counts, preparation by
//! the dynamic method, and prepared-specimen files (docs/SPECIMENS.md).

use crate::commands::progress::{Pace, phase_bar, steps_done};
use anyhow::bail;
use fdem_mesh::ElementOrder;
use fdem_triaxial::{
    Counts, Observer, PRESETS, Phase, PreparationReport, PreparedSpecimen, Preset, SpecimenSpec,
    Status, prepare,
};
use indicatif::ProgressBar;
use serde_json::json;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Element order as typed on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OrderArg {
    /// 4-node tetrahedra.
    Linear,
    /// 10-node tetrahedra (mid-edge nodes on straight edges).
    Quadratic,
}

impl OrderArg {
    /// The order this names.
    pub fn order(self) -> ElementOrder {
        match self {
            OrderArg::Linear => ElementOrder::Linear,
            OrderArg::Quadratic => ElementOrder::Quadratic,
        }
    }
}

/// The preset `name` with the command line's model and order: a model given without an
/// order gets [`fdem_triaxial::surface_order`]'s choice (linear surfaces for rigid and
/// `auto` particles), as in every command that runs presets.
pub(crate) fn preset_spec(
    name: &str,
    model: Option<ModelArg>,
    order: Option<OrderArg>,
) -> anyhow::Result<SpecimenSpec> {
    let preset = Preset::find(name)?;
    Ok(match model {
        Some(m) => preset.spec_in(m.model(), order.map(OrderArg::order)),
        None => preset.spec(),
    })
}

/// Particle model as typed on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelArg {
    /// Elastic tetrahedral meshes (FDEM, the paper's model).
    Deformable,
    /// Rigid bodies with the meshes' surfaces and mass properties.
    Rigid,
    /// Per size class, rigid where the estimated deflection is a small fraction of the
    /// contact overlap (docs/MODEL.md section 12).
    Auto,
}

impl ModelArg {
    /// The model this names.
    pub fn model(self) -> fdem_solver::ParticleModel {
        match self {
            ModelArg::Deformable => fdem_solver::ParticleModel::Deformable,
            ModelArg::Rigid => fdem_solver::ParticleModel::Rigid,
            ModelArg::Auto => fdem_solver::ParticleModel::Auto,
        }
    }
}

/// Arguments of `fdem specimen`.
#[derive(clap::Args, Debug)]
pub struct SpecimenArgs {
    /// A test of the paper's Table 4: E1, E2, E3, E4, E2s, E3s, E4s, B1, B2, B3, B2s, B3s.
    #[arg(long, value_name = "NAME")]
    test: Option<String>,
    /// A user specimen definition (TOML, schema in docs/SPECIMENS.md).
    #[arg(long, value_name = "SPEC.toml")]
    file: Option<PathBuf>,
    /// A prepared specimen file (written by --prepare): verify it and print its summary.
    #[arg(
        long,
        value_name = "FILE",
        conflicts_with_all = ["level", "order", "model", "seed", "toml"]
    )]
    specimen: Option<PathBuf>,
    /// List the built-in tests with their counts.
    #[arg(long)]
    list: bool,
    /// Print the particle, element and node counts.
    #[arg(long)]
    counts: bool,
    /// Prepare the specimen by the dynamic method and write it to --out.
    #[arg(long)]
    prepare: bool,
    /// The prepared-specimen file to write (with --prepare).
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Print the specimen definition as TOML (a starting point for a user file).
    #[arg(long, conflicts_with_all = ["prepare", "counts", "list"])]
    toml: bool,
    /// Override the mesh subdivision level (0 to 4).
    #[arg(long)]
    level: Option<u32>,
    /// Override the element order (without it, a preset in the rigid or auto model gets
    /// linear surfaces).
    #[arg(long, value_enum)]
    order: Option<OrderArg>,
    /// Override the particle model.
    #[arg(long, value_enum)]
    model: Option<ModelArg>,
    /// Override the placement seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Print results as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub(crate) threads: Option<usize>,
}

/// Progress of a preparation on stderr: one line per phase, the compaction's cost once
/// measured, and a bar on a terminal or otherwise a line every
/// [`crate::commands::progress::LINE_INTERVAL`] with the phase's pace and what is left.
pub struct PreparationProgress {
    bar: Option<ProgressBar>,
    terminal: bool,
    interrupt: Arc<AtomicBool>,
    /// The compaction's planned steps and start, until its cost estimate is printed.
    compaction: Option<(u64, std::time::Instant)>,
    /// The phase's planned steps (the most it may take when it can end early) and pace.
    planned: u64,
    pace: Option<Pace>,
}

/// Steps of compaction timed before its cost estimate is printed.
const ESTIMATE_AFTER_STEPS: u64 = 1000;

impl PreparationProgress {
    /// A reporter that draws bars when `terminal` and stops when `interrupt` is set.
    pub fn new(terminal: bool, interrupt: Arc<AtomicBool>) -> Self {
        PreparationProgress {
            bar: None,
            terminal,
            interrupt,
            compaction: None,
            planned: 0,
            pace: None,
        }
    }

    /// Clears the bar.
    pub fn finish(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }

    /// A line above the bar, or on stderr without one.
    fn println(&self, line: String) {
        match &self.bar {
            Some(bar) => bar.println(line),
            None => eprintln!("{line}"),
        }
    }
}

/// `gap 0.1234 m, 5321 contacts` (and the unbalanced force while settling).
fn preparation_state(status: &Status) -> String {
    let mut state = format!(
        "gap {:.4} m, {} contacts",
        status.platen_gap, status.contacts
    );
    if let Some(r) = status.unbalanced_force {
        state.push_str(&format!(", unbalanced {r:.2e}"));
    }
    state
}

impl Observer for PreparationProgress {
    fn phase(&mut self, phase: Phase, planned_steps: u64) {
        self.finish();
        match phase {
            Phase::Place => eprintln!("place: random loose packing"),
            Phase::Compact => {
                eprintln!("compact: {planned_steps} steps");
                self.compaction = Some((planned_steps, std::time::Instant::now()));
            }
            Phase::Settle => eprintln!("settle: at most {planned_steps} steps"),
        }
        (self.planned, self.pace) = (planned_steps, None);
        if self.terminal && planned_steps > 0 {
            self.bar = Some(phase_bar(planned_steps, phase.name()));
        }
    }

    fn progress(&mut self, phase: Phase, status: &Status) -> bool {
        // The compaction is most of a preparation: its cost, once measured.
        if phase == Phase::Compact
            && status.step >= ESTIMATE_AFTER_STEPS
            && let Some((planned, start)) = self.compaction.take()
        {
            let per_step = start.elapsed().as_secs_f64() / status.step as f64;
            self.println(format!(
                "compact: {:.2} ms per step, about {:.0} s for the compaction",
                1e3 * per_step,
                per_step * planned as f64
            ));
        }
        let state = preparation_state(status);
        let planned = self.planned;
        let pace = self.pace.get_or_insert_with(|| Pace::new(status.step));
        if let Some(bar) = &self.bar {
            bar.set_position(status.step);
            bar.set_message(state);
        } else {
            let bound = match phase {
                Phase::Settle => "at most ",
                Phase::Place | Phase::Compact => "about ",
            };
            if let Some(tail) = pace.line(status.step, planned, bound) {
                eprintln!(
                    "{}, {state}{tail}",
                    steps_done(phase.name(), status.step, planned)
                );
            }
        }
        !self.interrupt.load(Ordering::SeqCst)
    }
}

/// The definition named by --test or --file, with the command-line overrides applied.
fn definition(args: &SpecimenArgs) -> anyhow::Result<SpecimenSpec> {
    let mut spec = match (&args.test, &args.file) {
        (Some(name), None) => preset_spec(name, args.model, args.order)?,
        (None, Some(path)) => SpecimenSpec::load(path)?,
        _ => bail!("give one of --test NAME, --file SPEC.toml or --specimen FILE"),
    };
    if let Some(level) = args.level {
        spec.mesh.level = level;
    }
    if let Some(order) = args.order {
        spec.mesh.order = order.order();
    }
    if let Some(model) = args.model {
        spec.model = model.model();
    }
    if let Some(seed) = args.seed {
        spec.seed = seed;
    }
    let origin = args.file.as_ref().map_or_else(
        || format!("preset {}", spec.name),
        |p| p.display().to_string(),
    );
    spec.validate(&origin)?;
    Ok(spec)
}

/// The one-line JSON of `--counts --json`, keys in the documented order.
pub fn counts_json(counts: &Counts) -> String {
    format!(
        r#"{{"particles":{},"elements":{},"nodes":{}}}"#,
        counts.particles, counts.elements, counts.nodes
    )
}

fn print_counts(name: &str, counts: &Counts, quadratic: bool) {
    println!(
        "{name}: {} particles ({} rigid), {} elements, {} nodes; nominal solid fraction {:.4}; \
         memory about {:.2} GB ({} surface nodes)",
        counts.particles,
        counts.rigid_particles,
        counts.elements,
        counts.nodes,
        counts.solid_fraction,
        counts.memory_estimate(quadratic) as f64 / 1e9,
        counts.surface_nodes
    );
    for line in counts.model_report() {
        println!("  {line}");
    }
    println!(
        "{:>14} {:>14} {:>12}",
        "diameter (m)", "mass fraction", "particles"
    );
    for c in &counts.classes {
        println!(
            "{:>14} {:>14} {:>12}",
            c.diameter, c.mass_fraction, c.particles
        );
    }
}

fn print_report(r: &PreparationReport) {
    println!(
        "{} particles, {} nodes, {} elements; loose column {:.4} m -> {:.4} m",
        r.particles, r.nodes, r.elements, r.loose_height, r.target_height
    );
    println!(
        "steps: {} compaction + {} settling (dt {:.3e} s, settled: {}); {:.1} s wall, {} CPU, {} threads",
        r.compact_steps,
        r.settle_steps,
        r.dt,
        r.settled,
        r.wall_seconds,
        r.cpu_seconds
            .map_or_else(|| "unknown".to_string(), |c| format!("{c:.1} s")),
        r.threads
    );
    println!(
        "solid fraction: nominal {:.4}, real {:.4}; coordination number {:.2}; \
         stress on the platens {:.3e} Pa, on the cylinder {:.3e} Pa",
        r.solid_fraction_nominal,
        r.solid_fraction_real,
        r.coordination_number,
        r.platen_stress,
        r.cylinder_stress
    );
    let c = &r.checks;
    println!(
        "checks: {} particles outside, overlap {:.3e} m and wall penetration {:.3e} m (limit {:.3e} m), \
         unbalanced force {:.3e} (limit {})",
        c.particles_outside,
        c.max_overlap,
        c.max_wall_penetration,
        c.overlap_limit,
        c.unbalanced_force,
        c.unbalanced_force_limit
    );
}

fn list(json_out: bool) -> anyhow::Result<()> {
    let mut rows = Vec::new();
    for p in PRESETS {
        let spec = p.spec();
        let counts = spec.counts()?;
        let sizes: Vec<f64> = counts.classes.iter().map(|c| c.diameter).collect();
        rows.push((p, sizes, counts));
    }
    if json_out {
        let tests: Vec<serde_json::Value> = rows
            .iter()
            .map(|(p, sizes, c)| {
                json!({
                    "test": p.name, "diameters": sizes, "coarse_graining": p.coarse_graining,
                    "exact_scaling": p.exact_scaling, "particles": c.particles,
                    "elements": c.elements, "nodes": c.nodes,
                })
            })
            .collect();
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({ "tests": tests }))?
        );
    } else {
        println!(
            "{:<5} {:<16} {:>5} {:>6} {:>10} {:>10} {:>10}",
            "test", "diameters (mm)", "h", "exact", "particles", "elements", "nodes"
        );
        for (p, sizes, c) in rows {
            let mm: Vec<String> = sizes.iter().map(|d| format!("{}", d * 1e3)).collect();
            println!(
                "{:<5} {:<16} {:>5} {:>6} {:>10} {:>10} {:>10}",
                p.name,
                mm.join("-"),
                p.coarse_graining,
                if p.exact_scaling { "yes" } else { "no" },
                c.particles,
                c.elements,
                c.nodes
            );
        }
    }
    Ok(())
}

fn summary_json(file: &std::path::Path, s: &PreparedSpecimen) -> anyhow::Result<String> {
    Ok(serde_json::to_string_pretty(&json!({
        "file": file.display().to_string(),
        "test": s.spec.name,
        "format_version": fdem_triaxial::FORMAT_VERSION,
        "time": s.state.time,
        "step": s.state.step,
        "report": serde_json::to_value(&s.report)?,
    }))?)
}

/// Runs `fdem specimen`.
pub fn run(args: &SpecimenArgs) -> anyhow::Result<()> {
    if args.list {
        return list(args.json);
    }
    if args.out.is_some() && !args.prepare {
        bail!("--out goes with --prepare; add --prepare to prepare the specimen");
    }
    if let Some(path) = &args.specimen {
        if args.test.is_some() || args.file.is_some() || args.prepare {
            bail!(
                "--specimen reads a prepared file; it does not go with --test, --file or --prepare"
            );
        }
        let s = PreparedSpecimen::load(path)?;
        if args.counts {
            let counts = s.spec.counts()?;
            if args.json {
                println!("{}", counts_json(&counts));
            } else {
                print_counts(
                    &s.spec.name,
                    &counts,
                    s.spec.mesh.order == ElementOrder::Quadratic,
                );
            }
        } else if args.json {
            println!("{}", summary_json(path, &s)?);
        } else {
            println!(
                "{}: prepared specimen `{}` (format {}), t = {:.4e} s after {} steps",
                path.display(),
                s.spec.name,
                fdem_triaxial::FORMAT_VERSION,
                s.state.time,
                s.state.step
            );
            print_report(&s.report);
        }
        return Ok(());
    }
    let spec = definition(args)?;
    if args.toml {
        print!("{}", spec.to_toml_string()?);
        return Ok(());
    }
    if args.prepare {
        let Some(out) = &args.out else {
            bail!("--prepare needs --out FILE, the prepared-specimen file to write");
        };
        super::check_output_file(out)?;
        let interrupt = super::interrupt_flag();
        let counts = spec.counts()?;
        eprintln!(
            "prepare {}: {} particles, {} elements, {} nodes",
            spec.name, counts.particles, counts.elements, counts.nodes
        );
        let mut progress = PreparationProgress::new(std::io::stderr().is_terminal(), interrupt);
        let result = prepare(&spec, &mut progress);
        progress.finish();
        let prepared = result?;
        prepared.save(out)?;
        if args.json {
            println!("{}", summary_json(out, &prepared)?);
        } else {
            print_report(&prepared.report);
            println!("written to {}", out.display());
        }
        let failures = &prepared.report.checks.failures;
        if !failures.is_empty() {
            bail!(
                "the prepared specimen was written to {} but failed its checks: {}",
                out.display(),
                failures.join("; ")
            );
        }
        return Ok(());
    }
    let counts = spec.counts()?;
    if args.json {
        println!("{}", counts_json(&counts));
    } else {
        print_counts(
            &spec.name,
            &counts,
            spec.mesh.order == ElementOrder::Quadratic,
        );
        let simulated = spec.simulated()?;
        for (key, quantity, factor) in &simulated.scaled {
            println!("exact scaling: {key} ({quantity}) x {factor}");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_json_is_table_2_for_e1() {
        let counts = Preset::find("E1")
            .and_then(|p| p.spec().counts())
            .map_err(|e| e.to_string());
        assert_eq!(
            counts.map(|c| counts_json(&c)),
            Ok(r#"{"particles":15186,"elements":1214880,"nodes":3113130}"#.to_string())
        );
    }
}
