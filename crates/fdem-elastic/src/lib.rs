//! # fdem-elastic (not yet implemented)
//!
//! Will own isotropic linear elasticity on tetrahedra: materials, co-rotational 4- and
//! 10-node element kernels, lumped masses, per-element stable time-step bounds, Cauchy
//! stress and strain energy. It will know nothing of contact or time integration. This
//! crate is an empty placeholder until the elastic/solver issue fills it.
#![warn(missing_docs)]
