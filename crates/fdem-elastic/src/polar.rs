//! Rotation of the polar decomposition `F = R U` of a 3x3 deformation gradient.
//!
//! # Method
//! Two quadratically convergent iterations that both keep the orthogonal polar factor of the
//! iterate unchanged (in exact arithmetic every iterate is `R H_k` with `H_k` symmetric
//! positive definite), so only the stretch is driven to the identity and the rotation is
//! never approximated:
//!
//! 1. Newton–Schulz (Higham, *Functions of Matrices*, 2008, eq. 8.20):
//!    `X_{k+1} = X_k (3 I - X_k^T X_k) / 2`, no inverse, about 45 multiply-adds a step.
//!    It maps each singular value `s -> s (3 - s^2) / 2`, which converges for
//!    `0 < s < sqrt(3)`; it is used only while `||X^T X - I||_F < 1/4`.
//! 2. Otherwise (large stretch, far outside elastic strains) scaled Newton (Higham 2008,
//!    eqs. 8.17 and 8.25): `X_{k+1} = (g X_k + X_k^{-T} / g) / 2` with Frobenius-norm
//!    scaling `g = sqrt(||X^{-1}||_F / ||X||_F)`, which converges for any non-singular `X`,
//!    until Newton–Schulz can take over.
//!
//! A Newton–Schulz step maps `r = ||X^T X - I||_F` to about `(3/4) r^2`. The iteration
//! stops after the step taken with `r < 1e-7`, which leaves `r < 1e-14`: the computed `R`
//! is orthogonal to within `1e-14`, i.e. the co-rotated strain `sym(R^T F) - I` carries an
//! absolute error below `1e-14` (a stress error below `1e-14 E`, 4e-4 Pa for rock), and
//! a rigid rotation (`r ~ 1e-16` from the start) is recovered to round-off in one step.
//! Elastic strains of `1e-4` take two steps, `1e-3` three. (Iterating to `r < 1e-8`
//! instead costs one more step for strains around `1e-4`, a noticeable share of the linear
//! kernel's time: docs/PERFORMANCE.md, "Elastic particles: one full step".)
//!
//! A warm start from the previous step's rotation does not help these iterations: their
//! convergence depends only on the singular values of `F`, which a rotation does not change.
//! That is why the kernels keep no rotation state. (The warm-started quaternion iteration of
//! Müller et al. 2016 converges only linearly, at a rate of 1/3 per step for an undeformed
//! element, and stalls when seeded 180 degrees away, so it was not used.)
//!
//! `det F > 0` is required: for `det F <= 0` the orthogonal factor is a reflection.

use crate::mat3::{IDENTITY, Mat3, cofactor, det, gram, mul, norm2};

/// Switch from scaled Newton to Newton–Schulz below this value of `||X^T X - I||_F^2`
/// (`(1/4)^2`).
pub(crate) const NS_REGION2: f64 = 0.0625;
/// Final Newton–Schulz step once `||X^T X - I||_F^2` is below this (`(1e-7)^2`).
pub(crate) const CONVERGED2: f64 = 1e-14;
/// Iteration caps (never reached for finite `F` with `det F > 0` in tests; a safety net).
const MAX_NEWTON: usize = 100;
pub(crate) const MAX_NS: usize = 20;

/// `||X^T X - I||_F^2` and `X^T X`.
#[inline(always)]
fn orthogonality_defect(x: &Mat3) -> (f64, Mat3) {
    let m = gram(x);
    let mut r2 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            let d = m[i][j] - IDENTITY[i][j];
            r2 += d * d;
        }
    }
    (r2, m)
}

/// Rotation `R` of the polar decomposition `F = R U` (`R` proper orthogonal, `U` symmetric
/// positive definite), orthogonal to within `1e-14` (see the module documentation).
///
/// Returns `None` when `det F <= 0` (inverted: the orthogonal factor would be a reflection),
/// when `F` is not finite, or when `F` is so close to singular that the iteration leaves the
/// floating-point range. Never returns a matrix containing NaN.
///
/// See the [module documentation](self) for the method.
pub fn polar_rotation(f: &Mat3) -> Option<Mat3> {
    let d = det(f);
    if !(d.is_finite() && d > 0.0) {
        return None;
    }
    polar_rotation_positive(f)
}

/// [`polar_rotation`] for a matrix already known to have a finite, positive determinant.
#[inline]
pub(crate) fn polar_rotation_positive(f: &Mat3) -> Option<Mat3> {
    let mut x = *f;
    let (mut r2, mut m) = orthogonality_defect(&x);
    // Phase 1: scaled Newton, only for stretches far outside the elastic range.
    let mut newton_steps = 0;
    while r2.is_nan() || r2 >= NS_REGION2 {
        if newton_steps == MAX_NEWTON || !r2.is_finite() {
            return None;
        }
        newton_steps += 1;
        let dx = det(&x);
        if !(dx.is_finite() && dx > 0.0) {
            return None;
        }
        let c = cofactor(&x);
        // X^{-T} = cof(X) / det X; ||X^{-1}||_F = ||cof X||_F / det X.
        let g = (norm2(&c).sqrt() / (dx * norm2(&x).sqrt())).sqrt();
        let a = 0.5 * g;
        let b = 0.5 / (g * dx);
        for i in 0..3 {
            for j in 0..3 {
                x[i][j] = a * x[i][j] + b * c[i][j];
            }
        }
        (r2, m) = orthogonality_defect(&x);
    }
    // Phase 2: Newton–Schulz, X <- X (3 I - X^T X) / 2.
    for _ in 0..MAX_NS {
        let mut t = m;
        for i in 0..3 {
            for j in 0..3 {
                t[i][j] = 0.5 * (3.0 * IDENTITY[i][j] - t[i][j]);
            }
        }
        x = mul(&x, &t);
        if r2 < CONVERGED2 {
            return Some(x);
        }
        (r2, m) = orthogonality_defect(&x);
        if r2.is_nan() || r2 >= NS_REGION2 {
            // Cannot happen in exact arithmetic once inside the region; be safe.
            return None;
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mat3::{mul_tn, transpose};

    fn rot(axis: [f64; 3], angle: f64) -> Mat3 {
        let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
        let (x, y, z) = (axis[0] / n, axis[1] / n, axis[2] / n);
        let (s, c) = angle.sin_cos();
        let t = 1.0 - c;
        [
            [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
            [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
            [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
        ]
    }

    fn max_diff(a: &Mat3, b: &Mat3) -> f64 {
        let mut m: f64 = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                m = m.max((a[i][j] - b[i][j]).abs());
            }
        }
        m
    }

    #[test]
    fn recovers_rotation_of_pure_rotation_and_stretch() {
        let u: Mat3 = [[1.3, 0.2, -0.1], [0.2, 0.7, 0.05], [-0.1, 0.05, 2.5]];
        for angle in [0.0, 0.3, 1.0, 3.0, std::f64::consts::PI] {
            let q = rot([0.3, -1.0, 0.5], angle);
            let f = mul(&q, &u);
            let r = polar_rotation(&f).unwrap();
            // Tolerance: orthogonal to round-off; cond(U) ~ 4, so 1e-14 is ~50 ulp.
            assert!(max_diff(&r, &q) < 1e-14, "angle {angle}: {r:?} vs {q:?}");
            let s = mul_tn(&r, &f);
            assert!(max_diff(&s, &transpose(&s)) < 1e-14);
        }
    }

    #[test]
    fn large_stretches_use_newton_and_converge() {
        let q = rot([1.0, 2.0, 3.0], 2.0);
        let u: Mat3 = [[1e-4, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1e3]];
        let r = polar_rotation(&mul(&q, &u)).unwrap();
        assert!(max_diff(&r, &q) < 1e-12);
    }

    #[test]
    fn rejects_reflections_singular_and_nan() {
        let refl: Mat3 = [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(polar_rotation(&refl).is_none());
        assert!(polar_rotation(&[[0.0; 3]; 3]).is_none());
        let mut nan = IDENTITY;
        nan[1][2] = f64::NAN;
        assert!(polar_rotation(&nan).is_none());
        let mut inf = IDENTITY;
        inf[0][0] = f64::INFINITY;
        assert!(polar_rotation(&inf).is_none());
    }
}
