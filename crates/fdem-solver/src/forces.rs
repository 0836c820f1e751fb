//! The force-contribution interface and the elastic contribution of the particles.
//!
//! Every physical effect that puts force on nodes (element elasticity now; contact, walls
//! and membranes later) implements [`ForceContribution`]. The engine zeroes the force
//! array, asks every contribution to add its forces for the current positions and
//! velocities, and takes the smallest of their stable-step bounds.

use crate::{Body, SolverError};
use fdem_elastic::ElementSet;
use std::ops::Range;

/// Read-only view of the node state that contributions evaluate forces from.
#[derive(Clone, Copy, Debug)]
pub struct NodeView<'a> {
    /// Current positions (m).
    pub positions: &'a [[f64; 3]],
    /// Velocities at the evaluation instant (m/s): the half-step velocities of the
    /// velocity-Verlet update.
    pub velocities: &'a [[f64; 3]],
    /// Lumped masses (kg).
    pub masses: &'a [f64],
    /// Simulated time of the evaluation (s).
    pub time: f64,
    /// The step size in use (s): contributions with history (friction) integrate with it.
    pub dt: f64,
}

/// A stable time-step bound and what sets it.
#[derive(Clone, Debug, PartialEq)]
pub struct StepBound {
    /// Largest stable step (s) for central differences.
    pub dt: f64,
    /// Human-readable origin, e.g. `elastic: body 3, element 17`.
    pub source: String,
}

impl StepBound {
    /// The smallest of the given bounds (contributions without one give `None`).
    pub fn smallest(bounds: impl IntoIterator<Item = Option<StepBound>>) -> Option<StepBound> {
        bounds
            .into_iter()
            .flatten()
            .min_by(|a, b| a.dt.total_cmp(&b.dt))
    }
}

/// Energy exchanged by a contribution at the evaluated state, for energy bookkeeping.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Powers {
    /// Power of external forces on the nodes (`sum f_ext . v`), W.
    pub external: f64,
    /// Power dissipated by viscous damping, W (positive when energy is removed).
    pub damping: f64,
    /// Energy dissipated by friction sliding during this evaluation's step, J.
    pub friction_energy: f64,
}

/// Something that adds forces to nodes.
pub trait ForceContribution: Send {
    /// Short name used in reports (`elastic`, `contact`, ...).
    fn name(&self) -> &str;
    /// The stable-step bound this contribution imposes, if any.
    fn stable_time_step(&self) -> Option<StepBound>;
    /// Adds this contribution's forces to `forces` (N) and returns the powers it exchanges.
    fn add_forces(
        &mut self,
        nodes: NodeView<'_>,
        forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError>;
    /// Energy stored by this contribution (strain energy, contact springs) in J.
    fn potential_energy(&self, nodes: NodeView<'_>) -> f64;
    /// The contribution as contact forces, if it is one (for contact outputs).
    fn as_contact(&self) -> Option<&crate::ContactForces> {
        None
    }
    /// The contribution as mutable contact forces, if it is one (to restore history).
    fn as_contact_mut(&mut self) -> Option<&mut crate::ContactForces> {
        None
    }
}

/// The elements of one body with its node range.
#[derive(Debug)]
pub struct BodyElements {
    /// Body id.
    pub body: usize,
    /// Global node ids of the body (element connectivity is local to this range).
    pub nodes: Range<usize>,
    /// The body's precomputed element set.
    pub set: ElementSet,
}

/// Elastic forces of all particles: one [`ElementSet`] per body, evaluated in parallel
/// over bodies. Bodies own disjoint node ranges, so no locks and no reduction are needed
/// and the result is bit-for-bit the same for any thread count.
#[derive(Debug, Default)]
pub struct ElasticForces {
    /// Per-body element sets, in increasing node order.
    pub bodies: Vec<BodyElements>,
}

/// Bodies handled serially below this count per task (keeps rayon's overhead small).
const SERIAL_BODIES: usize = 4;

impl ElasticForces {
    /// Builds the element sets of `bodies` from the reference positions and the global
    /// connectivity (`npe` node ids per element).
    pub fn new(
        material: &fdem_elastic::Material,
        npe: usize,
        reference: &[[f64; 3]],
        connectivity: &[usize],
        bodies: &[Body],
    ) -> Result<Self, SolverError> {
        let mut out = Vec::with_capacity(bodies.len());
        for (id, body) in bodies.iter().enumerate() {
            let local: Vec<usize> = connectivity
                [body.elements.start * npe..body.elements.end * npe]
                .iter()
                .map(|&n| n - body.nodes.start)
                .collect();
            let set = ElementSet::new(material, npe, &reference[body.nodes.clone()], &local)
                .map_err(|source| SolverError::Elastic { body: id, source })?;
            out.push(BodyElements {
                body: id,
                nodes: body.nodes.clone(),
                set,
            });
        }
        Ok(ElasticForces { bodies: out })
    }

    /// Lumped masses of all nodes (`n_nodes` entries; nodes of no body get 0).
    pub fn lumped_masses(&self, n_nodes: usize) -> Vec<f64> {
        let mut masses = vec![0.0; n_nodes];
        for b in &self.bodies {
            let local = b.set.lumped_masses(b.nodes.len());
            masses[b.nodes.clone()].copy_from_slice(&local);
        }
        masses
    }

    /// Cauchy stress per element (xx, yy, zz, yz, xz, xy; Pa), for output.
    pub fn stresses(&self, positions: &[[f64; 3]]) -> Result<Vec<[f64; 6]>, SolverError> {
        let n: usize = self.bodies.iter().map(|b| b.set.n_elements()).sum();
        let mut out = vec![[0.0; 6]; n];
        let mut offset = 0;
        for b in &self.bodies {
            let ne = b.set.n_elements();
            b.set
                .cauchy_stresses(&positions[b.nodes.clone()], &mut out[offset..offset + ne])
                .map_err(|source| SolverError::Elastic {
                    body: b.body,
                    source,
                })?;
            offset += ne;
        }
        Ok(out)
    }
}

/// Adds the elastic forces of `bodies` (which start at global node `offset` and are
/// contiguous) into `forces`, splitting the work in halves with `rayon::join`.
fn add_elastic(
    bodies: &mut [BodyElements],
    positions: &[[f64; 3]],
    forces: &mut [[f64; 3]],
    offset: usize,
) -> Result<(), SolverError> {
    if bodies.len() <= SERIAL_BODIES {
        for b in bodies.iter_mut() {
            let r = b.nodes.start - offset..b.nodes.end - offset;
            b.set
                .add_forces(&positions[b.nodes.clone()], &mut forces[r])
                .map_err(|source| SolverError::Elastic {
                    body: b.body,
                    source,
                })?;
        }
        return Ok(());
    }
    let mid = bodies.len() / 2;
    let split_node = bodies[mid].nodes.start;
    let (left_bodies, right_bodies) = bodies.split_at_mut(mid);
    let (left_forces, right_forces) = forces.split_at_mut(split_node - offset);
    let (left, right) = rayon::join(
        || add_elastic(left_bodies, positions, left_forces, offset),
        || add_elastic(right_bodies, positions, right_forces, split_node),
    );
    // Report the error of the lowest body first, whatever the thread timing.
    left.and(right)
}

impl ForceContribution for ElasticForces {
    fn name(&self) -> &str {
        "elastic"
    }

    fn stable_time_step(&self) -> Option<StepBound> {
        let mut best: Option<StepBound> = None;
        for b in &self.bodies {
            let steps = b.set.element_time_steps();
            if let Some((e, &dt)) = steps.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))
                && best.as_ref().is_none_or(|s| dt < s.dt)
            {
                best = Some(StepBound {
                    dt,
                    source: format!("elastic: body {}, element {e}", b.body),
                });
            }
        }
        best
    }

    fn add_forces(
        &mut self,
        nodes: NodeView<'_>,
        forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError> {
        let start = self.bodies.first().map_or(0, |b| b.nodes.start);
        let end = self.bodies.last().map_or(0, |b| b.nodes.end);
        add_elastic(
            &mut self.bodies,
            nodes.positions,
            &mut forces[start..end],
            start,
        )?;
        Ok(Powers::default())
    }

    fn potential_energy(&self, nodes: NodeView<'_>) -> f64 {
        self.bodies
            .iter()
            .map(|b| b.set.strain_energy(&nodes.positions[b.nodes.clone()]))
            .sum()
    }
}
