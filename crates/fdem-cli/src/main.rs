//! `fdem`: the command-line front end of the fdem workspace.
//!
//! It parses arguments, calls the library crates and prints; it holds no physics. Every
//! error is printed as one line on stderr with a non-zero exit code.

mod commands;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Large arrays on huge pages (`fdem_core::huge_pages`): fewer address-translation misses
/// in the contact passes of large models.
#[global_allocator]
static ALLOCATOR: fdem_core::huge_pages::HugePages = fdem_core::huge_pages::HugePages;

/// Fast, verified FDEM simulation of granular materials.
#[derive(Parser, Debug)]
#[command(name = "fdem", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Print the exact-scaling factors (paper Table 1), or exactly scale a scene file.
    // A negative number is a value to check (and refuse with its range), not a flag.
    #[command(allow_negative_numbers = true)]
    Scale(commands::scale::ScaleArgs),
    /// Build a tetrahedral sphere mesh and print its statistics (optionally write VTU).
    // A negative number is a value to check (and refuse with its range), not a flag.
    #[command(allow_negative_numbers = true)]
    Mesh(commands::mesh::MeshArgs),
    /// Run a scene file (TOML) and write its outputs to a directory.
    // A negative number is a value to check (and refuse with its range), not a flag.
    #[command(allow_negative_numbers = true)]
    Run(commands::run::RunArgs),
    /// Coarse-grain a scene: particle sizes x h in the same domain (optionally with exact scaling).
    // A negative number is a value to check (and refuse with its range), not a flag.
    #[command(allow_negative_numbers = true)]
    Coarsen(commands::coarsen::CoarsenArgs),
    /// Specimens of the triaxial test: counts, preparation by the dynamic method, saved files.
    // A negative number is a value to check (and refuse with its range), not a flag.
    #[command(allow_negative_numbers = true)]
    Specimen(commands::specimen::SpecimenArgs),
    /// The triaxial test end to end: prepare (or reuse) a specimen, consolidate, shear, write curve.csv, summary.json, plots and peak contacts.
    // A negative number is a value to check (and refuse with its range), not a flag.
    #[command(allow_negative_numbers = true)]
    Triaxial(commands::triaxial::TriaxialArgs),
    /// Finished triaxial tests side by side: curves on one chart, results and costs against the first run.
    // A negative number is a value to check (and refuse with its range), not a flag.
    #[command(allow_negative_numbers = true)]
    Compare(commands::compare::CompareArgs),
    /// A coarse-graining study: series of triaxial tests over seeds, errors against the original, cost, charts and RESULTS.md (finished runs are reused).
    // A negative number is a value to check (and refuse with its range), not a flag.
    #[command(allow_negative_numbers = true)]
    Study(commands::study::StudyArgs),
    /// Stability maps: the test model of a dense packing at multiples of its stable step, over the penalty and the damping, for rigid, linear and quadratic particles; STABILITY.md.
    Stability(commands::stability::StabilityArgs),
    /// Contact-force micro-analysis of contact snapshots: DBSCAN clustering into particle contacts, statistics, validation, force_distribution.svg.
    // A negative number is a value to check (and refuse with its range), not a flag.
    #[command(allow_negative_numbers = true)]
    Micro(commands::micro::MicroArgs),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // Help and version go to stdout with success; real parse errors are one line.
            if !e.use_stderr() {
                let _ = e.print();
                return ExitCode::SUCCESS;
            }
            // Clap's message up to the usage block, folded onto one line.
            let text = e.to_string();
            let message: Vec<&str> = text
                .lines()
                .take_while(|l| !l.trim().is_empty())
                .map(str::trim)
                .collect();
            eprintln!("{} (see `fdem --help`)", message.join(" "));
            return ExitCode::from(2);
        }
    };
    let result = match cli.command {
        Command::Scale(args) => commands::scale::run(&args),
        Command::Mesh(args) => commands::mesh::run(&args),
        Command::Run(args) => commands::on_pool(args.threads, || commands::run::run(&args)),
        Command::Micro(args) => commands::micro::run(&args),
        Command::Coarsen(args) => commands::coarsen::run(&args),
        Command::Specimen(args) => {
            commands::on_pool(args.threads, || commands::specimen::run(&args))
        }
        Command::Triaxial(args) => {
            commands::on_pool(args.threads, || commands::triaxial::run(&args))
        }
        Command::Compare(args) => commands::compare::run(&args),
        Command::Study(args) => commands::on_pool(args.threads, || commands::study::run(&args)),
        Command::Stability(args) => {
            commands::on_pool(args.threads, || commands::stability::run(&args))
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
