//! The `fdem micro` subcommand (crates/fdem-cli/src/commands/micro.rs, compiled here as
//! well) on synthetic run directories: snapshot selection, outputs and errors.

#[path = "../../fdem-cli/src/commands/micro.rs"]
mod micro;

use clap::Parser;
use fdem_micro::synthetic::{SyntheticSpec, generate};
use fdem_micro::{write_nodes, write_pairs};
use std::path::Path;

#[derive(Parser, Debug)]
struct Cli {
    #[command(flatten)]
    args: micro::MicroArgs,
}

fn micro(args: &[&str]) -> anyhow::Result<()> {
    let cli = Cli::try_parse_from(std::iter::once("micro").chain(args.iter().copied()))?;
    micro::run(&cli.args)
}

/// A run directory with numbered snapshots at t = 0, 1, ... (and optionally a peak
/// snapshot at t = 100), forces scaled by `force_scale`, and a summary.json.
fn run_dir(path: &Path, snapshots: usize, peak: bool, force_scale: f64) {
    let contacts = path.join("contacts");
    std::fs::create_dir_all(&contacts).unwrap();
    let mut spec = SyntheticSpec::e2(5);
    spec.grid = [3, 3, 3];
    spec.mean_force *= force_scale;
    let data = generate(&spec);
    let write = |nodes: &Path, pairs: &Path, time: f64| {
        let mut s = data.snapshot.clone();
        s.time = time;
        write_nodes(nodes, &s).unwrap();
        write_pairs(pairs, time, &data.truth).unwrap();
    };
    for i in 0..snapshots {
        write(
            &contacts.join(format!("nodes_{i:06}.csv")),
            &contacts.join(format!("pairs_{i:06}.csv")),
            i as f64,
        );
    }
    if peak {
        write(
            &path.join("contacts_peak.csv"),
            &path.join("pairs_peak.csv"),
            100.0,
        );
    }
    std::fs::write(path.join("summary.json"), "{\"bodies\": 27}").unwrap();
}

/// The time column of the first data row of the per-contact CSV.
fn contacts_time(path: &Path) -> f64 {
    let text = std::fs::read_to_string(path).unwrap();
    let line = text.lines().nth(1).unwrap();
    line.split(',').next().unwrap().parse().unwrap()
}

#[test]
fn snapshot_selection_outputs_and_table() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("E1");
    run_dir(&run, 3, false, 1.0);
    let csv = dir.path().join("contacts.csv");
    let (run_s, csv_s) = (run.to_str().unwrap(), csv.to_str().unwrap());

    // Default: the last numbered snapshot; the plot goes into the run directory.
    micro(&[run_s, "--contacts-csv", csv_s]).unwrap();
    assert_eq!(contacts_time(&csv), 2.0);
    let svg = std::fs::read_to_string(run.join("force_distribution.svg")).unwrap();
    for text in ["F_n / mean(F_n)", "probability density", "E1", "log scale"] {
        assert!(svg.contains(text), "the plot lacks `{text}`");
    }
    micro(&[
        run_s,
        "--snapshot",
        "0",
        "--contacts-csv",
        csv_s,
        "--json",
        "--no-svg",
    ])
    .unwrap();
    assert_eq!(contacts_time(&csv), 0.0);
    // A snapshot file directly.
    let file = run.join("contacts").join("nodes_000001.csv");
    micro(&[file.to_str().unwrap(), "--contacts-csv", csv_s, "--no-svg"]).unwrap();
    assert_eq!(contacts_time(&csv), 1.0);

    // The peak snapshot wins when present, unless asked otherwise.
    run_dir(&run, 3, true, 1.0);
    micro(&[run_s, "--contacts-csv", csv_s, "--no-svg"]).unwrap();
    assert_eq!(contacts_time(&csv), 100.0);
    micro(&[
        run_s,
        "--snapshot",
        "last",
        "--contacts-csv",
        csv_s,
        "--no-svg",
    ])
    .unwrap();
    assert_eq!(contacts_time(&csv), 2.0);

    // Several runs: overlaid plot, Table 5-style table, labels.
    let scaled = dir.path().join("E2");
    run_dir(&scaled, 1, false, 4.0);
    let overlay = dir.path().join("overlay.svg");
    micro(&[
        run_s,
        scaled.to_str().unwrap(),
        "--svg",
        overlay.to_str().unwrap(),
        "--labels",
        "original,h = 2",
    ])
    .unwrap();
    let svg = std::fs::read_to_string(&overlay).unwrap();
    assert!(svg.contains("original") && svg.contains("h = 2"));
    micro(&[run_s, scaled.to_str().unwrap(), "--json", "--no-svg"]).unwrap();
}

#[test]
fn errors_are_one_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    run_dir(&run, 1, false, 1.0);
    let run_s = run.to_str().unwrap();
    let message = |args: &[&str]| format!("{:#}", micro(args).unwrap_err());

    let m = message(&[dir.path().join("missing").to_str().unwrap()]);
    assert!(m.contains("no such file or directory"), "{m}");
    let m = message(&[run_s, "--snapshot", "7"]);
    assert!(m.contains("no nodes_000007.csv"), "{m}");
    let m = message(&[run_s, "--snapshot", "peak"]);
    assert!(m.contains("contacts_peak.csv"), "{m}");
    let m = message(&[run_s, "--snapshot", "first"]);
    assert!(m.contains("not a snapshot"), "{m}");
    let m = message(&[run_s, "--eps=-1"]);
    assert!(m.contains("`eps` = -1"), "{m}");
    let m = message(&[run_s, run_s, "--contacts-csv", "x.csv"]);
    assert!(m.contains("takes one run"), "{m}");
    let m = message(&[run_s, "--labels", "a,b"]);
    assert!(m.contains("one label per run"), "{m}");

    // A malformed snapshot: file, line and column.
    let nodes = run.join("contacts").join("nodes_000000.csv");
    let text = std::fs::read_to_string(&nodes).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut fields: Vec<String> = lines[3].split(',').map(str::to_string).collect();
    fields[5] = "1.0.0".to_string(); // x
    lines[3] = fields.join(",");
    std::fs::write(&nodes, lines.join("\n")).unwrap();
    let m = message(&[run_s, "--no-svg"]);
    assert!(
        m.contains(&format!("{}:4:x: `1.0.0` is not a number", nodes.display())),
        "{m}"
    );
}
