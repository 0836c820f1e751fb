//! Shared fixtures for the criterion benchmarks and the bench examples.

pub mod lattice;
