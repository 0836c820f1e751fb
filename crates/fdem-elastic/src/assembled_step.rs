//! The stable time step of a whole body by power iteration on its assembled stiffness.
//!
//! Central differences are stable for `dt <= 2 / omega_max`, `omega_max^2` the largest
//! eigenvalue of `M^-1/2 K M^-1/2` of the *assembled* body (docs/MODEL.md section 11). The
//! element bound ([`ElementSet::stable_time_step`]) never exceeds it (element eigenvalue
//! inequality) and is often well below it, because an element's nodes carry only that
//! element's share of mass (docs/VERIFICATION.md, "Free particles in explicit dynamics",
//! has the ratio for a level-1 linear particle). This module estimates the assembled bound
//! itself, the "global estimate" of explicit codes (Abaqus/Explicit, LS-DYNA), so that a
//! run does not pay for the element bound's pessimism.
//!
//! Method: power iteration `y <- A y / |A y|` with `A = M^-1/2 K M^-1/2`, `K` the rest
//! stiffness (the co-rotational tangent at rest), applied element by element from the
//! element matrices ([`ElementSet::element_stiffness`]); no finite differences, so the
//! estimate carries round-off only and scales exactly with the body (a body `h` times
//! larger gets a step `h` times larger, to about 1e-13). After each product the Rayleigh quotient
//! `rho = y . A y` (approaching `lambda_max` from below) and the residual
//! `r = A y - rho y` give `rho + |r|`, the bound on the eigenvalue the iteration converges
//! to (Krylov–Bogoliubov: some eigenvalue lies within `|r|` of `rho`). The returned step uses
//! `rho + |r|`, never exceeds what the element bound allows for the same body
//! ([`AssembledStep::time_step`] is at least the element bound) and stops once
//! `|r| <= tolerance * rho`.
//!
//! The estimate assumes the iteration converged to the top of the spectrum, which a
//! generic start vector ensures in practice but not in theory; callers keep a safety factor
//! below 1 (the solver's `dt_safety`).

use crate::ElementSet;
use crate::modes::MassScaledStiffness;

/// Relative residual `|r| / rho` at which the power iteration stops.
pub const ASSEMBLED_STEP_TOLERANCE: f64 = 1e-3;
/// Largest number of power iterations (two force evaluations each).
pub const ASSEMBLED_STEP_MAX_ITERATIONS: usize = 2000;

/// Result of [`ElementSet::assembled_time_step`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AssembledStep {
    /// The stable step used, s: `2 / sqrt(rho + |r|)`, raised to the element bound if that
    /// is larger (it is rigorous).
    pub time_step: f64,
    /// The element bound of the same body, s.
    pub element_time_step: f64,
    /// Rayleigh quotient at the last iteration, rad^2/s^2.
    pub rayleigh_quotient: f64,
    /// Residual norm `|A y - rho y|` at the last iteration, rad^2/s^2.
    pub residual: f64,
    /// Power iterations performed.
    pub iterations: usize,
}

impl ElementSet {
    /// Estimates the stable step of this body as an assembled system (see the docs of
    /// this module, `assembled_step`): power iteration on `M^-1/2 K M^-1/2` with the rest
    /// stiffness. A set without elements gives `+inf`.
    ///
    /// Cost: the element matrices once, then one sparse product per iteration
    /// (docs/PERFORMANCE.md, "Setting up", has the timing of a level-1 particle).
    pub fn assembled_time_step(&self) -> AssembledStep {
        let n = self.n_nodes();
        let element_time_step = self.stable_time_step();
        let infinite = AssembledStep {
            time_step: f64::INFINITY,
            element_time_step,
            rayleigh_quotient: 0.0,
            residual: 0.0,
            iterations: 0,
        };
        if self.n_elements() == 0 {
            return infinite;
        }
        let op = MassScaledStiffness::new(self);
        let scale = &op.scale;
        // A deterministic, generic start vector (golden-ratio sequence), zero on massless
        // nodes.
        let mut y: Vec<f64> = (0..3 * n)
            .map(|i| {
                let v = (i as f64 * 0.618_033_988_749_895).fract() - 0.5;
                if scale[i / 3] > 0.0 { v } else { 0.0 }
            })
            .collect();
        let mut ay = vec![0.0; 3 * n];
        let mut out = infinite;
        for iteration in 1..=ASSEMBLED_STEP_MAX_ITERATIONS {
            let norm = y.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm == 0.0 || !norm.is_finite() {
                break;
            }
            y.iter_mut().for_each(|x| *x /= norm);
            // A y = M^-1/2 K M^-1/2 y, element by element.
            op.apply(&y, &mut ay);
            let rho: f64 = ay.iter().zip(&y).map(|(a, v)| a * v).sum();
            let residual = ay
                .iter()
                .zip(&y)
                .map(|(a, v)| (a - rho * v).powi(2))
                .sum::<f64>()
                .sqrt();
            out = AssembledStep {
                time_step: if rho > 0.0 {
                    (2.0 / (rho + residual).sqrt()).max(element_time_step)
                } else {
                    element_time_step
                },
                element_time_step,
                rayleigh_quotient: rho,
                residual,
                iterations: iteration,
            };
            if rho > 0.0 && residual <= ASSEMBLED_STEP_TOLERANCE * rho {
                break;
            }
            std::mem::swap(&mut y, &mut ay);
        }
        out
    }
}
