//! Preparation by the dynamic method: random loose placement in a tall rigid cylinder,
//! compaction by two rigid platens to the target height, settling with the platens
//! fixed, and the checks of the result.
//!
//! Walls are rigid and move at a constant velocity fixed when a simulation is built, so a
//! change of platen motion is a rebuild: a new [`Simulation`] from the same particle
//! placements (hence the same reference meshes, masses and stable step) with the new
//! walls, into which the node state and the friction history are restored (a
//! [`Snapshot`]). The same restore reloads a saved specimen.

use crate::counts::sphere_volume;
use crate::placement::{Column, PlacedParticle, place_spheres};
use crate::{SpecimenSpec, TriaxialError};
use fdem_contact::Counterpart;
use fdem_solver::{
    ContactSection, MeshSection, ParticleModel, ParticleSection, RigidState, Scene, Simulation,
    SimulationSection, WallSection, WallType,
};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Index of the cylinder in the walls of every preparation scene.
pub const WALL_CYLINDER: usize = 0;
/// Index of the bottom platen (a plane with normal +z).
pub const WALL_BOTTOM: usize = 1;
/// Index of the top platen (a plane with normal -z).
pub const WALL_TOP: usize = 2;
/// Most nodes a preparation accepts (about 200 GB of node state and contact data).
pub const MAX_NODES: u64 = 1_000_000_000;
/// Energy-balance tolerance of the preparation's stability guard (the solver's default is
/// 0.05). Settling quenches the assembly (every velocity set to zero) whenever the kinetic
/// energy peaks, and each quench restarts the balance from the stored energy of a nearly
/// static packing, so the energy scale is tiny and the balance carries the
/// central-difference error of the energy of the fastest modes (order (omega dt)^2 / 4 of
/// their energy, 0.25 at half the stable step): a sizeable share of the scale with nothing
/// unstable (docs/SPECIMENS.md, "Energy guard during preparation", has the measurement).
/// An instability grows by orders of magnitude; 0.5 is the triaxial test's tolerance too.
pub const PREPARATION_ENERGY_TOLERANCE: f64 = 0.5;
/// Growth of the loose column when random placement finds no room.
pub const COLUMN_GROWTH: f64 = 1.15;
/// Column heights tried before placement gives up.
pub const COLUMN_TRIES: usize = 8;

/// A phase of the preparation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// Random placement in the loose column.
    Place,
    /// Platens close at constant speed to the target height.
    Compact,
    /// Platens fixed at the target height until the unbalanced force is small.
    Settle,
}

impl Phase {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Place => "place",
            Phase::Compact => "compact",
            Phase::Settle => "settle",
        }
    }
}

/// What an observer sees during a phase.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Status {
    /// Steps taken in this phase.
    pub step: u64,
    /// Simulated time since the start of the preparation (s).
    pub time: f64,
    /// Distance between the platens (m).
    pub platen_gap: f64,
    /// Active node contacts.
    pub contacts: usize,
    /// Unbalanced-force ratio at the last check (settling only).
    pub unbalanced_force: Option<f64>,
}

/// Receives the progress of a preparation (for a progress bar); every method has a
/// do-nothing default.
pub trait Observer {
    /// A phase starts; `planned_steps` is its step count (the most it may take when it can
    /// end early; 0 for placement).
    fn phase(&mut self, _phase: Phase, _planned_steps: u64) {}
    /// Progress within a phase, a few hundred times per phase. Returning `false` stops the
    /// preparation with [`TriaxialError::Interrupted`].
    fn progress(&mut self, _phase: Phase, _status: &Status) -> bool {
        true
    }
}

/// An observer that ignores everything.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Observer for Silent {}

/// The state a simulation is restored from: node positions and velocities at step `step`,
/// and the tangential history that the force evaluation at that state consumes (the
/// history exported just before the step that reached it). Restoring re-evaluates the
/// forces at this state, which reproduces the history the original run had after its
/// evaluation.
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    /// Node positions (m).
    pub positions: Vec<[f64; 3]>,
    /// Node velocities (m/s).
    pub velocities: Vec<[f64; 3]>,
    /// Tangential history `(global node, counterpart, d_s in m)`.
    pub history: Vec<(usize, Counterpart, [f64; 3])>,
    /// Pose and momenta of every rigid particle, in body order (their nodes follow them).
    pub rigid: Vec<RigidState>,
    /// Simulated time (s).
    pub time: f64,
    /// Steps taken.
    pub step: u64,
}

/// Results of the end-of-preparation checks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Checks {
    /// Particles whose centroid lies outside the cylinder or the platens.
    pub particles_outside: u64,
    /// Deepest penetration of a node into a wall (m), 0 when none.
    pub max_wall_penetration: f64,
    /// Deepest penetration of a node into another particle (m), 0 when none.
    pub max_overlap: f64,
    /// Limit for both penetrations: `preparation.max_overlap` times the smallest diameter (m).
    pub overlap_limit: f64,
    /// Unbalanced-force ratio: the sum over particles of the magnitude of their net force,
    /// over the sum over particles of the magnitudes of the contact forces on them.
    pub unbalanced_force: f64,
    /// Its limit, `preparation.unbalanced_force`.
    pub unbalanced_force_limit: f64,
    /// Which checks failed (empty when all passed).
    pub failures: Vec<String>,
}

impl Checks {
    /// Whether every check passed.
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }
}

/// What a preparation produced and what it cost.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PreparationReport {
    /// Particles.
    pub particles: u64,
    /// Nodes.
    pub nodes: u64,
    /// Tetrahedra.
    pub elements: u64,
    /// Inner radius of the cylinder (m).
    pub inner_radius: f64,
    /// Height of the loose column the platens started from (m).
    pub loose_height: f64,
    /// Target height (m): the platens end at z = 0 and z = this.
    pub target_height: f64,
    /// Time step (s).
    pub dt: f64,
    /// The stable bound it is a fraction of (s).
    pub dt_bound: f64,
    /// What sets the bound.
    pub dt_bound_source: String,
    /// Closing speed of the platens (m/s); the loose column's height is rounded up so that
    /// a whole number of steps at this speed reaches the target height exactly.
    pub platen_speed: f64,
    /// Steps of the compaction phase.
    pub compact_steps: u64,
    /// Steps of the settling phase.
    pub settle_steps: u64,
    /// Whether settling ended on the unbalanced-force criterion (not the time limit).
    pub settled: bool,
    /// Simulated time of the whole preparation (s).
    pub simulated_time: f64,
    /// Wall-clock seconds of the whole preparation (placement, builds, steps, checks).
    pub wall_seconds: f64,
    /// CPU seconds of the process over the preparation (all threads), when measurable.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cpu_seconds: Option<f64>,
    /// Worker threads.
    pub threads: u64,
    /// Nominal solid fraction: nominal sphere volumes over the inner volume at the target
    /// height.
    pub solid_fraction_nominal: f64,
    /// Real solid fraction: the deformed tetrahedra's volume over the inner volume.
    pub solid_fraction_real: f64,
    /// Mean axial stress on the platens at the end (Pa): the mean of the two platens'
    /// axial forces over the inner cross-section. Compare with the confining pressure: a
    /// specimen that jammed before the target height ends over-compressed.
    pub platen_stress: f64,
    /// Mean radial stress on the cylinder at the end (Pa): the radial normal forces of its
    /// node contacts over the inner lateral area.
    pub cylinder_stress: f64,
    /// Active node contacts at the end.
    pub node_contacts: u64,
    /// Particle pairs in contact at the end.
    pub particle_contacts: u64,
    /// Coordination number: twice the particle contacts over the particles.
    pub coordination_number: f64,
    /// Kinetic energy removed by the final stop (J): what was left when settling ended.
    pub residual_kinetic_energy: f64,
    /// Times the kinetic damping stopped every node while settling.
    pub quenches: u64,
    /// The checks of the result.
    pub checks: Checks,
}

/// A prepared specimen: its definition, the reference placement of every particle, the
/// node state and friction history at the end of preparation, and the report.
///
/// [`PreparedSpecimen::simulation`] rebuilds the prepared configuration (platens fixed at
/// z = 0 and z = height, the cylinder, the preparation's contact law) and restores the
/// state; [`PreparedSpecimen::restore_into`] restores it into a simulation built by the
/// caller from [`PreparedSpecimen::particle_sections`] with other walls (the test).
#[derive(Clone, Debug, PartialEq)]
pub struct PreparedSpecimen {
    /// The definition it was prepared from (with any overrides applied).
    pub spec: SpecimenSpec,
    /// Reference placement of every particle, in body order (largest first).
    pub particles: Vec<PlacedParticle>,
    /// Time step used (s); simulations rebuilt from the specimen use it as a fixed step.
    pub dt: f64,
    /// The state at the end of preparation.
    pub state: Snapshot,
    /// What the preparation produced and cost.
    pub report: PreparationReport,
}

pub(crate) fn solver(phase: &'static str) -> impl Fn(fdem_solver::SolverError) -> TriaxialError {
    move |cause| TriaxialError::Solver { phase, cause }
}

/// The `[[particle]]` tables of a placement with the specimen's mesh and each size
/// class's model (`auto` resolved, [`crate::Counts`]).
pub fn particle_sections(
    spec: &SpecimenSpec,
    particles: &[PlacedParticle],
) -> Result<Vec<ParticleSection>, TriaxialError> {
    let models: Vec<ParticleModel> = spec.counts()?.classes.iter().map(|c| c.model).collect();
    let mesh = MeshSection {
        level: spec.mesh.level,
        order: spec.mesh.order,
        shells: 1,
        sizing: spec.mesh.sizing,
        axes: fdem_solver::sphere_axes(),
    };
    Ok(particles
        .iter()
        .map(|p| ParticleSection {
            diameter: p.diameter,
            center: p.center,
            velocity: None,
            angular_velocity: None,
            orientation: Some(p.orientation),
            mesh: Some(mesh),
            model: models.get(p.class).copied().unwrap_or(spec.model),
        })
        .collect())
}

/// The preparation walls: the cylinder, then the bottom and top platens at `bottom` and
/// `top` moving at `speed` each towards the other (m/s, 0 for fixed platens).
pub fn preparation_walls(radius: f64, bottom: f64, top: f64, speed: f64) -> Vec<WallSection> {
    let plane = |z: f64, n: f64, v: f64| WallSection {
        kind: WallType::Plane,
        point: Some([0.0, 0.0, z]),
        normal: Some([0.0, 0.0, n]),
        axis_point: None,
        axis: None,
        radius: None,
        velocity: if v == 0.0 { None } else { Some([0.0, 0.0, v]) },
    };
    vec![
        WallSection {
            kind: WallType::Cylinder,
            point: None,
            normal: None,
            axis_point: Some([0.0; 3]),
            axis: Some([0.0, 0.0, 1.0]),
            radius: Some(radius),
            velocity: None,
        },
        plane(bottom, 1.0, speed),
        plane(top, -1.0, -speed),
    ]
}

/// A scene of the specimen's particles with the given walls and step rule; contact as
/// simulated (exact scaling applied) but with the preparation's friction.
fn scene(
    spec: &SpecimenSpec,
    particles: Vec<ParticleSection>,
    walls: Vec<WallSection>,
    dt: Option<f64>,
) -> Result<Scene, TriaxialError> {
    let simulated = spec.simulated()?;
    let contact = ContactSection {
        friction: simulated.preparation_friction,
        ..simulated.contact
    };
    let g = spec.preparation.gravity;
    Ok(Scene {
        simulation: SimulationSection {
            // The time loop is driven here, step by step; the duration is never used.
            duration: 1.0,
            dt,
            dt_safety: Some(spec.preparation.dt_safety),
            output_interval: None,
            gravity: if g == [0.0; 3] { None } else { Some(g) },
            energy_tolerance: Some(PREPARATION_ENERGY_TOLERANCE),
            // The particles sit at their reference placements here and start from a
            // restored state (the preparation checks its packing itself).
            allow_initial_overlap: true,
        },
        material: simulated.material,
        particles,
        contact: Some(contact),
        walls,
        auto: None,
    })
}

/// The time step of a specimen: `dt_safety` times the stable bound of one particle of
/// each simulated size (the bounds are per particle: the assembled elastic bound combined
/// with the per-node contact springs), with the returned bound and its source. With one
/// size the probe has no second body, so the contact springs count the node's own mass
/// only, not the reduced mass with another body's node (docs/SPECIMENS.md, "Rigid
/// specimens").
pub fn specimen_time_step(spec: &SpecimenSpec) -> Result<(f64, f64, String), TriaxialError> {
    let sizes = spec.simulated()?.sizes;
    let d_max = sizes.iter().copied().fold(0.0, f64::max);
    let probe: Vec<PlacedParticle> = sizes
        .iter()
        .enumerate()
        .map(|(i, &d)| PlacedParticle {
            diameter: d,
            center: [3.0 * d_max * i as f64, 0.0, 0.0],
            orientation: [1.0, 0.0, 0.0, 0.0],
            class: i,
        })
        .collect();
    let radius = 3.0 * d_max * (sizes.len() as f64 + 1.0);
    let walls = preparation_walls(radius, -radius, radius, 0.0);
    let s = scene(spec, particle_sections(spec, &probe)?, walls, None)?;
    let sim = s.build().map_err(solver("time step"))?;
    Ok((sim.dt(), sim.bound().dt, sim.bound().source.clone()))
}

impl Snapshot {
    /// Takes the state of `sim` with `history` (the history consumed by its last force
    /// evaluation).
    fn take(sim: &Simulation, history: Vec<(usize, Counterpart, [f64; 3])>) -> Snapshot {
        Snapshot {
            positions: sim.state().positions.clone(),
            velocities: sim.state().velocities.clone(),
            history,
            rigid: sim.rigid_states(),
            time: sim.time(),
            step: sim.step(),
        }
    }

    /// Places the particles of `sim` (its first nodes, in the same order) in this state:
    /// node positions and velocities, then the rigid particles' poses and momenta (which
    /// place their nodes again, from the pose).
    pub fn place_particles(&self, sim: &mut Simulation) -> Result<(), TriaxialError> {
        let n = self.positions.len();
        if self.velocities.len() != n || n > sim.state().len() {
            return Err(TriaxialError::Solver {
                phase: "restore",
                cause: fdem_solver::SolverError::InvalidScene(format!(
                    "the snapshot has {n} positions and {} velocities for a simulation of {} nodes",
                    self.velocities.len(),
                    sim.state().len()
                )),
            });
        }
        let nodes = sim.nodes_mut();
        nodes.positions[..n].copy_from_slice(&self.positions);
        nodes.velocities[..n].copy_from_slice(&self.velocities);
        sim.set_rigid_states(&self.rigid).map_err(solver("restore"))
    }

    /// Restores this state into `sim` (built on the same particles): positions,
    /// velocities, time, step count and friction history (entries against walls only
    /// with `keep_wall_history`), then re-evaluates the forces and makes the restored
    /// state the reference of the energy balance (gravity's work included).
    pub fn restore_into(
        &self,
        sim: &mut Simulation,
        keep_wall_history: bool,
    ) -> Result<(), TriaxialError> {
        let n = sim.state().len();
        if self.positions.len() != n || self.velocities.len() != n {
            return Err(TriaxialError::Solver {
                phase: "restore",
                cause: fdem_solver::SolverError::InvalidScene(format!(
                    "the snapshot has {} nodes but the simulation {n}; build it from the same particles",
                    self.positions.len()
                )),
            });
        }
        self.place_particles(sim)?;
        sim.set_clock(self.time, self.step);
        let history: Vec<_> = self
            .history
            .iter()
            .copied()
            .filter(|h| keep_wall_history || matches!(h.1, Counterpart::Body(_)))
            .collect();
        match sim.contact_mut() {
            Some(c) => c
                .model_mut()
                .import_history(&history)
                .map_err(TriaxialError::History)?,
            None if history.is_empty() => {}
            None => {
                return Err(TriaxialError::History(
                    fdem_contact::ContactError::InconsistentSurface {
                        what: "the simulation has no contact model".into(),
                        fix: "build it with contact enabled",
                    },
                ));
            }
        }
        sim.rebase_energy().map_err(solver("restore"))
    }
}

/// History consumed by the next evaluation of `sim`.
fn history(sim: &Simulation) -> Vec<(usize, Counterpart, [f64; 3])> {
    sim.contact()
        .map(|c| c.model().export_history())
        .unwrap_or_default()
}

/// Forces below this fraction of the reference contact force `sigma_0 d_min^2` count as
/// no force in [`unbalanced_force_ratio`].
pub const FORCE_FLOOR: f64 = 1e-6;

/// The reference contact force `sigma_0 d_min^2` (N) of a specimen confined at `sigma_0`
/// (Pa) whose smallest particle has diameter `d_min` (m): the scale against which
/// [`unbalanced_force_ratio`] floors its forces.
pub fn reference_force(sigma_0: f64, d_min: f64) -> f64 {
    sigma_0 * d_min * d_min
}

/// Unbalanced-force ratio of `sim`: `sum_b |F_b| / max(sum_b sum_(contacts on b) |f_c|,
/// n_b FORCE_FLOOR f_ref)`, with `F_b` the net force on particle `b` (the sum of its node
/// forces: elastic forces cancel), each node contact counted on the node's particle and,
/// for a face contact, on the face's particle, `n_b` the number of particles and
/// `f_ref` a reference contact force (the caller's `sigma_0 d_min^2`). The floor keeps
/// round-off forces of an assembly without load from counting as unbalanced.
pub fn unbalanced_force_ratio(sim: &Simulation, reference_force: f64) -> f64 {
    let mut denominator = 0.0;
    if let Some(contact) = sim.contact() {
        for c in contact.model().node_contacts() {
            let f = c.force();
            let m = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
            denominator += match c.counterpart {
                Counterpart::Body(_) => 2.0 * m,
                Counterpart::Wall(_) => m,
            };
        }
    }
    let floor = sim.particles().count() as f64 * FORCE_FLOOR * reference_force;
    let denominator = denominator.max(floor);
    if denominator <= 0.0 {
        return 0.0;
    }
    let numerator: f64 = sim
        .particles()
        .map(|(_, b)| {
            let mut f = [0.0; 3];
            for i in b.nodes.clone() {
                for (k, fk) in f.iter_mut().enumerate() {
                    *fk += sim.state().forces[i][k];
                }
            }
            (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt()
        })
        .sum();
    numerator / denominator
}

fn platen_gap(sim: &Simulation) -> f64 {
    sim.contact()
        .map(|c| {
            let walls = c.model().walls();
            let z = |w: usize| match walls.get(w).map(|w| w.shape_at(sim.time())) {
                Some(fdem_contact::WallShape::Plane { point, .. }) => point[2],
                _ => 0.0,
            };
            z(WALL_TOP) - z(WALL_BOTTOM)
        })
        .unwrap_or(0.0)
}

fn status(sim: &Simulation, step: u64, unbalanced: Option<f64>) -> Status {
    Status {
        step,
        time: sim.time(),
        platen_gap: platen_gap(sim),
        contacts: sim.contact().map_or(0, |c| c.model().node_contacts().len()),
        unbalanced_force: unbalanced,
    }
}

/// Advances `steps` steps (at least 1) and returns the snapshot at the end, reporting to
/// `observer` about every `steps / 200` steps.
fn run_phase(
    sim: &mut Simulation,
    steps: u64,
    phase: Phase,
    observer: &mut dyn Observer,
) -> Result<Snapshot, TriaxialError> {
    let every = (steps / 200).max(1);
    let mut before_last = Vec::new();
    for s in 0..steps {
        if s + 1 == steps {
            before_last = history(sim);
        }
        sim.advance().map_err(solver(phase.name()))?;
        if (s + 1) % every == 0 && !observer.progress(phase, &status(sim, s + 1, None)) {
            return Err(TriaxialError::Interrupted {
                phase: phase.name(),
                step: sim.step(),
            });
        }
    }
    Ok(Snapshot::take(sim, before_last))
}

/// Kinetic damping: stops every node (velocities zero) and restores that state, so that
/// the forces and the energy balance are re-evaluated at rest. The history is the one the
/// last evaluation produced; at rest the re-evaluation adds no tangential increment.
fn quench(sim: &mut Simulation) -> Result<Snapshot, TriaxialError> {
    let snapshot = Snapshot {
        positions: sim.state().positions.clone(),
        velocities: vec![[0.0; 3]; sim.state().len()],
        history: history(sim),
        rigid: sim
            .rigid_states()
            .into_iter()
            .map(|r| RigidState {
                velocity: [0.0; 3],
                body_momentum: [0.0; 3],
                ..r
            })
            .collect(),
        time: sim.time(),
        step: sim.step(),
    };
    snapshot.restore_into(sim, true)?;
    Ok(snapshot)
}

/// Mean axial stress on the two platens and mean radial stress on the cylinder (Pa).
fn wall_stresses(spec: &SpecimenSpec, sim: &Simulation) -> (f64, f64) {
    let Some(contact) = sim.contact() else {
        return (0.0, 0.0);
    };
    let forces = contact.model().wall_forces();
    let axial = |w: usize| forces.get(w).map_or(0.0, |f| f[2].abs());
    let platen = 0.5 * (axial(WALL_BOTTOM) + axial(WALL_TOP)) / spec.inner_area();
    let radial: f64 = contact
        .model()
        .node_contacts()
        .iter()
        .filter(|c| c.counterpart == Counterpart::Wall(WALL_CYLINDER as u32))
        .map(|c| c.normal_force[0].hypot(c.normal_force[1]))
        .fold(0.0, |a, b| a + b);
    let lateral = std::f64::consts::TAU * spec.inner_radius() * spec.height;
    (platen, radial / lateral)
}

/// Real solid fraction over `volume`: the deformed tetrahedra's volume (corner nodes)
/// plus each rigid particle's, its mass over `density`.
fn real_solid_fraction(sim: &Simulation, volume: f64, density: f64) -> f64 {
    let rigid: f64 = sim
        .particles()
        .filter(|(_, b)| b.kind == fdem_solver::BodyKind::Rigid)
        .map(|(id, _)| sim.body_motion(id).mass / density)
        .sum();
    let x = &sim.state().positions;
    let solid: f64 = sim
        .connectivity()
        .iter()
        .map(|e| {
            let (a, b, c, d) = (x[e[0]], x[e[1]], x[e[2]], x[e[3]]);
            let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
            (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
                + u[2] * (v[0] * w[1] - v[1] * w[0]))
                / 6.0
        })
        .sum();
    (solid + rigid) / volume
}

/// Checks of the prepared state in `sim` (platens fixed at 0 and `height`).
fn checks(spec: &SpecimenSpec, sim: &Simulation, d_min: f64) -> Checks {
    let radius = spec.inner_radius();
    let height = spec.height;
    let x = &sim.state().positions;
    let mut particles_outside = 0;
    let mut max_wall_penetration = 0.0f64;
    for b in sim.bodies() {
        let mut c = [0.0; 3];
        let mut m = 0.0;
        for i in b.nodes.clone() {
            let xi = x[i];
            let mi = sim.state().masses[i];
            m += mi;
            for k in 0..3 {
                c[k] += mi * xi[k];
            }
            let r = (xi[0] * xi[0] + xi[1] * xi[1]).sqrt();
            max_wall_penetration = max_wall_penetration
                .max(r - radius)
                .max(-xi[2])
                .max(xi[2] - height);
        }
        let c = c.map(|v| v / m);
        let r = (c[0] * c[0] + c[1] * c[1]).sqrt();
        if !(r < radius && c[2] > 0.0 && c[2] < height) {
            particles_outside += 1;
        }
    }
    let max_overlap = sim.contact().map_or(0.0, |c| {
        c.model()
            .node_contacts()
            .iter()
            .filter(|n| matches!(n.counterpart, Counterpart::Body(_)))
            .map(|n| n.depth)
            .fold(0.0, f64::max)
    });
    let overlap_limit = spec.max_overlap() * d_min;
    let unbalanced = unbalanced_force_ratio(sim, reference_force(spec.confining_pressure, d_min));
    let limit = spec.preparation.unbalanced_force;
    let mut failures = Vec::new();
    if particles_outside > 0 {
        failures.push(format!(
            "{particles_outside} particle centroids lie outside the cylinder or the platens"
        ));
    }
    if max_wall_penetration > overlap_limit {
        failures.push(format!(
            "a node is {max_wall_penetration:.3e} m inside a wall, more than {overlap_limit:.3e} m \
             (preparation.max_overlap x smallest diameter)"
        ));
    }
    if max_overlap > overlap_limit {
        failures.push(format!(
            "particles overlap by {max_overlap:.3e} m, more than {overlap_limit:.3e} m \
             (preparation.max_overlap x smallest diameter)"
        ));
    }
    if unbalanced > limit {
        failures.push(format!(
            "unbalanced-force ratio {unbalanced:.3e} is above preparation.unbalanced_force = {limit}; \
             raise preparation.settle_time"
        ));
    }
    Checks {
        particles_outside,
        max_wall_penetration: max_wall_penetration.max(0.0),
        max_overlap,
        overlap_limit,
        unbalanced_force: unbalanced,
        unbalanced_force_limit: limit,
        failures,
    }
}

/// Places the particles of `spec` at random in a loose column centred on the target
/// height, `travel` taller than the target (half above, half below), growing the column
/// by [`COLUMN_GROWTH`] when it is too full.
fn place(
    spec: &SpecimenSpec,
    diameters: &[(f64, usize)],
    clearance: f64,
    mut travel: impl FnMut(f64) -> f64,
) -> Result<(Vec<PlacedParticle>, Column), TriaxialError> {
    let solids: f64 = diameters.iter().map(|d| sphere_volume(d.0)).sum();
    let mut height = solids / (spec.preparation.loose_solid_fraction * spec.inner_area());
    let mut last = None;
    for _ in 0..COLUMN_TRIES {
        let t = travel(height);
        let column = Column {
            radius: spec.inner_radius(),
            bottom: -0.5 * t,
            top: spec.height + 0.5 * t,
        };
        match place_spheres(diameters, &column, clearance, spec.seed) {
            Ok(p) => return Ok((p, column)),
            Err(e) => last = Some((e, column)),
        }
        height *= COLUMN_GROWTH;
    }
    let (e, column) = last.ok_or(TriaxialError::Placement {
        particle: 0,
        total: diameters.len(),
        diameter: 0.0,
        height,
        sweeps: 0,
    })?;
    Err(TriaxialError::Placement {
        particle: e.particle,
        total: diameters.len(),
        diameter: e.diameter,
        height: column.top - column.bottom,
        sweeps: crate::placement::MAX_SWEEPS,
    })
}

/// Prepares a specimen by the dynamic method (docs/SPECIMENS.md, "Preparation"):
///
/// 1. the definition is validated and counted (nothing else happens if it is refused);
/// 2. the time step: `dt_safety` times the stable bound of one particle per size;
/// 3. placement: spheres at random without overlap, largest first, in a cylinder of the
///    inner radius whose height gives the loose solid fraction, centred on the target;
/// 4. compaction: both platens move towards each other at half the platen speed (the
///    loose column is rounded up so that a whole number of steps ends exactly at z = 0
///    and z = height);
/// 5. settling: platens fixed (a rebuild with the state and history restored) until the
///    unbalanced-force ratio is at most `preparation.unbalanced_force`, checked every
///    `check_interval` steps, or the settling time runs out; then a stop, and settling
///    again from rest while the ratio at rest is above the limit and time remains;
/// 6. checks: no particle outside, overlaps and wall penetrations below the limit, the
///    unbalanced force small. A failed check is recorded in the report
///    ([`Checks::failures`]), not raised: the caller decides.
pub fn prepare(
    spec: &SpecimenSpec,
    observer: &mut dyn Observer,
) -> Result<PreparedSpecimen, TriaxialError> {
    let wall_clock = Instant::now();
    let cpu = cpu_time::ProcessTime::try_now().ok();
    let counts = spec.counts()?;
    check_size(spec, &counts)?;
    let sizes = spec.simulated()?.sizes;
    let d_min = sizes.iter().copied().fold(f64::INFINITY, f64::min);
    let d_max = sizes.iter().copied().fold(0.0, f64::max);
    let prep = &spec.preparation;

    let (dt, dt_bound, dt_bound_source) = specimen_time_step(spec)?;

    // Placement: the column's extra height is a whole number of steps of platen travel.
    observer.phase(Phase::Place, 0);
    let diameters = counts.diameters();
    let mut compact_steps = 0u64;
    let (particles, column) = place(spec, &diameters, prep.clearance * d_min, |loose_height| {
        let wanted = (loose_height - spec.height).max(0.0);
        compact_steps = ((wanted / (prep.platen_speed * dt)).ceil() as u64).max(1);
        prep.platen_speed * dt * compact_steps as f64
    })?;
    let sections = particle_sections(spec, &particles)?;
    let compacted = compact(
        spec,
        &counts,
        &sections,
        &column,
        dt,
        compact_steps,
        observer,
    )?;

    // Settling: platens fixed exactly at the target.
    let walls = preparation_walls(column.radius, 0.0, spec.height, 0.0);
    let mut sim = scene(spec, sections, walls, Some(dt))?
        .build()
        .map_err(solver("settle"))?;
    compacted.restore_into(&mut sim, true)?;
    let interval = prep.check_interval;
    let settle_time = prep.settle_time_or_default(d_max);
    let max_steps = ((settle_time / (dt * interval as f64)).ceil() as u64).max(1) * interval;
    let mut settling = settle(&mut sim, spec, max_steps, d_min, observer)?;
    // The specimen is kept at rest. At rest the contacts' damping forces vanish, so the
    // ratio that ended settling can be above the limit again: settle on from rest while
    // steps remain (a packing that passes at rest is stopped once, as before).
    let mut last = quench(&mut sim)?;
    let f_ref = reference_force(spec.confining_pressure, d_min);
    while settling.steps < max_steps && unbalanced_force_ratio(&sim, f_ref) > prep.unbalanced_force
    {
        let more = settle(&mut sim, spec, max_steps - settling.steps, d_min, observer)?;
        settling = settling.then(more);
        last = quench(&mut sim)?;
    }

    let checks = checks(spec, &sim, d_min);
    let inner_volume = spec.inner_volume();
    let pairs = sim.contact().map_or(0, |c| {
        c.model()
            .pair_sums()
            .iter()
            .filter(|p| matches!(p.counterpart, Counterpart::Body(_)))
            .count()
    }) as u64;
    let (platen_stress, cylinder_stress) = wall_stresses(spec, &sim);
    let report = PreparationReport {
        particles: counts.particles,
        nodes: counts.nodes,
        elements: counts.elements,
        inner_radius: column.radius,
        loose_height: column.top - column.bottom,
        target_height: spec.height,
        dt,
        dt_bound,
        dt_bound_source,
        platen_speed: prep.platen_speed,
        compact_steps,
        settle_steps: settling.steps,
        settled: settling.settled,
        simulated_time: sim.time(),
        wall_seconds: wall_clock.elapsed().as_secs_f64(),
        cpu_seconds: cpu.map(|c| c.elapsed().as_secs_f64()),
        threads: rayon::current_num_threads() as u64,
        solid_fraction_nominal: counts.solid_volume / inner_volume,
        solid_fraction_real: real_solid_fraction(&sim, inner_volume, spec.material.density),
        platen_stress,
        cylinder_stress,
        node_contacts: sim.contact().map_or(0, |c| c.model().node_contacts().len()) as u64,
        particle_contacts: pairs,
        coordination_number: 2.0 * pairs as f64 / counts.particles as f64,
        residual_kinetic_energy: settling.residual_kinetic_energy,
        quenches: settling.quenches,
        checks,
    };
    Ok(PreparedSpecimen {
        spec: spec.clone(),
        particles,
        dt,
        state: last,
        report,
    })
}

/// Refuses, before any work, a specimen whose estimated memory exceeds `available`
/// (bytes; `None` when the platform does not say), with both figures.
pub fn check_memory(
    spec: &SpecimenSpec,
    counts: &crate::Counts,
    available: Option<u64>,
) -> Result<(), TriaxialError> {
    let need = counts.memory_estimate(spec.mesh.order == fdem_mesh::ElementOrder::Quadratic);
    match available {
        Some(have) if need > have => Err(TriaxialError::Definition {
            origin: spec.name.clone(),
            line: 0,
            column: 0,
            key: "gradation".into(),
            message: format!(
                "{} particles with {} nodes and {} elements need about {:.1} GB, but {:.1} GB \
                 are available; use larger sizes, a coarse_graining factor, a lower mesh level, \
                 the rigid model or a smaller specimen",
                counts.particles,
                counts.nodes,
                counts.elements,
                need as f64 / 1e9,
                have as f64 / 1e9
            ),
        }),
        _ => Ok(()),
    }
}

/// Refuses a specimen larger than one preparation handles or than the memory available,
/// before any work.
fn check_size(spec: &SpecimenSpec, counts: &crate::Counts) -> Result<(), TriaxialError> {
    check_memory(spec, counts, fdem_core::fs::available_memory())?;
    if counts.nodes > MAX_NODES {
        return Err(TriaxialError::Definition {
            origin: spec.name.clone(),
            line: 0,
            column: 0,
            key: "gradation".into(),
            message: format!(
                "{} particles with {} nodes are more than one preparation handles ({MAX_NODES} \
                 nodes); use larger sizes, a coarse_graining factor or a smaller specimen",
                counts.particles, counts.nodes
            ),
        });
    }
    Ok(())
}

/// Compaction: the platens close at half the platen speed each for `steps` steps; a
/// contact the law refuses stops it with the gap reached.
fn compact(
    spec: &SpecimenSpec,
    counts: &crate::Counts,
    sections: &[ParticleSection],
    column: &Column,
    dt: f64,
    steps: u64,
    observer: &mut dyn Observer,
) -> Result<Snapshot, TriaxialError> {
    let speed = spec.preparation.platen_speed;
    let walls = preparation_walls(column.radius, column.bottom, column.top, 0.5 * speed);
    let mut sim = scene(spec, sections.to_vec(), walls, Some(dt))?
        .build()
        .map_err(solver("compact"))?;
    observer.phase(Phase::Compact, steps);
    match run_phase(&mut sim, steps, Phase::Compact, observer) {
        Ok(snapshot) => Ok(snapshot),
        Err(TriaxialError::Solver { cause, .. }) => {
            let gap = platen_gap(&sim);
            Err(TriaxialError::Compaction {
                gap,
                target: spec.height,
                solid_fraction: counts.solid_volume / (spec.inner_area() * gap),
                cause,
            })
        }
        Err(e) => Err(e),
    }
}

/// How settling ended.
struct Settling {
    steps: u64,
    settled: bool,
    quenches: u64,
    residual_kinetic_energy: f64,
}

impl Settling {
    /// This settling followed by `more` from where it ended.
    fn then(self, more: Settling) -> Settling {
        Settling {
            steps: self.steps + more.steps,
            settled: more.settled,
            quenches: self.quenches + more.quenches,
            residual_kinetic_energy: more.residual_kinetic_energy,
        }
    }
}

/// Settling with kinetic damping (every node stopped when the kinetic energy has passed
/// a peak) until the unbalanced-force ratio reaches `preparation.unbalanced_force` or
/// `max_steps` (a multiple of `preparation.check_interval`) have passed.
fn settle(
    sim: &mut Simulation,
    spec: &SpecimenSpec,
    max_steps: u64,
    d_min: f64,
    observer: &mut dyn Observer,
) -> Result<Settling, TriaxialError> {
    let prep = &spec.preparation;
    let interval = prep.check_interval;
    let f_ref = reference_force(spec.confining_pressure, d_min);
    observer.phase(Phase::Settle, max_steps);
    let (mut steps, mut settled, mut quenches) = (0, false, 0u64);
    let (mut ke_prev, mut rising) = (0.0, false);
    let n_nodes = sim.state().len();
    while steps < max_steps {
        sim.advance().map_err(solver("settle"))?;
        steps += 1;
        let ke = sim.state().kinetic_energy(0..n_nodes);
        if rising && ke < ke_prev {
            quench(sim)?;
            quenches += 1;
            ke_prev = 0.0;
            rising = false;
        } else {
            rising = ke > ke_prev;
            ke_prev = ke;
        }
        if steps % interval == 0 {
            let ratio = unbalanced_force_ratio(sim, f_ref);
            if !observer.progress(Phase::Settle, &status(sim, steps, Some(ratio))) {
                return Err(TriaxialError::Interrupted {
                    phase: "settle",
                    step: sim.step(),
                });
            }
            if ratio <= prep.unbalanced_force {
                settled = true;
                break;
            }
        }
    }
    Ok(Settling {
        steps,
        settled,
        quenches,
        residual_kinetic_energy: sim.state().kinetic_energy(0..n_nodes),
    })
}

impl PreparedSpecimen {
    /// The `[[particle]]` tables of the specimen (reference placements and mesh), for a
    /// caller that builds its own scene around the specimen.
    ///
    /// # Errors
    /// A specimen definition that no longer gives counts (it did when prepared).
    pub fn particle_sections(&self) -> Result<Vec<ParticleSection>, TriaxialError> {
        particle_sections(&self.spec, &self.particles)
    }

    /// The prepared configuration as a scene: the particles at their reference
    /// placements, the cylinder, the platens fixed at z = 0 and z = height, the
    /// preparation's contact law and the specimen's fixed step. Restoring the state into
    /// its simulation is [`PreparedSpecimen::simulation`].
    pub fn scene(&self) -> Result<Scene, TriaxialError> {
        let walls = preparation_walls(self.spec.inner_radius(), 0.0, self.spec.height, 0.0);
        scene(&self.spec, self.particle_sections()?, walls, Some(self.dt))
    }

    /// Builds the prepared configuration ([`PreparedSpecimen::scene`]) and restores the
    /// state and friction history into it: ready to step on from where preparation ended.
    pub fn simulation(&self) -> Result<Simulation, TriaxialError> {
        let mut sim = self.scene()?.build().map_err(solver("restore"))?;
        self.state.restore_into(&mut sim, true)?;
        Ok(sim)
    }

    /// Restores the prepared state into a simulation the caller built from
    /// [`PreparedSpecimen::particle_sections`] (in that order) with its own walls and
    /// contact law. History against walls is kept only with `keep_wall_history` (when the
    /// caller's walls 0, 1, 2 are the cylinder and platens of the preparation). Build it
    /// with `simulation.dt = Some(self.dt)` to keep the preparation's step.
    pub fn restore_into(
        &self,
        sim: &mut Simulation,
        keep_wall_history: bool,
    ) -> Result<(), TriaxialError> {
        self.state.restore_into(sim, keep_wall_history)
    }
}
