//! End-to-end tests of the `fdem` binary: what users type, what they get.

use serde_json::Value;
use std::process::{Command, Output};

fn fdem(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fdem"))
        .args(args)
        .output()
        .expect("the fdem binary runs")
}

fn json(out: &Output) -> Value {
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON object")
}

#[test]
fn scale_json_gives_the_exact_factors_of_table_1() {
    let v = json(&fdem(&["scale", "--h", "4", "--format", "json"]));
    let f = &v["factors"];
    // Exactly (no round-off): integer powers of h are evaluated exactly.
    assert_eq!(f["force"], 16.0);
    assert_eq!(f["time"], 4.0);
    assert_eq!(f["mass"], 64.0);
    assert_eq!(f["penalty_stiffness"], 0.25);
    assert_eq!(f["stress"], 1.0);
    for key in [
        "length",
        "time",
        "mass",
        "force",
        "stress",
        "strain",
        "youngs_modulus",
        "poisson_ratio",
        "penalty_stiffness",
        "friction",
        "damping",
        "density",
        "velocity",
        "acceleration",
        "energy",
        "contact_stiffness",
        "time_step",
    ] {
        assert!(f[key].is_number(), "factors.{key} missing");
    }
}

#[test]
fn scale_table_lists_every_quantity() {
    let out = fdem(&["scale", "--h", "2"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("penalty_stiffness"));
    assert!(
        text.lines()
            .any(|l| l.starts_with("force") && l.trim_end().ends_with(" 4"))
    );
}

#[test]
fn bad_h_is_one_clear_line_and_a_failure() {
    for bad in ["0", "-2", "nan", "inf", "abc", ""] {
        let out = fdem(&["scale", "--h", bad]);
        assert!(!out.status.success(), "h = {bad:?} accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.trim_end().lines().count(), 1, "h = {bad:?}: {err}");
        assert!(err.contains("--h"), "h = {bad:?}: {err}");
        assert!(out.stdout.is_empty());
    }
    let out = fdem(&["scale"]);
    assert!(!out.status.success());
    assert_eq!(
        String::from_utf8_lossy(&out.stderr)
            .trim_end()
            .lines()
            .count(),
        1
    );
}

#[test]
fn mesh_json_reports_the_paper_particle() {
    let v = json(&fdem(&[
        "mesh",
        "--level",
        "1",
        "--order",
        "quadratic",
        "--diameter",
        "0.015",
        "--json",
    ]));
    assert_eq!(v["tets"], 80);
    assert_eq!(v["nodes"], 205);
    let ratio = v["volume_ratio_to_sphere"].as_f64().unwrap();
    assert!((ratio - 0.8735).abs() < 5e-5, "{ratio}");
    for key in [
        "surface_triangles",
        "surface_nodes",
        "volume",
        "surface_area",
        "min_altitude",
    ] {
        assert!(v[key].is_number(), "{key} missing");
    }
    let v = json(&fdem(&[
        "mesh", "--level", "1", "--order", "linear", "--json",
    ]));
    assert_eq!(
        (v["tets"].as_u64(), v["nodes"].as_u64()),
        (Some(80), Some(43))
    );
}

#[test]
fn mesh_writes_a_vtu_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.vtu");
    let out = fdem(&[
        "mesh",
        "--level",
        "2",
        "--order",
        "linear",
        "--vtu",
        path.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.contains("UnstructuredGrid") && text.contains("NumberOfPoints=\"163\""),
        "{}",
        &text[..400.min(text.len())]
    );
}

#[test]
fn bad_mesh_input_is_refused() {
    for args in [
        &["mesh", "--level", "5"][..],
        &["mesh", "--diameter", "-1"],
        &["mesh", "--order", "cubic"],
        &["mesh", "--vtu", "/nonexistent-dir/x.vtu"],
    ] {
        let out = fdem(args);
        assert!(!out.status.success(), "{args:?} accepted");
        assert_eq!(
            String::from_utf8_lossy(&out.stderr)
                .trim_end()
                .lines()
                .count(),
            1,
            "{args:?}"
        );
    }
}

fn example(name: &str) -> String {
    format!(
        "{}/../../examples/scenes/{name}",
        env!("CARGO_MANIFEST_DIR")
    )
}

#[test]
fn run_writes_the_documented_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let out = fdem(&[
        "run",
        &example("two_particles.toml"),
        "--out",
        out_dir.to_str().unwrap(),
        "--threads",
        "2",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["status"], "completed");
    assert_eq!(summary["bodies"], 2);
    assert_eq!(summary["threads"], 2);
    let energy = std::fs::read_to_string(out_dir.join("energy.csv")).unwrap();
    assert!(energy.starts_with(
        "time,kinetic,strain,external_work,dissipated,balance_error,contact,damping_dissipated,friction_dissipated\n"
    ));
    assert!(out_dir.join("walls.csv").exists());
    let bodies = std::fs::read_to_string(out_dir.join("bodies.csv")).unwrap();
    assert!(bodies.starts_with("time,body,x,y,z,vx,vy,vz,wx,wy,wz\n"));
    // The plan is announced up front on stderr, with the run identifier of summary.json.
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("steps of dt"), "{stderr}");
    let run_id = summary["run_id"].as_str().unwrap();
    assert_eq!(run_id.len(), 25, "{run_id}");
    assert!(stderr.contains(&format!("run {run_id}: ")), "{stderr}");
}

#[test]
fn run_refuses_a_bad_scene_in_one_line_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bad.toml");
    let text = std::fs::read_to_string(example("two_particles.toml")).unwrap();
    std::fs::write(&scene, text.replace("dt_safety = 0.5", "dt_safety = 2.0")).unwrap();
    let out_dir = dir.path().join("out");
    let out = fdem(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("bad.toml:5:") && err.contains("simulation.dt_safety"),
        "{err}"
    );
    assert!(!out_dir.exists());
    let missing = fdem(&[
        "run",
        "/nonexistent/scene.toml",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(!missing.status.success());
    assert_eq!(
        String::from_utf8_lossy(&missing.stderr)
            .trim_end()
            .lines()
            .count(),
        1
    );
}

/// A scene that cannot fit in the memory available (20000 particles of the finest mesh,
/// about a terabyte) is refused in one line with the estimate, before any output.
#[test]
fn run_refuses_a_scene_that_cannot_fit_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from(
        "[simulation]\nduration = 1.0e-5\n\
         [material]\ndensity = 2650.0\nyoungs_modulus = 40.0e9\npoisson_ratio = 0.2\n",
    );
    for i in 0..20_000 {
        text.push_str(&format!(
            "[[particle]]\ndiameter = 0.015\ncenter = [{}, 0.0, 0.0]\n\
             mesh = {{ level = 4, order = \"quadratic\", shells = 8 }}\n",
            0.02 * f64::from(i)
        ));
    }
    let need = fdem_solver::Scene::from_toml_str(&text, "huge.toml")
        .unwrap()
        .model_size()
        .unwrap()
        .bytes();
    match fdem_core::fs::available_memory() {
        Some(available) if available < need => {}
        _ => return eprintln!("skipped: the memory available is unknown or above {need} bytes"),
    }
    let scene = dir.path().join("huge.toml");
    std::fs::write(&scene, text).unwrap();
    let out_dir = dir.path().join("out");
    let out = fdem(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    let estimate = fdem_solver::bytes_text(need);
    assert!(
        err.contains(&format!("need about {estimate}")) && err.contains("are available"),
        "{err}"
    );
    assert!(!out_dir.exists());
}

#[test]
fn scale_and_coarsen_work_on_every_example_scene() {
    let dir = tempfile::tempdir().unwrap();
    let examples = format!("{}/../../examples/scenes", env!("CARGO_MANIFEST_DIR"));
    let mut seen = 0;
    for entry in std::fs::read_dir(&examples).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        seen += 1;
        let p = path.to_str().unwrap();
        let scaled = dir.path().join("scaled.toml");
        let out = fdem(&[
            "scale",
            p,
            "--h",
            "2.5",
            "--out",
            scaled.to_str().unwrap(),
            "--format",
            "json",
        ]);
        assert!(
            out.status.success(),
            "{p}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert!(v["fields"].as_array().is_some_and(|f| !f.is_empty()));
        // The scaled scene loads and its duration is 2.5 times the original's.
        let a = fdem_solver::Scene::load(&path).unwrap();
        let b = fdem_solver::Scene::load(&scaled).unwrap();
        assert!((b.simulation.duration / a.simulation.duration - 2.5).abs() < 1e-12);
        for exact in [false, true] {
            let cg = dir.path().join("cg.toml");
            let mut args = vec!["coarsen", p, "--h", "2", "--out", cg.to_str().unwrap()];
            if exact {
                args.push("--exact-scaling");
            }
            let out = fdem(&args);
            assert!(
                out.status.success(),
                "{p}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            let c = fdem_solver::Scene::load(&cg).unwrap();
            assert_eq!(c.particles[0].diameter, 2.0 * a.particles[0].diameter);
            let penalty = c.contact.unwrap().normal_penalty;
            let expected = a.contact_section().normal_penalty / if exact { 2.0 } else { 1.0 };
            assert_eq!(penalty, expected);
        }
    }
    assert!(seen >= 2);
    // Bad input: h <= 0 and a scene that fails to load, one line each, nothing written.
    let out_path = dir.path().join("never.toml");
    for args in [
        vec![
            "scale",
            "/nonexistent.toml",
            "--h",
            "2",
            "--out",
            out_path.to_str().unwrap(),
        ],
        vec![
            "coarsen",
            "/nonexistent.toml",
            "--h",
            "2",
            "--out",
            out_path.to_str().unwrap(),
        ],
    ] {
        let out = fdem(&args);
        assert!(!out.status.success());
        assert_eq!(
            String::from_utf8_lossy(&out.stderr)
                .trim_end()
                .lines()
                .count(),
            1
        );
    }
    let ex = format!("{examples}/two_particles.toml");
    for h in ["0", "-1", "x"] {
        for cmd in ["scale", "coarsen"] {
            let out = fdem(&[cmd, &ex, "--h", h, "--out", out_path.to_str().unwrap()]);
            assert!(!out.status.success(), "{cmd} --h {h}");
            assert_eq!(
                String::from_utf8_lossy(&out.stderr)
                    .trim_end()
                    .lines()
                    .count(),
                1
            );
        }
    }
    assert!(!out_path.exists());
}

/// A scene that runs for minutes: two particles, 10 s of simulated time.
const LONG_SCENE: &str = r#"
[simulation]
duration = 10.0
output_interval = 1.0e-3
[material]
density = 2650.0
youngs_modulus = 40.0e9
poisson_ratio = 0.2
[[particle]]
diameter = 0.015
center = [0.0, 0.0, 0.0]
velocity = [0.5, 0.0, 0.0]
[[particle]]
diameter = 0.015
center = [0.0152, 0.0, 0.0]
"#;

/// Sends `signals` (as `kill` flags) to `child` one after the other and waits for it to
/// end, at most `seconds`.
#[cfg(unix)]
fn signal_and_wait(
    child: &mut std::process::Child,
    signals: &[&str],
    seconds: u64,
) -> std::process::ExitStatus {
    let pid = child.id().to_string();
    for s in signals {
        let sent = Command::new("kill").args([*s, &pid]).status().unwrap();
        assert!(sent.success(), "kill {s} {pid}");
    }
    let start = std::time::Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status;
        }
        assert!(start.elapsed().as_secs() < seconds, "still running");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// `fdem run` stopped by SIGTERM, by SIGINT, or by SIGINT twice at once (as `timeout -s
/// INT` delivers it) ends within seconds with a complete `interrupted` summary, whole CSV
/// rows and no temporary file.
#[cfg(unix)]
#[test]
fn signals_stop_a_run_with_complete_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("long.toml");
    std::fs::write(&scene, LONG_SCENE).unwrap();
    for (name, signals) in [
        ("term", &["-TERM"][..]),
        ("int", &["-INT"][..]),
        ("int-twice", &["-INT", "-INT"][..]),
    ] {
        let out = dir.path().join(name);
        let mut child = Command::new(env!("CARGO_BIN_EXE_fdem"))
            .args([
                "run",
                scene.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ])
            .args(["--threads", "1"])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        // Until the run has written its first rows.
        let energy = out.join("energy.csv.part");
        let start = std::time::Instant::now();
        while !energy.exists() && start.elapsed().as_secs() < 30 {
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        std::thread::sleep(std::time::Duration::from_millis(300));
        let status = signal_and_wait(&mut child, signals, 20);
        assert_eq!(status.code(), Some(1), "{name}");
        assert_interrupted_outputs(&out, "energy.csv", 2, name);
    }
}

/// An output path that cannot take the outputs is refused before any preparation, in one
/// line: a file where `fdem triaxial` needs a directory, a directory where
/// `fdem specimen --prepare` needs a file.
#[test]
fn unwritable_outputs_are_refused_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("taken");
    std::fs::write(&file, "x").unwrap();
    let start = std::time::Instant::now();
    let out = fdem(&["triaxial", "--quick", "--out", file.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("is a file"), "{err}");
    let out = fdem(&[
        "specimen",
        "--test",
        "E4s",
        "--prepare",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("is a directory"), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    // Neither prepared anything (a preparation takes far longer).
    assert!(start.elapsed().as_secs() < 20);
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
}

/// `fdem specimen` and `fdem triaxial` give a preset's rigid or auto particles linear
/// surfaces unless --order is given, as `fdem study` does.
#[test]
fn a_rigid_preset_gets_linear_surfaces_unless_an_order_is_given() {
    let order_of = |extra: &[&str]| {
        let mut args = vec!["specimen", "--test", "B2", "--toml"];
        args.extend_from_slice(extra);
        let out = fdem(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        let orders: Vec<&str> = text
            .lines()
            .filter_map(|l| l.strip_prefix("order = \""))
            .collect();
        assert_eq!(orders.len(), 1, "{text}");
        orders[0].trim_end_matches('"').to_string()
    };
    assert_eq!(order_of(&[]), "quadratic");
    assert_eq!(order_of(&["--model", "rigid"]), "linear");
    assert_eq!(order_of(&["--model", "auto"]), "linear");
    assert_eq!(
        order_of(&["--model", "rigid", "--order", "quadratic"]),
        "quadratic"
    );
    assert_eq!(order_of(&["--model", "deformable"]), "quadratic");
}

/// Flags that do not go together are refused in one line instead of one of them being
/// ignored.
#[test]
fn conflicting_flags_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("f");
    let cases: [&[&str]; 4] = [
        &[
            "specimen",
            "--test",
            "E4s",
            "--toml",
            "--prepare",
            "--out",
            "x",
        ],
        &[
            "triaxial",
            "--specimen",
            "s.fdemspec",
            "--level",
            "3",
            "--out",
            "x",
        ],
        &[
            "triaxial",
            "--specimen",
            "s.fdemspec",
            "--quick",
            "--out",
            "x",
        ],
        &["scale", "--h", "2", "--out", f.to_str().unwrap()],
    ];
    for args in cases {
        let out = fdem(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} accepted");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    }
    assert!(!f.exists());
}

/// `fdem specimen --prepare` stopped by SIGTERM ends within seconds with a failure, and
/// writes neither the specimen file nor its temporary.
#[cfg(unix)]
#[test]
fn a_signal_stops_a_preparation_without_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("e4s.fdemspec");
    let mut child = Command::new(env!("CARGO_BIN_EXE_fdem"))
        .args([
            "specimen",
            "--test",
            "E4s",
            "--order",
            "linear",
            "--prepare",
        ])
        .args(["--out", file.to_str().unwrap(), "--threads", "1"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_secs(2));
    let status = signal_and_wait(&mut child, &["-TERM"], 30);
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert!(!status.success());
    assert!(err.contains("interrupted"), "{err}");
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
}

/// `fdem triaxial` stopped by SIGTERM, SIGINT, or SIGINT twice at once during its test
/// ends within seconds with a complete `interrupted` summary, whole CSV rows and no
/// temporary file (the quick specimen, prepared by the first run and reused by the
/// others from a copy in their own directories).
#[cfg(unix)]
#[test]
fn signals_stop_a_triaxial_test_with_complete_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let prepared = dir.path().join("term").join("specimen.fdemspec");
    for (name, signals) in [
        ("term", &["-TERM"][..]),
        ("int", &["-INT"][..]),
        ("int-twice", &["-INT", "-INT"][..]),
    ] {
        let out = dir.path().join(name);
        if prepared.exists() {
            std::fs::create_dir_all(&out).unwrap();
            std::fs::copy(&prepared, out.join("specimen.fdemspec")).unwrap();
        }
        let mut child = Command::new(env!("CARGO_BIN_EXE_fdem"))
            .args(["triaxial", "--quick", "--out", out.to_str().unwrap()])
            .args(["--threads", "1"])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        // Until the test (after the preparation) has begun its rows.
        let rows = out.join("consolidation.csv");
        let start = std::time::Instant::now();
        while !rows.exists() && start.elapsed().as_secs() < 300 {
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        assert!(rows.exists(), "{name}: the test did not start");
        std::thread::sleep(std::time::Duration::from_millis(1500));
        let status = signal_and_wait(&mut child, signals, 30);
        assert_eq!(status.code(), Some(1), "{name}");
        assert_interrupted_outputs(&out, "consolidation.csv", 1, name);
    }
}

/// The outputs an interrupted run leaves in `out`: a summary saying `interrupted`, the
/// CSV file `csv` with at least `min_lines` lines, all whole (as many columns as the
/// header, a final newline), and no `.part` file.
fn assert_interrupted_outputs(out: &std::path::Path, csv: &str, min_lines: usize, name: &str) {
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["status"], "interrupted", "{name}");
    let rows = std::fs::read_to_string(out.join(csv)).unwrap();
    assert!(
        rows.ends_with('\n') && rows.lines().count() >= min_lines,
        "{name}: {rows}"
    );
    let columns = rows.lines().next().unwrap().split(',').count();
    assert!(
        rows.lines().all(|l| l.split(',').count() == columns),
        "{name}: {rows}"
    );
    let parts: Vec<_> = std::fs::read_dir(out)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".part"))
        .collect();
    assert!(parts.is_empty(), "{name}: {parts:?}");
}

/// A negative number given to a numeric flag is a value out of range, refused in one
/// line naming the flag, not an unknown argument.
#[test]
fn negative_flag_values_are_refused_as_values() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x");
    let out = out.to_str().unwrap();
    for (args, expected) in [
        (
            &["triaxial", "--quick", "--out", out, "--strain", "-1"][..],
            "--strain must lie in (0, 0.5], got -1",
        ),
        (
            &["triaxial", "--quick", "--out", out, "--threads", "-1"][..],
            "'-1' for '--threads",
        ),
        (
            &["specimen", "--test", "E4s", "--counts", "--level", "-1"][..],
            "'-1' for '--level",
        ),
    ] {
        let o = fdem(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} accepted");
        assert!(err.contains(expected), "{args:?}: {err}");
        assert!(!err.contains("unexpected argument"), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    }
}

#[test]
fn bad_study_input_is_one_line_and_runs_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    let out_s = out.to_str().unwrap();
    for (args, says) in [
        (vec!["--preset", "huge"], "unknown study preset 'huge'"),
        (
            vec!["--preset", "quick", "--seeds", "0"],
            "--seeds must be at least 1",
        ),
        (
            vec!["--preset", "quick", "--tests", "E9"],
            "'E9' is not a test of this study",
        ),
        (
            vec!["--preset", "quick", "--strain", "1e300"],
            "--strain must lie in",
        ),
        (vec![], "give one of --preset NAME"),
    ] {
        let mut all = vec!["study", "--out", out_s];
        all.extend(args.iter().copied());
        let o = fdem(&all);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} was accepted");
        assert!(err.contains(says), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
        assert!(!out.join("runs").exists(), "{args:?} started runs");
    }
    // The plan alone runs nothing and names every run.
    let o = fdem(&[
        "study", "--preset", "quick", "--model", "rigid", "--out", out_s, "--plan",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    for label in [
        "Q1-rigid-linear-seed1",
        "Q2s-rigid-linear-seed1",
        "estimated",
    ] {
        assert!(err.contains(label), "{err}");
    }
    assert!(!out.join("runs").exists());
}
