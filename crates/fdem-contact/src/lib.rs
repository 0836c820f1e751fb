//! Penalty node-to-face contact between deformable bodies and rigid walls.
//!
//! # What this crate owns (an API boundary: other crates call it directly)
//! - **The contact law** ([`evaluate_law`], docs/MODEL.md section 2, paper eqs 1-3): normal
//!   penalty `F_n = max(0, k_n d_n + c_n v_approach)` with `k_n = p_n A` (eq 2) and
//!   `c_n = 2 beta_n sqrt(m k_n)` (eq 3); tangential elastic displacement with history,
//!   rotated into the current tangent plane, Coulomb cap `|F_s| <= mu F_n` with cut-back.
//!   Deviation from the paper: its `|k_n d_n - f_vd|` is replaced by a clamp at zero, so
//!   the normal force never attracts.
//! - **Detection** ([`ContactModel`]): a grid broad phase over the surface nodes with a
//!   Verlet skin (renewed only when a surface node has moved more than half the margin:
//!   the pairs of the bodies that drifted, or all of them, as a [`RefreshPolicy`]
//!   decides), a symmetric node-to-face narrow phase (nodes of A against faces of
//!   B and nodes of B against faces of A, so edges and faces cannot pass through each
//!   other), and rigid walls ([`Wall`]: planes and cylinders at a prescribed
//!   constant velocity).
//! - **Sheets** ([`ContactModel::set_sheet_bodies`], module `sheet`): bodies that are thin
//!   membranes contacted from one side, with faces oriented towards the particles, such as
//!   the triaxial test's membrane. There is no volume behind a sheet's face, so when it
//!   folds over angular particles "behind a face" no longer means "inside": a node that no
//!   face of a sheet covers is also tested against the sheet's edges and vertices (the
//!   holes at folded ridges), and a hit deeper than the sheet's fold depth is a fold
//!   artefact, discarded and counted ([`ContactReport::discarded_sheet_hits`]). The
//!   closest-face rule that goes with them holds for every body: a face of the same body
//!   that covers the node from the front, nearer than the hit, means the node is outside.
//! - **Rigid bodies' frames** ([`ContactModel::set_rigid_frames`], module `rigid_frames`):
//!   a caller whose rigid bodies' faces are placed instances of templates gives the
//!   templates, and before each evaluation the bodies' poses ([`RigidPose`]) and motions
//!   ([`RigidMotion`]). The plane filter and the foot screen then meet those faces in the
//!   template's frame, the per-step scan bounds the bodies' drift and speed from poses and
//!   motions instead of reading their nodes, and a face's velocity comes from its body's
//!   motion; every contact and force is the same, bit for bit, as without them.
//! - **Reactions**: equal and opposite on the face, spread to its three nodes by the
//!   barycentric weights of the contact point, so linear momentum is conserved to
//!   round-off. The normal force then also conserves angular momentum (it acts along the
//!   line from the node to the contact point); the tangential force leaves a couple
//!   `(x_node - x_contact) x F_s` of size `d_n |F_s|`, which vanishes with the penetration.
//! - **Bookkeeping**: stored energy, damping power, friction dissipation, wall power
//!   ([`ContactReport`]); the force on each wall; every node contact ([`NodeContact`]) and
//!   per body-pair sums ([`PairSum`]); the contact stable time step ([`StableStep`],
//!   docs/MODEL.md section 11).
//!
//! # What it does not own
//! No constitutive model, no masses of its own, no time integration: its inputs are
//! surface triangles with owner bodies, surface nodes with control areas
//! ([`ContactSurface`]), node masses, positions and velocities; its output is forces added
//! to a force array, plus reports. Node state and the time loop belong to `fdem-solver`,
//! meshes to `fdem-mesh`, elasticity to `fdem-elastic`.
//!
//! # Choices (documented assumptions)
//! - Control areas `A` are fixed at set-up from the reference configuration.
//! - A margin `delta` (m) sets the Verlet skin (rebuild when a node moved `delta / 2`,
//!   checked at every evaluation) and the tunnelling guard against sheets:
//!   [`ContactError::Tunnelling`] when a node moves more than `delta / 2` relative to a
//!   nearby sheet face in one step. Default: [`ContactModel::suggested_margin`], a tenth
//!   of the shortest surface edge.
//! - A depth limit `D` (m; `delta` unless [`ContactModel::set_depth_limit`] changes it):
//!   a node more than `D` behind a face is not in contact with it, and
//!   [`ContactError::PenetrationTooDeep`] fires when a node is more than `D / 2` behind a
//!   face (so a contact can never silently pass the depth limit). It is also the
//!   tunnelling scale against solid faces and walls: a node may move `D / 2` relative to
//!   them in one step, and no two nodes may approach by more than `D` (the distance that
//!   separates bodies outside each other's candidate lists).
//! - Broad phase: the surface nodes are binned in a uniform grid (cells of three quarters
//!   of the mean triangle box enlarged by `delta + D` plus the tolerance band); cells are
//!   numbered densely when the nodes' region is compact (up to 8 cells per node) and
//!   through a seedless hash table otherwise. Each triangle visits the cells its enlarged
//!   box overlaps: a node of another body there whose position the box holds and that
//!   lies within `delta + D` (plus the band) of the triangle is a candidate. Builds and
//!   evaluations are O(surface nodes + triangles + candidate pairs).
//! - Narrow phase: per (node, other body) the contact face is the nearest one (smallest
//!   depth) among the faces the node is behind with its foot inside (within
//!   [`BARYCENTRIC_TOLERANCE`]), on a sheet the nearest edge when no face covers the
//!   node; none when a nearer face of that body covers the node from the front (closest
//!   face), or when a sheet hit is deeper than the fold depth. The hand-written
//!   projection is the default kernel; the parry3d-f64 one (`ProjectionKernel::Parry`)
//!   gives the same contacts and is slower per pair (docs/PERFORMANCE.md, "Narrow phase:
//!   hand-written projection versus parry3d-f64"). A node without candidates is passed
//!   over when no wall can touch it in the evaluation (read from its position, or for a
//!   framed rigid body from its pose): it could have no contact and trip no check.
//! - Tangential history is keyed by (node, other body or wall), so it survives a switch of
//!   face on the same body, and is dropped when the contact opens.
//! - Parallelism (rayon): surface nodes are processed in fixed chunks of 512, each chunk
//!   writing its own contact records; forces are then added in the serial order of the
//!   contacts, one thread per range of node ids. The result is bit-for-bit the same for
//!   every thread count.
//!
//! # Modules
//! - `model`: [`ContactModel`] (set-up, settings, the three passes of
//!   [`ContactModel::add_forces`], history export and import) and its report types.
//! - `broad`: the node grid and the Verlet skin (candidate faces per surface node).
//! - `detect`: the narrow-phase pass, the contacts of each surface node against its
//!   candidates and the walls, evaluated with the law in fixed chunks.
//! - `history`: the last evaluation's contacts kept chunk by chunk, the next
//!   evaluation's tangential history.
//! - `sheet`: what a sheet body is, and the rules contact with it needs (closest point with
//!   its pseudo-normal, fold depth; the solids' closest-face rule) with their invariants.
//! - [`events`]: the optional log of contacts whose stored energy jumps in an evaluation.
//! - [`narrow`]: the node-face projections; `law`, `wall`, `surface`, `params`, `error`:
//!   the items re-exported below.

//! # Example: two overlapping spheres
//! ```
//! use fdem_contact::{ContactModel, ContactParams, ContactSurface};
//! use fdem_mesh::{ElementOrder, MeshAssembly, Placement, SphereSpec, sphere_mesh};
//!
//! let d = 0.015;
//! let particle = sphere_mesh(&SphereSpec { order: ElementOrder::Linear, ..SphereSpec::paper(d) })?;
//! let mut assembly = MeshAssembly::new();
//! assembly.push_instance(&particle, &Placement::at([0.0, 0.0, 0.0]))?;
//! // The second sphere's lowest vertex sits 10 um inside the first one's top vertex.
//! assembly.push_instance(&particle, &Placement::at([0.0, 0.0, d - 1e-5]))?;
//!
//! let surface = ContactSurface::from_assembly(&assembly)?;
//! let masses = vec![1e-3; assembly.n_nodes()];
//! let margin = ContactModel::suggested_margin(&surface, &assembly.nodes).unwrap();
//! let mut contact = ContactModel::new(ContactParams::default(), surface, vec![], &masses, margin)?;
//!
//! let velocities = vec![[0.0; 3]; assembly.n_nodes()];
//! let mut forces = vec![[0.0; 3]; assembly.n_nodes()];
//! let report = contact.add_forces(&assembly.nodes, &velocities, 0.0, 1e-7, &mut forces)?;
//! assert!(report.contacts >= 2); // each top/bottom vertex is inside the other sphere
//!
//! // Equal and opposite: the forces on the two bodies cancel.
//! let on_body = |b: usize| -> f64 { assembly.bodies[b].nodes.clone().map(|i| forces[i][2]).sum() };
//! assert!(on_body(1) > 0.0);
//! assert!((on_body(0) + on_body(1)).abs() < 1e-12 * on_body(1));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![warn(missing_docs)]

mod broad;
mod detect;
mod error;
pub mod events;
mod history;
mod law;
mod mean_motion;
mod model;
pub mod narrow;
mod params;
mod prefetch;
mod rigid_frames;
mod scan;
mod sheet;
mod surface;
mod vec3;
mod wall;

pub use error::{ContactError, TunnellingScale};
pub use law::{LawInput, LawOutput, evaluate_law};
pub use model::{
    ContactCheckpoint, ContactModel, ContactReport, Counterpart, DEPTH_LIMIT_GROWTH,
    MARGIN_EDGE_FRACTION, NodeContact, PairSum, RefreshPolicy, StableStep, TUNNELLING_FRACTION,
};
pub use narrow::{BARYCENTRIC_TOLERANCE, FaceHit, ProjectionKernel, front_distance};
pub use params::{ContactParams, NodeCoefficients, Requirement, spring_dashpot_time_step};
pub use rigid_frames::{RigidMotion, RigidPose, RigidTemplate};
pub use surface::ContactSurface;
pub use wall::{Wall, WallShape};
