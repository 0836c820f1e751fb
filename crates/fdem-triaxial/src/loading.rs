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

use crate::membrane::{
    MembraneForces, MembraneMesh, MembraneSpec, TRIANGLES_PER_TASK, membrane_mesh,
};
use crate::{PreparedSpecimen, SpecimenSpec, TriaxialError};
use fdem_contact::{Counterpart, Wall, WallShape};
use fdem_core::geometry::{cross, sub};
use fdem_solver::{
    BodyId, Constraint, ConstraintHandle, ContactSettings, ForceContribution, Guard, Handle,
    ModelBuilder, NodeView, Powers, Scene, SheetBody, Simulation, SimulationSection, SolverError,
    StepBound, TimeStep, VerletWork, WallId, node_span,
};
use rayon::prelude::*;

/// Default starting depth limit of the test's contacts, in contact margins (`[contact]
/// depth_limit` overrides it). The limit grows, up to [`TEST_DEPTH_LIMIT_CAP_DIAMETERS`],
/// when a contact passes half of it or a node moves farther than half of it relative to a
/// particle or platen in one step ([`fdem_contact::ContactModel::set_depth_limit_cap`]),
/// and contacts within half the limit are the same with any larger one, so the start sets
/// the cost, not the result: candidate boxes are enlarged by skin plus depth limit. Half
/// a margin is two skins; measured in docs/TRIAXIAL.md ("A depth limit that grows").
pub const TEST_DEPTH_LIMIT_MARGINS: f64 = 0.5;

/// The largest depth limit of the test's contacts, in smallest particle diameters: a
/// contact deeper than half the depth limit grows the limit up to this cap
/// ([`fdem_contact::ContactModel::set_depth_limit_cap`]) instead of stopping the run.
/// Vertex contacts press deeper in binary mixtures (a small particle's vertex against a
/// large one's face) and with exact scaling's softer penalty than the margin-based
/// default allows (docs/TRIAXIAL.md, "Contact depth limit"). A quarter diameter keeps the
/// window far below a particle's thickness, so the nearest face behind a node is still
/// the one it crossed, and lets contacts reach an eighth of the diameter.
pub const TEST_DEPTH_LIMIT_CAP_DIAMETERS: f64 = 0.25;

/// The test's Verlet skin (the contact model's margin: rebuild distance and tunnelling
/// scale against the membrane), in specimen contact margins. Candidate boxes are enlarged by skin plus depth
/// limit, and the narrow phase's cost grows faster than that enlargement: a thin skin
/// pays for the deeper depth limit, keeping the candidate pairs near those of a skin and
/// depth limit of one margin each (docs/TRIAXIAL.md, "Contact depth limit", has the
/// candidate counts and step costs). The particles move a quarter margin in thousands
/// of steps, so the extra rebuilds cost little.
pub const TEST_SKIN_FRACTION: f64 = 0.25;

/// Depth, in specimen contact margins, beyond which a particle node found behind the
/// membrane is a fold artefact and discarded (`fdem_contact::ContactModel::set_sheet_bodies`).
pub const TEST_FOLD_DEPTH_MARGINS: f64 = 0.5;

/// Density of the cell fluid (water, kg/m^3) behind the default added mass.
pub const WATER_DENSITY: f64 = 1000.0;

/// Wall index of the bottom platen in the test's contact model (fixed).
pub const TEST_WALL_BOTTOM: WallId = WallId(0);
/// Wall index of the top platen (driven).
pub const TEST_WALL_TOP: WallId = WallId(1);
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
/// `-sum f . v`, as external power. A constraint, so it sees the whole force on its nodes.
#[derive(Debug)]
pub struct RingHold {
    nodes: Vec<usize>,
    /// [`node_span`] of `nodes`.
    span: std::ops::Range<usize>,
}

impl Constraint for RingHold {
    fn name(&self) -> &str {
        "membrane rings"
    }

    fn apply(
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

    fn node_range(&self) -> Option<std::ops::Range<usize>> {
        Some(self.span.clone())
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
/// power is booked as damping, with the velocity-Verlet correction ([`VerletWork`]): for a
/// damping force as stiff as the limiter it is tens of percent of the dissipation.
#[derive(Debug)]
pub struct MembraneDamping {
    nodes: Vec<usize>,
    /// [`node_span`] of `nodes`.
    span: std::ops::Range<usize>,
    /// `c A` per node (N s/m).
    linear: Vec<f64>,
    /// Speed above which the limiter acts (m/s).
    speed_limit: f64,
    work: VerletWork,
    /// Per node its force's x and y (N), and their power with the Verlet correction, at
    /// the state of time `.2` ([`ForceContribution::prepare`]; scratch).
    prepared: (Vec<[f64; 2]>, f64, Option<f64>),
}

impl MembraneDamping {
    /// The damping forces at `nodes` into `prepared.0`, and their power, booked with the
    /// Verlet correction held for [`VerletWork::commit`] at `nodes.time`.
    fn evaluate(&mut self, nodes: NodeView<'_>) -> f64 {
        self.work.ensure(self.nodes.len());
        self.work.hold(nodes.time);
        let out = &mut self.prepared.0;
        out.resize(self.nodes.len(), [0.0; 2]);
        let mut power = 0.0;
        for (k, &i) in self.nodes.iter().enumerate() {
            let v = nodes.velocities[i];
            let speed = v[0].hypot(v[1]);
            let mut c = self.linear[k];
            if speed > self.speed_limit {
                let limiter = 0.5 * nodes.masses[i] / nodes.dt;
                c += limiter * (speed - self.speed_limit) / speed;
            }
            let f = [-c * v[0], -c * v[1], 0.0];
            // The correction is work done on the nodes: dissipation is its negative.
            power -= self.work.held_correction(k, f, [v[0], v[1], 0.0]);
            out[k] = [f[0], f[1]];
            power += c * speed * speed;
        }
        power
    }
}

impl ForceContribution for MembraneDamping {
    fn name(&self) -> &str {
        "membrane damping"
    }

    fn node_range(&self) -> Option<std::ops::Range<usize>> {
        Some(self.span.clone())
    }

    /// Explicit damping is stable while `(c A + c_lim A) dt / m < 2`; with the limiter at
    /// `c_lim A = m / (2 dt)` that is `dt < 3 m / (2 c A)` on every damped node.
    fn stable_time_step(&self, masses: &[f64]) -> Option<StepBound> {
        self.nodes
            .iter()
            .zip(&self.linear)
            .filter(|(_, c)| **c > 0.0)
            .map(|(&i, &c)| (i, 1.5 * masses[i] / c))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, dt)| StepBound {
                dt,
                source: format!("membrane damping: node {i} (lower membrane.damping)"),
            })
    }

    /// The forces and their power, beside the contact detection: `add_forces` only adds
    /// them.
    fn prepare(&mut self, nodes: NodeView<'_>) -> Result<(), SolverError> {
        self.prepared.1 = self.evaluate(nodes);
        self.prepared.2 = Some(nodes.time);
        Ok(())
    }

    fn add_forces(
        &mut self,
        nodes: NodeView<'_>,
        forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError> {
        let power = match self.prepared.2.take() {
            Some(time) if time == nodes.time => self.prepared.1,
            _ => self.evaluate(nodes),
        };
        self.work.commit(nodes.time);
        for (&i, f) in self.nodes.iter().zip(&self.prepared.0) {
            forces[i][0] += f[0];
            forces[i][1] += f[1];
        }
        Ok(Powers {
            damping: power,
            ..Powers::default()
        })
    }

    fn potential_energy(&self, _nodes: NodeView<'_>) -> f64 {
        0.0
    }

    fn checkpoint(&self) -> Vec<f64> {
        self.work.to_numbers()
    }

    fn restore_checkpoint(&mut self, values: &[f64]) -> Result<(), SolverError> {
        self.prepared.2 = None;
        self.work.restore_numbers(values)
    }
}

/// The membrane's forces (elastic sheet and follower pressure) with the pressure the test
/// driver sets between steps ([`TestModel::set_pressure`]).
///
/// The follower pressure is not conservative, so its work is booked from its power, with
/// the velocity-Verlet correction ([`VerletWork`]): on light membrane nodes that oscillate
/// in contact the uncorrected booking accumulates to percents of the pressure work.
#[derive(Debug)]
pub struct PressurisedMembrane {
    inner: MembraneForces,
    triangles: Vec<[usize; 3]>,
    work: VerletWork,
    /// Pressure forces of the current evaluation per membrane node (scratch).
    scratch: Vec<[f64; 3]>,
    /// `(b - a) x (c - a)` of every triangle of the current evaluation (scratch).
    areas: Vec<[f64; 3]>,
    /// The pressure's Verlet correction (W) at the state of time `.1`, from
    /// [`ForceContribution::prepare`] ([`PressurisedMembrane::corrections`]).
    correction: (f64, Option<f64>),
}

impl PressurisedMembrane {
    fn new(inner: MembraneForces) -> Self {
        let triangles = inner.triangles().to_vec();
        PressurisedMembrane {
            inner,
            triangles,
            work: VerletWork::default(),
            scratch: Vec::new(),
            areas: Vec::new(),
            correction: (0.0, None),
        }
    }

    /// The membrane's geometry and forces.
    pub fn membrane(&self) -> &MembraneForces {
        &self.inner
    }

    /// `(b - a) x (c - a)` of every triangle at `nodes`, in parallel over triangles.
    fn evaluate_areas(&mut self, nodes: NodeView<'_>) {
        let first = self.inner.first_node();
        let x = nodes.positions;
        self.areas.resize(self.triangles.len(), [0.0; 3]);
        self.areas
            .par_iter_mut()
            .zip(self.triangles.par_iter())
            .with_min_len(TRIANGLES_PER_TASK)
            .for_each(|(area, t)| {
                let [a, b, c] = t.map(|i| x[i + first]);
                *area = cross(sub(b, a), sub(c, a));
            });
    }

    /// The pressure forces at `nodes` ([`PressurisedMembrane::pressure_forces`]) and the
    /// Verlet correction of their work (W), summed node by node, held for
    /// [`VerletWork::commit`] at `nodes.time`.
    fn corrections(&mut self, nodes: NodeView<'_>) -> f64 {
        self.pressure_forces(nodes);
        let first = self.inner.first_node();
        self.work.ensure(self.scratch.len());
        self.work.hold(nodes.time);
        let mut correction = 0.0;
        for (j, f) in self.scratch.iter().enumerate() {
            correction += self
                .work
                .held_correction(j, *f, nodes.velocities[j + first]);
        }
        correction
    }

    /// The pressure forces alone at `nodes`: the membrane adds `p a_in / 3` to each corner,
    /// `a_in = (b - a) x (c - a) / 2`; summed node by node in triangle order.
    fn pressure_forces(&mut self, nodes: NodeView<'_>) {
        self.evaluate_areas(nodes);
        let (n, p) = (self.inner.n_nodes(), self.inner.pressure());
        self.scratch.clear();
        self.scratch.resize(n, [0.0; 3]);
        let (areas, incidence) = (&self.areas, self.inner.incidence());
        incidence.for_each_node(&mut self.scratch, |i, f| {
            for &(t, _) in incidence.of(i) {
                for (f, a) in f.iter_mut().zip(&areas[t as usize]) {
                    *f += p * a / 6.0;
                }
            }
        });
    }
}

impl ForceContribution for PressurisedMembrane {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn stable_time_step(&self, masses: &[f64]) -> Option<StepBound> {
        self.inner.stable_time_step(masses)
    }

    /// The membrane's corner forces and the pressure's Verlet correction, beside the
    /// contact detection.
    fn prepare(&mut self, nodes: NodeView<'_>) -> Result<(), SolverError> {
        self.inner.prepare(nodes)?;
        self.correction = (self.corrections(nodes), Some(nodes.time));
        Ok(())
    }

    fn node_range(&self) -> Option<std::ops::Range<usize>> {
        self.inner.node_range()
    }

    fn add_forces(
        &mut self,
        nodes: NodeView<'_>,
        forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError> {
        // A preparation holds while the membrane's does (a new pressure drops both).
        let prepared =
            self.correction.1.take() == Some(nodes.time) && self.inner.prepared_at(nodes.time);
        let mut powers = self.inner.add_forces(nodes, forces)?;
        let correction = if prepared {
            self.correction.0
        } else {
            self.corrections(nodes)
        };
        self.work.commit(nodes.time);
        powers.external += correction;
        Ok(powers)
    }

    fn potential_energy(&self, nodes: NodeView<'_>) -> f64 {
        self.inner.potential_energy(nodes)
    }

    fn checkpoint(&self) -> Vec<f64> {
        self.work.to_numbers()
    }

    fn restore_checkpoint(&mut self, values: &[f64]) -> Result<(), SolverError> {
        self.correction.1 = None;
        self.inner.forget_preparation();
        self.work.restore_numbers(values)
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
        added_mass: spec
            .membrane
            .added_mass
            .unwrap_or(0.5 * WATER_DENSITY * spec.inner_radius()),
    }
}

/// The assembled test: the simulation and what the test needs to drive and measure it.
pub struct TestModel {
    /// The simulation (particles, membrane, platens).
    pub sim: Simulation,
    /// Number of particles (bodies 0..n; the membrane is body n).
    pub particles: usize,
    /// The membrane body.
    membrane_body: BodyId,
    /// The membrane's forces under the confining pressure.
    membrane: Handle<PressurisedMembrane>,
    /// The membrane's end rings held on the platens.
    rings: ConstraintHandle<RingHold>,
    /// Membrane specification.
    pub membrane_spec: MembraneSpec,
    /// Global ids of the top ring's nodes (they move with the top platen).
    pub top_ring: Vec<usize>,
    /// Global ids of the bottom ring's nodes (fixed).
    pub bottom_ring: Vec<usize>,
    /// Membrane triangles with global node ids (for output frames).
    pub membrane_triangles: Vec<[usize; 3]>,
    /// Elements of the particles.
    pub elements: usize,
}

/// The scene of the test's particles: as prepared, with the test's material and contact.
fn particle_scene(prepared: &PreparedSpecimen) -> Result<Scene, TriaxialError> {
    let simulated = prepared.spec.simulated()?;
    Ok(Scene {
        simulation: SimulationSection {
            duration: 1.0,
            dt: None,
            dt_safety: None,
            output_interval: None,
            gravity: None,
            energy_tolerance: None,
            // The particles sit at their reference placements here and start from a
            // restored state (the preparation checks its packing itself).
            allow_initial_overlap: true,
        },
        material: simulated.material.clone(),
        particles: prepared.particle_sections()?,
        contact: Some(simulated.contact.clone()),
        walls: Vec::new(),
        auto: None,
    })
}

/// The test's contact settings: the scene's law and margin, from which the specimen's
/// margin sets the test's lengths (a thinner Verlet skin, a deeper depth limit unless
/// `[contact] depth_limit` is given, the membrane's fold depth), and the depth limit's
/// cap from the `smallest` particle diameter (m).
fn test_contact(
    scene: &Scene,
    model: &ModelBuilder,
    smallest: f64,
) -> Result<ContactSettings, TriaxialError> {
    let base = scene
        .contact_settings(model)
        .map_err(solver_error("set-up"))?;
    let margin = base.margin;
    Ok(ContactSettings {
        margin: TEST_SKIN_FRACTION * margin,
        depth_limit: Some(
            base.depth_limit
                .unwrap_or(TEST_DEPTH_LIMIT_MARGINS * margin),
        ),
        depth_limit_cap: Some(TEST_DEPTH_LIMIT_CAP_DIAMETERS * smallest),
        sheet_fold_depth: Some(TEST_FOLD_DEPTH_MARGINS * margin),
        ..base
    })
}

/// The membrane's mesh and body: masses (its own and the cell fluid's added mass on each
/// node's area), faces towards the axis.
fn membrane_body(ms: &MembraneSpec, mesh: &MembraneMesh) -> SheetBody {
    SheetBody {
        positions: mesh.positions.clone(),
        masses: mesh.lumped_masses(ms),
        triangles: mesh.triangles.clone(),
        control_areas: mesh.control_areas(),
    }
}

/// The cell fluid's damping of the free (non-ring) membrane nodes.
fn membrane_damping(spec: &SpecimenSpec, mesh: &MembraneMesh, first: usize) -> MembraneDamping {
    let areas = mesh.control_areas();
    let damped: Vec<usize> = (0..mesh.positions.len())
        .filter(|&i| !mesh.is_ring_node(i))
        .collect();
    let nodes: Vec<usize> = damped.iter().map(|i| i + first).collect();
    MembraneDamping {
        linear: damped
            .iter()
            .map(|&i| spec.membrane.damping * areas[i])
            .collect(),
        span: node_span(&nodes),
        nodes,
        speed_limit: spec
            .membrane
            .speed_limit
            .unwrap_or_else(|| spec.loading_velocity()),
        work: VerletWork::default(),
        prepared: (Vec::new(), 0.0, None),
    }
}

impl TestModel {
    /// Builds the test around a prepared specimen: the particles as prepared (state,
    /// friction history against particles and platens), the test's contact law, the
    /// membrane under the confining pressure, the platens fixed where preparation left
    /// them, and the step `dt` (unless given, `test.dt_safety` times the stable bound of
    /// the assembled test: the particles' assembled elastic bound combined with the contact
    /// springs, or the membrane's bound if smaller).
    pub fn build(prepared: &PreparedSpecimen, dt: Option<f64>) -> Result<TestModel, TriaxialError> {
        let spec = &prepared.spec;
        let scene = particle_scene(prepared)?;
        let mut model = ModelBuilder::new();
        scene
            .add_particles(&mut model)
            .map_err(solver_error("set-up"))?;
        let (particles, n_particle_nodes) = (model.n_bodies(), model.n_nodes());
        let contact = test_contact(&scene, &model, spec.smallest_simulated_size())?;
        let bottom = model.add_wall(Wall::plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]));
        let top = model.add_wall(Wall::plane([0.0, 0.0, spec.height], [0.0, 0.0, -1.0]));
        debug_assert_eq!((bottom, top), (TEST_WALL_BOTTOM, TEST_WALL_TOP));
        model.set_contact(contact);

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
        let mesh = membrane_mesh(&membrane_spec).map_err(|e| setup(e.to_string()))?;
        let membrane_body = model
            .add_sheet(membrane_body(&membrane_spec, &mesh))
            .map_err(solver_error("set-up"))?;
        let first = n_particle_nodes;
        let forces = MembraneForces::new(&mesh, &membrane_spec, first, spec.confining_pressure)
            .map_err(|e| setup(e.to_string()))?;
        let membrane = model.add_contribution(PressurisedMembrane::new(forces));
        model.add_contribution(membrane_damping(spec, &mesh, first));
        let global = |ids: &[usize]| ids.iter().map(|i| i + first).collect::<Vec<_>>();
        let (top_ring, bottom_ring) = (global(&mesh.top_ring), global(&mesh.bottom_ring));
        let ring_nodes: Vec<usize> = bottom_ring.iter().chain(&top_ring).copied().collect();
        let rings = model.add_constraint(RingHold {
            span: node_span(&ring_nodes),
            nodes: ring_nodes,
        });
        model.set_time_step(match dt {
            Some(dt) => TimeStep::Fixed(dt),
            None => TimeStep::Automatic {
                safety: spec.test.dt_safety(),
            },
        });
        // The solver's guard as in every run: the driver starts a new window of the
        // balance at every output row and accumulates the phase's balance, reported in
        // `curve.csv` and `summary.json` (docs/TRIAXIAL.md, "Energy balance").
        model.set_guard(Guard::default());
        let elements = model.n_elements();
        let sim = model.build().map_err(solver_error("set-up"))?;
        if sim.bound().dt < sim.dt() {
            return Err(setup(format!(
                "the step {:e} s exceeds the stable bound {:e} s set by {}; \
                 refine nothing: lower the step (or soften the membrane or the contact)",
                sim.dt(),
                sim.bound().dt,
                sim.bound().source
            )));
        }
        let mut model = TestModel {
            sim,
            particles,
            membrane_body,
            membrane,
            rings,
            membrane_spec,
            top_ring,
            bottom_ring,
            membrane_triangles: mesh
                .triangles
                .iter()
                .map(|t| t.map(|i| i + first))
                .collect(),
            elements,
        };
        model.restore_prepared(prepared, n_particle_nodes)?;
        Ok(model)
    }

    /// The prepared state: particle nodes, rigid particles' poses and momenta, and friction history against particles and the
    /// platens (preparation walls 1 and 2 are the test's walls 0 and 1); the test's clock
    /// and step count start at zero, and the energy balance from this state.
    fn restore_prepared(
        &mut self,
        prepared: &PreparedSpecimen,
        n_particle_nodes: usize,
    ) -> Result<(), TriaxialError> {
        let snapshot = &prepared.state;
        if snapshot.positions.len() != n_particle_nodes {
            return Err(setup(format!(
                "the prepared state has {} nodes but the particles {n_particle_nodes}",
                snapshot.positions.len()
            )));
        }
        snapshot.place_particles(&mut self.sim)?;
        let history: Vec<_> = snapshot
            .history
            .iter()
            .filter_map(|&(node, c, d)| match c {
                Counterpart::Body(_) => Some((node, c, d)),
                Counterpart::Wall(w) if w as usize == crate::WALL_BOTTOM => {
                    Some((node, Counterpart::Wall(TEST_WALL_BOTTOM.0 as u32), d))
                }
                Counterpart::Wall(w) if w as usize == crate::WALL_TOP => {
                    Some((node, Counterpart::Wall(TEST_WALL_TOP.0 as u32), d))
                }
                Counterpart::Wall(_) => None,
            })
            .collect();
        if let Some(c) = self.sim.contact_mut() {
            c.model_mut()
                .import_history(&history)
                .map_err(TriaxialError::History)?;
        }
        self.sim.rebase_energy().map_err(solver_error("set-up"))
    }

    /// The membrane's geometry and forces (volume, containment, node range).
    pub fn membrane(&self) -> &MembraneForces {
        self.sim.get(self.membrane).membrane()
    }

    /// The constraint that holds the membrane's rings.
    pub fn rings(&self) -> &RingHold {
        self.sim.constraint(self.rings)
    }

    /// Sets the confining pressure on the membrane (Pa) from the next evaluation on.
    pub fn set_pressure(&mut self, pressure: f64) {
        self.sim.get_mut(self.membrane).inner.set_pressure(pressure);
    }

    /// The confining pressure on the membrane (Pa).
    pub fn pressure(&self) -> f64 {
        self.membrane().pressure()
    }

    /// z of a platen now (m).
    pub fn platen_z(&self, wall: WallId) -> f64 {
        self.sim
            .contact()
            .and_then(|c| {
                c.model()
                    .walls()
                    .get(wall.0)
                    .map(|w| w.shape_at(self.sim.time()))
            })
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
        self.membrane().enclosed_volume(
            &self.sim.state().positions,
            self.platen_z(TEST_WALL_BOTTOM),
            self.platen_z(TEST_WALL_TOP),
        )
    }

    /// The volume by which the membrane drapes into the surface voids, with envelope
    /// window `window` (m^3; [`crate::MembraneForces::draped_volume`]).
    pub fn draped_volume(&self, window: f64) -> f64 {
        self.membrane().draped_volume(
            &self.sim.state().positions,
            self.platen_z(TEST_WALL_BOTTOM),
            self.platen_z(TEST_WALL_TOP),
            window,
        )
    }

    /// Axial force F_l (N): what the particles push the top platen up with (compression
    /// positive).
    pub fn axial_force(&self) -> f64 {
        self.sim
            .contact()
            .and_then(|c| c.model().wall_forces().get(TEST_WALL_TOP.0).copied())
            .map_or(0.0, |f| f[2])
    }

    /// Moves the top platen (and the top ring) at `velocity` (m/s along z) from now on.
    pub fn set_top_velocity(&mut self, velocity: f64) -> Result<(), TriaxialError> {
        let time = self.sim.time();
        if let Some(c) = self.sim.contact_mut() {
            c.model_mut()
                .set_wall_velocity(TEST_WALL_TOP.0, [0.0, 0.0, velocity], time)
                .map_err(|e| TriaxialError::Test {
                    phase: "servo",
                    message: e.to_string(),
                })?;
        }
        let z = self.platen_z(TEST_WALL_TOP);
        let nodes = self.sim.nodes_mut();
        for &i in &self.top_ring {
            // Re-seat the ring on the platen (removes round-off drift) and give it the
            // platen's velocity.
            nodes.positions[i][2] = z;
            nodes.velocities[i] = [0.0, 0.0, velocity];
        }
        self.follow_platens()
    }

    /// Tells the contact model the specimen's mean motion, the axial squeeze the top
    /// platen imposes at its present velocity about the fixed bottom platen, so that its
    /// broad phase measures the nodes' drift from that motion
    /// (`fdem_contact::ContactModel::set_mean_motion`; the contacts do not depend on it).
    /// Called whenever the platen's velocity is set and after a restored state.
    pub(crate) fn follow_platens(&mut self) -> Result<(), TriaxialError> {
        let time = self.sim.time();
        let (bottom, height) = (self.platen_z(TEST_WALL_BOTTOM), self.height());
        let Some(c) = self.sim.contact_mut() else {
            return Ok(());
        };
        let velocity = c.model().walls()[TEST_WALL_TOP.0].velocity[2];
        let mut rate = [[0.0; 3]; 3];
        rate[2][2] = velocity / height;
        c.model_mut()
            .set_mean_motion([0.0, 0.0, bottom], rate, time)
            .map_err(|e| TriaxialError::Test {
                phase: "servo",
                message: e.to_string(),
            })
    }

    /// Particles whose centre of mass is outside the closed surface of membrane and platens.
    pub fn particles_outside(&self) -> Vec<usize> {
        let (bottom, top) = (
            self.platen_z(TEST_WALL_BOTTOM),
            self.platen_z(TEST_WALL_TOP),
        );
        let x = &self.sim.state().positions;
        let membrane = self.membrane();
        // Centroids nearer the axis than the membrane comes in their sector and layer are
        // inside (`ClearRegion::holds`): one winding number stands for all of them. The
        // others get one each, in parallel (`collect` keeps the particles' order).
        let clear = membrane.clear_region(x, bottom, top);
        let particles: Vec<(usize, [f64; 3])> = self
            .sim
            .particles()
            .map(|(id, b)| (id, b.motion(self.sim.state()).centroid))
            .filter(|(_, c)| !clear.as_ref().is_some_and(|r| r.holds(*c)))
            .collect();
        particles
            .into_par_iter()
            .filter(|(_, c)| !membrane.contains(x, bottom, top, *c))
            .map(|(id, _)| id)
            .collect()
    }

    /// The membrane's contact body id.
    pub fn membrane_body(&self) -> u32 {
        self.membrane_body.0 as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::membrane::NODES_PER_TASK;

    fn test_membrane_spec() -> MembraneSpec {
        MembraneSpec {
            radius: 0.05,
            bottom: 0.1,
            top: 0.3,
            divisions_around: 40,
            divisions_along: 30,
            thickness: 0.002,
            youngs_modulus: 1e6,
            poisson_ratio: 0.4,
            density: 1100.0,
            added_mass: 0.0,
        }
    }

    /// The state of step `step`: every node moved and moving a little differently.
    fn state_of(base: &[[f64; 3]], step: usize) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let a = |i: usize, k: usize, s: f64| ((3 * i + k) as f64 * 0.37 + s).sin();
        let s = step as f64;
        let x = (base.iter().enumerate())
            .map(|(i, x)| std::array::from_fn(|k| x[k] + 1e-3 * a(i, k, s)))
            .collect();
        let v = (0..base.len())
            .map(|i| std::array::from_fn(|k| 0.2 * a(i, k, 2.0 * s + 1.0)))
            .collect();
        (x, v)
    }

    /// Steps `contribution` through four states, with a preparation before each
    /// `add_forces` when `prepare` says so (at the third state, a preparation for another
    /// state and time instead, which must not be used); returns every force, power and
    /// checkpoint number as bits.
    fn run_steps(
        contribution: &mut dyn ForceContribution,
        base: &[[f64; 3]],
        prepare: bool,
    ) -> Vec<u64> {
        let masses = vec![0.01; base.len()];
        let mut out = Vec::new();
        for step in 0..4 {
            let (x, v) = state_of(base, step);
            let time = step as f64 * 1e-6;
            let view = |time: f64| NodeView {
                positions: &x,
                velocities: &v,
                masses: &masses,
                time,
                dt: 1e-6,
            };
            if prepare && step == 2 {
                let (x2, v2) = state_of(base, 7);
                let other = NodeView {
                    positions: &x2,
                    velocities: &v2,
                    ..view(time + 0.5)
                };
                contribution.prepare(other).unwrap();
            } else if prepare {
                contribution.prepare(view(time)).unwrap();
            }
            let mut forces = vec![[0.5; 3]; base.len()];
            let p = contribution.add_forces(view(time), &mut forces).unwrap();
            out.extend(forces.iter().flatten().map(|f| f.to_bits()));
            out.extend([p.external, p.damping, p.friction_energy].map(f64::to_bits));
            out.extend(contribution.checkpoint().iter().map(|c| c.to_bits()));
        }
        out
    }

    /// The membrane's damping and its pressurised sheet give the same forces, powers
    /// and booked Verlet work, bit for bit, whether their `prepare` ran before each
    /// `add_forces` or not; a preparation for another state is not used.
    #[test]
    fn prepared_membrane_contributions_equal_those_computed_on_the_spot() {
        let spec = test_membrane_spec();
        let mesh = membrane_mesh(&spec).unwrap();
        let first = 2;
        let base: Vec<[f64; 3]> = [[0.0; 3]; 2]
            .into_iter()
            .chain(mesh.positions.clone())
            .collect();
        let pressurised =
            || PressurisedMembrane::new(MembraneForces::new(&mesh, &spec, first, 2e5).unwrap());
        let nodes: Vec<usize> = (first..base.len()).collect();
        let damping = || MembraneDamping {
            linear: nodes.iter().map(|&i| 0.3 + 0.01 * (i % 7) as f64).collect(),
            span: node_span(&nodes),
            nodes: nodes.clone(),
            // Some nodes above the limit, some below.
            speed_limit: 0.15,
            work: VerletWork::default(),
            prepared: (Vec::new(), 0.0, None),
        };
        let spot = run_steps(&mut pressurised(), &base, false);
        assert_eq!(spot, run_steps(&mut pressurised(), &base, true));
        let spot = run_steps(&mut damping(), &base, false);
        assert_eq!(spot, run_steps(&mut damping(), &base, true));
    }

    /// A new pressure after a preparation drops it: the forces and the booking are those
    /// of the new pressure.
    #[test]
    fn a_pressure_set_after_a_preparation_is_the_one_booked() {
        let spec = test_membrane_spec();
        let mesh = membrane_mesh(&spec).unwrap();
        let make = || PressurisedMembrane::new(MembraneForces::new(&mesh, &spec, 0, 2e5).unwrap());
        let (x, v) = state_of(&mesh.positions, 1);
        let masses = vec![0.01; x.len()];
        let view = NodeView {
            positions: &x,
            velocities: &v,
            masses: &masses,
            time: 1e-6,
            dt: 1e-6,
        };
        let run = |membrane: &mut PressurisedMembrane, prepare: bool| {
            // A first step books forces for the correction of the second.
            let mut forces = vec![[0.0; 3]; x.len()];
            membrane
                .add_forces(NodeView { time: 0.0, ..view }, &mut forces)
                .unwrap();
            if prepare {
                membrane.prepare(view).unwrap();
            }
            membrane.inner.set_pressure(3e5);
            let p = membrane.add_forces(view, &mut forces).unwrap();
            let mut bits: Vec<u64> = forces.iter().flatten().map(|f| f.to_bits()).collect();
            bits.push(p.external.to_bits());
            bits.extend(membrane.checkpoint().iter().map(|c| c.to_bits()));
            bits
        };
        assert_eq!(run(&mut make(), false), run(&mut make(), true));
    }

    /// The pressure forces of the work booking, summed node by node in parallel tasks,
    /// have the bits of a serial pass over the triangles in order.
    #[test]
    fn pressure_forces_node_by_node_equal_the_serial_pass_over_the_triangles() {
        let spec = MembraneSpec {
            radius: 0.05,
            bottom: 0.1,
            top: 0.3,
            divisions_around: 100,
            divisions_along: 100,
            thickness: 0.002,
            youngs_modulus: 1e6,
            poisson_ratio: 0.4,
            density: 1100.0,
            added_mass: 0.0,
        };
        let mesh = membrane_mesh(&spec).unwrap();
        let (first, pressure) = (3, 2.5e5);
        let inner = MembraneForces::new(&mesh, &spec, first, pressure).unwrap();
        let mut membrane = PressurisedMembrane::new(inner);
        let wobble = |i: usize, k: usize| 1e-3 * ((3 * i + k) as f64 * 0.37).sin();
        let positions: Vec<[f64; 3]> = (0..first)
            .map(|i| [i as f64; 3])
            .chain(
                (mesh.positions.iter().enumerate())
                    .map(|(i, x)| std::array::from_fn(|k| x[k] + wobble(i, k))),
            )
            .collect();
        let velocities = vec![[0.0; 3]; positions.len()];
        let masses = vec![1.0; positions.len()];
        membrane.pressure_forces(NodeView {
            positions: &positions,
            velocities: &velocities,
            masses: &masses,
            time: 0.0,
            dt: 0.0,
        });
        let mut reference = vec![[0.0; 3]; mesh.positions.len()];
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| positions[first + i]);
            let area = cross(sub(b, a), sub(c, a));
            for &i in t {
                for (f, a) in reference[i].iter_mut().zip(&area) {
                    *f += pressure * a / 6.0;
                }
            }
        }
        let bits =
            |f: &[[f64; 3]]| -> Vec<u64> { f.iter().flatten().map(|x| x.to_bits()).collect() };
        assert!(mesh.positions.len() > 4 * NODES_PER_TASK);
        assert_eq!(bits(&membrane.scratch), bits(&reference));
    }
}
