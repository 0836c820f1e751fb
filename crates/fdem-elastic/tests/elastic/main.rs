//! Integration tests of fdem-elastic: one test binary, one module per topic.
//!
//! Every tolerance is stated next to its assertion together with where it comes from.

// Index loops over the 3 coordinates read like the formulas they check.
#![allow(clippy::needless_range_loop)]

mod common;
mod conservative;
mod dynamics;
mod errors;
mod mass;
mod material;
mod objectivity;
mod patch;
mod rigid;
