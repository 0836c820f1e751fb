//! The `[f64; 3]` helpers the kernels use: the project's one definition, in `fdem-core`.

pub(crate) use fdem_core::geometry::{add, cross, dot, is_finite, norm, norm2, scale, sub};
