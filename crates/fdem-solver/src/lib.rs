//! # fdem-solver (not yet implemented)
//!
//! Will own the explicit dynamics engine: node state in structure-of-arrays form, bodies as
//! contiguous node and element ranges, the force-contribution interface (elements, contact,
//! walls, membranes), central-difference time stepping with an automatic stable step,
//! energy bookkeeping, the stability guard, TOML scenes and run outputs. This crate is an
//! empty placeholder until the elastic/solver issue fills it.
#![warn(missing_docs)]
