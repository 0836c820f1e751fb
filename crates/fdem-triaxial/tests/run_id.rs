//! Every test run is named: its identifier (UTC start and the hash of its definition) is
//! announced to the observer before the first step and written as `run_id` in its
//! `summary.json`; the CSV files beside it stay plain.

use fdem_triaxial::{
    PreparedSpecimen, Silent, SpecimenSpec, TestObserver, TestOptions, TestStatus, prepare,
    run_test,
};
use std::sync::atomic::AtomicBool;

/// A few dozen level-0 particles of a soft material: a preparation of few steps (the
/// small specimen of the preparation tests).
const SMALL: &str = r#"
name = "small"
diameter = 0.104
height = 0.06
solid_fraction = 0.5
gradation = [{ size = 0.02, mass_fraction = 1.0 }]

[material]
density = 2650.0
youngs_modulus = 1.0e8
poisson_ratio = 0.2

[contact]
normal_penalty = 1.0e9

[mesh]
level = 0
order = "linear"

[preparation]
loose_solid_fraction = 0.25
"#;

/// Records the identifier and stops the test at its first progress report.
#[derive(Default)]
struct FirstReport {
    run_id: Vec<String>,
}

impl TestObserver for FirstReport {
    fn run_id(&mut self, run_id: &str) {
        self.run_id.push(run_id.to_string());
    }
    fn progress(&mut self, _status: &TestStatus) -> bool {
        false
    }
}

/// Runs the test on `prepared` into `dir` until its first report; returns the identifier
/// the observer saw and the summary's.
fn named_run(prepared: &PreparedSpecimen, dir: &std::path::Path) -> (String, String) {
    let options = TestOptions::new(dir);
    let mut observer = FirstReport::default();
    let summary = run_test(prepared, &options, &mut observer, &AtomicBool::new(false)).unwrap();
    assert_eq!(summary.status, "interrupted");
    assert_eq!(observer.run_id, std::slice::from_ref(&summary.run_id));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    let written = json["run_id"].as_str().unwrap().to_string();
    assert_eq!(written, summary.run_id);
    // The CSV files stay plain: their first line is the header.
    let csv = std::fs::read_to_string(dir.join("consolidation.csv")).unwrap();
    assert!(csv.starts_with(fdem_triaxial::CURVE_HEADER), "{csv}");
    (observer.run_id.remove(0), written)
}

#[test]
fn every_test_run_is_named_in_its_summary() {
    let spec = SpecimenSpec::from_toml_str(SMALL, "small").unwrap();
    let prepared = prepare(&spec, &mut Silent).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let seconds = |t: std::time::SystemTime| {
        t.duration_since(std::time::UNIX_EPOCH).unwrap().as_secs() as i64
    };
    let before = fdem_core::run_id::utc_stamp(seconds(std::time::SystemTime::now()));
    let (seen, first) = named_run(&prepared, &dir.path().join("a"));
    let after = fdem_core::run_id::utc_stamp(seconds(std::time::SystemTime::now()));
    assert_eq!(seen, first);
    // `YYYYMMDDTHHMMSSZ-hhhhhhhh`: the start, then the definition's hash.
    let (stamp, hash) = first.split_once('-').unwrap();
    assert!(
        before.as_str() <= stamp && stamp <= after.as_str(),
        "{first}"
    );
    let definition = prepared.spec.to_toml_string().unwrap();
    let expected = fdem_core::hash::Fnv1a::of(definition.as_bytes()) >> 32;
    assert_eq!(hash, format!("{expected:08x}"));
    // The same definition gives the same hash; another test of the same specimen another.
    let (_, again) = named_run(&prepared, &dir.path().join("b"));
    assert_eq!(again.split_once('-').unwrap().1, hash);
    let mut other = prepared.clone();
    other.spec.test.target_strain = 0.1;
    let (_, changed) = named_run(&other, &dir.path().join("c"));
    assert_ne!(changed.split_once('-').unwrap().1, hash);
}
