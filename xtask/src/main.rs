//! The project's task runner: `cargo xtask <task>`.
//!
//! Tasks are whole jobs built from the library crates (the CLI's job is single commands).
//! `triaxial` is the main job; until the triaxial test exists (issue 7) it runs the
//! preflight that the test will start from: the exact-scaling factors of every series of
//! the source paper and the statistics of its particle meshes. It prints nothing it did not
//! compute.

use anyhow::{Context, bail};
use fdem_mesh::{ElementOrder, Sizing, SphereSpec, sphere_mesh};
use fdem_scaling::ScaleLaw;
use std::process::ExitCode;

const USAGE: &str = "usage: cargo xtask <task>\n\ntasks:\n  triaxial   the main job (currently: the preflight of the paper's test series)\n  docs       regenerate the generated parts of docs/ (the scaling table of docs/SCALING.md)";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("triaxial") => triaxial(&args[1..]),
        Some("docs") => docs(),
        Some("-h" | "--help") | None => {
            println!("{USAGE}");
            Ok(())
        }
        Some(other) => Err(anyhow::anyhow!("unknown task '{other}'; {USAGE}")),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// One series of the paper's Table 2/4: name, particle diameter(s) in metres, h.
struct Series {
    tests: &'static str,
    diameters: &'static [f64],
    h: f64,
}

const SERIES: &[Series] = &[
    Series {
        tests: "E1",
        diameters: &[0.015],
        h: 1.0,
    },
    Series {
        tests: "E2 / E2s",
        diameters: &[0.030],
        h: 2.0,
    },
    Series {
        tests: "E3 / E3s",
        diameters: &[0.045],
        h: 3.0,
    },
    Series {
        tests: "E4 / E4s",
        diameters: &[0.060],
        h: 4.0,
    },
    Series {
        tests: "B1",
        diameters: &[0.015, 0.030],
        h: 1.0,
    },
    Series {
        tests: "B2 / B2s",
        diameters: &[0.0225, 0.045],
        h: 1.5,
    },
    Series {
        tests: "B3 / B3s",
        diameters: &[0.030, 0.060],
        h: 2.0,
    },
];

/// Paper Table 3: normal penalty p_n in N/m^3.
const NORMAL_PENALTY: f64 = 1.8e11;

fn triaxial(rest: &[String]) -> anyhow::Result<()> {
    if let Some(extra) = rest.first() {
        bail!("`cargo xtask triaxial` takes no arguments yet, got '{extra}'");
    }
    println!("fdem main job: triaxial test");
    println!(
        "The triaxial loading is not implemented yet (issues 3-7). This run prints the\n\
         preflight it will start from, all computed now by fdem-scaling and fdem-mesh.\n"
    );
    println!(
        "Coarse-graining series of the source paper (Table 4), particle meshes level 1, 10-node:"
    );
    println!(
        "{:<10} {:>5} {:>14} {:>12} {:>8} {:>8} {:>14} {:>9}",
        "tests", "h", "d (mm)", "p_n*1/h", "tets", "nodes", "volume (m^3)", "V/sphere"
    );
    for series in SERIES {
        let law = ScaleLaw::exact(series.h)?;
        let penalty_factor = law
            .factor_of("penalty_stiffness")
            .context("penalty_stiffness missing from the catalogue")?;
        for (i, &d) in series.diameters.iter().enumerate() {
            let mesh = sphere_mesh(&SphereSpec {
                level: 1,
                order: ElementOrder::Quadratic,
                diameter: d,
                sizing: Sizing::Inscribed,
            })?;
            let sphere = std::f64::consts::PI * d.powi(3) / 6.0;
            let (name, h, pen) = if i == 0 {
                (
                    series.tests.to_string(),
                    format!("{}", series.h),
                    format!("{:.4e}", NORMAL_PENALTY * penalty_factor),
                )
            } else {
                (String::new(), String::new(), String::new())
            };
            println!(
                "{:<10} {:>5} {:>14.1} {:>12} {:>8} {:>8} {:>14.4e} {:>9.4}",
                name,
                h,
                d * 1e3,
                pen,
                mesh.n_elements(),
                mesh.n_nodes(),
                mesh.volume(),
                mesh.volume() / sphere
            );
        }
    }
    println!("\np_n*1/h: the normal penalty of the exactly scaled variant (the `s` tests);");
    println!(
        "the plain variants keep p_n = {NORMAL_PENALTY:.1e} N/m^3. Full factor table: `fdem scale --h H`."
    );
    Ok(())
}

/// Markers around the generated table in docs/SCALING.md.
pub const TABLE_BEGIN: &str = "<!-- BEGIN GENERATED: cargo xtask docs -->";
/// End marker.
pub const TABLE_END: &str = "<!-- END GENERATED -->";

/// Rewrites the generated table of docs/SCALING.md from fdem-scaling.
fn docs() -> anyhow::Result<()> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/SCALING.md");
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let (Some(begin), Some(end)) = (text.find(TABLE_BEGIN), text.find(TABLE_END)) else {
        bail!("{} lacks the generated-table markers", path.display());
    };
    let table = fdem_scaling::markdown_table()?;
    let updated = format!("{}{TABLE_BEGIN}\n{table}{}", &text[..begin], &text[end..]);
    std::fs::write(&path, updated).with_context(|| format!("writing {}", path.display()))?;
    println!("regenerated the scaling table in {}", path.display());
    Ok(())
}
