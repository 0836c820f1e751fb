//! The simulation of the triaxial test: the prepared particles, the membrane that replaces
//! the preparation cylinder, the two rigid platens, and the geometric measurements
//! (height, enclosed volume, axial force) the test reads from them.
//!
//! Node layout: the particles' nodes first (as prepared, so friction history keys and
//! body ids are unchanged), then the membrane's. The membrane is one more body of the
//! contact surface (id = number of particles) with its faces oriented towards the axis,
//! so particle nodes touch membrane faces and membrane nodes touch particle faces with the
//! same law as between particles. Its two end rings are held by the platens: a
//! constraint contribution, evaluated after every other force, removes the net force on
//! the ring nodes (their velocity is the platen's) and books the reaction's power as
//! external work, so the energy balance stays checked.

use crate::membrane::{MembraneForces, MembraneMesh, MembraneSpec, membrane_mesh};
use crate::{PreparedSpecimen, SpecimenSpec, TriaxialError};
use fdem_contact::{ContactModel, ContactSurface, Counterpart, Wall, WallShape};
use fdem_solver::{
    ForceContribution, NodeState, NodeView, Powers, Scene, SceneParts, Simulation,
    SimulationSection, SolverError, StepBound, TimeStep,
};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Energy-balance tolerance of the stability guard during the test (the solver's default
/// is 0.05), checked every 256 steps against the balance since the last output (the
/// driver starts a new window at every output row and accumulates the phase's balance,
/// reported in `curve.csv` and `summary.json`). The balance drifts during the test without
/// anything going unstable: steadily while the membrane sinks into the surface voids in
/// consolidation and while E4s is sheared, in bursts while particles rearrange; the
/// kinetic energy stays at a few joules (docs/TRIAXIAL.md, "Energy balance"; the source is
/// not isolated yet). The largest drift measured in one window was 0.14 of the window's
/// energy scale (E4s shear, 1,700 steps); an instability grows by orders of magnitude in
/// a window (a step 2.5 times the element bound stopped the quick test's model at step 4,
/// through the contact's tunnelling guard).
pub const TEST_ENERGY_TOLERANCE: f64 = 0.5;

/// Default depth limit of the test's contacts, in contact margins (`[contact]
/// depth_limit` overrides it). Under the confining stress, vertex nodes of the angular
/// particles carry large forces on small control areas and press deeper than half a
/// margin while moving slowly: the E4s shear stopped at 3.5 % axial strain and the quick
/// one at 9.5 % on such genuine contacts (docs/TRIAXIAL.md, "Contact depth limit"). Two
/// margins let contacts reach one margin (a quarter of the shortest surface edge with the
/// default margin; the quick test's deepest was 0.65 of it).
pub const TEST_DEPTH_LIMIT_MARGINS: f64 = 2.0;

/// The test's Verlet skin (the contact model's margin: rebuild distance and tunnelling
/// scale), in specimen contact margins. Candidate boxes are enlarged by skin plus depth
/// limit, and the narrow phase's cost grows faster than that enlargement: a thin skin
/// pays for the deeper depth limit (quick specimen, one thread: 60,503 candidates with
/// skin = depth limit = margin, 292,802 with a depth limit of 3 margins, 78,042 with
/// this skin and a depth limit of 2 margins). The particles move a quarter margin in
/// thousands of steps, so the extra rebuilds cost little.
pub const TEST_SKIN_FRACTION: f64 = 0.25;

/// Depth, in specimen contact margins, beyond which a particle node found behind the
/// membrane is a fold artefact and discarded (`fdem_contact::ContactModel::set_sheet_bodies`).
pub const TEST_FOLD_DEPTH_MARGINS: f64 = 0.5;

/// Density of the cell fluid (water, kg/m^3) behind the default added mass.
pub const WATER_DENSITY: f64 = 1000.0;

/// Wall index of the bottom platen in the test's contact model (fixed).
pub const TEST_WALL_BOTTOM: usize = 0;
/// Wall index of the top platen (driven).
pub const TEST_WALL_TOP: usize = 1;
/// Wall index the membrane is reported as in contact snapshots (it is a body of the
/// contact surface, reported as a boundary).
pub const TEST_WALL_MEMBRANE: u32 = 2;

fn setup(message: impl Into<String>) -> TriaxialError {
    TriaxialError::Test {
        phase: "set-up",
        message: message.into(),
    }
}

fn solver_error(phase: &'static str) -> impl Fn(SolverError) -> TriaxialError {
    move |e| TriaxialError::Test {
        phase,
        message: e.to_string(),
    }
}

/// Holds the membrane's end rings on the platens: removes the net force on the ring nodes
/// (so their velocity, the platen's, does not change) and books the reaction's power,
/// `-sum f . v`, as external power. Must be the last contribution.
#[derive(Debug)]
struct RingConstraint {
    nodes: Vec<usize>,
}

impl ForceContribution for RingConstraint {
    fn name(&self) -> &str {
        "membrane rings"
    }

    fn stable_time_step(&self) -> Option<StepBound> {
        None
    }

    fn add_forces(
        &mut self,
        nodes: NodeView<'_>,
        forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError> {
        let mut power = 0.0;
        for &i in &self.nodes {
            let (f, v) = (forces[i], nodes.velocities[i]);
            power -= f[0] * v[0] + f[1] * v[1] + f[2] * v[2];
            forces[i] = [0.0; 3];
        }
        Ok(Powers {
            external: power,
            ..Powers::default()
        })
    }

    fn potential_energy(&self, _nodes: NodeView<'_>) -> f64 {
        0.0
    }
}

/// Viscous damping of the membrane's horizontal motion, the cell fluid's resistance in
/// the simplest form, with a speed limit:
/// `f = -c A v_h - c_lim A max(0, |v_h| - v_lim) v_h / |v_h|` on every free membrane node
/// (A its control area, v_h = (v_x, v_y, 0)). The linear part damps the radial approach and
/// the hoop (wrinkling) modes of a sheet without bending stiffness; the limiter, as stiff
/// as the explicit step allows (`c_lim A dt / m = 1/2`), keeps a membrane that finds no
/// support (a loose specimen under a rising pressure) from reaching speeds at which it
/// slams into the particles. Quasi-static tests move the membrane far below `v_lim`, where
/// only the linear part acts. The axial motion, which the platens impose, is free. The
/// power is booked as damping.
#[derive(Debug)]
struct MembraneDamping {
    nodes: Vec<usize>,
    /// `c A` per node (N s/m).
    linear: Vec<f64>,
    /// `c_lim A` per node (N s/m).
    limiter: Vec<f64>,
    /// Speed above which the limiter acts (m/s).
    speed_limit: f64,
    /// Horizontal damping force of the previous evaluation and the velocity it was
    /// evaluated with, per node, for the bookkeeping correction (see `add_forces`).
    previous: Vec<([f64; 2], [f64; 2])>,
}

impl ForceContribution for MembraneDamping {
    fn name(&self) -> &str {
        "membrane damping"
    }

    fn stable_time_step(&self) -> Option<StepBound> {
        // Its bound, 2 m / (c A + c_lim A) per node, is checked when the test is built.
        None
    }

    fn add_forces(
        &mut self,
        nodes: NodeView<'_>,
        forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError> {
        // The engine books `P dt` with P evaluated at the half-step velocity v(n+1/2);
        // velocity Verlet applies the force F(n+1) over the half kicks from v(n+1/2) to
        // v(n+3/2), so its true work is `F(n+1) . (v(n+1/2) + v(n+3/2)) / 2 dt`. For a
        // damping force as stiff as the limiter (c dt / m up to 1/2) the difference is
        // tens of percent of the dissipation, so the previous force's share is added
        // here, once v(n+3/2) is known: `-F(n) . (v(n+3/2) - v(n+1/2)) / 2`.
        let fresh = self.previous.len() != self.nodes.len();
        if fresh {
            self.previous = vec![([0.0; 2], [0.0; 2]); self.nodes.len()];
        }
        let mut power = 0.0;
        for (k, &i) in self.nodes.iter().enumerate() {
            let v = nodes.velocities[i];
            let (f_old, v_old) = self.previous[k];
            power -= 0.5 * (f_old[0] * (v[0] - v_old[0]) + f_old[1] * (v[1] - v_old[1]));
            let speed = v[0].hypot(v[1]);
            let mut c = self.linear[k];
            if speed > self.speed_limit {
                c += self.limiter[k] * (speed - self.speed_limit) / speed;
            }
            let f = [-c * v[0], -c * v[1]];
            forces[i][0] += f[0];
            forces[i][1] += f[1];
            power += c * speed * speed;
            self.previous[k] = (f, [v[0], v[1]]);
        }
        Ok(Powers {
            damping: power,
            ..Powers::default()
        })
    }

    fn potential_energy(&self, _nodes: NodeView<'_>) -> f64 {
        0.0
    }
}

/// The membrane's forces with a pressure the test driver can change between steps (the
/// contribution itself is owned by the simulation).
///
/// The follower pressure is not conservative, so its work is booked from its power. The
/// engine books `P dt` at the half-step velocity v(n+1/2), while velocity Verlet applies
/// the force F(n+1) from v(n+1/2) to v(n+3/2); on light membrane nodes that oscillate in
/// contact the difference accumulates to percents of the pressure work. The share
/// `F(n) . (v(n+3/2) - v(n+1/2)) / 2` of the previous force is added once v(n+3/2) is
/// known (the same correction as in `MembraneDamping`).
#[derive(Debug)]
struct PressurisedMembrane {
    inner: MembraneForces,
    pressure: Arc<AtomicU64>,
    triangles: Vec<[usize; 3]>,
    /// Pressure force of the previous evaluation and the velocity it was evaluated with,
    /// per membrane node.
    previous: Vec<([f64; 3], [f64; 3])>,
    scratch: Vec<[f64; 3]>,
}

impl PressurisedMembrane {
    fn new(inner: MembraneForces, pressure: Arc<AtomicU64>) -> Self {
        let triangles = inner.triangles().to_vec();
        PressurisedMembrane {
            inner,
            pressure,
            triangles,
            previous: Vec::new(),
            scratch: Vec::new(),
        }
    }
}

impl ForceContribution for PressurisedMembrane {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn stable_time_step(&self) -> Option<StepBound> {
        self.inner.stable_time_step()
    }

    fn add_forces(
        &mut self,
        nodes: NodeView<'_>,
        forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError> {
        let p = f64::from_bits(self.pressure.load(Ordering::Relaxed));
        self.inner.set_pressure(p);
        let mut powers = self.inner.add_forces(nodes, forces)?;
        // The pressure forces alone (the membrane adds p a_in / 3 to each corner), for
        // the bookkeeping correction.
        let (first, n) = (self.inner.first_node(), self.inner.n_nodes());
        self.scratch.clear();
        self.scratch.resize(n, [0.0; 3]);
        let x = nodes.positions;
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| x[i + first]);
            let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let area = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            for &i in t {
                for (f, a) in self.scratch[i].iter_mut().zip(area) {
                    *f += p * a / 6.0;
                }
            }
        }
        if self.previous.len() != n {
            self.previous = vec![([0.0; 3], [0.0; 3]); n];
        }
        let mut correction = 0.0;
        for (j, (f, prev)) in self.scratch.iter().zip(&mut self.previous).enumerate() {
            let v = nodes.velocities[j + first];
            let (f_old, v_old) = *prev;
            for k in 0..3 {
                correction += 0.5 * f_old[k] * (v[k] - v_old[k]);
            }
            *prev = (*f, v);
        }
        powers.external += correction;
        Ok(powers)
    }

    fn potential_energy(&self, nodes: NodeView<'_>) -> f64 {
        self.inner.potential_energy(nodes)
    }
}

/// The membrane of a specimen around particle nodes that reach `reach` (m) from the axis:
/// its faces (chords of the equal-area polygon, see `MembraneSpec::node_radius`) start at
/// the larger of the inner radius and `reach`, so no membrane node or face starts inside
/// a particle (an initial overlap of the light membrane nodes would be released
/// explosively). The polygon's circle is therefore slightly larger than the faces: 0.1 %
/// for 40 divisions.
pub fn membrane_spec(spec: &SpecimenSpec, reach: f64) -> MembraneSpec {
    let (around, along) = spec.membrane.divisions(
        spec.inner_radius(),
        spec.height,
        spec.smallest_simulated_size(),
    );
    let n = around.max(3) as f64;
    let half = std::f64::consts::PI / n;
    // node radius = R sqrt(2 pi / (n sin(2 pi / n))); chord distance = node radius cos(pi/n).
    let chord_per_radius = half.cos() * (2.0 * half / (2.0 * half).sin()).sqrt();
    let radius = spec.inner_radius().max(reach) / chord_per_radius;
    MembraneSpec {
        radius,
        bottom: 0.0,
        top: spec.height,
        divisions_around: around,
        divisions_along: along,
        thickness: spec.membrane_thickness,
        youngs_modulus: spec.membrane.youngs_modulus,
        poisson_ratio: spec.membrane.poisson_ratio,
        density: spec.membrane.density,
    }
}

/// The assembled test: the simulation and what the test needs to drive and measure it.
pub struct TestModel {
    /// The simulation (particles, membrane, platens).
    pub sim: Simulation,
    /// Number of particles (bodies 0..n; the membrane is contact body n).
    pub particles: usize,
    /// A copy of the membrane's geometry and forces, for measurements (volume, inclusion).
    pub membrane: MembraneForces,
    /// Membrane specification.
    pub membrane_spec: MembraneSpec,
    /// The confining pressure on the membrane (f64 bits), read at every evaluation.
    pressure: Arc<AtomicU64>,
    /// Global ids of the top ring's nodes (they move with the top platen).
    pub top_ring: Vec<usize>,
    /// Global ids of the bottom ring's nodes (fixed).
    pub bottom_ring: Vec<usize>,
    /// Membrane triangles with global node ids (for output frames).
    pub membrane_triangles: Vec<[usize; 3]>,
    /// Elements of the particles.
    pub elements: usize,
}

impl TestModel {
    /// Builds the test around a prepared specimen: the particles as prepared (state,
    /// friction history against particles and platens), the test's contact law, the
    /// membrane under the confining pressure, the platens fixed where preparation left
    /// them, and the step `dt` (unless given, `test.dt_safety` times the stable bound of
    /// the assembled test: the particles' assembled elastic bound combined with the contact
    /// springs, or the membrane elements' bound if smaller).
    pub fn build(prepared: &PreparedSpecimen, dt: Option<f64>) -> Result<TestModel, TriaxialError> {
        let spec = &prepared.spec;
        let simulated = spec.simulated()?;
        let height = spec.height;
        let walls = vec![
            Wall::plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
            Wall::plane([0.0, 0.0, height], [0.0, 0.0, -1.0]),
        ];
        let scene = Scene {
            simulation: SimulationSection {
                duration: 1.0,
                dt: None,
                dt_safety: None,
                output_interval: None,
                gravity: None,
                energy_tolerance: None,
            },
            material: simulated.material.clone(),
            particles: prepared.particle_sections(),
            contact: Some(simulated.contact.clone()),
            walls: Vec::new(),
        };
        let SceneParts {
            assembly,
            bodies,
            elastic,
            state: particle_state,
        } = scene.assemble().map_err(solver_error("set-up"))?;
        let particles = bodies.len();
        let n_particle_nodes = particle_state.len();

        // Particle nodes pressed into the preparation cylinder reach beyond the inner
        // radius; the membrane starts just outside all of them (plus 1e-6 of the radius,
        // so that round-off cannot create a contact).
        let reach = prepared
            .state
            .positions
            .iter()
            .map(|x| x[0].hypot(x[1]))
            .fold(0.0, f64::max)
            * (1.0 + 1e-6);
        let membrane_spec = membrane_spec(spec, reach);
        let mesh: MembraneMesh = membrane_mesh(&membrane_spec).map_err(|e| setup(e.to_string()))?;
        let first = n_particle_nodes;
        let mut reference = particle_state.reference.clone();
        reference.extend_from_slice(&mesh.positions);
        let mut masses = particle_state.masses.clone();
        // Membrane masses plus the cell fluid's added mass on each node's area.
        let added = spec
            .membrane
            .added_mass
            .unwrap_or(0.5 * WATER_DENSITY * spec.inner_radius());
        masses.extend(
            mesh.lumped_masses(&membrane_spec)
                .iter()
                .zip(mesh.control_areas())
                .map(|(m, a)| m + added * a),
        );
        let state = NodeState::new(reference, masses);

        // The contact surface: the particles' surfaces and the membrane as body n.
        let mut surface = ContactSurface::from_assembly(&assembly)
            .map_err(|e| setup(format!("contact surface: {e}")))?;
        let margin = scene
            .contact_margin(&surface, &assembly.nodes)
            .map_err(solver_error("set-up"))?;
        let membrane_body = u32::try_from(particles).map_err(|_| setup("too many particles"))?;
        let global = |t: &[usize; 3]| t.map(|i| i + first);
        let membrane_triangles: Vec<[usize; 3]> = mesh.triangles.iter().map(global).collect();
        surface.triangles.extend_from_slice(&membrane_triangles);
        surface
            .triangle_body
            .extend(std::iter::repeat_n(membrane_body, mesh.triangles.len()));
        surface
            .surface_nodes
            .extend(first..first + mesh.positions.len());
        surface
            .node_body
            .extend(std::iter::repeat_n(membrane_body, mesh.positions.len()));
        surface.control_areas.extend(mesh.control_areas());
        // The specimen's margin is the length scale of the test's contact settings: a
        // thinner Verlet skin, a deeper depth limit, the membrane's fold depth.
        let mut model = ContactModel::new(
            scene.contact_params(),
            surface,
            walls,
            &state.masses,
            TEST_SKIN_FRACTION * margin,
        )
        .map_err(|e| setup(format!("contact: {e}")))?;
        let depth_limit = scene
            .contact_section()
            .depth_limit
            .unwrap_or(TEST_DEPTH_LIMIT_MARGINS * margin);
        model
            .set_depth_limit(depth_limit)
            .map_err(|e| setup(format!("contact: {e}")))?;
        model
            .set_sheet_bodies(&[membrane_body], TEST_FOLD_DEPTH_MARGINS * margin)
            .map_err(|e| setup(format!("contact: {e}")))?;

        let pressure = spec.confining_pressure;
        let pressure_cell = Arc::new(AtomicU64::new(pressure.to_bits()));
        let membrane = PressurisedMembrane::new(
            MembraneForces::new(&mesh, &membrane_spec, first, pressure)
                .map_err(|e| setup(e.to_string()))?,
            Arc::clone(&pressure_cell),
        );
        let measuring = MembraneForces::new(&mesh, &membrane_spec, first, pressure)
            .map_err(|e| setup(e.to_string()))?;
        let contact = fdem_solver::ContactForces::new(model);
        // The bound the simulation will compute (damping and rings impose none).
        let bound = StepBound::of_model(
            elastic.stable_time_step(),
            contact.stable_time_step(),
            [membrane.stable_time_step()],
        )
        .ok_or_else(|| setup("nothing bounds the time step"))?;
        let dt = dt.unwrap_or(spec.test.dt_safety * bound.dt);
        let top_ring: Vec<usize> = mesh.top_ring.iter().map(|i| i + first).collect();
        let bottom_ring: Vec<usize> = mesh.bottom_ring.iter().map(|i| i + first).collect();
        let rings = RingConstraint {
            nodes: bottom_ring.iter().chain(&top_ring).copied().collect(),
        };
        // Damping coefficients per node; explicit damping is stable while
        // (c + c_lim) A dt / m < 2, and the limiter takes half of what that allows.
        let areas = mesh.control_areas();
        let damped: Vec<usize> = (0..mesh.positions.len())
            .filter(|&i| !mesh.is_ring_node(i))
            .collect();
        let linear: Vec<f64> = damped
            .iter()
            .map(|&i| spec.membrane.damping * areas[i])
            .collect();
        let limiter: Vec<f64> = damped
            .iter()
            .map(|&i| 0.5 * state.masses[i + first] / dt)
            .collect();
        if let Some((k, _)) = damped
            .iter()
            .enumerate()
            .find(|&(k, &i)| (linear[k] + limiter[k]) * dt >= 2.0 * state.masses[i + first])
        {
            return Err(setup(format!(
                "membrane.damping = {} Pa s/m makes the membrane's explicit damping unstable at \
                 dt = {dt:e} s (node {}); lower it",
                spec.membrane.damping,
                damped[k] + first
            )));
        }
        let damping = MembraneDamping {
            nodes: damped.iter().map(|i| i + first).collect(),
            linear,
            limiter,
            speed_limit: spec
                .membrane
                .speed_limit
                .unwrap_or_else(|| spec.loading_velocity()),
            previous: Vec::new(),
        };
        let contributions: Vec<Box<dyn ForceContribution>> = vec![
            Box::new(contact),
            Box::new(membrane),
            Box::new(damping),
            Box::new(rings),
        ];
        let npe = assembly.nodes_per_element();
        let elements = assembly.n_elements();
        let mut sim = Simulation::new(
            state,
            bodies,
            npe,
            assembly.elements,
            elastic,
            contributions,
            [0.0; 3],
            TimeStep::Fixed(dt),
        )
        .map_err(solver_error("set-up"))?;
        if sim.bound.dt < dt {
            return Err(setup(format!(
                "the step {dt:e} s exceeds the stable bound {:e} s set by {}; \
                 refine nothing: lower the step (or soften the membrane or the contact)",
                sim.bound.dt, sim.bound.source
            )));
        }

        // The prepared state: particle nodes, time and step; history against particles
        // and the platens (preparation walls 1 and 2 are the test's walls 0 and 1).
        let snapshot = &prepared.state;
        if snapshot.positions.len() != n_particle_nodes {
            return Err(setup(format!(
                "the prepared state has {} nodes but the particles {n_particle_nodes}",
                snapshot.positions.len()
            )));
        }
        sim.state.positions[..n_particle_nodes].copy_from_slice(&snapshot.positions);
        sim.state.velocities[..n_particle_nodes].copy_from_slice(&snapshot.velocities);
        // The test's clock and step count start at zero.
        let history: Vec<_> = snapshot
            .history
            .iter()
            .filter_map(|&(node, c, d)| match c {
                Counterpart::Body(_) => Some((node, c, d)),
                Counterpart::Wall(w) if w as usize == crate::WALL_BOTTOM => {
                    Some((node, Counterpart::Wall(TEST_WALL_BOTTOM as u32), d))
                }
                Counterpart::Wall(w) if w as usize == crate::WALL_TOP => {
                    Some((node, Counterpart::Wall(TEST_WALL_TOP as u32), d))
                }
                Counterpart::Wall(_) => None,
            })
            .collect();
        if let Some(c) = sim.contact_mut() {
            c.model
                .import_history(&history)
                .map_err(TriaxialError::History)?;
        }
        sim.guard.energy_tolerance = TEST_ENERGY_TOLERANCE;
        sim.rebase_energy().map_err(solver_error("set-up"))?;
        Ok(TestModel {
            sim,
            particles,
            membrane: measuring,
            pressure: pressure_cell,
            membrane_spec,
            top_ring,
            bottom_ring,
            membrane_triangles,
            elements,
        })
    }

    /// Sets the confining pressure on the membrane (Pa) from the next evaluation on.
    pub fn set_pressure(&self, pressure: f64) {
        self.pressure.store(pressure.to_bits(), Ordering::Relaxed);
    }

    /// The confining pressure on the membrane (Pa).
    pub fn pressure(&self) -> f64 {
        f64::from_bits(self.pressure.load(Ordering::Relaxed))
    }

    /// z of a platen now (m).
    pub fn platen_z(&self, wall: usize) -> f64 {
        self.sim
            .contact()
            .and_then(|c| c.model.walls().get(wall).map(|w| w.shape_at(self.sim.time)))
            .map_or(f64::NAN, |s| match s {
                WallShape::Plane { point, .. } => point[2],
                WallShape::Cylinder { .. } => f64::NAN,
            })
    }

    /// Specimen height H: the distance between the platens (m).
    pub fn height(&self) -> f64 {
        self.platen_z(TEST_WALL_TOP) - self.platen_z(TEST_WALL_BOTTOM)
    }

    /// Volume enclosed by the membrane and the platens (m^3), by the divergence theorem.
    pub fn volume(&self) -> f64 {
        self.membrane.enclosed_volume(
            &self.sim.state.positions,
            self.platen_z(TEST_WALL_BOTTOM),
            self.platen_z(TEST_WALL_TOP),
        )
    }

    /// Axial force F_l (N): what the particles push the top platen up with (compression
    /// positive).
    pub fn axial_force(&self) -> f64 {
        self.sim
            .contact()
            .and_then(|c| c.model.wall_forces().get(TEST_WALL_TOP).copied())
            .map_or(0.0, |f| f[2])
    }

    /// Moves the top platen (and the top ring) at `velocity` (m/s along z) from now on.
    pub fn set_top_velocity(&mut self, velocity: f64) -> Result<(), TriaxialError> {
        let time = self.sim.time;
        if let Some(c) = self.sim.contact_mut() {
            c.model
                .set_wall_velocity(TEST_WALL_TOP, [0.0, 0.0, velocity], time)
                .map_err(|e| TriaxialError::Test {
                    phase: "servo",
                    message: e.to_string(),
                })?;
        }
        let z = self.platen_z(TEST_WALL_TOP);
        for &i in &self.top_ring {
            // Re-seat the ring on the platen (removes round-off drift) and give it the
            // platen's velocity.
            self.sim.state.positions[i][2] = z;
            self.sim.state.velocities[i] = [0.0, 0.0, velocity];
        }
        Ok(())
    }

    /// Particles whose centre of mass is outside the closed surface of membrane and platens.
    pub fn particles_outside(&self) -> Vec<usize> {
        let (bottom, top) = (
            self.platen_z(TEST_WALL_BOTTOM),
            self.platen_z(TEST_WALL_TOP),
        );
        let x = &self.sim.state.positions;
        self.sim
            .bodies
            .iter()
            .enumerate()
            .filter(|(_, b)| {
                let centroid = b.motion(&self.sim.state).centroid;
                !self.membrane.contains(x, bottom, top, centroid)
            })
            .map(|(id, _)| id)
            .collect()
    }

    /// The membrane's contact body id.
    pub fn membrane_body(&self) -> u32 {
        self.particles as u32
    }
}
