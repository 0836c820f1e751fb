//! Co-rotational linear elastic tetrahedra for the FDEM simulator.
//!
//! # What this crate owns
//! * [`Material`]: isotropic linear elasticity (density, Young's modulus, Poisson's ratio),
//!   Lamé parameters and wave speeds (docs/MODEL.md section 3).
//! * [`ElementSet`]: all tetrahedra of one body (4-node linear or 10-node quadratic), with
//!   reference data precomputed once; elastic nodal forces, strain energy and element
//!   stresses for given node positions; lumped nodal masses; the per-element stable time
//!   step of explicit central differences (docs/MODEL.md section 11), and the assembled body's
//!   bound estimated by power iteration ([`ElementSet::assembled_time_step`]).
//! * [`polar_rotation`]: the rotation of the polar decomposition of a 3x3 matrix.
//!
//! # What it does not own
//! It knows nothing of contact, of the time integrator, of meshes as data structures, or of
//! other bodies: it works on plain node arrays (`&[[f64; 3]]`, SI units) and a flat
//! connectivity of body-local node ids. Node state, integration and contact live in other
//! crates.
//!
//! # Formulation
//! Co-rotational linear elasticity (Felippa & Haugen 2005; Nour-Omid & Rankin 1991). Per
//! element, `F` is the deformation gradient (`F = sum_a x_a (x) grad N_a`), `R` the rotation
//! of its polar decomposition `F = R U` (for 10-node elements, of `F` at the centroid),
//! `u_i = R^T x_i - X_i` the local displacement, `eps = sym(R^T F) - I` the co-rotated small
//! strain and `sigma = lambda tr(eps) I + 2 G eps` the co-rotated stress. The strain energy
//! is `W = u^T K_e u / 2` and the nodal forces are exactly `-dW/dx`:
//! * 4-node: `f_a = -V R sigma grad N_a` (`= -R K_e u`; the derivative of `R` contributes
//!   nothing because `R sigma F^T` is symmetric);
//! * 10-node: `-R K_e u`, integrated exactly from the four corner stresses (the stress is
//!   linear in a straight-sided element), plus the term from the derivative of the centroid
//!   rotation, which is second order in the strain variation over the element.
//!
//! So the model is hyperelastic: the forces conserve energy (up to the integrator),
//! linear momentum and angular momentum, and the tangent at rest is `K_e`.
//! See `kernels.rs` (equations C1-C2, Q1-Q5) for the derivations.
//!
//! A rigid rotation of any angle gives zero strain and force to round-off: the polar
//! rotation is computed to within 1e-14 by Newton–Schulz / scaled Newton iterations (see
//! [`polar`]). An element with `det F <= 0` (inverted or flat) is an error naming the
//! element; no method returns NaN.
//!
//! Conventions: SI units, `f64`; node positions `[f64; 3]`; element connectivity a flat
//! `&[usize]`, `nodes_per_element` body-local node ids per element; corner nodes 0..3
//! positively oriented; 10-node mid-edge order VTK_QUADRATIC_TETRA
//! (4:(0,1) 5:(1,2) 6:(0,2) 7:(0,3) 8:(1,3) 9:(2,3)), mid-edge nodes at the midpoints of
//! straight edges in the rest configuration. Stresses in Voigt order
//! `(xx, yy, zz, yz, xz, xy)`.

#![warn(missing_docs)]

mod assembled_step;
mod element_set;
mod error;
mod kernels;
mod lamb;
mod lanes;
mod mat3;
mod material;
mod modes;
pub mod polar;

pub use assembled_step::{ASSEMBLED_STEP_MAX_ITERATIONS, ASSEMBLED_STEP_TOLERANCE, AssembledStep};
pub use element_set::{
    ElementSet, HRZ_CORNER_FRACTION, HRZ_MID_EDGE_FRACTION, TetKind, lumped_masses,
};
pub use error::ElasticError;
pub use lamb::lamb_spheroidal_frequency;
pub use mat3::Mat3;
pub use material::Material;
pub use modes::{VIBRATION_MODE_TOLERANCE, VibrationMode};
pub use polar::polar_rotation;

#[cfg(test)]
mod send_sync {
    fn assert_send_sync<T: Send + Sync>() {}
    #[test]
    fn element_set_is_send_and_sync() {
        assert_send_sync::<crate::ElementSet>();
        assert_send_sync::<crate::Material>();
        assert_send_sync::<crate::ElasticError>();
    }
}
