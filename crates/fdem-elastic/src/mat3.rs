//! Small fixed-size 3x3 helpers for the element kernels.
//!
//! Matrices are row-major `[[f64; 3]; 3]` (`m[i][j]` is row `i`, column `j`). The kernels use
//! these instead of a general linear-algebra type so that every operation is a handful of
//! straight-line multiply-adds the compiler can keep in registers.

/// A 3x3 matrix, row-major.
pub type Mat3 = [[f64; 3]; 3];

/// The 3x3 identity.
pub(crate) const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

// The vector helpers are the project's one definition, in `fdem-core`.
pub(crate) use fdem_core::geometry::{cross, dot, sub};

/// `m += a (x) b` (outer product, `m[i][j] += a[i] b[j]`).
#[inline(always)]
pub(crate) fn add_outer(m: &mut Mat3, a: [f64; 3], b: [f64; 3]) {
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] += a[i] * b[j];
        }
    }
}

/// `a b`.
#[inline(always)]
pub(crate) fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    c
}

/// `a^T b`.
#[inline(always)]
pub(crate) fn mul_tn(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[0][i] * b[0][j] + a[1][i] * b[1][j] + a[2][i] * b[2][j];
        }
    }
    c
}

/// `a^T a` (symmetric, all nine entries filled).
#[inline(always)]
pub(crate) fn gram(a: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in i..3 {
            let v = a[0][i] * a[0][j] + a[1][i] * a[1][j] + a[2][i] * a[2][j];
            c[i][j] = v;
            c[j][i] = v;
        }
    }
    c
}

/// `m v`.
#[inline(always)]
pub(crate) fn mul_vec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

/// Determinant.
#[inline(always)]
pub(crate) fn det(m: &Mat3) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// Cofactor matrix, `cof(m) = det(m) m^{-T}`.
#[inline(always)]
pub(crate) fn cofactor(m: &Mat3) -> Mat3 {
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
pub(crate) fn transpose(m: &Mat3) -> Mat3 {
    [
        [m[0][0], m[1][0], m[2][0]],
        [m[0][1], m[1][1], m[2][1]],
        [m[0][2], m[1][2], m[2][2]],
    ]
}
