//! Rigid bodies' faces met in their template's frame, for the narrow phase's plane filter.
//!
//! A rigid body's faces keep their shape: each is a face of a template (the body's mesh
//! before it was placed) carried by `x = origin + A t`, `A` a rotation times a uniform
//! scale `s`. The narrow phase's pre-filter, the signed distance of a node to each
//! candidate face's plane, then needs no world plane for such a face: the node's template
//! coordinates are `u = A^-1 (x - origin)` (one transform per node and body) and its
//! signed distance is `s (n . u - d)` with the template face's plane `(n, d)`. Every
//! instance of a template shares those planes (a few kilobytes that stay in cache),
//! where a world plane is computed from the face's corners, gathered with a cache miss
//! per candidate.
//!
//! The same frame screens the foot of the perpendicular: the barycentric coordinates of
//! the foot are affine functions of the node's position, unchanged by a rotation, a
//! uniform scale and a shift, so the template face gives them as `w_b = g_b . (u - a)`,
//! `w_c = g_c . (u - a)`, `w_a = 1 - w_b - w_c` with gradients `g_b`, `g_c` computed once per
//! template face. A candidate whose foot lies outside the face by more than
//! [`FOOT_BAND`] (in those coordinates) cannot pass the exact projection, whose tolerance
//! is `BARYCENTRIC_TOLERANCE`, far inside that band; the narrow phase then skips its
//! world positions altogether (on a convex particle most candidates lie behind their
//! face's plane, so the plane alone passes most of them on to the projection).
//!
//! The frames also stand in for a rigid body's nodes in the per-step scan (`crate::scan`):
//! its caller bounds how fast its nodes move and says whether they are finite
//! ([`RigidMotion`], from the body's state), and its drift since its reference
//! is bounded from its pose: with the reference positions `c + G t` (the pose when the
//! body's pairs were found, mapped back by the mean motion as the node references are) and
//! the mean motion's map `y -> O + M (y - O)`, node `t` has drifted `delta + B t` with
//! `delta = origin - O - M (c - O)` and `B = A - M G`, at most `|delta| + |B|_F r` (`r` the
//! template's largest node distance). Where that bound, plus the mismatch, is clearly below
//! a threshold the nodes are clearly below it too; elsewhere the scan reads the nodes as
//! before, so its decisions are the same.
//!
//! The filters' decisions do not change: the two distances differ by round-off (of the
//! order of 1e-16 of the coordinates), and the filter keeps every face within its slack
//! of its reach (`PLANE_SLACK` of the depth limit, orders of magnitude above that), after
//! which exact tests on the world positions decide every contact. So contacts and forces
//! are the same bit for bit. The maps' agreement with the node positions is measured when
//! they are set ([`RigidFrames::new`]), and the frames stand aside (the world planes
//! serve) in an evaluation whose poses are not of its time or whose slacks are not far
//! above that disagreement (in metres for the planes, in barycentric units, through the
//! largest gradient of a template's weights, for the feet).

use crate::broad::{CHUNK, FaceCones};
use crate::mean_motion::{Expected, IDENTITY, Matrix};
use crate::model::unit_plane;
use crate::narrow::BARYCENTRIC_TOLERANCE;
use crate::vec3::{add, cross, dot, norm, norm2, scale, sub};
use crate::{ContactError, ContactSurface};
use fdem_core::geometry::rigid_velocity;

/// The surface of a rigid body's template: its nodes in template coordinates, and its
/// faces as triples of those nodes, outward (counter-clockwise seen from outside), in the
/// order the body's faces have in the contact surface.
#[derive(Clone, Debug, PartialEq)]
pub struct RigidTemplate {
    /// Node coordinates (template units).
    pub nodes: Vec<[f64; 3]>,
    /// Faces, by index into `nodes`.
    pub triangles: Vec<[usize; 3]>,
}

/// Where a rigid body is: world positions `x = origin + A t` of its template coordinates
/// `t`, with `A` a rotation times the scale `scale`; given by its inverse.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidPose {
    /// `A^-1`, row by row: world offsets from `origin` to template coordinates.
    pub to_template: [[f64; 3]; 3],
    /// The world position of the template's origin (m).
    pub origin: [f64; 3],
    /// The uniform scale of `A` (metres per template unit).
    pub scale: f64,
}

impl RigidPose {
    /// Whether `to_template` times `scale` is a rotation (orthonormal rows to 1e-9, right
    /// handed) and `scale` finite and positive: then a distance in template units times
    /// the scale is the world distance.
    pub fn is_scaled_rotation(&self) -> bool {
        let s = self.scale;
        if !(s.is_finite() && s > 0.0) {
            return false;
        }
        let r = self.to_template.map(|row| row.map(|v| v * s));
        let orthonormal = (0..3).all(|i| {
            (0..3).all(|j| {
                let want = if i == j { 1.0 } else { 0.0 };
                (dot(r[i], r[j]) - want).abs() <= 1e-9
            })
        });
        orthonormal && dot(cross(r[0], r[1]), r[2]) > 0.0
    }

    /// Whether every number of the pose is finite.
    pub fn is_finite(&self) -> bool {
        let rows = self.to_template.iter().flatten();
        rows.chain(&self.origin).all(|v| v.is_finite()) && self.scale.is_finite()
    }

    /// Template coordinates of the world point `x`.
    #[inline(always)]
    pub fn template_point(&self, x: [f64; 3]) -> [f64; 3] {
        let d = sub(x, self.origin);
        self.to_template.map(|row| dot(row, d))
    }
}

/// A rigid body's motion as its caller knows it at an evaluation: a bound of its nodes'
/// speeds, and whether every node position and velocity is finite. With these the contact
/// model's per-step scan need not read the body's nodes
/// ([`crate::ContactModel::set_rigid_motions`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidMotion {
    /// At least the speed of every node of the body as placed (m/s), for example
    /// `|V| + |omega| max |r|` with room for the round-off of placing them.
    pub speed_bound: f64,
    /// Whether every node position and velocity of the body is finite.
    pub finite: bool,
    /// The velocity of `centre` (m/s), the body's spin (rad/s) and the centre (m): every
    /// node's velocity is `fdem_core::geometry::rigid_velocity` of these and its position,
    /// bit for bit (the narrow phase computes a face's velocity from them instead of
    /// gathering its corners').
    pub velocity: [f64; 3],
    /// The body's angular velocity (rad/s).
    pub angular_velocity: [f64; 3],
    /// The point of the body that moves at `velocity` (m).
    pub centre: [f64; 3],
}

/// The node velocities an evaluation reads: the caller's array, except for the nodes of a
/// framed body whose motion of the evaluation's time the caller gave
/// ([`crate::ContactModel::set_rigid_motions`]). Those move with their body, at
/// `fdem_core::geometry::rigid_velocity` of the motion and their position: the bits a
/// caller that places them from the same motion writes, read without the array (so a
/// caller may leave those entries as they were).
#[derive(Clone, Copy)]
pub(crate) struct NodeVelocities<'a> {
    array: &'a [[f64; 3]],
    moving: Option<(&'a RigidFrames, &'a [RigidMotion])>,
}

impl<'a> NodeVelocities<'a> {
    /// The velocities at `time`: `array`, and the motions `frames` holds if they are of
    /// that time (whether or not the frames serve the evaluation's planes).
    pub(crate) fn new(
        array: &'a [[f64; 3]],
        frames: Option<&'a RigidFrames>,
        time: f64,
    ) -> NodeVelocities<'a> {
        let moving = frames.and_then(|f| Some((f, f.motions_at(time)?)));
        NodeVelocities { array, moving }
    }

    /// The motion body `body` moves with, if it is framed and its motion was given.
    #[inline(always)]
    fn motion(&self, body: u32) -> Option<&'a RigidMotion> {
        self.moving.and_then(|(f, m)| f.motion_of(body, m))
    }

    /// Asks the memory system for the velocities [`NodeVelocities::of`] will read for the
    /// global nodes `nodes` of body `body`: the array's entries, unless the body's motion
    /// gives them (then nothing is asked). A hint changes no value.
    #[inline(always)]
    pub(crate) fn prefetch(&self, body: u32, nodes: impl IntoIterator<Item = usize>) {
        if self.motion(body).is_none() {
            for node in nodes {
                crate::prefetch::prefetch(self.array, node);
            }
        }
    }

    /// The velocity of global node `node`, of body `body`, at its position `x`.
    #[inline(always)]
    pub(crate) fn of(&self, body: u32, node: usize, x: [f64; 3]) -> [f64; 3] {
        match self.motion(body) {
            Some(m) => rigid_velocity(m.velocity, m.angular_velocity, m.centre, x),
            None => self.array[node],
        }
    }

    /// The velocity of surface node `k` of `surface`, at its position `x`.
    #[inline(always)]
    pub(crate) fn of_surface_node(
        &self,
        surface: &ContactSurface,
        k: usize,
        x: [f64; 3],
    ) -> [f64; 3] {
        let node = surface.surface_nodes[k];
        match self.moving {
            None => self.array[node],
            Some(_) => self.of(surface.node_body[k], node, x),
        }
    }
}

/// Where a framed body's nodes had their reference positions: `c + G t` for template
/// coordinates `t`.
#[derive(Clone, Copy, Debug)]
struct ReferenceMap {
    c: [f64; 3],
    g: Matrix,
}

/// A framed body's surface nodes when they are consecutive in the surface and in node
/// ids, each a corner of one of its faces: surface indices `start..start + len`, global ids
/// from `first`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct NodeRun {
    pub(crate) start: usize,
    pub(crate) len: usize,
    pub(crate) first: usize,
}

/// A rigid body as the frames know it.
#[derive(Clone, Copy, Debug)]
struct FrameBody {
    template: u32,
    /// Its first face in the contact surface (its faces are consecutive there).
    first_triangle: u32,
}

/// Body ids without a frame.
const NO_FRAME: u32 = u32::MAX;

/// The rigid bodies' templates, their faces' planes in template coordinates, and the
/// bodies' poses of one time.
#[derive(Clone, Debug)]
pub(crate) struct RigidFrames {
    /// Per template, its faces' planes `[n, n . a]` (unit normal, template coordinates).
    planes: Vec<Vec<[f64; 4]>>,
    /// Per template, its faces' barycentric maps.
    feet: Vec<Vec<FootMap>>,
    /// Per template, the largest distance of its nodes from its origin (template units).
    radius: Vec<f64>,
    /// Per template, its faces as cones of directions from its origin (the full build's
    /// screen, `crate::broad`).
    cones: Vec<FaceCones>,
    /// Per framed body (in the order of `bodies`), its surface nodes when the scan may
    /// stand in for them (`NodeRun`).
    node_runs: Vec<Option<NodeRun>>,
    /// The surface nodes the scan reads one by one whenever the frames serve: those of
    /// bodies without a `NodeRun`, in increasing runs of at most `CHUNK`.
    scanned_nodes: Vec<std::ops::Range<usize>>,
    /// The caller's motions of the framed bodies, and their time.
    motions: Vec<RigidMotion>,
    motions_time: Option<f64>,
    /// Per framed body, the map of its nodes' reference positions (`None`: unknown, the
    /// scan reads the nodes).
    references: Vec<Option<ReferenceMap>>,
    /// Per body id, its index in `bodies` (`NO_FRAME`: not a rigid body with a frame).
    slot: Vec<u32>,
    /// The faces of bodies without a frame, in increasing runs of at most `CHUNK`.
    unframed: Vec<std::ops::Range<usize>>,
    bodies: Vec<FrameBody>,
    poses: Vec<RigidPose>,
    /// The time of `poses` (`None` before the first [`RigidFrames::set_poses`]).
    time: Option<f64>,
    /// The largest distance between a face corner's world position and where its pose
    /// puts the template's node, when the frames were set (m).
    mismatch: f64,
    /// That disagreement's largest effect on a foot's barycentric coordinates: per body,
    /// its mismatch times its template's largest weight gradient over its scale.
    foot_mismatch: f64,
}

/// A template face's barycentric coordinates as affine maps of template coordinates:
/// `w_b = g_b . (u - a)`, `w_c = g_c . (u - a)`, `w_a = 1 - w_b - w_c`.
#[derive(Clone, Copy, Debug)]
struct FootMap {
    a: [f64; 3],
    g_b: [f64; 3],
    g_c: [f64; 3],
}

impl FootMap {
    /// The map of the face `[a, b, c]` (`None` for a degenerate face): with the face's
    /// normal `N = (b - a) x (c - a)`, `g_b = ((c - a) x N) / |N|^2` and
    /// `g_c = (N x (b - a)) / |N|^2` (the triple products of `narrow::project_hand`).
    fn of([a, b, c]: [[f64; 3]; 3]) -> Option<FootMap> {
        let (e1, e2) = (sub(b, a), sub(c, a));
        let n = cross(e1, e2);
        let nn = norm2(n);
        (nn > 0.0 && nn.is_finite()).then(|| FootMap {
            a,
            g_b: scale(cross(e2, n), 1.0 / nn),
            g_c: scale(cross(n, e1), 1.0 / nn),
        })
    }

    /// The largest change of a weight per unit move of the node (template units^-1).
    fn gradient(&self) -> f64 {
        let g_a = scale(add(self.g_b, self.g_c), -1.0);
        norm(g_a).max(norm(self.g_b)).max(norm(self.g_c))
    }

    /// Whether the foot of `u` lies outside the face by more than `FOOT_BAND` beyond the
    /// projection's tolerance in some barycentric coordinate.
    #[inline(always)]
    fn clearly_outside(&self, u: [f64; 3]) -> bool {
        let p = sub(u, self.a);
        let (w_b, w_c) = (dot(self.g_b, p), dot(self.g_c, p));
        let limit = -BARYCENTRIC_TOLERANCE - FOOT_BAND;
        w_b < limit || w_c < limit || 1.0 - w_b - w_c < limit
    }
}

impl RigidFrames {
    /// The frames of `bodies` (each a body id and its template's index in `templates`) at
    /// `poses` (one per body, of the positions `positions` at `time`): each body's faces
    /// must be as many as its template's and consecutive in `surface`, and each face
    /// corner where its pose puts the template's node (the largest distance is kept as the
    /// frames' mismatch).
    pub(crate) fn new(
        surface: &ContactSurface,
        positions: &[[f64; 3]],
        templates: &[RigidTemplate],
        bodies: &[(u32, usize)],
        (time, poses): (f64, &[RigidPose]),
    ) -> Result<RigidFrames, ContactError> {
        let invalid = |what: String| ContactError::InconsistentSurface {
            what,
            fix: "give each rigid body its own template's faces in their order, and its pose",
        };
        if poses.len() != bodies.len() {
            return Err(invalid(format!(
                "{} rigid poses for {} rigid bodies",
                poses.len(),
                bodies.len()
            )));
        }
        for (k, t) in templates.iter().enumerate() {
            let bad_node = t.nodes.iter().flatten().any(|v| !v.is_finite());
            let bad_index = t.triangles.iter().flatten().any(|&i| i >= t.nodes.len());
            if bad_node || bad_index {
                return Err(invalid(format!(
                    "rigid template {k} has a node that is not finite or a face naming a node \
                     it does not have ({} nodes)",
                    t.nodes.len()
                )));
            }
        }
        let planes: Vec<Vec<[f64; 4]>> = templates
            .iter()
            .map(|t| {
                t.triangles
                    .iter()
                    .map(|tri| unit_plane(tri.map(|i| t.nodes[i])))
                    .collect()
            })
            .collect();
        let feet = templates
            .iter()
            .enumerate()
            .map(|(k, t)| {
                t.triangles
                    .iter()
                    .map(|tri| FootMap::of(tri.map(|i| t.nodes[i])))
                    .collect::<Option<Vec<FootMap>>>()
                    .ok_or_else(|| invalid(format!("rigid template {k} has a degenerate face")))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let gradient: Vec<f64> = feet
            .iter()
            .map(|f| f.iter().map(FootMap::gradient).fold(0.0, f64::max))
            .collect();
        let ranges = face_ranges(surface);
        let mut slot = vec![NO_FRAME; ranges.len()];
        let mut frame_bodies = Vec::with_capacity(bodies.len());
        let (mut mismatch, mut foot_mismatch, mut finite): (f64, f64, bool) = (0.0, 0.0, true);
        for (k, (&(body, template), pose)) in bodies.iter().zip(poses).enumerate() {
            let tpl = templates.get(template).ok_or_else(|| {
                invalid(format!(
                    "rigid body {body} names template {template} of {}",
                    templates.len()
                ))
            })?;
            let faces = ranges.get(body as usize).cloned().flatten().unwrap_or(0..0);
            if faces.len() != tpl.triangles.len() || slot.get(body as usize) != Some(&NO_FRAME) {
                return Err(invalid(format!(
                    "rigid body {body} has {} consecutive faces against its template's {}, or is given twice",
                    faces.len(),
                    tpl.triangles.len()
                )));
            }
            let mut body_mismatch: f64 = 0.0;
            for (t, local) in faces.clone().zip(&tpl.triangles) {
                for (&g, &i) in surface.triangles[t].iter().zip(local) {
                    let u = pose.template_point(positions[g]);
                    let d = pose.scale * norm(sub(u, tpl.nodes[i]));
                    finite &= d.is_finite();
                    body_mismatch = body_mismatch.max(d);
                }
            }
            mismatch = mismatch.max(body_mismatch);
            // A node and the face's corners each off by the mismatch move a weight by at
            // most the gradient times each offset (in template units: divided by the scale).
            foot_mismatch =
                foot_mismatch.max(4.0 * body_mismatch * gradient[template] / pose.scale);
            slot[body as usize] = k as u32;
            frame_bodies.push(FrameBody {
                template: template as u32,
                first_triangle: faces.start as u32,
            });
        }
        if !finite || !poses.iter().all(RigidPose::is_scaled_rotation) {
            return Err(invalid(
                "a rigid pose is not finite, or not a rotation divided by its positive scale"
                    .into(),
            ));
        }
        let unframed = unframed_faces(surface, &slot);
        let node_ranges = consecutive_ranges(&surface.node_body, surface.n_bodies());
        let node_runs: Vec<Option<NodeRun>> = bodies
            .iter()
            .zip(&frame_bodies)
            .map(|(&(body, template), b)| {
                let nodes = node_ranges.get(body as usize).cloned().flatten();
                node_run(
                    surface,
                    nodes,
                    &templates[template],
                    b.first_triangle as usize,
                )
            })
            .collect();
        let scanned_nodes = scanned_nodes(surface, &slot, &node_runs);
        let radius = templates
            .iter()
            .map(|t| t.nodes.iter().map(|&n| norm(n)).fold(0.0, f64::max))
            .collect();
        let cones = templates
            .iter()
            .map(|t| FaceCones::of(&t.nodes, &t.triangles))
            .collect();
        Ok(RigidFrames {
            planes,
            feet,
            radius,
            cones,
            references: vec![None; node_runs.len()],
            node_runs,
            scanned_nodes,
            motions: Vec::new(),
            motions_time: None,
            slot,
            unframed,
            bodies: frame_bodies,
            poses: poses.to_vec(),
            time: Some(time),
            mismatch,
            foot_mismatch,
        })
    }

    /// The poses at `time`, one per rigid body in the order the frames were given (copied
    /// into the frames' own vector).
    pub(crate) fn set_poses(&mut self, time: f64, poses: &[RigidPose]) -> Result<(), ContactError> {
        self.check_poses(poses)?;
        self.poses.copy_from_slice(poses);
        self.time = Some(time);
        Ok(())
    }

    /// [`RigidFrames::set_poses`] taken from `poses`, which receives the previous ones.
    pub(crate) fn exchange_poses(
        &mut self,
        time: f64,
        poses: &mut Vec<RigidPose>,
    ) -> Result<(), ContactError> {
        self.check_poses(poses)?;
        std::mem::swap(&mut self.poses, poses);
        self.time = Some(time);
        Ok(())
    }

    /// Refuses poses of another count than one per framed body. A finite pose must be a
    /// scaled rotation; a pose that is not finite (a body whose state overflowed) is taken
    /// as it is: the scan finds its nodes not finite and the evaluation ends in that error.
    fn check_poses(&self, poses: &[RigidPose]) -> Result<(), ContactError> {
        self.one_per_body("rigid poses", poses.len())?;
        debug_assert!(
            poses
                .iter()
                .all(|p| !p.is_finite() || p.is_scaled_rotation())
        );
        Ok(())
    }

    /// Refuses `found` entries of `array` for another number than one per framed body.
    fn one_per_body(&self, array: &'static str, found: usize) -> Result<(), ContactError> {
        if found == self.bodies.len() {
            return Ok(());
        }
        Err(ContactError::LengthMismatch {
            array,
            expected: self.bodies.len(),
            found,
            reason: "one entry per rigid body given to set_rigid_frames",
        })
    }

    /// Whether the frames may stand in for the world planes and screen the feet in an
    /// evaluation at `time` whose plane filter has slack `slack` (m): poses of that time,
    /// and a mismatch far below both slacks.
    pub(crate) fn usable(&self, time: f64, slack: f64) -> bool {
        self.time == Some(time)
            && self.mismatch <= MISMATCH_FRACTION * slack
            && self.foot_mismatch.is_finite()
            && self.foot_mismatch <= MISMATCH_FRACTION * FOOT_BAND
    }

    /// The faces of the bodies without a frame: increasing, disjoint runs of consecutive
    /// faces, each of at most `CHUNK` faces.
    pub(crate) fn unframed_faces(&self) -> &[std::ops::Range<usize>] {
        &self.unframed
    }

    /// Body `body`'s place in the frames' order, if it has a frame.
    pub(crate) fn slot_of(&self, body: u32) -> Option<usize> {
        let slot = *self.slot.get(body as usize)?;
        (slot != NO_FRAME).then_some(slot as usize)
    }

    /// Whether `body` has a frame.
    #[inline(always)]
    pub(crate) fn has(&self, body: u32) -> bool {
        self.slot.get(body as usize).is_some_and(|&s| s != NO_FRAME)
    }

    /// The framed bodies' motions at `time`, one per body in the order the frames were
    /// given (copied into the frames' own vector).
    pub(crate) fn set_motions(
        &mut self,
        time: f64,
        motions: &[RigidMotion],
    ) -> Result<(), ContactError> {
        self.one_per_body("rigid motions", motions.len())?;
        self.motions.clear();
        self.motions.extend_from_slice(motions);
        self.motions_time = Some(time);
        Ok(())
    }

    /// [`RigidFrames::set_motions`] taken from `motions`, which receives the previous ones.
    pub(crate) fn exchange_motions(
        &mut self,
        time: f64,
        motions: &mut Vec<RigidMotion>,
    ) -> Result<(), ContactError> {
        self.one_per_body("rigid motions", motions.len())?;
        std::mem::swap(&mut self.motions, motions);
        self.motions_time = Some(time);
        Ok(())
    }

    /// Body `body`'s motion among `motions` (of this evaluation), if it has a frame.
    #[inline(always)]
    pub(crate) fn motion_of<'m>(
        &self,
        body: u32,
        motions: &'m [RigidMotion],
    ) -> Option<&'m RigidMotion> {
        let k = *self.slot.get(body as usize)?;
        motions.get(k as usize)
    }

    /// The caller's motions if they are of `time`.
    pub(crate) fn motions_at(&self, time: f64) -> Option<&[RigidMotion]> {
        (self.motions_time == Some(time)).then_some(self.motions.as_slice())
    }

    /// Each framed body's id and its index in the frames' order.
    pub(crate) fn framed_bodies(&self) -> impl Iterator<Item = (u32, usize)> + '_ {
        self.slot
            .iter()
            .enumerate()
            .filter(|(_, s)| **s != NO_FRAME)
            .map(|(body, &s)| (body as u32, s as usize))
    }

    /// Per framed body, its node run when the scan may stand in for its nodes.
    pub(crate) fn node_runs(&self) -> &[Option<NodeRun>] {
        &self.node_runs
    }

    /// The surface nodes the scan reads one by one while the frames serve.
    pub(crate) fn scanned_nodes(&self) -> &[std::ops::Range<usize>] {
        &self.scanned_nodes
    }

    /// Framed body `k`'s pose (`k` in the frames' order).
    pub(crate) fn pose(&self, k: usize) -> &RigidPose {
        &self.poses[k]
    }

    /// A ball that holds every node of framed body `k` that is a face corner where the
    /// pose of this time puts it: the pose's origin and the template's radius times the
    /// scale, grown by the frames' mismatch (m).
    pub(crate) fn ball(&self, k: usize) -> ([f64; 3], f64) {
        let pose = &self.poses[k];
        let template = self.bodies[k].template as usize;
        (
            pose.origin,
            self.radius[template] * pose.scale + self.mismatch,
        )
    }

    /// [`RigidFrames::ball`] of framed body `k` when its surface nodes are a run of its
    /// faces' corners ([`RigidFrames::node_runs`]), so that the ball holds all of them;
    /// `None` otherwise.
    pub(crate) fn nodes_ball(&self, k: usize) -> Option<([f64; 3], f64)> {
        self.node_runs.get(k)?.as_ref()?;
        Some(self.ball(k))
    }

    /// Framed body `k`'s template.
    pub(crate) fn template_of(&self, k: usize) -> u32 {
        self.bodies[k].template
    }

    /// Framed body `k`'s first face in the contact surface (its faces are consecutive).
    pub(crate) fn first_triangle(&self, k: usize) -> u32 {
        self.bodies[k].first_triangle
    }

    /// Template `template`'s faces as cones of directions from its origin.
    pub(crate) fn cones(&self, template: u32) -> &FaceCones {
        &self.cones[template as usize]
    }

    /// The frames' mismatch (m): how far a node may lie from where its pose puts it.
    pub(crate) fn mismatch(&self) -> f64 {
        self.mismatch
    }

    /// Takes every framed body's current pose as its reference (a full build, which resets
    /// the mean motion's map), or forgets them all when the poses are not the positions'
    /// (`current` false).
    pub(crate) fn reset_references(&mut self, current: bool) {
        for k in 0..self.references.len() {
            self.references[k] = current.then(|| self.reference_of(k, None));
        }
    }

    /// Takes the current pose of each framed body marked in `dirty` (per body id) as its
    /// reference, mapped back by the mean motion `expected` as a refresh maps the node
    /// references; forgets them when the poses are not the positions' (`current` false).
    pub(crate) fn refresh_references(
        &mut self,
        dirty: &[bool],
        expected: Option<&Expected>,
        current: bool,
    ) {
        for (body, _) in dirty.iter().enumerate().filter(|(_, d)| **d) {
            if let Some(&k) = self.slot.get(body).filter(|&&k| k != NO_FRAME) {
                let k = k as usize;
                self.references[k] = current.then(|| self.reference_of(k, expected));
            }
        }
    }

    /// Framed body `k`'s current pose as a reference map, mapped back by `expected`.
    fn reference_of(&self, k: usize, expected: Option<&Expected>) -> ReferenceMap {
        let (origin, a) = placement(&self.poses[k]);
        match expected {
            None => ReferenceMap { c: origin, g: a },
            Some(e) => {
                let (o, _, inverse) = e.parts();
                let c = add(o, apply(inverse, sub(origin, o)));
                ReferenceMap {
                    c,
                    g: product(inverse, &a),
                }
            }
        }
    }

    /// A bound of how far any node of framed body `k` lies from where the mean motion
    /// `expected` has taken its reference (m), from the poses alone, mismatch excluded;
    /// `None` without a reference.
    pub(crate) fn drift_bound(&self, k: usize, expected: Option<&Expected>) -> Option<f64> {
        let reference = self.references[k].as_ref()?;
        let (origin, a) = placement(&self.poses[k]);
        let (o, m) = match expected {
            Some(e) => {
                let (o, m, _) = e.parts();
                (o, *m)
            }
            None => ([0.0; 3], IDENTITY),
        };
        // delta = origin - O - M (c - O), B = A - M G.
        let delta = sub(sub(origin, o), apply(&m, sub(reference.c, o)));
        let mg = product(&m, &reference.g);
        let b: f64 = (0..3)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| (a[i][j] - mg[i][j]).powi(2))
            .sum::<f64>()
            .sqrt();
        let template = self.bodies[k].template as usize;
        Some(norm(delta) + b * self.radius[template])
    }

    /// The node at `x` as seen from `body`'s template, if the body has a frame.
    #[inline(always)]
    pub(crate) fn view(&self, body: u32, x: [f64; 3]) -> Option<TemplateView<'_>> {
        let k = *self.slot.get(body as usize)?;
        let b = self.bodies.get(k as usize)?;
        let pose = &self.poses[k as usize];
        Some(TemplateView {
            u: pose.template_point(x),
            scale: pose.scale,
            planes: &self.planes[b.template as usize],
            feet: &self.feet[b.template as usize],
            first_triangle: b.first_triangle,
        })
    }
}

/// The frames stand aside unless their mismatch is below this fraction of the plane
/// filter's slack.
const MISMATCH_FRACTION: f64 = 1e-3;

/// How far outside a face (in barycentric coordinates, beyond the projection's own
/// tolerance) a foot must lie for the template's screen to skip the face: orders of
/// magnitude above the round-off of either computation (about 1e-16 times the
/// coordinates over the face's size), yet thin enough to pass on only the candidates
/// whose foot is near the face. (The parry kernel, a benchmark alternative whose band
/// depends on the face's shape, is not screened.)
pub(crate) const FOOT_BAND: f64 = 1e-4;

/// A node in the template coordinates of one rigid body.
pub(crate) struct TemplateView<'a> {
    u: [f64; 3],
    scale: f64,
    planes: &'a [[f64; 4]],
    feet: &'a [FootMap],
    first_triangle: u32,
}

impl TemplateView<'_> {
    /// The node's signed distance to the plane of the body's face `triangle` (the
    /// contact surface's index; m, positive in front).
    #[inline(always)]
    pub(crate) fn signed_distance(&self, triangle: u32) -> f64 {
        let [nx, ny, nz, d] = self.planes[(triangle - self.first_triangle) as usize];
        self.scale * (nx * self.u[0] + ny * self.u[1] + nz * self.u[2] - d)
    }

    /// Whether the foot of the node's perpendicular on face `triangle` (the contact
    /// surface's index) lies outside it by more than [`FOOT_BAND`] beyond the projection's
    /// tolerance: then no exact test on the world positions can accept the face.
    #[inline(always)]
    pub(crate) fn foot_clearly_outside(&self, triangle: u32) -> bool {
        self.feet[(triangle - self.first_triangle) as usize].clearly_outside(self.u)
    }
}

/// A pose's placement `x = origin + A t`: `A = s^2 (A^-1)^T` for a rotation times `s`.
fn placement(pose: &RigidPose) -> ([f64; 3], Matrix) {
    let s2 = pose.scale * pose.scale;
    let a = std::array::from_fn(|i| std::array::from_fn(|j| s2 * pose.to_template[j][i]));
    (pose.origin, a)
}

/// `m v`.
fn apply(m: &Matrix, v: [f64; 3]) -> [f64; 3] {
    m.map(|row| dot(row, v))
}

/// `m n`.
fn product(m: &Matrix, n: &Matrix) -> Matrix {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| m[i][k] * n[k][j]).sum()))
}

/// The node run of `body` (its template `template`, its first face `first_triangle`): its
/// surface nodes consecutive, their global ids consecutive, each a corner of one of its
/// faces; `None` otherwise.
fn node_run(
    surface: &ContactSurface,
    nodes: Option<std::ops::Range<usize>>,
    template: &RigidTemplate,
    first_triangle: usize,
) -> Option<NodeRun> {
    let nodes = nodes.filter(|r| !r.is_empty())?;
    let (start, len) = (nodes.start, nodes.len());
    let first = surface.surface_nodes[start];
    if !(0..len).all(|i| surface.surface_nodes[start + i] == first + i) {
        return None;
    }
    let mut corner = vec![false; len];
    let faces = first_triangle..first_triangle + template.triangles.len();
    for &g in surface.triangles[faces].iter().flatten() {
        if let Some(c) = g.checked_sub(first).and_then(|i| corner.get_mut(i)) {
            *c = true;
        }
    }
    corner
        .iter()
        .all(|&c| c)
        .then_some(NodeRun { start, len, first })
}

/// The surface nodes not in a node run, as increasing runs of at most `CHUNK`.
fn scanned_nodes(
    surface: &ContactSurface,
    slot: &[u32],
    node_runs: &[Option<NodeRun>],
) -> Vec<std::ops::Range<usize>> {
    let in_run = |k: usize| {
        let body = surface.node_body[k] as usize;
        slot.get(body)
            .filter(|&&s| s != NO_FRAME)
            .is_some_and(|&s| node_runs[s as usize].is_some())
    };
    chunked_runs((0..surface.surface_nodes.len()).filter(|&k| !in_run(k)))
}

/// Increasing `indices` as runs of consecutive indices, each of at most `CHUNK`.
fn chunked_runs(indices: impl Iterator<Item = usize>) -> Vec<std::ops::Range<usize>> {
    let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
    for i in indices {
        match runs.last_mut() {
            Some(r) if r.end == i && r.len() < CHUNK => r.end = i + 1,
            _ => runs.push(i..i + 1),
        }
    }
    runs
}

/// The faces of `surface` whose body has no frame in `slot`, as increasing runs of at most
/// `CHUNK` consecutive faces.
fn unframed_faces(surface: &ContactSurface, slot: &[u32]) -> Vec<std::ops::Range<usize>> {
    let framed = |t: usize| {
        slot.get(surface.triangle_body[t] as usize)
            .is_some_and(|&s| s != NO_FRAME)
    };
    chunked_runs((0..surface.triangles.len()).filter(|&t| !framed(t)))
}

/// Per body id, the range of its faces in `surface` when they are consecutive (`None`
/// when they are not; an empty range when it has none).
fn face_ranges(surface: &ContactSurface) -> Vec<Option<std::ops::Range<usize>>> {
    consecutive_ranges(&surface.triangle_body, surface.n_bodies())
}

/// Per body id below `n_bodies`, the range of the entries of `owners` that name it when
/// they are consecutive (`None` when they are not; an empty range when there are none).
fn consecutive_ranges(owners: &[u32], n_bodies: usize) -> Vec<Option<std::ops::Range<usize>>> {
    let mut ranges: Vec<Option<std::ops::Range<usize>>> = vec![Some(0..0); n_bodies];
    for (t, &b) in owners.iter().enumerate() {
        let r = &mut ranges[b as usize];
        *r = match r.take() {
            Some(r) if r.is_empty() => Some(t..t + 1),
            Some(r) if r.end == t => Some(r.start..t + 1),
            _ => None,
        };
    }
    ranges
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::narrow::project_hand;
    use fdem_core::geometry::rotation_matrix;
    use rand::{RngExt, SeedableRng};

    /// A placed template face: the world corners of `x = origin + A t`.
    fn place(r: [[f64; 3]; 3], s: f64, origin: [f64; 3], t: [f64; 3]) -> [f64; 3] {
        add(origin, r.map(|row| s * dot(row, t)))
    }

    /// The screen against the exact projection on world positions: a foot placed at
    /// chosen barycentric coordinates of a placed template face (a millimetre particle a
    /// tenth of a metre from the origin, turned at random) is screened out exactly when
    /// one coordinate lies beyond the band, and the projection accepts every foot inside
    /// the tolerance. A band of the wrong sign, or maps of the wrong corners, fail it.
    #[test]
    fn the_foot_screen_skips_only_faces_the_projection_refuses() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let (scale_m, depth_limit) = (1e-3, 1e-4);
        let tol = BARYCENTRIC_TOLERANCE;
        let (mut screened, mut accepted) = (0, 0);
        for _ in 0..2000 {
            let face: [[f64; 3]; 3] =
                std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-0.5..0.5)));
            let Some(map) = FootMap::of(face) else {
                continue;
            };
            let q: [f64; 4] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let r = rotation_matrix(q);
            let origin: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.1..0.1));
            let world = face.map(|t| place(r, scale_m, origin, t));
            // Weights: one coordinate just inside the tolerance, beyond the band, or inside.
            let w_b = match rng.random_range(0..3) {
                0 => -0.5 * tol,
                1 => -tol - 2.0 * FOOT_BAND,
                _ => rng.random_range(0.0..1.0),
            };
            let w_c = rng.random_range(0.0..(1.0 - w_b).min(1.0));
            let w = [1.0 - w_b - w_c, w_b, w_c];
            let foot: [f64; 3] = std::array::from_fn(|i| (0..3).map(|j| w[j] * face[j][i]).sum());
            let n = cross(sub(face[1], face[0]), sub(face[2], face[0]));
            let behind = -0.5 * depth_limit / scale_m / norm(n);
            let t = add(foot, scale(n, behind));
            let x = place(r, scale_m, origin, t);
            // The pose maps world to template coordinates as the frames do.
            let pose = RigidPose {
                to_template: std::array::from_fn(|i| std::array::from_fn(|j| r[j][i] / scale_m)),
                origin,
                scale: scale_m,
            };
            assert!(pose.is_scaled_rotation());
            let out = map.clearly_outside(pose.template_point(x));
            let hit = project_hand(x, world, depth_limit);
            let beyond = w.iter().any(|&wi| wi < -tol - FOOT_BAND);
            assert_eq!(out, beyond, "weights {w:?}: screened {out}");
            assert!(
                !out || hit.is_none(),
                "screened out a face the projection accepts"
            );
            let inside = w.iter().all(|&wi| wi >= -tol);
            assert_eq!(hit.is_some(), inside, "weights {w:?}: projection {hit:?}");
            screened += usize::from(out);
            accepted += usize::from(hit.is_some());
        }
        assert!(
            screened > 400 && accepted > 800,
            "screened {screened}, accepted {accepted}"
        );
    }

    /// A tetrahedron on the unit axes, its faces outward.
    fn unit_tetrahedron() -> RigidTemplate {
        RigidTemplate {
            nodes: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        }
    }

    /// The pose of a template shifted by `x` along the first axis, unturned, unscaled.
    fn shifted_pose(x: f64) -> RigidPose {
        RigidPose {
            to_template: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            origin: [x, 0.0, 0.0],
            scale: 1.0,
        }
    }

    /// The faces outside the frames: every face of the bodies without one, in order, in
    /// runs no longer than a chunk, and none of a framed body's.
    #[test]
    fn the_unframed_faces_are_the_other_bodies_faces_in_chunks() {
        let template = unit_tetrahedron();
        let shift = |tris: &[[usize; 3]], by: usize| -> Vec<[usize; 3]> {
            tris.iter().map(|t| t.map(|i| i + by)).collect()
        };
        // Bodies 0 and 2 framed tetrahedra; body 1 a deformable body of 1,000 faces.
        let mut surface = ContactSurface::default();
        surface
            .push_body(0, &template.triangles, &[0, 1, 2, 3], &[1.0; 4])
            .unwrap();
        let many = vec![[4, 5, 6]; 1000];
        surface.push_body(1, &many, &[4, 5, 6], &[1.0; 3]).unwrap();
        surface
            .push_body(2, &shift(&template.triangles, 7), &[7, 8, 9, 10], &[1.0; 4])
            .unwrap();
        let mut positions = template.nodes.clone();
        positions.extend([[5.0, 0.0, 0.0], [6.0, 0.0, 0.0], [5.0, 1.0, 0.0]]);
        positions.extend(template.nodes.iter().map(|p| [p[0] + 9.0, p[1], p[2]]));
        let frames = RigidFrames::new(
            &surface,
            &positions,
            std::slice::from_ref(&template),
            &[(0, 0), (2, 0)],
            (0.0, &[shifted_pose(0.0), shifted_pose(9.0)]),
        )
        .unwrap();
        assert_eq!(frames.unframed_faces(), &[4..4 + CHUNK, 4 + CHUNK..1004]);
    }

    /// A pose `x = origin + s R t` turned by the unit quaternion `q` (need not be normalised).
    fn turned_pose(q: [f64; 4], s: f64, origin: [f64; 3]) -> RigidPose {
        let r = rotation_matrix(q);
        RigidPose {
            to_template: std::array::from_fn(|i| std::array::from_fn(|j| r[j][i] / s)),
            origin,
            scale: s,
        }
    }

    /// The drift bound from the poses holds every node of the body: references taken at a
    /// refresh under one state of a mean motion (an axial squeeze), nodes moved by another
    /// pose and the motion gone on, each node's drift from where its reference is expected
    /// is within the bound; and a pure shift without mean motion is bounded by the shift.
    #[test]
    fn the_drift_bound_holds_every_node_of_the_body() {
        use crate::mean_motion::MeanMotion;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let template = unit_tetrahedron();
        let mut surface = ContactSurface::default();
        surface
            .push_body(0, &template.triangles, &[0, 1, 2, 3], &[1.0; 4])
            .unwrap();
        let rate = [[0.0; 3], [0.0; 3], [0.0, 0.0, -0.3]];
        let motion = MeanMotion::continued(None, [0.1, -0.2, 0.5], rate, 0.0);
        let mut tight = 0;
        for case in 0..500 {
            let mut q = || std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let (q0, q1) = (q(), q());
            let s = rng.random_range(1e-3..1e-2);
            let o0: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.3..0.3));
            let shift: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1e-4..1e-4));
            let turn = rng.random_range(0.0..1e-2);
            let q1 = std::array::from_fn(|i| q0[i] + turn * q1[i]);
            let (p0, p1) = (turned_pose(q0, s, o0), turned_pose(q1, s, add(o0, shift)));
            let place = |p: &RigidPose, t: [f64; 3]| {
                let a = placement(p).1;
                add(p.origin, apply(&a, t))
            };
            let x0: Vec<[f64; 3]> = template.nodes.iter().map(|&t| place(&p0, t)).collect();
            let mut frames = RigidFrames::new(
                &surface,
                &x0,
                std::slice::from_ref(&template),
                &[(0, 0)],
                (0.0, &[p0]),
            )
            .unwrap();
            let squeezed = case % 2 == 0;
            let at = |t: f64| motion.since(&IDENTITY, t).filter(|_| squeezed);
            let (e0, e1) = (at(0.01), at(0.03));
            frames.refresh_references(&[true], e0.as_ref(), true);
            frames.set_poses(1.0, &[p1]).unwrap();
            let bound = frames.drift_bound(0, e1.as_ref()).unwrap();
            let mut largest: f64 = 0.0;
            for (&t, &y0) in template.nodes.iter().zip(&x0) {
                let reference = e0.as_ref().map_or(y0, |e| e.reference(y0));
                let expected = e1.as_ref().map_or(reference, |e| e.position(reference));
                let drift = norm(sub(place(&p1, t), expected));
                assert!(
                    drift <= bound * (1.0 + 1e-9),
                    "case {case}: {drift} > {bound}"
                );
                largest = largest.max(drift);
            }
            tight += usize::from(bound <= 3.0 * largest);
        }
        assert!(
            tight > 400,
            "{tight} of 500 bounds within three times the largest drift"
        );
        // A pure shift: the bound is the shift.
        let p0 = shifted_pose(0.0);
        let mut frames = RigidFrames::new(
            &surface,
            &template.nodes,
            std::slice::from_ref(&template),
            &[(0, 0)],
            (0.0, &[p0]),
        )
        .unwrap();
        frames.reset_references(true);
        frames.set_poses(1.0, &[shifted_pose(2e-3)]).unwrap();
        assert!((frames.drift_bound(0, None).unwrap() - 2e-3).abs() < 1e-18);
        frames.reset_references(false);
        assert_eq!(frames.drift_bound(0, None), None);
    }

    /// The frames stand aside when a body's corners are off their pose by more than the
    /// feet's share of the band allows, even if the planes' slack would allow it.
    #[test]
    fn a_mismatch_beyond_the_feet_band_sets_the_frames_aside() {
        let template = unit_tetrahedron();
        let mut surface = ContactSurface::default();
        surface
            .push_body(0, &template.triangles, &[0, 1, 2, 3], &[1.0; 4])
            .unwrap();
        let pose = shifted_pose(0.0);
        let frames_with = |offset: f64| {
            let mut positions = template.nodes.clone();
            positions[3][2] += offset;
            RigidFrames::new(
                &surface,
                &positions,
                std::slice::from_ref(&template),
                &[(0, 0)],
                (0.0, &[pose]),
            )
            .unwrap()
        };
        let slack = 1.0;
        assert!(frames_with(0.0).usable(0.0, slack));
        assert!(!frames_with(1e-6).usable(0.0, slack));
    }
}
