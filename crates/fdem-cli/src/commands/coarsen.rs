//! `fdem coarsen SCENE --h H [--exact-scaling] --out CG.toml`: coarse graining of a scene.

use super::{Format, positive_number};
use std::path::PathBuf;

/// Arguments of `fdem coarsen`.
#[derive(clap::Args, Debug)]
pub struct CoarsenArgs {
    /// Scene file to coarse-grain.
    scene: PathBuf,
    /// Coarse-graining factor h (> 0): particle diameters are multiplied by h.
    #[arg(long = "h", value_name = "H", allow_hyphen_values = true)]
    h: String,
    /// Also scale the material and contact parameters by Table 1 (exact scaling), which in
    /// a fixed domain divides the penalty by h.
    #[arg(long)]
    exact_scaling: bool,
    /// Where to write the coarse-grained scene.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Output format of the list of changed fields.
    #[arg(long, value_enum, default_value_t = Format::Table)]
    format: Format,
}

/// Coarse-grains the scene and says what changed.
pub fn run(args: &CoarsenArgs) -> anyhow::Result<()> {
    let h = positive_number("--h", &args.h)?;
    let scene = fdem_solver::Scene::load(&args.scene)?;
    let (coarse, applied) = scene.coarsened(h, args.exact_scaling)?;
    let variant = if args.exact_scaling {
        "with exact scaling"
    } else {
        "plain (parameters unchanged)"
    };
    super::write_scene(
        &coarse,
        &args.out,
        &format!(
            "coarse-grained by h = {h}, {variant}, from {}",
            args.scene.display()
        ),
    )?;
    if args.format == Format::Table {
        println!(
            "Coarse graining by h = {h}, {variant}: particle sizes x h in the same domain; \
             positions, walls, loads, velocities and times unchanged."
        );
        println!(
            "Particle positions are kept as they were: a coarse specimen holds about h^3 = {:.3} times \
             fewer particles, placed by the specimen generator, not by this transform.",
            h.powi(3)
        );
    }
    super::print_applied(&applied, args.format)?;
    Ok(())
}
