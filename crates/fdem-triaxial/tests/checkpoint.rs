//! A test stopped and resumed from its checkpoints gives the same outputs as one that
//! ran through, bit for bit: the quick specimen (rigid particles, a short shear) stopped
//! once in consolidation and once in shear, each time resumed by a new `run_test` call.

use fdem_solver::ParticleModel;
use fdem_triaxial::{
    CHECKPOINT_FILE, PreparedSpecimen, Silent, SilentTest, TestObserver, TestOptions, TestPhase,
    TestStatus, TriaxialError, checkpoint_progress, prepare, quick_spec, run_test,
};
use std::path::Path;
use std::sync::atomic::AtomicBool;

/// Stops the test at its first progress report in `phase` after `steps` steps of it.
struct StopAt {
    phase: TestPhase,
    steps: u64,
}

impl TestObserver for StopAt {
    fn run_id(&mut self, _run_id: &str) {}
    fn progress(&mut self, status: &TestStatus) -> bool {
        !(status.phase == self.phase && status.steps >= self.steps)
    }
}

fn options(dir: &Path, resume: bool) -> TestOptions {
    TestOptions {
        // Only the checkpoints written when the test is stopped (an interval longer
        // than the test).
        checkpoint_interval: Some(1e9),
        resume,
        ..TestOptions::new(dir)
    }
}

fn read(dir: &Path, file: &str) -> String {
    std::fs::read_to_string(dir.join(file)).unwrap()
}

fn quick_rigid() -> PreparedSpecimen {
    quick(ParticleModel::Rigid)
}

fn quick(model: ParticleModel) -> PreparedSpecimen {
    let mut spec = quick_spec();
    spec.model = model;
    spec.test.target_strain = 0.01;
    prepare(&spec, &mut Silent).unwrap()
}

#[test]
fn a_resumed_test_gives_the_curve_of_an_uninterrupted_one_bit_for_bit() {
    let whole = stop_twice_and_compare(&quick_rigid());
    // The rigid bodies' contact network sets the step of this test (docs/MODEL.md section
    // 12), so the resumed run above has followed a changing step.
    assert!(
        whole.final_dt_source.contains("contact network"),
        "{}",
        whole.final_dt_source
    );
    assert_ne!(whole.final_dt.to_bits(), whole.plan.dt.to_bits());
}

#[test]
fn a_resumed_deformable_test_gives_the_curve_of_an_uninterrupted_one_bit_for_bit() {
    let whole = stop_twice_and_compare(&quick(ParticleModel::Deformable));
    assert!(!whole.final_dt_source.contains("contact network"));
    assert_eq!(whole.final_dt.to_bits(), whole.plan.dt.to_bits());
}

/// Runs `prepared` through, then stopped halfway in consolidation and halfway in shear
/// and resumed each time, and compares the outputs; returns the uninterrupted run's
/// summary.
fn stop_twice_and_compare(prepared: &PreparedSpecimen) -> fdem_triaxial::TestSummary {
    let never = AtomicBool::new(false);
    let root = tempfile::tempdir().unwrap();
    let (whole, parts) = (root.path().join("whole"), root.path().join("parts"));

    let reference = run_test(prepared, &options(&whole, false), &mut SilentTest, &never).unwrap();
    assert_eq!(reference.status, "completed");
    assert!(!whole.join(CHECKPOINT_FILE).exists());
    // The shear re-estimated from its own first steps, the plan's step count at that pace.
    let plan = &reference.plan;
    assert!(reference.shear.steps > 200, "{}", reference.shear.steps);
    assert!(plan.shear_seconds_per_step > 0.0, "{plan:?}");
    let at_pace = plan.shear_seconds_per_step * plan.shear_steps as f64;
    assert_eq!(plan.reestimated_shear_seconds, at_pace);

    // Stopped in consolidation, halfway: a checkpoint, an interrupted summary.
    let mut stop = StopAt {
        phase: TestPhase::Consolidation,
        steps: reference.consolidation.cost.steps / 2,
    };
    let first = run_test(prepared, &options(&parts, true), &mut stop, &never).unwrap();
    assert_eq!(first.status, "interrupted");
    assert!(first.consolidation.cost.steps < reference.consolidation.cost.steps);
    let at = checkpoint_progress(&parts.join(CHECKPOINT_FILE)).unwrap();
    assert_eq!(at.phase, TestPhase::Consolidation);
    assert_eq!(at.steps, first.consolidation.cost.steps);
    assert!(at.wall_seconds > 0.0 && at.dt > 0.0);
    // Resumed, then stopped in shear, halfway.
    let mut stop = StopAt {
        phase: TestPhase::Shear,
        steps: reference.shear.steps / 2,
    };
    let second = run_test(prepared, &options(&parts, true), &mut stop, &never).unwrap();
    assert_eq!(second.status, "interrupted");
    assert!(second.shear.steps > 0 && second.shear.steps < reference.shear.steps);
    let at = checkpoint_progress(&parts.join(CHECKPOINT_FILE)).unwrap();
    assert_eq!((at.phase, at.steps), (TestPhase::Shear, second.shear.steps));
    // The step in use: the plan's, or where rigid bodies' contact network set it since.
    assert!(at.dt.is_finite() && at.dt > 0.0, "{}", at.dt);
    // Resumed to the end.
    let last = run_test(prepared, &options(&parts, true), &mut SilentTest, &never).unwrap();
    assert_eq!(last.status, "completed");
    assert!(!parts.join(CHECKPOINT_FILE).exists());

    for file in [
        "consolidation.csv",
        "curve.csv",
        "contacts_peak.csv",
        "pairs_peak.csv",
    ] {
        assert_eq!(read(&whole, file), read(&parts, file), "{file} differs");
    }
    assert_eq!(
        last.consolidation.cost.steps,
        reference.consolidation.cost.steps
    );
    assert_eq!(last.shear.steps, reference.shear.steps);
    assert_eq!(last.escape_checks, reference.escape_checks);
    assert_eq!(
        last.max_contact_depth.to_bits(),
        reference.max_contact_depth.to_bits()
    );
    let json = |s: &fdem_triaxial::TestSummary| {
        serde_json::to_string(&(&s.curve, &s.energy, s.energy_balance_error)).unwrap()
    };
    assert_eq!(json(&last), json(&reference));
    reference
}

#[test]
fn a_checkpoint_of_another_definition_or_a_damaged_one_is_refused() {
    let prepared = quick_rigid();
    let never = AtomicBool::new(false);
    let dir = tempfile::tempdir().unwrap();
    let mut stop = StopAt {
        phase: TestPhase::Consolidation,
        steps: 1,
    };
    let first = run_test(&prepared, &options(dir.path(), true), &mut stop, &never).unwrap();
    assert_eq!(first.status, "interrupted");
    let path = dir.path().join(CHECKPOINT_FILE);

    let mut other = prepared.clone();
    other.spec.test.target_strain = 0.02;
    let err = run_test(&other, &options(dir.path(), true), &mut SilentTest, &never).unwrap_err();
    assert!(
        matches!(&err, TriaxialError::File { .. }) && err.to_string().contains("another"),
        "{err}"
    );

    let mut bytes = std::fs::read(&path).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 1;
    std::fs::write(&path, &bytes).unwrap();
    let err = run_test(
        &prepared,
        &options(dir.path(), true),
        &mut SilentTest,
        &never,
    )
    .unwrap_err();
    assert!(err.to_string().contains("checksum"), "{err}");
    assert!(err.to_string().contains("delete it"), "{err}");
}
