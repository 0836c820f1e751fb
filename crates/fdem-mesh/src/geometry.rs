//! Small geometric formulas on `[f64; 3]` points, shared by the mesh code and useful to
//! other crates (element kernels, contact) that need the same conventions.

/// `a - b`.
#[inline]
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Dot product `a · b`.
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

/// Euclidean length `|a|`.
#[inline]
pub fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
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

/// Signed volume of the tetrahedron `x0 x1 x2 x3`:
/// `(x1 - x0) · ((x2 - x0) × (x3 - x0)) / 6`.
///
/// Positive for the project's element convention (see the crate docs).
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
