//! The force-contribution and constraint interfaces, and the elastic forces of the
//! particles.
//!
//! Every physical effect that puts force on nodes (element elasticity, contact, a
//! membrane, external loads) is a [`ForceContribution`]. The engine zeroes the force
//! array, adds the elastic forces, the contact forces and every further contribution for
//! the current positions and velocities, then runs the [`Constraint`]s as a pass of their
//! own. The stable step combines the elastic and contact bounds (they act on the same
//! nodes, [`StepBound::combined`]) and takes the smallest of that and the other
//! contributions' bounds. The elastic bound is each body's assembled bound, estimated
//! once by power iteration.

use crate::SolverError;
use fdem_core::number::Number;
use fdem_elastic::{AssembledStep, ElementSet};
use rayon::prelude::*;
use std::any::Any;
use std::ops::Range;

/// Read-only view of the node state that contributions evaluate forces from.
#[derive(Clone, Copy, Debug)]
pub struct NodeView<'a> {
    /// Current positions (m).
    pub positions: &'a [[f64; 3]],
    /// Velocities at the evaluation instant (m/s): the half-step velocities of the
    /// velocity-Verlet update. A rigid body's nodes hold theirs only when a contribution
    /// or constraint may read them ([`ForceContribution::node_range`]); the contact model
    /// takes them from the bodies' motions.
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
    /// The smallest of the given bounds (contributions without one give `None`): for
    /// contributions that act on different nodes.
    pub fn smallest(bounds: impl IntoIterator<Item = Option<StepBound>>) -> Option<StepBound> {
        bounds
            .into_iter()
            .flatten()
            .min_by(|a, b| a.dt.total_cmp(&b.dt))
    }

    /// The bound of two stiffnesses acting on the same nodes (the elastic elements and the
    /// contact springs of the surface nodes): `1/dt^2 = 1/dt_a^2 + 1/dt_b^2`, because the
    /// largest eigenvalue of a sum of positive semi-definite matrices is at most the sum of
    /// their largest eigenvalues (Weyl's inequality; `omega^2 = 4 / dt^2`). Where the
    /// contact springs are soft next to the elements, as in the paper's specimens, it is
    /// barely below the elastic bound (docs/TRIAXIAL.md, "Time step", has the E4s bounds);
    /// where they are as stiff (soft grains, a stiff penalty) the smallest of the two would
    /// overestimate the stable step by up to `sqrt(2)`.
    pub fn combined(a: Option<StepBound>, b: Option<StepBound>) -> Option<StepBound> {
        match (a, b) {
            (Some(a), Some(b)) => Some(StepBound {
                dt: 1.0 / (a.dt.powi(-2) + b.dt.powi(-2)).sqrt(),
                source: format!(
                    "{} ({:.4e} s) combined with {} ({:.4e} s)",
                    a.source, a.dt, b.source, b.dt
                ),
            }),
            (a, b) => a.or(b),
        }
    }

    /// The bound of a model: the elastic bound combined with the contact springs' (both
    /// act on the particles' nodes), and each of `others` (the contributions' bounds, such
    /// as a membrane's elements) combined with the smaller of the contact springs' and the
    /// sheet nodes' two-sided bound (`sheet_contact`, [`fdem_contact::ContactModel::sheet_stable_time_step`]),
    /// then the smallest of these. A contribution's nodes may be contact surface nodes (a
    /// membrane is a sheet, contacted by the particles it wraps), and the contact bound is
    /// the smallest over all surface nodes, so combining is safe for every contribution;
    /// for one whose nodes carry no contact it is pessimistic. The sheet's two-sided bound
    /// counts on its own too (a sheet without a contribution of its own). What
    /// [`crate::ModelBuilder::build`] uses.
    pub fn of_model(
        elastic: Option<StepBound>,
        contact: Option<StepBound>,
        sheet_contact: Option<StepBound>,
        others: impl IntoIterator<Item = Option<StepBound>>,
    ) -> Option<StepBound> {
        let on_others = Self::smallest([contact.clone(), sheet_contact.clone()]);
        let with_contact = |b: Option<StepBound>| match b {
            Some(b) => Self::combined(Some(b), on_others.clone()),
            None => None,
        };
        Self::smallest(
            [Self::combined(elastic, contact), sheet_contact]
                .into_iter()
                .chain(others.into_iter().map(with_contact)),
        )
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

impl Powers {
    /// Adds `other` term by term.
    pub fn add(&mut self, other: Powers) {
        self.external += other.external;
        self.damping += other.damping;
        self.friction_energy += other.friction_energy;
    }
}

/// Something that adds forces to nodes.
///
/// A contribution is owned by the [`crate::Simulation`]; the driver reaches it between
/// steps through the typed [`crate::Handle`] that [`crate::ModelBuilder::add_contribution`]
/// returned (`sim.get_mut(handle)`), so that it can change a load, a pressure or a
/// coefficient without any side channel.
pub trait ForceContribution: Any + Send {
    /// Short name used in reports (`membrane`, `membrane damping`, ...).
    fn name(&self) -> &str;
    /// The stable-step bound this contribution imposes, if any, given the lumped masses
    /// of all nodes (kg).
    fn stable_time_step(&self, masses: &[f64]) -> Option<StepBound>;
    /// Work that reads the state and writes no force, such as per-element forces into the
    /// contribution's own scratch: the engine runs it in parallel with the elements' forces
    /// and the contact detection, then calls [`ForceContribution::add_forces`] at the same
    /// state, in the order the contributions were added. A contribution that prepares must
    /// give the same forces at a state whether or not `prepare` came first at that state,
    /// and must not use a preparation for any other state. Nothing by default.
    ///
    /// # Errors
    /// As [`ForceContribution::add_forces`].
    fn prepare(&mut self, nodes: NodeView<'_>) -> Result<(), SolverError> {
        let _ = nodes;
        Ok(())
    }
    /// Adds this contribution's forces to `forces` (N) and returns the powers it exchanges.
    fn add_forces(
        &mut self,
        nodes: NodeView<'_>,
        forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError>;
    /// Energy stored by this contribution (strain energy, springs) in J.
    fn potential_energy(&self, nodes: NodeView<'_>) -> f64;
    /// The node ids this contribution reads the state of or adds forces to, when they
    /// lie in one range ([`node_span`] of a list); `None`, the default, when it may touch
    /// any node. The engine leaves out work no one needs by it: the half-step velocities
    /// of rigid bodies' nodes are placed only when a contribution or constraint may read
    /// them.
    fn node_range(&self) -> Option<Range<usize>> {
        None
    }
    /// What this contribution carries from one evaluation to the next (beyond what the
    /// driver sets between steps), as numbers, for a checkpoint
    /// ([`crate::Simulation::checkpoint`]); none by default.
    fn checkpoint(&self) -> Vec<f64> {
        Vec::new()
    }
    /// Restores [`ForceContribution::checkpoint`].
    ///
    /// # Errors
    /// Numbers this contribution did not write (by default: any).
    fn restore_checkpoint(&mut self, values: &[f64]) -> Result<(), SolverError> {
        if values.is_empty() {
            Ok(())
        } else {
            Err(SolverError::InvalidScene(format!(
                "{} keeps no state, but the checkpoint holds {} numbers for it",
                self.name(),
                values.len()
            )))
        }
    }
}

/// A condition on nodes enforced after every force has been added: a node held on a
/// moving platen, a prescribed motion.
///
/// Constraints run as a pass of their own, in the order they were added, after the
/// elastic, contact and contributed forces and gravity: a constraint sees the whole force
/// on its nodes, not a partial sum that depends on where it stands in a list. The reaction
/// it applies is an external force; its power is booked as external work.
pub trait Constraint: Any + Send {
    /// Short name used in reports.
    fn name(&self) -> &str;
    /// Changes `forces` on the constrained nodes and returns the powers of the reactions
    /// (`external`: the reaction's power on the nodes at the evaluation velocities).
    fn apply(
        &mut self,
        nodes: NodeView<'_>,
        forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError>;
    /// As [`ForceContribution::node_range`]: the node ids this constraint reads the state
    /// of or changes the forces of, when they lie in one range; `None`, the default, when
    /// it may touch any node.
    fn node_range(&self) -> Option<Range<usize>> {
        None
    }
}

/// The smallest range of node ids that holds every id of `nodes` (empty for none): what a
/// contribution or constraint on a list of nodes gives as
/// [`ForceContribution::node_range`].
pub fn node_span(nodes: &[usize]) -> Range<usize> {
    match (nodes.iter().min(), nodes.iter().max()) {
        (Some(&lo), Some(&hi)) => lo..hi + 1,
        _ => 0..0,
    }
}

/// The work of forces that are not the gradient of a stored energy (a follower pressure,
/// viscous damping), booked over a velocity-Verlet step.
///
/// The engine books `P dt` with the power `P = F(n+1) . v(n+1/2)` evaluated at the
/// half-step velocity. Velocity Verlet applies the force `F(n+1)` over the half kicks from
/// `v(n+1/2)` to `v(n+3/2)`, so its true work is `F(n+1) . (v(n+1/2) + v(n+3/2)) / 2 dt`.
/// On light nodes under a stiff force the difference accumulates to a visible share of the
/// work. [`VerletWork::correction`] returns the missing share of the previous force as a
/// power, `F(n) . (v(n+3/2) - v(n+1/2)) / 2`, once `v(n+3/2)` is known (the engine
/// multiplies it by `dt` like every other power), and remembers the new force and
/// velocity for the next step.
///
/// A contribution that computes its forces in [`ForceContribution::prepare`] books them
/// there too, with [`VerletWork::hold`] and [`VerletWork::held_correction`]: the new pairs
/// are held, not remembered, until [`VerletWork::commit`] in `add_forces` at the same
/// time, so a preparation that no `add_forces` uses changes nothing.
#[derive(Clone, Debug, Default)]
pub struct VerletWork {
    previous: Vec<ForceAndVelocity>,
    /// The pairs of a held booking and its time ([`VerletWork::hold`]).
    held: (Vec<ForceAndVelocity>, Option<f64>),
}

/// A node's force (N) and velocity (m/s) of one evaluation.
type ForceAndVelocity = ([f64; 3], [f64; 3]);

impl VerletWork {
    /// Prepares for `n` nodes; the first step after a change of `n` books no correction.
    pub fn ensure(&mut self, n: usize) {
        if self.previous.len() != n {
            self.previous = vec![([0.0; 3], [0.0; 3]); n];
        }
    }

    /// The remembered forces and velocities, six numbers per node, for a checkpoint.
    pub fn to_numbers(&self) -> Vec<f64> {
        self.previous
            .iter()
            .flat_map(|(f, v)| f.iter().chain(v).copied().collect::<Vec<_>>())
            .collect()
    }

    /// Restores [`VerletWork::to_numbers`].
    ///
    /// # Errors
    /// A count that is not a multiple of six.
    pub fn restore_numbers(&mut self, values: &[f64]) -> Result<(), SolverError> {
        if !values.len().is_multiple_of(6) {
            return Err(SolverError::InvalidScene(format!(
                "{} numbers cannot be a Verlet work record (six per node)",
                values.len()
            )));
        }
        self.held.1 = None;
        self.previous = values
            .chunks_exact(6)
            .map(|c| ([c[0], c[1], c[2]], [c[3], c[4], c[5]]))
            .collect();
        Ok(())
    }

    /// For node `k` (of the `n` given to [`VerletWork::ensure`]) with force `force` now and
    /// velocity `velocity` at this evaluation: `F_old . (v - v_old) / 2` (a power, W, in the
    /// engine's `P dt` booking: the force of the previous evaluation times the velocity
    /// change since, halved), and remembers `(force, velocity)`.
    pub fn correction(&mut self, k: usize, force: [f64; 3], velocity: [f64; 3]) -> f64 {
        let before = self.previous[k];
        self.previous[k] = (force, velocity);
        verlet_correction(before, velocity)
    }

    /// Starts a held booking for the evaluation at `time` (after [`VerletWork::ensure`]):
    /// each node then gets one [`VerletWork::held_correction`], and
    /// [`VerletWork::commit`] at `time` makes their pairs the remembered ones.
    pub fn hold(&mut self, time: f64) {
        self.held
            .0
            .resize(self.previous.len(), ([0.0; 3], [0.0; 3]));
        self.held.1 = Some(time);
    }

    /// [`VerletWork::correction`] in a held booking: the same value, the pair held for
    /// [`VerletWork::commit`] instead of remembered now.
    pub fn held_correction(&mut self, k: usize, force: [f64; 3], velocity: [f64; 3]) -> f64 {
        self.held.0[k] = (force, velocity);
        verlet_correction(self.previous[k], velocity)
    }

    /// Remembers the pairs of the booking held at `time`, if there is one; a booking of
    /// another time is dropped.
    pub fn commit(&mut self, time: f64) {
        if self.held.1.take() == Some(time) {
            std::mem::swap(&mut self.previous, &mut self.held.0);
        }
    }
}

/// `F_old . (v - v_old) / 2` for the remembered pair `(F_old, v_old)` and the velocity `v`
/// of this evaluation ([`VerletWork`]).
fn verlet_correction((f, v): ForceAndVelocity, velocity: [f64; 3]) -> f64 {
    0.5 * (f[0] * (velocity[0] - v[0]) + f[1] * (velocity[1] - v[1]) + f[2] * (velocity[2] - v[2]))
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
    /// The body's stable step as an assembled system (power iteration about its rest
    /// configuration, [`ElementSet::assembled_time_step`]), with its element bound.
    pub step: AssembledStep,
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

/// What [`ElasticForces::new`] needs of one deformable body: its id, node range, material
/// and body-local connectivity (`nodes_per_element` ids per element, indices into the
/// body's reference positions).
#[derive(Clone, Debug)]
pub struct ElementInput {
    /// Body id.
    pub body: usize,
    /// Global node ids of the body.
    pub nodes: Range<usize>,
    /// The body's material.
    pub material: fdem_elastic::Material,
    /// 4 or 10.
    pub nodes_per_element: usize,
    /// Body-local connectivity.
    pub connectivity: Vec<usize>,
}

impl ElasticForces {
    /// Builds the element sets of `bodies` (in increasing node order) from the reference
    /// positions and estimates each body's assembled stable step (in parallel over
    /// bodies; a few hundred force evaluations per body).
    pub fn new(bodies: &[ElementInput], reference: &[[f64; 3]]) -> Result<Self, SolverError> {
        let out = bodies
            .par_iter()
            .map(|input| {
                let rest = &reference[input.nodes.clone()];
                let error = |source| SolverError::Elastic {
                    body: input.body,
                    source,
                };
                let set = ElementSet::new(
                    &input.material,
                    input.nodes_per_element,
                    rest,
                    &input.connectivity,
                )
                .map_err(error)?;
                let step = set.assembled_time_step();
                // Elements always have a finite stable step: an infinite or zero one is the
                // arithmetic's (the element frequencies over- or underflow for a material
                // of extreme stiffness or density), which would leave the step to the
                // contact springs alone or to nothing.
                if set.n_elements() > 0 && !(step.time_step.is_finite() && step.time_step > 0.0) {
                    let m = &input.material;
                    return Err(SolverError::InvalidScene(format!(
                        "body {}: its elements have no finite stable time step: youngs_modulus \
                         {} Pa over density {} kg/m^3 is beyond the range of the arithmetic at \
                         this size; use values of realistic magnitudes",
                        input.body,
                        Number(m.youngs_modulus),
                        Number(m.density)
                    )));
                }
                Ok(BodyElements {
                    body: input.body,
                    nodes: input.nodes.clone(),
                    set,
                    step,
                })
            })
            .collect::<Result<Vec<_>, SolverError>>()?;
        Ok(ElasticForces { bodies: out })
    }

    /// The smallest element bound over all bodies (rigorous, conservative), s; `+inf`
    /// without elements. The simulation uses the assembled bound
    /// ([`ForceContribution::stable_time_step`]).
    pub fn element_time_step(&self) -> f64 {
        self.bodies
            .iter()
            .map(|b| b.step.element_time_step)
            .fold(f64::INFINITY, f64::min)
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

impl ElasticForces {
    /// The smallest assembled bound over the bodies (bodies are coupled only through
    /// contact, whose springs bound the step separately).
    pub fn stable_time_step(&self) -> Option<StepBound> {
        self.bodies
            .iter()
            .filter(|b| b.step.time_step.is_finite())
            .min_by(|a, b| a.step.time_step.total_cmp(&b.step.time_step))
            .map(|b| StepBound {
                dt: b.step.time_step,
                source: format!(
                    "elastic: body {} as assembled (power iteration; its element bound {:.4e} s)",
                    b.body, b.step.element_time_step
                ),
            })
    }

    /// Adds the elastic forces of every body at `nodes.positions` to `forces` (N).
    pub fn add_forces(
        &mut self,
        nodes: NodeView<'_>,
        forces: &mut [[f64; 3]],
    ) -> Result<(), SolverError> {
        let start = self.bodies.first().map_or(0, |b| b.nodes.start);
        let end = self.bodies.last().map_or(0, |b| b.nodes.end);
        add_elastic(
            &mut self.bodies,
            nodes.positions,
            &mut forces[start..end],
            start,
        )
    }

    /// Strain energy of every body at `nodes.positions` (J).
    pub fn potential_energy(&self, nodes: NodeView<'_>) -> f64 {
        self.bodies
            .iter()
            .map(|b| b.set.strain_energy(&nodes.positions[b.nodes.clone()]))
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::{StepBound, VerletWork, node_span};

    /// A held booking gives the corrections of the direct one and, once committed, the
    /// same remembered pairs, bit for bit; a booking that is not committed at its time
    /// changes nothing.
    #[test]
    fn a_held_booking_books_as_the_direct_one() {
        let pair = |step: usize, k: usize| {
            let a = |j: usize| ((7 * step + 3 * k + j) as f64 * 0.61).sin();
            ([a(0), a(1), a(2)], [a(3), a(4), a(5)])
        };
        let (mut direct, mut held) = (VerletWork::default(), VerletWork::default());
        for step in 0..4 {
            direct.ensure(5);
            held.ensure(5);
            let time = step as f64;
            // A booking for another time, never committed at it: dropped.
            held.hold(time + 0.5);
            for k in 0..5 {
                held.held_correction(k, [1e3; 3], [1e3; 3]);
            }
            held.commit(time + 0.25);
            held.hold(time);
            for k in 0..5 {
                let (f, v) = pair(step, k);
                let a = direct.correction(k, f, v);
                let b = held.held_correction(k, f, v);
                assert_eq!(a.to_bits(), b.to_bits(), "step {step}, node {k}");
            }
            held.commit(time);
            let bits = |w: &VerletWork| -> Vec<u64> {
                w.to_numbers().iter().map(|x| x.to_bits()).collect()
            };
            assert_eq!(bits(&direct), bits(&held), "step {step}");
        }
    }

    #[test]
    fn a_node_span_holds_every_id_of_its_list() {
        assert_eq!(node_span(&[7, 3, 9, 4]), 3..10);
        assert_eq!(node_span(&[5]), 5..6);
        assert_eq!(node_span(&[]), 0..0);
    }

    fn bound(dt: f64, source: &str) -> Option<StepBound> {
        Some(StepBound {
            dt,
            source: source.into(),
        })
    }

    /// Two springs k1, k2 on one mass m: omega^2 = (k1 + k2) / m, so
    /// 1/dt^2 = 1/dt_1^2 + 1/dt_2^2 exactly (dt = 2 / omega); 3 and 4 give 12/5.
    #[test]
    fn combined_bounds_add_their_squared_frequencies() {
        let c = StepBound::combined(bound(3.0, "a"), bound(4.0, "b")).unwrap();
        assert!((c.dt - 2.4).abs() < 1e-15, "{}", c.dt);
        assert!(c.source.contains('a') && c.source.contains('b'));
        let (m, k1, k2) = (2.0_f64, 5.0_f64, 7.0_f64);
        let dt = |k: f64| 2.0 / (k / m).sqrt();
        let c = StepBound::combined(bound(dt(k1), "1"), bound(dt(k2), "2")).unwrap();
        assert!((c.dt / dt(k1 + k2) - 1.0).abs() < 1e-14);
        assert_eq!(StepBound::combined(bound(3.0, "a"), None), bound(3.0, "a"));
        assert_eq!(StepBound::combined(None, None), None);
    }

    #[test]
    fn a_model_bound_is_the_smallest_of_the_bounds_each_combined_with_contact() {
        // Elastic 3 with contact 4 gives 2.4; a contribution's 6 with contact 4 gives
        // 24 / sqrt(52) = 3.33: the elastic one sets the bound.
        let m = StepBound::of_model(bound(3.0, "e"), bound(4.0, "c"), None, [bound(6.0, "m")]);
        assert_eq!(m.unwrap().dt, 2.4);
        // A contribution's 3 with contact 4 is 2.4 too, its 2 with contact 4 is
        // 4 / sqrt(5): below the elastic one.
        let m = StepBound::of_model(
            bound(3.0, "e"),
            bound(4.0, "c"),
            None,
            [bound(2.0, "m"), None],
        );
        let m = m.unwrap();
        assert!((m.dt - 4.0 / 5f64.sqrt()).abs() < 1e-15, "{}", m.dt);
        assert!(m.source.starts_with('m') && m.source.contains('c'));
        // Without contact the contributions' bounds stand alone.
        let m = StepBound::of_model(bound(3.0, "e"), None, None, [bound(2.0, "m")]);
        assert_eq!(m, bound(2.0, "m"));
        // The sheet's two-sided 3 is combined with the contribution (6 with 3 gives
        // 6 / sqrt(5) = 2.68, below the contact's 3.33), not with the elastic bound (which
        // stays 2.4 and is smaller still).
        let m = StepBound::of_model(
            bound(3.0, "e"),
            bound(4.0, "c"),
            bound(3.0, "s"),
            [bound(6.0, "m")],
        );
        assert_eq!(m.unwrap().dt, 2.4);
        let m = StepBound::of_model(
            bound(30.0, "e"),
            bound(4.0, "c"),
            bound(3.0, "s"),
            [bound(6.0, "m")],
        );
        let m = m.unwrap();
        assert!((m.dt - 6.0 / 5f64.sqrt()).abs() < 1e-15, "{}", m.dt);
        assert!(m.source.starts_with('m') && m.source.contains('s'));
        // Alone, the sheet's bound counts as it is.
        let m = StepBound::of_model(None, None, bound(3.0, "s"), [None]);
        assert_eq!(m, bound(3.0, "s"));
    }
}
