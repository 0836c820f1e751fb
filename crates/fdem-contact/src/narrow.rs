//! Narrow phase: one node against one flat triangle.
//!
//! A node is in contact with a face when it lies behind the face's plane (the face normal
//! points out of the face's body: triangles are counter-clockwise seen from outside) by at
//! most a depth limit, and the foot of its perpendicular falls inside the triangle within
//! [`BARYCENTRIC_TOLERANCE`]. Two interchangeable kernels compute this: a hand-written
//! projection ([`project_hand`]) and one built on parry's
//! `PointQueryWithLocation` for triangles ([`project_parry`]). They agree except within the
//! tolerance band along the edges (tested); [`ProjectionKernel`] selects one, the default
//! being the hand-written one, which exits early for most candidates (docs/PERFORMANCE.md,
//! "Narrow phase: hand-written projection versus parry3d-f64", has the `contact` bench's
//! timings).

use parry3d_f64::math::Vector;
use parry3d_f64::query::PointQueryWithLocation;
use parry3d_f64::shape::{Triangle, TrianglePointLocation};
use serde::{Deserialize, Serialize};

use crate::vec3::{add, cross, dot, norm2, scale, sub};

/// Tolerance on the barycentric coordinates of the foot of the perpendicular: a foot with
/// every coordinate `>= -1e-6` counts as inside. It keeps a node pressed exactly onto a
/// shared edge from slipping between the two faces by round-off. Weights within the band
/// are clamped to `>= 0` and renormalised before they spread the reaction.
pub const BARYCENTRIC_TOLERANCE: f64 = 1e-6;

/// A node found behind a face (the output of the narrow phase).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FaceHit {
    /// Penetration depth `d_n >= 0` (m): the distance of the node behind the face plane.
    pub depth: f64,
    /// Unit outward normal of the face (the direction the node is pushed).
    pub normal: [f64; 3],
    /// Barycentric weights of the contact point (the foot of the perpendicular) on the
    /// face's three nodes: non-negative, summing to 1.
    pub weights: [f64; 3],
}

/// Which narrow-phase kernel [`crate::ContactModel`] uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProjectionKernel {
    /// [`project_hand`]: plane distance first (early exit for nodes in front of the face or
    /// too deep), then barycentrics from two triple products. The default: most candidates
    /// end at the plane test (docs/PERFORMANCE.md, "Narrow phase: hand-written projection
    /// versus parry3d-f64").
    #[default]
    Hand,
    /// [`project_parry`]: parry3d-f64's `Triangle::project_local_point_and_get_location`
    /// (Voronoi-region closest point with location) after the same plane test.
    Parry,
}

impl ProjectionKernel {
    /// Runs the selected kernel.
    #[inline]
    pub fn project(self, node: [f64; 3], face: [[f64; 3]; 3], depth_limit: f64) -> Option<FaceHit> {
        match self {
            ProjectionKernel::Hand => project_hand(node, face, depth_limit),
            ProjectionKernel::Parry => project_parry(node, face, depth_limit),
        }
    }
}

/// Clamps weights within the tolerance band to `>= 0` and renormalises them.
#[inline(always)]
fn clamp_weights(w: [f64; 3]) -> [f64; 3] {
    if w[0] >= 0.0 && w[1] >= 0.0 && w[2] >= 0.0 {
        return w;
    }
    let c = [w[0].max(0.0), w[1].max(0.0), w[2].max(0.0)];
    let s = c[0] + c[1] + c[2];
    [c[0] / s, c[1] / s, c[2] / s]
}

/// Distance of a node in front of a face: `Some(s)` with `0 <= s <= limit` when the node
/// lies on the outward side of the face's plane by `s` and the foot of its perpendicular
/// falls inside the triangle (within [`BARYCENTRIC_TOLERANCE`]); `None` otherwise.
///
/// The model uses it to resolve ambiguous contacts: a node behind one face of a body but
/// in front of a nearer face of the same body that covers it is outside that body there
/// (closest face wins). On a convex particle this removes false contacts of nodes in the
/// wedge outside an edge; on a draped membrane it removes the fold artefacts where a
/// particle vertex sits on the particle side of one face and far behind a steep neighbour.
#[inline]
pub fn front_distance(node: [f64; 3], face: [[f64; 3]; 3], limit: f64) -> Option<f64> {
    // In front of (a, b, c) is behind the mirrored face (a, c, b), same foot and distance.
    let [a, b, c] = face;
    project_hand(node, [a, c, b], limit).map(|hit| hit.depth)
}

/// Barycentric weights of the closest point of the triangle `[a, b, c]` to `p` (Ericson,
/// Real-Time Collision Detection, section 5.1.5: the Voronoi region of a vertex, an edge
/// or the face). On an edge the weight of the opposite corner is exactly 0, at a vertex
/// the other two are: the number of non-zero weights tells the region. A degenerate
/// triangle gives weights that may not be finite.
pub fn closest_point_weights(p: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> [f64; 3] {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = sub(p, b);
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    let cp = sub(p, c);
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    let vc = d1 * d4 - d3 * d2;
    let vb = d5 * d2 - d1 * d6;
    let va = d3 * d6 - d5 * d4;
    if d3 >= 0.0 && d4 <= d3 {
        [0.0, 1.0, 0.0]
    } else if d6 >= 0.0 && d5 <= d6 {
        [0.0, 0.0, 1.0]
    } else if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        [1.0 - v, v, 0.0]
    } else if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        [1.0 - w, 0.0, w]
    } else if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        [0.0, 1.0 - w, w]
    } else {
        let denom = 1.0 / (va + vb + vc);
        let v = vb * denom;
        let w = vc * denom;
        [1.0 - v - w, v, w]
    }
}

/// The point of a triangle with barycentric `weights`.
#[inline]
pub fn point_at(weights: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> [f64; 3] {
    [0, 1, 2].map(|k| weights[0] * a[k] + weights[1] * b[k] + weights[2] * c[k])
}

/// Squared distance from `p` to the closest point of the triangle `[a, b, c]` (Ericson,
/// Real-Time Collision Detection, section 5.1.5: the Voronoi region of a vertex, an edge
/// or the face). A degenerate triangle gives 0 (the exact tests reject it later).
#[inline]
pub(crate) fn distance2_to_triangle(p: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> f64 {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return norm2(ap);
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return norm2(bp);
    }
    let vc = d1 * d4 - d3 * d2;
    let d = if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        norm2(sub(ap, scale(ab, d1 / (d1 - d3))))
    } else {
        let cp = sub(p, c);
        let (d5, d6) = (dot(ab, cp), dot(ac, cp));
        let vb = d5 * d2 - d1 * d6;
        let va = d3 * d6 - d5 * d4;
        if d6 >= 0.0 && d5 <= d6 {
            norm2(cp)
        } else if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            norm2(sub(ap, scale(ac, d2 / (d2 - d6))))
        } else if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            norm2(sub(bp, scale(sub(c, b), w)))
        } else {
            let denom = 1.0 / (va + vb + vc);
            norm2(sub(ap, add(scale(ab, vb * denom), scale(ac, vc * denom))))
        }
    };
    if d.is_nan() { 0.0 } else { d }
}

/// Hand-written node-to-triangle test.
///
/// With `N = (b - a) x (c - a)` (outward, not normalised) the signed distance of the node
/// `x` is `s = (x - a) . N / |N|`; the node is a candidate when `-depth_limit <= s < 0`.
/// The barycentric coordinates of the foot of the perpendicular are
/// `w_b = ((x - a) x (c - a)) . N / |N|^2`, `w_c = ((b - a) x (x - a)) . N / |N|^2`,
/// `w_a = 1 - w_b - w_c` (the normal component of `x - a` drops out of both triple
/// products). Returns `None` for a node in front of the face, deeper than `depth_limit`,
/// with its foot outside the triangle, or for a degenerate face.
#[inline]
pub fn project_hand(node: [f64; 3], face: [[f64; 3]; 3], depth_limit: f64) -> Option<FaceHit> {
    let [a, b, c] = face;
    let e1 = sub(b, a);
    let e2 = sub(c, a);
    let n = cross(e1, e2);
    let p = sub(node, a);
    let s_scaled = dot(p, n);
    // Also rejects NaN.
    if s_scaled >= 0.0 || s_scaled.is_nan() {
        return None;
    }
    let nn = norm2(n);
    if nn <= 0.0 || nn.is_nan() {
        return None;
    }
    let inv_len = 1.0 / nn.sqrt();
    let depth = -s_scaled * inv_len;
    if depth > depth_limit {
        return None;
    }
    let inv_nn = 1.0 / nn;
    let wb = dot(cross(p, e2), n) * inv_nn;
    let wc = dot(cross(e1, p), n) * inv_nn;
    let wa = 1.0 - wb - wc;
    let tol = -BARYCENTRIC_TOLERANCE;
    if wa < tol || wb < tol || wc < tol {
        return None;
    }
    Some(FaceHit {
        depth,
        normal: scale(n, inv_len),
        weights: clamp_weights([wa, wb, wc]),
    })
}

#[inline(always)]
fn to_glam(p: [f64; 3]) -> Vector {
    Vector::new(p[0], p[1], p[2])
}

/// Node-to-triangle test through parry3d-f64.
///
/// Same plane test as [`project_hand`] (on parry's `Triangle::scaled_normal`), then
/// `Triangle::project_local_point_and_get_location`: a foot on the face interior gives its
/// barycentrics directly; a foot that parry snaps to an edge or vertex counts as inside
/// when the snap moved it by at most [`BARYCENTRIC_TOLERANCE`] times `sqrt(|N|)` (the
/// length scale of the face), with the snapped barycentrics as weights. `[f64; 3]` is
/// converted to glam's `DVec3` at the boundary.
#[inline]
pub fn project_parry(node: [f64; 3], face: [[f64; 3]; 3], depth_limit: f64) -> Option<FaceHit> {
    let tri = Triangle::new(to_glam(face[0]), to_glam(face[1]), to_glam(face[2]));
    let x = to_glam(node);
    let n = tri.scaled_normal();
    let s_scaled = (x - tri.a).dot(n);
    if s_scaled >= 0.0 || s_scaled.is_nan() {
        return None;
    }
    let nn = n.length_squared();
    if nn <= 0.0 || nn.is_nan() {
        return None;
    }
    let len = nn.sqrt();
    let depth = -s_scaled / len;
    if depth > depth_limit {
        return None;
    }
    let unit = n / len;
    let (projection, location) = tri.project_local_point_and_get_location(x, false);
    let weights = match location {
        TrianglePointLocation::OnFace(_, w) => w,
        _ => {
            let foot = x - unit * (x - tri.a).dot(unit);
            let snap = (projection.point - foot).length();
            if snap > BARYCENTRIC_TOLERANCE * len.sqrt() {
                return None;
            }
            location.barycentric_coordinates()?
        }
    };
    Some(FaceHit {
        depth,
        normal: [unit.x, unit.y, unit.z],
        weights: clamp_weights(weights),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closest point by brute force: a fine barycentric grid over the triangle.
    fn sampled_distance2(p: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> f64 {
        let n = 400;
        let mut best = f64::INFINITY;
        for i in 0..=n {
            for j in 0..=(n - i) {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                let q = add(a, add(scale(sub(b, a), u), scale(sub(c, a), v)));
                best = best.min(norm2(sub(p, q)));
            }
        }
        best
    }

    #[test]
    fn point_triangle_distance_matches_a_sampled_closest_point() {
        // Deterministic pseudo-random points around equilateral, right, obtuse and
        // sliver triangles: every Voronoi region (vertices, edges, face, both sides).
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let triangles = [
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.866, 0.0]],
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.3, 0.1]],
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.02, 0.01]],
        ];
        for tri in triangles {
            for _ in 0..300 {
                let p = [2.0 * next() + 0.5, 2.0 * next() + 0.3, next()];
                let exact = distance2_to_triangle(p, tri).sqrt();
                let sampled = sampled_distance2(p, tri).sqrt();
                // The grid's spacing bounds how far its best sample is from the truth.
                assert!(
                    exact <= sampled + 1e-12,
                    "{p:?} {tri:?}: {exact} > {sampled}"
                );
                assert!(
                    sampled - exact < 6e-3,
                    "{p:?} {tri:?}: {exact} vs {sampled}"
                );
            }
        }
    }
}
