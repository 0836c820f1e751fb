//! The quick stability map: for rigid and linear particles at the paper's penalty, a
//! step of 0.9 times the computed bound runs stably and twice the bound is stopped by a
//! guard, and the map's files are written. Seconds on 2 threads.

use fdem_study::stability::{MapSpec, read_rows, run_map, write_stability};
use std::sync::atomic::AtomicBool;

#[test]
fn below_the_bound_is_stable_and_twice_the_bound_is_caught() {
    let dir = tempfile::tempdir().unwrap();
    let spec = MapSpec::quick();
    let mut seen = 0;
    let rows = run_map(
        &spec,
        dir.path(),
        &mut fdem_triaxial::Silent,
        &mut |_, _, _| seen += 1,
        &AtomicBool::new(false),
    )
    .unwrap();
    assert_eq!(rows.len(), 4);
    assert_eq!(seen, 4);
    for r in &rows {
        if r.dt_factor < 1.0 {
            assert_eq!(r.class, "stable", "{r:?}");
            assert_eq!(r.steps, spec.steps);
            assert!(r.max_energy_error <= 0.01, "{r:?}");
        } else {
            assert!(!r.finished(), "twice the bound ran through: {r:?}");
            assert!(r.steps < spec.steps, "{r:?}");
        }
    }
    let report = dir.path().join("report");
    let written =
        write_stability(&rows, &spec, None, &report, "cargo xtask stability --quick").unwrap();
    assert_eq!(written.len(), 4);
    let doc = std::fs::read_to_string(report.join("STABILITY.md")).unwrap();
    assert!(doc.contains("cargo xtask stability --quick"));
    assert_eq!(
        read_rows(&report.join("results/stability.csv")).unwrap(),
        rows
    );

    // A second call finds every probe done and runs nothing.
    let mut again = 0;
    let start = std::time::Instant::now();
    let rows2 = run_map(
        &spec,
        dir.path(),
        &mut fdem_triaxial::Silent,
        &mut |_, _, _| again += 1,
        &AtomicBool::new(false),
    )
    .unwrap();
    assert_eq!(rows2, rows);
    assert!(start.elapsed().as_secs_f64() < 5.0);
}
