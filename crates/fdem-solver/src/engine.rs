//! The explicit central-difference (velocity-Verlet) engine with energy bookkeeping and
//! a stability guard.

use crate::checkpoint::SimulationCheckpoint;
use crate::forces::{Constraint, ElasticForces, ForceContribution, NodeView, Powers, StepBound};
use crate::model::{ConstraintHandle, Handle};
use crate::rigid::{HalfStepVelocities, RigidBodies, RigidState, Spring};
use crate::team::Team;
use crate::{Body, BodyKind, BodyMotion, Connectivity, ContactForces, NodeState, SolverError};
use fdem_contact::Counterpart;
use rayon::prelude::*;
use std::any::Any;
use std::ops::Range;

const FOREIGN_HANDLE: &str = "a handle of another model was used with this simulation";

/// Nodes per chunk of the node-update loops. Small enough that the loops' halves (rayon
/// splits a range in halves, the calling thread keeping the first) fall near the
/// elements' halves, so that each thread mostly updates the nodes whose forces it has just
/// computed, in its own cache, instead of pulling the other core's lines
/// (docs/PERFORMANCE.md, "Node chunks that follow the elements' halves").
const NODE_CHUNK: usize = 512;

/// The nodes the step's per-node passes (kick, drift, force reset, gravity) update, by
/// chunk of [`NODE_CHUNK`]: every node but the rigid bodies', whose poses place them and
/// whose forces their own pass resets. The passes keep the chunks of the whole node array
/// (one parallel region each, the same tasks for every scene) and skip what a chunk holds
/// of rigid bodies: in a rigid scene those are nearly all the nodes, and the passes would
/// compute values the placement overwrites.
#[derive(Clone, Debug, Default)]
struct NodeChunks {
    /// Chunk `c`'s spans are `spans[starts[c]..starts[c + 1]]`.
    starts: Vec<usize>,
    /// Node ranges local to their chunk.
    spans: Vec<Range<usize>>,
}

impl NodeChunks {
    /// The chunks of `n` nodes less the disjoint, increasing ranges `rigid`.
    fn new(n: usize, rigid: impl IntoIterator<Item = Range<usize>>) -> NodeChunks {
        // The free ranges: the complement of the rigid ones.
        let mut free = Vec::new();
        let mut next = 0;
        for r in rigid {
            if r.start > next {
                free.push(next..r.start);
            }
            next = next.max(r.end);
        }
        if next < n {
            free.push(next..n);
        }
        let mut chunks = NodeChunks {
            starts: vec![0],
            spans: Vec::new(),
        };
        let mut k = 0;
        for c in 0..n.div_ceil(NODE_CHUNK) {
            let (lo, hi) = (c * NODE_CHUNK, ((c + 1) * NODE_CHUNK).min(n));
            while k < free.len() && free[k].end <= lo {
                k += 1;
            }
            for r in free[k..].iter().take_while(|r| r.start < hi) {
                chunks.spans.push(r.start.max(lo) - lo..r.end.min(hi) - lo);
            }
            chunks.starts.push(chunks.spans.len());
        }
        chunks
    }

    /// The local node ranges of chunk `c` the passes update.
    fn of(&self, c: usize) -> &[Range<usize>] {
        &self.spans[self.starts[c]..self.starts[c + 1]]
    }
}

/// Steps between estimates of the rigid bodies' contact network's step
/// ([`Simulation::rigid_network_step`]).
pub const NETWORK_INTERVAL: u64 = 100;

/// Lanczos steps of an estimate of the network's largest frequency: on E1's network the
/// extreme Ritz value of 40 steps agrees with that of 400 to about 1e-5 (docs/MODEL.md
/// section 12).
pub const NETWORK_LANCZOS_STEPS: usize = 40;

/// How the time step is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TimeStep {
    /// A fixed step (s), used as given even above the stable bound (the guard watches).
    Fixed(f64),
    /// `safety x` the stable bound ([`Simulation::bound`]).
    Automatic {
        /// Fraction of the bound, in (0, 1].
        safety: f64,
    },
}

/// Settings of the stability guard.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Guard {
    /// The run stops when the energy balance error exceeds this fraction of the energy
    /// scale (the larger of the initial energy and the external work so far).
    pub energy_tolerance: f64,
    /// Steps between energy checks (non-finite values are checked every step).
    pub check_interval: u64,
    /// Absolute floor of the energy scale, as a fraction of `M c_p^2` (total mass times
    /// the squared p-wave speed): the kinetic energy of the system moving at
    /// `sqrt(2 x 1e-12) c_p`, about 6 mm/s for rock. Below it the balance error is
    /// round-off of a system at rest, not instability; an instability grows exponentially
    /// and passes the floor a few dozen steps after it starts.
    pub energy_floor: f64,
}

impl Default for Guard {
    fn default() -> Self {
        Guard {
            energy_tolerance: 0.05,
            check_interval: 256,
            energy_floor: 1e-12,
        }
    }
}

/// Energies at one instant (J), the columns of `energy.csv`.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EnergyReport {
    /// Simulated time (s).
    pub time: f64,
    /// Kinetic energy `sum 1/2 m v^2`.
    pub kinetic: f64,
    /// Elastic strain energy of the particles.
    pub strain: f64,
    /// Energy stored by other contributions (contact springs, ...).
    pub other_potential: f64,
    /// Energy dissipated by viscous damping since the start.
    pub damping_dissipated: f64,
    /// Energy dissipated by friction sliding since the start.
    pub friction_dissipated: f64,
    /// Work done on the system by external forces (gravity, loads) since the start.
    pub external_work: f64,
    /// Energy dissipated since the start (damping + friction).
    pub dissipated: f64,
    /// `kinetic + strain + other_potential + dissipated - external_work - initial total`:
    /// zero for exact energy conservation.
    pub balance_error: f64,
}

/// The contributions and constraints of a model, stored behind typed handles.
pub(crate) struct Parts {
    pub(crate) contributions: Vec<Box<dyn ForceContribution>>,
    pub(crate) constraints: Vec<Box<dyn Constraint>>,
}

/// Everything [`crate::ModelBuilder::build`] hands to the engine.
pub(crate) struct Assembled {
    pub(crate) state: NodeState,
    pub(crate) bodies: Vec<Body>,
    pub(crate) connectivity: Connectivity,
    pub(crate) elastic: ElasticForces,
    pub(crate) contact: Option<ContactForces>,
    pub(crate) rigid: RigidBodies,
    pub(crate) parts: Parts,
    pub(crate) gravity: [f64; 3],
    pub(crate) bound: StepBound,
    pub(crate) dt: f64,
    /// The safety factor of an automatic step, which the rigid bodies' contact network
    /// may lower ([`Simulation::network_bound`]); `None` for a fixed step.
    pub(crate) safety: Option<f64>,
    pub(crate) guard: Guard,
}

/// An FDEM model advanced by explicit central differences (velocity Verlet).
///
/// Built by [`crate::ModelBuilder`]. Between steps a driver reads everything through
/// accessors, reaches its own contributions and constraints through their handles
/// ([`Simulation::get_mut`], [`Simulation::constraint_mut`]), moves walls and restores
/// history through [`Simulation::contact_mut`], and edits node positions and velocities
/// through [`Simulation::nodes_mut`]; the engine's own bookkeeping (clock, energy
/// balance, bound) changes only through its methods.
pub struct Simulation {
    state: NodeState,
    /// The nodes the per-node passes update.
    chunks: NodeChunks,
    bodies: Vec<Body>,
    connectivity: Connectivity,
    elastic: ElasticForces,
    contact: Option<ContactForces>,
    rigid: RigidBodies,
    parts: Parts,
    gravity: [f64; 3],
    time: f64,
    step: u64,
    dt: f64,
    bound: StepBound,
    safety: Option<f64>,
    /// The contact network's step where it sets the step now.
    network: Option<StepBound>,
    guard: Guard,
    initial_energy: f64,
    /// `M c_p^2` of the system (J), the unit of [`Guard::energy_floor`].
    wave_energy: f64,
    contribution_work: f64,
    /// Gravity's work `sum m g . (x - x_ref)` at the last energy reference (J): the balance
    /// counts gravity's work from there.
    gravity_work_origin: f64,
    damping_dissipated: f64,
    friction_dissipated: f64,
    last_powers: Powers,
    /// The rigid bodies' poses handed to the contact's frames (scratch).
    pose_scratch: Vec<fdem_contact::RigidPose>,
    /// The rigid bodies' motions handed to the contact's scan (scratch).
    motion_scratch: Vec<fdem_contact::RigidMotion>,
    /// Whether the nodes were open for editing since the last force evaluation
    /// ([`Simulation::nodes_mut`]).
    rigid_nodes_edited: bool,
    /// The pool's other workers, kept awake between the steps' parallel regions.
    team: Team,
}

/// Mutable access to the node positions and velocities between steps
/// ([`Simulation::nodes_mut`]). Masses, reference positions and forces stay the engine's.
pub struct NodesMut<'a> {
    /// Current positions (m).
    pub positions: &'a mut [[f64; 3]],
    /// Current velocities (m/s).
    pub velocities: &'a mut [[f64; 3]],
}

impl Simulation {
    /// Chooses the step, evaluates the initial forces and takes the initial energy.
    pub(crate) fn new(parts: Assembled) -> Result<Self, SolverError> {
        let total_mass: f64 = parts.state.masses.iter().sum();
        let wave_speed = parts
            .elastic
            .bodies
            .iter()
            .map(|b| b.set.material().p_wave_speed())
            .fold(0.0, f64::max);
        let mut sim = Simulation {
            wave_energy: total_mass * wave_speed * wave_speed,
            chunks: NodeChunks::new(parts.state.len(), parts.rigid.iter().map(|p| p.nodes())),
            state: parts.state,
            bodies: parts.bodies,
            connectivity: parts.connectivity,
            elastic: parts.elastic,
            contact: parts.contact,
            rigid: parts.rigid,
            parts: parts.parts,
            gravity: parts.gravity,
            time: 0.0,
            step: 0,
            dt: parts.dt,
            bound: parts.bound,
            safety: parts.safety,
            network: None,
            guard: parts.guard,
            initial_energy: 0.0,
            contribution_work: 0.0,
            gravity_work_origin: 0.0,
            damping_dissipated: 0.0,
            friction_dissipated: 0.0,
            last_powers: Powers::default(),
            pose_scratch: Vec::new(),
            motion_scratch: Vec::new(),
            rigid_nodes_edited: false,
            team: Team::default(),
        };
        // Finite inputs can still give a state that is not (a rigid body's spin turned
        // into node velocities overflows), and the first output is written from the
        // initial state and forces before any step checks them.
        let s = &sim.state;
        let mut moving = s.positions.iter().zip(&s.velocities);
        if let Some(node) = moving.position(|(x, v)| !x.iter().chain(v).all(|c| c.is_finite())) {
            return Err(SolverError::InvalidScene(format!(
                "the position or velocity of {} in the initial state is not finite: a centre, \
                 velocity or angular velocity overflows; use values of realistic magnitudes",
                sim.node_name(node)
            )));
        }
        sim.compute_forces()?;
        sim.follow_network();
        let e = sim.energy();
        sim.initial_energy = e.kinetic + e.strain + e.other_potential;
        let forces = &sim.state.forces;
        if let Some(node) = forces.iter().position(|f| !f.iter().all(|x| x.is_finite())) {
            return Err(SolverError::InvalidScene(format!(
                "the force on {} in the initial state is not finite: a stiffness, damping or \
                 load overflows; use values of realistic magnitudes",
                sim.node_name(node)
            )));
        }
        if !sim.initial_energy.is_finite() {
            return Err(SolverError::InvalidScene(format!(
                "the energy of the initial state is not finite ({}): the velocities, masses or \
                 stiffnesses overflow; use values of realistic magnitudes",
                not_finite(&e)
            )));
        }
        Ok(sim)
    }

    /// `node N of body B` (or `node N` for a node of no body), for messages.
    fn node_name(&self, node: usize) -> String {
        match self.bodies.iter().position(|b| b.nodes.contains(&node)) {
            Some(b) => format!("node {node} of body {b}"),
            None => format!("node {node}"),
        }
    }

    /// Node state (positions, reference, velocities, forces, masses).
    pub fn state(&self) -> &NodeState {
        &self.state
    }

    /// Positions and velocities for editing between steps (restoring a saved state,
    /// seating nodes on a platen). The forces are re-evaluated at the next step; call
    /// [`Simulation::rebase_energy`] to re-evaluate them now and measure the energy
    /// balance from the edited state. Nodes of rigid bodies follow their body's pose: an
    /// edit of them is overwritten at the next step or force evaluation.
    pub fn nodes_mut(&mut self) -> NodesMut<'_> {
        self.rigid_nodes_edited = !self.rigid.is_empty();
        NodesMut {
            positions: &mut self.state.positions,
            velocities: &mut self.state.velocities,
        }
    }

    /// The state of every rigid body (pose and momenta), in body order: with
    /// [`Simulation::set_rigid_states`], what a saved state needs beyond the nodes.
    pub fn rigid_states(&self) -> Vec<RigidState> {
        self.rigid.iter().map(|p| p.state).collect()
    }

    /// Sets the state of every rigid body (one per rigid body, in body order, as
    /// [`Simulation::rigid_states`] returns them) and places their nodes from it. Like
    /// [`Simulation::nodes_mut`], the forces are re-evaluated at the next step or by
    /// [`Simulation::rebase_energy`].
    ///
    /// # Errors
    /// A count other than the number of rigid bodies, or a state that is not finite or
    /// whose orientation is not a unit quaternion.
    pub fn set_rigid_states(&mut self, states: &[RigidState]) -> Result<(), SolverError> {
        self.rigid.set_states(
            states,
            &mut self.state.positions,
            &mut self.state.velocities,
        )
    }

    /// The state this simulation carries to its next step ([`SimulationCheckpoint`]):
    /// take it between steps, restore it with [`Simulation::restore_checkpoint`] into a
    /// simulation built from the same model, and the run continues bit for bit.
    pub fn checkpoint(&self) -> SimulationCheckpoint {
        SimulationCheckpoint {
            time: self.time,
            step: self.step,
            dt: self.dt,
            positions: self.state.positions.clone(),
            velocities: self.state.velocities.clone(),
            forces: self.state.forces.clone(),
            rigid: self.rigid.checkpoint(),
            energy: [
                self.initial_energy,
                self.contribution_work,
                self.gravity_work_origin,
                self.damping_dissipated,
                self.friction_dissipated,
            ],
            contact: self.contact.as_ref().map(|c| c.model().checkpoint()),
            contributions: self
                .parts
                .contributions
                .iter()
                .map(|c| c.checkpoint())
                .collect(),
        }
    }

    /// Restores a [`Simulation::checkpoint`] of a simulation built from the same model.
    /// What the driver sets between steps (a pressure, a wall's velocity) is the
    /// driver's to restore.
    ///
    /// # Errors
    /// A checkpoint of another model (node, rigid body, wall or contribution counts, or
    /// another step) or one holding a value that is not finite; the simulation may then
    /// be partly restored and is to be dropped.
    pub fn restore_checkpoint(&mut self, c: &SimulationCheckpoint) -> Result<(), SolverError> {
        use crate::checkpoint::mismatch;
        let n = self.state.len();
        if [c.positions.len(), c.velocities.len(), c.forces.len()] != [n; 3] {
            return Err(mismatch(format!(
                "{} nodes saved, {n} in the model",
                c.positions.len()
            )));
        }
        // A step the contact network set is at most the model's bound times the safety
        // factor (the model knows only the contacts it was built with); any other step must
        // be the model's.
        let largest = self.safety.map_or(0.0, |safety| safety * self.bound.dt);
        let adapts = self.safety.is_some() && !self.rigid.is_empty();
        let lowered = adapts && c.dt.is_finite() && c.dt > 0.0 && c.dt <= largest;
        if !lowered && c.dt.to_bits() != self.dt.to_bits() {
            return Err(mismatch(format!(
                "step {:e} s saved, {:e} s in the model",
                c.dt, self.dt
            )));
        }
        if c.contributions.len() != self.parts.contributions.len() {
            return Err(mismatch(format!(
                "{} contributions saved, {} in the model",
                c.contributions.len(),
                self.parts.contributions.len()
            )));
        }
        let finite = [&c.positions, &c.velocities, &c.forces]
            .into_iter()
            .flatten()
            .flatten()
            .chain(&c.energy)
            .chain([&c.time])
            .all(|v| v.is_finite());
        if !finite {
            return Err(mismatch(
                "a saved node state, time or energy is not finite".into(),
            ));
        }
        self.state.positions.clone_from(&c.positions);
        self.state.velocities.clone_from(&c.velocities);
        self.state.forces.clone_from(&c.forces);
        let s = &mut self.state;
        self.rigid
            .restore(&c.rigid, &mut s.positions, &mut s.velocities)?;
        match (self.contact.as_mut(), &c.contact) {
            (Some(contact), Some(saved)) => contact.model_mut().restore_checkpoint(saved)?,
            (None, None) => {}
            _ => {
                return Err(mismatch(
                    "contact in only one of model and checkpoint".into(),
                ));
            }
        }
        for (part, saved) in self.parts.contributions.iter_mut().zip(&c.contributions) {
            part.restore_checkpoint(saved)?;
        }
        [
            self.initial_energy,
            self.contribution_work,
            self.gravity_work_origin,
            self.damping_dissipated,
            self.friction_dissipated,
        ] = c.energy;
        self.time = c.time;
        self.step = c.step;
        if lowered {
            self.dt = c.dt;
            let safety = self.safety.unwrap_or(1.0);
            self.network = Some(StepBound {
                dt: c.dt / safety,
                source: "contact network of the rigid bodies (the restored run's step)".into(),
            });
        }
        Ok(())
    }

    /// Sets the clock (simulated time and step count), e.g. when a saved state is
    /// restored.
    pub fn set_clock(&mut self, time: f64, step: u64) {
        self.time = time;
        self.step = step;
    }

    /// Bodies in node order.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// The bodies that are grains ([`Body::is_particle`]), with their body ids.
    pub fn particles(&self) -> impl Iterator<Item = (usize, &Body)> {
        self.bodies
            .iter()
            .enumerate()
            .filter(|(_, b)| b.is_particle())
    }

    /// The elements' global node ids, in body order (4 or 10 per element).
    pub fn connectivity(&self) -> &Connectivity {
        &self.connectivity
    }

    /// Number of elements.
    pub fn n_elements(&self) -> usize {
        self.bodies.iter().map(|b| b.elements.len()).sum()
    }

    /// The elastic forces of the deformable particles.
    pub fn elastic(&self) -> &ElasticForces {
        &self.elastic
    }

    /// Gravitational acceleration (m/s^2).
    pub fn gravity(&self) -> [f64; 3] {
        self.gravity
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps taken.
    pub fn step(&self) -> u64 {
        self.step
    }

    /// The step size in use (s).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Sets the time step (s) and keeps it: unlike [`Simulation::set_dt`], the rigid
    /// bodies' contact network no longer sets it (a probe of the step's stability wants
    /// the step it asked for).
    ///
    /// # Errors
    /// [`SolverError::InvalidScene`] for a step that is not finite and > 0.
    pub fn fix_dt(&mut self, dt: f64) -> Result<(), SolverError> {
        self.set_dt(dt)?;
        self.safety = None;
        Ok(())
    }

    /// Changes the step from the next step on, even above the stable bound (the guard
    /// watches): velocity Verlet holds velocities at whole steps, so a new step needs no
    /// restart. With an automatic step and rigid bodies, the contact network's next
    /// estimate sets it again ([`Simulation::fix_dt`] keeps it).
    ///
    /// # Errors
    /// [`SolverError::InvalidScene`] for a step that is not finite and > 0.
    pub fn set_dt(&mut self, dt: f64) -> Result<(), SolverError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(SolverError::InvalidScene(format!(
                "time step {dt:e} s is not a positive finite number"
            )));
        }
        self.dt = dt;
        Ok(())
    }

    /// The stable bound and what sets it: the elastic bound (each body's assembled bound)
    /// combined with the contact springs' ([`StepBound::combined`]), or any other
    /// contribution's bound if smaller.
    pub fn bound(&self) -> &StepBound {
        &self.bound
    }

    /// The contact network's step where it sets the automatic step
    /// ([`Simulation::rigid_network_step`]), if it does now.
    pub fn network_bound(&self) -> Option<&StepBound> {
        self.network.as_ref()
    }

    /// With an automatic step and rigid bodies, sets the step to the safety factor times the
    /// smaller of the model's bound and the contact network's step: springs that act
    /// together on one rigid body make it stiffer than the bound known before the contacts
    /// formed, and the network stiffens and softens as contacts come and go. The network's
    /// step ([`Simulation::rigid_network_step`]) is estimated every [`NETWORK_INTERVAL`]
    /// steps (and when the model is built); the step follows from the state and the step
    /// count, so a resumed run takes the same steps.
    fn follow_network(&mut self) {
        let Some(safety) = self.safety else {
            return;
        };
        if self.rigid.is_empty() || !self.step.is_multiple_of(NETWORK_INTERVAL) {
            return;
        }
        match self.rigid_network_step() {
            Some(b) if b.dt < self.bound.dt => {
                self.dt = safety * b.dt;
                self.network = Some(b);
            }
            _ => {
                self.dt = safety * self.bound.dt;
                self.network = None;
            }
        }
    }

    /// The rigid bodies' stable step under the contact springs of the last evaluation
    /// (`None` without rigid contacts): `2 / (sqrt(omega^2 + gamma^2 / 4) + gamma / 2)` with
    /// `omega^2` and `gamma` the largest eigenvalues of the network's mass-weighted
    /// stiffness and damping, each from [`NETWORK_LANCZOS_STEPS`] Lanczos steps (docs/MODEL.md
    /// section 12). An estimate, as the particles' elastic bound is (a power iteration):
    /// the safety factor covers it.
    pub fn rigid_network_step(&self) -> Option<StepBound> {
        let springs: Vec<Spring> = self.springs()?.collect();
        let (omega2, gamma) = self
            .rigid
            .network_frequency_and_damping(&springs, NETWORK_LANCZOS_STEPS)?;
        let half_gamma = 0.5 * gamma;
        Some(StepBound {
            dt: 2.0 / ((omega2 + half_gamma * half_gamma).sqrt() + half_gamma),
            source: format!(
                "contact network of the rigid bodies: largest frequency {:.4e} rad/s, damping \
                 {gamma:.4e} 1/s (Lanczos)",
                omega2.sqrt()
            ),
        })
    }

    /// The rigid bodies' stable step under the contact springs of the last evaluation,
    /// each body counting every spring that acts on it (`None` without rigid contacts):
    /// the bound [`Simulation::bound`] cannot know before the contacts form
    /// (docs/MODEL.md section 12).
    pub fn rigid_network_bound(&self) -> Option<StepBound> {
        let b = self.rigid.network_bound(self.springs()?)?;
        Some(StepBound {
            dt: b.dt,
            source: format!(
                "contact network: rigid body {}, {} springs",
                b.body, b.springs
            ),
        })
    }

    /// An estimate of the rigid bodies' largest frequency (rad/s) under the contact springs
    /// of the last evaluation, undamped, from `iterations` Lanczos steps: it approaches the
    /// true value from below where [`Simulation::rigid_network_bound`] bounds it from above
    /// (a diagnostic of the bound's margin; `None` without rigid contacts).
    pub fn rigid_network_frequency(&self, iterations: usize) -> Option<f64> {
        let springs: Vec<Spring> = self.springs()?.collect();
        let omega2 = self.rigid.network_frequency(&springs, iterations)?;
        Some(omega2.sqrt())
    }

    /// The contacts of the last evaluation as springs between bodies.
    fn springs(&self) -> Option<impl Iterator<Item = Spring> + '_> {
        let contact = self.contact.as_ref()?;
        Some(
            contact
                .model()
                .contact_springs()
                .map(|(c, k, dashpot)| Spring {
                    body: c.body as usize,
                    point: c.position,
                    other: match c.counterpart {
                        Counterpart::Body(b) => Some((b as usize, c.contact_point)),
                        Counterpart::Wall(_) => None,
                    },
                    stiffness: k,
                    dashpot,
                }),
        )
    }

    /// Stability guard settings.
    pub fn guard(&self) -> &Guard {
        &self.guard
    }

    /// Changes the stability guard's settings from the next check on.
    pub fn set_guard(&mut self, guard: Guard) {
        self.guard = guard;
    }

    /// The contact stage, if the model has contact.
    pub fn contact(&self) -> Option<&ContactForces> {
        self.contact.as_ref()
    }

    /// The contact stage, mutable (move a wall, restore friction history).
    pub fn contact_mut(&mut self) -> Option<&mut ContactForces> {
        self.contact.as_mut()
    }

    /// The contribution behind `handle`.
    ///
    /// # Panics
    /// If `handle` was issued by the builder of another model (a programming error, like
    /// an index out of bounds).
    pub fn get<T: ForceContribution>(&self, handle: Handle<T>) -> &T {
        let part: &dyn Any = self.parts.contributions[handle.index()].as_ref();
        part.downcast_ref().expect(FOREIGN_HANDLE)
    }

    /// The contribution behind `handle`, mutable: change its parameters between steps.
    ///
    /// # Panics
    /// As [`Simulation::get`].
    pub fn get_mut<T: ForceContribution>(&mut self, handle: Handle<T>) -> &mut T {
        let part: &mut dyn Any = self.parts.contributions[handle.index()].as_mut();
        part.downcast_mut().expect(FOREIGN_HANDLE)
    }

    /// The constraint behind `handle`.
    ///
    /// # Panics
    /// As [`Simulation::get`].
    pub fn constraint<T: Constraint>(&self, handle: ConstraintHandle<T>) -> &T {
        let part: &dyn Any = self.parts.constraints[handle.index()].as_ref();
        part.downcast_ref().expect(FOREIGN_HANDLE)
    }

    /// The constraint behind `handle`, mutable.
    ///
    /// # Panics
    /// As [`Simulation::get`].
    pub fn constraint_mut<T: Constraint>(&mut self, handle: ConstraintHandle<T>) -> &mut T {
        let part: &mut dyn Any = self.parts.constraints[handle.index()].as_mut();
        part.downcast_mut().expect(FOREIGN_HANDLE)
    }

    /// Makes the current state the reference of the energy balance (initial energy, zero
    /// work and dissipation) and re-evaluates the forces. Call it after editing positions
    /// or velocities by hand, so that the stability guard measures from the new state.
    pub fn rebase_energy(&mut self) -> Result<(), SolverError> {
        self.compute_forces()?;
        self.reset_energy_reference();
        Ok(())
    }

    /// Makes the current state the reference of the energy balance without re-evaluating
    /// the forces (they belong to the current state after [`Simulation::advance`]): the
    /// stability guard then measures from here. A driver that checks the balance over
    /// windows (the triaxial test) calls it at the end of each window.
    pub fn reset_energy_reference(&mut self) {
        self.contribution_work = 0.0;
        self.gravity_work_origin = 0.0;
        self.gravity_work_origin = self.gravity_work();
        self.damping_dissipated = 0.0;
        self.friction_dissipated = 0.0;
        let e = self.energy();
        self.initial_energy = e.kinetic + e.strain + e.other_potential;
    }

    /// Estimates the assembled system's stable step `2 / omega_max` by power iteration on
    /// `M^-1/2 K M^-1/2`, with `K v` from the elastic forces at a tiny displacement of the
    /// reference configuration (co-rotational forces are linear to first order there).
    ///
    /// The Rayleigh quotient approaches `omega_max^2` from below, so the estimate is at or
    /// above the true bound. [`Simulation::bound`] uses each body's assembled estimate
    /// (rest stiffness, Rayleigh quotient plus residual); this whole-system check of it
    /// works from the force evaluation instead. Costs `iterations` elastic force
    /// evaluations; intended for diagnostics and tests.
    pub fn estimate_system_time_step(&mut self, iterations: usize) -> Result<f64, SolverError> {
        let n = self.state.len();
        let x0 = self.state.reference.clone();
        let size = x0
            .iter()
            .flatten()
            .fold(0.0f64, |a, &b| a.max(b.abs()))
            .max(f64::MIN_POSITIVE);
        let sqrt_inv_m: Vec<f64> = self.state.inverse_masses.iter().map(|w| w.sqrt()).collect();
        // Deterministic, non-special start vector.
        let mut y: Vec<[f64; 3]> = (0..n)
            .map(|i| [0, 1, 2].map(|k| ((i * 3 + k) as f64 * 0.618_033_988_75).fract() - 0.5))
            .collect();
        // Displacements are scaled so that the largest is 1e-7 of the model size.
        let max_sqrt_inv = sqrt_inv_m.iter().copied().fold(0.0, f64::max);
        let vscale = 1e-7 * size / max_sqrt_inv;
        let mut lambda = 0.0;
        let mut x = x0.clone();
        let mut f = vec![[0.0; 3]; n];
        for _ in 0..iterations {
            let norm = y.iter().flatten().map(|v| v * v).sum::<f64>().sqrt();
            if norm == 0.0 || !norm.is_finite() {
                break;
            }
            y.iter_mut().flatten().for_each(|v| *v /= norm);
            for i in 0..n {
                for k in 0..3 {
                    x[i][k] = x0[i][k] + vscale * sqrt_inv_m[i] * y[i][k];
                }
            }
            f.fill([0.0; 3]);
            let view = NodeView {
                positions: &x,
                velocities: &self.state.velocities,
                masses: &self.state.masses,
                time: self.time,
                dt: self.dt,
            };
            self.elastic.add_forces(view, &mut f)?;
            // A y = M^-1/2 K M^-1/2 y = -M^-1/2 f / vscale; lambda = y . A y.
            let mut dot = 0.0;
            for i in 0..n {
                for k in 0..3 {
                    let ay = -sqrt_inv_m[i] * f[i][k] / vscale;
                    dot += ay * y[i][k];
                    y[i][k] = ay;
                }
            }
            lambda = dot;
        }
        Ok(if lambda > 0.0 {
            2.0 / lambda.sqrt()
        } else {
            f64::INFINITY
        })
    }

    /// The forces at the current state: zero them, then [`Simulation::add_forces`], then
    /// each rigid body's force and torque from its nodes' (a step gathers them with its
    /// last kick instead).
    fn compute_forces(&mut self) -> Result<(), SolverError> {
        if std::mem::take(&mut self.rigid_nodes_edited) {
            // The nodes were open for editing: rigid bodies' nodes follow their poses (a
            // step's kick and drift places them anyway).
            let s = &mut self.state;
            self.rigid.place_all(&mut s.positions, &mut s.velocities);
        }
        self.state
            .forces
            .par_chunks_mut(NODE_CHUNK)
            .for_each(|chunk| chunk.fill([0.0; 3]));
        self.add_forces()?;
        let s = &mut self.state;
        let nodes = [
            &mut s.positions[..],
            &mut s.velocities[..],
            &mut s.forces[..],
        ];
        self.rigid.gather(self.gravity, nodes);
        Ok(())
    }

    /// Adds the forces at the current state to the node forces, which must be zero: the
    /// elastic forces with the contact detection and the contributions' preparations
    /// beside them (these read the state and write no force), then the contact forces,
    /// every contribution in the order added, gravity, and the constraints as a pass of
    /// their own. The order of the additions into each node's force is fixed, so the sum
    /// does not depend on the threads.
    fn add_forces(&mut self) -> Result<(), SolverError> {
        if let Some(contact) = self.contact.as_mut()
            && !self.rigid.is_empty()
        {
            // The rigid bodies' poses of this time, for the contact's frames (which the
            // rigid nodes reproduce).
            self.rigid.poses(&mut self.pose_scratch);
            contact
                .model_mut()
                .exchange_rigid_poses(self.time, &mut self.pose_scratch)?;
            // Their motions of this time, so the contact's scan need not read their nodes.
            self.rigid.motions(&mut self.motion_scratch);
            contact
                .model_mut()
                .exchange_rigid_motions(self.time, &mut self.motion_scratch)?;
        }
        let state = &mut self.state;
        let view = NodeView {
            positions: &state.positions,
            velocities: &state.velocities,
            masses: &state.masses,
            time: self.time,
            dt: self.dt,
        };
        let forces = &mut state.forces;
        let elastic = &mut self.elastic;
        let contributions = &mut self.parts.contributions;
        let (elastic, (detected, prepared)) = rayon::join(
            || elastic.add_forces(view, forces),
            || {
                rayon::join(
                    || self.contact.as_mut().map(|c| c.evaluate(view)),
                    || contributions.iter_mut().try_for_each(|c| c.prepare(view)),
                )
            },
        );
        // The errors in the order the parts add their forces.
        elastic?;
        detected.transpose()?;
        prepared?;
        let mut powers = Powers::default();
        if let Some(contact) = self.contact.as_mut() {
            powers.add(contact.add_evaluated_forces(forces)?);
        }
        for c in &mut self.parts.contributions {
            powers.add(c.add_forces(view, forces)?);
        }
        add_gravity(
            self.gravity,
            (&state.masses, &state.inverse_masses),
            forces,
            &self.chunks,
        );
        for c in &mut self.parts.constraints {
            powers.add(c.apply(view, forces)?);
        }
        self.last_powers = powers;
        Ok(())
    }

    /// Advances one step of velocity Verlet:
    /// `v(n+1/2) = v(n) + dt/2 a(n)`, `x(n+1) = x(n) + dt v(n+1/2)`,
    /// `a(n+1) = f(x(n+1), v(n+1/2)) / m`, `v(n+1) = v(n+1/2) + dt/2 a(n+1)`:
    /// kick and drift, forces (with the constraints' pass), booking of work and
    /// dissipation, kick, guard.
    ///
    /// A step opens three parallel regions of the rayon pool with deformable bodies
    /// alone (kick, drift and the forces' reset; elements beside the contact detection;
    /// kick), four more with rigid bodies (kick, drift and node placement; poses; motions;
    /// forces gathered, kick and node velocities) and one for gravity. The simulation's
    /// team (`team.rs`) keeps the pool's other workers awake between them. Call it from a
    /// worker of the pool (inside `ThreadPool::install` or `rayon::scope`), as the command
    /// line does: from any other thread every region is a hand-over to the pool and a
    /// wake-up, and there is no team.
    pub fn advance(&mut self) -> Result<(), SolverError> {
        let (dt, half) = (self.dt, 0.5 * self.dt);
        self.team.keep();
        let _stepping = Team::stepping();
        kick_drift_and_reset(&mut self.state, half, dt, &self.chunks);
        let velocities = self.half_step_velocities();
        let s = &mut self.state;
        self.rigid.kick_drift(
            half,
            dt,
            [&mut s.positions, &mut s.velocities, &mut s.forces],
            velocities,
        );
        self.rigid_nodes_edited = false;
        let (step, time) = (self.step + 1, self.time + dt);
        self.time = time;
        if let Err(e) = self.add_forces() {
            if velocities != HalfStepVelocities::All {
                // The state the error leaves is whole: every node's velocity of its time.
                let s = &mut self.state;
                self.rigid.place_velocities(&s.positions, &mut s.velocities);
            }
            // An inverted element or a refused contact step during the time loop is a
            // step-size problem: report it with the step, time, dt and bound.
            return Err(match e {
                SolverError::Elastic { .. } | SolverError::Contact(_) => {
                    self.unstable(step, time, e.to_string())
                }
                other => other,
            });
        }
        // Work and dissipation over the step, from powers at the half-step velocities.
        self.contribution_work += dt * self.last_powers.external;
        self.damping_dissipated += dt * self.last_powers.damping;
        self.friction_dissipated += self.last_powers.friction_energy;
        let s = &mut self.state;
        let nodes = [
            &mut s.positions[..],
            &mut s.velocities[..],
            &mut s.forces[..],
        ];
        let rigid_finite = self.rigid.gather_and_kick(half, self.gravity, nodes);
        let finite = kick(&mut self.state, half, &self.chunks) && rigid_finite;
        self.step = step;
        self.time = time;
        if !finite {
            return Err(self.unstable(step, time, "a velocity became non-finite".into()));
        }
        self.follow_network();
        if self.guard.check_interval > 0 && step % self.guard.check_interval == 0 {
            self.check_energy()?;
        }
        Ok(())
    }

    /// Which rigid bodies' nodes a step gives their half-step velocities: every body's
    /// when a contribution or constraint may read one of their nodes
    /// ([`ForceContribution::node_range`]), else those the contact model does not take
    /// from the bodies' motions.
    fn half_step_velocities(&self) -> HalfStepVelocities {
        let contributions = self.parts.contributions.iter().map(|c| c.node_range());
        let constraints = self.parts.constraints.iter().map(|c| c.node_range());
        let read = contributions
            .chain(constraints)
            .any(|nodes| nodes.is_none_or(|r| self.rigid.holds_any(&r)));
        if read {
            HalfStepVelocities::All
        } else {
            HalfStepVelocities::Unframed
        }
    }

    /// The energy scale the balance error is measured against: the largest of the initial
    /// energy, the external work, the dissipated energy and the guard's absolute floor.
    pub fn energy_scale(&self, e: &EnergyReport) -> f64 {
        self.initial_energy
            .abs()
            .max(e.external_work.abs())
            .max(e.dissipated.abs())
            .max(self.guard.energy_floor * self.wave_energy)
            .max(f64::MIN_POSITIVE)
    }

    /// `|balance error| / energy scale`.
    pub fn relative_balance_error(&self, e: &EnergyReport) -> f64 {
        e.balance_error.abs() / self.energy_scale(e)
    }

    /// Stops the run if the energy balance error has grown past the guard's tolerance.
    pub fn check_energy(&self) -> Result<EnergyReport, SolverError> {
        let e = self.energy();
        let scale = self.energy_scale(&e);
        let relative = self.relative_balance_error(&e);
        if !relative.is_finite() {
            // Its numbers would be NaN: say which energy overflowed instead.
            return Err(self.unstable(
                self.step,
                self.time,
                format!("the energy balance is not finite ({})", not_finite(&e)),
            ));
        }
        if relative > self.guard.energy_tolerance {
            return Err(self.unstable(
                self.step,
                self.time,
                format!(
                    "energy balance error {:.3e} J is {:.3e} of the energy scale {:.3e} J (tolerance {})",
                    e.balance_error,
                    relative,
                    scale,
                    fdem_core::number::Number(self.guard.energy_tolerance)
                ),
            ));
        }
        Ok(e)
    }

    fn unstable(&self, step: u64, time: f64, reason: String) -> SolverError {
        // The bound that set the step: the contact network's where it lowered it.
        let bound = self.network.as_ref().unwrap_or(&self.bound);
        SolverError::Unstable {
            step,
            time,
            dt: self.dt,
            bound: bound.dt,
            bound_source: bound.source.clone(),
            reason,
        }
    }

    fn view(&self) -> NodeView<'_> {
        NodeView {
            positions: &self.state.positions,
            velocities: &self.state.velocities,
            masses: &self.state.masses,
            time: self.time,
            dt: self.dt,
        }
    }

    /// Gravity's work since the reference configuration, `sum m g . (x - x_ref)` (J):
    /// exact, gravity being uniform and constant.
    fn gravity_work(&self) -> f64 {
        let (g, s) = (self.gravity, &self.state);
        if g == [0.0; 3] {
            return 0.0;
        }
        let nodes: f64 = s
            .positions
            .iter()
            .zip(&s.reference)
            .zip(&s.masses)
            .zip(&s.inverse_masses)
            .filter(|(_, w)| **w > 0.0)
            .map(|(((x, x0), &m), _)| {
                m * (g[0] * (x[0] - x0[0]) + g[1] * (x[1] - x0[1]) + g[2] * (x[2] - x0[2]))
            })
            .sum();
        if self.rigid.is_empty() {
            return nodes;
        }
        nodes + self.rigid.iter().map(|p| p.gravity_work(g)).sum::<f64>()
    }

    /// Kinetic energy (J): `m v^2 / 2` of the nodes the node update moves, plus every
    /// rigid body's translational and rotational energy.
    pub fn kinetic_energy(&self) -> f64 {
        let s = &self.state;
        if self.rigid.is_empty() {
            return s.kinetic_energy(0..s.len());
        }
        let nodes: f64 = s
            .velocities
            .iter()
            .zip(&s.masses)
            .zip(&s.inverse_masses)
            .filter(|(_, w)| **w > 0.0)
            .map(|((v, &m), _)| 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
            .sum();
        nodes
            + self
                .rigid
                .iter()
                .map(|p| p.state.kinetic_energy(&p.inertia))
                .sum::<f64>()
    }

    /// Rigid-body summary of body `id` (`bodies.csv`): a rigid body's from its own state,
    /// any other's from its nodes ([`Body::motion`]).
    ///
    /// # Panics
    /// If `id` is not a body of this simulation.
    pub fn body_motion(&self, id: usize) -> BodyMotion {
        let body = &self.bodies[id];
        if body.kind == BodyKind::Rigid
            && let Some(p) = self.rigid.get(id)
        {
            return BodyMotion {
                mass: p.inertia.mass,
                centroid: p.state.position,
                velocity: p.state.velocity,
                angular_velocity: p.state.angular_velocity(&p.inertia),
                angular_momentum: p.state.angular_momentum(),
            };
        }
        body.motion(&self.state)
    }

    /// The energies now.
    pub fn energy(&self) -> EnergyReport {
        let kinetic = self.kinetic_energy();
        let strain = self.elastic.potential_energy(self.view());
        let contact = self.contact.as_ref().map_or(0.0, |c| c.potential_energy());
        let other_potential: f64 = contact
            + self
                .parts
                .contributions
                .iter()
                .map(|c| c.potential_energy(self.view()))
                .sum::<f64>();
        let gravity_work = self.gravity_work() - self.gravity_work_origin;
        let external_work = gravity_work + self.contribution_work;
        let dissipated = self.damping_dissipated + self.friction_dissipated;
        EnergyReport {
            time: self.time,
            kinetic,
            strain,
            other_potential,
            damping_dissipated: self.damping_dissipated,
            friction_dissipated: self.friction_dissipated,
            external_work,
            dissipated,
            balance_error: kinetic + strain + other_potential + dissipated
                - external_work
                - self.initial_energy,
        }
    }
}

/// The terms of `e` that are not finite, named (`kinetic energy, contact energy not
/// finite`), or `their sum overflows` when each is finite: the words a message prints
/// instead of the NaN the balance would show.
fn not_finite(e: &EnergyReport) -> String {
    let terms = [
        ("kinetic energy", e.kinetic),
        ("strain energy", e.strain),
        ("contact energy", e.other_potential),
        ("external work", e.external_work),
        ("dissipated energy", e.dissipated),
    ];
    let names: Vec<&str> = terms
        .iter()
        .filter(|(_, v)| !v.is_finite())
        .map(|(name, _)| *name)
        .collect();
    if names.is_empty() {
        "their sum overflows".into()
    } else {
        format!("{} not finite", names.join(", "))
    }
}

/// Adds `m g` to the force of every node the node update moves (rigid bodies take their
/// weight as a whole).
fn add_gravity(g: [f64; 3], s: (&[f64], &[f64]), forces: &mut [[f64; 3]], chunks: &NodeChunks) {
    if g == [0.0; 3] {
        return;
    }
    let (masses, inverse_masses) = s;
    forces
        .par_chunks_mut(NODE_CHUNK)
        .zip(masses.par_chunks(NODE_CHUNK))
        .zip(inverse_masses.par_chunks(NODE_CHUNK))
        .enumerate()
        .for_each(|(c, ((f, m), im))| {
            for r in chunks.of(c) {
                for (f, (&m, &im)) in f[r.clone()]
                    .iter_mut()
                    .zip(m[r.clone()].iter().zip(&im[r.clone()]))
                {
                    if im > 0.0 {
                        for k in 0..3 {
                            f[k] += m * g[k];
                        }
                    }
                }
            }
        });
}

/// The first half kick and the drift, `v += dt/2 f/m`, `x += dt v`; then the forces, used
/// up, are reset to zero for the step's new ones (one pass over the nodes instead of two).
fn kick_drift_and_reset(s: &mut NodeState, half: f64, dt: f64, chunks: &NodeChunks) {
    s.positions
        .par_chunks_mut(NODE_CHUNK)
        .zip(s.velocities.par_chunks_mut(NODE_CHUNK))
        .zip(s.forces.par_chunks_mut(NODE_CHUNK))
        .zip(s.inverse_masses.par_chunks(NODE_CHUNK))
        .enumerate()
        .for_each(|(c, (((x, v), f), im))| {
            // Span by span over zipped slices, so that the loop needs no bounds checks.
            for r in chunks.of(c) {
                let nodes = x[r.clone()].iter_mut().zip(&mut v[r.clone()]);
                for ((x, v), (f, &im)) in nodes.zip(f[r.clone()].iter_mut().zip(&im[r.clone()])) {
                    for k in 0..3 {
                        v[k] += half * f[k] * im;
                        x[k] += dt * v[k];
                    }
                    *f = [0.0; 3];
                }
            }
        });
}

/// The second half kick, `v += dt/2 f/m`; false if a velocity became non-finite.
fn kick(s: &mut NodeState, half: f64, chunks: &NodeChunks) -> bool {
    s.velocities
        .par_chunks_mut(NODE_CHUNK)
        .zip(s.forces.par_chunks(NODE_CHUNK))
        .zip(s.inverse_masses.par_chunks(NODE_CHUNK))
        .enumerate()
        .map(|(c, ((v, f), im))| {
            let mut ok = true;
            for r in chunks.of(c) {
                for (v, (f, &im)) in v[r.clone()]
                    .iter_mut()
                    .zip(f[r.clone()].iter().zip(&im[r.clone()]))
                {
                    for k in 0..3 {
                        v[k] += half * f[k] * im;
                        ok &= v[k].is_finite();
                    }
                }
            }
            ok
        })
        // `reduce` (not `all`) so that every chunk is updated; `&&` is order-independent,
        // so the result does not depend on scheduling.
        .reduce(|| true, |a, b| a && b)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The guard names the energies that are not finite instead of printing the NaN their
    /// balance would be.
    #[test]
    fn energies_that_are_not_finite_are_named() {
        let e = EnergyReport {
            kinetic: f64::INFINITY,
            other_potential: f64::NAN,
            ..EnergyReport::default()
        };
        assert_eq!(not_finite(&e), "kinetic energy, contact energy not finite");
        let sum = EnergyReport {
            kinetic: f64::MAX,
            strain: f64::MAX,
            ..EnergyReport::default()
        };
        assert_eq!(not_finite(&sum), "their sum overflows");
    }

    /// The per-node passes visit every node but the rigid bodies', each once, in its own
    /// chunk: rigid ranges across chunk boundaries, at either end and back to back.
    #[test]
    fn node_chunks_cover_exactly_the_nodes_of_no_rigid_body() {
        let n = 3 * NODE_CHUNK + 17;
        let rigid = [
            0..5,
            5..9,
            NODE_CHUNK - 3..NODE_CHUNK + 40,
            2 * NODE_CHUNK..n - 1,
        ];
        let chunks = NodeChunks::new(n, rigid.iter().cloned());
        let mut visited = vec![0u32; n];
        for c in 0..n.div_ceil(NODE_CHUNK) {
            for r in chunks.of(c) {
                assert!(r.end <= NODE_CHUNK && r.start < r.end, "chunk {c}: {r:?}");
                for i in r.clone() {
                    visited[c * NODE_CHUNK + i] += 1;
                }
            }
        }
        for (i, &count) in visited.iter().enumerate() {
            let in_rigid = rigid.iter().any(|r| r.contains(&i));
            assert_eq!(count, u32::from(!in_rigid), "node {i}");
        }
        // Without rigid bodies every chunk is one whole span.
        let all = NodeChunks::new(n, []);
        assert_eq!(all.of(0).to_vec(), vec![0..NODE_CHUNK]);
        assert_eq!(all.of(3).to_vec(), vec![0..17]);
    }
}
