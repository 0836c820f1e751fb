//! Contact as a part of the engine: a thin adapter from `fdem-contact`'s [`ContactModel`]
//! to the engine's step (forces, powers, stored energy, stable step).

use crate::SolverError;
use crate::forces::{NodeView, Powers, StepBound};
use fdem_contact::{ContactModel, ContactReport};

/// Penalty contact between particles, with sheets and with rigid walls (docs/MODEL.md
/// section 2).
///
/// Contact is a stage of every step, not a plug-in contribution: its springs act on the
/// same surface nodes as the elements, so its stable bound combines with the elastic one
/// ([`StepBound::of_model`]), and outputs read its contacts.
#[derive(Debug)]
pub struct ContactForces {
    model: ContactModel,
    last: ContactReport,
}

impl ContactForces {
    /// Wraps a contact model.
    pub fn new(model: ContactModel) -> Self {
        ContactForces {
            model,
            last: ContactReport::default(),
        }
    }

    /// The contact model: detection, law, history, wall forces, snapshots.
    pub fn model(&self) -> &ContactModel {
        &self.model
    }

    /// The contact model, mutable: move a wall, restore friction history between steps.
    pub fn model_mut(&mut self) -> &mut ContactModel {
        &mut self.model
    }

    /// The report of the last evaluation (contacts, energies, deepest penetration).
    pub fn last_report(&self) -> &ContactReport {
        &self.last
    }

    /// The contact springs' stable step and the node that sets it.
    pub fn stable_time_step(&self) -> Option<StepBound> {
        self.model.stable_time_step().map(|s| StepBound {
            dt: s.time_step,
            source: format!("contact: body {}, node {}", s.body, s.node),
        })
    }

    /// The sheet nodes' stable step with both sides of a conformal contact counted
    /// ([`ContactModel::sheet_stable_time_step`]); `None` without sheets.
    pub fn sheet_stable_time_step(&self) -> Option<StepBound> {
        self.model.sheet_stable_time_step().map(|s| StepBound {
            dt: s.time_step,
            source: format!(
                "contact on the sheet, two-sided: body {}, node {}",
                s.body, s.node
            ),
        })
    }

    /// Adds the contact forces at `nodes` to `forces` (N) and returns the powers of the
    /// walls (external), the dashpots (damping) and friction sliding over the step.
    pub fn add_forces(
        &mut self,
        nodes: NodeView<'_>,
        forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError> {
        let report = self.model.add_forces(
            nodes.positions,
            nodes.velocities,
            nodes.time,
            nodes.dt,
            forces,
        )?;
        Ok(self.book(report))
    }

    /// Finds the contacts at `nodes` and evaluates the law, touching no force array
    /// ([`ContactModel::evaluate`]); the engine computes the element forces meanwhile.
    pub(crate) fn evaluate(&mut self, nodes: NodeView<'_>) -> Result<(), SolverError> {
        Ok(self
            .model
            .evaluate(nodes.positions, nodes.velocities, nodes.time, nodes.dt)?)
    }

    /// Adds the forces of the last [`ContactForces::evaluate`] to `forces` (N) and returns
    /// the powers of the walls (external), the dashpots (damping) and friction sliding over
    /// the step.
    pub(crate) fn add_evaluated_forces(
        &mut self,
        forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError> {
        let report = self.model.add_evaluated_forces(forces)?;
        Ok(self.book(report))
    }

    /// Keeps `report` as the last one and returns its powers.
    fn book(&mut self, report: ContactReport) -> Powers {
        let powers = Powers {
            external: report.wall_power,
            damping: report.normal_damping_power + report.tangential_damping_power,
            friction_energy: report.friction_dissipation,
        };
        self.last = report;
        powers
    }

    /// Energy stored in the contact springs (J).
    pub fn potential_energy(&self) -> f64 {
        self.model.stored_energy()
    }
}
