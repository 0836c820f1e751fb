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
//! draped over angular particles folds over their edges and vertices, and that breaks the
//! solid-body reading in three places:
//! - **Edge test** ([`edge_contact`]): a particle vertex pressing on the convex ridge of a
//!   sheet folded over it projects outside both faces of the ridge, so no face covers it
//!   and node-to-face contact alone lets it pass through. For a sheet, a node that no face
//!   covers is also tested against the faces' edges and vertices (the closest point,
//!   [`crate::narrow::project_to_edge`]). Such a hit counts only where the node is behind
//!   the planes of all the sheet's nearby faces (a ridge folded over it), not in front of
//!   any of them within the hit's depth.
//! - **Closest face** ([`covered_in_front`]): a particle vertex can sit in front of one
//!   sheet face (on the particle side, outside) and far behind a steep neighbour face. A
//!   face of the same body that covers the node from the front nearer than the hit's depth
//!   means the node is outside there, and the hit is dropped. The rule applies to every
//!   body, not only to sheets: on a convex particle it removes false contacts of nodes in
//!   the wedge outside an edge ([`crate::narrow::front_distance`]).
//! - **Fold depth** ([`Sheets::is_fold_artefact`]): a node found behind a sheet deeper than
//!   the fold depth is not a tunnelling particle but a fold artefact (the sheet moves
//!   slowly and has the edge test): the hit is discarded and counted in
//!   [`ContactReport::discarded_sheet_hits`]. The caller checks containment by other
//!   means (the triaxial test checks that every particle stays inside membrane and
//!   platens at every output).
//!
//! # Invariants
//! - Declaring is additive: [`ContactModel::set_sheet_bodies`] marks bodies as sheets and
//!   never unmarks one; the fold depth (finite and > 0) is one value for all sheets, and
//!   infinite (nothing discarded) until the first declaration. A body id past the end of
//!   the flags is not a sheet.
//! - The rules concern the faces of a sheet, as the counterpart of another body's node; the
//!   sheet's own nodes against particle faces are ordinary node-to-face contacts.
//! - The broad phase keeps every face of a sheet within reach of a node as a candidate,
//!   also in front of its plane (the edge test and its filter look at faces in front);
//!   see the broad phase's `FRONT_SKINS`.
//! - Per (node, other body) the rules run in a fixed order: nearest face behind, else (for
//!   a sheet) the nearest edge; then the closest-face rule; then (for a sheet) the fold
//!   depth. A discarded fold artefact is never a [`ContactError::PenetrationTooDeep`].
//! - Every test is exact on its own; the plane pre-filter
//!   ([`Reach`](crate::detect::Reach)) only skips faces beyond its reach by more than its
//!   slack, so it does not change the contacts.
//!
//! [`ContactModel::set_sheet_bodies`]: crate::ContactModel::set_sheet_bodies
//! [`ContactReport::discarded_sheet_hits`]: crate::ContactReport::discarded_sheet_hits
//! [`ContactError::PenetrationTooDeep`]: crate::ContactError::PenetrationTooDeep

use crate::ContactError;
use crate::detect::{FaceContact, FaceGroup};
use crate::model::positive_length;
use crate::narrow::{front_distance, project_to_edge};
use crate::vec3::{cross, dot, norm, sub};

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

/// The edge test of a sheet that no face covers the node with: the nearest closest
/// point on the edges and vertices of the group's faces that the node is behind, kept only
/// where no nearby face of the sheet has the node in front of its plane within the hit's
/// depth (so the node is behind the planes of all of them: a ridge folded over it).
/// Nearby: the node's candidates, the faces within skin plus depth limit of it at the last
/// broad-phase build.
pub(crate) fn edge_contact(group: &FaceGroup<'_>) -> Option<FaceContact> {
    let (x, positions, reach) = (group.x, group.positions, group.reach);
    let mut edge: Option<FaceContact> = None;
    for (c, &s) in group.cands.iter().zip(group.signed) {
        // `project_to_edge` needs the node behind the plane within the limit.
        if !reach.within(s) {
            continue;
        }
        let nodes = c.nodes.map(|j| j as usize);
        let face = nodes.map(|j| positions[j]);
        if let Some(hit) = project_to_edge(x, face, reach.depth_limit)
            && edge.is_none_or(|b| hit.depth < b.hit.depth)
        {
            edge = Some(FaceContact {
                triangle: c.triangle as usize,
                nodes,
                hit,
            });
        }
    }
    edge.filter(|e| !in_front_of_a_plane(group, e.hit.depth))
}

/// Whether a face of the group has the node in front of its plane by at most `depth`.
fn in_front_of_a_plane(group: &FaceGroup<'_>, depth: f64) -> bool {
    let (x, positions, slack) = (group.x, group.positions, group.reach.slack);
    group.cands.iter().zip(group.signed).any(|(c, &s)| {
        if s < -slack || s > depth + slack {
            return false;
        }
        let [a, b, cc] = c.nodes.map(|j| positions[j as usize]);
        let n = cross(sub(b, a), sub(cc, a));
        let len = norm(n);
        len > 0.0 && {
            let s = dot(sub(x, a), n) / len;
            (0.0..=depth).contains(&s)
        }
    })
}

/// The closest-face rule (every body): whether a face of the group covers the node from
/// the front, nearer than a hit `depth` behind another face; the node is then outside the
/// body there and the hit is dropped.
pub(crate) fn covered_in_front(group: &FaceGroup<'_>, depth: f64) -> bool {
    let (x, positions, slack) = (group.x, group.positions, group.reach.slack);
    group.cands.iter().zip(group.signed).any(|(c, &s)| {
        s >= -slack && s <= depth + slack && {
            let face = c.nodes.map(|j| positions[j as usize]);
            front_distance(x, face, depth).is_some()
        }
    })
}
