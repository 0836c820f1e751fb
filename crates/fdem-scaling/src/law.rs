//! Scale laws: factors of every quantity from three base factors (paper eqs 8-9).

use crate::{Dimension, ScalingError};
use std::fmt;

/// An exact rational number `num / den` with `den > 0`, reduced.
///
/// Base-factor exponents come out of a 2x2 integer system (Cramer's rule), so they are
/// rational; keeping them exact lets integer powers of `h` be evaluated exactly
/// (`4^2 = 16`, not `16.000000000000004`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rational {
    /// Numerator.
    pub num: i64,
    /// Denominator, always positive.
    pub den: i64,
}

impl Rational {
    fn new(num: i64, den: i64) -> Option<Self> {
        if den == 0 {
            return None;
        }
        let g = gcd(num.unsigned_abs(), den.unsigned_abs()).max(1) as i64;
        let sign = if den < 0 { -1 } else { 1 };
        Some(Rational {
            num: sign * num / g,
            den: sign * den / g,
        })
    }

    /// The integer value, if the number is an integer.
    pub fn as_integer(self) -> Option<i64> {
        (self.den == 1).then_some(self.num)
    }

    /// The value as a float.
    pub fn to_f64(self) -> f64 {
        self.num as f64 / self.den as f64
    }
}

impl Rational {
    /// `self + other`.
    pub fn plus(self, other: Rational) -> Rational {
        // Denominators here are tiny (from 2x2 integer systems): no overflow.
        Rational::new(
            self.num * other.den + other.num * self.den,
            self.den * other.den,
        )
        .unwrap_or(self)
    }

    /// `self * n`.
    pub fn times(self, n: i64) -> Rational {
        Rational::new(self.num * n, self.den).unwrap_or(self)
    }
}

impl HExponents {
    /// The exponent `e` of h in the factor `h^e` of a quantity of dimension `d`:
    /// `e = a + b p + c q` for `d = L^a T^b M^c`, `lambda_T = h^p`, `lambda_M = h^q`.
    pub fn of(&self, d: crate::Dimension) -> Rational {
        Rational {
            num: d.length as i64,
            den: 1,
        }
        .plus(self.time.times(d.time as i64))
        .plus(self.mass.times(d.mass as i64))
    }
}

impl fmt::Display for Rational {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.as_integer() {
            Some(n) => write!(f, "{n}"),
            None => write!(f, "{}/{}", self.num, self.den),
        }
    }
}

fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// `h^e`, exact for integer `e` whenever the result is representable.
fn power(h: f64, e: Rational) -> f64 {
    match e.as_integer().and_then(|n| i32::try_from(n).ok()) {
        Some(n) => h.powi(n),
        None => h.powf(e.to_f64()),
    }
}

/// A scale law: base factors `lambda_L, lambda_T, lambda_M` for length, time and mass.
///
/// Any quantity of dimension `L^a T^b M^c` scales by
/// `lambda_L^a * lambda_T^b * lambda_M^c` (paper eq 8), see [`ScaleLaw::factor`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScaleLaw {
    /// Length factor `lambda_L`.
    pub length: f64,
    /// Time factor `lambda_T`.
    pub time: f64,
    /// Mass factor `lambda_M`.
    pub mass: f64,
}

/// The factor of one quantity, as the exponents of `h` it was derived with, when the law
/// came from [`ScaleLaw::solve`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HExponents {
    /// Exponent of `h` in `lambda_T`.
    pub time: Rational,
    /// Exponent of `h` in `lambda_M`.
    pub mass: Rational,
}

impl ScaleLaw {
    /// The identity law (all factors 1).
    pub const IDENTITY: ScaleLaw = ScaleLaw {
        length: 1.0,
        time: 1.0,
        mass: 1.0,
    };

    /// A law from explicit base factors; each must be finite and positive.
    pub fn from_base_factors(length: f64, time: f64, mass: f64) -> Result<Self, ScalingError> {
        for (name, value) in [("length", length), ("time", time), ("mass", mass)] {
            check_factor(name, value)?;
        }
        Ok(ScaleLaw { length, time, mass })
    }

    /// Exact scaling (paper eq 9): length factor `h` with density and Young's modulus held
    /// invariant, which the solver turns into `lambda_T = h`, `lambda_M = h^3`.
    pub fn exact(h: f64) -> Result<Self, ScalingError> {
        let density = crate::dimension_of("density").ok_or(ScalingError::Internal("density"))?;
        let modulus = crate::dimension_of("youngs_modulus")
            .ok_or(ScalingError::Internal("youngs_modulus"))?;
        Ok(Self::solve(h, [("density", density), ("youngs_modulus", modulus)])?.0)
    }

    /// Derives the base factors from a length factor `h` and two quantities held invariant
    /// (factor 1).
    ///
    /// Writing `lambda_T = h^p`, `lambda_M = h^q`, each invariant quantity `L^a T^b M^c`
    /// gives one linear equation `a + b p + c q = 0` in log space; the 2x2 system is solved
    /// exactly (Cramer's rule over the integers). A singular system, where the two
    /// quantities do not pin time and mass down (for example strain and friction, which are
    /// dimensionless), is an error naming them.
    pub fn solve(
        h: f64,
        invariants: [(&str, Dimension); 2],
    ) -> Result<(Self, HExponents), ScalingError> {
        check_factor("h", h)?;
        let [(name1, d1), (name2, d2)] = invariants;
        // b1 p + c1 q = -a1 ; b2 p + c2 q = -a2
        let (b1, c1, r1) = (d1.time as i64, d1.mass as i64, -(d1.length as i64));
        let (b2, c2, r2) = (d2.time as i64, d2.mass as i64, -(d2.length as i64));
        let det = b1 * c2 - b2 * c1;
        let singular = || ScalingError::NoUniqueSolution {
            first: name1.to_string(),
            second: name2.to_string(),
        };
        if det == 0 {
            return Err(singular());
        }
        let p = Rational::new(r1 * c2 - r2 * c1, det).ok_or_else(singular)?;
        let q = Rational::new(b1 * r2 - b2 * r1, det).ok_or_else(singular)?;
        let law = ScaleLaw {
            length: h,
            time: power(h, p),
            mass: power(h, q),
        };
        // Every catalogued factor must be a number (h = 1e300 overflows the mass factor).
        for quantity in crate::CATALOGUE {
            let factor = law.factor(quantity.dimension);
            if !(factor.is_finite() && factor > 0.0) {
                return Err(ScalingError::FactorOutOfRange {
                    name: "h".into(),
                    value: h,
                    quantity: quantity.name.into(),
                    factor,
                });
            }
        }
        Ok((law, HExponents { time: p, mass: q }))
    }

    /// The factor of a quantity of dimension `L^a T^b M^c`:
    /// `lambda_L^a lambda_T^b lambda_M^c` (paper eq 8).
    pub fn factor(&self, dimension: Dimension) -> f64 {
        self.length.powi(dimension.length)
            * self.time.powi(dimension.time)
            * self.mass.powi(dimension.mass)
    }

    /// The factor of a catalogued quantity by name (`None` for an unknown name).
    pub fn factor_of(&self, name: &str) -> Option<f64> {
        crate::dimension_of(name).map(|d| self.factor(d))
    }

    /// This law followed by `next`: base factors multiply.
    pub fn then(&self, next: &ScaleLaw) -> ScaleLaw {
        ScaleLaw {
            length: self.length * next.length,
            time: self.time * next.time,
            mass: self.mass * next.mass,
        }
    }

    /// The law that undoes this one.
    pub fn inverse(&self) -> ScaleLaw {
        ScaleLaw {
            length: 1.0 / self.length,
            time: 1.0 / self.time,
            mass: 1.0 / self.mass,
        }
    }
}

fn check_factor(name: &str, value: f64) -> Result<(), ScalingError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ScalingError::InvalidFactor {
            name: name.to_string(),
            value,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dimension_of;

    fn dim(name: &str) -> Dimension {
        dimension_of(name).unwrap()
    }

    #[test]
    fn exact_law_comes_out_of_the_solver() {
        let (law, exps) = ScaleLaw::solve(
            2.0,
            [
                ("density", dim("density")),
                ("youngs_modulus", dim("youngs_modulus")),
            ],
        )
        .unwrap();
        assert_eq!(exps.time.as_integer(), Some(1));
        assert_eq!(exps.mass.as_integer(), Some(3));
        assert_eq!((law.length, law.time, law.mass), (2.0, 2.0, 8.0));
    }

    #[test]
    fn integer_powers_are_exact() {
        let law = ScaleLaw::exact(4.0).unwrap();
        assert_eq!(law.factor_of("force"), Some(16.0));
        assert_eq!(law.factor_of("time"), Some(4.0));
        assert_eq!(law.factor_of("mass"), Some(64.0));
        assert_eq!(law.factor_of("penalty_stiffness"), Some(0.25));
        assert_eq!(law.factor_of("stress"), Some(1.0));
    }

    #[test]
    fn gravity_invariant_law_is_froude_scaling() {
        // Holding acceleration and density invariant: lambda_T = sqrt(h), lambda_M = h^3.
        let (law, exps) = ScaleLaw::solve(
            4.0,
            [
                ("acceleration", dim("acceleration")),
                ("density", dim("density")),
            ],
        )
        .unwrap();
        assert_eq!(exps.time, Rational { num: 1, den: 2 });
        assert_eq!(exps.mass.as_integer(), Some(3));
        assert_eq!(law.time, 2.0);
        assert_eq!(law.factor_of("acceleration"), Some(1.0));
        // Stress is no longer invariant: it scales by h.
        assert_eq!(law.factor_of("stress"), Some(4.0));
    }

    /// A factor whose powers leave the floating-point range is refused with the first
    /// quantity whose factor is not a number, instead of giving infinite or NaN factors.
    #[test]
    fn factors_beyond_the_floating_point_range_are_refused() {
        for h in [1e300, 1e-300, 1e120] {
            match ScaleLaw::exact(h) {
                Err(ScalingError::FactorOutOfRange { value, factor, .. }) => {
                    assert_eq!(value, h);
                    assert!(!(factor.is_finite() && factor > 0.0), "{factor}");
                }
                other => panic!("h = {h}: {other:?}"),
            }
        }
        let law = ScaleLaw::exact(1e20).unwrap();
        assert!(
            crate::CATALOGUE
                .iter()
                .all(|q| law.factor(q.dimension).is_finite())
        );
    }

    #[test]
    fn singular_choices_are_refused_with_names() {
        let err = ScaleLaw::solve(
            2.0,
            [("strain", dim("strain")), ("friction", dim("friction"))],
        )
        .unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("strain") && msg.contains("friction"), "{msg}");
        // Stress and Young's modulus share a dimension: one equation twice.
        assert!(
            ScaleLaw::solve(
                2.0,
                [
                    ("stress", dim("stress")),
                    ("youngs_modulus", dim("youngs_modulus"))
                ]
            )
            .is_err()
        );
    }

    #[test]
    fn bad_h_is_refused() {
        for h in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(ScaleLaw::exact(h).is_err(), "h = {h}");
        }
    }
}
