//! Tetrahedral meshes of spherical particles for the FDEM simulator.
//!
//! # What this crate owns
//! - **Particle meshes** ([`sphere_mesh`]): an icosahedron subdivided `level` times
//!   (`0..=4`) plus ONE centre node; every surface triangle together with the centre is one
//!   tetrahedron. Linear (4-node) or quadratic (10-node, straight-edged) elements. Level 1
//!   quadratic is the source paper's particle: 80 tetrahedra, 205 nodes.
//! - **Surfaces** ([`Surface`]): flat outward 3-node triangles (a quadratic face is split
//!   into 4), the sorted surface nodes and their control areas.
//! - **Quality figures** ([`MeshQuality`]): volume, area, edge lengths, smallest altitude,
//!   dihedral angles.
//! - **Placement** ([`MeshAssembly`], [`Placement`]): copies of a template scaled, rotated
//!   and translated into global structure-of-arrays; each body a contiguous range that
//!   shares no node with another.
//! - **VTK output** ([`vtu`]): `.vtu` frames (generic, reused by the solver for time
//!   series) and `.pvd` collections, written atomically (temporary name, then rename).
//!
//! # What it does not own
//! No physics: no materials, masses, stiffness or time steps (`fdem-elastic`), no contact
//! detection or contact forces (`fdem-contact`), no node state or time integration
//! (`fdem-solver`).
//!
//! # Element node ordering (project-wide convention)
//! Corners `0..4` are positively oriented: the signed volume
//! `(x1 - x0) · ((x2 - x0) × (x3 - x0)) / 6` is > 0. Quadratic elements follow with the
//! mid-edge nodes in VTK_QUADRATIC_TETRA order ([`TET_EDGES`]):
//! `4:(0,1) 5:(1,2) 6:(0,2) 7:(0,3) 8:(1,3) 9:(2,3)`. Mid-edge nodes sit at the midpoints
//! of the straight edges (they are not projected on the sphere) and each edge has exactly one
//! mid-edge node, shared by all elements around it. Sphere elements have corners
//! `[centre, a, b, c]` with `a b c` a surface face seen counter-clockwise from outside.
//!
//! # Sizing
//! [`Sizing::Inscribed`] (default, the paper's reading) puts the surface vertices on the
//! sphere of the nominal diameter, so a particle holds less solid than the sphere (0.8735
//! of it at level 1) and a specimen's real solid fraction is the nominal one times that
//! ratio. [`Sizing::VolumeEquivalent`] scales the mesh so its volume equals `pi d^3 / 6` and
//! the real solid fraction equals the nominal one. Particle counts always use the nominal
//! sphere volume. The centre node is at the origin in both cases.
//!
//! # Counts
//! | level | tets | linear nodes | quadratic nodes | surface triangles (lin / quad) | surface nodes (lin / quad) |
//! |---|---|---|---|---|---|
//! | 0 | 20 | 13 | 55 | 20 / 80 | 12 / 42 |
//! | 1 | 80 | 43 | 205 | 80 / 320 | 42 / 162 |
//! | 2 | 320 | 163 | 805 | 320 / 1280 | 162 / 642 |
//! | 3 | 1280 | 643 | 3205 | 1280 / 5120 | 642 / 2562 |
//! | 4 | 5120 | 2563 | 12805 | 5120 / 20480 | 2562 / 10242 |
//!
//! # Example
//! ```
//! use fdem_mesh::{sphere_mesh, MeshAssembly, Placement, SphereSpec};
//!
//! let particle = sphere_mesh(&SphereSpec::paper(0.015))?;
//! assert_eq!((particle.n_elements(), particle.n_nodes()), (80, 205));
//!
//! let mut specimen = MeshAssembly::new();
//! let body = specimen.push_instance(&particle, &Placement::at([0.0, 0.0, 0.1]))?;
//! assert_eq!(specimen.bodies[body].nodes, 0..205);
//! # Ok::<(), fdem_mesh::MeshError>(())
//! ```

#![warn(missing_docs)]

mod assembly;
mod error;
mod mesh;
mod sphere;
pub mod vtu;

/// Small geometric formulas on `[f64; 3]` points (the project's one definition, in
/// `fdem-core`), used by the mesh code and re-exported here for its users.
pub use fdem_core::geometry;

pub use assembly::{BodyRange, MeshAssembly, Placement, ROTATION_NORM_TOLERANCE};
pub use error::MeshError;
pub use mesh::{
    ElementOrder, MeshQuality, Surface, TET_EDGES, TetMesh, VolumeProperties, volume_properties,
};
pub use sphere::{MAX_LEVEL, MAX_SHELLS, Sizing, SphereSpec, sphere_mesh, sphere_mesh_in_shells};
pub use vtu::{CellNodes, VtuField, VtuFrame, write_pvd, write_vtu};
