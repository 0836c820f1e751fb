//! One module per subcommand.

pub mod mesh;
pub mod run;
pub mod scale;

use anyhow::{Context, bail};

/// Output format shared by the subcommands that print results.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Format {
    /// Human-readable table.
    #[default]
    Table,
    /// One JSON object on stdout.
    Json,
}

/// Parses a strictly positive, finite number given on the command line as `flag`.
pub fn positive_number(flag: &str, text: &str) -> anyhow::Result<f64> {
    let value: f64 = text
        .trim()
        .parse()
        .ok()
        .with_context(|| format!("{flag} must be a positive number, got '{text}'"))?;
    if !value.is_finite() || value <= 0.0 {
        bail!("{flag} must be a positive finite number, got '{text}'");
    }
    Ok(value)
}
