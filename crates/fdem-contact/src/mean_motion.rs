//! The mean motion of the surface: a uniform deformation the caller expects the nodes to
//! follow on average (a specimen between platens that squeeze it), from which the broad
//! phase measures each node's drift instead of from rest.
//!
//! Why: the candidate lists hold while no node has drifted half the skin from where it was
//! when its pairs were found. In a specimen squeezed between platens every node near the
//! moving platen travels with it, so the lists were renewed every few dozen steps although
//! neighbours hardly moved relative to each other. Measured from the mean motion, a node's
//! drift is what it did beyond that motion, and the lists last as long as the neighbours
//! keep their arrangement.
//!
//! Why the lists still hold every contact. Let `A` be the mean motion's linear map from the
//! last full build to now and `g` a bound of `|A_t A_s^-1 - I|` (spectral norm, bounded by
//! the Frobenius norm) over any two evaluations `s`, `t` since that build. Each node is at
//! `x = o + A (X - o) + r` with `X` its reference and `r` its residual drift. The relative
//! position of a node and a point of a face, each with residual at most `rho`, is the mean
//! map's image of their relative position when the pair was found, plus at most the
//! residuals of both ends (the older end's residual when the pair was found also carried
//! over by a map within `g` of the identity). The map changes any distance `d` by at most
//! `g d`, keeps every face's orientation (its determinant stays positive while `g < 1`) and
//! barycentric coordinates, and tilts a face by at most about `g` radians. So the argument
//! of the lists (`crate::broad`, `crate::broad::refresh`) goes through unchanged when the
//! residuals stay within `rho = skin / 2 - g L`, `L` the sum of the refresh's enlargement
//! and front reach (the longest node-to-face distances the lists cover): the map's
//! distortion of those distances is paid out of the skin.
//! [`DriftAllowance::of`] computes `rho`; a full build resets `A` to the identity when `g L`
//! passes [`DISTORTION_FRACTION`] of the skin's half.

use nalgebra::{Matrix3, Vector3};

/// The share of half the skin the mean map's distortion of the lists' reach (`g L`) may
/// take before a full build resets the map. It bounds `g` for the broad phase's window
/// reach (`crate::broad::window`, which grows with `g`), keeps the drift allowance at
/// least seven eighths of half the skin, and in a triaxial shear is reached once the axial
/// strain since the last full build passes about `skin / (32 L)` (`g` is about twice the
/// strain).
pub(crate) const DISTORTION_FRACTION: f64 = 0.125;

/// A 3x3 matrix as rows.
pub(crate) type Matrix = [[f64; 3]; 3];

pub(crate) const IDENTITY: Matrix = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

fn na(m: &Matrix) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| m[i][j])
}

fn rows(m: &Matrix3<f64>) -> Matrix {
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

/// The caller's mean motion: from `time` on, the deformation gradient is
/// `F(t) = (I + (t - time) rate) F(time)` about the fixed point `origin`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MeanMotion {
    origin: [f64; 3],
    /// `F(time)`, relative to where the caller first set the motion.
    gradient: Matrix,
    rate: Matrix,
    time: f64,
}

impl MeanMotion {
    /// The motion `rate` about `origin` from `time` on, continuing `previous` (whose
    /// gradient at `time` it starts from).
    pub(crate) fn continued(
        previous: Option<&MeanMotion>,
        origin: [f64; 3],
        rate: Matrix,
        time: f64,
    ) -> MeanMotion {
        MeanMotion {
            origin,
            gradient: previous.map_or(IDENTITY, |m| m.gradient_at(time)),
            rate,
            time,
        }
    }

    /// `F(t)`.
    pub(crate) fn gradient_at(&self, t: f64) -> Matrix {
        let step = na(&IDENTITY) + na(&self.rate) * (t - self.time);
        rows(&(step * na(&self.gradient)))
    }

    /// The map from a configuration where the gradient was `from` (a full build's) to
    /// time `t`, or `None` when `from` is singular.
    pub(crate) fn since(&self, from: &Matrix, t: f64) -> Option<Expected> {
        let inverse_from = na(from).try_inverse()?;
        let a = na(&self.gradient_at(t)) * inverse_from;
        let a_inv = a.try_inverse()?;
        let distortion = (a - Matrix3::identity()).norm();
        Some(Expected {
            origin: self.origin,
            a: rows(&a),
            a_inv: rows(&a_inv),
            distortion,
        })
    }
}

/// Where the mean motion has taken the reference positions of the last full build.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Expected {
    origin: [f64; 3],
    a: Matrix,
    a_inv: Matrix,
    /// `|A - I|` (Frobenius norm).
    pub(crate) distortion: f64,
}

fn apply(m: &Matrix, o: [f64; 3], x: [f64; 3]) -> [f64; 3] {
    let d = Vector3::new(x[0] - o[0], x[1] - o[1], x[2] - o[2]);
    std::array::from_fn(|i| o[i] + m[i][0] * d[0] + m[i][1] * d[1] + m[i][2] * d[2])
}

impl Expected {
    /// The map's fixed point `O`, its matrix `M` and `M^-1`: `y -> O + M (y - O)`.
    pub(crate) fn parts(&self) -> ([f64; 3], &Matrix, &Matrix) {
        (self.origin, &self.a, &self.a_inv)
    }

    /// The expected position now of a node whose reference is `reference`.
    #[inline]
    pub(crate) fn position(&self, reference: [f64; 3]) -> [f64; 3] {
        apply(&self.a, self.origin, reference)
    }

    /// The reference (in the full build's configuration) of a node at `x` now.
    #[inline]
    pub(crate) fn reference(&self, x: [f64; 3]) -> [f64; 3] {
        apply(&self.a_inv, self.origin, x)
    }
}

/// Squared drift of a node at `x` from its expected position, given its `reference`.
#[inline(always)]
pub(crate) fn drift2(expected: Option<&Expected>, x: [f64; 3], reference: [f64; 3]) -> f64 {
    let y = match expected {
        Some(e) => e.position(reference),
        None => reference,
    };
    let d = [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// How far a node may drift from its expected position before the lists are renewed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct DriftAllowance {
    /// The largest residual drift (m).
    pub(crate) drift: f64,
    /// Whether the mean motion's distortion has taken so much of the skin that a full
    /// build (which resets it) is due.
    pub(crate) exhausted: bool,
}

impl DriftAllowance {
    /// The allowance `half - g L` for the largest distortion `largest` seen since the last
    /// full build (`g = 2 d / (1 - d)` bounds the map between any two evaluations of the
    /// epoch when each is within `d` of the build's), with `L` the refresh's reach
    /// (`length`); exhausted once `g L` passes [`DISTORTION_FRACTION`] of `half`. Without
    /// mean motion, exactly `half`.
    pub(crate) fn of(half: f64, largest: f64, length: f64) -> DriftAllowance {
        if largest == 0.0 {
            return DriftAllowance {
                drift: half,
                exhausted: false,
            };
        }
        if largest >= 0.5 {
            return DriftAllowance {
                drift: 0.0,
                exhausted: true,
            };
        }
        let g = 2.0 * largest / (1.0 - largest);
        let drift = half - g * length;
        DriftAllowance {
            drift: drift.max(0.0),
            exhausted: g * length > DISTORTION_FRACTION * half,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_axial_squeeze_maps_points_linearly_in_time_about_the_origin() {
        let rate = [[0.0; 3], [0.0; 3], [0.0, 0.0, -0.5]];
        let m = MeanMotion::continued(None, [0.0, 0.0, 1.0], rate, 2.0);
        let e = m.since(&IDENTITY, 2.4).unwrap();
        // z = 1 + (1 - 0.5 * 0.4) (z0 - 1)
        let y = e.position([0.3, -0.2, 3.0]);
        assert!((y[0] - 0.3).abs() < 1e-15 && (y[1] + 0.2).abs() < 1e-15);
        assert!((y[2] - (1.0 + 0.8 * 2.0)).abs() < 1e-14, "{y:?}");
        let back = e.reference(y);
        assert!((back[2] - 3.0).abs() < 1e-14);
        assert!((e.distortion - 0.2).abs() < 1e-14);
    }

    #[test]
    fn a_continued_motion_keeps_the_gradient_and_a_build_resets_the_map() {
        let rate = [[0.0; 3], [0.0; 3], [0.0, 0.0, -0.5]];
        let first = MeanMotion::continued(None, [0.0; 3], rate, 0.0);
        let faster = [[0.0; 3], [0.0; 3], [0.0, 0.0, -1.0]];
        let second = MeanMotion::continued(Some(&first), [0.0; 3], faster, 0.2);
        // F(0.2) = 0.9, then F(0.3) = (1 - 0.1) 0.9 = 0.81.
        assert!((second.gradient_at(0.3)[2][2] - 0.81).abs() < 1e-15);
        let at_build = second.gradient_at(0.25);
        let e = second.since(&at_build, 0.25).unwrap();
        assert!(e.distortion < 1e-15);
    }

    #[test]
    fn the_allowance_is_half_the_skin_without_motion_and_shrinks_with_distortion() {
        assert_eq!(DriftAllowance::of(1.0, 0.0, 10.0).drift, 1.0);
        let a = DriftAllowance::of(1.0, 0.005, 10.0);
        let g = 0.01 / 0.995;
        assert!((a.drift - (1.0 - 10.0 * g)).abs() < 1e-15);
        assert!(!a.exhausted);
        // g L = 0.202 > DISTORTION_FRACTION of half.
        assert!(DriftAllowance::of(1.0, 0.01, 10.0).exhausted);
        assert!(DriftAllowance::of(1.0, 0.6, 0.0).exhausted);
    }
}
