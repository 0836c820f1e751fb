//! A stability probe: the test model of a prepared specimen run for a fixed number of
//! steps at a chosen multiple of its computed stable step, under the full confining
//! pressure applied at once (a load step that excites every mode), with the platens
//! held. What stopped it, or how far its energy balance drifted, classifies the run
//! (docs/STABILITY.md).

use crate::loading::TestModel;
use crate::{PreparedSpecimen, TriaxialError};
use fdem_solver::{Guard, SolverError};
use serde::Serialize;

/// A finished probe whose energy balance error stayed below this fraction of its energy
/// scale is stable; above it (and below the guard's tolerance) it is slow energy growth.
pub const STABLE_ENERGY_ERROR: f64 = 0.01;

/// Steps between two checks of the energy balance and of the membrane's containment.
const CHECK_STEPS: u64 = 50;

/// How a probe ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StabilityClass {
    /// Every step done, the energy balance error below [`STABLE_ENERGY_ERROR`].
    Stable,
    /// Every step done, the error between [`STABLE_ENERGY_ERROR`] and the guard's
    /// tolerance: energy grows, slowly.
    SlowGrowth,
    /// The guard stopped the run: the balance error passed its tolerance.
    BlowUp,
    /// A contact deeper than half the depth limit stopped the run.
    Penetration,
    /// A node moved more than half the contact margin in a step, or a particle left the
    /// membrane.
    Tunnelling,
    /// A position, velocity or force became non-finite, or an element inverted.
    NonFinite,
}

impl StabilityClass {
    /// Name as written in tables (`stable`, `slow_growth`, ...).
    pub fn name(self) -> &'static str {
        match self {
            StabilityClass::Stable => "stable",
            StabilityClass::SlowGrowth => "slow_growth",
            StabilityClass::BlowUp => "blow_up",
            StabilityClass::Penetration => "penetration",
            StabilityClass::Tunnelling => "tunnelling",
            StabilityClass::NonFinite => "non_finite",
        }
    }

    /// Whether the run finished (stable or slow growth).
    pub fn finished(self) -> bool {
        matches!(self, StabilityClass::Stable | StabilityClass::SlowGrowth)
    }

    /// The class of a run stopped by `error`: the rule of docs/STABILITY.md, read from
    /// the messages the solver and contact detection stop a run with.
    pub fn of_error(error: &SolverError) -> StabilityClass {
        let text = error.to_string();
        if text.contains("tunnelling risk") {
            StabilityClass::Tunnelling
        } else if text.contains("depth limit") {
            StabilityClass::Penetration
        } else if text.contains("non-finite")
            || text.contains("not finite")
            || text.contains("inverted")
        {
            StabilityClass::NonFinite
        } else {
            StabilityClass::BlowUp
        }
    }
}

/// The outcome of one probe.
#[derive(Clone, Debug, Serialize)]
pub struct ProbeOutcome {
    /// Its class.
    pub class: StabilityClass,
    /// Steps done.
    pub steps: u64,
    /// Largest energy balance error over the energy scale seen at the checks.
    pub max_energy_error: f64,
    /// Deepest node contact seen at the checks (m).
    pub max_depth: f64,
    /// The step used (s).
    pub dt: f64,
    /// The computed stable bound (s) and what sets it.
    pub bound: f64,
    /// What sets the bound.
    pub bound_source: String,
    /// The message that stopped the run, if any.
    pub failure: Option<String>,
}

/// The test model's computed stable bound for `prepared` (what [`probe`] multiplies): a
/// map compares it with the bound of an earlier probe before reusing that probe.
///
/// # Errors
/// A model that cannot be built.
pub fn probe_bound(prepared: &PreparedSpecimen) -> Result<fdem_solver::StepBound, TriaxialError> {
    Ok(TestModel::build(prepared, None)?.sim.bound().clone())
}

/// Runs the probe: `steps` steps of `dt_factor` times the test model's stable bound.
///
/// # Errors
/// A model that cannot be built (set-up errors, not instabilities: those are outcomes).
pub fn probe(
    prepared: &PreparedSpecimen,
    dt_factor: f64,
    steps: u64,
) -> Result<ProbeOutcome, TriaxialError> {
    let setup = |e: SolverError| TriaxialError::Test {
        phase: "probe",
        message: e.to_string(),
    };
    let mut model = TestModel::build(prepared, None)?;
    let bound = model.sim.bound().clone();
    let dt = dt_factor * bound.dt;
    model.sim.fix_dt(dt).map_err(setup)?;
    model.sim.set_guard(Guard::default());
    model.set_pressure(prepared.spec.confining_pressure);
    model.sim.rebase_energy().map_err(setup)?;
    model.sim.reset_energy_reference();
    let mut outcome = ProbeOutcome {
        class: StabilityClass::Stable,
        steps: 0,
        max_energy_error: 0.0,
        max_depth: 0.0,
        dt,
        bound: bound.dt,
        bound_source: bound.source,
        failure: None,
    };
    for step in 1..=steps {
        if let Err(e) = model.sim.advance() {
            outcome.class = StabilityClass::of_error(&e);
            outcome.failure = Some(e.to_string());
            return Ok(outcome);
        }
        outcome.steps = step;
        if step % CHECK_STEPS == 0 || step == steps {
            let e = model.sim.energy();
            outcome.max_energy_error = outcome
                .max_energy_error
                .max(model.sim.relative_balance_error(&e));
            if let Some(c) = model.sim.contact() {
                outcome.max_depth = outcome.max_depth.max(c.last_report().max_depth);
            }
            if let Some(first) = model.particles_outside().first() {
                outcome.class = StabilityClass::Tunnelling;
                outcome.failure =
                    Some(format!("particle {first} left the membrane at step {step}"));
                return Ok(outcome);
            }
        }
    }
    if outcome.max_energy_error.is_nan() || outcome.max_energy_error > STABLE_ENERGY_ERROR {
        outcome.class = StabilityClass::SlowGrowth;
    }
    Ok(outcome)
}
