//! The catalogue of named mechanical quantities and their dimensions.
//!
//! Every row of the paper's Table 1 (docs/MODEL.md section 4) plus the quantities the scenes and
//! the triaxial test need. The dimensions are the only thing stated here; scale factors are
//! always derived from them by a [`ScaleLaw`](crate::ScaleLaw), never tabulated.

use crate::Dimension;

/// A named mechanical quantity with its dimension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Quantity {
    /// Identifier in snake_case, as used in JSON output and scene declarations.
    pub name: &'static str,
    /// Conventional symbol (as in the paper where it has one).
    pub symbol: &'static str,
    /// SI unit of the quantity.
    pub unit: &'static str,
    /// Dimension `L^a T^b M^c`.
    pub dimension: Dimension,
}

const fn q(
    name: &'static str,
    symbol: &'static str,
    unit: &'static str,
    length: i32,
    time: i32,
    mass: i32,
) -> Quantity {
    Quantity {
        name,
        symbol,
        unit,
        dimension: Dimension::new(length, time, mass),
    }
}

/// All named quantities: first the rows of Table 1 in the paper's order, then the
/// follow-on quantities of docs/MODEL.md section 4.
pub const CATALOGUE: &[Quantity] = &[
    // Table 1 of the source paper.
    q("length", "L", "m", 1, 0, 0),
    q("time", "T", "s", 0, 1, 0),
    q("mass", "m", "kg", 0, 0, 1),
    q("force", "F", "N", 1, -2, 1),
    q("stress", "sigma", "Pa", -1, -2, 1),
    q("strain", "eps", "1", 0, 0, 0),
    q("youngs_modulus", "E", "Pa", -1, -2, 1),
    q("poisson_ratio", "nu", "1", 0, 0, 0),
    q("penalty_stiffness", "p_c", "N/m^3", -2, -2, 1),
    q("friction", "mu", "1", 0, 0, 0),
    q("damping", "beta_c", "1", 0, 0, 0),
    // Follow-on quantities.
    q("density", "rho", "kg/m^3", -3, 0, 1),
    q("velocity", "v", "m/s", 1, -1, 0),
    q("acceleration", "g", "m/s^2", 1, -2, 0),
    q("angular_velocity", "omega", "rad/s", 0, -1, 0),
    q("pressure", "p", "Pa", -1, -2, 1),
    q("energy", "W", "J", 2, -2, 1),
    q("contact_stiffness", "k_c", "N/m", 0, -2, 1),
    q("damping_coefficient", "c", "N s/m", 0, -1, 1),
    q("time_step", "dt", "s", 0, 1, 0),
    q("volume", "V", "m^3", 3, 0, 0),
    q("area", "A", "m^2", 2, 0, 0),
    q("strain_rate", "eps_dot", "1/s", 0, -1, 0),
    q("ratio", "-", "1", 0, 0, 0),
];

/// Looks a quantity up by its snake_case name.
pub fn quantity(name: &str) -> Option<&'static Quantity> {
    CATALOGUE.iter().find(|q| q.name == name)
}

/// The dimension of a catalogued quantity, by name (`None` for an unknown name).
pub fn dimension_of(name: &str) -> Option<Dimension> {
    quantity(name).map(|q| q.dimension)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_snake_case() {
        for (i, a) in CATALOGUE.iter().enumerate() {
            assert!(
                a.name
                    .chars()
                    .all(|c| c.is_ascii_lowercase() || c == '_' || c.is_ascii_digit()),
                "{} is not snake_case",
                a.name
            );
            for b in &CATALOGUE[i + 1..] {
                assert_ne!(a.name, b.name);
            }
        }
    }

    #[test]
    fn derived_dimensions_are_consistent() {
        let d = |n| dimension_of(n).unwrap();
        assert_eq!(d("force"), d("mass") * d("acceleration"));
        assert_eq!(d("stress"), d("force") / d("area"));
        assert_eq!(d("penalty_stiffness"), d("stress") / d("length"));
        assert_eq!(d("contact_stiffness"), d("penalty_stiffness") * d("area"));
        assert_eq!(d("energy"), d("force") * d("length"));
        assert_eq!(d("density"), d("mass") / d("volume"));
        // Damping force 2 beta sqrt(m k) v (paper eq 3) is a force.
        let sqrt_mk_squared = d("mass") * d("contact_stiffness");
        assert_eq!(d("damping_coefficient").powi(2), sqrt_mk_squared);
        assert_eq!(d("damping_coefficient") * d("velocity"), d("force"));
    }
}
