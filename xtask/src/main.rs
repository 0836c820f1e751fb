//! The project's task runner: `cargo xtask <task>`.
//!
//! Tasks are whole jobs built from the library crates (the CLI's job is single commands).
//! `triaxial` is the main job: the numerical triaxial test of the paper's E4s specimen
//! (phi 300 x 600 mm, 237 particles of 60 mm, exact scaling, sigma_0 = 0.8 MPa) with
//! level-1 linear meshes to 15 % axial strain, written to `out/triaxial/`. It builds the
//! `fdem` binary in release mode and runs `fdem triaxial` (docs/TRIAXIAL.md), so that the
//! job and the command line are one code path. `preflight` prints the exact-scaling
//! factors and mesh statistics of every series of the paper; `docs` regenerates the
//! generated parts of docs/.

mod compare_builds;

use anyhow::{Context, bail};
use fdem_mesh::{ElementOrder, Sizing, SphereSpec, sphere_mesh};
use fdem_scaling::ScaleLaw;
use std::process::ExitCode;

const USAGE: &str = "usage: cargo xtask <task> [options]\n\ntasks:\n  triaxial   the main job: the triaxial test of E4s (linear meshes) into out/triaxial/;\n             --quick runs the quick specimen into out/quick/; other options go to\n             `fdem triaxial` (--test NAME, --model deformable|rigid|auto, --order linear|quadratic,\n             --level N, --strain S, --vtk, --threads N, --fresh, --out DIR, --config FILE);\n             a preset with --model rigid or auto gets linear surfaces unless --order is given\n  study      a coarse-graining study (`fdem study`, docs/STUDY.md): --preset quick|equal|binary|paper
             or --series FILE, --model, --order, --seeds N, --tests A,B, --strain S, --out DIR
             (default out/study/PRESET), --report DIR (RESULTS.md and results/), --plan, --report-only
  stability  stability maps of the step, penalty and damping (`fdem stability`, docs/STABILITY.md):
             --quick, --out DIR (default out/stability), --report DIR (STABILITY.md and results/)
  compare-builds  two or more fdem binaries run one command in alternated rounds: wall times,
             ms per step, ratios and whether the results are byte-identical (`--help`)
  preflight  the exact-scaling factors and particle meshes of the paper's series\n  docs       regenerate the generated parts of docs/ (the scaling table of docs/SCALING.md)";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("triaxial") => triaxial(&args[1..]),
        Some("study") => study(&args[1..]),
        Some("stability") => stability(&args[1..]),
        Some("compare-builds") => compare_builds::compare_builds(&args[1..]),
        Some("preflight") => preflight(&args[1..]),
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

/// The workspace root (xtask lives one level below it).
fn workspace_root() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(std::path::Path::to_path_buf)
        .unwrap_or_else(|| std::path::PathBuf::from("."))
}

/// Runs the release `fdem` binary with `args`.
fn fdem(args: &[String]) -> anyhow::Result<std::process::ExitStatus> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    std::process::Command::new(cargo)
        .current_dir(workspace_root())
        .args([
            "run",
            "--release",
            "--locked",
            "--quiet",
            "-p",
            "fdem-cli",
            "--bin",
            "fdem",
            "--",
        ])
        .args(args)
        .status()
        .context("starting cargo")
}

/// A study: `fdem study` in release mode, into `out/study/PRESET` unless `--out` is given.
fn study(rest: &[String]) -> anyhow::Result<()> {
    let given = |flag: &str| {
        rest.iter()
            .any(|a| a == flag || a.starts_with(&format!("{flag}=")))
    };
    let mut args: Vec<String> = vec!["study".into()];
    args.extend(rest.iter().cloned());
    if !given("--out") {
        let preset = rest
            .windows(2)
            .find(|w| w[0] == "--preset")
            .map_or("custom", |w| w[1].as_str());
        args.extend(["--out".to_string(), format!("out/study/{preset}")]);
    }
    args.extend(["--invoked-as".to_string(), "cargo xtask study".to_string()]);
    eprintln!(
        "building fdem (release) and running: fdem {}",
        args.join(" ")
    );
    let status = fdem(&args)?;
    if !status.success() {
        bail!("fdem study failed ({status})");
    }
    Ok(())
}

/// Stability maps: `fdem stability` in release mode, into `out/stability` unless `--out`
/// is given.
fn stability(rest: &[String]) -> anyhow::Result<()> {
    let mut args: Vec<String> = vec!["stability".into()];
    args.extend(rest.iter().cloned());
    if !rest.iter().any(|a| a == "--out" || a.starts_with("--out=")) {
        args.extend(["--out".to_string(), "out/stability".to_string()]);
    }
    args.extend([
        "--invoked-as".to_string(),
        "cargo xtask stability".to_string(),
    ]);
    eprintln!(
        "building fdem (release) and running: fdem {}",
        args.join(" ")
    );
    let status = fdem(&args)?;
    if !status.success() {
        bail!("fdem stability failed ({status})");
    }
    Ok(())
}

/// The main job: `fdem triaxial` in release mode with the default scene filled in.
fn triaxial(rest: &[String]) -> anyhow::Result<()> {
    let given = |flag: &str| rest.iter().any(|a| a == flag);
    let quick = given("--quick");
    let chooses_specimen = quick || given("--test") || given("--config") || given("--specimen");
    let has_order = given("--order");
    let has_out = given("--out");
    let mut args: Vec<String> = rest.to_vec();
    // The main job is E4s with linear meshes; a preset's rigid or auto particles get
    // linear surfaces from `fdem triaxial` itself.
    if !chooses_specimen {
        args.extend(["--test", "E4s"].map(String::from));
        if !has_order {
            args.extend(["--order", "linear"].map(String::from));
        }
    }
    if !has_out {
        let dir = if quick { "out/quick" } else { "out/triaxial" };
        args.extend(["--out".to_string(), dir.to_string()]);
    }
    eprintln!(
        "building fdem (release) and running: fdem triaxial {}",
        args.join(" ")
    );
    args.insert(0, "triaxial".to_string());
    let status = fdem(&args)?;
    if !status.success() {
        bail!("fdem triaxial failed ({status})");
    }
    Ok(())
}

/// The computed preflight of the paper's series: scale factors and particle meshes.
fn preflight(rest: &[String]) -> anyhow::Result<()> {
    if let Some(extra) = rest.first() {
        bail!("`cargo xtask preflight` takes no arguments, got '{extra}'");
    }
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
