//! `fdem mesh`: one particle mesh, its statistics and optionally a VTU file.

use super::specimen::OrderArg;
use super::{Format, positive_number};
use anyhow::{Context, bail};
use fdem_mesh::{Sizing, SphereSpec, sphere_mesh};
use serde_json::json;
use std::path::PathBuf;

/// How the mesh is sized relative to the nominal diameter.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SizingArg {
    /// Surface vertices on the sphere of the nominal diameter (default; the paper's reading).
    Inscribed,
    /// Scaled so that the mesh volume equals pi d^3 / 6.
    VolumeEquivalent,
}

/// Arguments of `fdem mesh`.
#[derive(clap::Args, Debug)]
pub struct MeshArgs {
    /// Icosahedron subdivision level, 0 to 4 (20/80/320/1280/5120 tetrahedra).
    #[arg(long, default_value_t = 1)]
    level: u32,
    /// Element order.
    #[arg(long, value_enum, default_value_t = OrderArg::Quadratic)]
    order: OrderArg,
    /// Nominal particle diameter in metres.
    #[arg(long, default_value = "0.015", allow_hyphen_values = true)]
    diameter: String,
    /// Mesh sizing.
    #[arg(long, value_enum, default_value_t = SizingArg::Inscribed)]
    sizing: SizingArg,
    /// Print the statistics as one JSON object.
    #[arg(long)]
    json: bool,
    /// Write the mesh as a VTK XML unstructured grid (.vtu) to this file.
    #[arg(long, value_name = "FILE")]
    vtu: Option<PathBuf>,
}

/// Builds the mesh, prints its statistics and writes the VTU file if asked.
pub fn run(args: &MeshArgs) -> anyhow::Result<()> {
    let diameter = positive_number("--diameter", &args.diameter)?;
    if args.level > 4 {
        bail!(
            "--level {} is out of range; use a subdivision level from 0 to 4",
            args.level
        );
    }
    let spec = SphereSpec {
        level: args.level,
        order: args.order.order(),
        diameter,
        sizing: match args.sizing {
            SizingArg::Inscribed => Sizing::Inscribed,
            SizingArg::VolumeEquivalent => Sizing::VolumeEquivalent,
        },
    };
    let mesh = sphere_mesh(&spec)?;
    let quality = mesh.quality();
    let sphere_volume = std::f64::consts::PI * diameter.powi(3) / 6.0;
    if let Some(path) = &args.vtu {
        mesh.write_vtu(path)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let format = if args.json {
        Format::Json
    } else {
        Format::Table
    };
    match format {
        Format::Json => {
            let out = json!({
                "level": args.level,
                "order": spec.order,
                "diameter": diameter,
                "sizing": spec.sizing,
                "tets": mesh.n_elements(),
                "nodes": mesh.n_nodes(),
                "surface_triangles": mesh.surface.triangles.len(),
                "surface_nodes": mesh.surface.nodes.len(),
                "volume": quality.volume,
                "volume_ratio_to_sphere": quality.volume / sphere_volume,
                "surface_area": quality.surface_area,
                "min_edge": quality.min_edge,
                "max_edge": quality.max_edge,
                "min_altitude": quality.min_altitude,
                "min_dihedral_deg": quality.min_dihedral_deg,
                "max_dihedral_deg": quality.max_dihedral_deg,
            });
            println!("{}", serde_json::to_string_pretty(&out)?);
        }
        Format::Table => {
            println!(
                "sphere mesh: level {}, {:?}, diameter {diameter} m, {:?}",
                args.level, spec.order, spec.sizing
            );
            println!("  tetrahedra         {}", mesh.n_elements());
            println!("  nodes              {}", mesh.n_nodes());
            println!("  surface triangles  {}", mesh.surface.triangles.len());
            println!("  surface nodes      {}", mesh.surface.nodes.len());
            println!(
                "  volume             {:.6e} m^3 ({:.4} of the sphere)",
                quality.volume,
                quality.volume / sphere_volume
            );
            println!("  surface area       {:.6e} m^2", quality.surface_area);
            println!(
                "  edge min / max     {:.6e} / {:.6e} m",
                quality.min_edge, quality.max_edge
            );
            println!("  smallest altitude  {:.6e} m", quality.min_altitude);
            println!(
                "  dihedral min / max {:.2} / {:.2} deg",
                quality.min_dihedral_deg, quality.max_dihedral_deg
            );
            if let Some(path) = &args.vtu {
                println!("  written            {}", path.display());
            }
        }
    }
    Ok(())
}
