//! The pairs of rigid bodies that have a frame, found body by body instead of face by
//! face, at a full build and at a refresh.
//!
//! The grid scan visits, for every face, the cells its enlarged box overlaps and reads
//! every node there; on a packing of small rigid particles most of those nodes are the
//! face's own body's, and the scan's cost is that reading. A framed body's faces are a
//! template's faces carried by the body's pose (`crate::rigid_frames`), so they can be met
//! from the other side: for each framed body `B` the bodies `A` whose bounding sphere can
//! reach its sphere (the framed ones on a grid of the spheres, [`SphereGrid`]; the nodes of
//! a body without a frame one by one), and for each node of `A` within `B`'s sphere grown
//! by the enlargement `e`, the faces of `B` toward which the node lies. Face body by face
//! body, so that each body's faces and corners are read in one go. The framed bodies'
//! nodes then stay out of the grid; a face of a body without a frame (a membrane) finds
//! them through the spheres that meet its enlarged box ([`SphereGrid::pairs_of_face`]).
//!
//! **The screen.** Every pair the grid scan keeps has the node within `e` of the face
//! (`super::is_candidate` refuses a larger distance). With `x` the node, `u` its template
//! coordinates in `B`'s frame and `e_t = e / s` the enlargement in template units (`s` the
//! pose's scale), a template point `p` of face `f` with `|u - p| <= e_t` satisfies
//! `angle(u, p) <= asin(e_t / |p|) <= beta_f = asin(e_t / rho_f)`, `rho_f` the face's
//! distance from the template's origin, while `angle(p, d_f) <= alpha_f`, the largest
//! angle between the direction `d_f` of the face's centroid and its corners (the cone of
//! half-angle `alpha_f < 90 degrees` about `d_f` is convex and holds the corners, so it
//! holds the face). Directions are binned on a cube map of [`PER_EDGE`]^2 bins per cube
//! face; a bin's directions lie within `gamma` of its centre direction `c` (its corners
//! do, and the bin is convex), so a face can be within `e` of a node whose direction falls
//! in the bin only if `angle(c, d_f) <= gamma + alpha_f + beta_f`: the bin lists exactly
//! those faces. A face with `e_t >= rho_f`, or a template face whose cone is not narrow,
//! is listed in every bin; a node at the template's origin reads every face. Of the faces
//! a bin lists, only those within `e_t` of `u` (the template face's plane first, a lower
//! bound of the distance, then the distance itself) go on: the template's faces are
//! shared by its instances and stay in cache, where each world face is a gather.
//!
//! Each pair the screen passes then takes the grid scan's own test on the world positions
//! (the face's enlarged box and `super::is_candidate`), so the lists are those of the grid
//! scan, pair for pair: the screen only decides which pairs are tested. The template
//! faces differ from the world faces by the frames' mismatch (far below a millionth of
//! the enlargement when the frames are in use), which the screen's relative slack
//! [`SCREEN_SLACK`] covers, as [`ANGLE_SLACK`] covers the round-off of the angles.
//!
//! Bins depend on `e_t`, which changes with the largest face at each build: they are kept
//! per template and per `e_t` rounded up to a power of [`REACH_STEP`] (a larger reach only
//! lists more faces), so a build reuses those of the last one.

use rayon::prelude::*;

use super::{
    BodyIndex, Candidate, CellTable, Reaches, WindowReach, grown_box, in_box, is_candidate, pack,
};
use crate::ContactSurface;
use crate::narrow::distance2_to_triangle;
use crate::rigid_frames::RigidFrames;
use crate::vec3::{dot, norm, norm2, scale, sub};

/// Bins per edge of each cube face of the direction map.
const PER_EDGE: usize = 8;

/// Bins of the direction map (six cube faces).
const BINS: usize = 6 * PER_EDGE * PER_EDGE;

/// Relative growth of the enlargement that covers the frames' mismatch and round-off.
const SCREEN_SLACK: f64 = 1e-6;

/// Angular slack of the bins' cone tests (rad), far above the round-off of the angles.
const ANGLE_SLACK: f64 = 1e-6;

/// Reaches in template units are rounded up to a power of this ratio before binning.
const REACH_STEP: f64 = 1.0 + 1.0 / 64.0;

/// Framed bodies per parallel work item of the scan (fixed, so the lists never depend on
/// the thread count; their order does not matter, the placement sorts each list).
const BODY_CHUNK: usize = 64;

/// A template's faces as cones of directions from its origin: per face, the direction of
/// its centroid, the half-angle of the cone about it that holds the face (`None`: no
/// narrow cone), and the face's distance from the origin (template units).
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct FaceCones {
    direction: Vec<[f64; 3]>,
    half_angle: Vec<Option<f64>>,
    distance: Vec<f64>,
    /// The faces' corners and unit planes `[n, n . a]` (template units), for the screen's
    /// last test: the node's distance to the template face.
    corners: Vec<[[f64; 3]; 3]>,
    planes: Vec<[f64; 4]>,
}

/// The angle between two unit vectors (rad).
#[inline]
fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    dot(a, b).clamp(-1.0, 1.0).acos()
}

/// `v / |v|`, `None` for a zero or non-finite vector.
fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let n = norm(v);
    (n > 0.0 && n.is_finite()).then(|| scale(v, 1.0 / n))
}

impl FaceCones {
    /// The cones of a template's faces (`nodes` indexed by `triangles`).
    pub(crate) fn of(nodes: &[[f64; 3]], triangles: &[[usize; 3]]) -> FaceCones {
        let mut cones = FaceCones::default();
        for tri in triangles {
            let face = tri.map(|i| nodes[i]);
            let centroid = scale(
                [0, 1, 2].map(|d| face[0][d] + face[1][d] + face[2][d]),
                1.0 / 3.0,
            );
            let direction = unit(centroid);
            // The largest angle to a corner; a cone of 90 degrees or more is not convex.
            let half_angle = direction.and_then(|d| {
                let corners = face.map(unit);
                let widest = corners
                    .iter()
                    .try_fold(0.0_f64, |w, c| Some(w.max(angle(d, (*c)?))))?;
                (widest < 0.5 * std::f64::consts::PI).then_some(widest)
            });
            cones.direction.push(direction.unwrap_or([0.0; 3]));
            cones.half_angle.push(half_angle);
            cones
                .distance
                .push(distance2_to_triangle([0.0; 3], face).sqrt());
            cones.corners.push(face);
            cones.planes.push(crate::model::unit_plane(face));
        }
        cones
    }

    fn len(&self) -> usize {
        self.direction.len()
    }
}

/// Per direction bin, the template faces a node in that direction may be within the
/// reach of (compressed rows; one more row, the last, lists every face).
#[derive(Clone, Debug, Default)]
pub(super) struct DirectionBins {
    start: Vec<u32>,
    faces: Vec<u32>,
}

/// The unit direction of the point `(s, t)` of cube face `(axis, negative)`.
fn cube_direction(axis: usize, negative: bool, s: f64, t: f64) -> [f64; 3] {
    let mut v = [0.0; 3];
    v[axis] = if negative { -1.0 } else { 1.0 };
    v[(axis + 1) % 3] = s;
    v[(axis + 2) % 3] = t;
    unit(v).expect("a cube point is not zero")
}

impl DirectionBins {
    /// The bins of `cones` for nodes within `reach` (template units) of a face.
    fn of(cones: &FaceCones, reach: f64) -> DirectionBins {
        let mut bins = DirectionBins {
            start: vec![0],
            faces: Vec::new(),
        };
        let width = 2.0 / PER_EDGE as f64;
        for bin in 0..BINS {
            let (cube, i, j) = (
                bin / (PER_EDGE * PER_EDGE),
                (bin / PER_EDGE) % PER_EDGE,
                bin % PER_EDGE,
            );
            let (axis, negative) = (cube / 2, cube % 2 == 1);
            let (s0, t0) = (-1.0 + width * i as f64, -1.0 + width * j as f64);
            let centre = cube_direction(axis, negative, s0 + 0.5 * width, t0 + 0.5 * width);
            let gamma = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                .iter()
                .map(|&(a, b)| {
                    angle(
                        centre,
                        cube_direction(axis, negative, s0 + a * width, t0 + b * width),
                    )
                })
                .fold(0.0, f64::max);
            for f in 0..cones.len() {
                let listed = match cones.half_angle[f] {
                    Some(alpha) if reach < cones.distance[f] => {
                        let beta = (reach / cones.distance[f]).asin();
                        angle(centre, cones.direction[f]) <= gamma + alpha + beta + ANGLE_SLACK
                    }
                    _ => true,
                };
                if listed {
                    bins.faces.push(f as u32);
                }
            }
            bins.start.push(bins.faces.len() as u32);
        }
        bins.faces.extend(0..cones.len() as u32);
        bins.start.push(bins.faces.len() as u32);
        bins
    }

    /// The template faces a node at template coordinates `u` may be within the reach of.
    #[inline]
    fn toward(&self, u: [f64; 3]) -> &[u32] {
        let a = u.map(f64::abs);
        let axis = if a[0] >= a[1] && a[0] >= a[2] {
            0
        } else if a[1] >= a[2] {
            1
        } else {
            2
        };
        let bin = if a[axis] > 0.0 && a[axis].is_finite() {
            let cell =
                |v: f64| (((v / a[axis] + 1.0) * 0.5 * PER_EDGE as f64) as usize).min(PER_EDGE - 1);
            let cube = 2 * axis + usize::from(u[axis] < 0.0);
            (cube * PER_EDGE + cell(u[(axis + 1) % 3])) * PER_EDGE + cell(u[(axis + 2) % 3])
        } else {
            BINS
        };
        &self.faces[self.start[bin] as usize..self.start[bin + 1] as usize]
    }
}

/// The direction bins a build has made, per template and rounded reach; kept across
/// builds.
#[derive(Clone, Debug, Default)]
pub(super) struct BinCache {
    keys: Vec<(u32, i64)>,
    bins: Vec<DirectionBins>,
}

impl BinCache {
    /// The index of the bins of `template` (whose cones are `cones`) for at least `reach`
    /// (template units), made if need be.
    fn index(&mut self, template: u32, reach: f64, cones: &FaceCones) -> usize {
        let step = REACH_STEP.ln();
        let (key, rounded) = if reach.is_finite() && reach > 0.0 {
            let mut q = (reach.ln() / step).ceil() as i64;
            if ((q as f64) * step).exp() < reach {
                q += 1;
            }
            (q, ((q as f64) * step).exp())
        } else {
            (i64::MAX, f64::INFINITY)
        };
        if let Some(i) = self.keys.iter().position(|&k| k == (template, key)) {
            return i;
        }
        self.keys.push((template, key));
        self.bins.push(DirectionBins::of(cones, rounded));
        self.bins.len() - 1
    }
}

/// A framed body as the scan sees it: its body id, the centre and radius of a sphere that
/// holds its faces (the pose's origin and its farthest node), and its bins.
#[derive(Clone, Copy, Debug)]
struct Sphere {
    body: u32,
    slot: u32,
    centre: [f64; 3],
    radius: f64,
    bins: u32,
}

/// The framed bodies' spheres binned by their centres on a hashed grid whose cells are at
/// least the largest diameter plus the enlargement.
pub(super) struct SphereGrid {
    spheres: Vec<Sphere>,
    inv: f64,
    largest: f64,
    table: CellTable,
    start: Vec<u32>,
    items: Vec<u32>,
}

impl SphereGrid {
    /// The grid of every framed body's sphere at the positions `nodes` of the surface nodes
    /// `bodies` lists, with the bins of enlargement `e` made in `cache`.
    pub(super) fn of(
        (nodes, bodies): (NodeAt<'_>, &BodyIndex),
        frames: &RigidFrames,
        cache: &mut BinCache,
        e: f64,
    ) -> SphereGrid {
        SphereGrid::new(spheres((nodes, bodies), frames, cache, e), e)
    }

    /// The body id of sphere `s`.
    pub(super) fn body(&self, s: u32) -> u32 {
        self.spheres[s as usize].body
    }

    /// Pushes onto `out` the spheres that meet the box `bx`. `cells` keeps the spheres of
    /// the last box's cells: consecutive boxes of a surface often overlap the same cells,
    /// which are then not looked up again.
    pub(super) fn near_box(&self, bx: &[f64; 6], cells: &mut BoxCells, out: &mut Vec<u32>) {
        let span = self.largest * (1.0 + SCREEN_SLACK);
        let lo = [0, 1, 2].map(|d| ((bx[d] - span) * self.inv).floor() as i64);
        let hi = [0, 1, 2].map(|d| ((bx[d + 3] + span) * self.inv).floor() as i64);
        if cells.range != Some((lo, hi)) {
            cells.range = Some((lo, hi));
            cells.spheres.clear();
            for k in lo[2]..=hi[2] {
                for j in lo[1]..=hi[1] {
                    for i in lo[0]..=hi[0] {
                        if let Some(cell) = self.table.get(pack(i, j, k)) {
                            let (a, b) = (self.start[cell as usize], self.start[cell as usize + 1]);
                            cells
                                .spheres
                                .extend_from_slice(&self.items[a as usize..b as usize]);
                        }
                    }
                }
            }
        }
        for &s in &cells.spheres {
            let sphere = &self.spheres[s as usize];
            // The squared distance from the centre to the box.
            let d2: f64 = (0..3)
                .map(|d| {
                    (bx[d] - sphere.centre[d])
                        .max(sphere.centre[d] - bx[d + 3])
                        .max(0.0)
                        .powi(2)
                })
                .sum();
            let reach = sphere.radius * (1.0 + SCREEN_SLACK);
            if d2 <= reach * reach {
                out.push(s);
            }
        }
    }

    /// Pushes onto `pairs` the pairs `(k, candidate)` of a face whose enlarged box is `bx`
    /// with every node `k` (at `nodes`) of the bodies whose sphere meets the box that
    /// passes `test` (the caller's grid-scan test of its position); `scratch` keeps
    /// buffers from face to face.
    pub(super) fn pairs_of_face(
        &self,
        (bx, candidate): (&[f64; 6], Candidate),
        (nodes, bodies): (NodeAt<'_>, &BodyIndex),
        test: &mut impl FnMut([f64; 3]) -> bool,
        (near, cells): &mut (Vec<u32>, BoxCells),
        pairs: &mut Vec<(u32, Candidate)>,
    ) {
        near.clear();
        self.near_box(bx, cells, near);
        for &k in near
            .iter()
            .flat_map(|&s| bodies.nodes(self.body(s) as usize))
        {
            if test(nodes.get(k)) {
                pairs.push((k, candidate));
            }
        }
    }

    fn new(spheres: Vec<Sphere>, e: f64) -> SphereGrid {
        let largest = spheres.iter().map(|s| s.radius).fold(0.0, f64::max);
        let inv = 1.0 / (2.0 * largest + e);
        let mut table = CellTable::default();
        table.reset(spheres.len());
        let cells: Vec<u32> = spheres
            .iter()
            .map(|s| {
                let [i, j, k] = s.centre.map(|c| (c * inv).floor() as i64);
                table.insert(pack(i, j, k))
            })
            .collect();
        let (start, items) = super::bodies::rows(&cells, table.len);
        SphereGrid {
            spheres,
            inv,
            largest,
            table,
            start,
            items,
        }
    }

    /// Pushes onto `out` the spheres grown by `r` that hold `x`.
    fn near(&self, x: [f64; 3], r: f64, out: &mut Vec<u32>) {
        let span = r + self.largest;
        let lo = x.map(|c| ((c - span) * self.inv).floor() as i64);
        let hi = x.map(|c| ((c + span) * self.inv).floor() as i64);
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    let Some(cell) = self.table.get(pack(i, j, k)) else {
                        continue;
                    };
                    let row =
                        self.start[cell as usize] as usize..self.start[cell as usize + 1] as usize;
                    for &s in &self.items[row] {
                        let sphere = &self.spheres[s as usize];
                        let reach = (sphere.radius + r) * (1.0 + SCREEN_SLACK);
                        if norm2(sub(x, sphere.centre)) <= reach * reach {
                            out.push(s);
                        }
                    }
                }
            }
        }
    }
}

/// The spheres of the cells the last box of [`SphereGrid::near_box`] overlapped (those
/// cells' range), reused while consecutive boxes overlap the same cells.
#[derive(Default)]
pub(super) struct BoxCells {
    range: Option<([i64; 3], [i64; 3])>,
    spheres: Vec<u32>,
}

/// Where the surface nodes are: `positions[ids[k]]` for surface node `k`, or
/// `positions[k]` without `ids` (the build's reference positions).
#[derive(Clone, Copy)]
pub(super) struct NodeAt<'a> {
    pub(super) positions: &'a [[f64; 3]],
    pub(super) ids: Option<&'a [usize]>,
}

impl NodeAt<'_> {
    #[inline(always)]
    fn get(&self, k: u32) -> [f64; 3] {
        match self.ids {
            Some(ids) => self.positions[ids[k as usize]],
            None => self.positions[k as usize],
        }
    }
}

/// What the scan reads: the surface nodes' positions, the positions by node id (the
/// faces' corners), the surface, its body index, and the candidate test's reaches.
pub(super) struct ScanInput<'a> {
    pub(super) nodes: NodeAt<'a>,
    pub(super) positions: &'a [[f64; 3]],
    pub(super) surface: &'a ContactSurface,
    pub(super) bodies: &'a BodyIndex,
    pub(super) reaches: Reaches,
    pub(super) window: WindowReach,
}

/// The pairs of every surface node with the faces of the bodies `frames` has, one list per
/// work item: per framed body, its faces against the nodes of the framed bodies near it;
/// per chunk of [`super::CHUNK`] nodes of bodies without a frame, each against the framed
/// bodies near it. The screen is described in the module documentation; every pair passes
/// the grid scan's own test.
pub(super) fn framed_pairs(
    input: &ScanInput<'_>,
    frames: &RigidFrames,
    (grid, cache): (&SphereGrid, &BinCache),
    two_sided: &(impl Fn(u32) -> bool + Sync),
) -> Vec<Vec<(u32, Candidate)>> {
    let e = input.reaches.enlargement;
    let mut found: Vec<Vec<(u32, Candidate)>> = (0..grid.spheres.len().div_ceil(BODY_CHUNK))
        .into_par_iter()
        .map(|chunk| {
            let mut pairs = Vec::new();
            let mut near = Vec::new();
            let first = chunk * BODY_CHUNK;
            // Face body by face body, so that each body's faces are read in one go.
            for b in &grid.spheres[first..(first + BODY_CHUNK).min(grid.spheres.len())] {
                near.clear();
                grid.near(b.centre, b.radius + e, &mut near);
                for &a in &near {
                    let a = &grid.spheres[a as usize];
                    if a.body != b.body {
                        let nodes = input.bodies.nodes(a.body as usize);
                        pairs_with(input, frames, (cache, b), nodes, two_sided, &mut pairs);
                    }
                }
            }
            pairs
        })
        .collect();
    found.extend(loose_pairs(input, frames, (grid, cache), two_sided));
    found
}

/// The pairs of the nodes of the bodies without a frame, each on its own, with the faces
/// of the framed bodies of `grid` near it, one list per chunk of [`super::CHUNK`] nodes.
fn loose_pairs(
    input: &ScanInput<'_>,
    frames: &RigidFrames,
    (grid, cache): (&SphereGrid, &BinCache),
    two_sided: &(impl Fn(u32) -> bool + Sync),
) -> Vec<Vec<(u32, Candidate)>> {
    let e = input.reaches.enlargement;
    let loose: Vec<u32> = (0..input.bodies.bodies() as u32)
        .filter(|&b| !frames.has(b))
        .flat_map(|b| input.bodies.nodes(b as usize).iter().copied())
        .collect();
    loose
        .par_chunks(super::CHUNK)
        .map(|nodes| {
            let (mut pairs, mut near) = (Vec::new(), Vec::new());
            for k in nodes {
                near.clear();
                grid.near(input.nodes.get(*k), e, &mut near);
                for &b in &near {
                    let b = &grid.spheres[b as usize];
                    let node = std::slice::from_ref(k);
                    pairs_with(input, frames, (cache, b), node, two_sided, &mut pairs);
                }
            }
            pairs
        })
        .collect()
}

/// A refresh's new pairs of the framed bodies marked in `dirty` (per body id), in both
/// directions, one list per work item (a pair may come twice; the merge keeps one): per
/// dirty body, its nodes against the faces of the framed bodies near it and, when such a
/// body is not dirty itself (its own turn gives them otherwise), that body's nodes against
/// its faces; the nodes of the bodies without a frame against the dirty bodies' faces;
/// and the faces of the bodies without a frame against the dirty bodies' nodes. The
/// spheres are those of the positions `input.nodes`.
pub(super) fn refreshed_pairs(
    input: &ScanInput<'_>,
    frames: &RigidFrames,
    (dirty, cache): (&[bool], &mut BinCache),
    two_sided: &(impl Fn(u32) -> bool + Sync),
) -> Vec<Vec<(u32, Candidate)>> {
    let e = input.reaches.enlargement;
    let is_dirty = |body: u32| dirty.get(body as usize).is_some_and(|&d| d);
    if !frames.framed_bodies().any(|(body, _)| is_dirty(body)) {
        return Vec::new();
    }
    let grid = SphereGrid::of((input.nodes, input.bodies), frames, cache, e);
    let cache = &*cache;
    let dirty_spheres: Vec<Sphere> = (grid.spheres.iter())
        .filter(|s| is_dirty(s.body))
        .copied()
        .collect();
    let mut found: Vec<Vec<(u32, Candidate)>> = dirty_spheres
        .par_chunks(BODY_CHUNK)
        .map(|chunk| {
            let (mut pairs, mut near) = (Vec::new(), Vec::new());
            for d in chunk {
                near.clear();
                grid.near(d.centre, d.radius + e, &mut near);
                let nodes = input.bodies.nodes(d.body as usize);
                for &b in &near {
                    let b = &grid.spheres[b as usize];
                    if b.body == d.body {
                        continue;
                    }
                    pairs_with(input, frames, (cache, b), nodes, two_sided, &mut pairs);
                    if !is_dirty(b.body) {
                        let theirs = input.bodies.nodes(b.body as usize);
                        pairs_with(input, frames, (cache, d), theirs, two_sided, &mut pairs);
                    }
                }
            }
            pairs
        })
        .collect();
    let dirty_grid = SphereGrid::new(dirty_spheres, e);
    found.extend(loose_pairs(input, frames, (&dirty_grid, cache), two_sided));
    found.par_extend((frames.unframed_faces().par_iter()).map(|faces| {
        let (mut pairs, mut scratch) = (Vec::new(), Default::default());
        for t in faces.clone() {
            unframed_face_pairs(input, (&dirty_grid, t), two_sided, &mut scratch, &mut pairs);
        }
        pairs
    }));
    found
}

/// Pushes onto `pairs` the pairs of face `t` (of a body without a frame) with the nodes of
/// the bodies in `grid` whose sphere meets its enlarged box, by the grid scan's test.
fn unframed_face_pairs(
    input: &ScanInput<'_>,
    (grid, t): (&SphereGrid, usize),
    two_sided: &(impl Fn(u32) -> bool + Sync),
    scratch: &mut (Vec<u32>, BoxCells),
    pairs: &mut Vec<(u32, Candidate)>,
) {
    let e = input.reaches.enlargement;
    let (owner, ids) = (input.surface.triangle_body[t], input.surface.triangles[t]);
    let face = ids.map(|i| input.positions[i]);
    let bx = grown_box(face, e);
    let reach = input.reaches.of_face(two_sided(owner));
    let window = input.window;
    let mut face_window = window.of_face_lazily(face);
    let candidate = Candidate {
        nodes: ids.map(|i| i as u32),
        triangle: t as u32,
        body: owner,
    };
    let nodes = (input.nodes, input.bodies);
    let mut test = |x| in_box(&bx, x) && is_candidate(x, face, reach, &mut face_window);
    grid.pairs_of_face((&bx, candidate), nodes, &mut test, scratch, pairs);
}

/// Every framed body's sphere and bins (of enlargement `e`), in the frames' order.
///
/// A body whose surface nodes are a run of its faces' corners (`RigidFrames::node_runs`)
/// takes the ball its pose gives it (`RigidFrames::ball`: every such node lies in it), so
/// that no node is read; any other body the farthest of its nodes at `nodes`. The sphere is
/// a screen only (every pair it lets through passes the grid scan's own test), so a radius
/// larger by the frames' mismatch lists the same pairs.
fn spheres(
    (nodes, bodies): (NodeAt<'_>, &BodyIndex),
    frames: &RigidFrames,
    cache: &mut BinCache,
    e: f64,
) -> Vec<Sphere> {
    let framed: Vec<(u32, usize)> = frames.framed_bodies().collect();
    let mut spheres: Vec<Sphere> = framed
        .par_iter()
        .map(|&(body, slot)| {
            let (centre, radius) = match frames.nodes_ball(slot) {
                Some(ball) => ball,
                None => {
                    let centre = frames.pose(slot).origin;
                    let farthest = (bodies.nodes(body as usize).iter())
                        .map(|&k| norm2(sub(nodes.get(k), centre)))
                        .fold(0.0, f64::max);
                    (centre, farthest.sqrt())
                }
            };
            Sphere {
                body,
                slot: slot as u32,
                centre,
                radius,
                bins: 0,
            }
        })
        .collect();
    let reach = e * (1.0 + SCREEN_SLACK);
    // Bodies of one template and scale share their bins: look them up once per run of such
    // bodies (the lookup takes logarithms).
    let mut last: Option<((u32, u64), u32)> = None;
    for s in &mut spheres {
        let slot = s.slot as usize;
        let template = frames.template_of(slot);
        let scale = frames.pose(slot).scale;
        let key = (template, scale.to_bits());
        s.bins = match last {
            Some((k, bins)) if k == key => bins,
            _ => cache.index(template, reach / scale, frames.cones(template)) as u32,
        };
        last = Some((key, s.bins));
    }
    spheres
}

/// Pushes onto `pairs` the pairs of the surface nodes `nodes` (of a body other than `b`'s)
/// with the faces of framed body `b` that pass the screen and the grid scan's test.
fn pairs_with(
    input: &ScanInput<'_>,
    frames: &RigidFrames,
    (cache, b): (&BinCache, &Sphere),
    nodes: &[u32],
    two_sided: &(impl Fn(u32) -> bool + Sync),
    pairs: &mut Vec<(u32, Candidate)>,
) {
    let e = input.reaches.enlargement;
    let reach = (b.radius + e) * (1.0 + SCREEN_SLACK);
    let pose = frames.pose(b.slot as usize);
    let first = frames.first_triangle(b.slot as usize) as usize;
    let bins = &cache.bins[b.bins as usize];
    let cones = frames.cones(frames.template_of(b.slot as usize));
    let e_t = e * (1.0 + SCREEN_SLACK) / pose.scale;
    let face_reach = input.reaches.of_face(two_sided(b.body));
    for &k in nodes {
        let x = input.nodes.get(k);
        if norm2(sub(x, b.centre)) > reach * reach {
            continue;
        }
        let u = pose.template_point(x);
        for &f in bins.toward(u) {
            // The node's distance to the template face: its plane's first (a lower bound).
            let [nx, ny, nz, d] = cones.planes[f as usize];
            let s = nx * u[0] + ny * u[1] + nz * u[2] - d;
            if s.abs() > e_t || distance2_to_triangle(u, cones.corners[f as usize]) > e_t * e_t {
                continue;
            }
            // The grid scan's test: the face's enlarged box (made from its corners as the
            // build's boxes are, bit for bit: their corners are at hand, the boxes are not),
            // then `is_candidate`.
            let t = first + f as usize;
            let ids = input.surface.triangles[t];
            let face = ids.map(|i| input.positions[i]);
            if !in_box(&grown_box(face, e), x) {
                continue;
            }
            let mut face_window = input.window.of_face_lazily(face);
            if is_candidate(x, face, face_reach, &mut face_window) {
                pairs.push((
                    k,
                    Candidate {
                        nodes: ids.map(|i| i as u32),
                        triangle: t as u32,
                        body: b.body,
                    },
                ));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    /// The faces of a level-1 sphere (42 nodes, 80 faces, diameter 2) stretched along the
    /// axes: a template like the particles'.
    fn template(stretch: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
        use fdem_mesh::{ElementOrder, MeshAssembly, Placement, Sizing, SphereSpec};
        let spec = SphereSpec {
            level: 1,
            order: ElementOrder::Linear,
            diameter: 2.0,
            sizing: Sizing::Inscribed,
        };
        let mesh = fdem_mesh::sphere_mesh(&spec).expect("a valid sphere");
        let mut one = MeshAssembly::new();
        one.push_instance(&mesh, &Placement::default())
            .expect("one instance");
        let nodes = (mesh.nodes.iter())
            .map(|n| [0, 1, 2].map(|d| n[d] * stretch[d]))
            .collect();
        (nodes, one.triangles.clone())
    }

    /// Every face within the reach of a node is among the faces its bin lists, for nodes
    /// around a sphere and an ellipsoid, reaches from a hundredth to twice the radius, and
    /// points at the origin and on the cube map's seams.
    #[test]
    fn the_bins_list_every_face_within_the_reach() {
        let mut rng = Pcg64::seed_from_u64(11);
        for stretch in [[1.0, 1.0, 1.0], [1.0, 0.7, 0.5]] {
            let (nodes, triangles) = template(stretch);
            let cones = FaceCones::of(&nodes, &triangles);
            for reach in [0.01, 0.08, 0.3, 2.0] {
                let bins = DirectionBins::of(&cones, reach);
                let mut listed = 0;
                let mut points: Vec<[f64; 3]> =
                    vec![[0.0; 3], [1.0, 1.0, 1.0], [0.0, -0.9, 0.0], [0.5, 0.5, 0.0]];
                points.extend((0..4000).map(|_| {
                    let d = unit([0, 1, 2].map(|_| rng.random_range(-1.0..1.0)))
                        .unwrap_or([1.0, 0.0, 0.0]);
                    scale(d, rng.random_range(0.3..1.0 + 1.5 * reach))
                }));
                for u in points {
                    let got = bins.toward(u);
                    listed += got.len();
                    for (f, tri) in triangles.iter().enumerate() {
                        let d2 = distance2_to_triangle(u, tri.map(|i| nodes[i]));
                        assert!(
                            d2 > reach * reach || got.contains(&(f as u32)),
                            "face {f} at {} of {u:?} (reach {reach}, stretch {stretch:?}) not listed",
                            d2.sqrt()
                        );
                    }
                }
                // The screen is worth having at small reaches: a fraction of the faces.
                if reach <= 0.08 && stretch == [1.0; 3] {
                    let mean = listed as f64 / 4004.0;
                    assert!(
                        mean < 0.25 * triangles.len() as f64,
                        "{mean} faces per node"
                    );
                }
            }
        }
    }

    #[test]
    fn a_cache_reuses_the_bins_of_a_reach_rounded_up_and_never_below() {
        let (nodes, triangles) = template([1.0; 3]);
        let cones = FaceCones::of(&nodes, &triangles);
        let mut cache = BinCache::default();
        let a = cache.index(0, 0.05, &cones);
        let b = cache.index(0, 0.05 * (1.0 + 1e-4), &cones);
        let c = cache.index(1, 0.05, &cones);
        let d = cache.index(0, 0.2, &cones);
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_ne!(a, d);
        assert_eq!(cache.bins.len(), 3);
        let inf = cache.index(0, f64::NAN, &cones);
        assert_eq!(
            cache.bins[inf].toward([1.0, 0.0, 0.0]).len(),
            triangles.len()
        );
    }
}
