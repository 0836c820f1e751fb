//! Isotropic linear elastic material (docs/MODEL.md section 3).

use crate::mat3::Real;
use serde::{Deserialize, Serialize};

use crate::ElasticError;

/// Isotropic linear elastic material, SI units.
///
/// Lamé parameters (docs/MODEL.md section 3): `lambda = E nu / ((1 + nu)(1 - 2 nu))`,
/// `G = E / (2 (1 + nu))`.
///
/// The fields are public for serialization; anything built from them
/// ([`ElementSet::new`](crate::ElementSet::new)) calls [`Material::validate`] first.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// Mass density `rho`, kg/m^3, finite and > 0.
    pub density: f64,
    /// Young's modulus `E`, Pa, finite and > 0.
    pub youngs_modulus: f64,
    /// Poisson's ratio `nu`, dimensionless, in the open interval (-1, 0.5).
    pub poisson_ratio: f64,
}

impl Material {
    /// A validated material. See [`Material::validate`] for the rules.
    pub fn new(
        density: f64,
        youngs_modulus: f64,
        poisson_ratio: f64,
    ) -> Result<Self, ElasticError> {
        let m = Self {
            density,
            youngs_modulus,
            poisson_ratio,
        };
        m.validate()?;
        Ok(m)
    }

    /// Checks `density > 0`, `youngs_modulus > 0`, `-1 < poisson_ratio < 0.5`, all finite.
    /// The error names the first offending field.
    pub fn validate(&self) -> Result<(), ElasticError> {
        if !(self.density.is_finite() && self.density > 0.0) {
            return Err(ElasticError::InvalidMaterial {
                field: "density",
                value: self.density,
                requirement: "must be finite and > 0 (kg/m^3), e.g. 2650 for rock",
            });
        }
        if !(self.youngs_modulus.is_finite() && self.youngs_modulus > 0.0) {
            return Err(ElasticError::InvalidMaterial {
                field: "youngs_modulus",
                value: self.youngs_modulus,
                requirement: "must be finite and > 0 (Pa), e.g. 40e9 for rock",
            });
        }
        if !(self.poisson_ratio > -1.0 && self.poisson_ratio < 0.5) {
            return Err(ElasticError::InvalidMaterial {
                field: "poisson_ratio",
                value: self.poisson_ratio,
                requirement: "must lie strictly between -1 and 0.5 (0.5 is incompressible, \
                              which these elements cannot represent); e.g. 0.2",
            });
        }
        Ok(())
    }

    /// First Lamé parameter `lambda = E nu / ((1 + nu)(1 - 2 nu))`, Pa.
    pub fn lame_lambda(&self) -> f64 {
        let (e, nu) = (self.youngs_modulus, self.poisson_ratio);
        e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    }

    /// Shear modulus (second Lamé parameter) `G = E / (2 (1 + nu))`, Pa.
    pub fn shear_modulus(&self) -> f64 {
        self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))
    }

    /// P-wave modulus `lambda + 2 G`, Pa.
    pub fn p_wave_modulus(&self) -> f64 {
        self.lame_lambda() + 2.0 * self.shear_modulus()
    }

    /// Dilatational wave speed `c_p = sqrt((lambda + 2 G) / rho)`, m/s (docs/MODEL.md section 11).
    pub fn p_wave_speed(&self) -> f64 {
        (self.p_wave_modulus() / self.density).sqrt()
    }

    /// Shear wave speed `c_s = sqrt(G / rho)`, m/s.
    pub fn s_wave_speed(&self) -> f64 {
        (self.shear_modulus() / self.density).sqrt()
    }

    /// Local linear-elastic stress `sigma = lambda tr(eps) I + 2 G eps` (docs/MODEL.md eq. 4-5 in
    /// total form) for a symmetric strain given as a full matrix.
    #[inline(always)]
    pub(crate) fn stress<T: Real>(lambda: T, mu: T, eps: &[[T; 3]; 3]) -> [[T; 3]; 3] {
        let tr = eps[0][0] + eps[1][1] + eps[2][2];
        let two_mu = T::splat(2.0) * mu;
        let mut s = [[T::ZERO; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                s[i][j] = two_mu * eps[i][j];
            }
            s[i][i] += lambda * tr;
        }
        s
    }
}
