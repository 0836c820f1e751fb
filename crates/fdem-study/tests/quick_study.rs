//! The quick study end to end (the `quick` preset in the rigid model): every run
//! completes, the original compares to itself with zero error, every metric is finite,
//! the results document, its data and charts are written, and a second call reuses every
//! run. A few minutes on 2 threads.

use fdem_solver::ParticleModel;
use fdem_study::run::{RunRecord, SilentStudy, StudyObserver};
use fdem_study::{
    Provenance, RunDef, StudyOptions, StudyPreset, expand, gather, run_study, write_results,
};
use fdem_triaxial::{Observer, TestObserver};
use std::sync::atomic::AtomicBool;

/// Counts the runs that were reused.
#[derive(Default)]
struct Counting {
    inner: SilentStudy,
    reused: usize,
    computed: usize,
}

impl StudyObserver for Counting {
    fn run_ended(&mut self, _: usize, _: usize, _: &RunRecord, reused: bool) {
        if reused {
            self.reused += 1;
        } else {
            self.computed += 1;
        }
    }
    fn preparation(&mut self) -> &mut dyn Observer {
        self.inner.preparation()
    }
    fn test(&mut self) -> &mut dyn TestObserver {
        self.inner.test()
    }
}

#[test]
fn the_quick_study_runs_end_to_end_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    let series = StudyPreset::Quick.series().unwrap();
    let options = StudyOptions {
        model: ParticleModel::Rigid,
        ..StudyOptions::default()
    };
    let runs: Vec<RunDef> = expand(&series, &options, false).unwrap();
    assert_eq!(runs.len(), 5);
    let mut observer = Counting::default();
    let records = run_study(&runs, &out, &mut observer, &AtomicBool::new(false), false).unwrap();
    assert_eq!((observer.computed, observer.reused), (5, 0));
    for r in &records {
        assert!(r.completed(), "{}: {} {:?}", r.label, r.status, r.failure);
        assert_eq!(r.model_used, "rigid");
        assert!(r.steps() > 0 && r.wall_seconds() > 0.0 && r.peak.is_some());
    }

    let results = gather(&series, &options, &out).unwrap();
    assert_eq!(results.entries.len(), 5);
    let reference = results.groups.iter().find(|g| g.reference).unwrap();
    assert_eq!(reference.test, "Q1");
    let e = &reference.errors[0];
    assert_eq!(
        (
            e.peak_eta,
            e.rms_eta,
            e.rms_eps_v,
            e.eps_v_final,
            e.mean_force_ratio
        ),
        (0.0, 0.0, 0.0, 0.0, 1.0),
        "the original against itself"
    );
    for entry in &results.entries {
        let m = &entry.measured.metrics;
        for (name, v) in [
            ("peak_eta", m.peak_eta),
            ("eps_a_peak", m.eps_a_peak),
            ("residual_eta", m.residual_eta),
            ("eps_v_final", m.eps_v_final),
            ("initial_modulus", m.initial_modulus),
            ("dilatancy_onset", m.dilatancy_onset),
            ("mean_normal_force", m.mean_normal_force),
            ("strong_share", m.strong_share),
            ("weak_share", m.weak_share),
        ] {
            assert!(v.is_finite(), "{}: {name} = {v}", entry.record.label);
        }
        assert!(m.peak_eta > 0.5 && m.mean_normal_force > 0.0);
    }
    for g in results.groups.iter().filter(|g| !g.reference) {
        assert!(g.speedup.is_finite() && g.speedup > 0.0, "{}", g.test);
        assert!(g.errors[0].rms_eta.is_finite() && g.errors[0].rms_eta > 0.0);
    }

    let report = dir.path().join("report");
    let written = write_results(
        &results,
        &report,
        &Provenance {
            command: "cargo xtask study --preset quick --model rigid",
            pending: &[],
            failed: &[],
        },
    )
    .unwrap();
    for name in [
        "RESULTS.md",
        "results/runs.csv",
        "results/cost.svg",
        "results/speed_accuracy.svg",
        "results/quick_rigid_linear_eta.svg",
        "results/quick_rigid_linear_eps_v.svg",
        "results/quick_rigid_linear_forces.svg",
    ] {
        let path = report.join(name);
        assert!(written.contains(&path), "{name} not reported as written");
        assert!(std::fs::metadata(&path).unwrap().len() > 100, "{name}");
    }
    let csv = std::fs::read_to_string(report.join("results/runs.csv")).unwrap();
    assert_eq!(csv.lines().count(), 6);
    assert!(csv.starts_with("test,h,exact_scaling,model,order,seed,particles,peak_eta,"));
    let doc = std::fs::read_to_string(report.join("RESULTS.md")).unwrap();
    assert!(doc.contains("cargo xtask study --preset quick --model rigid"));
    assert!(doc.contains("| Q2s |"));

    // A second call has nothing to compute.
    let mut again = Counting::default();
    let start = std::time::Instant::now();
    run_study(&runs, &out, &mut again, &AtomicBool::new(false), false).unwrap();
    assert_eq!((again.computed, again.reused), (0, 5));
    assert!(start.elapsed().as_secs_f64() < 30.0);
}
