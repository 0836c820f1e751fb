//! `cargo xtask compare-builds`: two or more `fdem` binaries run the same command in alternated
//! rounds, and the runs' wall times and per-step costs side by side.
//!
//! A shared or virtual machine changes speed by tens of percent within an hour, so a
//! figure of one binary taken an hour before a figure of another says little. Here every
//! round runs each binary once, in an order that turns by one binary each round (so that
//! none always runs first), and the ratios are taken round by round as well as between
//! the medians. Each run writes its outputs into a directory of its own; the runs of one
//! round are compared file by file with the first binary's, so a speed change that should
//! leave the results alone shows whether it did. `runs.csv` gets each round's rows when
//! the round ends, so an interrupted comparison keeps its finished rounds.

use anyhow::{Context, bail};
use fdem_core::statistics::median;
use fdem_triaxial::RunCost;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The result files of a triaxial run compared between the binaries of a round.
const RESULT_FILES: &[&str] = &[
    "curve.csv",
    "consolidation.csv",
    "contacts_peak.csv",
    "pairs_peak.csv",
];

const USAGE: &str = "usage: cargo xtask compare-builds [--rounds N] [--out DIR] NAME=BINARY NAME=BINARY [...] -- ARGS...
  runs `BINARY ARGS... --out DIR/NAME-rK` for every binary in every round K, in an order that
  turns each round; writes DIR/runs.csv and prints each binary's min / median / max (wall,
  consolidation and shear ms per step, peak RSS) and its ratios to the first binary. Defaults: --rounds 3, --out out/compare-builds.
  `fdem compare --run A=DIR/A-r1 --run B=DIR/B-r1 --out DIR2` then draws two runs' curves together.
  example: cargo xtask compare-builds --rounds 5 before=/tmp/fdem-before after=target/release/fdem -- triaxial --quick --fresh --threads 2";

/// What the command line asks for.
#[derive(Debug, PartialEq)]
struct Plan {
    rounds: usize,
    out: PathBuf,
    binaries: Vec<(String, PathBuf)>,
    args: Vec<String>,
}

/// Reads `[--rounds N] [--out DIR] NAME=BINARY... -- ARGS...`.
fn parse(rest: &[String]) -> anyhow::Result<Plan> {
    let Some(split) = rest.iter().position(|a| a == "--") else {
        bail!("the command to run is missing: put it after `--`\n{USAGE}");
    };
    let (own, args) = (&rest[..split], rest[split + 1..].to_vec());
    if args.is_empty() {
        bail!("nothing to run after `--`: give the fdem command, e.g. `triaxial --quick`\n{USAGE}");
    }
    if args.iter().any(|a| a == "--out" || a.starts_with("--out=")) {
        bail!(
            "`--out` after `--`: each run gets a directory of its own; give `--out DIR` before `--`"
        );
    }
    let mut plan = Plan {
        rounds: 3,
        out: PathBuf::from("out/compare-builds"),
        binaries: Vec::new(),
        args,
    };
    let mut it = own.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--rounds" => {
                let v = it.next().context("`--rounds` needs a number")?;
                plan.rounds = v
                    .parse()
                    .ok()
                    .filter(|&n| n > 0)
                    .with_context(|| format!("`--rounds {v}`: give a whole number >= 1"))?;
            }
            "--out" => plan.out = PathBuf::from(it.next().context("`--out` needs a directory")?),
            other if other.starts_with('-') => {
                bail!(
                    "unknown option '{other}' before `--`: give --rounds N or --out DIR (each with a space before its value)\n{USAGE}"
                );
            }
            other => {
                let Some((name, path)) = other.split_once('=') else {
                    bail!(
                        "'{other}': give each binary as NAME=PATH, e.g. before=/tmp/fdem-before\n{USAGE}"
                    );
                };
                let valid = |c: char| c.is_ascii_alphanumeric() || c == '-' || c == '_';
                if name.is_empty() || !name.chars().all(valid) {
                    bail!("'{other}': a binary's name may hold letters, digits, '-' and '_' only");
                }
                if plan.binaries.iter().any(|(n, _)| n == name) {
                    bail!("the name '{name}' is given twice: give each binary its own name");
                }
                plan.binaries.push((name.to_string(), PathBuf::from(path)));
            }
        }
    }
    if plan.binaries.len() < 2 {
        bail!("give at least two binaries to compare, as NAME=PATH\n{USAGE}");
    }
    for (name, path) in &plan.binaries {
        if !path.is_file() {
            bail!(
                "binary '{name}' = {}: no such file (build it, then copy it aside, e.g. `cp target/release/fdem /tmp/fdem-before`)",
                path.display()
            );
        }
    }
    Ok(plan)
}

/// One run's figures.
#[derive(Clone, Debug, Default, PartialEq)]
struct Run {
    round: usize,
    binary: String,
    wall: f64,
    /// `summary.json`'s status, or why it could not be read.
    status: String,
    /// Peak resident set size (kB), where the system reports it.
    peak_rss_kb: Option<u64>,
    /// (steps, ms per step) of the consolidation and of the shear.
    consolidation: Option<(u64, f64)>,
    shear: Option<(u64, f64)>,
    /// Whether the result files equal those of the first binary's run in the same round
    /// (None for that binary).
    same: Option<bool>,
}

/// The order of the binaries in round `r` (from 0): turned by `r`.
fn order(n: usize, r: usize) -> Vec<usize> {
    (0..n).map(|i| (i + r) % n).collect()
}

/// A phase's steps and wall seconds as `(steps, milliseconds per step)`, where it ran.
fn per_step(steps: u64, wall_seconds: f64) -> Option<(u64, f64)> {
    (steps > 0 && wall_seconds.is_finite()).then(|| (steps, 1e3 * wall_seconds / steps as f64))
}

/// Reads the status and the phases' costs of the run in `dir` (docs/TRIAXIAL.md,
/// `summary.json`, read by [`RunCost::of_summary`]); other commands have no summary and
/// keep their wall time alone.
fn read_summary(dir: &Path, run: &mut Run) {
    let path = dir.join("summary.json");
    let Ok(text) = std::fs::read_to_string(&path) else {
        run.status = "no summary.json".into();
        return;
    };
    let Ok(v) = serde_json::from_str::<serde_json::Value>(&text) else {
        run.status = "summary.json unreadable".into();
        return;
    };
    run.status = v["status"].as_str().unwrap_or("?").to_string();
    let cost = RunCost::of_summary(&v);
    run.consolidation = per_step(cost.consolidation_steps, cost.consolidation_wall);
    run.shear = per_step(cost.shear_steps, cost.shear_wall);
}

/// Whether the result files present in `a` are present and byte-identical in `b`.
fn same_results(a: &Path, b: &Path) -> anyhow::Result<bool> {
    for f in RESULT_FILES {
        let (pa, pb) = (a.join(f), b.join(f));
        match (pa.is_file(), pb.is_file()) {
            (false, false) => continue,
            (true, true) => {
                let read =
                    |p: &Path| std::fs::read(p).with_context(|| format!("reading {}", p.display()));
                if read(&pa)? != read(&pb)? {
                    return Ok(false);
                }
            }
            _ => return Ok(false),
        }
    }
    Ok(true)
}

/// The median of the figures `v` (all finite: [`Figure::of`] gives none that is not).
fn median_of(v: &[f64]) -> Option<f64> {
    median(&mut v.to_vec())
}

/// `min / median / max` of `v`, with `digits` decimals, or `-`.
fn spread(v: &[f64], digits: usize) -> String {
    let min = v.iter().copied().fold(f64::INFINITY, f64::min);
    let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    match median_of(v) {
        Some(m) => format!("{min:.digits$} / {m:.digits$} / {max:.digits$}"),
        None => "-".into(),
    }
}

const CSV_HEADER: &str = "round,binary,wall_s,peak_rss_kb,status,consolidation_steps,consolidation_ms_per_step,shear_steps,shear_ms_per_step,same_results_as_first";

fn csv_row(r: &Run) -> String {
    let phase = |p: Option<(u64, f64)>| p.map_or(",".into(), |(s, ms)| format!("{s},{ms:.6}"));
    let same = r.same.map_or("", |s| if s { "yes" } else { "no" });
    let rss = r.peak_rss_kb.map_or(String::new(), |kb| kb.to_string());
    format!(
        "{},{},{:.3},{rss},{},{},{},{}",
        r.round,
        r.binary,
        r.wall,
        r.status.replace(',', ";"),
        phase(r.consolidation),
        phase(r.shear),
        same
    )
}

/// Runs binary `name` at `path` once into `dir`, its output into `log`.
fn run_once(
    (name, path): (&str, &Path),
    args: &[String],
    dir: &Path,
    log: &Path,
    round: usize,
) -> anyhow::Result<Run> {
    if dir.exists() {
        std::fs::remove_dir_all(dir).with_context(|| format!("clearing {}", dir.display()))?;
    }
    let out = std::fs::File::create(log).with_context(|| format!("creating {}", log.display()))?;
    let err = out.try_clone()?;
    let start = Instant::now();
    let mut child = std::process::Command::new(path)
        .args(args)
        .arg("--out")
        .arg(dir)
        .stdout(out)
        .stderr(err)
        .spawn()
        .with_context(|| format!("starting {}", path.display()))?;
    let (status, peak_rss_kb) = wait_with_peak_rss(&mut child)?;
    let wall = start.elapsed().as_secs_f64();
    if !status.success() {
        bail!(
            "binary '{name}' failed in round {round} ({status}); its output is in {}",
            log.display()
        );
    }
    let mut run = Run {
        round,
        binary: name.to_string(),
        wall,
        peak_rss_kb,
        ..Run::default()
    };
    read_summary(dir, &mut run);
    Ok(run)
}

/// Waits for `child`: its exit status, and on Linux its peak resident set size (kB) from
/// the kernel's accounting of the reaped process (`wait4`, the figure `/usr/bin/time`
/// prints as its maximum resident set size).
#[cfg(target_os = "linux")]
fn wait_with_peak_rss(
    child: &mut std::process::Child,
) -> anyhow::Result<(std::process::ExitStatus, Option<u64>)> {
    use std::os::unix::process::ExitStatusExt;
    let pid = libc::pid_t::try_from(child.id()).context("a process id out of range")?;
    let mut status: libc::c_int = 0;
    // SAFETY: `rusage` is a plain C struct of integers, for which all zeros is a value.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    loop {
        // SAFETY: `pid` is our own child, not yet reaped (`child` is not waited on before
        // or after this), and `status` and `usage` are valid for writes.
        let reaped = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
        if reaped == pid {
            break;
        }
        let e = std::io::Error::last_os_error();
        if e.kind() != std::io::ErrorKind::Interrupted {
            return Err(e).context("waiting for the run");
        }
    }
    let peak = u64::try_from(usage.ru_maxrss).ok();
    Ok((std::process::ExitStatus::from_raw(status), peak))
}

/// Waits for `child`: its exit status (no peak memory on this system).
#[cfg(not(target_os = "linux"))]
fn wait_with_peak_rss(
    child: &mut std::process::Child,
) -> anyhow::Result<(std::process::ExitStatus, Option<u64>)> {
    Ok((child.wait().context("waiting for the run")?, None))
}

/// A figure of a run that the report sets side by side.
#[derive(Clone, Copy, Debug)]
enum Figure {
    Wall,
    ConsolidationStep,
    ShearStep,
    PeakRss,
}

impl Figure {
    const ALL: [Figure; 4] = [
        Figure::Wall,
        Figure::ConsolidationStep,
        Figure::ShearStep,
        Figure::PeakRss,
    ];

    fn label(self) -> &'static str {
        match self {
            Figure::Wall => "wall (s)",
            Figure::ConsolidationStep => "consolidation (ms/step)",
            Figure::ShearStep => "shear (ms/step)",
            Figure::PeakRss => "peak RSS (MiB)",
        }
    }

    fn of(self, r: &Run) -> Option<f64> {
        match self {
            Figure::Wall => Some(r.wall),
            Figure::ConsolidationStep => r.consolidation.map(|c| c.1),
            Figure::ShearStep => r.shear.map(|c| c.1),
            Figure::PeakRss => r.peak_rss_kb.map(|kb| kb as f64 / 1024.0),
        }
    }
}

/// Figure `f` of binary `name`'s runs, round by round.
fn values(runs: &[Run], name: &str, f: Figure) -> Vec<f64> {
    runs.iter()
        .filter(|r| r.binary == name)
        .filter_map(|r| f.of(r))
        .collect()
}

/// Figure `f` of binary `name`'s run in `round`.
fn in_round(runs: &[Run], name: &str, round: usize, f: Figure) -> Option<f64> {
    runs.iter()
        .find(|r| r.binary == name && r.round == round)
        .and_then(|r| f.of(r))
}

/// Prints each binary's figures and its ratios to the first binary.
fn report(plan: &Plan, runs: &[Run]) {
    let first = &plan.binaries[0].0;
    let rounds = if plan.rounds == 1 { "round" } else { "rounds" };
    println!("\nmin / median / max over {} {rounds}:", plan.rounds);
    for (name, _) in &plan.binaries {
        let parts: Vec<String> = Figure::ALL
            .iter()
            .map(|&f| format!("{} {}", f.label(), spread(&values(runs, name, f), 3)))
            .collect();
        println!("  {name}: {}", parts.join("; "));
    }
    for (name, _) in plan.binaries.iter().skip(1) {
        println!("  {first} over {name} (above 1: {name} is faster, or smaller in memory):");
        for f in Figure::ALL {
            let medians = median_of(&values(runs, first, f)).zip(median_of(&values(runs, name, f)));
            let Some((a, b)) = medians else {
                continue;
            };
            let by_round: Vec<String> = (1..=plan.rounds)
                .filter_map(|k| Some(in_round(runs, first, k, f)? / in_round(runs, name, k, f)?))
                .map(|x| format!("{x:.3}"))
                .collect();
            println!(
                "    {}: {:.3} at the medians; by round {}",
                f.label(),
                a / b,
                by_round.join(" / ")
            );
        }
        let theirs = || runs.iter().filter(|r| r.binary == *name);
        let differ = theirs().filter(|r| r.same == Some(false)).count();
        if differ > 0 {
            println!(
                "    results differ from {first}'s in {differ} of {} rounds",
                plan.rounds
            );
        } else if theirs().any(|r| r.same == Some(true)) {
            println!("    results byte-identical to {first}'s in every round");
        }
    }
}

/// `cargo xtask compare-builds`.
pub(crate) fn compare_builds(rest: &[String]) -> anyhow::Result<()> {
    if rest.iter().any(|a| a == "-h" || a == "--help") {
        println!("{USAGE}");
        return Ok(());
    }
    let plan = parse(rest)?;
    let logs = plan.out.join("logs");
    std::fs::create_dir_all(&logs).with_context(|| format!("creating {}", logs.display()))?;
    let csv_path = plan.out.join("runs.csv");
    let mut csv = std::fs::File::create(&csv_path)
        .with_context(|| format!("creating {}", csv_path.display()))?;
    writeln!(csv, "{CSV_HEADER}")?;
    let n = plan.binaries.len();
    eprintln!(
        "{} round(s) of {n} binaries: {} runs of `BINARY {} --out {}/NAME-rK`, one after another",
        plan.rounds,
        plan.rounds * n,
        plan.args.join(" "),
        plan.out.display()
    );
    let mut runs: Vec<Run> = Vec::new();
    for round in 1..=plan.rounds {
        let dir_of = |name: &str| plan.out.join(format!("{name}-r{round}"));
        let mut this_round: Vec<Run> = Vec::new();
        for i in order(n, round - 1) {
            let (name, path) = (&plan.binaries[i].0, &plan.binaries[i].1);
            let log = logs.join(format!("{name}-r{round}.txt"));
            let run = run_once((name, path), &plan.args, &dir_of(name), &log, round)?;
            let shear = run.shear.map(|(_, ms)| format!(", shear {ms:.3} ms/step"));
            eprintln!(
                "round {round}/{}: {name} {:.2} s{}",
                plan.rounds,
                run.wall,
                shear.unwrap_or_default()
            );
            this_round.push(run);
        }
        // Every other binary's results against the first binary's of the same round.
        let first = dir_of(&plan.binaries[0].0);
        for run in this_round.iter_mut() {
            if run.binary != plan.binaries[0].0 {
                run.same = Some(same_results(&first, &dir_of(&run.binary))?);
            }
        }
        this_round.sort_by_key(|r| plan.binaries.iter().position(|(b, _)| *b == r.binary));
        for run in &this_round {
            writeln!(csv, "{}", csv_row(run))?;
        }
        csv.flush()?;
        runs.extend(this_round);
    }
    report(&plan, &runs);
    println!("per run: {}", csv_path.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(s: &str) -> Vec<String> {
        s.split_whitespace().map(String::from).collect()
    }

    #[test]
    fn a_plan_reads_its_binaries_rounds_and_command() {
        let exe = std::env::current_exe().unwrap();
        let e = exe.display();
        let plan = parse(&args(&format!(
            "--rounds 4 --out o a={e} b={e} -- triaxial --quick"
        )))
        .unwrap();
        assert_eq!(plan.rounds, 4);
        assert_eq!(plan.out, PathBuf::from("o"));
        assert_eq!(plan.binaries.len(), 2);
        assert_eq!(plan.binaries[1].0, "b");
        assert_eq!(plan.args, args("triaxial --quick"));
    }

    #[test]
    fn bad_command_lines_say_what_to_do() {
        let exe = std::env::current_exe().unwrap();
        let e = exe.display();
        let cases = [
            (format!("a={e} b={e}"), "after `--`"),
            (format!("a={e} b={e} --"), "nothing to run"),
            (format!("a={e} -- triaxial"), "at least two"),
            (format!("a={e} a={e} -- triaxial"), "given twice"),
            (format!("a={e} b=/no/such/fdem -- triaxial"), "no such file"),
            (
                format!("a={e} b={e} -- triaxial --out x"),
                "directory of its own",
            ),
            (
                format!("--rounds 0 a={e} b={e} -- triaxial"),
                "whole number",
            ),
            (format!("a/b={e} c={e} -- triaxial"), "letters, digits"),
            (format!("{e} c={e} -- triaxial"), "NAME=PATH"),
            (
                format!("--rounds=2 a={e} b={e} -- triaxial"),
                "unknown option",
            ),
        ];
        for (line, expected) in cases {
            let err = parse(&args(&line)).unwrap_err().to_string();
            assert!(err.contains(expected), "{line}: {err}");
        }
    }

    #[test]
    fn each_round_turns_the_order() {
        assert_eq!(order(2, 0), [0, 1]);
        assert_eq!(order(2, 1), [1, 0]);
        assert_eq!(order(3, 2), [2, 0, 1]);
    }

    #[test]
    fn medians_and_spreads() {
        assert_eq!(median_of(&[4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(median_of(&[]), None);
        assert_eq!(spread(&[2.0, 1.0, 4.0], 1), "1.0 / 2.0 / 4.0");
        assert_eq!(spread(&[], 1), "-");
    }

    #[test]
    fn a_summary_gives_the_phases_per_step() {
        let dir = std::env::temp_dir().join(format!("xtask-compare-builds-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let summary = r#"{"status": "completed", "consolidation": {"cost": {"steps": 100, "wall_seconds": 0.05}},
                         "shear": {"steps": 200, "wall_seconds": 0.2}}"#;
        std::fs::write(dir.join("summary.json"), summary).unwrap();
        let mut run = Run::default();
        read_summary(&dir, &mut run);
        assert_eq!(run.status, "completed");
        let (steps, ms) = run.consolidation.unwrap();
        assert_eq!(steps, 100);
        assert!((ms - 0.5).abs() < 1e-12);
        let (steps, ms) = run.shear.unwrap();
        assert_eq!(steps, 200);
        assert!((ms - 1.0).abs() < 1e-12);
        // Result files: equal, then one byte changed, then one missing.
        let other = dir.join("other");
        std::fs::create_dir_all(&other).unwrap();
        std::fs::write(dir.join("curve.csv"), "a,b\n1,2\n").unwrap();
        std::fs::write(other.join("curve.csv"), "a,b\n1,2\n").unwrap();
        assert!(same_results(&dir, &other).unwrap());
        std::fs::write(other.join("curve.csv"), "a,b\n1,3\n").unwrap();
        assert!(!same_results(&dir, &other).unwrap());
        std::fs::remove_file(other.join("curve.csv")).unwrap();
        assert!(!same_results(&dir, &other).unwrap());
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(
            csv_row(&run),
            "0,,0.000,,completed,100,0.500000,200,1.000000,"
        );
    }

    /// Writes an executable stand-in for `fdem` that writes a summary and a curve (`curve`)
    /// into the directory after its `--out`.
    #[cfg(unix)]
    fn fake_fdem(dir: &Path, name: &str, curve: &str) -> PathBuf {
        use std::os::unix::fs::PermissionsExt;
        let path = dir.join(name);
        let script = format!(
            "#!/bin/sh\nfor a; do out=$a; done\nmkdir -p \"$out\"\n\
             printf '{{\"status\": \"completed\", \"consolidation\": {{\"cost\": {{\"steps\": 10, \"wall_seconds\": 0.01}}}}, \"shear\": {{\"steps\": 20, \"wall_seconds\": 0.04}}}}' > \"$out/summary.json\"\n\
             printf '{curve}' > \"$out/curve.csv\"\n"
        );
        std::fs::write(&path, script).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
        path
    }

    #[cfg(unix)]
    #[test]
    fn a_comparison_runs_every_binary_in_every_round_and_compares_their_results() {
        let dir = tempfile::tempdir().unwrap();
        let same = fake_fdem(dir.path(), "same", "a,b 1,2");
        let twin = fake_fdem(dir.path(), "twin", "a,b 1,2");
        let other = fake_fdem(dir.path(), "other", "a,b 1,3");
        let out = dir.path().join("out");
        let line = format!(
            "--rounds 2 --out {} first={} twin={} other={} -- triaxial --quick",
            out.display(),
            same.display(),
            twin.display(),
            other.display()
        );
        compare_builds(&args(&line)).unwrap();
        let csv = std::fs::read_to_string(out.join("runs.csv")).unwrap();
        let rows: Vec<Vec<&str>> = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect())
            .collect();
        assert_eq!(rows.len(), 6, "{csv}");
        // Within a round the rows follow the binaries' order, whatever order they ran in.
        let names: Vec<&str> = rows.iter().map(|r| r[1]).collect();
        assert_eq!(names, ["first", "twin", "other", "first", "twin", "other"]);
        for r in &rows {
            assert_eq!(r[4], "completed", "{csv}");
            assert_eq!((r[5], r[7]), ("10", "20"), "{csv}");
            assert!((r[6].parse::<f64>().unwrap() - 1.0).abs() < 1e-9, "{csv}");
            assert!((r[8].parse::<f64>().unwrap() - 2.0).abs() < 1e-9, "{csv}");
            if cfg!(target_os = "linux") {
                assert!(r[3].parse::<u64>().unwrap() > 0, "{csv}");
            }
        }
        let verdicts: Vec<&str> = rows.iter().map(|r| r[9]).collect();
        assert_eq!(verdicts, ["", "yes", "no", "", "yes", "no"]);
        assert!(out.join("logs").join("other-r2.txt").is_file());
        // A binary that fails stops the comparison with where its output is.
        let failing = dir.path().join("failing");
        std::fs::write(&failing, "#!/bin/sh\necho broken >&2\nexit 3\n").unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&failing, std::fs::Permissions::from_mode(0o755)).unwrap();
        let line = format!(
            "--rounds 1 --out {} first={} failing={} -- triaxial",
            out.display(),
            same.display(),
            failing.display()
        );
        let err = compare_builds(&args(&line)).unwrap_err().to_string();
        assert!(
            err.contains("'failing' failed in round 1") && err.contains("failing-r1.txt"),
            "{err}"
        );
    }
}
