//! Physical dimensions as exponents of length, time and mass (docs/MODEL.md section 4, eq 7).

use std::fmt;
use std::ops::{Div, Mul};

/// The dimension `L^length T^time M^mass` of a mechanical quantity (paper eq 7).
///
/// Mechanical quantities in this project need only the three base dimensions of length,
/// time and mass, with integer exponents. Dimensions multiply and divide by adding and
/// subtracting exponents, and raise to integer powers by multiplying them.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
pub struct Dimension {
    /// Exponent of length L.
    pub length: i32,
    /// Exponent of time T.
    pub time: i32,
    /// Exponent of mass M.
    pub mass: i32,
}

impl Dimension {
    /// The dimensionless dimension `1` (strain, friction coefficient, ...).
    pub const NONE: Dimension = Dimension::new(0, 0, 0);
    /// Length `L`.
    pub const LENGTH: Dimension = Dimension::new(1, 0, 0);
    /// Time `T`.
    pub const TIME: Dimension = Dimension::new(0, 1, 0);
    /// Mass `M`.
    pub const MASS: Dimension = Dimension::new(0, 0, 1);

    /// The dimension `L^length T^time M^mass`.
    pub const fn new(length: i32, time: i32, mass: i32) -> Self {
        Dimension { length, time, mass }
    }

    /// This dimension raised to an integer power: every exponent times `n`.
    pub const fn powi(self, n: i32) -> Self {
        Dimension::new(self.length * n, self.time * n, self.mass * n)
    }

    /// The reciprocal dimension (`1 / self`).
    pub const fn recip(self) -> Self {
        self.powi(-1)
    }

    /// True when all exponents are zero.
    pub const fn is_dimensionless(self) -> bool {
        self.length == 0 && self.time == 0 && self.mass == 0
    }
}

impl Mul for Dimension {
    type Output = Dimension;
    fn mul(self, rhs: Dimension) -> Dimension {
        Dimension::new(
            self.length + rhs.length,
            self.time + rhs.time,
            self.mass + rhs.mass,
        )
    }
}

impl Div for Dimension {
    type Output = Dimension;
    fn div(self, rhs: Dimension) -> Dimension {
        Dimension::new(
            self.length - rhs.length,
            self.time - rhs.time,
            self.mass - rhs.mass,
        )
    }
}

impl fmt::Display for Dimension {
    /// Writes the dimension the way the paper's Table 1 does: `L^-1 T^-2 M`, or `1`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_dimensionless() {
            return f.write_str("1");
        }
        let mut parts = Vec::with_capacity(3);
        for (symbol, exponent) in [("L", self.length), ("T", self.time), ("M", self.mass)] {
            match exponent {
                0 => {}
                1 => parts.push(symbol.to_string()),
                e => parts.push(format!("{symbol}^{e}")),
            }
        }
        f.write_str(&parts.join(" "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn algebra_adds_exponents() {
        let force = Dimension::new(1, -2, 1);
        let area = Dimension::LENGTH.powi(2);
        assert_eq!(force / area, Dimension::new(-1, -2, 1));
        assert_eq!(force * Dimension::LENGTH, Dimension::new(2, -2, 1));
        assert_eq!(Dimension::TIME.recip(), Dimension::new(0, -1, 0));
    }

    #[test]
    fn display_matches_table_1_notation() {
        assert_eq!(Dimension::new(-1, -2, 1).to_string(), "L^-1 T^-2 M");
        assert_eq!(Dimension::new(1, -2, 1).to_string(), "L T^-2 M");
        assert_eq!(Dimension::NONE.to_string(), "1");
    }
}
