//! Contact parameters (paper Table 3) and the per-node coefficients they give (eqs 2-3).

use serde::{Deserialize, Serialize};

use crate::ContactError;

/// Parameters of the penalty contact law (docs/MODEL.md section 2, paper eqs 1-3, Table 3).
///
/// The default is the source paper's Table 3.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactParams {
    /// Normal penalty per unit area `p_n` (N/m^3); a node's normal stiffness is
    /// `k_n = p_n A` with `A` its control area (eq 2). Finite and > 0.
    pub normal_penalty: f64,
    /// Ratio `p_s / p_n` of the tangential to the normal penalty (eq 2). Finite and > 0.
    pub penalty_ratio: f64,
    /// Coulomb friction coefficient `mu` (eq 1, `|F_s| <= mu F_n`). Finite and >= 0.
    pub friction: f64,
    /// Normal damping ratio `beta_n` (eq 3, `c_n = 2 beta_n sqrt(m k_n)`). Finite and >= 0.
    pub damping: f64,
    /// Ratio `beta_s / beta_n` of the tangential to the normal damping ratio (eq 3).
    /// Finite and >= 0.
    pub damping_ratio: f64,
}

impl Default for ContactParams {
    /// Paper Table 3: `p_n = 1.8e11 N/m^3`, `p_s/p_n = 1`, `mu = 0.3`, `beta = 0.2`,
    /// `beta_s/beta_n = 1`.
    fn default() -> Self {
        ContactParams {
            normal_penalty: 1.8e11,
            penalty_ratio: 1.0,
            friction: 0.3,
            damping: 0.2,
            damping_ratio: 1.0,
        }
    }
}

/// Spring and dashpot coefficients of one surface node (eqs 2-3).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NodeCoefficients {
    /// Normal stiffness `k_n = p_n A` (N/m).
    pub normal_stiffness: f64,
    /// Normal dashpot `c_n = 2 beta_n sqrt(m k_n)` (N s/m).
    pub normal_damping: f64,
    /// Tangential stiffness `k_s = (p_s/p_n) k_n` (N/m).
    pub tangential_stiffness: f64,
    /// Tangential dashpot `c_s = 2 beta_s sqrt(m k_s)`, `beta_s = beta_n (beta_s/beta_n)`
    /// (N s/m).
    pub tangential_damping: f64,
    /// Friction coefficient `mu`.
    pub friction: f64,
}

/// The range a parameter of the law must lie in.
///
/// Each field of [`ContactParams`] has one (the `ContactParams::*` constants below): they
/// are the one definition of what the law accepts, used by [`ContactParams::validate`]
/// and by the TOML schemas' range checks, which report the same rule with a line number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Requirement {
    /// Finite and > 0.
    Positive,
    /// Finite and >= 0.
    NonNegative,
}

impl Requirement {
    /// Whether `value` satisfies the requirement.
    pub fn holds(self, value: f64) -> bool {
        value.is_finite()
            && match self {
                Requirement::Positive => value > 0.0,
                Requirement::NonNegative => value >= 0.0,
            }
    }

    /// The rule in words (`finite and > 0`).
    pub fn describe(self) -> &'static str {
        match self {
            Requirement::Positive => "finite and > 0",
            Requirement::NonNegative => "finite and >= 0",
        }
    }
}

impl ContactParams {
    /// Range of [`ContactParams::normal_penalty`].
    pub const NORMAL_PENALTY: Requirement = Requirement::Positive;
    /// Range of [`ContactParams::penalty_ratio`].
    pub const PENALTY_RATIO: Requirement = Requirement::Positive;
    /// Range of [`ContactParams::friction`].
    pub const FRICTION: Requirement = Requirement::NonNegative;
    /// Range of [`ContactParams::damping`].
    pub const DAMPING: Requirement = Requirement::NonNegative;
    /// Range of [`ContactParams::damping_ratio`].
    pub const DAMPING_RATIO: Requirement = Requirement::NonNegative;

    /// Every field as `(name, value, range)`, in declaration order.
    pub fn fields(&self) -> [(&'static str, f64, Requirement); 5] {
        let ContactParams {
            normal_penalty,
            penalty_ratio,
            friction,
            damping,
            damping_ratio,
        } = *self;
        [
            ("normal_penalty", normal_penalty, Self::NORMAL_PENALTY),
            ("penalty_ratio", penalty_ratio, Self::PENALTY_RATIO),
            ("friction", friction, Self::FRICTION),
            ("damping", damping, Self::DAMPING),
            ("damping_ratio", damping_ratio, Self::DAMPING_RATIO),
        ]
    }

    /// Checks every field and names the first invalid one.
    ///
    /// # Errors
    /// [`ContactError::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<(), ContactError> {
        match self.fields().into_iter().find(|(_, v, r)| !r.holds(*v)) {
            Some((field, value, requirement)) => Err(ContactError::InvalidParameter {
                field,
                value,
                requirement: requirement.describe(),
            }),
            None => Ok(()),
        }
    }

    /// Tangential damping ratio `beta_s = beta_n * damping_ratio` (eq 3).
    pub fn tangential_damping_ratio(&self) -> f64 {
        self.damping * self.damping_ratio
    }

    /// Coefficients of a node of control area `area` (m^2) and lumped mass `mass` (kg):
    /// `k_n = p_n A` (eq 2), `k_s = (p_s/p_n) k_n`, `c = 2 beta sqrt(m k)` (eq 3).
    ///
    /// No validation here: [`crate::ContactModel::new`] checks areas and masses.
    pub fn coefficients(&self, area: f64, mass: f64) -> NodeCoefficients {
        let k_n = self.normal_penalty * area;
        let k_s = self.penalty_ratio * k_n;
        NodeCoefficients {
            normal_stiffness: k_n,
            normal_damping: 2.0 * self.damping * (mass * k_n).sqrt(),
            tangential_stiffness: k_s,
            tangential_damping: 2.0 * self.tangential_damping_ratio() * (mass * k_s).sqrt(),
            friction: self.friction,
        }
    }
}

/// Critical time step of one spring-dashpot (docs/MODEL.md section 11):
/// `dt <= 2 (sqrt(1 + beta^2) - beta) / sqrt(k / m)` (s).
///
/// This is the central-difference stability limit of a damped oscillator of stiffness `k`
/// (N/m), mass `m` (kg) and damping ratio `beta`; it equals `2 / omega` without damping.
///
/// Above critical damping the factor is evaluated as `r / (1 + sqrt(1 + r^2))` with
/// `r = 1 / beta`, the same number without the cancellation that makes the difference
/// zero for large `beta` and without `beta^2`, which overflows; up to critical damping the
/// direct form is kept, so the steps of ordinary runs are unchanged to the last bit.
pub fn spring_dashpot_time_step(stiffness: f64, mass: f64, damping_ratio: f64) -> f64 {
    let omega = (stiffness / mass).sqrt();
    let beta = damping_ratio;
    let factor = if beta > 1.0 {
        let r = 1.0 / beta;
        r / (1.0 + (1.0 + r * r).sqrt())
    } else {
        (1.0 + beta * beta).sqrt() - beta
    };
    2.0 * factor / omega
}

#[cfg(test)]
mod tests {
    use super::spring_dashpot_time_step;

    /// Large damping ratios give the small positive step of the closed form, not zero
    /// (cancellation) or infinity (overflow of `beta^2`): `2 (sqrt(1 + b^2) - b) ~ 1 / b`.
    #[test]
    fn heavy_damping_gives_a_small_positive_step() {
        for beta in [1e4, 1e8, 1e12, 1e200, 1e300, f64::MAX] {
            let dt = spring_dashpot_time_step(1.0, 1.0, beta);
            assert!(dt > 0.0 && dt.is_finite(), "beta {beta:e}: {dt:e}");
            let relative = (dt * beta - 1.0).abs();
            assert!(relative < 1e-6, "beta {beta:e}: {dt:e}");
        }
        // Up to critical damping the direct form: no damping gives 2 / omega exactly.
        assert_eq!(spring_dashpot_time_step(4.0, 1.0, 0.0), 1.0);
        assert_eq!(
            spring_dashpot_time_step(1.0, 1.0, 0.5),
            2.0 * ((1.25f64).sqrt() - 0.5)
        );
    }
}
