//! # fdem-contact (not yet implemented)
//!
//! Will own penalty node-to-face contact between deformable particles and rigid walls
//! (MODEL.md section 2, paper eqs 1-3): a spatial-hash broad phase over surface triangles
//! with a Verlet skin, a symmetric node-to-face narrow phase, the normal penalty law with
//! viscous damping, Coulomb friction with per-contact tangential history, and the stable
//! time-step contribution of each node's spring-dashpot. It will know nothing of
//! constitutive models: its inputs are surface triangles, node positions, velocities and
//! masses. This crate is an empty placeholder until the contact issue fills it.
#![warn(missing_docs)]
