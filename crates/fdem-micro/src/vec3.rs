//! The 3-vector helpers: the project's one definition, in `fdem-core`.

pub(crate) use fdem_core::geometry::{add, cross, distance, norm, scale, sub};
