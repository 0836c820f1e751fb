//! `fdem micro` as a stand-alone program: the CLI module of fdem-cli compiled here, for
//! trying it without the `fdem` binary.
//!
//! ```text
//! cargo run --release -p fdem-micro --example micro_cli -- RUN_DIR [OPTIONS]
//! ```

#[path = "../../fdem-cli/src/commands/micro.rs"]
mod micro;

use clap::Parser;

/// Contact-force micro-analysis of contact snapshots.
#[derive(Parser, Debug)]
struct Cli {
    #[command(flatten)]
    args: micro::MicroArgs,
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    match micro::run(&cli.args) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
