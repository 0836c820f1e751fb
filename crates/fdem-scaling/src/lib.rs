//! # fdem-scaling: dimensions, quantities and exact-scaling laws
//!
//! This crate owns dimensional analysis for the project (MODEL.md section 4, paper eqs 6-11):
//! the [`Dimension`] of a mechanical quantity as exponents of length, time and mass; a
//! [`CATALOGUE`] of named quantities (every row of the paper's Table 1 and the follow-ons
//! scenes need); and [`ScaleLaw`]s that give the factor of any dimension from three base
//! factors. The base factors are *derived*: [`ScaleLaw::solve`] takes a length factor `h`
//! and two quantities to hold invariant and solves for the time and mass factors;
//! [`ScaleLaw::exact`] holds density and Young's modulus invariant, which gives the paper's
//! exact scaling `lambda_L = h, lambda_T = h, lambda_M = h^3` (eq 9). Table 1 is an output
//! of this crate ([`table`]), never an input.
//!
//! It knows nothing of meshes, scenes or solvers; those crates declare the dimension of
//! each of their fields and ask this crate for the factor.
//!
//! ## Example: the factor of a quantity the catalogue does not name
//! Dynamic viscosity has units Pa s, dimension `L^-1 T^-1 M`. Under exact scaling by
//! `h = 2` it scales by `2^-1 * 2^-1 * 2^3 = 2`:
//! ```
//! use fdem_scaling::{Dimension, ScaleLaw, dimension_of};
//!
//! let stress = dimension_of("stress").unwrap();
//! let viscosity: Dimension = stress * Dimension::TIME; // Pa s
//! assert_eq!(viscosity, Dimension::new(-1, -1, 1));
//!
//! let law = ScaleLaw::exact(2.0)?;
//! assert_eq!(law.factor(viscosity), 2.0);
//! # Ok::<(), fdem_scaling::ScalingError>(())
//! ```
#![warn(missing_docs)]

mod catalogue;
mod dimension;
mod law;

pub use catalogue::{CATALOGUE, Quantity, dimension_of, quantity};
pub use dimension::Dimension;
pub use law::{HExponents, Rational, ScaleLaw};

/// Errors of the scaling crate.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ScalingError {
    /// A scale factor that is not a finite positive number.
    #[error("scale factor {name} = {value} is invalid: it must be a finite number greater than 0")]
    InvalidFactor {
        /// Which factor (`h`, `length`, `time`, `mass`).
        name: String,
        /// The value given.
        value: f64,
    },
    /// The two invariant quantities do not determine the time and mass factors.
    #[error(
        "holding {first} and {second} invariant does not determine the time and mass factors \
         (their dimensions give a singular system); choose two quantities whose time and mass \
         exponents are independent, such as density and youngs_modulus"
    )]
    NoUniqueSolution {
        /// First invariant quantity.
        first: String,
        /// Second invariant quantity.
        second: String,
    },
    /// A quantity the project relies on is missing from the catalogue (a bug, not a user error).
    #[error("internal error: quantity `{0}` is missing from the catalogue")]
    Internal(&'static str),
}

/// One row of a scaling table: a catalogued quantity and its factor under a law.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TableRow {
    /// The quantity.
    pub quantity: &'static Quantity,
    /// Its factor under the law.
    pub factor: f64,
}

/// The factor of every catalogued quantity under `law`, in catalogue order (Table 1 first).
pub fn table(law: &ScaleLaw) -> Vec<TableRow> {
    CATALOGUE
        .iter()
        .map(|quantity| TableRow {
            quantity,
            factor: law.factor(quantity.dimension),
        })
        .collect()
}
