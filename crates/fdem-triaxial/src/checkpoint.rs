//! The test's checkpoint file: everything a triaxial test needs to continue from a step
//! as if it had never stopped (docs/TRIAXIAL.md, "Checkpoints").
//!
//! It holds the simulation's state ([`fdem_solver::SimulationCheckpoint`]), the
//! confining pressure the driver last set, the stage (consolidation or shear) with its
//! loop state, the rows of the stage's CSV file so far, the bookkeeping of the outputs
//! (energy windows, escape checks, deepest contact, discarded membrane hits), the
//! consolidation's result, the peak's contact snapshot, the wall and CPU seconds spent
//! before, and the definition it belongs to (the specimen and test as TOML). It is a
//! [`fdem_core::sections`] file, written atomically.

use crate::TriaxialError;
use crate::measure::CurvePoint;
use fdem_core::sections::Sections;
use fdem_solver::SimulationCheckpoint;
use std::path::Path;

/// The checkpoint's file name in the test's output directory.
pub const CHECKPOINT_FILE: &str = "checkpoint.fdemckpt";
const MAGIC: &[u8; 8] = b"FDEMCKPT";
/// Format version this build writes and reads (2: the stage's reference holds the
/// membrane's draped volume).
const VERSION: u32 = 2;

/// Where the test stood.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Stage {
    /// In consolidation, after `steps` steps.
    Consolidation {
        steps: u64,
        /// The ramp: start time, duration, start pressure, sigma_0.
        ramp: [f64; 4],
        /// Time and volume of the last equilibrium check.
        last_volume: [f64; 2],
        /// Height, volume and the membrane's draped volume at the start of consolidation.
        reference: [f64; 3],
    },
    /// In shear, after `steps` steps from time `t0`.
    Shear {
        steps: u64,
        t0: f64,
        /// Height, volume and the membrane's draped volume at the start of shear.
        reference: [f64; 3],
        /// Axial strain of the next curve row.
        next_output: f64,
    },
}

/// A test's checkpoint.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct TestCheckpoint {
    /// The specimen and test definition as TOML.
    pub definition: String,
    pub sim: SimulationCheckpoint,
    /// Confining pressure set last (Pa).
    pub pressure: f64,
    pub stage: Stage,
    /// Rows of the stage's CSV file so far (`consolidation.csv` or `curve.csv`).
    pub rows: Vec<CurvePoint>,
    /// Escape checks, discarded membrane hits (sum, most), deepest contact.
    pub outputs: [f64; 4],
    /// The phase's energy windows: initial, error, work, damping, friction.
    pub energy: [f64; 5],
    /// The consolidation's result (`test_run::consolidation_numbers`).
    pub consolidation: Vec<f64>,
    /// Wall and CPU seconds the stage had taken before this checkpoint.
    pub seconds: [f64; 2],
    /// The peak's contact snapshot (nodes, pairs) and its axial strain.
    pub peak: Option<(String, String, f64)>,
}

fn stage_numbers(stage: &Stage) -> Vec<f64> {
    match *stage {
        Stage::Consolidation {
            steps,
            ramp,
            last_volume,
            reference,
        } => [0.0, steps as f64]
            .into_iter()
            .chain(ramp)
            .chain(last_volume)
            .chain(reference)
            .collect(),
        Stage::Shear {
            steps,
            t0,
            reference,
            next_output,
        } => [1.0, steps as f64, t0]
            .into_iter()
            .chain(reference)
            .chain([next_output])
            .collect(),
    }
}

fn stage_from(n: &[f64]) -> Result<Stage, String> {
    match (n.first().copied(), n.len()) {
        (Some(0.0), 11) => Ok(Stage::Consolidation {
            steps: n[1] as u64,
            ramp: [n[2], n[3], n[4], n[5]],
            last_volume: [n[6], n[7]],
            reference: [n[8], n[9], n[10]],
        }),
        (Some(1.0), 7) => Ok(Stage::Shear {
            steps: n[1] as u64,
            t0: n[2],
            reference: [n[3], n[4], n[5]],
            next_output: n[6],
        }),
        _ => Err("section `test.stage` is not a stage".into()),
    }
}

fn array<const N: usize>(s: &Sections, name: &str) -> Result<[f64; N], String> {
    let v = s.numbers_of(name, N)?;
    Ok(std::array::from_fn(|i| v[i]))
}

impl TestCheckpoint {
    /// Writes the checkpoint to `path` atomically.
    pub(crate) fn write(&self, path: &Path) -> Result<(), TriaxialError> {
        let mut s = Sections::new();
        s.put_text("test.definition", self.definition.clone());
        self.sim.to_sections("sim", &mut s);
        s.put_numbers("test.pressure", vec![self.pressure]);
        s.put_numbers("test.stage", stage_numbers(&self.stage));
        let rows = self.rows.iter().flat_map(CurvePoint::to_numbers).collect();
        s.put_numbers("test.rows", rows);
        s.put_numbers("test.outputs", self.outputs.to_vec());
        s.put_numbers("test.energy", self.energy.to_vec());
        s.put_numbers("test.consolidation", self.consolidation.clone());
        s.put_numbers("test.seconds", self.seconds.to_vec());
        if let Some((nodes, pairs, eps_a)) = &self.peak {
            s.put_text("test.peak.nodes", nodes.clone());
            s.put_text("test.peak.pairs", pairs.clone());
            s.put_numbers("test.peak.eps_a", vec![*eps_a]);
        }
        s.write(path, MAGIC, VERSION)
            .map_err(|e| TriaxialError::io("writing the checkpoint", path, e))
    }

    /// Reads the checkpoint at `path`.
    ///
    /// # Errors
    /// A file that cannot be read or is not a whole checkpoint of this format, named with
    /// the way out (delete it to start again).
    pub(crate) fn read(path: &Path) -> Result<TestCheckpoint, TriaxialError> {
        let bad = |why: String| {
            TriaxialError::file(
                path,
                format!("{why}; delete it to run the test from its start"),
            )
        };
        let s = Sections::read(path, MAGIC, VERSION).map_err(bad)?;
        let parse = || -> Result<TestCheckpoint, String> {
            let rows = s.numbers("test.rows")?;
            if !rows.len().is_multiple_of(CurvePoint::NUMBERS) {
                return Err("section `test.rows` is not whole rows".into());
            }
            let peak = match s.text("test.peak.nodes") {
                Ok(nodes) => Some((
                    nodes.to_string(),
                    s.text("test.peak.pairs")?.to_string(),
                    s.numbers_of("test.peak.eps_a", 1)?[0],
                )),
                Err(_) => None,
            };
            Ok(TestCheckpoint {
                definition: s.text("test.definition")?.to_string(),
                sim: SimulationCheckpoint::from_sections("sim", &s)?,
                pressure: s.numbers_of("test.pressure", 1)?[0],
                stage: stage_from(s.numbers("test.stage")?)?,
                rows: rows
                    .chunks_exact(CurvePoint::NUMBERS)
                    .map(CurvePoint::from_numbers)
                    .collect(),
                outputs: array(&s, "test.outputs")?,
                energy: array(&s, "test.energy")?,
                consolidation: s.numbers("test.consolidation")?.to_vec(),
                seconds: array(&s, "test.seconds")?,
                peak,
            })
        };
        parse().map_err(bad)
    }
}

/// Where the checkpoint of a test stood, for estimates of what is left.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CheckpointProgress {
    /// The phase it was written in.
    pub phase: crate::TestPhase,
    /// Steps done in that phase.
    pub steps: u64,
    /// The simulation's step (s).
    pub dt: f64,
    /// Wall-clock seconds the phase had taken (all earlier processes together).
    pub wall_seconds: f64,
}

/// Where the checkpoint at `path` stood (it reads the whole file).
///
/// # Errors
/// As [`TestCheckpoint::read`].
pub fn checkpoint_progress(path: &Path) -> Result<CheckpointProgress, TriaxialError> {
    let c = TestCheckpoint::read(path)?;
    let (phase, steps) = match c.stage {
        Stage::Consolidation { steps, .. } => (crate::TestPhase::Consolidation, steps),
        Stage::Shear { steps, .. } => (crate::TestPhase::Shear, steps),
    };
    Ok(CheckpointProgress {
        phase,
        steps,
        dt: c.sim.dt,
        wall_seconds: c.seconds[0],
    })
}

impl crate::TestModel {
    /// The test model of `prepared` in the state of the checkpoint at `path` (written by
    /// a test of the same definition): for diagnostics that step it by hand
    /// (`sim.advance()`) from shortly before an event. The platens keep the motion they
    /// had; a consolidation's servo is not driven.
    ///
    /// # Errors
    /// A checkpoint that does not read, belongs to another definition or does not fit
    /// the model.
    pub fn at_checkpoint(
        prepared: &crate::PreparedSpecimen,
        path: &Path,
    ) -> Result<crate::TestModel, TriaxialError> {
        let c = TestCheckpoint::read(path)?;
        if c.definition != prepared.spec.to_toml_string()? {
            return Err(TriaxialError::file(
                path,
                "is a checkpoint of another specimen or test definition",
            ));
        }
        let mut model = crate::TestModel::build(prepared, None)?;
        model
            .sim
            .restore_checkpoint(&c.sim)
            .map_err(|e| TriaxialError::file(path, e.to_string()))?;
        model.set_pressure(c.pressure);
        model.follow_platens()?;
        Ok(model)
    }
}
