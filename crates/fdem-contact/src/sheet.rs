//! Sheet bodies: thin membranes contacted from one side.
//!
//! # What a sheet is
//! A sheet is a body of the contact surface that is an open surface with no volume of its
//! own, such as the rubber membrane around a triaxial specimen. It is contacted from one
//! side only: its faces are oriented towards the particles (the membrane's outward normal
//! by the right-hand rule points to the specimen's axis), so a particle node that presses
//! the sheet outwards lies behind a face, at a depth measured along the face's normal,
//! exactly as a node pressed into a solid particle. The caller declares sheets with
//! [`ContactModel::set_sheet_bodies`]; every other body is a solid particle.
//!
//! # Why it needs rules of its own
//! Node-to-face contact reads "behind a face" as "inside the body", which holds for a solid
//! particle, whose volume lies behind every face. Behind a sheet there is nothing: a sheet
//! draped over angular particles folds over their edges and vertices, and the solid-body
//! rule (the nearest face the node is behind with its foot inside) breaks there: a
//! particle vertex pressing on the convex ridge of a sheet folded over it projects outside
//! both faces of the ridge, and a vertex can sit in front of one sheet face and far behind
//! a steep neighbour. Patching those holes with an edge test and filters made the contact
//! switch on and off at finite depths, which creates and destroys stored energy.
//! - **Closest point** ([`closest_contact`]): the depth of a node behind a sheet is its
//!   distance to the closest point of the sheet, and the angle-weighted pseudo-normal at
//!   that point says whether the node is behind. The depth is continuous over faces,
//!   edges and vertices, and the force is the gradient of the stored energy.
//! - **Fold depth** ([`Sheets::is_fold_artefact`]): a node found behind a sheet deeper than
//!   the fold depth is not a tunnelling particle but a fold artefact (the sheet moves
//!   slowly and the closest point follows it): the hit is discarded and counted in
//!   [`ContactReport::discarded_sheet_hits`]. The caller checks containment by other
//!   means (the triaxial test checks that every particle stays inside membrane and
//!   platens at every output).
//! - **Closest face** ([`covered_in_front`]) is the solid bodies' rule: a face of the same
//!   body that covers the node from the front, nearer than the hit's depth, means the node
//!   is outside there (on a convex particle it removes false contacts of nodes in the
//!   wedge outside an edge, [`crate::narrow::front_distance`]).
//!
//! # Invariants
//! - Declaring is additive: [`ContactModel::set_sheet_bodies`] marks bodies as sheets and
//!   never unmarks one; the fold depth (finite and > 0) is one value for all sheets, and
//!   infinite (nothing discarded) until the first declaration. A body id past the end of
//!   the flags is not a sheet.
//! - The rules concern the faces of a sheet, as the counterpart of another body's node; the
//!   sheet's own nodes against particle faces are ordinary node-to-face contacts.
//! - The broad phase keeps every face of a sheet within the skin plus the listing depth
//!   of a node as a candidate ([`Sheets::listing_depth`]: about the fold depth, at most
//!   the depth limit), also in front of its plane (the closest point and its
//!   pseudo-normal need the faces around it); see the broad phase's `FRONT_SKINS`. Every
//!   kept hit lies within that depth, and so does every face the tunnelling guard
//!   watches; the model refuses a step in which two nodes could approach by more.
//! - Per (node, sheet) the closest point decides, then the fold depth. A discarded fold
//!   artefact is never a [`ContactError::PenetrationTooDeep`].
//! - Every test is exact on its own; the plane pre-filter
//!   ([`Reach`](crate::detect::Reach)) only skips faces beyond its reach by more than its
//!   slack, so it does not change the contacts.
//!
//! [`ContactModel::set_sheet_bodies`]: crate::ContactModel::set_sheet_bodies
//! [`ContactReport::discarded_sheet_hits`]: crate::ContactReport::discarded_sheet_hits
//! [`ContactError::PenetrationTooDeep`]: crate::ContactError::PenetrationTooDeep

use crate::ContactError;
use crate::detect::{FaceContact, FaceGroup, plane_slack};
use crate::model::positive_length;
use crate::narrow::{FaceHit, closest_point_weights, front_distance, point_at};
use crate::vec3::{add, cross, dot, norm, norm2, scale, sub};

/// Which bodies are sheets, and the fold depth they share.
#[derive(Clone, Debug)]
pub(crate) struct Sheets {
    /// Per body id: whether the body is a sheet (bodies past the end are not).
    flags: Vec<bool>,
    /// Sheet hits deeper than this are discarded as fold artefacts (m).
    fold_depth: f64,
}

impl Default for Sheets {
    fn default() -> Self {
        Sheets {
            flags: Vec::new(),
            fold_depth: f64::INFINITY,
        }
    }
}

impl Sheets {
    /// Marks `bodies` as sheets and sets the fold depth (m).
    ///
    /// # Errors
    /// [`ContactError::InvalidLength`] for a `fold_depth` that is not finite and > 0
    /// (nothing is changed then).
    pub(crate) fn declare(&mut self, bodies: &[u32], fold_depth: f64) -> Result<(), ContactError> {
        self.fold_depth = positive_length("sheet fold depth", fold_depth)?;
        let n = bodies.iter().map(|&b| b as usize + 1).max().unwrap_or(0);
        if self.flags.len() < n {
            self.flags.resize(n, false);
        }
        for &b in bodies {
            self.flags[b as usize] = true;
        }
        Ok(())
    }

    /// How far behind a sheet its faces are listed for a node (m): what a kept hit and
    /// the tunnelling guard need, at most the depth limit `depth_limit`; `step_reach` is
    /// how far a node may move relative to a sheet in one step (`StepReach::sheet`).
    ///
    /// A kept hit is at most the fold depth deep, and [`closest_contact`] looks at the
    /// faces within `1 + TIE` times its depth plus the plane slack, so those are listed. A
    /// node farther than that from every listed face has no kept hit whatever lies
    /// beyond: its closest point over the listed faces is deeper than the fold depth too,
    /// or it has none. The forces are then those of lists that reach the depth limit; the
    /// count of discarded fold artefacts counts only the hits within this depth. The
    /// tunnelling guard watches the sheet faces within this depth (at least the step
    /// reach), and the model refuses a step in which two nodes could approach by more
    /// (`ContactModel::check_scan`).
    pub(crate) fn listing_depth(&self, depth_limit: f64, step_reach: f64) -> f64 {
        let kept = self.fold_depth.max(step_reach);
        (kept * (1.0 + TIE) + plane_slack(depth_limit)).min(depth_limit)
    }

    /// Whether any body is a sheet.
    pub(crate) fn any(&self) -> bool {
        self.flags.iter().any(|&f| f)
    }

    /// Whether `body` is a sheet.
    #[inline]
    pub(crate) fn is_sheet(&self, body: u32) -> bool {
        self.flags.get(body as usize).copied().unwrap_or(false)
    }

    /// Whether a hit `depth` (m) behind a face of `body` is a fold artefact: deeper than
    /// the fold depth, on a sheet.
    #[inline]
    pub(crate) fn is_fold_artefact(&self, body: u32, depth: f64) -> bool {
        depth > self.fold_depth && self.is_sheet(body)
    }
}

/// The contact of a node with a sheet: the closest point `q` of the sheet's nearby faces
/// (the node's candidates of that body, which for a sheet include the faces in front of
/// it), kept when the node lies behind the sheet there, with the depth `|x - q|` and the
/// node pushed towards `q`.
///
/// Behind is read from the angle-weighted pseudo-normal at `q` (Baerentzen and Aanaes,
/// "Signed distance computation using the angle weighted pseudonormal", IEEE TVCG 11,
/// 2005): the face normal inside a face, the sum of the two faces' normals on an edge, and
/// the normals of the faces around a vertex weighted by their angles there; the node is
/// behind when `(x - q) . n_q < 0`. Unlike a foot-inside-the-face test, the depth is then
/// continuous wherever the node moves over the faceted sheet (across edges and ridges),
/// and the force `k_n d (q - x) / d` is minus the gradient of `k_n d^2 / 2` with respect to
/// the node and, spread by the barycentric weights of `q`, to the face's nodes (the
/// closest point is a minimum over the triangle, so its own motion drops out): contacts
/// neither create nor destroy stored energy as they slide over the sheet.
///
/// A node behind the sheet within the depth limit is behind the plane of a face around
/// its closest point (the node lies in the normal cone at `q`, and a vector in a polar cone
/// with positive products with every generating normal would have a negative square), so
/// a node in front of every plane has no contact and costs no more than the plane test.
///
/// Where the sheet lies folded flat onto itself (two layers with opposite normals at the
/// same place), the closest point is a tie between the layers and its side is decided by
/// round-off. Ties (distances within [`TIE`] of the closest) are resolved by the history,
/// so that the side changes only through the sheet: a node that was in contact stays
/// behind if any tied face has it behind; a node that was not stays in front if any tied
/// face has it in front.
pub(crate) fn closest_contact(group: &FaceGroup<'_>, had_contact: bool) -> Option<FaceContact> {
    let reach = group.reach;
    let behind_some = group.signed.iter().any(|&s| s < 0.0 && reach.within(s));
    if !behind_some {
        return None;
    }
    let mut points = ClosestPoints::of(group);
    let closest = closest_distance(&mut points)?;
    if closest > reach.depth_limit {
        return None;
    }
    // The faces whose closest points tie with the closest, each with its side.
    let tie = closest * (1.0 + TIE) + reach.slack;
    let mut chosen: Option<FaceContact> = None;
    for (i, &s) in group.signed.iter().enumerate() {
        if s.abs() > tie {
            continue;
        }
        let Some(contact) = face_contact(&mut points, i) else {
            continue;
        };
        if contact.hit.depth > tie {
            continue;
        }
        let behind = contact.hit.depth == 0.0 || dot_behind(group, &contact);
        match (behind, had_contact) {
            (false, false) => return None,
            (false, true) => {}
            (true, _) => {
                if chosen.is_none_or(|b| contact.hit.depth < b.hit.depth) {
                    chosen = Some(contact);
                }
            }
        }
    }
    chosen
}

/// Relative tolerance of a tie between the closest points of two faces of a sheet.
pub(crate) const TIE: f64 = 1e-3;

/// Candidates of a group whose closest-point weights [`ClosestPoints`] keeps: a node has a
/// few candidate faces on one sheet, rarely more.
const KEPT: usize = 8;

/// The closest points of a group's faces to its node, each computed once: the closest
/// distance and the contact's choice look at the same faces, and a candidate past the
/// first [`KEPT`] is computed each time it is asked for (the same value).
struct ClosestPoints<'g, 'a> {
    group: &'g FaceGroup<'a>,
    /// Bit `i` set: `weights[i]` holds candidate `i`'s weights.
    known: u32,
    weights: [[f64; 3]; KEPT],
}

impl<'g, 'a> ClosestPoints<'g, 'a> {
    fn of(group: &'g FaceGroup<'a>) -> Self {
        ClosestPoints {
            group,
            known: 0,
            weights: [[0.0; 3]; KEPT],
        }
    }

    /// Candidate `i`'s face corners, and the barycentric weights of the face's closest
    /// point to the node.
    fn closest(&mut self, i: usize) -> ([[f64; 3]; 3], [f64; 3]) {
        let positions = self.group.positions;
        let face = self.group.cands[i].nodes.map(|j| positions[j as usize]);
        let bit = (i < KEPT).then(|| 1u32 << i);
        match bit {
            Some(b) if self.known & b != 0 => (face, self.weights[i]),
            _ => {
                let w = closest_point_weights(self.group.x, face);
                if let Some(b) = bit {
                    self.weights[i] = w;
                    self.known |= b;
                }
                (face, w)
            }
        }
    }

    /// The distance from the node to the closest point of candidate `i`'s face.
    fn distance(&mut self, i: usize) -> f64 {
        let (face, weights) = self.closest(i);
        norm2(sub(self.group.x, point_at(weights, face))).sqrt()
    }
}

/// The distance from the node to the closest point of the group's faces, or `None` when
/// the node is certainly in front of the sheet or farther behind it than the depth limit.
///
/// A node behind the sheet has its closest point on a face whose plane it is behind (see
/// [`closest_contact`]), so the closest distance over those faces, `d_b`, is the depth of
/// any contact. The faces the node is in front of matter only if one is nearer than
/// `d_b`: by more than a tie, the node is in front of the sheet there; within a tie, the
/// tie decides. Faces whose plane is farther than the best distance so far are skipped.
fn closest_distance(points: &mut ClosestPoints<'_, '_>) -> Option<f64> {
    let (signed, reach) = (points.group.signed, points.group.reach);
    let mut behind: Option<f64> = None;
    for (i, &s) in signed.iter().enumerate() {
        if s < 0.0 && reach.within(s) && behind.is_none_or(|b| -s <= b + reach.slack) {
            let d = points.distance(i);
            if d.is_finite() && behind.is_none_or(|b| d < b) {
                behind = Some(d);
            }
        }
    }
    let behind = behind.filter(|&b| b <= reach.depth_limit)?;
    let mut closest = behind;
    for (i, &s) in signed.iter().enumerate() {
        if s >= 0.0 && s <= behind + reach.slack {
            let d = points.distance(i);
            if d * (1.0 + TIE) + reach.slack < behind {
                return None;
            }
            closest = closest.min(d);
        }
    }
    Some(closest)
}

/// The contact of the node with the closest point of one face: depth `|x - q|`, the node
/// pushed towards `q` (along the face's pseudo-normal where `q = x`).
fn face_contact(points: &mut ClosestPoints<'_, '_>, i: usize) -> Option<FaceContact> {
    let group = points.group;
    let c = &group.cands[i];
    let x = group.x;
    let nodes = c.nodes.map(|j| j as usize);
    let (face, weights) = points.closest(i);
    let to_q = sub(point_at(weights, face), x);
    let depth = norm(to_q);
    if !depth.is_finite() {
        return None;
    }
    let normal = if depth > 0.0 {
        scale(to_q, 1.0 / depth)
    } else {
        let pseudo = pseudo_normal(group, c.nodes, weights);
        scale(pseudo, 1.0 / norm(pseudo))
    };
    Some(FaceContact {
        triangle: c.triangle as usize,
        nodes,
        hit: FaceHit {
            depth,
            normal,
            weights,
        },
        edge: weights.contains(&0.0),
    })
}

/// Whether the node is behind the sheet at the contact's closest point: `(q - x) . n_q > 0`
/// with the pseudo-normal `n_q` there.
fn dot_behind(group: &FaceGroup<'_>, contact: &FaceContact) -> bool {
    let tri = contact.nodes.map(|j| j as u32);
    let pseudo = pseudo_normal(group, tri, contact.hit.weights);
    dot(contact.hit.normal, pseudo) > 0.0
}

/// The angle-weighted pseudo-normal of the sheet at the point of triangle `tri` (global
/// node ids) with barycentric `weights`: the triangle's unit normal inside it; on an edge
/// (one weight 0) the sum of the unit normals of the group's faces that share the edge;
/// at a vertex (two weights 0) the sum over the group's faces around it of the unit
/// normal times the face's angle there.
fn pseudo_normal(group: &FaceGroup<'_>, tri: [u32; 3], weights: [f64; 3]) -> [f64; 3] {
    let (mut corners, mut n_on) = ([0u32; 3], 0);
    for (k, &w) in weights.iter().enumerate() {
        if w != 0.0 {
            corners[n_on] = tri[k];
            n_on += 1;
        }
    }
    let on = &corners[..n_on];
    let mut sum = [0.0; 3];
    for c in group.cands {
        if !on.iter().all(|v| c.nodes.contains(v)) {
            continue;
        }
        let face = c.nodes.map(|j| group.positions[j as usize]);
        let n = cross(sub(face[1], face[0]), sub(face[2], face[0]));
        let len = norm(n);
        if !(len > 0.0 && len.is_finite()) {
            continue;
        }
        let weight = match on {
            [v] => {
                let k = c.nodes.iter().position(|j| j == v).unwrap_or(0);
                corner_angle(face, k)
            }
            _ => 1.0,
        };
        sum = add(sum, scale(n, weight / len));
    }
    sum
}

/// The angle of the triangle `face` at its corner `k` (radians).
fn corner_angle(face: [[f64; 3]; 3], k: usize) -> f64 {
    let (a, b, c) = (face[k], face[(k + 1) % 3], face[(k + 2) % 3]);
    let (u, v) = (sub(b, a), sub(c, a));
    norm(cross(u, v)).atan2(dot(u, v))
}

/// The closest-face rule (every body): whether a face of the group covers the node from
/// the front, nearer than a hit `depth` behind another face; the node is then outside the
/// body there and the hit is dropped.
pub(crate) fn covered_in_front(group: &FaceGroup<'_>, depth: f64) -> bool {
    let (x, positions, slack) = (group.x, group.positions, group.reach.slack);
    let mut candidates = group.cands.iter().zip(group.signed).zip(group.outside);
    candidates.any(|((c, &s), &outside)| {
        !outside && s >= -slack && s <= depth + slack && {
            let face = c.nodes.map(|j| positions[j as usize]);
            front_distance(x, face, depth).is_some()
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::broad::Candidate;
    use crate::detect::Reach;

    /// A fan of `n` faces around node 0, its rim slightly warped, and a node below it.
    fn fan(n: u32) -> (Vec<[f64; 3]>, Vec<Candidate>) {
        let mut positions = vec![[0.0; 3]];
        for i in 0..n {
            let a = std::f64::consts::TAU * f64::from(i) / f64::from(n);
            positions.push([a.cos(), a.sin(), 0.05 * (3.0 * a).sin()]);
        }
        let cands = (0..n)
            .map(|i| Candidate {
                nodes: [0, 1 + i, 1 + (i + 1) % n],
                triangle: i,
                body: 1,
            })
            .collect();
        (positions, cands)
    }

    #[test]
    fn closest_points_are_those_of_each_face_asked_in_any_order() {
        let n = 12;
        let (positions, cands) = fan(n);
        let signed = vec![0.0; cands.len()];
        let outside = vec![false; cands.len()];
        let group = FaceGroup {
            x: [0.3, 0.2, -0.1],
            body: 1,
            cands: &cands,
            signed: &signed,
            outside: &outside,
            positions: &positions,
            reach: Reach {
                depth_limit: 1.0,
                slack: 0.0,
            },
        };
        let mut points = ClosestPoints::of(&group);
        // Kept and not kept candidates, each asked for more than once, out of order.
        for i in [3, 11, 0, 3, 11, 9, 0, 10, 10, 7, 1, 2, 1] {
            let face = cands[i].nodes.map(|j| positions[j as usize]);
            let direct = closest_point_weights(group.x, face);
            let (kept_face, kept) = points.closest(i);
            assert_eq!(kept_face, face, "candidate {i}");
            assert_eq!(
                kept.map(f64::to_bits),
                direct.map(f64::to_bits),
                "candidate {i}"
            );
            let q = point_at(direct, face);
            let d = norm2(sub(group.x, q)).sqrt();
            assert_eq!(points.distance(i).to_bits(), d.to_bits(), "candidate {i}");
        }
    }
}
