//! Small fixed-size 3x3 helpers for the element kernels.
//!
//! Matrices are row-major `[[f64; 3]; 3]` (`m[i][j]` is row `i`, column `j`). The kernels use
//! these instead of a general linear-algebra type so that every operation is a handful of
//! straight-line multiply-adds the compiler can keep in registers.
//!
//! The products are generic over [`Real`]: `f64` for one element, and the lane vectors of
//! [`crate::lanes`] for several elements at once. Both run the same operations in the same
//! order, which is what makes the two kernels agree to the last bit.

use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

/// A number type the 3x3 products work on: `f64`, or a vector of `f64` lanes with
/// element-wise operations.
pub(crate) trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
{
    /// Zero.
    const ZERO: Self;
    /// `value` (in every lane).
    fn splat(value: f64) -> Self;
}

impl Real for f64 {
    const ZERO: f64 = 0.0;
    #[inline(always)]
    fn splat(value: f64) -> f64 {
        value
    }
}

/// A 3x3 matrix, row-major.
pub type Mat3 = [[f64; 3]; 3];

/// The 3x3 identity.
pub(crate) const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

// The vector helpers are the project's one definition, in `fdem-core`.
pub(crate) use fdem_core::geometry::{dot, sub};

/// [`sub`] for any [`Real`] (the lane kernels need it on lane vectors): the same operations.
#[inline(always)]
pub(crate) fn vsub<T: Real>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `fdem_core::geometry::cross` for any [`Real`]: the same operations in the same order.
#[inline(always)]
pub(crate) fn vcross<T: Real>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `m += a (x) b` (outer product, `m[i][j] += a[i] b[j]`).
#[inline(always)]
pub(crate) fn add_outer<T: Real>(m: &mut [[T; 3]; 3], a: [T; 3], b: [T; 3]) {
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] += a[i] * b[j];
        }
    }
}

/// `a b`.
#[inline(always)]
pub(crate) fn mul<T: Real>(a: &[[T; 3]; 3], b: &[[T; 3]; 3]) -> [[T; 3]; 3] {
    let mut c = [[T::ZERO; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    c
}

/// `a^T b`.
#[inline(always)]
pub(crate) fn mul_tn<T: Real>(a: &[[T; 3]; 3], b: &[[T; 3]; 3]) -> [[T; 3]; 3] {
    let mut c = [[T::ZERO; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[0][i] * b[0][j] + a[1][i] * b[1][j] + a[2][i] * b[2][j];
        }
    }
    c
}

/// `a^T a` (symmetric, all nine entries filled).
#[inline(always)]
pub(crate) fn gram<T: Real>(a: &[[T; 3]; 3]) -> [[T; 3]; 3] {
    let mut c = [[T::ZERO; 3]; 3];
    for i in 0..3 {
        for j in i..3 {
            let v = a[0][i] * a[0][j] + a[1][i] * a[1][j] + a[2][i] * a[2][j];
            c[i][j] = v;
            c[j][i] = v;
        }
    }
    c
}

/// `m v` (each entry in the order of [`dot`]).
#[inline(always)]
pub(crate) fn mul_vec<T: Real>(m: &[[T; 3]; 3], v: [T; 3]) -> [T; 3] {
    // Index loops, not `array::map`: the closures of `map` are not always inlined, which
    // costs copies of the lane vectors.
    let mut c = [T::ZERO; 3];
    for i in 0..3 {
        c[i] = m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2];
    }
    c
}

/// `a s`.
#[inline(always)]
pub(crate) fn scale<T: Real>(a: &[[T; 3]; 3], s: T) -> [[T; 3]; 3] {
    let mut c = *a;
    for row in &mut c {
        for v in row.iter_mut() {
            *v = *v * s;
        }
    }
    c
}

/// Determinant.
#[inline(always)]
pub(crate) fn det<T: Real>(m: &[[T; 3]; 3]) -> T {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// Cofactor matrix, `cof(m) = det(m) m^{-T}`.
#[inline(always)]
pub(crate) fn cofactor<T: Real>(m: &[[T; 3]; 3]) -> [[T; 3]; 3] {
    [
        [
            m[1][1] * m[2][2] - m[1][2] * m[2][1],
            m[1][2] * m[2][0] - m[1][0] * m[2][2],
            m[1][0] * m[2][1] - m[1][1] * m[2][0],
        ],
        [
            m[0][2] * m[2][1] - m[0][1] * m[2][2],
            m[0][0] * m[2][2] - m[0][2] * m[2][0],
            m[0][1] * m[2][0] - m[0][0] * m[2][1],
        ],
        [
            m[0][1] * m[1][2] - m[0][2] * m[1][1],
            m[0][2] * m[1][0] - m[0][0] * m[1][2],
            m[0][0] * m[1][1] - m[0][1] * m[1][0],
        ],
    ]
}

/// Squared Frobenius norm.
#[inline(always)]
pub(crate) fn norm2(m: &Mat3) -> f64 {
    let mut s = 0.0;
    for row in m {
        s += dot(*row, *row);
    }
    s
}

/// Transpose.
#[inline(always)]
pub(crate) fn transpose<T: Real>(m: &[[T; 3]; 3]) -> [[T; 3]; 3] {
    [
        [m[0][0], m[1][0], m[2][0]],
        [m[0][1], m[1][1], m[2][1]],
        [m[0][2], m[1][2], m[2][2]],
    ]
}
