//! One narrow-phase pass: the contacts of every surface node in one evaluation.
//!
//! Per surface node, in the order of its candidates (sorted by owner body by the broad
//! phase): for each other body the nearest face the node is behind with its foot inside,
//! with the rules for sheets and the closest-face rule of [`crate::sheet`]; then the
//! walls. Each contact is evaluated with the law against its tangential history (the
//! previous evaluation's contact with the same key) and recorded with what the report
//! needs, and what the spread of its force reads ([`SpreadTerm`]). Surface nodes are
//! processed in fixed chunks of [`CHUNK`], each writing its own records and sums, so the
//! result does not depend on the thread count; the model adds the forces afterwards, in
//! the order of the records.

use crate::broad::{BroadPhase, CHUNK, Candidate};
use crate::events::{Reason, Rejection};
use crate::history::{Cursor, History};
use crate::law::{LawInput, evaluate_law};
use crate::model::{
    Counterpart, NodeContact, StepReach, TUNNELLING_FRACTION, history_key, unit_plane,
};
use crate::narrow::{FaceHit, ProjectionKernel, distance2_to_triangle, project_hand};
use crate::prefetch::prefetch;
use crate::rigid_frames::{NodeVelocities, RigidFrames, RigidMotion};
use crate::sheet::{self, Sheets};
use crate::vec3::{add, norm, scale, sub};
use crate::wall::wall_distance;
use crate::{ContactError, ContactSurface, NodeCoefficients, TunnellingScale, Wall, WallShape};

/// Slack of the plane pre-filter of the narrow phase, as a fraction of the depth limit.
const PLANE_SLACK: f64 = 1e-9;

/// How many surface nodes ahead the narrow phase asks for its candidates' corners
/// ([`Ctx::prefetch_faces`]).
const PREFETCH_AHEAD: usize = 8;

/// Relative slack of the test that a body is clear of the walls
/// ([`bodies_clear_of_walls`]): far above the round-off of a node's wall distance (about
/// 1e-16 of the coordinates).
const CLEAR_SLACK: f64 = 1e-9;

/// Marks in `clear` (per body id, resized to `n_bodies`) the framed rigid bodies whose
/// nodes the narrow phase may pass over when they have no candidate: every node lies in
/// the ball its pose gives it ([`RigidFrames::ball`]), and that ball stays farther from
/// every wall than the margin plus the most its nodes can move relative to the wall in
/// one step (`motions`' speed bound and the wall's speed, times `dt`). Such a node can
/// neither touch a wall (its distance stays positive) nor trip a wall's tunnelling check
/// (which needs a distance below the margin plus that motion, `Ctx::wall_contacts`),
/// and without candidates it meets no face, so passing over it changes no contact and no
/// error. Bodies without a run of face-corner nodes, or with a motion that is not finite,
/// are not marked. Like the template-frame distances, this takes the poses of the time
/// for where the nodes are.
pub(crate) fn bodies_clear_of_walls(
    frames: &RigidFrames,
    motions: &[RigidMotion],
    (walls, shapes): (&[Wall], &[WallShape]),
    (margin, dt): (f64, f64),
    (n_bodies, clear): (usize, &mut Vec<bool>),
) {
    clear.clear();
    clear.resize(n_bodies, false);
    for (body, k) in frames.framed_bodies() {
        let (Some(motion), Some((centre, radius))) = (motions.get(k), frames.nodes_ball(k)) else {
            continue;
        };
        let clear_of = |(wall, shape): (&Wall, &WallShape)| {
            let Some((distance, _)) = wall_distance(shape, centre) else {
                return false;
            };
            let extent = match *shape {
                WallShape::Plane { point, .. } => norm(point),
                WallShape::Cylinder {
                    axis_point, radius, ..
                } => norm(axis_point) + radius,
            };
            let slack = CLEAR_SLACK * (norm(centre) + radius + extent + margin);
            let travel = (motion.speed_bound + norm(wall.velocity)) * dt;
            // Written so that a NaN anywhere leaves the body unmarked.
            distance - radius - slack >= margin + travel * (1.0 + CLEAR_SLACK)
        };
        clear[body as usize] = motion.finite && walls.iter().zip(shapes).all(clear_of);
    }
}

/// What spreading one contact's force needs, in one cache line: the force on the node,
/// the node, and the face's nodes with the contact point's weights on them (or a wall).
/// Node ids are kept in 32 bits, as in the broad phase's candidates.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SpreadTerm {
    /// The force on the node (N): the contact's normal plus tangential force.
    pub(crate) force: [f64; 3],
    /// The contact point's barycentric weights on `corners` (zeros for a wall).
    pub(crate) weights: [f64; 3],
    /// The node's global id.
    pub(crate) node: u32,
    /// The face's three global node ids; for a wall `[NO_FACE, wall, 0]`, and
    /// `[NO_FACE; 3]` for neither.
    pub(crate) corners: [u32; 3],
}

/// The first corner of a [`SpreadTerm`] without a face.
pub(crate) const NO_FACE: u32 = u32::MAX;

/// One chunk's sums for the report.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Sums {
    /// Sheet hits discarded as fold artefacts.
    pub(crate) discarded: usize,
    /// Sliding contacts.
    pub(crate) sliding: usize,
    /// Contacts with walls.
    pub(crate) wall_contacts: usize,
    pub(crate) stored: f64,
    pub(crate) normal_damping: f64,
    pub(crate) tangential_damping: f64,
    pub(crate) friction: f64,
    pub(crate) max_depth: f64,
}

/// What one chunk of surface nodes writes: its contact records, its sums, its first error.
#[derive(Clone, Debug, Default)]
pub(crate) struct ChunkScratch {
    pub(crate) contacts: Vec<NodeContact>,
    /// Per contact, in the same order, what the spread of its force reads.
    pub(crate) terms: Vec<SpreadTerm>,
    /// Signed distances of the current node to its candidates' planes.
    signed: Vec<f64>,
    /// Per candidate of the current node, whether its template screened the foot out.
    outside: Vec<bool>,
    pub(crate) sums: Sums,
    pub(crate) error: Option<ContactError>,
    /// Why (node, body) pairs with candidates got no contact; filled only while the
    /// stored-energy jump log is on ([`crate::events`]).
    pub(crate) rejections: Vec<Rejection>,
}

/// The contact of a node with one face: the triangle, its global node ids, the hit.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FaceContact {
    pub(crate) triangle: usize,
    pub(crate) nodes: [usize; 3],
    pub(crate) hit: FaceHit,
    /// Whether the hit is a sheet's closest point on an edge or a vertex of the face.
    pub(crate) edge: bool,
}

/// A node and its candidate faces on one other body: what the per-body rules look at.
pub(crate) struct FaceGroup<'a> {
    /// Position of the node (m).
    pub(crate) x: [f64; 3],
    /// The other body.
    pub(crate) body: u32,
    /// The node's candidate faces on that body.
    pub(crate) cands: &'a [Candidate],
    /// The node's signed distances to their planes (positive in front).
    pub(crate) signed: &'a [f64],
    /// Per candidate, whether its foot lies clearly outside the face (screened in a rigid
    /// body's template frame, `crate::rigid_frames`; `false` where not screened): no exact
    /// test on the face can accept the node then.
    pub(crate) outside: &'a [bool],
    /// Positions of all nodes (m).
    pub(crate) positions: &'a [[f64; 3]],
    pub(crate) reach: Reach,
}

/// The reach of the narrow phase behind a face's plane: the depth limit, and the slack of
/// the plane pre-filter.
///
/// The signed distances to the candidates' planes are a cheap pre-filter. Every test is
/// exact on its own; the filter only skips faces that are beyond its reach by more than
/// `slack`, far above the round-off of `n . x - n . a` (1e-16 of the coordinates), so the
/// contacts are unchanged.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Reach {
    pub(crate) depth_limit: f64,
    pub(crate) slack: f64,
}

/// The slack of the plane pre-filter at the depth limit `depth_limit` (m).
pub(crate) fn plane_slack(depth_limit: f64) -> f64 {
    PLANE_SLACK * depth_limit
}

impl Reach {
    fn of(depth_limit: f64) -> Reach {
        Reach {
            depth_limit,
            slack: plane_slack(depth_limit),
        }
    }

    /// Behind the plane (or on it) by at most the depth limit, up to the slack.
    #[inline]
    pub(crate) fn within(self, s: f64) -> bool {
        s <= self.slack && s >= -self.depth_limit - self.slack
    }
}

/// Read-only context of one narrow-phase pass.
pub(crate) struct Ctx<'a> {
    pub(crate) surface: &'a ContactSurface,
    pub(crate) broad: &'a BroadPhase,
    pub(crate) coefficients: &'a [NodeCoefficients],
    pub(crate) walls: &'a [Wall],
    pub(crate) wall_shapes: &'a [WallShape],
    /// The contacts of the previous evaluation, chunk by chunk: the tangential history.
    pub(crate) previous: &'a History,
    pub(crate) kernel: ProjectionKernel,
    pub(crate) positions: &'a [[f64; 3]],
    /// The node velocities: a framed body's from its motion when given.
    pub(crate) velocities: NodeVelocities<'a>,
    pub(crate) dt: f64,
    pub(crate) margin: f64,
    pub(crate) depth_limit: f64,
    /// How far behind a sheet its faces are listed (m), `Sheets::listing_depth`.
    pub(crate) sheet_depth: f64,
    /// How far a node may move relative to a face or wall in one step.
    pub(crate) reach: StepReach,
    /// Whether to check each node against the faces' velocities for tunnelling.
    pub(crate) check_faces: bool,
    /// Whether to check each node against the walls' velocities for tunnelling.
    pub(crate) check_walls: bool,
    pub(crate) sheets: &'a Sheets,
    /// The rigid bodies' frames, when they stand in for their faces' world planes.
    pub(crate) frames: Option<&'a RigidFrames>,
    /// Whether to record the rejections of the stored-energy jump log.
    pub(crate) diagnose: bool,
    /// Whether an evaluation came before this one (its contacts are `previous`).
    pub(crate) evaluated: bool,
    /// Per body id, whether its nodes without candidates may be passed over
    /// ([`bodies_clear_of_walls`]; empty: none may).
    pub(crate) clear_of_walls: &'a [bool],
    /// Whether the node arrays lie beyond a core's cache ([`far_arrays`]).
    pub(crate) far_arrays: bool,
}

/// The size of the positions array (bytes) above which [`far_arrays`] holds: twice the
/// second-level cache of one core of the development machine.
const FAR_ARRAYS_BYTES: usize = 2 << 20;

/// Whether the node arrays of `positions` are too large to stay in a core's cache between
/// evaluations, so that the narrow phase also asks ahead for the reads that miss only
/// then (its nodes' own positions and velocities, its candidates' corner velocities,
/// [`Ctx::prefetch_faces`]). In a smaller model those reads hit the cache and the hints'
/// own instructions cost more than they save (docs/PERFORMANCE.md, "The corners'
/// velocities asked for ahead ..."). Either way the values are the same.
pub(crate) fn far_arrays(positions: &[[f64; 3]]) -> bool {
    std::mem::size_of_val(positions) > FAR_ARRAYS_BYTES
}

/// Whether a node at signed `distance` (m, positive in front) from a wall is in contact
/// with it: [`Ctx::wall_contacts`] records a contact on this test alone, and
/// [`Ctx::touches_no_wall`] passes a node over on it.
#[inline(always)]
fn behind_wall(distance: f64) -> bool {
    distance < 0.0
}

impl Ctx<'_> {
    /// How far node `k` may move relative to `counterpart` in one step, and the scale
    /// that sets it ([`StepReach`]).
    fn reach(&self, counterpart: Counterpart) -> (f64, TunnellingScale) {
        match counterpart {
            Counterpart::Body(b) if self.sheets.is_sheet(b) => {
                (self.reach.sheet, TunnellingScale::Margin)
            }
            _ => (self.reach.solid, TunnellingScale::DepthLimit),
        }
    }

    fn tunnelling(&self, k: usize, relative_to: Counterpart, displacement: f64) -> ContactError {
        let (reach, scale) = self.reach(relative_to);
        ContactError::Tunnelling {
            node: self.surface.surface_nodes[k],
            body: self.surface.node_body[k],
            relative_to: relative_to.to_string(),
            displacement,
            limit: reach / TUNNELLING_FRACTION,
            scale,
            dt: self.dt,
        }
    }

    /// All contacts of the surface nodes of `chunk` (fixed chunks of [`CHUNK`] nodes) into
    /// `scratch`; stops at the first error.
    pub(crate) fn run_chunk(&self, chunk: usize, scratch: &mut ChunkScratch) {
        scratch.contacts.clear();
        scratch.terms.clear();
        scratch.sums = Sums::default();
        scratch.error = None;
        scratch.rejections.clear();
        let n = self.surface.surface_nodes.len();
        let start = chunk * CHUNK;
        let mut cursor = Cursor::new(self.previous.chunk(chunk));
        let lists = self.broad.chunk_lists(chunk);
        let end = (start + CHUNK).min(n);
        for k in start..end {
            if k + PREFETCH_AHEAD < end {
                let ahead = k + PREFETCH_AHEAD;
                self.prefetch_faces(ahead, lists.of(ahead - start));
            }
            let cands = lists.of(k - start);
            if cands.is_empty() && (self.clear_of_walls(k) || self.touches_no_wall(k)) {
                continue;
            }
            if let Err(e) = self.node(k, cands, scratch, &mut cursor) {
                scratch.error = Some(e);
                return;
            }
        }
    }

    /// Whether surface node `k`'s body is clear of the walls in this evaluation
    /// ([`bodies_clear_of_walls`]): without candidates, the node has no contact then and
    /// trips no check.
    #[inline(always)]
    fn clear_of_walls(&self, k: usize) -> bool {
        let body = self.surface.node_body[k] as usize;
        self.clear_of_walls.get(body).copied().unwrap_or(false)
    }

    /// Whether surface node `k` stays clear of every wall in this evaluation without a
    /// tunnelling check to run: no wall check this step (`check_walls`) and no wall with
    /// the node behind it. Exactly when [`Ctx::wall_contacts`] would neither record a
    /// contact nor return an error, read from the node's position alone, so that a node
    /// without candidates (most nodes of a packing) is passed over without its velocity or
    /// scratch.
    #[inline(always)]
    fn touches_no_wall(&self, k: usize) -> bool {
        if self.check_walls {
            return false;
        }
        let x = self.positions[self.surface.surface_nodes[k]];
        !self
            .wall_shapes
            .iter()
            .any(|shape| wall_distance(shape, x).is_some_and(|(d, _)| behind_wall(d)))
    }

    /// Asks the memory system for the corners' positions of surface node `k`'s candidates
    /// `cands` and, when it has candidates, the node's contact coefficients; with node
    /// arrays beyond a core's cache ([`far_arrays`]) also for the node's own position and
    /// velocity and the corners' velocities. The candidates' faces lie on other bodies,
    /// anywhere in the arrays; the nodes with candidates, and the fewer with contacts, are
    /// read far apart: without a hint each waits for a cache miss. A velocity the node's
    /// or the face's body motion gives is not asked for ([`NodeVelocities::prefetch`]). A
    /// hint changes no value.
    #[inline(always)]
    fn prefetch_faces(&self, k: usize, cands: &[Candidate]) {
        let far = self.far_arrays;
        if !cands.is_empty() {
            // The law reads the node's coefficients if a contact forms.
            prefetch(self.coefficients, k);
        }
        if far {
            self.prefetch_node(k, !cands.is_empty());
        }
        for c in cands {
            let corners = c.nodes.map(|j| j as usize);
            for j in corners {
                prefetch(self.positions, j);
            }
            if far {
                // A contact's face velocity reads its corners' (`Ctx::push_face`).
                self.velocities.prefetch(c.body, corners);
            }
        }
    }

    /// Asks for surface node `k`'s own position, which is read with candidates or
    /// without (`Ctx::touches_no_wall`), and, `with_candidates`, its velocity, read before
    /// any face is met. Only for node arrays beyond a core's cache ([`far_arrays`]).
    #[inline(always)]
    fn prefetch_node(&self, k: usize, with_candidates: bool) {
        let node = self.surface.surface_nodes[k];
        prefetch(self.positions, node);
        if with_candidates {
            self.velocities.prefetch(self.surface.node_body[k], [node]);
        }
    }

    /// All contacts of surface node `k` (candidates `cands`): the best face per other body,
    /// then the walls.
    fn node(
        &self,
        k: usize,
        cands: &[Candidate],
        scratch: &mut ChunkScratch,
        cursor: &mut Cursor<'_>,
    ) -> Result<(), ContactError> {
        let node = self.surface.surface_nodes[k];
        let x = self.positions[node];
        let v = self.velocities.of_surface_node(self.surface, k, x);
        let mut signed = std::mem::take(&mut scratch.signed);
        let mut outside = std::mem::take(&mut scratch.outside);
        self.signed_distances(x, cands, &mut signed, &mut outside);
        let faces = self.body_contacts(k, x, v, cands, (&signed, &outside), scratch, cursor);
        scratch.signed = signed;
        scratch.outside = outside;
        faces?;
        self.wall_contacts(k, x, v, scratch, cursor)
    }

    /// Signed distances of `x` to the candidates' planes (positive in front) into `signed`,
    /// and into `outside` whether a candidate's foot was screened out: from the faces'
    /// planes at these positions ([`unit_plane`] of the corners, which the hint of
    /// [`Ctx::prefetch_faces`] brought in; nothing screened), or for a rigid body with a
    /// frame from its template's planes and barycentric maps (`crate::rigid_frames`; the
    /// candidates come grouped by body).
    fn signed_distances(
        &self,
        x: [f64; 3],
        cands: &[Candidate],
        signed: &mut Vec<f64>,
        outside: &mut Vec<bool>,
    ) {
        signed.clear();
        outside.clear();
        let world = |c: &Candidate| {
            let [nx, ny, nz, offset] = unit_plane(c.nodes.map(|j| self.positions[j as usize]));
            nx * x[0] + ny * x[1] + nz * x[2] - offset
        };
        let Some(frames) = self.frames else {
            signed.extend(cands.iter().map(world));
            outside.resize(cands.len(), false);
            return;
        };
        let mut start = 0;
        while start < cands.len() {
            let body = cands[start].body;
            let end = start + cands[start..].iter().take_while(|c| c.body == body).count();
            let group = &cands[start..end];
            match frames.view(body, x) {
                Some(view) => {
                    signed.extend(group.iter().map(|c| view.signed_distance(c.triangle)));
                    let screen = |c: &Candidate| view.foot_clearly_outside(c.triangle);
                    outside.extend(group.iter().map(screen));
                }
                None => {
                    signed.extend(group.iter().map(world));
                    outside.resize(end, false);
                }
            }
            start = end;
        }
    }

    /// The contacts of surface node `k` (at `x`, velocity `v`) with the faces of other
    /// bodies: at most one per body, from the candidates of that body (consecutive, as the
    /// broad phase sorts them by body).
    #[allow(clippy::too_many_arguments)]
    fn body_contacts(
        &self,
        k: usize,
        x: [f64; 3],
        v: [f64; 3],
        cands: &[Candidate],
        (signed, outside): (&[f64], &[bool]),
        scratch: &mut ChunkScratch,
        cursor: &mut Cursor<'_>,
    ) -> Result<(), ContactError> {
        let reach = Reach::of(self.depth_limit);
        let mut start = 0;
        while start < cands.len() {
            let body = cands[start].body;
            let end = start + cands[start..].iter().take_while(|c| c.body == body).count();
            let group = FaceGroup {
                x,
                body,
                cands: &cands[start..end],
                signed: &signed[start..end],
                outside: &outside[start..end],
                positions: self.positions,
                reach,
            };
            start = end;
            match self.group_contact(k, v, &group, &mut scratch.sums, cursor)? {
                Ok(contact) => self.push_face(k, v, body, contact, scratch, cursor)?,
                Err(reason) if self.diagnose => scratch.rejections.push(Rejection {
                    key: history_key(k, Counterpart::Body(body)),
                    reason,
                }),
                Err(_) => {}
            }
        }
        Ok(())
    }

    /// The contact of surface node `k` with one other body: the nearest face it is behind,
    /// else for a sheet its nearest edge; none (with the reason) when a nearer face of the
    /// body has it in front, or when it is a sheet's fold artefact (counted in `sums`). The
    /// sheet rules are explained in the `sheet` module.
    fn group_contact(
        &self,
        k: usize,
        v: [f64; 3],
        group: &FaceGroup<'_>,
        sums: &mut Sums,
        cursor: &mut Cursor<'_>,
    ) -> Result<Result<FaceContact, Reason>, ContactError> {
        self.check_tunnelling(k, v, group)?;
        let is_sheet = self.sheets.is_sheet(group.body);
        let had_contact = is_sheet
            && cursor
                .find(history_key(k, Counterpart::Body(group.body)))
                .is_some();
        let best = if is_sheet {
            sheet::closest_contact(group, had_contact)
        } else {
            self.nearest_face(group)
        };
        let Some(best) = best else {
            return Ok(Err(Reason::NoFaceBehind));
        };
        // Closest face wins: a face of the same body that covers the node from the
        // front, nearer than the deepest-behind hit, means the node is outside there.
        // (A sheet's closest point already decides that by its pseudo-normal.)
        if !is_sheet && sheet::covered_in_front(group, best.hit.depth) {
            return Ok(Err(Reason::ClosestFace));
        }
        // A sheet hit deeper than the fold depth is a fold artefact (the sheet moves
        // slowly and the closest point follows it): discard it, count it.
        if self.sheets.is_fold_artefact(group.body, best.hit.depth) {
            sums.discarded += 1;
            return Ok(Err(Reason::FoldDiscard));
        }
        // A new contact with a sheet starts at its surface: the node and the sheet move
        // less than half the margin relative to each other in one step (the tunnelling
        // guard), so a new hit deeper than that is a fold artefact too (a closest point that
        // moved to another layer of a folded sheet), unless no evaluation came before.
        if is_sheet
            && !had_contact
            && self.evaluated
            && best.hit.depth > TUNNELLING_FRACTION * self.margin
        {
            sums.discarded += 1;
            return Ok(Err(Reason::DeepStart));
        }
        Ok(Ok(best))
    }

    /// The tunnelling check of node `k` (velocity `v`) against the faces of the group
    /// whose window holds it (behind the face by at most the depth limit, its foot inside;
    /// for a sheet, every face within the depth limit of it), when this step needs it: the
    /// node may not move farther than its reach ([`StepReach`]) relative to a face's
    /// centroid in one step.
    ///
    /// A node that crosses a face in a step shorter than the reach lands in the window of
    /// a face of that body (of the crossed one, or beside an edge of a convex body of the
    /// next one), where this check sees it; a farther face cannot be met in this step (no
    /// two nodes approach by more than the depth limit in one, [`ContactModel::add_forces`]
    /// checks that first). Every face whose window holds the node, and every sheet face
    /// within the depth limit, is a candidate whatever the last build or refresh, so the
    /// check does not depend on how many other candidates the lists hold.
    ///
    /// [`ContactModel::add_forces`]: crate::ContactModel::add_forces
    fn check_tunnelling(
        &self,
        k: usize,
        v: [f64; 3],
        group: &FaceGroup<'_>,
    ) -> Result<(), ContactError> {
        if !self.check_faces {
            return Ok(());
        }
        let counterpart = Counterpart::Body(group.body);
        let (reach, _) = self.reach(counterpart);
        let is_sheet = self.sheets.is_sheet(group.body);
        let watched_depth = if is_sheet {
            self.sheet_depth
        } else {
            self.depth_limit
        };
        let limit2 = watched_depth * watched_depth * (1.0 + PLANE_SLACK);
        // The plane distance bounds the face distance from below: skip the faces beyond
        // the limit by more than the filter's slack (an exact test decides the rest).
        let plane_reach = limit2.sqrt() + plane_slack(self.depth_limit);
        for (c, &s) in group.cands.iter().zip(group.signed) {
            if s.abs() > plane_reach {
                continue;
            }
            let face = c.nodes.map(|j| self.positions[j as usize]);
            let watched = if is_sheet {
                distance2_to_triangle(group.x, face) <= limit2
            } else {
                project_hand(group.x, face, self.depth_limit).is_some()
            };
            if !watched {
                continue;
            }
            let [a, b, cc] = std::array::from_fn(|i| {
                self.velocities.of(group.body, c.nodes[i] as usize, face[i])
            });
            let vc = scale(add(add(a, b), cc), 1.0 / 3.0);
            let d = norm(sub(v, vc)) * self.dt;
            if d > reach {
                return Err(self.tunnelling(k, counterpart, d));
            }
        }
        Ok(())
    }

    /// The nearest face of the group that the node is behind with its foot inside.
    fn nearest_face(&self, group: &FaceGroup<'_>) -> Option<FaceContact> {
        let (x, reach) = (group.x, group.reach);
        let mut best: Option<FaceContact> = None;
        // The screen's band holds the hand-written projection's tolerance only.
        let screened = self.kernel == ProjectionKernel::Hand;
        let candidates = group.cands.iter().zip(group.signed).zip(group.outside);
        for ((c, &s), &outside) in candidates {
            if !reach.within(s) || (screened && outside) {
                continue;
            }
            let nodes = c.nodes.map(|j| j as usize);
            let face = nodes.map(|j| self.positions[j]);
            if let Some(hit) = self.kernel.project(x, face, reach.depth_limit)
                && best.is_none_or(|b| hit.depth < b.hit.depth)
            {
                best = Some(FaceContact {
                    triangle: c.triangle as usize,
                    nodes,
                    hit,
                    edge: false,
                });
            }
        }
        best
    }

    /// Records the contact of surface node `k` (velocity `v`) with a face of body `other`,
    /// refusing one deeper than [`TUNNELLING_FRACTION`] of the depth limit.
    fn push_face(
        &self,
        k: usize,
        v: [f64; 3],
        other: u32,
        contact: FaceContact,
        scratch: &mut ChunkScratch,
        cursor: &mut Cursor<'_>,
    ) -> Result<(), ContactError> {
        let FaceContact {
            triangle,
            nodes,
            hit,
            edge,
        } = contact;
        let counterpart = Counterpart::Body(other);
        let depth_limit = self.depth_limit;
        if hit.depth > TUNNELLING_FRACTION * depth_limit {
            return Err(ContactError::PenetrationTooDeep {
                node: self.surface.surface_nodes[k],
                body: self.surface.node_body[k],
                counterpart,
                depth: hit.depth,
                depth_limit,
            });
        }
        let w = hit.weights;
        let mut v_face = [0.0; 3];
        let mut point = [0.0; 3];
        // A framed body's corner velocities are its motion's at their positions, the same
        // bits as the placed ones, without a read of the velocity array (a cache miss per
        // contact in large models).
        for (j, wj) in nodes.iter().zip(w) {
            let x = self.positions[*j];
            let vj = self.velocities.of(other, *j, x);
            v_face = add(v_face, scale(vj, wj));
            point = add(point, scale(x, wj));
        }
        self.push(
            scratch,
            cursor,
            k,
            counterpart,
            Some((triangle, nodes)),
            w,
            point,
            hit.depth,
            hit.normal,
            sub(v, v_face),
        );
        if let Some(last) = scratch.contacts.last_mut() {
            last.edge = edge;
        }
        Ok(())
    }

    /// The contacts of surface node `k` (at `x`, velocity `v`) with the walls, after the
    /// tunnelling check against each wall (when this step needs it).
    fn wall_contacts(
        &self,
        k: usize,
        x: [f64; 3],
        v: [f64; 3],
        scratch: &mut ChunkScratch,
        cursor: &mut Cursor<'_>,
    ) -> Result<(), ContactError> {
        let reach = self.reach.solid;
        for (w, (wall, shape)) in self.walls.iter().zip(self.wall_shapes).enumerate() {
            let Some((distance, normal)) = wall_distance(shape, x) else {
                continue;
            };
            let counterpart = Counterpart::Wall(w as u32);
            let v_rel = sub(v, wall.velocity);
            if self.check_walls {
                let d = norm(v_rel) * self.dt;
                if d > reach && distance < self.margin + d {
                    return Err(self.tunnelling(k, counterpart, d));
                }
            }
            if behind_wall(distance) {
                let depth = -distance;
                let point = add(x, scale(normal, depth));
                self.push(
                    scratch,
                    cursor,
                    k,
                    counterpart,
                    None,
                    [0.0; 3],
                    point,
                    depth,
                    normal,
                    v_rel,
                );
            }
        }
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn push(
        &self,
        scratch: &mut ChunkScratch,
        cursor: &mut Cursor<'_>,
        k: usize,
        counterpart: Counterpart,
        face: Option<(usize, [usize; 3])>,
        weights: [f64; 3],
        contact_point: [f64; 3],
        depth: f64,
        normal: [f64; 3],
        relative_velocity: [f64; 3],
    ) {
        let key = history_key(k, counterpart);
        let previous = cursor.find(key);
        let mut history = previous.map_or([0.0; 3], |c| c.tangential_displacement);
        let out = evaluate_law(
            &LawInput {
                normal,
                depth,
                relative_velocity,
                dt: self.dt,
                coefficients: self.coefficients[k],
            },
            &mut history,
        );
        // The dashpot power is evaluated at the half-step velocity v(n+1/2), but velocity
        // Verlet applies this force over the kicks from v(n+1/2) to v(n+3/2): its true
        // work is `F . (v(n+1/2) + v(n+3/2)) / 2 dt`. The previous force's missing share,
        // `-F_nc(n) . (v(n+3/2) - v(n+1/2)) / 2`, is booked now that v(n+3/2) is known
        // (the dashpots of light nodes have `c dt / m` of order 0.1-1, where the
        // difference is tens of percent of the dissipation). `F_nc` is the non-elastic
        // part of the force: the normal dashpot and the tangential force beyond the spring.
        let damping_force = add(
            scale(
                normal,
                out.normal_magnitude - self.coefficients[k].normal_stiffness * depth,
            ),
            add(
                out.tangential_force,
                scale(history, self.coefficients[k].tangential_stiffness),
            ),
        );
        let correction = previous.map_or(0.0, |c| {
            -0.5 * crate::vec3::dot(c.damping_force, sub(relative_velocity, c.relative_velocity))
        });
        let sums = &mut scratch.sums;
        sums.stored += out.stored_energy;
        sums.normal_damping += out.normal_damping_power + correction;
        sums.tangential_damping += out.tangential_damping_power;
        sums.friction += out.friction_dissipation;
        sums.max_depth = sums.max_depth.max(depth);
        sums.sliding += usize::from(out.sliding);
        let node = self.surface.surface_nodes[k];
        let corners = match (face, counterpart) {
            (Some((_, nodes)), _) => nodes.map(|j| j as u32),
            (None, Counterpart::Wall(w)) => {
                sums.wall_contacts += 1;
                [NO_FACE, w, 0]
            }
            (None, Counterpart::Body(_)) => [NO_FACE; 3],
        };
        scratch.terms.push(SpreadTerm {
            force: add(out.normal_force, out.tangential_force),
            weights,
            node: node as u32,
            corners,
        });
        scratch.contacts.push(NodeContact {
            key,
            node,
            body: self.surface.node_body[k],
            counterpart,
            face: face.map(|(t, _)| t),
            weights,
            position: self.positions[node],
            contact_point,
            depth,
            normal_force: out.normal_force,
            tangential_force: out.tangential_force,
            tangential_displacement: history,
            sliding: out.sliding,
            damping_force,
            relative_velocity,
            edge: false,
        });
    }
}
