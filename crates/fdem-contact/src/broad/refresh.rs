//! Partial refresh of the broad phase: new candidate pairs for the few bodies that drifted
//! past half the skin, every other pair kept.
//!
//! A full build makes every pair that can come within the depth limit before any node
//! has drifted half the skin: both ends of a pair move at most half a skin each. In a
//! granular test a few rattling or spinning particles reach half a skin long before the
//! rest, and a full build every time one does costs most of the step. Instead, the bodies
//! with a node past half the skin (the dirty bodies) get new pairs, in both directions
//! (their nodes against every face, every node against their faces), from the current
//! positions, and take the current positions as their new reference.
//!
//! Why the kept and the new pairs still hold every contact until the next refresh: a pair
//! found at a full build has both ends within half a skin of where they were then, as
//! before. A pair found at a refresh has one end (the dirty body's) at its new reference,
//! moving at most half a skin before it is refreshed again; the other end may already have
//! drifted up to half a skin from its own reference when the pair was found and may drift
//! that far again, so relative to the pair's positions it moves up to a whole skin. The
//! relative motion is one and a half skins instead of one, and a refresh finds its pairs
//! with the enlargement and the front reach of the last full build each grown by what the
//! extra half skin adds ([`BroadPhase::refresh`]). When either end is refreshed again,
//! the pair is found anew.
//!
//! A sheet (a membrane of thousands of nodes, [`BroadPhase::refresh`]'s `single` bodies)
//! is renewed node by node instead: its drifted nodes get new pairs against every face, and
//! its faces with a drifted corner against every node. Nothing in the argument above needs
//! whole bodies: a kept pair has a node and face corners that each stayed within half a
//! skin of their own references, and a renewed node or face has its pairs found anew.
//!
//! Under a mean motion (`crate::mean_motion`) "drifted" means from where the mean motion
//! has taken a node's reference, the references are kept in the full build's
//! configuration, and the allowance is half a skin less the mean motion's distortion of
//! the reaches; the argument is the same in the frame the mean motion carries along.
//!
//! The lists stay sorted by (owner body, triangle) per node, and the narrow phase only
//! acts on faces whose window holds a node (every other candidate is skipped by an exact
//! test), so a list with more candidates than a full build would give yields the same
//! contacts and forces, bit for bit. A refresh's window reach takes the same extra motion
//! (`super::WindowReach::of_refresh`).

use rayon::prelude::*;

use super::framed;
use super::{
    BodyIndex, BroadPhase, CHUNK, Candidate, FRONT_SKINS, Frame, Reaches, TRIANGLE_CHUNK,
    WindowReach, grown_box, in_box, is_candidate,
};
use crate::ContactSurface;
use crate::mean_motion::{Expected, drift2};
use crate::rigid_frames::RigidFrames;

/// Items (surface nodes or triangles) binned by the cells their boxes overlap, on a dense
/// grid of a fixed cell size over the boxes' union.
#[derive(Default)]
struct LocalGrid {
    frame: Option<Frame>,
    dims: [i64; 3],
    /// Row starts of the cells' items in `items` (one more than the cells).
    start: Vec<u32>,
    items: Vec<u32>,
}

/// The number of cells of a box of `dims` cells, `None` on overflow.
fn cell_count(dims: [i64; 3]) -> Option<i64> {
    dims.iter().try_fold(1i64, |acc, &d| acc.checked_mul(d))
}

impl LocalGrid {
    /// Bins every `(item, box)` into the cells its box overlaps, items in the given order
    /// within a cell; `None` when a box overlaps more than [`MAX_CELLS_PER_BOX`] cells or
    /// the grid would have more than [`MAX_CELLS`] (a body torn far out of shape, or
    /// items spread over a region far larger than the cells: the caller rebuilds
    /// everything instead).
    fn build(cell_size: f64, boxes: &[(u32, [f64; 6])]) -> Option<LocalGrid> {
        if boxes.is_empty() {
            return Some(LocalGrid::default());
        }
        let mut union = [f64::INFINITY; 6];
        for (_, bx) in boxes {
            for d in 0..3 {
                union[d] = union[d].min(bx[d]);
                union[d + 3] = union[d + 3].min(-bx[d + 3]);
            }
        }
        let frame = Frame {
            origin: [union[0], union[1], union[2]],
            inv: 1.0 / cell_size,
            // `x` fastest, as `for_each_cell` numbers the cells.
            axes: [0, 1, 2],
        };
        let top = frame.cell([-union[3], -union[4], -union[5]]);
        let dims = top.map(|t| t.saturating_add(1).max(1));
        let cells = cell_count(dims).filter(|&c| c <= MAX_CELLS)? as usize;
        let mut grid = LocalGrid {
            frame: Some(frame),
            dims,
            start: vec![0; cells + 1],
            items: Vec::new(),
        };
        // Counting sort by cell (two passes over the boxes), items in their order within a
        // cell.
        for (_, bx) in boxes {
            let (lo, hi) = grid.range(bx);
            if cell_count([0, 1, 2].map(|d| hi[d] - lo[d] + 1))? > MAX_CELLS_PER_BOX {
                return None;
            }
            let start = &mut grid.start;
            for_each_cell(dims, lo, hi, |c| start[c + 1] += 1);
        }
        for c in 1..grid.start.len() {
            grid.start[c] += grid.start[c - 1];
        }
        let mut cursor = grid.start.clone();
        grid.items = vec![0; grid.start[cells] as usize];
        for &(item, ref bx) in boxes {
            let (lo, hi) = grid.range(bx);
            let items = &mut grid.items;
            for_each_cell(dims, lo, hi, |c| {
                items[cursor[c] as usize] = item;
                cursor[c] += 1;
            });
        }
        Some(grid)
    }

    /// The cells a box overlaps, clamped to the grid.
    #[inline]
    fn range(&self, bx: &[f64; 6]) -> ([i64; 3], [i64; 3]) {
        let frame = self.frame.expect("a grid with items has a frame");
        let lo = frame.cell([bx[0], bx[1], bx[2]]);
        let hi = frame.cell([bx[3], bx[4], bx[5]]);
        (
            [0, 1, 2].map(|d| lo[d].max(0)),
            [0, 1, 2].map(|d| hi[d].min(self.dims[d] - 1)),
        )
    }

    /// The items binned in the cell that holds `x`.
    #[inline]
    fn at(&self, x: [f64; 3]) -> &[u32] {
        let Some(frame) = self.frame else {
            return &[];
        };
        let c = frame.cell(x);
        if (0..3).any(|d| c[d] < 0 || c[d] >= self.dims[d]) {
            return &[];
        }
        let c = (c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])) as usize;
        &self.items[self.start[c] as usize..self.start[c + 1] as usize]
    }

    /// Calls `f` with the items of every cell box `bx` overlaps (an item binned in
    /// several of those cells comes several times).
    #[inline]
    fn for_each_overlapping(&self, bx: &[f64; 6], mut f: impl FnMut(u32)) {
        if self.frame.is_none() {
            return;
        }
        let (lo, hi) = self.range(bx);
        for_each_cell(self.dims, lo, hi, |c| {
            let row = self.start[c] as usize..self.start[c + 1] as usize;
            self.items[row].iter().for_each(|&item| f(item));
        });
    }

    fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Whether box `bx` overlaps a cell that holds an item.
    fn holds_items_within(&self, bx: &[f64; 6]) -> bool {
        if self.frame.is_none() {
            return false;
        }
        let (lo, hi) = self.range(bx);
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                let row = self.dims[0] * (j + self.dims[1] * k);
                for i in lo[0]..=hi[0] {
                    let c = (i + row) as usize;
                    if self.start[c] != self.start[c + 1] {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// Per body, whether its box (`boxes`) overlaps a cell that holds an item: the bodies
    /// whose faces or nodes can meet the items at all (in parallel over the bodies).
    fn near_bodies(&self, boxes: &[[f64; 6]]) -> Vec<bool> {
        (boxes.par_iter())
            .with_min_len(BOXES_PER_TASK)
            .map(|bx| self.holds_items_within(bx))
            .collect()
    }
}

/// Per body, a box that holds its surface nodes at `positions` (in parallel over the
/// bodies); it holds every face of the body, whose corners are surface nodes of the body
/// (`ContactSurface::validate`). A framed body whose nodes are a run of its faces' corners
/// takes the box of the ball its pose gives it (`RigidFrames::ball`), without reading its
/// nodes: the boxes only screen bodies. A body without surface nodes gets an empty box
/// (lower corner above the upper).
fn body_boxes(
    positions: &[[f64; 3]],
    surface: &ContactSurface,
    bodies: &BodyIndex,
    frames: Option<&RigidFrames>,
) -> Vec<[f64; 6]> {
    let (inf, neg) = (f64::INFINITY, f64::NEG_INFINITY);
    let ball = |body: u32| frames.and_then(|f| f.nodes_ball(f.slot_of(body)?));
    (0..bodies.bodies())
        .into_par_iter()
        .map(|body| {
            if let Some((c, r)) = ball(body as u32) {
                return [c[0] - r, c[1] - r, c[2] - r, c[0] + r, c[1] + r, c[2] + r];
            }
            let mut bx = [inf, inf, inf, neg, neg, neg];
            for &k in bodies.nodes(body) {
                let x = positions[surface.surface_nodes[k as usize]];
                for d in 0..3 {
                    bx[d] = bx[d].min(x[d]);
                    bx[d + 3] = bx[d + 3].max(x[d]);
                }
            }
            bx
        })
        .collect()
}

/// Calls `f` with the index of every cell from `lo` to `hi` (inclusive; empty when a
/// bound is below the other) of a dense grid of `dims` cells, x fastest.
#[inline(always)]
fn for_each_cell(dims: [i64; 3], lo: [i64; 3], hi: [i64; 3], mut f: impl FnMut(usize)) {
    for k in lo[2]..=hi[2] {
        for j in lo[1]..=hi[1] {
            let row = dims[0] * (j + dims[1] * k);
            for i in lo[0]..=hi[0] {
                f((i + row) as usize);
            }
        }
    }
}

/// A refresh gives up (and the model rebuilds everything) when its grid would have more
/// cells than this ...
const MAX_CELLS: i64 = 1 << 24;

/// ... or when one box overlaps more cells than this; a face at a full build overlaps at most about 10^3 (the cell size is
/// at least an eighth of the largest enlarged face box).
const MAX_CELLS_PER_BOX: i64 = 1 << 12;

/// Bodies per parallel task of [`LocalGrid::near_bodies`]: a few cell lookups each, so a
/// task of fewer would cost more to hand over than to do (a choice, not a measured
/// break-even).
const BOXES_PER_TASK: usize = 1024;

/// The reaches of a refresh: the last full build's enlargement and front reach, each grown
/// by what the extra half skin of relative motion adds (see the module documentation),
/// and the window reach's allowances for that motion.
#[derive(Clone, Copy, Debug)]
struct RefreshReach {
    reaches: Reaches,
    window: WindowReach,
}

impl RefreshReach {
    fn of(broad: &BroadPhase, skin: f64) -> RefreshReach {
        RefreshReach {
            reaches: Reaches {
                enlargement: broad.enlargement + 0.5 * skin,
                front: broad.front + FRONT_SKINS * 0.5 * skin,
                sheet: broad.sheet_enlargement + 0.5 * skin,
            },
            window: WindowReach::of_refresh(skin, broad.window.depth),
        }
    }
}

/// What a refresh renews: every pair of the dirty bodies, and the pairs of the single
/// drifted nodes (and of the faces they are corners of) of the bodies renewed node by node.
#[derive(Clone, Debug, Default)]
pub(crate) struct Dirt {
    /// Per body id, whether every pair of the body is renewed.
    pub(crate) bodies: Vec<bool>,
    /// The drifted surface nodes of the bodies renewed node by node, increasing.
    pub(crate) nodes: Vec<u32>,
}

impl Dirt {
    /// How many bodies are renewed whole.
    pub(crate) fn whole_bodies(&self) -> usize {
        self.bodies.iter().filter(|&&d| d).count()
    }
}

impl BroadPhase {
    /// The surface nodes a refresh of `dirt` renews: those of its dirty bodies and its
    /// single nodes.
    pub(crate) fn renewed_nodes(&self, dirt: &Dirt) -> usize {
        let whole: usize = (dirt.bodies.iter().enumerate())
            .filter(|&(_, &d)| d)
            .map(|(b, _)| self.bodies.nodes(b).len())
            .sum();
        whole + dirt.nodes.len()
    }

    /// What a refresh must renew ([`Dirt`]): per body, whether one of its surface nodes lies
    /// farther than `half` from where its reference position is expected (the reference
    /// itself without mean motion), and for the bodies marked `single` (renewed node by
    /// node) those nodes themselves. The nodes of bodies marked in `clean` (per body id:
    /// known to be within `half`) are not read.
    pub(crate) fn drifted(
        &self,
        positions: &[[f64; 3]],
        surface: &ContactSurface,
        (half, clean): (f64, &[bool]),
        expected: Option<&Expected>,
        single: impl Fn(u32) -> bool + Sync,
    ) -> Dirt {
        let n_bodies = self.bodies.bodies();
        // The drifted nodes' bodies (and single nodes), found in parallel over fixed chunks
        // of nodes.
        let drifted: Vec<(Vec<u32>, Vec<u32>)> = (0..surface.surface_nodes.len().div_ceil(CHUNK))
            .into_par_iter()
            .map(|chunk| {
                let nodes = chunk * CHUNK..((chunk + 1) * CHUNK).min(surface.surface_nodes.len());
                let (mut bodies, mut singles): (Vec<u32>, Vec<u32>) = (Vec::new(), Vec::new());
                for k in nodes {
                    let body = surface.node_body[k];
                    let one_by_one = single(body);
                    if (one_by_one || bodies.last() != Some(&body))
                        && !clean.get(body as usize).is_some_and(|&c| c)
                        && drift2(
                            expected,
                            positions[surface.surface_nodes[k]],
                            self.reference[k],
                        ) > half * half
                    {
                        if one_by_one {
                            singles.push(k as u32);
                        } else {
                            bodies.push(body);
                        }
                    }
                }
                (bodies, singles)
            })
            .collect();
        let mut dirt = Dirt {
            bodies: vec![false; n_bodies],
            nodes: Vec::new(),
        };
        for (bodies, singles) in &drifted {
            for &body in bodies {
                dirt.bodies[body as usize] = true;
            }
            dirt.nodes.extend_from_slice(singles);
        }
        dirt
    }

    /// The enlargement and the front reach a refresh finds its pairs with (m).
    pub(crate) fn refresh_reaches(&self, skin: f64) -> (f64, f64) {
        let r = RefreshReach::of(self, skin).reaches;
        (r.enlargement, r.front)
    }

    /// Surface nodes refreshed since the last full build (counting a node once per
    /// refresh).
    pub(crate) fn refreshed_nodes(&self) -> usize {
        self.refreshed_nodes
    }

    /// Replaces every candidate pair with a node or a face on a body marked in
    /// `dirt.bodies`, or with one of `dirt.nodes` or a face it is a corner of, by the pairs
    /// at the current positions (the refresh reaches, [`RefreshReach`]), and resets those
    /// nodes' reference positions (to the full build's configuration under the mean
    /// motion's map `expected`, so that they are expected where they are now); every
    /// other pair is kept. A full build must have come first. With `frames` (in use at these
    /// positions), the framed dirty bodies' pairs are found body by body
    /// (`super::framed`), the others' on local grids. Returns `false`, changing nothing,
    /// when a box is too large to bin ([`MAX_CELLS_PER_BOX`]).
    pub(crate) fn refresh(
        &mut self,
        (positions, surface): (&[[f64; 3]], &ContactSurface),
        (dirt, expected): (&Dirt, Option<&Expected>),
        (skin, frames): (f64, Option<&RigidFrames>),
        two_sided: impl Fn(u32) -> bool + Sync,
    ) -> bool {
        let dirty = dirt.bodies.as_slice();
        let reach = RefreshReach::of(self, skin);
        let single_faces = self.mark_singles(surface, &dirt.nodes);
        let on_grids: Vec<bool> = match frames {
            Some(f) => (dirty.iter().enumerate())
                .map(|(b, &d)| d && !f.has(b as u32))
                .collect(),
            None => dirty.to_vec(),
        };
        let mut found = Vec::new();
        if on_grids.iter().any(|&d| d) || !dirt.nodes.is_empty() {
            let items = (
                merged(self.bodies.nodes_of(&on_grids), &dirt.nodes),
                merged(self.bodies.triangles_of(&on_grids), &single_faces),
            );
            let pairs = self.grid_pairs(
                (positions, surface),
                items,
                (dirty, frames),
                reach,
                &two_sided,
            );
            let Some(pairs) = pairs else {
                self.unmark_singles(&dirt.nodes, &single_faces);
                return false;
            };
            found = pairs;
        }
        if let Some(frames) = frames {
            let input = framed::ScanInput {
                nodes: framed::NodeAt {
                    positions,
                    ids: Some(&surface.surface_nodes),
                },
                positions,
                surface,
                bodies: &self.bodies,
                reaches: reach.reaches,
                window: reach.window,
            };
            let dirty_framed = (dirty, &mut self.bins);
            found.extend(framed::refreshed_pairs(
                &input,
                frames,
                dirty_framed,
                &two_sided,
            ));
        }
        self.merge_refreshed(surface, dirty, found);
        self.unmark_singles(&dirt.nodes, &single_faces);
        let renewed = merged(self.bodies.nodes_of(dirty), &dirt.nodes);
        for &k in &renewed {
            let x = positions[surface.surface_nodes[k as usize]];
            self.reference[k as usize] = expected.map_or(x, |e| e.reference(x));
        }
        self.pairs = self.chunk_cands.iter().map(Vec::len).sum();
        self.refreshed_nodes += renewed.len();
        self.refreshes += 1;
        true
    }

    /// Marks `singles` (surface nodes renewed one by one) in `single_nodes`, and every face
    /// of their bodies with one of them as a corner in `single_faces`; returns those faces,
    /// increasing.
    fn mark_singles(&mut self, surface: &ContactSurface, singles: &[u32]) -> Vec<u32> {
        if singles.is_empty() {
            return Vec::new();
        }
        self.single_nodes.resize(surface.surface_nodes.len(), false);
        self.single_faces.resize(surface.triangles.len(), false);
        let mut corners: Vec<usize> = Vec::with_capacity(singles.len());
        let mut bodies: Vec<u32> = Vec::new();
        for &k in singles {
            self.single_nodes[k as usize] = true;
            corners.push(surface.surface_nodes[k as usize]);
            let body = surface.node_body[k as usize];
            if !bodies.contains(&body) {
                bodies.push(body);
            }
        }
        corners.sort_unstable();
        let mut faces: Vec<u32> = (bodies.iter())
            .flat_map(|&b| self.bodies.triangles(b as usize).iter().copied())
            .filter(|&t| {
                (surface.triangles[t as usize].iter()).any(|i| corners.binary_search(i).is_ok())
            })
            .collect();
        faces.sort_unstable();
        for &t in &faces {
            self.single_faces[t as usize] = true;
        }
        faces
    }

    /// Clears the marks [`BroadPhase::mark_singles`] set.
    fn unmark_singles(&mut self, singles: &[u32], faces: &[u32]) {
        for &k in singles {
            self.single_nodes[k as usize] = false;
        }
        for &t in faces {
            self.single_faces[t as usize] = false;
        }
    }

    /// The new pairs of the renewed surface nodes and faces `items` (increasing), in both
    /// directions, found on local grids; `None` when a box is too large to bin. A node of
    /// a body marked in `dirty` or a single node is renewed: its pairs come from its own
    /// turn, so the faces' turn passes over it.
    fn grid_pairs(
        &self,
        (positions, surface): (&[[f64; 3]], &ContactSurface),
        (dirty_nodes, dirty_faces): (Vec<u32>, Vec<u32>),
        (dirty, frames): (&[bool], Option<&RigidFrames>),
        reach: RefreshReach,
        two_sided: &(impl Fn(u32) -> bool + Sync),
    ) -> Option<Vec<Vec<(u32, Candidate)>>> {
        let e = reach.reaches.enlargement;
        // Each dirty node binned by the box it reaches, so that a triangle looks only at
        // the cells of its own box; each dirty face by its enlarged box.
        let node_boxes: Vec<(u32, [f64; 6])> = dirty_nodes
            .iter()
            .map(|&k| {
                let x = positions[surface.surface_nodes[k as usize]];
                (
                    k,
                    [x[0] - e, x[1] - e, x[2] - e, x[0] + e, x[1] + e, x[2] + e],
                )
            })
            .collect();
        let face_boxes: Vec<(u32, [f64; 6])> = (dirty_faces.into_iter())
            .map(|t| {
                let face = surface.triangles[t as usize].map(|i| positions[i]);
                (t, grown_box(face, e))
            })
            .collect();
        // Two serial counting sorts over dense grids, independent of each other.
        let (node_grid, face_grid) = rayon::join(
            || LocalGrid::build(self.cell_size, &node_boxes),
            || LocalGrid::build(self.cell_size, &face_boxes),
        );
        let (node_grid, face_grid) = (node_grid?, face_grid?);
        // Only the bodies whose box overlaps an occupied cell of a grid can pair with its
        // items: the scans below skip every other body's faces or nodes, which the grid
        // would give nothing (the same pairs, in the same order).
        // A body never pairs with itself: when every binned item is one body's (a
        // sheet's single nodes and faces), that body's items are skipped as well.
        let boxes = body_boxes(positions, surface, &self.bodies, frames);
        let mut near_nodes = node_grid.near_bodies(&boxes);
        if let Some(b) = sole_owner(
            node_boxes
                .iter()
                .map(|&(k, _)| surface.node_body[k as usize]),
        ) {
            near_nodes[b as usize] = false;
        }
        let mut found = faces_of_dirty_nodes(
            positions,
            surface,
            (&node_grid, &self.bodies.triangles_of(&near_nodes)),
            reach,
            two_sided,
        );
        let mut near_faces = face_grid.near_bodies(&boxes);
        let owners = face_boxes
            .iter()
            .map(|&(t, _)| surface.triangle_body[t as usize]);
        if let Some(b) = sole_owner(owners) {
            near_faces[b as usize] = false;
        }
        let renewed = |k: usize| {
            dirty[surface.node_body[k] as usize] || self.single_nodes.get(k).is_some_and(|&s| s)
        };
        found.extend(nodes_of_dirty_faces(
            positions,
            surface,
            &renewed,
            (&face_grid, &self.bodies.nodes_of(&near_faces)),
            reach,
            two_sided,
        ));
        Some(found)
    }
}

/// The body that owns every item of `owners`, when there is exactly one.
fn sole_owner(mut owners: impl Iterator<Item = u32>) -> Option<u32> {
    let first = owners.next()?;
    owners.all(|b| b == first).then_some(first)
}

/// The union of two increasing lists, increasing, without repeats.
fn merged(a: Vec<u32>, b: &[u32]) -> Vec<u32> {
    if b.is_empty() {
        return a;
    }
    let mut out = a;
    out.extend_from_slice(b);
    out.sort_unstable();
    out.dedup();
    out
}

/// The pairs of the dirty nodes (binned in `grid`) with the faces `near` them (the
/// faces of the bodies whose box reaches the grid's nodes, increasing), one list per fixed
/// chunk of those faces (a pair may be listed twice).
fn faces_of_dirty_nodes(
    positions: &[[f64; 3]],
    surface: &ContactSurface,
    (grid, near): (&LocalGrid, &[u32]),
    reach: RefreshReach,
    two_sided: &(impl Fn(u32) -> bool + Sync),
) -> Vec<Vec<(u32, Candidate)>> {
    if grid.is_empty() {
        return Vec::new();
    }
    let e = reach.reaches.enlargement;
    let reaches = reach.reaches;
    near.par_chunks(TRIANGLE_CHUNK)
        .map(|faces| {
            let mut pairs = Vec::new();
            for &t in faces {
                let t = t as usize;
                let owner = surface.triangle_body[t];
                let ids = surface.triangles[t];
                let face = ids.map(|i| positions[i]);
                let bx = grown_box(face, e);
                let face_reach = reaches.of_face(two_sided(owner));
                let mut face_window = reach.window.of_face_lazily(face);
                grid.for_each_overlapping(&grown_box(face, 0.0), |k| {
                    let x = positions[surface.surface_nodes[k as usize]];
                    if surface.node_body[k as usize] != owner
                        && in_box(&bx, x)
                        && is_candidate(x, face, face_reach, &mut face_window)
                    {
                        pairs.push((k, candidate(ids, t, owner)));
                    }
                });
            }
            pairs
        })
        .collect()
}

/// The pairs of the nodes `near` the dirty faces (the nodes of the bodies whose box
/// reaches the grid's faces, increasing; the `renewed` ones are skipped) with the dirty
/// faces (binned in `grid`), one list per fixed chunk of those nodes.
fn nodes_of_dirty_faces(
    positions: &[[f64; 3]],
    surface: &ContactSurface,
    renewed: &(impl Fn(usize) -> bool + Sync),
    (grid, near): (&LocalGrid, &[u32]),
    reach: RefreshReach,
    two_sided: &(impl Fn(u32) -> bool + Sync),
) -> Vec<Vec<(u32, Candidate)>> {
    if grid.is_empty() {
        return Vec::new();
    }
    let e = reach.reaches.enlargement;
    let reaches = reach.reaches;
    near.par_chunks(CHUNK)
        .map(|nodes| {
            let mut pairs = Vec::new();
            for &k in nodes {
                let k = k as usize;
                let body = surface.node_body[k];
                if renewed(k) {
                    continue;
                }
                let x = positions[surface.surface_nodes[k]];
                for &t in grid.at(x) {
                    let t = t as usize;
                    let owner = surface.triangle_body[t];
                    let ids = surface.triangles[t];
                    let face = ids.map(|i| positions[i]);
                    if owner != body
                        && in_box(&grown_box(face, e), x)
                        && is_candidate(
                            x,
                            face,
                            reaches.of_face(two_sided(owner)),
                            &mut reach.window.of_face_lazily(face),
                        )
                    {
                        pairs.push((k as u32, candidate(ids, t, owner)));
                    }
                }
            }
            pairs
        })
        .collect()
}

impl BroadPhase {
    /// Rewrites the lists of every chunk of nodes that a refresh touches: a renewed node's
    /// list (of a body marked in `dirty`, or a single node) becomes its new pairs; another
    /// node's list keeps its pairs with faces not renewed (of clean bodies, not single)
    /// and gains its new pairs with renewed faces; each sorted by (owner body, triangle).
    fn merge_refreshed(
        &mut self,
        surface: &ContactSurface,
        dirty: &[bool],
        found: Vec<Vec<(u32, Candidate)>>,
    ) {
        let n = surface.surface_nodes.len();
        let mut new_by_chunk: Vec<Vec<(u32, Candidate)>> = vec![Vec::new(); n.div_ceil(CHUNK)];
        for &(k, c) in found.iter().flatten() {
            new_by_chunk[k as usize / CHUNK].push((k, c));
        }
        let node_body = &surface.node_body;
        let (single_nodes, single_faces) = (&self.single_nodes, &self.single_faces);
        let renewed_node =
            |k: usize| dirty[node_body[k] as usize] || single_nodes.get(k).is_some_and(|&s| s);
        let renewed_face = |c: &Candidate| {
            dirty[c.body as usize] || single_faces.get(c.triangle as usize).is_some_and(|&s| s)
        };
        self.chunk_cands
            .par_iter_mut()
            .zip(self.chunk_starts.par_iter_mut())
            .zip(new_by_chunk.par_iter_mut())
            .enumerate()
            .for_each(|(chunk, ((cands, starts), new))| {
                let nodes = chunk * CHUNK..((chunk + 1) * CHUNK).min(n);
                let touched = !new.is_empty()
                    || nodes.clone().any(renewed_node)
                    || cands.iter().any(renewed_face);
                if !touched {
                    return;
                }
                new.sort_unstable_by_key(|&(k, c)| (k, c.body, c.triangle));
                new.dedup();
                let mut out = Vec::with_capacity(cands.len() + new.len());
                let mut out_starts = Vec::with_capacity(starts.len());
                out_starts.push(0);
                let mut next = new.iter().peekable();
                for (i, k) in nodes.enumerate() {
                    let begin = out.len();
                    if !renewed_node(k) {
                        out.extend(
                            cands[starts[i]..starts[i + 1]]
                                .iter()
                                .filter(|c| !renewed_face(c)),
                        );
                    }
                    while let Some(&(_, c)) = next.next_if(|&&(node, _)| node as usize == k) {
                        out.push(c);
                    }
                    out[begin..].sort_unstable_by_key(|c| (c.body, c.triangle));
                    out_starts.push(out.len());
                }
                *cands = out;
                *starts = out_starts;
            });
    }
}

/// The candidate record of triangle `t` (node ids fit in u32: `ContactSurface::validate`
/// checks the node count).
#[inline(always)]
fn candidate(ids: [usize; 3], t: usize, owner: u32) -> Candidate {
    Candidate {
        nodes: ids.map(|i| i as u32),
        triangle: t as u32,
        body: owner,
    }
}
