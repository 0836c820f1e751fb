//! The cost of a full broad-phase build on a bench lattice, in plain steps, measured
//! build by build.
//!
//! `cargo run --release -p fdem-benches --example build_cost -- [LATTICE [THREADS
//! [ROUNDS]]]` (defaults `8k 1 30`; LATTICE is a label of `fdem_benches::lattice`:
//! `1k`, `8k`, `8k-shuffled`, `64k`, `64k-shuffled`). Each round times one plain
//! evaluation (`add_forces` on the lists it has) and then one with a full rebuild, one
//! right after the other, so that both meet the host in the same state; the build's cost
//! is their difference, in milliseconds and in plain steps. The contact bench's
//! `rebuild+step` and `Hand` medians give the same difference from two measurements
//! taken minutes apart, which a host whose speed swings from minute to minute can move by
//! more than the build itself.
//!
//! Prints one CSV row per round (`round,step_ms,rebuild_step_ms,build_ms,build_in_steps`)
//! after three rounds of warm-up, then to standard error the minimum, median and maximum
//! of the build in steps and the medians of the times.

use std::time::Instant;

use fdem_benches::lattice::{LATTICES, packing};
use fdem_core::statistics::median;

fn main() {
    if let Err(e) = run() {
        eprintln!("build_cost: {e}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let label = args.first().map_or("8k", String::as_str);
    let threads = parse(args.get(1), "THREADS", 1)?;
    let rounds = parse(args.get(2), "ROUNDS", 30)?;
    let labels: Vec<&str> = LATTICES.iter().map(|l| l.1).collect();
    let Some(&(side, _, shuffled)) = LATTICES.iter().find(|l| l.1 == label) else {
        return Err(format!(
            "unknown lattice `{label}`; use one of {}",
            labels.join(", ")
        ));
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| format!("cannot start {threads} threads: {e}"))?;
    eprintln!("build_cost: lattice {label}, {threads} thread(s), {rounds} rounds");
    let mut p = packing(side, shuffled);
    let mut forces = vec![[0.0; 3]; p.positions.len()];
    let mut step = |rebuild: bool| -> Result<f64, String> {
        if rebuild {
            p.model.request_rebuild();
        }
        let start = Instant::now();
        let r = p
            .model
            .add_forces(&p.positions, &p.velocities, 0.0, 1e-7, &mut forces)
            .map_err(|e| format!("evaluation failed: {e}"))?;
        let ms = start.elapsed().as_secs_f64() * 1e3;
        if r.rebuilt != rebuild {
            return Err(format!(
                "an evaluation rebuilt its lists = {} where {rebuild} was asked",
                r.rebuilt
            ));
        }
        Ok(ms)
    };
    let mut rows = Vec::new();
    pool.install(|| -> Result<(), String> {
        step(true)?;
        println!("round,step_ms,rebuild_step_ms,build_ms,build_in_steps");
        for round in 0..rounds.saturating_add(WARM_UP) {
            let plain = step(false)?;
            let rebuilt = step(true)?;
            if round >= WARM_UP {
                let build = rebuilt - plain;
                let row = [plain, rebuilt, build, build / plain];
                println!(
                    "{},{:.3},{:.3},{:.3},{:.3}",
                    round - WARM_UP + 1,
                    row[0],
                    row[1],
                    row[2],
                    row[3]
                );
                rows.push(row);
            }
        }
        Ok(())
    })?;
    let column = |i: usize| -> Vec<f64> { rows.iter().map(|r| r[i]).collect() };
    let mut steps = column(3);
    let mid = |mut v: Vec<f64>| median(&mut v).unwrap_or(f64::NAN);
    let in_steps = mid(steps.clone());
    steps.sort_by(f64::total_cmp);
    eprintln!(
        "build in steps: min {:.3}, median {in_steps:.3}, max {:.3}; medians: step {:.3} ms, \
         rebuild and step {:.3} ms, build {:.3} ms",
        steps[0],
        steps[steps.len() - 1],
        mid(column(0)),
        mid(column(1)),
        mid(column(2)),
    );
    Ok(())
}

/// Rounds run before the recorded ones: the first builds and steps warm the caches and
/// the allocator.
const WARM_UP: usize = 3;

fn parse(arg: Option<&String>, what: &str, default: usize) -> Result<usize, String> {
    match arg {
        None => Ok(default),
        Some(a) => match a.parse::<usize>() {
            Ok(n) if n > 0 => Ok(n),
            _ => Err(format!("{what} must be a whole number above 0, got `{a}`")),
        },
    }
}
