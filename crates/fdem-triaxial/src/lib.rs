//! # fdem-triaxial (not yet implemented)
//!
//! Will own the numerical triaxial test of the source paper: the specimen catalogue
//! (Tables 2 and 4), particle counts, preparation by the dynamic method, the flexible
//! membrane, consolidation and shear loading, and the measurements of paper eqs 12-15.
//! This crate is an empty placeholder until the specimen and triaxial issues fill it.
#![warn(missing_docs)]
