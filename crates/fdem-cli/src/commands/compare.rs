//! `fdem compare`: finished triaxial tests side by side (curves on one chart, results and
//! costs in one table against the first run).

use fdem_triaxial::{COMPARISON_HEADER, FinishedRun, write_comparison};
use std::path::PathBuf;

/// Arguments of `fdem compare`.
#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// A finished test as LABEL=DIR (its output directory); at least one, the first is the
    /// reference of the differences.
    #[arg(long = "run", value_name = "LABEL=DIR", required = true)]
    runs: Vec<String>,
    /// Directory for eta.svg, eps_v.svg and comparison.csv.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Title of the charts.
    #[arg(long, default_value = "comparison")]
    title: String,
}

/// Reads the runs, writes the charts and the table, prints the table.
pub fn run(args: &CompareArgs) -> anyhow::Result<()> {
    let mut runs = Vec::with_capacity(args.runs.len());
    for text in &args.runs {
        let Some((label, dir)) = text.split_once('=') else {
            anyhow::bail!("--run {text}: give LABEL=DIR, for example --run rigid=out/quick-rigid");
        };
        runs.push(FinishedRun::load(label, &PathBuf::from(dir))?);
    }
    let rows = write_comparison(&runs, &args.out, &args.title)?;
    println!("{COMPARISON_HEADER}");
    for row in rows {
        println!("{row}");
    }
    eprintln!(
        "wrote eta.svg, eps_v.svg and comparison.csv to {}",
        args.out.display()
    );
    Ok(())
}
