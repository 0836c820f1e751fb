//! Running a study: the plan with its estimated cost, then each run in turn, prepared or
//! reused, tested, and recorded in `runs/LABEL/run.json`. A finished run whose record
//! holds the same key is reused; a prepared specimen of the same preparation is reused
//! (the preparation is a run's first checkpoint); everything else is computed.

use crate::cost::{peak_memory, reset_peak_memory};
use crate::metrics::{PeakContacts, peak_contacts};
use crate::{RunDef, StudyError};
use fdem_triaxial::{
    Cached, CheckpointProgress, Observer, PreparedSpecimen, TestObserver, TestOptions, TestPhase,
    TestSummary, TriaxialError, prepare, run_test, specimen_time_step,
};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// Name of a run's record in its directory.
pub const RECORD_FILE: &str = "run.json";
/// Name of a run's prepared specimen in its directory.
pub const SPECIMEN_FILE: &str = "specimen.fdemspec";
/// The key of the run whose test checkpoint a run directory holds (beside
/// `fdem_triaxial::CHECKPOINT_FILE`): a checkpoint of another key is not resumed.
const CHECKPOINT_KEY_FILE: &str = "checkpoint.key";
/// Wall-clock seconds between two checkpoints of a running test: a run killed loses at
/// most this much work.
pub const CHECKPOINT_SECONDS: f64 = 300.0;

/// Steps of a whole run (preparation, consolidation, shear) over the steps of its shear
/// at the particles' own bound, for the cost estimate before the study has measured its
/// own ratio: `[rigid particles only, with deformable particles]`. The membrane sets a
/// smaller step than rigid particles do, so their ratio is the larger (docs/STUDY.md has
/// the measured ratios these defaults come from).
pub const STEPS_OVER_SHEAR: [f64; 2] = [7.5, 2.0];

/// Wall-clock seconds per step and per unit of work (a deformable element, a surface node
/// of a particle or a membrane node) before the study has measured its own; docs/STUDY.md
/// says where it comes from. Replaced by the median of the study's finished runs.
pub const DEFAULT_SECONDS_PER_UNIT_STEP: f64 = 2.0e-7;

/// The directory of a run.
pub fn run_dir(out: &Path, run: &RunDef) -> PathBuf {
    out.join(RUNS_DIR).join(run.label())
}

/// The study directory's folder of runs, one directory per run.
const RUNS_DIR: &str = "runs";

/// What one phase of a run cost.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct PhaseRecord {
    /// Steps.
    pub steps: u64,
    /// Wall-clock seconds.
    pub wall_seconds: f64,
    /// CPU seconds of all threads (NaN where unknown, written as `null`).
    #[serde(deserialize_with = "nan_if_null")]
    pub cpu_seconds: f64,
}

/// Reads a number that JSON holds as `null` where it was NaN (unknown): what serde_json
/// writes for a NaN, so that a record reads back as it was written.
fn nan_if_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// The record of one run (`runs/LABEL/run.json`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct RunRecord {
    /// The run's key ([`RunDef::key`]).
    pub key: String,
    /// Its label ([`RunDef::label`]).
    pub label: String,
    /// Series and test.
    pub series: String,
    /// Test name.
    pub test: String,
    /// Coarse-graining factor.
    pub h: f64,
    /// Exact scaling applied.
    pub exact_scaling: bool,
    /// Model asked for (`deformable`, `rigid`, `auto`).
    pub model: String,
    /// Model used: `deformable`, `rigid`, or `mixed (R of N rigid)` when `auto` chose
    /// per size class.
    pub model_used: String,
    /// Element order.
    pub order: String,
    /// Placement seed.
    pub seed: u64,
    /// `completed`, `failed` or `interrupted` (the test's summary status).
    pub status: String,
    /// The failure, if any.
    pub failure: Option<String>,
    /// Particles.
    pub particles: u64,
    /// Deformable elements.
    pub elements: u64,
    /// Surface nodes of the particles.
    pub surface_nodes: u64,
    /// Nodes of the membrane.
    pub membrane_nodes: u64,
    /// Preparation (its cost as recorded when the specimen was prepared, also when the
    /// specimen file was reused).
    pub preparation: PhaseRecord,
    /// Whether the prepared specimen came from an earlier call.
    pub preparation_reused: bool,
    /// Consolidation.
    pub consolidation: PhaseRecord,
    /// Shear.
    pub shear: PhaseRecord,
    /// Peak resident memory of the run (bytes), where the platform reports it.
    pub peak_memory_bytes: Option<u64>,
    /// Worker threads.
    pub threads: usize,
    /// The plan's step estimate before the correction by [`STEPS_OVER_SHEAR`] or measured
    /// runs ([`planned_steps`]); 0 in records written before it existed.
    #[serde(default)]
    pub planned_steps: u64,
    /// The contacts at the peak (a completed run's).
    #[serde(default)]
    pub peak: Option<PeakContacts>,
}

impl RunRecord {
    /// Steps of all phases.
    pub fn steps(&self) -> u64 {
        self.preparation.steps + self.consolidation.steps + self.shear.steps
    }

    /// Wall-clock seconds of all phases.
    pub fn wall_seconds(&self) -> f64 {
        self.preparation.wall_seconds + self.consolidation.wall_seconds + self.shear.wall_seconds
    }

    /// CPU seconds of all phases (NaN where a phase's are unknown).
    pub fn cpu_seconds(&self) -> f64 {
        self.preparation.cpu_seconds + self.consolidation.cpu_seconds + self.shear.cpu_seconds
    }

    /// Work units of one step: deformable elements, particle surface nodes and membrane
    /// nodes.
    pub fn units(&self) -> u64 {
        self.elements + self.surface_nodes + self.membrane_nodes
    }

    /// Element-steps of all phases.
    pub fn element_steps(&self) -> u64 {
        self.elements.saturating_mul(self.steps())
    }

    /// Surface-node-steps of all phases.
    pub fn surface_node_steps(&self) -> u64 {
        self.surface_nodes.saturating_mul(self.steps())
    }

    /// Whether the run finished.
    pub fn completed(&self) -> bool {
        self.status == "completed"
    }
}

/// Reads the record of `run` in `out`, when one exists with the run's key and finished.
pub fn finished_record(out: &Path, run: &RunDef) -> Result<Option<RunRecord>, StudyError> {
    Ok(record(out, run)?.filter(|r| r.completed() && r.peak.is_some()))
}

/// Reads the record of `run` in `out` when it failed with the run's key: a failure of
/// the same definition, which another call would repeat (a study runs it again only when
/// asked to retry failed runs).
pub fn failed_record(out: &Path, run: &RunDef) -> Result<Option<RunRecord>, StudyError> {
    Ok(record(out, run)?.filter(|r| r.status == "failed"))
}

/// Every run record in the study directory `out` that reads (whatever its definition: the
/// throughput of any finished run of this machine's study informs the estimates), or
/// `selected` when there are none besides them.
fn study_records(out: &Path, selected: &[RunRecord]) -> Vec<RunRecord> {
    let Ok(dirs) = std::fs::read_dir(out.join(RUNS_DIR)) else {
        return selected.to_vec();
    };
    let mut paths: Vec<_> = dirs
        .filter_map(|d| Some(d.ok()?.path().join(RECORD_FILE)))
        .collect();
    paths.sort();
    let all: Vec<RunRecord> = paths
        .iter()
        .filter_map(|p| serde_json::from_str(&std::fs::read_to_string(p).ok()?).ok())
        .collect();
    if all.is_empty() {
        selected.to_vec()
    } else {
        all
    }
}

/// Reads the record of `run` in `out`, when one exists with the run's key.
fn record(out: &Path, run: &RunDef) -> Result<Option<RunRecord>, StudyError> {
    let path = run_dir(out, run).join(RECORD_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&path).map_err(|e| StudyError::io("reading", &path, e))?;
    let record: RunRecord = serde_json::from_str(&text).map_err(|e| {
        StudyError::file(
            &path,
            format!("is not a run record: {e}; delete it to run again"),
        )
    })?;
    Ok((record.key == run.key()?).then_some(record))
}

/// One run of the plan.
#[derive(Clone, Debug, Serialize)]
pub struct PlannedRun {
    /// Label.
    pub label: String,
    /// Particles.
    pub particles: u64,
    /// Work units per step ([`RunRecord::units`], the membrane estimated).
    pub units: u64,
    /// Estimated steps of the whole run.
    pub steps: u64,
    /// Estimated wall-clock seconds (0 for a reused run).
    pub seconds: f64,
    /// `finished` (reused), `failed` (a failure of the same definition, not run again
    /// unless failed runs are retried), `resumes` (from its test's checkpoint, estimated
    /// at the pace of the checkpoint's phase), `prepared` (its specimen is reused) or
    /// `new`.
    pub state: &'static str,
}

/// The plan of a study, printed before the long work.
#[derive(Clone, Debug, Serialize)]
pub struct StudyPlan {
    /// The runs in order.
    pub runs: Vec<PlannedRun>,
    /// Estimated wall-clock seconds of everything still to run.
    pub total_seconds: f64,
    /// Seconds per unit-step used for the estimate.
    pub seconds_per_unit_step: f64,
    /// Steps of a run per planned shear step used for the estimate, `[rigid particles
    /// only, with deformable particles]`.
    pub steps_per_planned: [f64; 2],
    /// Where that figure comes from.
    pub throughput_source: String,
}

/// The membrane's node count is set by the test from the specimen's size; the plan
/// estimates it from the membrane spacing (docs/TRIAXIAL.md) as the lateral area over a
/// node's share.
fn membrane_nodes_estimate(run: &RunDef) -> u64 {
    let spacing = fdem_triaxial::MEMBRANE_SPACING * run.spec.smallest_simulated_size();
    let area = std::f64::consts::PI * run.spec.diameter * run.spec.height;
    (area / (spacing * spacing)).ceil() as u64
}

/// What the finished runs of a study measured for its estimates: seconds per unit-step
/// (the median of their shears) and steps per planned step (the median of their actual
/// over their planned steps), each with where it comes from.
#[derive(Clone, Debug)]
struct Throughput {
    seconds_per_unit_step: f64,
    steps_per_planned: [f64; 2],
    source: String,
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    v.retain(|x| x.is_finite() && *x > 0.0);
    v.sort_by(f64::total_cmp);
    (!v.is_empty()).then(|| v[v.len() / 2])
}

fn throughput(records: &[RunRecord]) -> Throughput {
    let done: Vec<&RunRecord> = records
        .iter()
        .filter(|r| r.completed() && r.shear.steps > 0 && r.units() > 0)
        .collect();
    let rate = median(
        done.iter()
            .map(|r| r.shear.wall_seconds / (r.shear.steps as f64 * r.units() as f64))
            .collect(),
    );
    let steps = |deformable: bool| {
        let k = usize::from(deformable);
        median(
            done.iter()
                .filter(|r| r.planned_steps > 0 && (r.elements > 0) == deformable)
                .map(|r| r.steps() as f64 / r.planned_steps as f64)
                .collect(),
        )
        .unwrap_or(STEPS_OVER_SHEAR[k])
    };
    match rate {
        Some(rate) => Throughput {
            seconds_per_unit_step: rate,
            steps_per_planned: [steps(false), steps(true)],
            source: format!("the median of {} finished run(s) of this study", done.len()),
        },
        None => Throughput {
            seconds_per_unit_step: DEFAULT_SECONDS_PER_UNIT_STEP,
            steps_per_planned: STEPS_OVER_SHEAR,
            source: "the defaults (no finished run in this study yet)".into(),
        },
    }
}

/// The checkpoint of `run`'s test in its directory, when there is one of this run.
fn own_checkpoint(out: &Path, run: &RunDef) -> Result<Option<PathBuf>, StudyError> {
    let dir = run_dir(out, run);
    let path = dir.join(fdem_triaxial::CHECKPOINT_FILE);
    let owner = std::fs::read_to_string(dir.join(CHECKPOINT_KEY_FILE)).unwrap_or_default();
    Ok((path.exists() && owner.trim() == run.key()?).then_some(path))
}

/// What is left of a run that resumes from its checkpoint, at the pace the checkpoint's
/// phase has had so far (a large run's step costs more per unit than the small runs
/// behind `seconds_per_step`, so its own pace is the better guide); `steps` is the
/// plan's estimate of the whole test's steps.
fn resumed_seconds(
    run: &RunDef,
    out: &Path,
    seconds_per_step: f64,
    steps: u64,
) -> Result<f64, StudyError> {
    let Some(path) = own_checkpoint(out, run)? else {
        return Ok(seconds_per_step * steps as f64);
    };
    let at = fdem_triaxial::checkpoint_progress(&path)?;
    // The test is about two thirds of a run's steps, as for a prepared run.
    let left = steps_left(&at, run.spec.shear_steps(at.dt), steps * 2 / 3);
    Ok(pace(&at, seconds_per_step) * left as f64)
}

/// The steps a test resumed from `at` has left: the shear's rest, or in consolidation
/// the plan's `test_steps` less those done, and at least the whole shear (`shear`).
fn steps_left(at: &CheckpointProgress, shear: u64, test_steps: u64) -> u64 {
    match at.phase {
        TestPhase::Shear => shear.saturating_sub(at.steps),
        TestPhase::Consolidation => shear.max(test_steps.saturating_sub(at.steps)),
    }
}

/// Wall seconds per step of the checkpoint's phase so far, or `fallback` before any.
fn pace(at: &CheckpointProgress, fallback: f64) -> f64 {
    if at.steps > 0 && at.wall_seconds > 0.0 {
        at.wall_seconds / at.steps as f64
    } else {
        fallback
    }
}

/// The shear steps of `run` at its particles' stable step (before any correction).
pub fn planned_steps(run: &RunDef) -> Result<u64, StudyError> {
    let (_, bound, _) = specimen_time_step(&run.spec)?;
    Ok(run.spec.shear_steps(bound * run.spec.test.dt_safety()))
}

/// The plan of `runs` in `out`: what is reused, what is computed and what it will cost;
/// runs that failed with the same definition are planned again only with `retry_failed`.
pub fn plan(runs: &[RunDef], out: &Path, retry_failed: bool) -> Result<StudyPlan, StudyError> {
    let mut finished = Vec::new();
    let mut states = Vec::new();
    for run in runs {
        let record = finished_record(out, run)?;
        let state = if record.is_some() {
            "finished"
        } else if !retry_failed && failed_record(out, run)?.is_some() {
            "failed"
        } else if matches!(
            PreparedSpecimen::cached(&run_dir(out, run).join(SPECIMEN_FILE), &run.spec),
            Cached::Reusable(_)
        ) {
            if own_checkpoint(out, run)?.is_some() {
                "resumes"
            } else {
                "prepared"
            }
        } else {
            "new"
        };
        states.push(state);
        finished.extend(record);
    }
    let measured = throughput(&study_records(out, &finished));
    let rate = measured.seconds_per_unit_step;
    let mut planned = Vec::new();
    for (run, state) in runs.iter().zip(states) {
        let counts = run.spec.counts()?;
        let ratio = measured.steps_per_planned[usize::from(counts.elements > 0)];
        let steps = (ratio * planned_steps(run)? as f64) as u64;
        let units = counts.elements + counts.surface_nodes + membrane_nodes_estimate(run);
        let seconds = match state {
            "finished" | "failed" => 0.0,
            // The preparation is about a third of a run's steps (docs/STUDY.md).
            "prepared" => rate * units as f64 * steps as f64 * 2.0 / 3.0,
            "resumes" => resumed_seconds(run, out, rate * units as f64, steps)?,
            _ => rate * units as f64 * steps as f64,
        };
        planned.push(PlannedRun {
            label: run.label(),
            particles: counts.particles,
            units,
            steps,
            seconds,
            state,
        });
    }
    Ok(StudyPlan {
        total_seconds: planned.iter().map(|p| p.seconds).sum(),
        runs: planned,
        seconds_per_unit_step: rate,
        steps_per_planned: measured.steps_per_planned,
        throughput_source: measured.source,
    })
}

/// Receives a study's plan and progress, and lends the observers of each run's
/// preparation and test (progress bars, the interrupt).
pub trait StudyObserver {
    /// The plan, once, before the first run.
    fn plan(&mut self, _plan: &StudyPlan) {}
    /// Run `index` (from 0) of `total` starts; `estimate` its planned seconds.
    fn run_started(&mut self, _index: usize, _total: usize, _run: &RunDef, _estimate: f64) {}
    /// Run `index` ended (or was reused).
    fn run_ended(&mut self, _index: usize, _total: usize, _record: &RunRecord, _reused: bool) {}
    /// The observer of a preparation.
    fn preparation(&mut self) -> &mut dyn Observer;
    /// The observer of a test.
    fn test(&mut self) -> &mut dyn TestObserver;
}

/// An observer that reports nothing.
#[derive(Debug, Default)]
pub struct SilentStudy {
    preparation: fdem_triaxial::Silent,
    test: fdem_triaxial::SilentTest,
}

impl StudyObserver for SilentStudy {
    fn preparation(&mut self) -> &mut dyn Observer {
        &mut self.preparation
    }
    fn test(&mut self) -> &mut dyn TestObserver {
        &mut self.test
    }
}

/// Runs every run of `runs` not yet finished in `out` (nor failed, unless `retry_failed`),
/// cheapest first by the plan's
/// estimate, and returns the records of all (reused ones included, in that order). A failed run is recorded and the study goes on; an
/// interrupt stops it after writing what the interrupted test had ([`StudyError::Interrupted`]).
pub fn run_study(
    runs: &[RunDef],
    out: &Path,
    observer: &mut dyn StudyObserver,
    interrupt: &AtomicBool,
    retry_failed: bool,
) -> Result<Vec<RunRecord>, StudyError> {
    let plan = plan(runs, out, retry_failed)?;
    observer.plan(&plan);
    // Cheapest first: an interrupted study has finished as many runs as it could.
    let mut order: Vec<usize> = (0..runs.len()).collect();
    order.sort_by(|&a, &b| plan.runs[a].seconds.total_cmp(&plan.runs[b].seconds));
    let mut records = Vec::new();
    for (i, (run, planned)) in order.iter().map(|&k| (&runs[k], &plan.runs[k])).enumerate() {
        let reused = match finished_record(out, run)? {
            Some(record) => Some(record),
            None if !retry_failed => failed_record(out, run)?,
            None => None,
        };
        if let Some(record) = reused {
            observer.run_ended(i, runs.len(), &record, true);
            records.push(record);
            continue;
        }
        observer.run_started(i, runs.len(), run, planned.seconds);
        let record = one_run(run, out, observer, interrupt)?;
        observer.run_ended(i, runs.len(), &record, false);
        if record.status == "interrupted" || interrupt.load(Ordering::SeqCst) {
            return Err(StudyError::Interrupted { run: run.label() });
        }
        records.push(record);
    }
    Ok(records)
}

/// Prepares (or reuses the preparation of) one run, tests it and writes its record.
fn one_run(
    run: &RunDef,
    out: &Path,
    observer: &mut dyn StudyObserver,
    interrupt: &AtomicBool,
) -> Result<RunRecord, StudyError> {
    let dir = run_dir(out, run);
    std::fs::create_dir_all(&dir).map_err(|e| StudyError::io("creating", &dir, e))?;
    let record_path = dir.join(RECORD_FILE);
    if record_path.exists() {
        // A record of another definition or of an unfinished run: this run replaces it.
        std::fs::remove_file(&record_path)
            .map_err(|e| StudyError::io("removing", &record_path, e))?;
    }
    forget_other_checkpoint(&dir, &run.key()?)?;
    reset_peak_memory();
    let specimen_path = dir.join(SPECIMEN_FILE);
    let (prepared, reused) = match PreparedSpecimen::cached(&specimen_path, &run.spec) {
        Cached::Reusable(s) => (*s, true),
        _ => {
            let prepared = match prepare(&run.spec, observer.preparation()) {
                Ok(p) => p,
                Err(e @ TriaxialError::Interrupted { .. }) => return Err(e.into()),
                Err(e) => return failed(run, &record_path, format!("preparation: {e}")),
            };
            if !prepared.report.checks.failures.is_empty() {
                // Not saved: a later call prepares again (and fails the same way unless
                // the definition changed).
                let why = prepared.report.checks.failures.join("; ");
                return failed(
                    run,
                    &record_path,
                    format!("the prepared specimen failed its checks: {why}"),
                );
            }
            prepared.save(&specimen_path)?;
            // A checkpoint of another preparation is not this run's.
            remove_checkpoint(&dir)?;
            (prepared, false)
        }
    };
    let options = TestOptions {
        checkpoint_interval: Some(CHECKPOINT_SECONDS),
        // A checkpoint of another definition was cleared with the preparation above.
        resume: true,
        ..TestOptions::new(&dir)
    };
    let summary = match run_test(&prepared, &options, observer.test(), interrupt) {
        Ok(summary) => summary,
        Err(e @ TriaxialError::Interrupted { .. }) => return Err(e.into()),
        // The test's summary.json in the run directory says where it stopped.
        Err(e) => return failed(run, &record_path, format!("test: {e}")),
    };
    let record = record_of(run, &dir, &prepared, reused, &summary)?;
    let text = serde_json::to_string_pretty(&record)
        .map_err(|e| StudyError::file(&record_path, e.to_string()))?;
    fdem_core::fs::write_atomically(&record_path, text)
        .map_err(|e| StudyError::io("writing", &record_path, e))?;
    Ok(record)
}

/// Removes the test checkpoint in `dir` unless it belongs to the run of `key`, and marks
/// the directory's checkpoints as that run's.
fn forget_other_checkpoint(dir: &Path, key: &str) -> Result<(), StudyError> {
    let marker = dir.join(CHECKPOINT_KEY_FILE);
    let owner = std::fs::read_to_string(&marker).unwrap_or_default();
    if owner.trim() != key {
        remove_checkpoint(dir)?;
    }
    fdem_core::fs::write_atomically(&marker, format!("{key}\n"))
        .map_err(|e| StudyError::io("writing", &marker, e))
}

/// Removes the test checkpoint in `dir`, if there is one.
fn remove_checkpoint(dir: &Path) -> Result<(), StudyError> {
    let checkpoint = dir.join(fdem_triaxial::CHECKPOINT_FILE);
    if checkpoint.exists() {
        std::fs::remove_file(&checkpoint)
            .map_err(|e| StudyError::io("removing", &checkpoint, e))?;
    }
    Ok(())
}

/// Records a run that failed (preparation or test) with its reason, and returns it; the
/// study goes on with the next run.
fn failed(run: &RunDef, path: &Path, failure: String) -> Result<RunRecord, StudyError> {
    let counts = run.spec.counts()?;
    let mut record = RunRecord {
        key: run.key()?,
        label: run.label(),
        series: run.series.clone(),
        test: run.test.clone(),
        h: run.h(),
        exact_scaling: run.exact_scaling(),
        model: run.model().name().to_string(),
        model_used: String::new(),
        order: run.order().to_string(),
        seed: run.seed,
        status: "failed".into(),
        failure: Some(failure),
        particles: counts.particles,
        elements: counts.elements,
        surface_nodes: counts.surface_nodes,
        membrane_nodes: 0,
        preparation: PhaseRecord::default(),
        preparation_reused: false,
        consolidation: PhaseRecord::default(),
        shear: PhaseRecord::default(),
        peak_memory_bytes: peak_memory(),
        threads: rayon::current_num_threads(),
        planned_steps: planned_steps(run)?,
        peak: None,
    };
    if let Some(dir) = path.parent() {
        add_failed_test_costs(&mut record, &dir.join("summary.json"));
    }
    let text =
        serde_json::to_string_pretty(&record).map_err(|e| StudyError::file(path, e.to_string()))?;
    fdem_core::fs::write_atomically(path, text).map_err(|e| StudyError::io("writing", path, e))?;
    Ok(record)
}

/// Fills the phase costs, the model used and the membrane nodes of a failed run's
/// `record` from the test's `summary.json` (a test that failed writes it; a preparation
/// that failed leaves none, and the record keeps zeros).
fn add_failed_test_costs(record: &mut RunRecord, summary: &Path) {
    let Some(s) = read_summary(summary) else {
        return;
    };
    let phase = |c: &serde_json::Value| PhaseRecord {
        steps: c["steps"].as_u64().unwrap_or(0),
        wall_seconds: c["wall_seconds"].as_f64().unwrap_or(0.0),
        cpu_seconds: c["cpu_seconds"].as_f64().unwrap_or(f64::NAN),
    };
    record.consolidation = phase(&s["consolidation"]["cost"]);
    record.shear = phase(&s["shear"]);
    record.membrane_nodes = s["plan"]["membrane_nodes"].as_u64().unwrap_or(0);
    let classes = s["classes"].as_array().cloned().unwrap_or_default();
    let count = |rigid: bool| -> u64 {
        classes
            .iter()
            .filter(|c| (c["model"].as_str() == Some("rigid")) == rigid)
            .filter_map(|c| c["particles"].as_u64())
            .sum()
    };
    if !classes.is_empty() {
        record.model_used = model_used(count(true), count(true) + count(false));
    }
}

/// A test's `summary.json` at `path` as JSON, if it is there and parses.
pub(crate) fn read_summary(path: &Path) -> Option<serde_json::Value> {
    let text = std::fs::read_to_string(path).ok()?;
    serde_json::from_str(&text).ok()
}

/// The model a run used, from its rigid and total particle counts.
fn model_used(rigid: u64, particles: u64) -> String {
    match (rigid, particles) {
        (0, _) => "deformable".to_string(),
        (r, n) if r == n => "rigid".to_string(),
        (r, n) => format!("mixed ({r} of {n} rigid)"),
    }
}

fn record_of(
    run: &RunDef,
    dir: &Path,
    prepared: &PreparedSpecimen,
    reused: bool,
    summary: &TestSummary,
) -> Result<RunRecord, StudyError> {
    let counts = run.spec.counts()?;
    let report = &prepared.report;
    let phase = |c: &fdem_triaxial::PhaseCost| PhaseRecord {
        steps: c.steps,
        wall_seconds: c.wall_seconds,
        cpu_seconds: c.cpu_seconds.unwrap_or(f64::NAN),
    };
    let model_used = model_used(counts.rigid_particles, counts.particles);
    Ok(RunRecord {
        key: run.key()?,
        label: run.label(),
        series: run.series.clone(),
        test: run.test.clone(),
        h: run.h(),
        exact_scaling: run.exact_scaling(),
        model: run.model().name().to_string(),
        model_used,
        order: run.order().to_string(),
        seed: run.seed,
        status: summary.status.clone(),
        failure: summary.failure.clone(),
        particles: counts.particles,
        elements: counts.elements,
        surface_nodes: counts.surface_nodes,
        membrane_nodes: summary.plan.membrane_nodes as u64,
        preparation: PhaseRecord {
            steps: report.compact_steps + report.settle_steps,
            wall_seconds: report.wall_seconds,
            cpu_seconds: report.cpu_seconds.unwrap_or(f64::NAN),
        },
        preparation_reused: reused,
        consolidation: phase(&summary.consolidation.cost),
        shear: phase(&summary.shear),
        peak_memory_bytes: peak_memory(),
        threads: summary.threads,
        planned_steps: planned_steps(run)?,
        peak: if summary.status == "completed" {
            Some(peak_contacts(dir, counts.particles as usize)?)
        } else {
            None
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(phase: TestPhase, steps: u64, wall_seconds: f64) -> CheckpointProgress {
        CheckpointProgress {
            phase,
            steps,
            dt: 1e-5,
            wall_seconds,
        }
    }

    /// A resumed run is estimated from its own checkpoint: the rest of its shear, or in
    /// consolidation the plan's test steps less those done and at least the shear, at the
    /// pace its phase has had.
    #[test]
    fn a_resumed_run_is_estimated_at_its_own_pace() {
        let shear = at(TestPhase::Shear, 100, 20.0);
        assert_eq!(steps_left(&shear, 250, 1000), 150);
        assert_eq!(steps_left(&at(TestPhase::Shear, 300, 1.0), 250, 1000), 0);
        assert_eq!(pace(&shear, 1.0), 0.2);
        let early = at(TestPhase::Consolidation, 100, 5.0);
        assert_eq!(steps_left(&early, 250, 1000), 900);
        let late = at(TestPhase::Consolidation, 900, 5.0);
        assert_eq!(steps_left(&late, 250, 1000), 250);
        // Before its first step a phase has no pace of its own.
        assert_eq!(pace(&at(TestPhase::Consolidation, 0, 0.0), 0.3), 0.3);
    }

    /// A phase whose CPU time is unknown (NaN, written as `null`: a run interrupted before
    /// its shear) reads back as NaN, so an interrupted study resumes.
    #[test]
    fn an_unknown_cpu_time_survives_the_record_round_trip() {
        let phase = PhaseRecord {
            steps: 0,
            wall_seconds: 0.0,
            cpu_seconds: f64::NAN,
        };
        let text = serde_json::to_string(&phase).unwrap();
        assert!(text.contains("\"cpu_seconds\":null"), "{text}");
        let back: PhaseRecord = serde_json::from_str(&text).unwrap();
        assert!(back.cpu_seconds.is_nan() && back.steps == 0);
        let known: PhaseRecord =
            serde_json::from_str(r#"{"steps":3,"wall_seconds":1.5,"cpu_seconds":2.5}"#).unwrap();
        assert_eq!(known.cpu_seconds, 2.5);
    }
}
