//! The contact model: detection, the law, reactions, walls, reports.

use std::fmt;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::broad::{BroadPhase, CHUNK};
use crate::detect::{ChunkScratch, Ctx, NO_FACE, SpreadTerm, bodies_clear_of_walls};
use crate::events::{EnergyJump, JumpKind, JumpLog, Reason, Rejection};
use crate::history::History;
use crate::mean_motion::{DriftAllowance, Expected, IDENTITY, Matrix, MeanMotion};
use crate::narrow::ProjectionKernel;
use crate::params::spring_dashpot_time_step;
use crate::prefetch::prefetch;
use crate::rigid_frames::{NodeVelocities, RigidFrames, RigidMotion, RigidPose, RigidTemplate};
use crate::scan::{Nodes, Scan, bound_within};
use crate::sheet::Sheets;
use crate::vec3::{add, is_finite, norm, norm2, scale, sub};
use crate::{
    ContactError, ContactParams, ContactSurface, NodeCoefficients, TunnellingScale, Wall, WallShape,
};

/// Fraction of the shortest surface edge used by [`ContactModel::suggested_margin`].
pub const MARGIN_EDGE_FRACTION: f64 = 0.1;

/// Fraction of the scale on which the narrow phase sees a crossing (the margin against a
/// sheet's face, the depth limit against a solid face or a wall) that a node may move
/// relative to a nearby face (or wall) in one step before [`ContactModel::add_forces`]
/// reports [`ContactError::Tunnelling`]; also the fraction of the depth limit beyond
/// which it reports [`ContactError::PenetrationTooDeep`].
pub const TUNNELLING_FRACTION: f64 = 0.5;

/// When the broad phase renews only the pairs of the bodies that drifted instead of
/// rebuilding every pair ([`ContactModel::set_refresh_policy`]). A refresh renews the
/// pairs of every body with a surface node past `near` times half the margin (the one that
/// triggered it, and those that would trigger the next ones soon after) when they hold at
/// most `max_fraction` of the surface nodes and, with the nodes refreshed since the last
/// full build, at most `max_refreshed_fraction`; otherwise everything is rebuilt. Results
/// do not depend on the policy (the narrow phase gives the same forces for any candidate
/// lists that hold every face within the depth limit), only the cost does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefreshPolicy {
    /// Fraction of half the margin, in (0, 1].
    pub near: f64,
    /// Largest share of the surface nodes one refresh renews, in [0, 1] (0: always
    /// rebuild everything).
    pub max_fraction: f64,
    /// Largest share of the surface nodes renewed by refreshes between full builds, in
    /// [0, 1]: refreshed pairs are found with a wider reach (one and a half skins of
    /// relative motion instead of one), so the lists grow until a full build trims them.
    pub max_refreshed_fraction: f64,
}

impl Default for RefreshPolicy {
    /// Refresh the bodies past three eighths of the margin while they are at most a tenth
    /// of the surface nodes, and at most half between full builds (the fractions chosen on
    /// a checkpoint of the study's B1 run and the quick test, the reach on E1's checkpoint
    /// and the quick tests; docs/PERFORMANCE.md).
    fn default() -> Self {
        RefreshPolicy {
            near: 0.75,
            max_fraction: 0.1,
            max_refreshed_fraction: 0.5,
        }
    }
}

/// The scan's largest drift of one evaluation (squared, m^2), from the positions the mean
/// motion expects (`expected`, at the evaluation's `time`).
#[derive(Clone, Copy, Debug)]
struct Drift {
    max2: f64,
    expected: Option<Expected>,
    time: f64,
}

/// What [`ContactModel::add_forces`] did to the broad phase in one evaluation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Renewal {
    None,
    /// The pairs of this many bodies that drifted were refreshed.
    Refresh {
        bodies: usize,
    },
    /// Every pair was rebuilt.
    Full,
}

/// When a contact passes half the depth limit, the limit grows to this multiple of its
/// depth ([`ContactModel::set_depth_limit_cap`]): the contact then sits at a third of it.
pub const DEPTH_LIMIT_GROWTH: f64 = 3.0;

/// How far a node may move relative to a counterpart in one step before a crossing could
/// go unseen (m), [`TUNNELLING_FRACTION`] of the scale on which the narrow phase sees it.
///
/// The broad phase is renewed at the evaluation itself once a node has drifted half the
/// margin, so a long step never leaves stale candidates; what a long step can hide is the
/// crossing itself. Against a sheet a new contact deeper than half the margin is taken
/// for a fold artefact and discarded, so a node that crossed the sheet farther would pass
/// through it: the sheet's reach is half the margin. Against a solid face or a wall the
/// narrow phase sees a contact to the depth limit and refuses one deeper than half of it,
/// so a node that moved less than half the depth limit relative to the face lands where
/// its contact is seen: the solid reach is half the depth limit. A pair outside the
/// candidate lists cannot put the node in the face's window (behind it by at most the
/// depth limit, the foot inside) while every node stays within its drift allowance (the
/// broad phase's `window` module), and the allowance is checked at every evaluation, so
/// a step in which no two nodes approach by more than the depth limit cannot hide a
/// crossing of such a pair either.
#[derive(Clone, Copy, Debug)]
pub(crate) struct StepReach {
    /// Against a sheet's face (m).
    pub(crate) sheet: f64,
    /// Against a solid face or a wall (m).
    pub(crate) solid: f64,
}

impl StepReach {
    pub(crate) fn new(margin: f64, depth_limit: f64) -> StepReach {
        StepReach {
            sheet: TUNNELLING_FRACTION * margin,
            solid: TUNNELLING_FRACTION * depth_limit,
        }
    }
}

/// `value` if it is a finite length > 0, else [`ContactError::InvalidLength`].
pub(crate) fn positive_length(what: &'static str, value: f64) -> Result<f64, ContactError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(ContactError::InvalidLength { what, value })
    }
}

/// Unit normal and offset `[n, n . a]` of a face's plane; zeros for a degenerate face
/// (every node is then at signed distance 0 and reaches the exact tests, which reject it).
pub(crate) fn unit_plane(face: [[f64; 3]; 3]) -> [f64; 4] {
    let [a, b, c] = face;
    let n = crate::vec3::cross(sub(b, a), sub(c, a));
    let len = norm(n);
    if len > 0.0 && len.is_finite() {
        let u = scale(n, 1.0 / len);
        [u[0], u[1], u[2], crate::vec3::dot(u, a)]
    } else {
        [0.0; 4]
    }
}

/// The frames, when they stand in for the world planes in this evaluation (`active`). A
/// function of the two fields, not of the model, so that it borrows only them.
fn active_frames(frames: &Option<RigidFrames>, active: bool) -> Option<&RigidFrames> {
    frames.as_ref().filter(|_| active)
}

/// The error for a body declared both a sheet and a rigid body with a frame.
fn framed_sheet(body: u32) -> ContactError {
    ContactError::InconsistentSurface {
        what: format!("body {body} is given as a sheet and as a rigid body with a frame"),
        fix: "declare a body either a sheet or a rigid body, not both",
    }
}

/// Refuses a time step `dt` that is not finite and > 0 and a non-finite `time`.
fn check_step(time: f64, dt: f64) -> Result<(), ContactError> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(ContactError::InvalidStep {
            quantity: "dt",
            value: dt,
            requirement: "the time step must be finite and > 0",
        });
    }
    if !time.is_finite() {
        return Err(ContactError::InvalidStep {
            quantity: "time",
            value: time,
            requirement: "the time must be finite",
        });
    }
    Ok(())
}

/// What a surface node touches: a face of another body or a rigid wall.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Counterpart {
    /// A face of this body.
    Body(u32),
    /// The wall of this index (in the order given to [`ContactModel::new`]).
    Wall(u32),
}

impl Counterpart {
    /// Packed code, used in history keys and saved histories: bodies below 2^32, walls
    /// at 2^32 + index.
    #[inline]
    pub fn code(self) -> u64 {
        match self {
            Counterpart::Body(b) => b as u64,
            Counterpart::Wall(w) => (1u64 << 32) | w as u64,
        }
    }

    /// The counterpart of [`Counterpart::code`]; `None` for a number no counterpart has.
    pub fn from_code(code: u64) -> Option<Counterpart> {
        let index = u32::try_from(code & 0xffff_ffff).ok()?;
        match code >> 32 {
            0 => Some(Counterpart::Body(index)),
            1 => Some(Counterpart::Wall(index)),
            _ => None,
        }
    }
}

impl fmt::Display for Counterpart {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Counterpart::Body(b) => write!(f, "a face of body {b}"),
            Counterpart::Wall(w) => write!(f, "wall {w}"),
        }
    }
}

/// History key of a contact: surface-node index in the high bits, counterpart code below.
#[inline]
pub(crate) fn history_key(surface_index: usize, counterpart: Counterpart) -> u64 {
    ((surface_index as u64) << KEY_SHIFT) | counterpart.code()
}

/// Bits of a [`history_key`] below the surface-node index.
const KEY_SHIFT: u32 = 33;

/// The surface-node index of a [`history_key`].
#[inline]
pub(crate) fn key_surface_index(key: u64) -> usize {
    (key >> KEY_SHIFT) as usize
}

/// One active node contact of the last evaluation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NodeContact {
    #[serde(skip)]
    pub(crate) key: u64,
    /// Global id of the surface node.
    pub node: usize,
    /// Body of the node.
    pub body: u32,
    /// What the node touches.
    pub counterpart: Counterpart,
    /// The face (index into [`ContactSurface::triangles`]) for a body contact.
    pub face: Option<usize>,
    /// Barycentric weights of the contact point on the face's nodes (`[0; 3]` for walls).
    pub weights: [f64; 3],
    /// Position of the node (m).
    pub position: [f64; 3],
    /// Contact point on the face or wall (m): the foot of the node's perpendicular.
    pub contact_point: [f64; 3],
    /// Penetration depth (m).
    pub depth: f64,
    /// Normal force on the node (N); the face or wall receives the opposite.
    pub normal_force: [f64; 3],
    /// Tangential (friction) force on the node (N).
    pub tangential_force: [f64; 3],
    /// Elastic tangential displacement `d_s` kept as history (m).
    pub tangential_displacement: [f64; 3],
    /// Whether the contact slides (`|F_s| = mu F_n`).
    pub sliding: bool,
    /// The non-elastic part of the force (dashpots, and the friction cap's cut) and the
    /// relative velocity it was evaluated with, for the dissipation bookkeeping of the
    /// next evaluation (see `Ctx::push`).
    #[serde(skip)]
    pub(crate) damping_force: [f64; 3],
    #[serde(skip)]
    pub(crate) relative_velocity: [f64; 3],
    /// Whether the contact is a sheet's edge hit (the closest point on an edge or vertex
    /// of a face the node is behind) rather than a face hit.
    #[serde(skip)]
    pub(crate) edge: bool,
}

impl NodeContact {
    /// Total force on the node (N).
    pub fn force(&self) -> [f64; 3] {
        add(self.normal_force, self.tangential_force)
    }
}

/// Sum of the node contacts between one body and one counterpart (last evaluation).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairSum {
    /// The body receiving the forces (the lower id of a body pair).
    pub body: u32,
    /// The other body (higher id) or a wall.
    pub counterpart: Counterpart,
    /// Sum of the normal force vectors on `body` from `counterpart` (N): the nodes of
    /// `body` pressed into the counterpart's faces plus the reactions of the counterpart's
    /// nodes pressed into `body`'s faces.
    pub normal_force: [f64; 3],
    /// Sum of the tangential force vectors on `body` from `counterpart` (N), counted the
    /// same way.
    pub tangential_force: [f64; 3],
    /// Number of node contacts between the two, in both directions.
    pub nodes: usize,
}

/// Summary of one evaluation, for the solver's energy balance.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ContactReport {
    /// Active node contacts (node-to-face and node-to-wall).
    pub contacts: usize,
    /// Of which against walls.
    pub wall_contacts: usize,
    /// Contacts that slide.
    pub sliding: usize,
    /// Stored contact energy `sum k_n d_n^2 / 2 + k_s |d_s|^2 / 2` (J).
    pub stored_energy: f64,
    /// Power dissipated by the normal dashpots at the evaluated velocities (W).
    pub normal_damping_power: f64,
    /// Power dissipated by the tangential dashpots at the evaluated velocities (W).
    pub tangential_damping_power: f64,
    /// Energy dissipated by frictional sliding in this evaluation (J), from the Coulomb
    /// cut-back of the tangential displacements.
    pub friction_dissipation: f64,
    /// Power done by the walls on the particles (W): the wall velocity dotted with the
    /// force each wall exerts, summed over walls; external work of the prescribed motion.
    pub wall_power: f64,
    /// Largest penetration depth (m).
    pub max_depth: f64,
    /// Whether the broad phase was rebuilt in this evaluation (every pair).
    pub rebuilt: bool,
    /// Bodies whose pairs the broad phase refreshed in this evaluation, having drifted past
    /// half the margin (0 without a refresh, and at a full build). Sheets, whose drifted
    /// nodes are refreshed one by one, are not counted.
    pub refreshed_bodies: usize,
    /// Candidate (surface node, triangle) pairs of the current broad phase.
    pub candidate_pairs: usize,
    /// Node-to-sheet hits deeper than the sheets' fold depth that were discarded as fold
    /// artefacts (see [`ContactModel::set_sheet_bodies`]).
    pub discarded_sheet_hits: usize,
}

/// The smallest contact stable time step over the surface nodes (docs/MODEL.md section 11).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StableStep {
    /// `dt <= 2 (sqrt(1 + beta^2) - beta) / sqrt(k / m)` (s).
    pub time_step: f64,
    /// Global id of the node that sets it.
    pub node: usize,
    /// Its body.
    pub body: u32,
    /// The larger of its `k_n`, `k_s` (N/m).
    pub stiffness: f64,
    /// The reduced mass of the node and the lightest node of another body (kg).
    pub mass: f64,
    /// The damping ratio that goes with that stiffness.
    pub damping_ratio: f64,
}

impl fmt::Display for StableStep {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "contact spring-dashpot of surface node {} (body {}): dt <= {:.4e} s \
             (k = {:.4e} N/m, m = {:.4e} kg, beta = {})",
            self.node, self.body, self.time_step, self.stiffness, self.mass, self.damping_ratio
        )
    }
}

/// The per-pair tunnelling checks one evaluation needs (see `ContactModel::guards`).
#[derive(Clone, Copy, Debug)]
struct Guards {
    /// How far a node may move relative to a face or wall in one step.
    reach: StepReach,
    /// Node against the centroid velocity of each candidate face.
    check_faces: bool,
    /// Node against each wall.
    check_walls: bool,
}

/// Penalty node-to-face contact between deformable bodies and rigid walls.
///
/// Create it once with the surface, the masses and a margin, then call
/// [`ContactModel::add_forces`] exactly once per time step (or its two halves,
/// [`ContactModel::evaluate`] then [`ContactModel::add_evaluated_forces`], with nothing
/// changed in the model between them): each step advances the tangential history by `dt`.
/// The model is [`Clone`], so a state can be evaluated twice.
#[derive(Clone, Debug)]
pub struct ContactModel {
    params: ContactParams,
    surface: ContactSurface,
    walls: Vec<Wall>,
    n_nodes: usize,
    margin: f64,
    depth_limit: f64,
    /// The largest depth limit a too deep contact may grow it to (`None`: no growth).
    depth_limit_cap: Option<f64>,
    kernel: ProjectionKernel,
    coefficients: Vec<NodeCoefficients>,
    masses: Vec<f64>,
    /// The masses of the step bound per surface node: the lumped masses or those of
    /// [`ContactModel::set_bound_masses`].
    bound_masses: Vec<f64>,
    stable: Option<StableStep>,
    broad: BroadPhase,
    rebuild_requested: bool,
    refresh_policy: RefreshPolicy,
    /// The last evaluation's contacts: the next one's tangential history.
    history: History,
    chunks: Vec<ChunkScratch>,
    /// Per body id, whether the narrow phase may pass over its nodes without candidates
    /// (`detect::bodies_clear_of_walls`), rewritten every evaluation.
    clear_of_walls: Vec<bool>,
    wall_shapes: Vec<WallShape>,
    wall_forces: Vec<[f64; 3]>,
    report: ContactReport,
    /// The sheet bodies and their fold depth (`set_sheet_bodies`).
    sheets: Sheets,
    /// The stored-energy jump log, while it is on (`set_energy_jump_log`).
    jumps: Option<JumpLog>,
    /// Evaluations so far (whose forces were added): before the first, a sheet
    /// contact may start at any depth (an assembled or restored state).
    evaluations: u64,
    /// An evaluation whose forces wait for [`ContactModel::add_evaluated_forces`], with
    /// what it did to the broad phase.
    evaluated: Option<Renewal>,
    /// The mean motion the broad phase measures drift from (`set_mean_motion`).
    mean: Option<MeanMotion>,
    /// The mean motion's gradient at the last full build.
    build_gradient: Matrix,
    /// The largest distortion `|A - I|` of the mean motion since the last full build.
    largest_distortion: f64,
    /// The rigid bodies' faces in their templates' frames (`set_rigid_frames`).
    rigid_frames: Option<RigidFrames>,
    /// Whether the frames stand in for the world planes in this evaluation
    /// ([`RigidFrames::usable`]).
    frames_active: bool,
}

/// The lightest surface node of each body, then the two lightest bodies: a node's
/// counterpart is the lightest body other than its own. Returns, per body, the mass of
/// that counterpart (kg; infinite without another body).
fn counterpart_mass(surface: &ContactSurface, masses: &[f64]) -> impl Fn(u32) -> f64 {
    let mut lightest: std::collections::BTreeMap<u32, f64> = Default::default();
    for (&body, &m) in surface.node_body.iter().zip(masses) {
        let e = lightest.entry(body).or_insert(f64::INFINITY);
        *e = e.min(m);
    }
    let mut by_mass: Vec<(f64, u32)> = lightest.iter().map(|(&b, &m)| (m, b)).collect();
    by_mass.sort_by(|a, b| a.0.total_cmp(&b.0));
    by_mass.truncate(2);
    move |body: u32| match by_mass.as_slice() {
        [(m, b), ..] if *b != body => *m,
        [_, (m, _), ..] => *m,
        _ => f64::INFINITY,
    }
}

/// A node's stiffer spring (the larger of `k_n`, `k_s`) and the damping ratio that goes
/// with it.
fn stiffer_spring(params: &ContactParams, c: &NodeCoefficients) -> (f64, f64) {
    if c.tangential_stiffness > c.normal_stiffness {
        (c.tangential_stiffness, params.tangential_damping_ratio())
    } else {
        (c.normal_stiffness, params.damping)
    }
}

/// The smallest spring-dashpot bound over the surface nodes (see
/// [`ContactModel::stable_time_step`]); `masses` per surface node.
fn stable_step(
    params: &ContactParams,
    surface: &ContactSurface,
    coefficients: &[NodeCoefficients],
    masses: &[f64],
) -> Option<StableStep> {
    smallest_step(params, surface, coefficients, masses, |_, own| Some(own))
}

/// The smallest bound over the nodes of sheet bodies with both sides of a conformal
/// contact counted (see [`ContactModel::sheet_stable_time_step`]); `masses` per surface
/// node. `None` without sheet nodes.
fn sheet_stable_step(
    params: &ContactParams,
    surface: &ContactSurface,
    coefficients: &[NodeCoefficients],
    masses: &[f64],
    sheets: &Sheets,
) -> Option<StableStep> {
    // The stiffest spring of a node that is not on a sheet: one such node pressing a
    // sheet face at its corner puts all of it on the corner node.
    let counterpart = surface
        .node_body
        .iter()
        .zip(coefficients)
        .filter(|(b, _)| !sheets.is_sheet(**b))
        .map(|(_, c)| stiffer_spring(params, c).0)
        .fold(0.0, f64::max);
    // A sheet node's own spring against the face it touches, plus the springs of the
    // other surface's nodes pressing the faces around it: at most one node's worth of the
    // other surface's area per node of the sheet (the weights of a node's faces sum to
    // its share of their area), or the stiffest single node at a face corner.
    smallest_step(params, surface, coefficients, masses, |body, own| {
        sheets.is_sheet(body).then(|| own + own.max(counterpart))
    })
}

/// The smallest spring-dashpot bound over the surface nodes, each with the stiffness
/// `stiffness(body, own)` gives from its own stiffer spring (`None`: the node is left
/// out), its damping ratio and the reduced mass of the node and its counterpart body; the
/// first node of the smallest bound names it. `masses` per surface node.
fn smallest_step(
    params: &ContactParams,
    surface: &ContactSurface,
    coefficients: &[NodeCoefficients],
    masses: &[f64],
    stiffness: impl Fn(u32, f64) -> Option<f64>,
) -> Option<StableStep> {
    let other = counterpart_mass(surface, masses);
    let mut stable: Option<StableStep> = None;
    for (k, (&node, c)) in surface.surface_nodes.iter().zip(coefficients).enumerate() {
        let body = surface.node_body[k];
        let (own, damping_ratio) = stiffer_spring(params, c);
        let Some(stiffness) = stiffness(body, own) else {
            continue;
        };
        let mass = 1.0 / (1.0 / masses[k] + 1.0 / other(body));
        let dt = spring_dashpot_time_step(stiffness, mass, damping_ratio);
        if stable.is_none_or(|s| dt < s.time_step) {
            stable = Some(StableStep {
                time_step: dt,
                node,
                body,
                stiffness,
                mass,
                damping_ratio,
            });
        }
    }
    stable
}

impl ContactModel {
    /// Sets up the model.
    ///
    /// - `masses`: lumped mass of every global node (kg); its length fixes the number of
    ///   nodes that positions, velocities and forces must have. Surface-node masses must be
    ///   finite and > 0; they set the dashpots `c = 2 beta sqrt(m k)` (eq 3).
    /// - `margin` (m): the Verlet skin of the broad phase, the tunnelling scale and the
    ///   initial depth limit of the narrow phase; see [`ContactModel::suggested_margin`]
    ///   and [`ContactModel::set_depth_limit`].
    ///
    /// Stiffnesses use the control areas of `surface`, fixed from the reference
    /// configuration (`k_n = p_n A`, eq 2).
    ///
    /// # Errors
    /// Invalid parameters, an inconsistent surface, a bad mass, margin or wall.
    pub fn new(
        params: ContactParams,
        surface: ContactSurface,
        walls: Vec<Wall>,
        masses: &[f64],
        margin: f64,
    ) -> Result<ContactModel, ContactError> {
        params.validate()?;
        if !(margin.is_finite() && margin > 0.0) {
            return Err(ContactError::InvalidMargin { margin });
        }
        let n_nodes = masses.len();
        surface.validate(n_nodes)?;
        let walls = walls
            .iter()
            .enumerate()
            .map(|(i, w)| w.normalised(i))
            .collect::<Result<Vec<_>, _>>()?;
        if walls.len() > u32::MAX as usize {
            return Err(ContactError::TooLarge {
                what: "wall",
                count: walls.len(),
                limit: u32::MAX as usize,
            });
        }
        let mut coefficients = Vec::with_capacity(surface.surface_nodes.len());
        let mut node_masses = Vec::with_capacity(surface.surface_nodes.len());
        for (k, &node) in surface.surface_nodes.iter().enumerate() {
            let mass = masses[node];
            let body = surface.node_body[k];
            if !(mass.is_finite() && mass > 0.0) {
                return Err(ContactError::InvalidMass { node, body, mass });
            }
            coefficients.push(params.coefficients(surface.control_areas[k], mass));
            node_masses.push(mass);
        }
        let stable = stable_step(&params, &surface, &coefficients, &node_masses);
        let n_chunks = surface.surface_nodes.len().div_ceil(CHUNK);
        Ok(ContactModel {
            params,
            n_nodes,
            margin,
            depth_limit: margin,
            depth_limit_cap: None,
            kernel: ProjectionKernel::default(),
            coefficients,
            bound_masses: node_masses.clone(),
            masses: node_masses,
            stable,
            broad: BroadPhase::for_surface(&surface),
            rebuild_requested: true,
            refresh_policy: RefreshPolicy::default(),
            history: History::new(n_chunks),
            chunks: vec![ChunkScratch::default(); n_chunks],
            clear_of_walls: Vec::new(),
            wall_shapes: Vec::with_capacity(walls.len()),
            wall_forces: vec![[0.0; 3]; walls.len()],
            report: ContactReport::default(),
            walls,
            surface,
            sheets: Sheets::default(),
            jumps: None,
            evaluations: 0,
            evaluated: None,
            mean: None,
            build_gradient: IDENTITY,
            largest_distortion: 0.0,
            rigid_frames: None,
            frames_active: false,
        })
    }

    /// A margin of [`MARGIN_EDGE_FRACTION`] (0.1) times the shortest surface edge at the
    /// given positions; `None` without triangles. Large against typical penetrations
    /// (of the order of 1e-3 of a particle diameter for the paper's parameters:
    /// docs/SPECIMENS.md, "Why 2 % overlap"), small against the particles, so that the
    /// depth limit (= margin) never reaches through a particle.
    pub fn suggested_margin(surface: &ContactSurface, positions: &[[f64; 3]]) -> Option<f64> {
        surface
            .shortest_edge(positions)
            .map(|l| MARGIN_EDGE_FRACTION * l)
    }

    /// The contact parameters.
    pub fn params(&self) -> &ContactParams {
        &self.params
    }

    /// The contact surface.
    pub fn surface(&self) -> &ContactSurface {
        &self.surface
    }

    /// The walls, with unit normals and axes.
    pub fn walls(&self) -> &[Wall] {
        &self.walls
    }

    /// Declares bodies as sheets (thin open surfaces such as a membrane). A node's depth
    /// behind a sheet is its distance to the sheet's closest point, where the
    /// angle-weighted pseudo-normal there says the node is behind: continuous over the
    /// sheet's faces, edges and vertices, so contacts neither appear nor vanish at a
    /// finite depth as they slide over a folded sheet. A node found behind a sheet deeper than
    /// `fold_depth` (m) is not an error but a fold artefact of a sheet draped over angular
    /// particles: the hit is discarded and counted in
    /// [`ContactReport::discarded_sheet_hits`] (the caller checks containment by other
    /// means, as the triaxial test does every output). The crate's `sheet` module explains
    /// these rules and their invariants. A partial refresh of the broad phase renews a
    /// sheet's pairs node by node (its drifted nodes and the faces they are corners of),
    /// not the whole sheet. A sheet's faces are listed only to about the fold depth, and a
    /// step in which two nodes could approach by more is refused (the `sheet` module). The
    /// next evaluation rebuilds the lists.
    ///
    /// # Errors
    /// [`ContactError::InvalidLength`] for a `fold_depth` that is not finite and > 0.
    pub fn set_sheet_bodies(
        &mut self,
        bodies: &[u32],
        fold_depth: f64,
    ) -> Result<(), ContactError> {
        if let Some(&b) = bodies
            .iter()
            .find(|&&b| self.rigid_frames.as_ref().is_some_and(|f| f.has(b)))
        {
            return Err(framed_sheet(b));
        }
        self.sheets.declare(bodies, fold_depth)?;
        // A sheet's faces are listed in both directions and to its listing depth: lists
        // built before the declaration do not follow that rule.
        self.rebuild_requested = true;
        Ok(())
    }

    /// Changes the velocity of wall `index` from `time` on, keeping its position at `time`
    /// continuous: the wall's time-0 shape is shifted so that
    /// `shape_at(time)` is unchanged and `shape_at(t) = shape_at(time) + velocity (t - time)`.
    /// This is how a servo-controlled platen is driven; the wall power of the following
    /// evaluations uses the new velocity.
    ///
    /// # Errors
    /// [`ContactError::InvalidWall`] for an index out of range or a non-finite velocity or
    /// time.
    pub fn set_wall_velocity(
        &mut self,
        index: usize,
        velocity: [f64; 3],
        time: f64,
    ) -> Result<(), ContactError> {
        let n = self.walls.len();
        let wall = self
            .walls
            .get_mut(index)
            .ok_or_else(|| ContactError::InvalidWall {
                wall: index,
                reason: format!("there are {n} walls; use an index below {n}"),
            })?;
        if !(is_finite(velocity) && time.is_finite()) {
            return Err(ContactError::InvalidWall {
                wall: index,
                reason: format!(
                    "velocity {velocity:?} m/s at time {time} s is not finite; give finite numbers"
                ),
            });
        }
        wall.shape = wall.shape_at(time).translated(scale(velocity, -time));
        wall.velocity = velocity;
        Ok(())
    }

    /// The Verlet-skin margin (m).
    pub fn margin(&self) -> f64 {
        self.margin
    }

    /// The depth limit (m): the narrow phase looks this far behind a face; a contact
    /// deeper than half of it is refused ([`ContactError::PenetrationTooDeep`]). It equals
    /// the margin unless [`ContactModel::set_depth_limit`] changed it.
    pub fn depth_limit(&self) -> f64 {
        self.depth_limit
    }

    /// Sets the depth limit (m) independently of the Verlet skin.
    ///
    /// The margin bounds how far nodes may move between broad-phase builds and per step;
    /// the depth limit bounds how deep a contact may become (half of it) and how far
    /// behind a face the narrow phase looks (all of it). Stiff contacts at particle
    /// vertices under high stress can press deeper than half a small margin while moving
    /// slowly: raising the depth limit lets them, and costs only a larger candidate box
    /// (`margin + depth_limit` instead of `2 margin`). It must stay well below the
    /// particles' thickness, so that the nearest face behind a node is the one it
    /// crossed. Sheets ([`ContactModel::set_sheet_bodies`]) have a fold depth of their own.
    ///
    /// # Errors
    /// [`ContactError::InvalidLength`] for a depth that is not finite and > 0.
    pub fn set_depth_limit(&mut self, depth_limit: f64) -> Result<(), ContactError> {
        self.depth_limit = positive_length("depth limit", depth_limit)?;
        self.rebuild_requested = true;
        Ok(())
    }

    /// Lets a contact deeper than half the depth limit, or a node moving farther than
    /// half of it relative to a solid face or wall in one step, grow the limit, up to
    /// `cap` (m), instead of stopping the evaluation; `None` (the default) keeps the limit
    /// fixed.
    ///
    /// The stiff vertex contacts of angular particles press deeper as the stress grows,
    /// and how deep (or how fast a particle pops out of a wedge) is known only from the
    /// run. When a contact reaches half the limit, [`ContactModel::add_forces`] sets the
    /// limit to [`DEPTH_LIMIT_GROWTH`] times that depth (at most `cap`), rebuilds the
    /// broad phase and evaluates the step again; a displacement past the tunnelling reach
    /// against solids ([`TUNNELLING_FRACTION`] of the limit) grows it likewise. Only a
    /// depth or displacement above half of `cap` stops it. Contacts shallower than half
    /// the old limit are the same with either limit (the nearest face behind a node is the
    /// one within the old window), so the growth changes the candidate lists' cost, not
    /// the forces. `cap` must stay well below the particles' thickness (see
    /// [`ContactModel::set_depth_limit`]).
    ///
    /// # Errors
    /// [`ContactError::InvalidLength`] for a cap that is not finite and > 0.
    pub fn set_depth_limit_cap(&mut self, cap: Option<f64>) -> Result<(), ContactError> {
        self.depth_limit_cap = cap
            .map(|c| positive_length("depth limit cap", c))
            .transpose()?;
        Ok(())
    }

    /// The depth limit a contact `depth` (m) deeper than half the current limit grows it
    /// to, or `None` when the cap does not allow a larger one.
    fn grown_depth_limit(&self, depth: f64) -> Option<f64> {
        let cap = self.depth_limit_cap?;
        let grown = (DEPTH_LIMIT_GROWTH * depth).min(cap);
        (grown > self.depth_limit && depth <= TUNNELLING_FRACTION * grown).then_some(grown)
    }

    /// The depth limit that lets the evaluation go on past error `e`, when the cap allows
    /// one: a contact deeper than half the limit needs the limit above twice its depth, a
    /// node moving farther than half the limit relative to a solid face or wall in one
    /// step (or the fastest node's bound for pairs outside the candidate lists) needs it
    /// above twice that displacement (the narrow phase then still sees the contact it
    /// could make); both grow it to [`DEPTH_LIMIT_GROWTH`] times the length.
    fn grown_for(&self, e: &ContactError) -> Option<f64> {
        match *e {
            ContactError::PenetrationTooDeep { depth, .. } => self.grown_depth_limit(depth),
            ContactError::Tunnelling {
                displacement,
                scale: TunnellingScale::DepthLimit,
                ..
            } => self.grown_depth_limit(displacement),
            _ => None,
        }
    }

    /// Spring and dashpot coefficients of surface node `k` (index into
    /// [`ContactSurface::surface_nodes`]).
    pub fn coefficients(&self, k: usize) -> Option<&NodeCoefficients> {
        self.coefficients.get(k)
    }

    /// Every contact of the last evaluation with the stiffer of its node's springs (N/m)
    /// and the larger of its dashpots (N s/m): what a stable step over the contact network
    /// counts (the solver's rigid-body bound).
    pub fn contact_springs(&self) -> impl Iterator<Item = (&NodeContact, f64, f64)> + '_ {
        self.history.iter().map(|c| {
            let k = &self.coefficients[key_surface_index(c.key)];
            let stiffness = k.normal_stiffness.max(k.tangential_stiffness);
            (c, stiffness, k.normal_damping.max(k.tangential_damping))
        })
    }

    /// The narrow-phase kernel in use.
    pub fn projection_kernel(&self) -> ProjectionKernel {
        self.kernel
    }

    /// Selects the narrow-phase kernel (for benchmarks; both give the same contacts up to
    /// the tolerance band along face edges).
    pub fn set_projection_kernel(&mut self, kernel: ProjectionKernel) {
        self.kernel = kernel;
    }

    /// Smallest contact stable time step over the surface nodes (docs/MODEL.md section 11), with
    /// the node that sets it; `None` without surface nodes.
    ///
    /// Per node, `dt = 2 (sqrt(1 + beta^2) - beta) / sqrt(k / m)` with the larger of `k_n`,
    /// `k_s`, its damping ratio, and the reduced mass `m = 1 / (1 / m_i + 1 / m_o)` of the
    /// node (`m_i`) and the lightest surface node of any other body (`m_o`): the spring
    /// pushes the node and, in reaction, the nodes of the face it touches, and at a face
    /// corner one face node takes the whole reaction. Without another body (walls only)
    /// `m = m_i`, exact for a node against a wall. The masses are the lumped masses unless
    /// [`ContactModel::set_bound_masses`] gave others (a rigid body's effective mass).
    pub fn stable_time_step(&self) -> Option<StableStep> {
        self.stable
    }

    /// The bound of the sheet nodes ([`ContactModel::set_sheet_bodies`]) with both sides of
    /// a conformal contact counted; `None` without sheets.
    ///
    /// A sheet wraps the particles and drapes onto them: a node of it touches a particle's
    /// face with its own spring while the particle's nodes press the faces around it with
    /// theirs. Their sum on the node is at most its own stiffness plus the larger of that
    /// and the stiffest single node of another body (Gershgorin's bound on the row: the
    /// weights of the nodes pressing its faces sum to at most one node's worth of area,
    /// unless one node larger than its share sits at a face corner). The per-node bound of
    /// [`ContactModel::stable_time_step`] counts one spring; with light sheet nodes against
    /// heavy (rigid) particles and a soft sheet whose own elements do not set the step,
    /// the second spring decides (docs/TRIAXIAL.md, "Time step").
    pub fn sheet_stable_time_step(&self) -> Option<StableStep> {
        sheet_stable_step(
            &self.params,
            &self.surface,
            &self.coefficients,
            &self.bound_masses,
            &self.sheets,
        )
    }

    /// Gives the rigid bodies' faces their templates' frames: `bodies` pairs a body id with
    /// its template's index in `templates` (the template's faces in the order of the body's
    /// faces in the contact surface, which must be consecutive), and `poses` (one per
    /// body) say where each body is at `time`, whose node `positions` they must reproduce.
    /// From then on the narrow phase's plane filter meets those faces in their template's
    /// frame whenever [`ContactModel::set_rigid_poses`] gave the poses of the evaluation's
    /// time; the contacts are the same bit for bit (the `rigid_frames` module has why).
    ///
    /// # Errors
    /// [`ContactError::InconsistentSurface`] for a body whose faces are not its template's
    /// or not consecutive, a template index out of range, a body given twice, or poses not
    /// one per body or not finite.
    pub fn set_rigid_frames(
        &mut self,
        templates: &[RigidTemplate],
        bodies: &[(u32, usize)],
        (time, poses): (f64, &[RigidPose]),
        positions: &[[f64; 3]],
    ) -> Result<(), ContactError> {
        self.check_length("positions", positions.len())?;
        // The sheet rules test signs without slack: a sheet is never met in a frame.
        if let Some(&(b, _)) = bodies.iter().find(|(b, _)| self.sheets.is_sheet(*b)) {
            return Err(framed_sheet(b));
        }
        self.rigid_frames = Some(RigidFrames::new(
            &self.surface,
            positions,
            templates,
            bodies,
            (time, poses),
        )?);
        Ok(())
    }

    /// The rigid bodies' poses at `time`, one per body in the order
    /// [`ContactModel::set_rigid_frames`] was given them; an evaluation at another time
    /// uses the world planes.
    ///
    /// # Errors
    /// [`ContactError::LengthMismatch`] for another number of poses; `InconsistentSurface`
    /// when no frames were set.
    pub fn set_rigid_poses(&mut self, time: f64, poses: &[RigidPose]) -> Result<(), ContactError> {
        self.frames_for("rigid poses")?.set_poses(time, poses)
    }

    /// [`ContactModel::set_rigid_poses`] without copying them: the model takes the vector's
    /// contents and leaves its previous poses in `poses` (a driver that gives poses every
    /// step refills the same two vectors in turn). On an error `poses` is unchanged.
    ///
    /// # Errors
    /// As [`ContactModel::set_rigid_poses`].
    pub fn exchange_rigid_poses(
        &mut self,
        time: f64,
        poses: &mut Vec<RigidPose>,
    ) -> Result<(), ContactError> {
        self.frames_for("rigid poses")?.exchange_poses(time, poses)
    }

    /// The rigid frames, for giving them `what`; an error when none were set.
    fn frames_for(&mut self, what: &str) -> Result<&mut RigidFrames, ContactError> {
        self.rigid_frames
            .as_mut()
            .ok_or_else(|| ContactError::InconsistentSurface {
                what: format!("{what} given before the rigid frames"),
                fix: "call set_rigid_frames first",
            })
    }

    /// The rigid bodies' motions at `time` (a bound of their nodes' speeds, whether their
    /// nodes are finite; one per body in the order [`ContactModel::set_rigid_frames`] was
    /// given them): with the poses of that time, the evaluation's per-step scan reads those
    /// bodies' nodes only where the bounds cannot decide for them (the `scan` module has
    /// why the results are the same). Each motion must hold for the nodes as placed for the
    /// evaluation.
    ///
    /// An evaluation at `time` takes the velocity of every node of those bodies from its
    /// motion, `fdem_core::geometry::rigid_velocity(velocity, angular_velocity, centre, x)`
    /// at the node's position `x`, and never reads those nodes' entries of the
    /// `velocities` it is given: a caller that places them with that function from the same
    /// motion gets the same contacts bit for bit, and a caller that reads them nowhere else
    /// need not place them at all.
    ///
    /// # Errors
    /// [`ContactError::LengthMismatch`] for another number of motions; `InconsistentSurface`
    /// when no frames were set.
    pub fn set_rigid_motions(
        &mut self,
        time: f64,
        motions: &[RigidMotion],
    ) -> Result<(), ContactError> {
        self.frames_for("rigid motions")?.set_motions(time, motions)
    }

    /// [`ContactModel::set_rigid_motions`] without copying them, as
    /// [`ContactModel::exchange_rigid_poses`] gives poses: `motions` holds the model's
    /// previous motions afterwards (unchanged on an error).
    ///
    /// # Errors
    /// As [`ContactModel::set_rigid_motions`].
    pub fn exchange_rigid_motions(
        &mut self,
        time: f64,
        motions: &mut Vec<RigidMotion>,
    ) -> Result<(), ContactError> {
        self.frames_for("rigid motions")?
            .exchange_motions(time, motions)
    }

    /// Whether the last evaluation met the rigid bodies' faces in their templates' frames.
    pub fn rigid_frames_in_use(&self) -> bool {
        self.frames_active
    }

    /// Recomputes [`ContactModel::stable_time_step`] with `masses` (per global node, kg) in
    /// place of the lumped masses: for a node of a rigid body, the body's effective mass
    /// at that node. The dashpots keep the lumped masses (eq 3).
    ///
    /// # Errors
    /// `masses` of another length than the model's nodes, or a surface-node mass that is
    /// not finite and positive.
    pub fn set_bound_masses(&mut self, masses: &[f64]) -> Result<(), ContactError> {
        if masses.len() != self.n_nodes {
            return Err(ContactError::LengthMismatch {
                array: "bound masses",
                expected: self.n_nodes,
                found: masses.len(),
                reason: "one per node of the model",
            });
        }
        let mut bound = Vec::with_capacity(self.surface.surface_nodes.len());
        for (k, &node) in self.surface.surface_nodes.iter().enumerate() {
            let mass = masses[node];
            if !(mass.is_finite() && mass > 0.0) {
                let body = self.surface.node_body[k];
                return Err(ContactError::InvalidMass { node, body, mass });
            }
            bound.push(mass);
        }
        self.stable = stable_step(&self.params, &self.surface, &self.coefficients, &bound);
        self.bound_masses = bound;
        Ok(())
    }

    /// Sets when the broad phase refreshes only the bodies that drifted ([`RefreshPolicy`]);
    /// the results are the same under any policy.
    ///
    /// # Errors
    /// [`ContactError::InvalidRefreshPolicy`] naming the field when `near` is not in
    /// (0, 1] or a fraction not in [0, 1] (NaN included); nothing is changed then.
    pub fn set_refresh_policy(&mut self, policy: RefreshPolicy) -> Result<(), ContactError> {
        let fields = [
            ("near", policy.near, "(0, 1]", policy.near > 0.0),
            (
                "max_fraction",
                policy.max_fraction,
                "[0, 1]",
                policy.max_fraction >= 0.0,
            ),
            (
                "max_refreshed_fraction",
                policy.max_refreshed_fraction,
                "[0, 1]",
                policy.max_refreshed_fraction >= 0.0,
            ),
        ];
        for (field, value, range, above) in fields {
            if !(above && value <= 1.0) {
                return Err(ContactError::InvalidRefreshPolicy {
                    field,
                    value,
                    range,
                });
            }
        }
        self.refresh_policy = policy;
        Ok(())
    }

    /// Declares the mean motion the surface follows from `time` on: a uniform deformation
    /// about the fixed point `origin` (m) whose gradient changes at `rate` (1/s, rows),
    /// `F(t) = (I + (t - time) rate) F(time)`, continuing the motion set before. A specimen
    /// squeezed between platens at speed `v` over height `H` has `rate[2][2] = -v / H`
    /// about a point of the fixed platen.
    ///
    /// The broad phase then measures each node's drift from where the mean motion has
    /// taken it since its pairs were found, not from rest (`crate::mean_motion` has the
    /// argument), so the lists last while neighbours keep their arrangement. The contacts
    /// and forces are the same under any mean motion, or none: only the renewals change.
    ///
    /// # Errors
    /// [`ContactError::InvalidMeanMotion`] for a value that is not finite; nothing is
    /// changed then.
    pub fn set_mean_motion(
        &mut self,
        origin: [f64; 3],
        rate: [[f64; 3]; 3],
        time: f64,
    ) -> Result<(), ContactError> {
        let bad = |what, value: String| Err(ContactError::InvalidMeanMotion { what, value });
        if !is_finite(origin) {
            return bad("origin", format!("{origin:?}"));
        }
        if !rate.iter().all(|&row| is_finite(row)) {
            return bad("rate", format!("{rate:?}"));
        }
        if !time.is_finite() {
            return bad("time", format!("{time}"));
        }
        self.mean = Some(MeanMotion::continued(
            self.mean.as_ref(),
            origin,
            rate,
            time,
        ));
        Ok(())
    }

    /// Drift is measured from rest again (the default).
    pub fn clear_mean_motion(&mut self) {
        self.mean = None;
        self.rebuild_requested = true;
    }

    /// Where the mean motion has taken the last full build's reference positions at
    /// `time` (`None` without mean motion or before a build), recording its distortion;
    /// a map that cannot be inverted asks for a full build.
    fn expected_motion(&mut self, time: f64) -> Option<Expected> {
        let mean = self.mean.as_ref()?;
        if !self.broad.built {
            return None;
        }
        match mean.since(&self.build_gradient, time) {
            Some(e) => {
                self.largest_distortion = self.largest_distortion.max(e.distortion);
                Some(e)
            }
            None => {
                self.rebuild_requested = true;
                None
            }
        }
    }

    /// How far a node may drift from its expected position before the lists are renewed:
    /// half the margin, less the mean motion's distortion of the lists' reach.
    fn drift_allowance(&self) -> DriftAllowance {
        let (e, front) = self.broad.refresh_reaches(self.margin);
        DriftAllowance::of(
            TUNNELLING_FRACTION * self.margin,
            self.largest_distortion,
            e + front,
        )
    }

    /// Forces the next evaluation to rebuild the broad phase (for example after nodes were
    /// moved by something other than time stepping).
    pub fn request_rebuild(&mut self) {
        self.rebuild_requested = true;
    }

    /// Number of full broad-phase builds so far.
    pub fn rebuild_count(&self) -> usize {
        self.broad.builds
    }

    /// Number of partial broad-phase refreshes so far (the pairs of the bodies that drifted
    /// past half the margin renewed, the others kept).
    pub fn refresh_count(&self) -> usize {
        self.broad.refreshes
    }

    /// Enlargement of the triangle boxes at the last build (m): `margin + depth_limit`
    /// plus the tolerance band.
    pub fn candidate_enlargement(&self) -> f64 {
        self.broad.enlargement
    }

    /// How far in front of a face's plane a node remains a candidate of the face at the
    /// last build (m): two skins plus the tolerance band (a node further in front cannot
    /// get behind the face before the next build; see the broad phase's `FRONT_SKINS`).
    pub fn candidate_front_reach(&self) -> f64 {
        self.broad.front
    }

    /// The enlargement and the front reach (m) with which a partial refresh finds the pairs
    /// of the bodies that drifted: those of the last full build
    /// ([`ContactModel::candidate_enlargement`], [`ContactModel::candidate_front_reach`])
    /// grown for one and a half skins of relative motion instead of one.
    pub fn candidate_refresh_reaches(&self) -> (f64, f64) {
        self.broad.refresh_reaches(self.margin)
    }

    /// How far from the window of `face` (m) a node behind the face's plane remains a
    /// candidate of it: at the last full build, and at a refresh. The window is the prism
    /// over the face from its plane to the depth limit behind it, where the narrow phase
    /// accepts a node; the reach covers the motions the lists allow (the broad phase's
    /// `window` module has the bound).
    pub fn candidate_window_reaches(&self, face: [[f64; 3]; 3]) -> (f64, f64) {
        let build = self.broad.window;
        let refresh = crate::broad::WindowReach::of_refresh(self.margin, build.depth);
        (build.of_face(face), refresh.of_face(face))
    }

    /// Cell size of the broad phase's node grid at the last build (m).
    pub fn cell_size(&self) -> f64 {
        self.broad.cell_size
    }

    /// Candidate pairs of the current broad phase as (global node id, triangle index), in
    /// the order the narrow phase visits them. A pair is a candidate when, at the last
    /// build, the triangle belongs to another body, the node lies within
    /// [`ContactModel::candidate_enlargement`] of the triangle, and the node is behind the
    /// triangle's plane within the build's [`ContactModel::candidate_window_reaches`] of
    /// its window (the depth limit deep), or within
    /// [`ContactModel::candidate_front_reach`] of the triangle, or the triangle belongs to
    /// a sheet ([`ContactModel::set_sheet_bodies`]);
    /// a pair with a node or a face on a body refreshed since
    /// ([`ContactModel::refresh_count`]) was found the same way at its last refresh, with
    /// [`ContactModel::candidate_refresh_reaches`].
    pub fn candidate_pairs(&self) -> Vec<(usize, usize)> {
        let mut out = Vec::with_capacity(self.broad.pairs);
        if !self.broad.built {
            return out;
        }
        for (k, &node) in self.surface.surface_nodes.iter().enumerate() {
            for c in self.broad.candidates(k) {
                out.push((node, c.triangle as usize));
            }
        }
        out
    }

    /// Force exerted by the particles on each wall in the last evaluation (N).
    pub fn wall_forces(&self) -> &[[f64; 3]] {
        &self.wall_forces
    }

    /// Active node contacts of the last evaluation, sorted by surface node, then
    /// counterpart (bodies before walls). The model keeps them chunk by chunk; the first
    /// call after an evaluation assembles this list (a copy of every record), later calls
    /// return it as it is.
    pub fn node_contacts(&self) -> &[NodeContact] {
        self.history.flat()
    }

    /// The report of the last evaluation.
    pub fn last_report(&self) -> &ContactReport {
        &self.report
    }

    /// Stored contact energy of the last evaluation (J).
    pub fn stored_energy(&self) -> f64 {
        self.report.stored_energy
    }

    /// Per (body, counterpart) sums of the last evaluation, sorted by body then
    /// counterpart: the ground truth that contact clustering validates against. Body pairs
    /// appear once, under the lower body id.
    pub fn pair_sums(&self) -> Vec<PairSum> {
        let mut entries: Vec<(u32, Counterpart, f64, &NodeContact)> = self
            .history
            .iter()
            .map(|c| match c.counterpart {
                Counterpart::Body(b) if b < c.body => (b, Counterpart::Body(c.body), -1.0, c),
                other => (c.body, other, 1.0, c),
            })
            .collect();
        entries.sort_by_key(|e| (e.0, e.1));
        let mut out: Vec<PairSum> = Vec::new();
        for (body, counterpart, sign, c) in entries {
            let fresh = out
                .last()
                .is_none_or(|p| p.body != body || p.counterpart != counterpart);
            if fresh {
                out.push(PairSum {
                    body,
                    counterpart,
                    normal_force: [0.0; 3],
                    tangential_force: [0.0; 3],
                    nodes: 0,
                });
            }
            if let Some(p) = out.last_mut() {
                p.normal_force = add(p.normal_force, scale(c.normal_force, sign));
                p.tangential_force = add(p.tangential_force, scale(c.tangential_force, sign));
                p.nodes += 1;
            }
        }
        out
    }

    /// An array of `found` entries where one per node is required.
    fn check_length(&self, array: &'static str, found: usize) -> Result<(), ContactError> {
        if found != self.n_nodes {
            return Err(ContactError::LengthMismatch {
                array,
                expected: self.n_nodes,
                found,
                reason: "one entry per node, as many as the masses given to ContactModel::new",
            });
        }
        Ok(())
    }

    /// Scans the surface nodes: finiteness, drift since the last build (from the expected
    /// positions under a mean motion), largest speed; a framed body's pose and motion may
    /// stand in for its nodes against the drift `allowance` (m) and the tunnelling bound of
    /// the step `dt` (`crate::scan`).
    fn scan(
        &self,
        positions: &[[f64; 3]],
        velocities: &[[f64; 3]],
        expected: Option<&Expected>,
        (allowance, time, dt): (f64, f64, f64),
    ) -> Scan {
        let nodes = Nodes {
            surface: &self.surface,
            positions,
            velocities: NodeVelocities::new(velocities, self.rigid_frames.as_ref(), time),
            reference: self.broad.built.then_some(self.broad.reference.as_slice()),
            expected,
        };
        let frames = active_frames(&self.rigid_frames, self.frames_active);
        match frames.and_then(|f| Some((f, f.motions_at(time)?))) {
            Some((frames, motions)) => {
                nodes.scan_framed(frames, motions, (allowance, dt, self.depth_limit))
            }
            None => nodes.scan(),
        }
    }

    /// Adds the contact forces for the state at time `time` to `forces`, advancing the
    /// tangential histories by one step `dt`, and returns the report: an
    /// [`ContactModel::evaluate`] followed by [`ContactModel::add_evaluated_forces`].
    ///
    /// `positions`, `velocities` and `forces` are indexed by global node id and must have
    /// as many entries as the masses given to [`ContactModel::new`]. Wall positions are
    /// their initial ones plus `velocity * time`. The tangential displacement grows by
    /// `v_t dt` with the given velocities.
    ///
    /// Nothing is changed (neither `forces` nor the model's history) when an error is
    /// returned.
    ///
    /// # Errors
    /// [`ContactError::LengthMismatch`], [`ContactError::InvalidStep`],
    /// [`ContactError::NonFinite`] for a diverged state, [`ContactError::Tunnelling`] when
    /// a node moves more than half the margin relative to nearby faces or walls in one
    /// step, [`ContactError::PenetrationTooDeep`] when a node is deeper than half the
    /// depth limit ([`ContactModel::depth_limit`]).
    pub fn add_forces(
        &mut self,
        positions: &[[f64; 3]],
        velocities: &[[f64; 3]],
        time: f64,
        dt: f64,
        forces: &mut [[f64; 3]],
    ) -> Result<ContactReport, ContactError> {
        // Every argument checked before any work, in the order of the errors' precedence.
        check_step(time, dt)?;
        self.check_length("positions", positions.len())?;
        self.check_length("velocities", velocities.len())?;
        self.check_length("forces", forces.len())?;
        self.evaluate(positions, velocities, time, dt)?;
        self.add_evaluated_forces(forces)
    }

    /// The first half of [`ContactModel::add_forces`]: finds the contacts of the state at
    /// time `time` and evaluates the law for each, without touching any force array, so
    /// that a caller may compute other forces into its array meanwhile (the engine runs
    /// the elements' forces beside it). [`ContactModel::add_evaluated_forces`] then adds
    /// them and keeps the contacts as the history of the next evaluation; until then the
    /// history is that of the last evaluation, and a new `evaluate` replaces this one.
    ///
    /// # Errors
    /// As [`ContactModel::add_forces`] but for the `forces` array, which this does not
    /// see; the history is unchanged after an error, and no evaluation waits.
    pub fn evaluate(
        &mut self,
        positions: &[[f64; 3]],
        velocities: &[[f64; 3]],
        time: f64,
        dt: f64,
    ) -> Result<(), ContactError> {
        self.evaluated = None;
        check_step(time, dt)?;
        self.check_length("positions", positions.len())?;
        self.check_length("velocities", velocities.len())?;

        // Pass 1: finiteness, Verlet-skin drift, fastest node (a fastest node too fast for
        // the depth limit grows it, within its cap).
        let expected = self.expected_motion(time);
        let slack = crate::detect::plane_slack(self.depth_limit);
        self.frames_active = self
            .rigid_frames
            .as_ref()
            .is_some_and(|f| f.usable(time, slack));
        let allowance = self.drift_allowance().drift;
        let limits = (allowance, time, dt);
        let scan = self.scan(positions, velocities, expected.as_ref(), limits);
        self.wall_shapes.clear();
        self.wall_shapes
            .extend(self.walls.iter().map(|w| w.shape_at(time)));
        let v_max = match self.check_scan(&scan, positions, velocities, (time, dt)) {
            Err(e) if let Some(grown) = self.grown_for(&e) => {
                self.depth_limit = grown;
                self.rebuild_requested = true;
                scan.max_speed2.sqrt()
            }
            result => result?,
        };
        let drift = Drift {
            max2: scan.max_drift2,
            expected,
            time,
        };
        let mut renewal = self.rebuild_if_due(positions, drift);

        // Pass 2: narrow phase and law, in parallel over fixed chunks of surface nodes; a
        // contact too deep for the depth limit, or a node moving too far relative to a
        // solid face or wall, grows it (within its cap) and the pass runs again on the new
        // candidate lists.
        loop {
            let guards = self.guards(v_max, dt);
            match self.narrow_phase(positions, velocities, (time, dt), guards) {
                Err(e) if let Some(grown) = self.grown_for(&e) => {
                    self.depth_limit = grown;
                    self.rebuild_requested = true;
                    match self.rebuild_if_due(positions, drift) {
                        Renewal::None => {}
                        again => renewal = again,
                    }
                }
                result => break result?,
            }
        }
        self.evaluated = Some(renewal);
        Ok(())
    }

    /// The second half of [`ContactModel::add_forces`], serial in a fixed order: adds the
    /// forces of the last [`ContactModel::evaluate`] and the reactions on faces and walls
    /// to `forces`, keeps the contacts as the next evaluation's history, and returns the
    /// report.
    ///
    /// # Errors
    /// [`ContactError::LengthMismatch`] for a `forces` array of another length;
    /// [`ContactError::NotEvaluated`] when no evaluation is waiting (none since the last
    /// call, the last one failed, or the history was imported or restored since).
    pub fn add_evaluated_forces(
        &mut self,
        forces: &mut [[f64; 3]],
    ) -> Result<ContactReport, ContactError> {
        self.check_length("forces", forces.len())?;
        let renewal = self.evaluated.take().ok_or(ContactError::NotEvaluated)?;
        let before = self.jumps.is_some().then(|| self.history.flat().to_vec());
        let report = self.apply_forces(forces, renewal);
        self.report = report;
        self.evaluations += 1;
        if let Some(before) = before {
            self.log_jumps(&before);
        }
        Ok(report)
    }

    /// Turns the stored-energy jump log ([`crate::events`]) on with a `threshold` (J): from
    /// the next evaluation on, every contact whose stored energy jumps by more than it is
    /// logged with its cause. `None` turns it off and drops what was logged.
    ///
    /// # Errors
    /// [`ContactError::InvalidLength`] for a threshold that is not finite and >= 0.
    pub fn set_energy_jump_log(&mut self, threshold: Option<f64>) -> Result<(), ContactError> {
        self.jumps = match threshold {
            None => None,
            Some(t) if t.is_finite() && t >= 0.0 => Some(JumpLog {
                threshold: t,
                ..JumpLog::default()
            }),
            Some(t) => {
                return Err(ContactError::InvalidLength {
                    what: "energy jump threshold (J)",
                    value: t,
                });
            }
        };
        Ok(())
    }

    /// The jumps logged since the last call (empty while the log is off).
    pub fn take_energy_jumps(&mut self) -> Vec<EnergyJump> {
        self.jumps
            .as_mut()
            .map(|log| std::mem::take(&mut log.events))
            .unwrap_or_default()
    }

    /// Stored energy `k_n d_n^2 / 2 + k_s |d_s|^2 / 2` of a contact (J).
    fn contact_energy(&self, c: &NodeContact) -> f64 {
        let k = key_surface_index(c.key);
        let coef = &self.coefficients[k];
        0.5 * coef.normal_stiffness * c.depth * c.depth
            + 0.5 * coef.tangential_stiffness * norm2(c.tangential_displacement)
    }

    /// Why surface node `k` has no contact with `counterpart` in an evaluation whose
    /// recorded rejections are `rejections` (sorted by key).
    fn reason(&self, key: u64, counterpart: Counterpart, rejections: &[Rejection]) -> Reason {
        if let Counterpart::Wall(_) = counterpart {
            return Reason::InFrontOfWall;
        }
        match rejections.binary_search_by_key(&key, |r| r.key) {
            Ok(i) => rejections[i].reason,
            Err(_) => Reason::NoCandidate,
        }
    }

    /// Merges this evaluation's contacts with `before` (the previous evaluation's, both
    /// sorted by key) and logs the jumps above the threshold.
    fn log_jumps(&mut self, before: &[NodeContact]) {
        let Some(mut log) = self.jumps.take() else {
            return;
        };
        let rejections: Vec<Rejection> = self
            .chunks
            .iter()
            .flat_map(|c| c.rejections.iter().copied())
            .collect();
        let (mut i, mut j) = (0, 0);
        let now = self.history.flat();
        while i < before.len() || j < now.len() {
            let (b, a) = match (before.get(i), now.get(j)) {
                (Some(b), Some(a)) if b.key == a.key => (Some(b), Some(a)),
                (Some(b), Some(a)) if b.key < a.key => (Some(b), None),
                (Some(b), None) => (Some(b), None),
                (_, a) => (None, a),
            };
            i += usize::from(b.is_some());
            j += usize::from(a.is_some());
            let jump = self.jump(b, a, &rejections, &log.previous_rejections);
            if let Some(jump) = jump.filter(|e| e.change().abs() > log.threshold) {
                log.events.push(jump);
            }
        }
        log.previous_rejections = rejections;
        self.jumps = Some(log);
    }

    /// The jump of one contact key between two evaluations (`before`, `after`), if it is
    /// a discontinuity (appeared, vanished, or on another face).
    fn jump(
        &self,
        before: Option<&NodeContact>,
        after: Option<&NodeContact>,
        rejections: &[Rejection],
        previous_rejections: &[Rejection],
    ) -> Option<EnergyJump> {
        let c = after.or(before)?;
        let kind = match (before, after) {
            (Some(b), Some(a)) if b.face != a.face || b.edge != a.edge => JumpKind::FaceSwitch,
            (Some(_), Some(_)) => return None,
            (Some(b), None) => JumpKind::Vanished(self.reason(b.key, b.counterpart, rejections)),
            (None, Some(a)) => {
                JumpKind::Appeared(self.reason(a.key, a.counterpart, previous_rejections))
            }
            (None, None) => return None,
        };
        let energy = |x: Option<&NodeContact>| x.map_or(0.0, |x| self.contact_energy(x));
        let depth = |x: Option<&NodeContact>| x.map_or(0.0, |x| x.depth);
        let edge = |x: Option<&NodeContact>| x.is_some_and(|x| x.edge);
        Some(EnergyJump {
            node: c.node,
            body: c.body,
            counterpart: c.counterpart,
            kind,
            energy_before: energy(before),
            energy_after: energy(after),
            depth_before: depth(before),
            depth_after: depth(after),
            edge_before: edge(before),
            edge_after: edge(after),
        })
    }

    /// Refuses a scanned state with a non-finite position or velocity, and a step in which
    /// two nodes outside each other's candidate lists could meet. Returns the largest
    /// surface-node speed (m/s).
    fn check_scan(
        &self,
        scan: &Scan,
        positions: &[[f64; 3]],
        velocities: &[[f64; 3]],
        (time, dt): (f64, f64),
    ) -> Result<f64, ContactError> {
        if let Some((k, is_velocity)) = scan.bad {
            let node = self.surface.surface_nodes[k];
            let x = positions[node];
            let velocities = NodeVelocities::new(velocities, self.rigid_frames.as_ref(), time);
            return Err(ContactError::NonFinite {
                quantity: if is_velocity { "velocity" } else { "position" },
                node,
                body: self.surface.node_body[k],
                value: if is_velocity {
                    velocities.of_surface_node(&self.surface, k, x)
                } else {
                    x
                },
            });
        }
        // Tunnelling bound for pairs outside the candidate lists: none of them can have the
        // node in the face's window at an evaluation ([`StepReach`]), and no two nodes
        // approach faster than twice the largest speed.
        let v_max = scan.max_speed2.sqrt();
        let fastest = |relative_to: &str, (limit, scale): (f64, TunnellingScale)| {
            let k = scan.fastest;
            ContactError::Tunnelling {
                node: self.surface.surface_nodes[k],
                body: self.surface.node_body[k],
                relative_to: format!("{relative_to} (twice its speed bounds the relative speed)"),
                displacement: 2.0 * v_max * dt,
                limit,
                scale,
                dt,
            }
        };
        if 2.0 * v_max * dt > self.depth_limit {
            let limit = (self.depth_limit, TunnellingScale::DepthLimit);
            return Err(fastest("other bodies", limit));
        }
        // A sheet's faces are listed to its listing depth only (at least the sheet's step
        // reach, half the margin): a node crossing a sheet must land within it, where the
        // tunnelling guard watches the faces.
        if 2.0 * v_max * dt > self.sheet_listing_depth() && self.sheets.any() {
            let limit = (self.margin, TunnellingScale::Margin);
            return Err(fastest("the sheets", limit));
        }
        Ok(v_max)
    }

    /// How far behind a sheet its faces are listed (m), `Sheets::listing_depth`.
    fn sheet_listing_depth(&self) -> f64 {
        let reach = StepReach::new(self.margin, self.depth_limit);
        self.sheets.listing_depth(self.depth_limit, reach.sheet)
    }

    /// Rebuilds the broad phase when asked to, before the first evaluation, when the mean
    /// motion's distortion has used up the allowance, or when a surface node has drifted
    /// farther than the allowance (half the margin without mean motion); in the last case
    /// only the bodies that drifted are refreshed when the [`RefreshPolicy`] allows.
    /// Returns what it did.
    fn rebuild_if_due(&mut self, positions: &[[f64; 3]], drift: Drift) -> Renewal {
        let allowance = self.drift_allowance();
        let half = allowance.drift;
        let full = self.rebuild_requested || !self.broad.built || allowance.exhausted;
        if !full && drift.max2 <= half * half {
            return Renewal::None;
        }
        let sheets = &self.sheets;
        if !full {
            // Bodies past half the margin and those on their way there: in a specimen
            // deforming as a whole most bodies are, and one full build serves them all.
            let policy = self.refresh_policy;
            let near = policy.near * half;
            let expected = drift.expected.as_ref();
            let clean = self.clearly_clean(expected, near);
            // A sheet is renewed node by node: one drifted node of a membrane would
            // otherwise renew all of its pairs.
            let dirt =
                self.broad
                    .drifted(positions, &self.surface, (near, &clean), expected, |body| {
                        sheets.is_sheet(body)
                    });
            let nodes = self.broad.renewed_nodes(&dirt);
            let total = self.surface.surface_nodes.len() as f64;
            let refreshed = (self.broad.refreshed_nodes() + nodes) as f64;
            if nodes as f64 <= policy.max_fraction * total
                && refreshed <= policy.max_refreshed_fraction * total
            {
                let bodies = dirt.whole_bodies();
                let frames = active_frames(&self.rigid_frames, self.frames_active);
                let refreshed = self.broad.refresh(
                    (positions, &self.surface),
                    (&dirt, expected),
                    (self.margin, frames),
                    |body| sheets.is_sheet(body),
                );
                if refreshed {
                    let current = self.frames_active;
                    if let Some(frames) = self.rigid_frames.as_mut() {
                        frames.refresh_references(&dirt.bodies, expected, current);
                    }
                    return Renewal::Refresh { bodies };
                }
            }
        }
        self.broad.build(
            positions,
            &self.surface,
            (self.margin, self.depth_limit, self.sheet_listing_depth()),
            active_frames(&self.rigid_frames, self.frames_active),
            |body| sheets.is_sheet(body),
        );
        self.rebuild_requested = false;
        let current = self.frames_active;
        if let Some(frames) = self.rigid_frames.as_mut() {
            frames.reset_references(current);
        }
        self.build_gradient = self
            .mean
            .as_ref()
            .map_or(IDENTITY, |m| m.gradient_at(drift.time));
        self.largest_distortion = 0.0;
        Renewal::Full
    }

    /// Per body id, whether a framed body's pose shows all its nodes clearly within
    /// `threshold` (m) of their expected references (a refresh need not read them).
    fn clearly_clean(&self, expected: Option<&Expected>, threshold: f64) -> Vec<bool> {
        let mut clean = vec![false; self.broad.n_bodies()];
        let Some(frames) = active_frames(&self.rigid_frames, self.frames_active) else {
            return clean;
        };
        for (body, k) in frames.framed_bodies() {
            clean[body as usize] = bound_within(frames, k, expected, threshold).is_some();
        }
        clean
    }

    /// Which per-pair tunnelling checks this step needs, from the largest node speed
    /// `v_max` (m/s): none of them can fire while the relative motion in one step stays
    /// below the smaller reach ([`StepReach`]).
    fn guards(&self, v_max: f64, dt: f64) -> Guards {
        let reach = StepReach::new(self.margin, self.depth_limit);
        let check_faces = 2.0 * v_max * dt > reach.sheet.min(reach.solid);
        let wall_speed = self
            .walls
            .iter()
            .map(|w| norm(w.velocity))
            .fold(0.0, f64::max);
        let check_walls = (v_max + wall_speed) * dt > reach.solid;
        Guards {
            reach,
            check_faces,
            check_walls,
        }
    }

    /// Runs the narrow phase and the law over every chunk of surface nodes into the
    /// chunks' scratch; the first error in node order, if any.
    fn narrow_phase(
        &mut self,
        positions: &[[f64; 3]],
        velocities: &[[f64; 3]],
        (time, dt): (f64, f64),
        guards: Guards,
    ) -> Result<(), ContactError> {
        let frames = active_frames(&self.rigid_frames, self.frames_active);
        let motions = frames.and_then(|f| f.motions_at(time));
        match frames.zip(motions) {
            Some((frames, motions)) => bodies_clear_of_walls(
                frames,
                motions,
                (&self.walls, &self.wall_shapes),
                (self.margin, dt),
                (self.broad.n_bodies(), &mut self.clear_of_walls),
            ),
            None => self.clear_of_walls.clear(),
        }
        let ctx = Ctx {
            surface: &self.surface,
            broad: &self.broad,
            coefficients: &self.coefficients,
            walls: &self.walls,
            wall_shapes: &self.wall_shapes,
            previous: &self.history,
            kernel: self.kernel,
            positions,
            velocities: NodeVelocities::new(velocities, self.rigid_frames.as_ref(), time),
            dt,
            margin: self.margin,
            depth_limit: self.depth_limit,
            sheet_depth: self.sheet_listing_depth(),
            reach: guards.reach,
            check_faces: guards.check_faces,
            check_walls: guards.check_walls,
            sheets: &self.sheets,
            frames,
            diagnose: self.jumps.is_some(),
            evaluated: self.evaluations > 0,
            clear_of_walls: &self.clear_of_walls,
            far_arrays: crate::detect::far_arrays(positions),
        };
        self.chunks
            .par_iter_mut()
            .enumerate()
            .with_max_len(NARROW_CHUNKS_PER_TASK)
            .for_each(|(chunk, scratch)| ctx.run_chunk(chunk, scratch));
        match self.chunks.iter_mut().find_map(|c| c.error.take()) {
            Some(err) => Err(err),
            None => Ok(()),
        }
    }

    /// Adds the chunks' contact forces and the reactions on faces and walls to `forces`
    /// ([`spread_forces`]), keeps the contacts as the next evaluation's history (a swap of
    /// buffers, [`History::keep`]), and sums the report.
    fn apply_forces(&mut self, forces: &mut [[f64; 3]], renewal: Renewal) -> ContactReport {
        let mut report = ContactReport {
            rebuilt: renewal == Renewal::Full,
            refreshed_bodies: match renewal {
                Renewal::Refresh { bodies } => bodies,
                _ => 0,
            },
            candidate_pairs: self.broad.pairs,
            ..ContactReport::default()
        };
        spread_forces(&self.chunks, forces, &mut self.wall_forces);
        self.history.keep(&mut self.chunks);
        for s in self.chunks.iter().map(|scratch| &scratch.sums) {
            report.stored_energy += s.stored;
            report.normal_damping_power += s.normal_damping;
            report.tangential_damping_power += s.tangential_damping;
            report.friction_dissipation += s.friction;
            report.wall_contacts += s.wall_contacts;
            report.sliding += s.sliding;
            report.max_depth = report.max_depth.max(s.max_depth);
            report.discarded_sheet_hits += s.discarded;
        }
        report.contacts = self.history.len();
        // The wall exerts -(force on the wall) on the particles; its power is v_wall . that.
        report.wall_power = self
            .walls
            .iter()
            .zip(&self.wall_forces)
            .map(|(w, f)| -(w.velocity[0] * f[0] + w.velocity[1] * f[1] + w.velocity[2] * f[2]))
            .sum();
        report
    }

    /// Lumped mass of surface node `k` (kg).
    pub fn surface_node_mass(&self, k: usize) -> Option<f64> {
        self.masses.get(k).copied()
    }
}

/// At most this many chunks of the narrow phase per task of the pool. Without a cap
/// rayon's adaptive split stops splitting a few levels down, so a thread that has run out
/// of chunks (the one that started first: the other was preparing the force
/// contributions) finds no task to take while the other works through a run of hundreds.
/// Each chunk writes only its own scratch, so the split changes no result.
const NARROW_CHUNKS_PER_TASK: usize = 4;

/// Contacts from which [`spread_forces`] splits the nodes among the pool's threads. Small
/// scenes keep one thread, so that a short spread does not wake another; the value is a
/// choice, not a measured break-even.
const PARALLEL_SPREAD_MIN: usize = 1 << 12;

/// Adds the forces of the chunks' contacts ([`SpreadTerm`]s), in order, to their nodes,
/// the reactions to the faces' nodes (spread by the barycentric weights of the contact
/// point: momentum is conserved to round-off) and to `wall_forces` (zeroed first).
///
/// From [`PARALLEL_SPREAD_MIN`] contacts on, the node ids are split into one range per
/// thread, and each thread walks every contact in order, adding only into its own range:
/// every node still receives its terms in the serial order, so the sums are the serial
/// ones bit for bit, whatever the thread count.
fn spread_forces(chunks: &[ChunkScratch], forces: &mut [[f64; 3]], wall_forces: &mut [[f64; 3]]) {
    wall_forces.fill([0.0; 3]);
    let n: usize = chunks.iter().map(|scratch| scratch.terms.len()).sum();
    let threads = rayon::current_num_threads();
    if n < PARALLEL_SPREAD_MIN || threads < 2 {
        spread_range(chunks, (forces, 0), Some(wall_forces));
        return;
    }
    let size = forces.len().div_ceil(threads).max(1);
    let mut walls = Some(wall_forces);
    // The first range also adds the wall forces.
    let mut ranges: Vec<SpreadRange<'_>> = forces
        .chunks_mut(size)
        .enumerate()
        .map(|(i, range)| (range, i * size, walls.take()))
        .collect();
    ranges.par_iter_mut().for_each(|(range, first, walls)| {
        spread_range(chunks, (range, *first), walls.as_deref_mut());
    });
}

/// The forces of one range of node ids (from the id given), and the wall forces if this
/// range adds them.
type SpreadRange<'a> = (&'a mut [[f64; 3]], usize, Option<&'a mut [[f64; 3]]>);

/// [`spread_forces`] into the nodes `first .. first + forces.len()` (`forces` holds their
/// forces), and into `wall_forces` when given.
fn spread_range(
    chunks: &[ChunkScratch],
    (forces, first): (&mut [[f64; 3]], usize),
    mut wall_forces: Option<&mut [[f64; 3]]>,
) {
    // An id below `first` wraps to a huge index: outside the range, like one above it.
    let own = |j: u32| (j as usize).wrapping_sub(first);
    for terms in chunks.iter().map(|scratch| &scratch.terms) {
        for (i, t) in terms.iter().enumerate() {
            if let Some(ahead) = terms.get(i + SPREAD_AHEAD) {
                prefetch_spread(forces, ahead, own);
            }
            let f = t.force;
            if let Some(node) = forces.get_mut(own(t.node)) {
                *node = add(*node, f);
            }
            match t.corners {
                [NO_FACE, NO_FACE, _] => {}
                [NO_FACE, w, _] => {
                    if let Some(walls) = wall_forces.as_deref_mut() {
                        let w = w as usize;
                        walls[w] = sub(walls[w], f);
                    }
                }
                corners => {
                    for (j, &w) in corners.iter().zip(&t.weights) {
                        if let Some(face_node) = forces.get_mut(own(*j)) {
                            *face_node = sub(*face_node, scale(f, w));
                        }
                    }
                }
            }
        }
    }
}

/// How many contacts ahead the spread asks for the forces it will add into.
const SPREAD_AHEAD: usize = 8;

/// Asks the memory system for the forces the spread of `term` will add into (those in the
/// range `forces` holds; `own` maps a node id into it). The faces lie on other bodies,
/// anywhere in the array: without the hints the spread waits for a cache miss per
/// contact. A hint changes no value.
#[inline(always)]
fn prefetch_spread(forces: &[[f64; 3]], term: &SpreadTerm, own: impl Fn(u32) -> usize) {
    prefetch(forces, own(term.node));
    if term.corners[0] != NO_FACE {
        for &j in &term.corners {
            prefetch(forces, own(j));
        }
    }
}

/// Everything a [`ContactModel`] carries from one evaluation to the next that a driver
/// cannot rebuild from the model's definition: the tangential history, the walls as
/// moved so far, the wall forces of the last evaluation (a servo reads them before the
/// next step) and the count of evaluations (sheet contacts of the first evaluation may
/// start at any depth). With the node state it resumes a run bit-for-bit
/// ([`ContactModel::checkpoint`], [`ContactModel::restore_checkpoint`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ContactCheckpoint {
    /// [`ContactModel::export_history`].
    pub history: Vec<(usize, Counterpart, [f64; 3])>,
    /// Per history entry, the non-elastic force and the relative velocity of the last
    /// evaluation `[F_nc, v_rel]`: the next evaluation books the velocity-Verlet share of
    /// that force's work from them (energy bookkeeping only, not the motion).
    pub damping: Vec<[[f64; 3]; 2]>,
    /// The walls, each anchored at time 0 with its current velocity.
    pub walls: Vec<Wall>,
    /// Force on each wall at the last evaluation (N).
    pub wall_forces: Vec<[f64; 3]>,
    /// Evaluations so far.
    pub evaluations: u64,
    /// The depth limit (m), which a too deep contact may have grown
    /// ([`ContactModel::set_depth_limit_cap`]); `None` keeps the model's.
    pub depth_limit: Option<f64>,
}

impl ContactModel {
    /// The state to resume this model from ([`ContactCheckpoint`]).
    pub fn checkpoint(&self) -> ContactCheckpoint {
        ContactCheckpoint {
            history: self.export_history(),
            damping: self
                .history
                .iter()
                .map(|c| [c.damping_force, c.relative_velocity])
                .collect(),
            walls: self.walls.clone(),
            wall_forces: self.wall_forces.clone(),
            evaluations: self.evaluations,
            depth_limit: Some(self.depth_limit),
        }
    }

    /// Restores a [`ContactModel::checkpoint`] of a model built on the same surface and
    /// walls: the history ([`ContactModel::import_history`]), the walls' motion, the wall
    /// forces and the evaluation count; the broad phase is rebuilt at the next evaluation
    /// (which does not change its results).
    ///
    /// # Errors
    /// Nothing is changed when the wall count differs, a wall or wall force is not finite,
    /// or the history does not import.
    pub fn restore_checkpoint(
        &mut self,
        checkpoint: &ContactCheckpoint,
    ) -> Result<(), ContactError> {
        let n = self.walls.len();
        if checkpoint.walls.len() != n || checkpoint.wall_forces.len() != n {
            return Err(ContactError::InconsistentSurface {
                what: format!(
                    "the checkpoint has {} walls and {} wall forces, the model {n} walls",
                    checkpoint.walls.len(),
                    checkpoint.wall_forces.len()
                ),
                fix: "restore a checkpoint of a model built on the same assembly and walls",
            });
        }
        for (i, (w, f)) in checkpoint
            .walls
            .iter()
            .zip(&checkpoint.wall_forces)
            .enumerate()
        {
            let finite = is_finite(w.velocity)
                && is_finite(*f)
                && match w.shape {
                    WallShape::Plane { point, normal } => is_finite(point) && is_finite(normal),
                    WallShape::Cylinder {
                        axis_point,
                        axis,
                        radius,
                    } => is_finite(axis_point) && is_finite(axis) && radius.is_finite(),
                };
            if !finite {
                return Err(ContactError::InvalidWall {
                    wall: i,
                    reason: "the checkpoint's wall or wall force is not finite; restore an \
                             undamaged checkpoint"
                        .into(),
                });
            }
        }
        if let Some(d) = checkpoint.depth_limit {
            positive_length("checkpoint's depth limit", d)?;
        }
        let damping_finite = checkpoint.damping.iter().flatten().all(|v| is_finite(*v));
        if checkpoint.damping.len() != checkpoint.history.len() || !damping_finite {
            return Err(ContactError::InconsistentSurface {
                what: format!(
                    "the checkpoint has {} damping records for {} history entries, or one \
                     that is not finite",
                    checkpoint.damping.len(),
                    checkpoint.history.len()
                ),
                fix: "restore an undamaged checkpoint written by this build",
            });
        }
        self.import_history(&checkpoint.history)?;
        // The import sorted the entries by key, as the export listed them.
        for (c, [force, velocity]) in self.history.iter_mut().zip(&checkpoint.damping) {
            c.damping_force = *force;
            c.relative_velocity = *velocity;
        }
        self.walls.clone_from(&checkpoint.walls);
        self.wall_forces.clone_from(&checkpoint.wall_forces);
        self.evaluations = checkpoint.evaluations;
        self.evaluated = None;
        if let Some(d) = checkpoint.depth_limit {
            self.depth_limit = d;
            self.rebuild_requested = true;
        }
        Ok(())
    }
}

/// Export and import of the tangential (friction) history, so that a simulation can be
/// saved and resumed bit-for-bit (for example a prepared triaxial specimen).
impl ContactModel {
    /// The tangential history kept for the next evaluation: one entry per active contact of
    /// the last evaluation, `(global node id, counterpart, elastic tangential displacement
    /// d_s in m)`, sorted by surface node, then counterpart (bodies before walls).
    ///
    /// This is everything [`ContactModel::add_forces`] carries from one step to the next
    /// that changes the motion, besides the broad phase (which is rebuilt on demand and
    /// does not change results); [`ContactModel::checkpoint`] adds what the energy
    /// bookkeeping carries.
    pub fn export_history(&self) -> Vec<(usize, Counterpart, [f64; 3])> {
        self.history
            .iter()
            .map(|c| (c.node, c.counterpart, c.tangential_displacement))
            .collect()
    }

    /// Replaces the tangential history by `history` (as returned by
    /// [`ContactModel::export_history`] of a model built on the same surface and walls) and
    /// requests a broad-phase rebuild. The next [`ContactModel::add_forces`] continues every
    /// listed contact from its displacement; contacts not listed start from zero.
    ///
    /// Until that evaluation, [`ContactModel::node_contacts`] lists the imported entries
    /// with zero forces, depths and positions (only the history is meaningful).
    ///
    /// # Errors
    /// Nothing is changed when an entry names a node that is not a surface node of this
    /// model, a body that does not exist or is the node's own, a wall index out of range,
    /// a non-finite displacement, or the same (node, counterpart) twice.
    pub fn import_history(
        &mut self,
        history: &[(usize, Counterpart, [f64; 3])],
    ) -> Result<(), ContactError> {
        // An evaluation waiting for its forces would overwrite the imported history.
        self.evaluated = None;
        let fix = "import a history exported from a contact model built on the same \
                   assembly and walls";
        let index: std::collections::HashMap<usize, usize> = self
            .surface
            .surface_nodes
            .iter()
            .enumerate()
            .map(|(k, &node)| (node, k))
            .collect();
        let n_bodies = self.surface.node_body.iter().map(|&b| b as u64 + 1).max();
        let n_bodies = n_bodies.unwrap_or(0);
        let mut contacts = Vec::with_capacity(history.len());
        for (i, &(node, counterpart, displacement)) in history.iter().enumerate() {
            let Some(&k) = index.get(&node) else {
                return Err(ContactError::InconsistentSurface {
                    what: format!("history entry {i}: node {node} is not a surface node"),
                    fix,
                });
            };
            let body = self.surface.node_body[k];
            let valid = match counterpart {
                Counterpart::Body(b) => b != body && (b as u64) < n_bodies,
                Counterpart::Wall(w) => (w as usize) < self.walls.len(),
            };
            if !valid {
                return Err(ContactError::InconsistentSurface {
                    what: format!(
                        "history entry {i}: node {node} (body {body}) cannot touch {counterpart} \
                         ({n_bodies} bodies, {} walls)",
                        self.walls.len()
                    ),
                    fix,
                });
            }
            if !is_finite(displacement) {
                return Err(ContactError::NonFinite {
                    quantity: "tangential history",
                    node,
                    body,
                    value: displacement,
                });
            }
            contacts.push(NodeContact {
                key: history_key(k, counterpart),
                node,
                body,
                counterpart,
                face: None,
                weights: [0.0; 3],
                position: [0.0; 3],
                contact_point: [0.0; 3],
                depth: 0.0,
                normal_force: [0.0; 3],
                tangential_force: [0.0; 3],
                tangential_displacement: displacement,
                sliding: false,
                damping_force: [0.0; 3],
                relative_velocity: [0.0; 3],
                edge: false,
            });
        }
        contacts.sort_by_key(|c| c.key);
        if let Some(pair) = contacts.windows(2).find(|p| p[0].key == p[1].key) {
            return Err(ContactError::InconsistentSurface {
                what: format!(
                    "the history lists node {} against {} twice",
                    pair[0].node, pair[0].counterpart
                ),
                fix,
            });
        }
        self.history.replace(&contacts);
        self.rebuild_requested = true;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// Chunks of random spread terms over `n` nodes: face contacts, wall contacts and
    /// contacts without a face, many nodes hit by several.
    fn random_chunks(n: u32, contacts: usize) -> Vec<ChunkScratch> {
        let mut r = rand_pcg::Pcg64::seed_from_u64(7);
        let mut chunks = vec![ChunkScratch::default(); 5];
        for i in 0..contacts {
            let force = [(); 3].map(|_| r.random_range(-1.0..1.0));
            let a: f64 = r.random_range(0.0..1.0);
            let b: f64 = r.random_range(0.0..1.0 - a);
            let corners = match r.random_range(0..10) {
                0 => [NO_FACE, r.random_range(0..2), 0],
                1 => [NO_FACE; 3],
                _ => [(); 3].map(|_| r.random_range(0..n)),
            };
            chunks[i * 5 / contacts].terms.push(SpreadTerm {
                force,
                weights: [a, b, 1.0 - a - b],
                node: r.random_range(0..n),
                corners,
            });
        }
        chunks
    }

    /// The spread over node ranges gives every node the serial sum, bit for bit, with any
    /// number of threads (and ranges).
    #[test]
    fn the_spread_over_node_ranges_gives_the_serial_sums_bit_for_bit() {
        let n = 3001;
        let chunks = random_chunks(n, 2 * PARALLEL_SPREAD_MIN);
        let spread_with = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut forces = vec![[0.5; 3]; n as usize];
            let mut walls = vec![[1.0; 3]; 2];
            pool.install(|| spread_forces(&chunks, &mut forces, &mut walls));
            (forces, walls)
        };
        let (serial, serial_walls) = spread_with(1);
        // The serial sums, term by term, as the spread before the ranges added them.
        let mut expected = vec![[0.5; 3]; n as usize];
        let mut expected_walls = vec![[0.0; 3]; 2];
        for t in chunks.iter().flat_map(|c| &c.terms) {
            let node = &mut expected[t.node as usize];
            *node = add(*node, t.force);
            match t.corners {
                [NO_FACE, NO_FACE, _] => {}
                [NO_FACE, w, _] => {
                    let w = w as usize;
                    expected_walls[w] = sub(expected_walls[w], t.force);
                }
                corners => {
                    for (j, w) in corners.iter().zip(t.weights) {
                        let f = &mut expected[*j as usize];
                        *f = sub(*f, scale(t.force, w));
                    }
                }
            }
        }
        let bits =
            |f: &[[f64; 3]]| -> Vec<[u64; 3]> { f.iter().map(|v| v.map(f64::to_bits)).collect() };
        assert_eq!(bits(&serial), bits(&expected));
        assert_eq!(bits(&serial_walls), bits(&expected_walls));
        for threads in [2, 3, 7] {
            let (forces, walls) = spread_with(threads);
            assert_eq!(bits(&forces), bits(&serial), "{threads} threads");
            assert_eq!(bits(&walls), bits(&serial_walls), "{threads} threads");
        }
    }
}
