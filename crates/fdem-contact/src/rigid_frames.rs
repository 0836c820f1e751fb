//! Rigid bodies' faces met in their template's frame, for the narrow phase's plane filter.
//!
//! A rigid body's faces keep their shape: each is a face of a template (the body's mesh
//! before it was placed) carried by `x = origin + A t`, `A` a rotation times a uniform
//! scale `s`. The narrow phase's pre-filter, the signed distance of a node to each
//! candidate face's plane, then needs no world plane for such a face: the node's template
//! coordinates are `u = A^-1 (x - origin)` (one transform per node and body) and its
//! signed distance is `s (n . u - d)` with the template face's plane `(n, d)`. Every
//! instance of a template shares those planes (a few kilobytes that stay in cache),
//! where the world planes are rewritten every step and gathered with a cache miss per
//! candidate.
//!
//! The filter's decisions do not change: the two distances differ by round-off (of the
//! order of 1e-16 of the coordinates), and the filter keeps every face within its slack
//! of its reach (`PLANE_SLACK` of the depth limit, orders of magnitude above that), after
//! which exact tests on the world positions decide every contact. So contacts and forces
//! are the same bit for bit. The maps' agreement with the node positions is measured when
//! they are set ([`RigidFrames::new`]), and the frames stand aside (the world planes
//! serve) in an evaluation whose poses are not of its time or whose slack is not far
//! above that disagreement.

use crate::model::unit_plane;
use crate::vec3::{dot, norm, sub};
use crate::{ContactError, ContactSurface};

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
        orthonormal && dot(crate::vec3::cross(r[0], r[1]), r[2]) > 0.0
    }

    /// Template coordinates of the world point `x`.
    #[inline(always)]
    pub fn template_point(&self, x: [f64; 3]) -> [f64; 3] {
        let d = sub(x, self.origin);
        self.to_template.map(|row| dot(row, d))
    }
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
    /// Per body id, its index in `bodies` (`NO_FRAME`: not a rigid body with a frame).
    slot: Vec<u32>,
    bodies: Vec<FrameBody>,
    poses: Vec<RigidPose>,
    /// The time of `poses` (`None` before the first [`RigidFrames::set_poses`]).
    time: Option<f64>,
    /// The largest distance between a face corner's world position and where its pose
    /// puts the template's node, when the frames were set (m).
    mismatch: f64,
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
        let ranges = face_ranges(surface);
        let mut slot = vec![NO_FRAME; ranges.len()];
        let mut frame_bodies = Vec::with_capacity(bodies.len());
        let (mut mismatch, mut finite): (f64, bool) = (0.0, true);
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
            for (t, local) in faces.clone().zip(&tpl.triangles) {
                for (&g, &i) in surface.triangles[t].iter().zip(local) {
                    let u = pose.template_point(positions[g]);
                    let d = pose.scale * norm(sub(u, tpl.nodes[i]));
                    finite &= d.is_finite();
                    mismatch = mismatch.max(d);
                }
            }
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
        Ok(RigidFrames {
            planes,
            slot,
            bodies: frame_bodies,
            poses: poses.to_vec(),
            time: Some(time),
            mismatch,
        })
    }

    /// The poses at `time`, one per rigid body in the order the frames were given.
    pub(crate) fn set_poses(&mut self, time: f64, poses: &[RigidPose]) -> Result<(), ContactError> {
        if poses.len() != self.poses.len() {
            return Err(ContactError::LengthMismatch {
                array: "rigid poses",
                expected: self.poses.len(),
                found: poses.len(),
                reason: "one pose per rigid body given to set_rigid_frames",
            });
        }
        debug_assert!(poses.iter().all(RigidPose::is_scaled_rotation));
        self.poses.copy_from_slice(poses);
        self.time = Some(time);
        Ok(())
    }

    /// Whether the frames may stand in for the world planes in an evaluation at `time`
    /// whose plane filter has slack `slack` (m): poses of that time, and a mismatch far
    /// below the slack.
    pub(crate) fn usable(&self, time: f64, slack: f64) -> bool {
        self.time == Some(time) && self.mismatch <= MISMATCH_FRACTION * slack
    }

    /// Whether `body` has a frame.
    #[inline(always)]
    pub(crate) fn has(&self, body: u32) -> bool {
        self.slot.get(body as usize).is_some_and(|&s| s != NO_FRAME)
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
            first_triangle: b.first_triangle,
        })
    }
}

/// The frames stand aside unless their mismatch is below this fraction of the plane
/// filter's slack.
const MISMATCH_FRACTION: f64 = 1e-3;

/// A node in the template coordinates of one rigid body.
pub(crate) struct TemplateView<'a> {
    u: [f64; 3],
    scale: f64,
    planes: &'a [[f64; 4]],
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
}

/// Per body id, the range of its faces in `surface` when they are consecutive (`None`
/// when they are not; an empty range when it has none).
fn face_ranges(surface: &ContactSurface) -> Vec<Option<std::ops::Range<usize>>> {
    let mut ranges: Vec<Option<std::ops::Range<usize>>> = vec![Some(0..0); surface.n_bodies()];
    for (t, &b) in surface.triangle_body.iter().enumerate() {
        let r = &mut ranges[b as usize];
        *r = match r.take() {
            Some(r) if r.is_empty() => Some(t..t + 1),
            Some(r) if r.end == t => Some(r.start..t + 1),
            _ => None,
        };
    }
    ranges
}
