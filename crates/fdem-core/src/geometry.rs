//! Small geometric formulas on `[f64; 3]` points and vectors: the one definition the mesh
//! code, the element kernels, contact, the membrane and the micro-analysis share.
//!
//! Every formula is written out component by component in a fixed order (no fused
//! multiply-add, no `hypot`), so a result is the same bits wherever it is computed. Callers
//! that need another rounding (for example `hypot` for a radius) write it at the call site.

/// `a + b`.
#[inline]
pub fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a - b`.
#[inline]
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a s` (each component times `s`).
#[inline]
pub fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Dot product `a · b`, summed left to right.
#[inline]
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Cross product `a × b`.
#[inline]
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The velocity of the point `x` of a rigid body whose point `centre` moves at `velocity`
/// and which spins at `angular_velocity`: `velocity + angular_velocity x (x - centre)`, in
/// this operation order (the solver places rigid bodies' node velocities with it, and the
/// contact model recomputes them from the same inputs, bit for bit).
#[inline(always)]
pub fn rigid_velocity(
    velocity: [f64; 3],
    angular_velocity: [f64; 3],
    centre: [f64; 3],
    x: [f64; 3],
) -> [f64; 3] {
    let r = [x[0] - centre[0], x[1] - centre[1], x[2] - centre[2]];
    let u = cross(angular_velocity, r);
    [velocity[0] + u[0], velocity[1] + u[1], velocity[2] + u[2]]
}

/// Squared length `a · a`.
#[inline]
pub fn norm2(a: [f64; 3]) -> f64 {
    dot(a, a)
}

/// Euclidean length `|a|`, as `sqrt(a · a)`.
#[inline]
pub fn norm(a: [f64; 3]) -> f64 {
    norm2(a).sqrt()
}

/// Distance `|a - b|`.
#[inline]
pub fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm(sub(a, b))
}

/// Midpoint of the straight segment `a b`.
#[inline]
pub fn midpoint(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        0.5 * (a[0] + b[0]),
        0.5 * (a[1] + b[1]),
        0.5 * (a[2] + b[2]),
    ]
}

/// Whether all three components are finite.
#[inline]
pub fn is_finite(a: [f64; 3]) -> bool {
    a[0].is_finite() && a[1].is_finite() && a[2].is_finite()
}

/// Signed volume of the tetrahedron `x0 x1 x2 x3`:
/// `(x1 - x0) · ((x2 - x0) × (x3 - x0)) / 6`.
///
/// Positive for the project's element convention (corners `0..4` positively oriented).
#[inline]
pub fn tet_signed_volume(x0: [f64; 3], x1: [f64; 3], x2: [f64; 3], x3: [f64; 3]) -> f64 {
    dot(sub(x1, x0), cross(sub(x2, x0), sub(x3, x0))) / 6.0
}

/// Area vector of the triangle `a b c`: `(b - a) × (c - a) / 2`.
///
/// Its length is the area; it points to the side from which `a b c` is seen
/// counter-clockwise.
#[inline]
pub fn triangle_area_vector(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let n = cross(sub(b, a), sub(c, a));
    [0.5 * n[0], 0.5 * n[1], 0.5 * n[2]]
}

/// Area of the triangle `a b c`.
#[inline]
pub fn triangle_area(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    norm(triangle_area_vector(a, b, c))
}

/// Interior dihedral angle, in radians, of a tetrahedron along its edge `p q`, where `r`
/// and `s` are the two other corners (so the faces meeting at the edge are `p q r` and
/// `p q s`).
#[inline]
pub fn dihedral_angle(p: [f64; 3], q: [f64; 3], r: [f64; 3], s: [f64; 3]) -> f64 {
    let e = sub(q, p);
    let ee = dot(e, e);
    // Components of p->r and p->s perpendicular to the edge.
    let perp = |v: [f64; 3]| {
        let t = dot(v, e) / ee;
        [v[0] - t * e[0], v[1] - t * e[1], v[2] - t * e[2]]
    };
    let u = perp(sub(r, p));
    let v = perp(sub(s, p));
    let c = dot(u, v) / (norm(u) * norm(v));
    c.clamp(-1.0, 1.0).acos()
}

/// The rotation matrix (rows) of the quaternion `q / |q|`, `q = [w, x, y, z]`.
pub fn rotation_matrix(q: [f64; 4]) -> [[f64; 3]; 3] {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let (w, x, y, z) = (q[0] / n, q[1] / n, q[2] / n, q[3] / n);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: [f64; 3] = [1.0, -2.0, 0.5];
    const B: [f64; 3] = [0.25, 3.0, -4.0];

    #[test]
    fn rotation_matrix_turns_about_the_quaternion_axis() {
        // A quarter turn about z (unnormalised on purpose) takes x to y.
        let h = std::f64::consts::FRAC_PI_4;
        let r = rotation_matrix([2.0 * h.cos(), 0.0, 0.0, 2.0 * h.sin()]);
        let x = [r[0][0], r[1][0], r[2][0]];
        assert!(distance(x, [0.0, 1.0, 0.0]) < 1e-15, "{x:?}");
        // Any quaternion gives an orthonormal matrix of determinant 1.
        let rows = rotation_matrix([0.3, -0.5, 0.7, 0.1]);
        for (i, a) in rows.iter().enumerate() {
            for (j, b) in rows.iter().enumerate() {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((dot(*a, *b) - want).abs() < 1e-15);
            }
        }
        assert!((dot(cross(rows[0], rows[1]), rows[2]) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn vector_arithmetic() {
        assert_eq!(add(A, B), [1.25, 1.0, -3.5]);
        assert_eq!(sub(A, B), [0.75, -5.0, 4.5]);
        assert_eq!(scale(A, -2.0), [-2.0, 4.0, -1.0]);
        assert_eq!(dot(A, B), 0.25 - 6.0 - 2.0);
        assert_eq!(norm2(A), 5.25);
        assert_eq!(norm(A), 5.25f64.sqrt());
        assert_eq!(distance(A, B), norm(sub(A, B)));
        assert_eq!(midpoint(A, B), [0.625, 0.5, -1.75]);
    }

    #[test]
    fn cross_is_right_handed_and_orthogonal() {
        assert_eq!(cross([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]), [0.0, 0.0, 1.0]);
        let c = cross(A, B);
        assert_eq!(dot(c, A), 0.0);
        assert_eq!(dot(c, B), 0.0);
        assert_eq!(cross(B, A), scale(c, -1.0));
    }

    #[test]
    fn finiteness() {
        assert!(is_finite(A));
        assert!(!is_finite([0.0, f64::NAN, 0.0]));
        assert!(!is_finite([0.0, 0.0, f64::INFINITY]));
    }

    #[test]
    fn unit_simplex() {
        let o = [0.0; 3];
        let (x, y, z) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        assert_eq!(tet_signed_volume(o, x, y, z), 1.0 / 6.0);
        assert_eq!(tet_signed_volume(o, y, x, z), -1.0 / 6.0);
        assert_eq!(triangle_area_vector(o, x, y), [0.0, 0.0, 0.5]);
        assert_eq!(triangle_area(o, x, y), 0.5);
        // The edge o-z of the corner tetrahedron: faces o z x and o z y meet at 90 degrees.
        let right = dihedral_angle(o, z, x, y);
        assert!(
            (right - std::f64::consts::FRAC_PI_2).abs() < 1e-15,
            "{right}"
        );
    }

    #[test]
    fn regular_tetrahedron_dihedral() {
        let t = [
            [1.0, 1.0, 1.0],
            [1.0, -1.0, -1.0],
            [-1.0, 1.0, -1.0],
            [-1.0, -1.0, 1.0],
        ];
        let angle = dihedral_angle(t[0], t[1], t[2], t[3]);
        assert!((angle - (1.0f64 / 3.0).acos()).abs() < 1e-14, "{angle}");
    }
}
