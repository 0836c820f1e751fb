//! `fdem compare`'s library side: finished runs read back from their outputs and the
//! comparison written against the first.

use fdem_triaxial::{COMPARISON_HEADER, CurvePoint, CurveWriter, FinishedRun, write_comparison};
use std::path::Path;

/// A finished run in `dir`: a curve `eta = peak * (1 - exp(-eps_a / 0.02))` to 15 %
/// axial strain, `eps_v = -eps_a / 10`, and a summary with the costs.
fn fake_run(dir: &Path, peak: f64, model: &str, shear_wall: f64) {
    std::fs::create_dir_all(dir).unwrap();
    let mut w = CurveWriter::new(dir.join("curve.csv")).unwrap();
    for i in 0..=60 {
        let eps_a = 0.0025 * i as f64;
        w.push(&CurvePoint {
            eps_a,
            eps_v: -eps_a / 10.0,
            eta: peak * (1.0 - (-eps_a / 0.02).exp()),
            step: i,
            ..CurvePoint::default()
        })
        .unwrap();
    }
    let summary = format!(
        r#"{{"model":"{model}","consolidation":{{"cost":{{"wall_seconds":2.0,"cpu_seconds":3.5}}}},
            "shear":{{"steps":1000,"wall_seconds":{shear_wall},"cpu_seconds":{}}}}}"#,
        2.0 * shear_wall
    );
    std::fs::write(dir.join("summary.json"), summary).unwrap();
}

/// Two runs: the table has the first as reference (differences zero, speed-up 1), the
/// second's differences and speed-up from the files; both charts and the table are
/// written, nothing else.
#[test]
fn two_runs_are_compared_against_the_first() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b, out) = (
        dir.path().join("a"),
        dir.path().join("b"),
        dir.path().join("cmp"),
    );
    fake_run(&a, 1.7, "deformable", 40.0);
    fake_run(&b, 1.6, "rigid", 10.0);
    let runs = [
        FinishedRun::load("deformable", &a).unwrap(),
        FinishedRun::load("rigid", &b).unwrap(),
    ];
    assert_eq!(runs[1].model, "rigid");
    let rows = write_comparison(&runs, &out, "test").unwrap();
    let text = std::fs::read_to_string(out.join("comparison.csv")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], COMPARISON_HEADER);
    assert_eq!(
        lines[1..],
        rows.iter().map(String::as_str).collect::<Vec<_>>()[..]
    );
    let header: Vec<&str> = COMPARISON_HEADER.split(',').collect();
    let field = |row: &str, key: &str| -> f64 {
        let k = header.iter().position(|h| *h == key).unwrap();
        row.split(',').nth(k).unwrap().parse().unwrap()
    };
    assert_eq!(field(lines[1], "d_peak_eta"), 0.0);
    assert_eq!(field(lines[1], "speedup"), 1.0);
    // The peak of the sampled curve is its last point, 15 % strain.
    let peak = |p: f64| p * (1.0 - (-0.15f64 / 0.02).exp());
    assert!((field(lines[2], "d_peak_eta") - (peak(1.6) - peak(1.7))).abs() < 1e-6);
    assert_eq!(field(lines[2], "speedup"), 4.0);
    assert_eq!(field(lines[2], "shear_cpu_s"), 20.0);
    assert!((field(lines[2], "final_eps_v") + 0.015).abs() < 1e-6);
    let mut files: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    files.sort();
    assert_eq!(files, ["comparison.csv", "eps_v.svg", "eta.svg"]);
}

/// A directory without a curve, or without a summary, is refused naming the file; a
/// label with a comma is refused before anything is written.
#[test]
fn missing_outputs_and_bad_labels_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let e = FinishedRun::load("x", &dir.path().join("none")).unwrap_err();
    assert!(e.to_string().contains("curve.csv"), "{e}");
    let a = dir.path().join("a");
    fake_run(&a, 1.7, "deformable", 40.0);
    std::fs::remove_file(a.join("summary.json")).unwrap();
    let e = FinishedRun::load("x", &a).unwrap_err();
    assert!(e.to_string().contains("summary.json"), "{e}");
    fake_run(&a, 1.7, "deformable", 40.0);
    let run = FinishedRun::load("a,b", &a).unwrap();
    let out = dir.path().join("cmp");
    let e = write_comparison(&[run], &out, "t").unwrap_err();
    assert!(e.to_string().contains("comma"), "{e}");
    assert!(!out.exists());
}
