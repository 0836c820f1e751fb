//! Contact as a force contribution: a thin adapter from `fdem-contact`'s [`ContactModel`]
//! to the engine's [`ForceContribution`] interface.

use crate::SolverError;
use crate::forces::{ForceContribution, NodeView, Powers, StepBound};
use fdem_contact::{ContactModel, ContactReport};

/// Penalty contact between particles and with rigid walls (MODEL.md section 2).
#[derive(Debug)]
pub struct ContactForces {
    /// The contact model: detection, law, history, wall forces, snapshots.
    pub model: ContactModel,
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

    /// The report of the last evaluation (contacts, energies, deepest penetration).
    pub fn last_report(&self) -> &ContactReport {
        &self.last
    }
}

impl ForceContribution for ContactForces {
    fn name(&self) -> &str {
        "contact"
    }

    fn stable_time_step(&self) -> Option<StepBound> {
        self.model.stable_time_step().map(|s| StepBound {
            dt: s.time_step,
            source: format!("contact: body {}, node {}", s.body, s.node),
        })
    }

    fn add_forces(
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
        let powers = Powers {
            external: report.wall_power,
            damping: report.normal_damping_power + report.tangential_damping_power,
            friction_energy: report.friction_dissipation,
        };
        self.last = report;
        Ok(powers)
    }

    fn potential_energy(&self, _nodes: NodeView<'_>) -> f64 {
        self.model.stored_energy()
    }

    fn as_contact(&self) -> Option<&ContactForces> {
        Some(self)
    }

    fn as_contact_mut(&mut self) -> Option<&mut ContactForces> {
        Some(self)
    }
}
