//! `fdem scale`: the exact-scaling table derived from dimensions.

use super::{Format, positive_number};
use fdem_scaling::{ScaleLaw, table};
use serde_json::{Map, Value, json};
use std::path::PathBuf;

/// Arguments of `fdem scale`.
#[derive(clap::Args, Debug)]
pub struct ScaleArgs {
    /// Scene file to scale exactly (omit to print the factor table only).
    scene: Option<PathBuf>,
    /// Where to write the scaled scene (required with a scene).
    #[arg(long, value_name = "FILE", requires = "scene")]
    out: Option<PathBuf>,
    /// Length scale factor h (> 0): the scaled system's lengths are h times the original's.
    #[arg(long = "h", value_name = "H", allow_hyphen_values = true)]
    h: String,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Table)]
    format: Format,
}

/// Prints the factor of every catalogued quantity under exact scaling by `h`.
pub fn run(args: &ScaleArgs) -> anyhow::Result<()> {
    let h = positive_number("--h", &args.h)?;
    let law = ScaleLaw::exact(h)?;
    if let Some(scene_path) = &args.scene {
        let out = args
            .out
            .as_ref()
            .ok_or_else(|| anyhow::anyhow!("--out FILE is required when scaling a scene"))?;
        let scene = fdem_solver::Scene::load(scene_path)?;
        let (scaled, applied) = scene.scaled(&law);
        super::write_scene(
            &scaled,
            out,
            &format!("exactly scaled by h = {h} from {}", scene_path.display()),
        )?;
        super::print_applied(&applied, args.format)?;
        return Ok(());
    }
    let rows = table(&law);
    match args.format {
        Format::Json => {
            let mut factors = Map::new();
            let mut dimensions = Map::new();
            for row in &rows {
                factors.insert(row.quantity.name.into(), json!(row.factor));
                dimensions.insert(
                    row.quantity.name.into(),
                    Value::String(row.quantity.dimension.to_string()),
                );
            }
            let out = json!({
                "h": h,
                "law": "exact (density and youngs_modulus invariant)",
                "base_factors": {"length": law.length, "time": law.time, "mass": law.mass},
                "factors": factors,
                "dimensions": dimensions,
            });
            println!("{}", serde_json::to_string_pretty(&out)?);
        }
        Format::Table => {
            println!("Exact scaling, h = {h} (density and Young's modulus held invariant)");
            println!(
                "base factors: lambda_L = {}, lambda_T = {}, lambda_M = {}",
                law.length, law.time, law.mass
            );
            println!();
            println!(
                "{:<20} {:<8} {:<8} {:<12} {:>14}",
                "quantity", "symbol", "unit", "dimension", "factor"
            );
            for row in &rows {
                let q = row.quantity;
                println!(
                    "{:<20} {:<8} {:<8} {:<12} {:>14}",
                    q.name,
                    q.symbol,
                    q.unit,
                    q.dimension.to_string(),
                    format_factor(row.factor)
                );
            }
        }
    }
    Ok(())
}

fn format_factor(f: f64) -> String {
    if (1e-4..1e9).contains(&f.abs()) {
        format!("{f}")
    } else {
        format!("{f:e}")
    }
}
