//! `fdem micro RUN_DIR... [--json]`: contact-force micro-analysis of contact snapshots
//! (docs/MICRO.md): clustering into particle contacts, statistics, validation against the
//! per-pair ground truth, `force_distribution.svg`, and a Table 5-style comparison of
//! several runs.

use anyhow::{Context, bail};
use fdem_micro::{
    Analysis, AnalysisOptions, ClusterParams, PairValidation, Series, SnapshotChoice, TableRow,
    all_snapshots, analyse, locate_snapshot, plot_distributions, summary_bodies, table,
    write_contacts,
};
use serde_json::json;
use std::path::{Path, PathBuf};

/// Arguments of `fdem micro`.
#[derive(clap::Args, Debug)]
pub struct MicroArgs {
    /// Run directories written with `fdem run --contacts` (snapshots in contacts/), or
    /// node-level snapshot files. Several runs overlay their distributions and print a
    /// Table 5-style comparison (mean force and ratio to the first).
    #[arg(required = true, value_name = "RUN_DIR")]
    pub runs: Vec<PathBuf>,
    /// Print one JSON object on stdout instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Which snapshot of each run: `auto` (contacts_peak.csv if present, else the last
    /// contacts/nodes_N.csv), `last`, `peak`, or a number N.
    #[arg(long, default_value = "auto", value_name = "WHICH")]
    pub snapshot: SnapshotChoice,
    /// DBSCAN neighbourhood radius (m). Default: --eps-factor x each particle's node
    /// spacing (median nearest-neighbour distance of its force-carrying nodes).
    #[arg(long, value_name = "M")]
    pub eps: Option<f64>,
    /// Multiple of the node spacing used as the radius when --eps is not given.
    #[arg(long, default_value_t = 1.5, value_name = "F")]
    pub eps_factor: f64,
    /// DBSCAN minimum neighbourhood size (the node itself included); 1 keeps single-node
    /// contacts.
    #[arg(long, default_value_t = 1, value_name = "N")]
    pub min_points: usize,
    /// Clusters on two bodies are at the same place within this many radii.
    #[arg(long, default_value_t = 2.0, value_name = "F")]
    pub pair_distance: f64,
    /// Relative tolerance on |F_a + F_b| when pairing clusters whose counterpart is not
    /// recorded.
    #[arg(long, default_value_t = 0.1, value_name = "F")]
    pub force_tolerance: f64,
    /// Ignore node rows whose normal force is at most this (N).
    #[arg(long, default_value_t = 0.0, value_name = "NEWTON")]
    pub min_normal_force: f64,
    /// Bodies that are boundaries (meshed membrane, platens), not particles: comma
    /// separated or repeated.
    #[arg(long, value_delimiter = ',', value_name = "ID")]
    pub boundary_body: Vec<u32>,
    /// Particles for the coordination number. Default: `bodies` of the run's
    /// summary.json minus the boundary bodies, else the particles seen in the snapshot.
    #[arg(long, value_name = "N")]
    pub particles: Option<usize>,
    /// Validation: pairs carrying more than this fraction of the mean normal force are
    /// significant.
    #[arg(long, default_value_t = 0.01, value_name = "F")]
    pub significance: f64,
    /// Where to write the plot. Default: RUN_DIR/force_distribution.svg for one run
    /// directory, ./force_distribution.svg otherwise.
    #[arg(long, value_name = "FILE")]
    pub svg: Option<PathBuf>,
    /// Also validate every snapshot of each run (numbered and peak) against its ground
    /// truth and print one line per snapshot.
    #[arg(long)]
    pub validate_all: bool,
    /// Do not write the plot.
    #[arg(long, conflicts_with = "svg")]
    pub no_svg: bool,
    /// Also write every contact (bodies, position, forces, nodes) as CSV (one run only).
    #[arg(long, value_name = "FILE")]
    pub contacts_csv: Option<PathBuf>,
    /// Labels of the runs in the table and legend, comma separated (default: the
    /// directory names).
    #[arg(long, value_delimiter = ',', value_name = "LABEL")]
    pub labels: Vec<String>,
}

fn label_of(path: &Path) -> String {
    let named = if path.is_file() {
        path.parent().and_then(|p| p.file_name()).map(|n| {
            format!(
                "{}/{}",
                n.to_string_lossy(),
                path.file_name().unwrap_or_default().to_string_lossy()
            )
        })
    } else {
        path.file_name().map(|n| n.to_string_lossy().into_owned())
    };
    named.unwrap_or_else(|| path.display().to_string())
}

fn percent(x: Option<f64>) -> String {
    x.map_or_else(|| "n/a".to_string(), |v| format!("{:.1} %", 100.0 * v))
}

fn validation_line(name: &str, v: &PairValidation) -> String {
    format!(
        "    {name}: recall {} ({}/{}), precision {} ({}/{}); force error mean {}, max {} \
         ({} pairs above 5 %); all pairs: recall {}, precision {}",
        percent(v.recall),
        v.recalled,
        v.significant_truth_pairs,
        percent(v.precision),
        v.confirmed,
        v.significant_clustered_pairs,
        percent(v.mean_force_error),
        percent(v.max_force_error),
        v.pairs_over_5_percent,
        percent(v.recall_all),
        percent(v.precision_all),
    )
}

fn print_run(label: &str, a: &Analysis, particles_note: &str) {
    let (c, s) = (&a.clustering, &a.statistics);
    println!(
        "{label}: {} (t = {:.6e} s)",
        a.files.nodes.display(),
        c.time
    );
    let eps = c.eps_range.map_or_else(
        || "n/a".to_string(),
        |[lo, hi]| {
            if lo == hi {
                format!("{lo:.3e} m")
            } else {
                format!("{lo:.3e}..{hi:.3e} m")
            }
        },
    );
    println!(
        "  nodes: {} rows ({} without normal force), {} clusters, node spacing {}, eps {eps}",
        c.rows,
        c.ignored_rows,
        c.clusters,
        c.spacing
            .map_or_else(|| "n/a".to_string(), |v| format!("{v:.3e} m")),
    );
    println!(
        "  contacts: {} particle, {} boundary; {} particles ({particles_note}), {} in contact; \
         coordination number {:.3}",
        s.contacts, s.boundary_contacts, s.particles, s.particles_in_contact, s.coordination_number
    );
    println!(
        "  normal force: mean {:.6e} N, max {:.6e} N; mean tangential {:.6e} N; strong (> 4) \
         {:.2} %, weak (< 0.2) {:.2} %",
        s.mean_normal_force,
        s.max_normal_force,
        s.mean_tangential_force,
        100.0 * s.strong_share,
        100.0 * s.weak_share
    );
    if s.pairs_with_several_contacts > 0 {
        println!(
            "  note: {} body pairs have more than one contact",
            s.pairs_with_several_contacts
        );
    }
    match (&a.validation, &a.files.pairs) {
        (Some(v), Some(p)) => {
            println!(
                "  validation against {} (significant: above {} % of the mean normal force):",
                p.display(),
                100.0 * v.significance
            );
            println!("{}", validation_line("body pairs", &v.body_pairs));
            println!("{}", validation_line("wall pairs", &v.wall_pairs));
            if v.unknown_contacts > 0 {
                println!(
                    "    {} boundary contacts with an unknown counterpart not compared",
                    v.unknown_contacts
                );
            }
        }
        _ => println!("  validation: no ground truth (pairs_*.csv) next to the snapshot"),
    }
}

/// One line per snapshot: contacts, mean force and the validation of body and wall pairs.
fn print_every(every: &[Analysis]) {
    println!("  every snapshot (recall / precision / max force error of the significant pairs):");
    let header = format!(
        "    {:<20} {:>13} {:>9} {:>14}   {:<28} {}",
        "snapshot", "t (s)", "contacts", "mean F_n (N)", "body pairs", "wall pairs"
    );
    println!("{header}");
    let short = |v: Option<&PairValidation>| {
        v.map_or_else(
            || "no ground truth".to_string(),
            |v| {
                format!(
                    "{} / {} / {}",
                    percent(v.recall),
                    percent(v.precision),
                    percent(v.max_force_error)
                )
            },
        )
    };
    for s in every {
        let name = s
            .files
            .nodes
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        println!(
            "    {:<20} {:>13.6e} {:>9} {:>14.6e}   {:<28} {}",
            name,
            s.clustering.time,
            s.statistics.contacts,
            s.statistics.mean_normal_force,
            short(s.validation.as_ref().map(|v| &v.body_pairs)),
            short(s.validation.as_ref().map(|v| &v.wall_pairs)),
        );
    }
}

/// Analyses the runs, prints and plots.
pub fn run(args: &MicroArgs) -> anyhow::Result<()> {
    check_args(args)?;
    let params = ClusterParams {
        eps: args.eps,
        eps_factor: args.eps_factor,
        min_points: args.min_points,
        pair_distance_factor: args.pair_distance,
        force_tolerance: args.force_tolerance,
        min_normal_force: args.min_normal_force,
        boundary_bodies: args.boundary_body.clone(),
    };
    params.validate()?;
    let runs = args
        .runs
        .iter()
        .enumerate()
        .map(|(i, path)| analyse_run(args, &params, i, path))
        .collect::<anyhow::Result<Vec<_>>>()?;
    if let (Some(path), Some(first)) = (&args.contacts_csv, runs.first()) {
        write_contacts(path, &first.analysis.clustering)?;
    }
    let svg = svg_path(args);
    if let Some(path) = &svg {
        let series: Vec<Series<'_>> = runs
            .iter()
            .map(|r| Series {
                label: &r.label,
                histogram: &r.analysis.statistics.histogram,
            })
            .collect();
        plot_distributions(path, &series)?;
    }
    let rows = table(
        &runs
            .iter()
            .map(|r| (r.label.clone(), &r.analysis.statistics))
            .collect::<Vec<_>>(),
    );
    if args.json {
        print_json(args, &params, &runs, &rows, &svg)?;
    } else {
        print_text(&runs, &rows, &svg);
    }
    Ok(())
}

/// One analysed run.
struct RunAnalysis {
    /// Its label in the table and legend.
    label: String,
    /// The analysis of the chosen snapshot.
    analysis: Analysis,
    /// Where its particle count comes from.
    note: String,
    /// With --validate-all, the analysis of every snapshot.
    every: Vec<Analysis>,
}

/// Refuses option combinations that do not fit the runs given.
fn check_args(args: &MicroArgs) -> anyhow::Result<()> {
    if args.contacts_csv.is_some() && args.runs.len() > 1 {
        bail!("--contacts-csv takes one run; give one RUN_DIR or drop the option");
    }
    if !args.labels.is_empty() && args.labels.len() != args.runs.len() {
        bail!(
            "--labels has {} entries for {} runs; give one label per run",
            args.labels.len(),
            args.runs.len()
        );
    }
    Ok(())
}

/// The particle count for the coordination number of the run at `path`, and where it
/// comes from: --particles, else the run's summary.json minus the boundary bodies, else
/// the particles seen in the snapshot.
fn particles_for(args: &MicroArgs, params: &ClusterParams, path: &Path) -> (Option<usize>, String) {
    match args.particles {
        Some(n) => (Some(n), "--particles".to_string()),
        None => match summary_bodies(path) {
            Some(bodies) => {
                let boundary = params
                    .boundary_bodies
                    .iter()
                    .filter(|&&b| (b as usize) < bodies)
                    .collect::<std::collections::BTreeSet<_>>()
                    .len();
                (Some(bodies - boundary), "summary.json".to_string())
            }
            None => (None, "seen in the snapshot".to_string()),
        },
    }
}

/// Locates and analyses the snapshot of run `i` at `path` (and every snapshot with
/// --validate-all).
fn analyse_run(
    args: &MicroArgs,
    params: &ClusterParams,
    i: usize,
    path: &Path,
) -> anyhow::Result<RunAnalysis> {
    let files = locate_snapshot(path, args.snapshot)?;
    let (particles, note) = particles_for(args, params, path);
    let options = AnalysisOptions {
        params: params.clone(),
        particles,
        significance: args.significance,
    };
    let analysis = analyse(&files, &options)
        .with_context(|| format!("analysing {}", files.nodes.display()))?;
    let label = args
        .labels
        .get(i)
        .cloned()
        .unwrap_or_else(|| label_of(path));
    let mut every = Vec::new();
    if args.validate_all {
        for f in all_snapshots(path)? {
            every.push(
                analyse(&f, &options)
                    .with_context(|| format!("analysing {}", f.nodes.display()))?,
            );
        }
    }
    Ok(RunAnalysis {
        label,
        analysis,
        note,
        every,
    })
}

/// Where to write the plot: `None` with --no-svg, else --svg, else
/// RUN_DIR/force_distribution.svg for one run directory, ./force_distribution.svg
/// otherwise.
fn svg_path(args: &MicroArgs) -> Option<PathBuf> {
    if args.no_svg {
        None
    } else {
        Some(
            args.svg
                .clone()
                .unwrap_or_else(|| match args.runs.as_slice() {
                    [one] if one.is_dir() => one.join("force_distribution.svg"),
                    _ => PathBuf::from("force_distribution.svg"),
                }),
        )
    }
}

/// Prints everything as one JSON object.
fn print_json(
    args: &MicroArgs,
    params: &ClusterParams,
    runs: &[RunAnalysis],
    rows: &[TableRow],
    svg: &Option<PathBuf>,
) -> anyhow::Result<()> {
    let runs: Vec<serde_json::Value> = runs
        .iter()
        .map(|r| {
            let a = &r.analysis;
            let mut clustering = serde_json::to_value(&a.clustering)?;
            if let Some(map) = clustering.as_object_mut() {
                map.remove("contacts");
            }
            let every: Vec<serde_json::Value> = r
                .every
                .iter()
                .map(|s| {
                    json!({
                        "nodes_file": s.files.nodes,
                        "pairs_file": s.files.pairs,
                        "time": s.clustering.time,
                        "contacts": s.statistics.contacts,
                        "mean_normal_force": s.statistics.mean_normal_force,
                        "validation": s.validation,
                    })
                })
                .collect();
            Ok(json!({
                "label": r.label,
                "nodes_file": a.files.nodes,
                "pairs_file": a.files.pairs,
                "particles_from": r.note,
                "clustering": clustering,
                "statistics": a.statistics,
                "validation": a.validation,
                "snapshots": every,
            }))
        })
        .collect::<Result<_, serde_json::Error>>()?;
    let out = json!({
        "parameters": params,
        "significance": args.significance,
        "runs": runs,
        "table": rows,
        "svg": svg,
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}

/// Prints each run, the comparison table of several runs, and where the plot went.
fn print_text(runs: &[RunAnalysis], rows: &[TableRow], svg: &Option<PathBuf>) {
    for r in runs {
        print_run(&r.label, &r.analysis, &r.note);
        if !r.every.is_empty() {
            print_every(&r.every);
        }
    }
    if runs.len() > 1 {
        println!();
        println!(
            "{:<24} {:>18} {:>10} {:>10} {:>8}",
            "run", "mean F_n (N)", "ratio", "contacts", "Z"
        );
        for r in rows {
            println!(
                "{:<24} {:>18.6e} {:>10} {:>10} {:>8.3}",
                r.label,
                r.mean_normal_force,
                r.ratio_to_first
                    .map_or_else(|| "n/a".to_string(), |v| format!("{v:.3}")),
                r.contacts,
                r.coordination_number
            );
        }
    }
    if let Some(path) = svg {
        println!("plot: {}", path.display());
    }
}
