//! The model builder: the one way a [`Simulation`] is assembled, by scenes and by drivers
//! such as the triaxial test alike.
//!
//! A model is a list of bodies of several kinds ([`BodyKind`]), each a contiguous range
//! of nodes added in order, plus what acts on them: the elastic elements of deformable
//! bodies, contact (surfaces, walls, the law), force contributions and constraints.
//! Adding a contribution or a constraint returns a typed handle through which the driver
//! reaches it between steps ([`Simulation::get_mut`]). [`ModelBuilder::build`] computes
//! the element sets and lumped masses, the stable bound and the step, and the initial
//! forces.

use crate::engine::{Assembled, Guard, Parts, Simulation, TimeStep};
use crate::forces::{Constraint, ElasticForces, ElementInput, ForceContribution, StepBound};
use crate::rigid::{RigidPart, TemplateMap};
use crate::{
    Body, BodyKind, Connectivity, ContactForces, NodeState, RigidInertia, RigidState, SolverError,
};
use fdem_contact::{ContactModel, ContactParams, ContactSurface, RigidTemplate, Wall};
use fdem_elastic::Material;
use fdem_mesh::{MeshAssembly, Placement, TetMesh};
use std::marker::PhantomData;

/// Identifies a body of a model: its index in [`Simulation::bodies`], also its owner id
/// on the contact surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct BodyId(pub usize);

/// Identifies a wall of a model: its index in the contact model's walls.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct WallId(pub usize);

/// A typed handle to a force contribution of a model ([`ModelBuilder::add_contribution`]).
pub struct Handle<T> {
    index: usize,
    kind: PhantomData<fn() -> T>,
}

/// A typed handle to a constraint of a model ([`ModelBuilder::add_constraint`]).
pub struct ConstraintHandle<T> {
    index: usize,
    kind: PhantomData<fn() -> T>,
}

macro_rules! handle_impls {
    ($name:ident) => {
        impl<T> $name<T> {
            fn new(index: usize) -> Self {
                $name {
                    index,
                    kind: PhantomData,
                }
            }

            pub(crate) fn index(self) -> usize {
                self.index
            }
        }

        impl<T> Clone for $name<T> {
            fn clone(&self) -> Self {
                *self
            }
        }

        impl<T> Copy for $name<T> {}

        impl<T> std::fmt::Debug for $name<T> {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "{}({})", stringify!($name), self.index)
            }
        }

        impl<T> PartialEq for $name<T> {
            fn eq(&self, other: &Self) -> bool {
                self.index == other.index
            }
        }

        impl<T> Eq for $name<T> {}
    };
}

handle_impls!(Handle);
handle_impls!(ConstraintHandle);

/// Initial rigid motion of a body: the velocity of its centre and its angular velocity
/// about that centre.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct InitialMotion {
    /// Velocity of the centre (m/s).
    pub velocity: [f64; 3],
    /// Angular velocity (rad/s).
    pub angular_velocity: [f64; 3],
}

impl InitialMotion {
    /// The velocity of the point `x` of a body moving with this motion about `centre`:
    /// `v + omega x (x - centre)` (m/s).
    pub fn velocity_at(&self, x: [f64; 3], centre: [f64; 3]) -> [f64; 3] {
        fdem_core::geometry::rigid_velocity(self.velocity, self.angular_velocity, centre, x)
    }
}

/// A sheet body ([`BodyKind::Sheet`]): nodes with masses and outward contact faces, no
/// tetrahedra. Its in-plane forces are a contribution of the caller's.
#[derive(Clone, Debug, PartialEq)]
pub struct SheetBody {
    /// Node positions (m), which are also the reference positions.
    pub positions: Vec<[f64; 3]>,
    /// Lumped node masses (kg), > 0.
    pub masses: Vec<f64>,
    /// Contact faces, body-local node ids, ordered so that their normal points to the
    /// side the particles touch.
    pub triangles: Vec<[usize; 3]>,
    /// Control area of every node for the contact stiffness (m^2), > 0.
    pub control_areas: Vec<f64>,
}

/// How contact is modelled: the law, the lengths of detection, and the depth at which a
/// node behind a sheet is a fold artefact.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactSettings {
    /// The penalty law (docs/MODEL.md section 2).
    pub params: ContactParams,
    /// The contact margin (m): Verlet skin of the broad phase and tunnelling scale against
    /// sheets (against solids it is the depth limit).
    pub margin: f64,
    /// How far behind a face the narrow phase looks (m); `None` keeps the margin.
    pub depth_limit: Option<f64>,
    /// The largest depth limit a too deep contact may grow it to (m); `None` keeps it
    /// fixed ([`fdem_contact::ContactModel::set_depth_limit_cap`]).
    pub depth_limit_cap: Option<f64>,
    /// Depth behind a sheet (m) beyond which a particle node's hit is a fold artefact and
    /// discarded; required when the model has sheet bodies.
    pub sheet_fold_depth: Option<f64>,
}

/// Collects the bodies and everything acting on them, then builds the [`Simulation`].
pub struct ModelBuilder {
    reference: Vec<[f64; 3]>,
    velocities: Vec<[f64; 3]>,
    /// Lumped masses; deformable bodies' entries are filled in by [`ModelBuilder::build`].
    masses: Vec<f64>,
    bodies: Vec<Body>,
    elements: Vec<ElementInput>,
    connectivity: Connectivity,
    surface: ContactSurface,
    walls: Vec<Wall>,
    contact: Option<ContactSettings>,
    rigid: Vec<RigidPart>,
    /// The rigid bodies' templates, each once (`RigidPart::template` indexes them).
    rigid_templates: Templates,
    parts: Parts,
    gravity: [f64; 3],
    time_step: TimeStep,
    guard: Guard,
}

/// Distinct rigid templates, found again by their content.
#[derive(Default)]
struct Templates {
    list: Vec<RigidTemplate>,
    /// Indices into `list` by a hash of the template's bits.
    by_hash: std::collections::HashMap<u64, Vec<usize>>,
}

impl Templates {
    /// The index of `template`, added if it is new.
    fn intern(&mut self, template: RigidTemplate) -> usize {
        let mut h = fdem_core::hash::Fnv1a::new();
        for x in template.nodes.iter().flatten() {
            h.update(&x.to_bits().to_le_bytes());
        }
        for i in template.triangles.iter().flatten() {
            h.update(&(*i as u64).to_le_bytes());
        }
        let same = self.by_hash.entry(h.0).or_default();
        if let Some(&k) = same.iter().find(|&&k| self.list[k] == template) {
            return k;
        }
        same.push(self.list.len());
        self.list.push(template);
        self.list.len() - 1
    }
}

impl Default for ModelBuilder {
    fn default() -> Self {
        Self::new()
    }
}

impl ModelBuilder {
    /// An empty model: no gravity, an automatic step at half the stable bound, the
    /// default guard.
    pub fn new() -> Self {
        ModelBuilder {
            reference: Vec::new(),
            velocities: Vec::new(),
            masses: Vec::new(),
            bodies: Vec::new(),
            elements: Vec::new(),
            connectivity: Connectivity::default(),
            surface: ContactSurface::default(),
            walls: Vec::new(),
            contact: None,
            rigid: Vec::new(),
            rigid_templates: Templates::default(),
            parts: Parts {
                contributions: Vec::new(),
                constraints: Vec::new(),
            },
            gravity: [0.0; 3],
            time_step: TimeStep::Automatic {
                safety: crate::DEFAULT_DT_SAFETY,
            },
            guard: Guard::default(),
        }
    }

    /// Adds a deformable particle: `template` placed by `placement` (nodes, tetrahedra,
    /// outward surface with control areas), of `material`, moving rigidly with `motion`
    /// about `placement.translation`. Particles of either element order may be mixed.
    ///
    /// # Errors
    /// A template or placement that fdem-mesh refuses.
    pub fn add_deformable(
        &mut self,
        template: &TetMesh,
        placement: &Placement,
        material: &Material,
        motion: InitialMotion,
    ) -> Result<BodyId, SolverError> {
        let mut one = MeshAssembly::new();
        one.push_instance(template, placement)?;
        let npe = one.nodes_per_element();
        let id = self.bodies.len();
        let first = self.reference.len();
        let first_element = self.connectivity.len();
        self.push_surface(
            id,
            first,
            &one.triangles,
            &one.surface_nodes,
            &one.control_areas,
        )?;
        for x in &one.nodes {
            self.velocities
                .push(motion.velocity_at(*x, placement.translation));
        }
        self.reference.extend_from_slice(&one.nodes);
        self.masses.resize(self.reference.len(), 0.0);
        self.connectivity.extend(&one.elements, npe, first);
        let nodes = first..self.reference.len();
        let elements = first_element..self.connectivity.len();
        self.elements.push(ElementInput {
            body: id,
            nodes: nodes.clone(),
            material: *material,
            nodes_per_element: npe,
            connectivity: one.elements,
        });
        self.bodies.push(Body {
            kind: BodyKind::Deformable,
            nodes,
            elements,
        });
        Ok(BodyId(id))
    }

    /// Adds a rigid particle: `template` placed by `placement`, of `material`'s density,
    /// moving rigidly with `motion` about `placement.translation`. Its nodes are the
    /// template's surface nodes with their lumped masses as a deformable particle of the
    /// same mesh has them (the contact dashpots of eq 3 use them); its mass, centre and
    /// inertia are those of the solid meshed shape, integrated exactly over the
    /// tetrahedra.
    ///
    /// # Errors
    /// A template or placement that fdem-mesh refuses, or a degenerate shape.
    pub fn add_rigid(
        &mut self,
        template: &TetMesh,
        placement: &Placement,
        material: &Material,
        motion: InitialMotion,
    ) -> Result<BodyId, SolverError> {
        let mut one = MeshAssembly::new();
        one.push_instance(template, placement)?;
        let npe = one.nodes_per_element();
        let id = self.bodies.len();
        let shape = fdem_mesh::volume_properties(&one.nodes, &one.elements, npe);
        let inertia = RigidInertia::new(
            material.density * shape.volume,
            shape.inertia(material.density),
        )
        .map_err(|e| match e {
            SolverError::InvalidScene(m) => SolverError::InvalidScene(format!("body {id}: {m}")),
            other => other,
        })?;
        // A rigid body's nodes need their masses only, not an elastic element set.
        let lumped = fdem_elastic::lumped_masses(material, npe, &one.nodes, &one.elements)
            .map_err(|source| SolverError::Elastic { body: id, source })?;
        // The body's nodes are the surface nodes, renumbered in their surface order.
        let mut local = vec![usize::MAX; one.n_nodes()];
        for (k, &n) in one.surface_nodes.iter().enumerate() {
            local[n] = k;
        }
        let triangles: Vec<[usize; 3]> =
            one.triangles.iter().map(|t| t.map(|n| local[n])).collect();
        let surface: Vec<usize> = (0..one.surface_nodes.len()).collect();
        let first = self.reference.len();
        self.push_surface(id, first, &triangles, &surface, &one.control_areas)?;
        let c = shape.centroid;
        let frame = crate::rigid::rotation(inertia.principal_frame);
        let mut offsets = Vec::with_capacity(surface.len());
        for &n in &one.surface_nodes {
            let x = one.nodes[n];
            offsets.push(frame.inverse_apply([x[0] - c[0], x[1] - c[1], x[2] - c[2]]));
            self.reference.push(x);
            self.masses.push(lumped[n]);
        }
        let v = motion.velocity_at(c, placement.translation);
        let state = RigidState::new(
            &inertia,
            c,
            v,
            inertia.principal_frame,
            motion.angular_velocity,
        );
        let template_id = self.rigid_templates.intern(RigidTemplate {
            nodes: one
                .surface_nodes
                .iter()
                .map(|&n| template.nodes[n])
                .collect(),
            triangles: triangles.clone(),
        });
        let mut part = RigidPart::new(id, first, offsets, inertia, state);
        part.template = Some(TemplateMap::new(
            template_id,
            placement,
            inertia.principal_frame,
            c,
        ));
        self.velocities.resize(self.reference.len(), [0.0; 3]);
        let nodes = first..self.reference.len();
        part.place_nodes(
            &mut self.reference[nodes.clone()],
            &mut self.velocities[nodes],
        );
        self.rigid.push(part);
        let first_element = self.n_elements();
        self.bodies.push(Body {
            kind: BodyKind::Rigid,
            nodes: first..self.reference.len(),
            elements: first_element..first_element,
        });
        Ok(BodyId(id))
    }

    /// Adds a sheet body (a membrane) at rest.
    ///
    /// # Errors
    /// Arrays of different lengths or a face naming a node the sheet does not have.
    pub fn add_sheet(&mut self, sheet: SheetBody) -> Result<BodyId, SolverError> {
        let n = sheet.positions.len();
        if sheet.masses.len() != n || sheet.control_areas.len() != n {
            return Err(SolverError::InvalidScene(format!(
                "a sheet of {n} nodes has {} masses and {} control areas; give one per node",
                sheet.masses.len(),
                sheet.control_areas.len()
            )));
        }
        if let Some(t) = sheet.triangles.iter().find(|t| t.iter().any(|&i| i >= n)) {
            return Err(SolverError::InvalidScene(format!(
                "sheet face {t:?} names a node beyond the sheet's {n} nodes"
            )));
        }
        let id = self.bodies.len();
        let first = self.reference.len();
        let nodes: Vec<usize> = (0..n).collect();
        self.push_surface(id, first, &sheet.triangles, &nodes, &sheet.control_areas)?;
        self.reference.extend_from_slice(&sheet.positions);
        self.velocities.resize(self.reference.len(), [0.0; 3]);
        self.masses.extend_from_slice(&sheet.masses);
        let first_element = self.connectivity.len();
        self.bodies.push(Body {
            kind: BodyKind::Sheet,
            nodes: first..self.reference.len(),
            elements: first_element..first_element,
        });
        Ok(BodyId(id))
    }

    /// Adds the surface of body `id`, whose nodes start at global node `first`.
    fn push_surface(
        &mut self,
        id: usize,
        first: usize,
        triangles: &[[usize; 3]],
        nodes: &[usize],
        areas: &[f64],
    ) -> Result<(), SolverError> {
        let body = u32::try_from(id).map_err(|_| {
            SolverError::InvalidScene(format!("{id} bodies are more than a model can hold"))
        })?;
        let triangles: Vec<[usize; 3]> = triangles.iter().map(|t| t.map(|i| i + first)).collect();
        let nodes: Vec<usize> = nodes.iter().map(|i| i + first).collect();
        self.surface.push_body(body, &triangles, &nodes, areas)?;
        Ok(())
    }

    /// Adds a rigid wall of the contact model.
    pub fn add_wall(&mut self, wall: Wall) -> WallId {
        self.walls.push(wall);
        WallId(self.walls.len() - 1)
    }

    /// Models contact with these settings (no contact without them).
    pub fn set_contact(&mut self, settings: ContactSettings) {
        self.contact = Some(settings);
    }

    /// Adds a force contribution, evaluated after contact in the order added.
    pub fn add_contribution<T: ForceContribution>(&mut self, contribution: T) -> Handle<T> {
        self.parts.contributions.push(Box::new(contribution));
        Handle::new(self.parts.contributions.len() - 1)
    }

    /// Adds a constraint, applied after all forces in the order added.
    pub fn add_constraint<T: Constraint>(&mut self, constraint: T) -> ConstraintHandle<T> {
        self.parts.constraints.push(Box::new(constraint));
        ConstraintHandle::new(self.parts.constraints.len() - 1)
    }

    /// Gravitational acceleration (m/s^2), applied as `m g` on every node.
    pub fn set_gravity(&mut self, gravity: [f64; 3]) {
        self.gravity = gravity;
    }

    /// How the step is chosen.
    pub fn set_time_step(&mut self, time_step: TimeStep) {
        self.time_step = time_step;
    }

    /// The stability guard's settings.
    pub fn set_guard(&mut self, guard: Guard) {
        self.guard = guard;
    }

    /// A body added so far.
    pub fn body(&self, id: BodyId) -> Option<&Body> {
        self.bodies.get(id.0)
    }

    /// Number of nodes so far.
    pub fn n_nodes(&self) -> usize {
        self.reference.len()
    }

    /// Number of elements so far.
    pub fn n_elements(&self) -> usize {
        self.connectivity.len()
    }

    /// Number of bodies so far.
    pub fn n_bodies(&self) -> usize {
        self.bodies.len()
    }

    /// Reference positions of the nodes so far (m).
    pub fn reference_positions(&self) -> &[[f64; 3]] {
        &self.reference
    }

    /// The shortest edge of the contact faces added so far (m), in the reference
    /// configuration: the length scale of the default contact margin.
    pub fn shortest_surface_edge(&self) -> Option<f64> {
        self.surface.shortest_edge(&self.reference)
    }

    /// Builds the simulation: the element sets and lumped masses of the deformable
    /// bodies, the contact model, the stable bound (elastic combined with contact, then
    /// the smallest with every contribution's, [`StepBound::of_model`]), the step, and the
    /// initial forces and energy.
    ///
    /// # Errors
    /// Element, contact or step errors, and walls or sheets without contact settings.
    pub fn build(self) -> Result<Simulation, SolverError> {
        let elastic = ElasticForces::new(&self.elements, &self.reference)?;
        let mut masses = self.masses;
        for b in &elastic.bodies {
            masses[b.nodes.clone()].copy_from_slice(&b.set.lumped_masses(b.nodes.len()));
        }
        let mut state = NodeState::new(self.reference, masses);
        state.velocities = self.velocities;
        // Rigid bodies' nodes follow their pose: the node update leaves them alone.
        for part in &self.rigid {
            let nodes = part.first..part.first + part.offsets.len();
            state.inverse_masses[nodes].fill(0.0);
        }
        let sheets: Vec<u32> = (0..self.bodies.len() as u32)
            .filter(|&b| self.bodies[b as usize].kind == BodyKind::Sheet)
            .collect();
        let contact = match self.contact {
            Some(settings) => Some(contact_stage(
                settings,
                self.surface,
                self.walls,
                (&state.masses, &state.positions),
                &sheets,
                (&self.rigid, &self.rigid_templates.list),
            )?),
            None if self.walls.is_empty() && sheets.is_empty() => None,
            None => {
                return Err(SolverError::InvalidScene(
                    "the model has walls or sheets but no contact; give it contact settings".into(),
                ));
            }
        };
        let bound = StepBound::of_model(
            elastic.stable_time_step(),
            contact.as_ref().and_then(ContactForces::stable_time_step),
            contact
                .as_ref()
                .and_then(ContactForces::sheet_stable_time_step),
            self.parts
                .contributions
                .iter()
                .map(|c| c.stable_time_step(&state.masses)),
        )
        .unwrap_or(StepBound {
            dt: f64::INFINITY,
            source: "nothing (no elements or contacts)".into(),
        });
        let dt = step_of(self.time_step, &bound)?;
        Simulation::new(Assembled {
            state,
            bodies: self.bodies,
            connectivity: self.connectivity,
            elastic,
            contact,
            rigid: crate::rigid::RigidBodies::new(self.rigid),
            parts: self.parts,
            gravity: self.gravity,
            bound,
            dt,
            safety: match self.time_step {
                TimeStep::Automatic { safety } => Some(safety),
                TimeStep::Fixed(_) => None,
            },
            guard: self.guard,
        })
    }
}

/// The contact model of `settings` on `surface` and `walls`, with `sheets` declared and
/// the stable bound of `rigid` bodies' nodes from their effective masses.
fn contact_stage(
    settings: ContactSettings,
    surface: ContactSurface,
    walls: Vec<Wall>,
    (masses, positions): (&[f64], &[[f64; 3]]),
    sheets: &[u32],
    (rigid, templates): (&[RigidPart], &[RigidTemplate]),
) -> Result<ContactForces, SolverError> {
    let mut model = ContactModel::new(settings.params, surface, walls, masses, settings.margin)?;
    if !rigid.is_empty() {
        // A rigid body's node is as heavy as the body's effective mass there.
        let mut bound_masses = masses.to_vec();
        for part in rigid {
            part.effective_masses(&mut bound_masses[part.first..part.first + part.offsets.len()]);
        }
        model.set_bound_masses(&bound_masses)?;
        // Their faces in their templates' frames (the narrow phase's plane filter).
        let bodies: Vec<(u32, usize)> = rigid
            .iter()
            .filter_map(|p| Some((p.body as u32, p.template?.template)))
            .collect();
        let poses: Vec<_> = rigid.iter().filter_map(RigidPart::pose).collect();
        model.set_rigid_frames(templates, &bodies, (0.0, &poses), positions)?;
    }
    if let Some(depth_limit) = settings.depth_limit {
        model.set_depth_limit(depth_limit)?;
    }
    model.set_depth_limit_cap(settings.depth_limit_cap)?;
    if !sheets.is_empty() {
        let fold_depth = settings.sheet_fold_depth.ok_or_else(|| {
            SolverError::InvalidScene(
                "the model has sheet bodies; give the contact settings a sheet fold depth".into(),
            )
        })?;
        model.set_sheet_bodies(sheets, fold_depth)?;
    }
    Ok(ContactForces::new(model))
}

/// The time step of `rule` with the model's stable `bound`, refused unless positive and
/// finite; the message names the input that made it so (the step given, the bound's
/// source or the safety factor), in words a scene and a specimen both use.
fn step_of(rule: TimeStep, bound: &StepBound) -> Result<f64, SolverError> {
    let dt = match rule {
        TimeStep::Fixed(dt) => dt,
        TimeStep::Automatic { safety } => safety * bound.dt,
    };
    if dt.is_finite() && dt > 0.0 {
        return Ok(dt);
    }
    let message = match rule {
        TimeStep::Fixed(_) => {
            format!("the time step given, {dt:e} s, is not a positive finite number; give one > 0")
        }
        TimeStep::Automatic { .. } if !(bound.dt.is_finite() && bound.dt > 0.0) => format!(
            "no stable time step: the bound set by {} is {:e} s; check the values behind it, \
             or give the time step explicitly (a scene's simulation.dt)",
            bound.source, bound.dt
        ),
        TimeStep::Automatic { safety } => format!(
            "the time step, dt_safety {safety:e} x the stable bound {:e} s (set by {}), is \
             {dt:e} s, not a positive number; raise dt_safety",
            bound.dt, bound.source
        ),
    };
    Err(SolverError::InvalidScene(message))
}
