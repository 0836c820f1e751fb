//! Broad phase: a uniform grid over the surface nodes with a Verlet skin.
//!
//! Every triangle's bounding box is enlarged by `margin + depth limit` (plus the
//! barycentric tolerance band). The surface nodes are binned into a uniform grid (a
//! counting sort by cell, in parallel over ranges of cells, [`cell_sort`]), and each
//! triangle visits the cells its enlarged box overlaps: a node of another body in those
//! cells whose position lies in the box and within the enlargement of the triangle itself
//! (the point-triangle distance; the box's corners hold many pairs farther than that) is a
//! candidate pair if it lies in front of the face within the front reach, or behind it near
//! enough to its window, the prism where the narrow phase accepts a node ([`window`]: most
//! nodes within the enlargement behind a face lie beside it). The cell size is three
//! quarters of the mean enlarged box (at least an eighth of the largest), so a box overlaps
//! a few cells of a few nodes each; it sets only the work, never the lists. Cells are
//! numbered densely (`i + nx (j + ny k)`, `i` along the rows' axis, the one along which the
//! scan moves most from body to body, so that consecutive queries read rows that continue
//! each other) when the nodes' region holds at most [`DENSE_CELLS_PER_NODE`] cells per
//! node, and then a box's cells in one row are one run of binned nodes; otherwise through
//! their packed integer coordinates in a deterministic open-addressing table (fixed hash
//! function, slots numbered in insertion order). Triangles are scanned in parallel in fixed
//! chunks, and the pairs are then placed into each node's list, by parts of the nodes
//! ([`found`]), and sorted by (owner body, triangle): the lists are the same for every
//! thread count, and a build costs O(triangles + surface nodes + pairs). A run of
//! consecutive faces of one body (a particle's faces) whose boxes' union overlaps few cells
//! queries the grid once for the union, and each group of [`FACES_PER_GROUP`] faces, then
//! each face, tests the few nodes of other bodies found there instead of querying the grid
//! itself: every node in a face's box is in the union, so the lists are the same, and most
//! faces of a particle, far from its neighbours, meet none. Each chunk of the scan makes
//! its triangles' own boxes as it starts (the build's first pass over the triangles only
//! sizes them) and grows them by the enlargement where it reads them.
//!
//! Rigid bodies with a frame (`crate::rigid_frames`) are met body by body instead
//! ([`framed`]): their nodes stay out of the grid, the pairs with their faces come from
//! their bounding spheres and their template's faces binned by direction, and the other
//! faces find their nodes through the same spheres; a refresh meets its framed dirty
//! bodies the same way. Every pair still takes the scan's own test, so the lists are the
//! same.
//!
//! Verlet skin: while every surface node stays within `margin / 2` of its position at the
//! last build, a node and a triangle that were not candidates were more than `margin +
//! depth limit` apart and still are more than the depth limit apart (each moved less than
//! `margin / 2`), or the node cannot have entered the face's window ([`window`] has the
//! bound), so no contact within the depth limit can be missed. As soon as one node
//! has moved farther, the model either refreshes the pairs of the bodies that drifted
//! ([`refresh`]: a few rattling particles) or rebuilds everything.

mod bodies;
mod cell_sort;
mod found;
mod framed;
mod refresh;
mod window;

use bodies::BodyIndex;
use found::FoundPairs;
pub(crate) use framed::FaceCones;
pub(crate) use window::{FaceWindow, WindowReach};

use rayon::prelude::*;

use crate::ContactSurface;
use crate::narrow::{BARYCENTRIC_TOLERANCE, distance2_to_triangle};
use crate::prefetch::prefetch;
use crate::rigid_frames::RigidFrames;

/// Surface nodes per parallel work item (fixed, so the chunking never depends on the
/// thread count).
pub(crate) const CHUNK: usize = 512;

const EMPTY: u64 = u64::MAX;
const COORD_BITS: u32 = 21;
const COORD_MASK: u64 = (1 << COORD_BITS) - 1;

/// splitmix64 finaliser: a fixed, seedless hash, so the table layout is the same on every
/// run.
#[inline(always)]
fn hash(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Packs integer cell coordinates into 63 bits (21 per axis). Coordinates that wrap make
/// far-apart cells share a key; that only adds triangles to a cell, and the exact box test
/// removes them again.
#[inline(always)]
fn pack(i: i64, j: i64, k: i64) -> u64 {
    (i as u64 & COORD_MASK)
        | ((j as u64 & COORD_MASK) << COORD_BITS)
        | ((k as u64 & COORD_MASK) << (2 * COORD_BITS))
}

/// Deterministic open-addressing map from packed cell key to a dense cell number.
#[derive(Clone, Debug, Default)]
struct CellTable {
    keys: Vec<u64>,
    values: Vec<u32>,
    len: usize,
}

impl CellTable {
    fn reset(&mut self, expected: usize) {
        let cap = (expected.max(8) * 2).next_power_of_two();
        self.keys.clear();
        self.keys.resize(cap, EMPTY);
        self.values.clear();
        self.values.resize(cap, 0);
        self.len = 0;
    }

    #[inline]
    fn get(&self, key: u64) -> Option<u32> {
        let mask = self.keys.len() - 1;
        let mut i = hash(key) as usize & mask;
        loop {
            let k = self.keys[i];
            if k == key {
                return Some(self.values[i]);
            }
            if k == EMPTY {
                return None;
            }
            i = (i + 1) & mask;
        }
    }

    /// Returns the cell number of `key`, numbering a new key `len`.
    fn insert(&mut self, key: u64) -> u32 {
        if (self.len + 1) * 2 > self.keys.len() {
            self.grow();
        }
        let mask = self.keys.len() - 1;
        let mut i = hash(key) as usize & mask;
        loop {
            let k = self.keys[i];
            if k == key {
                return self.values[i];
            }
            if k == EMPTY {
                self.keys[i] = key;
                let v = self.len as u32;
                self.values[i] = v;
                self.len += 1;
                return v;
            }
            i = (i + 1) & mask;
        }
    }

    fn grow(&mut self) {
        let old_keys = std::mem::take(&mut self.keys);
        let old_values = std::mem::take(&mut self.values);
        let cap = old_keys.len().max(8) * 2;
        self.keys = vec![EMPTY; cap];
        self.values = vec![0; cap];
        let mask = cap - 1;
        for (k, v) in old_keys.into_iter().zip(old_values) {
            if k != EMPTY {
                let mut i = hash(k) as usize & mask;
                while self.keys[i] != EMPTY {
                    i = (i + 1) & mask;
                }
                self.keys[i] = k;
                self.values[i] = v;
            }
        }
    }
}

/// One candidate face of a surface node, with what the narrow phase needs inline (so the
/// hot loop reads it sequentially instead of chasing triangle -> body -> node ids).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Candidate {
    /// Global node ids of the face, in the order of `ContactSurface::triangles`: the narrow
    /// phase computes the face's plane from them (`model::unit_plane`), so the order sets
    /// the normal's side and the plane's bits.
    pub(crate) nodes: [u32; 3],
    /// Triangle index.
    pub(crate) triangle: u32,
    /// Owner body of the triangle.
    pub(crate) body: u32,
}

/// Grid, reference positions and candidate lists (compressed rows per surface node).
#[derive(Clone, Debug, Default)]
pub(crate) struct BroadPhase {
    /// Whether a build has happened.
    pub(crate) built: bool,
    /// Number of full builds so far.
    pub(crate) builds: usize,
    /// Number of partial refreshes so far ([`refresh`]).
    pub(crate) refreshes: usize,
    /// Surface nodes refreshed since the last full build.
    refreshed_nodes: usize,
    /// Enlargement of the triangle boxes at the last build (m).
    pub(crate) enlargement: f64,
    /// Reach in front of a face's plane at the last build (m), see [`FRONT_SKINS`].
    pub(crate) front: f64,
    /// Enlargement of a sheet's faces at the last build (m): the skin, the sheets' listing
    /// depth and the tolerance band.
    pub(crate) sheet_enlargement: f64,
    /// The allowances behind the window reach of the last build ([`window`]).
    pub(crate) window: WindowReach,
    /// Each body's surface nodes and triangles ([`bodies`]).
    bodies: BodyIndex,
    /// Cell size at the last build (m).
    pub(crate) cell_size: f64,
    /// Surface node positions at the last build.
    pub(crate) reference: Vec<[f64; 3]>,
    /// Candidate faces per chunk of [`CHUNK`] surface nodes, sorted by (owner body,
    /// triangle) per node; the narrow phase reads them in place.
    chunk_cands: Vec<Vec<Candidate>>,
    /// Per chunk, the row starts of its nodes in `chunk_cands` (one more than its nodes).
    chunk_starts: Vec<Vec<usize>>,
    /// Number of candidate pairs of the last build.
    pub(crate) pairs: usize,
    /// Per surface node and per triangle, whether the refresh under way renews them one by
    /// one ([`refresh::Dirt`]); all `false` between refreshes.
    single_nodes: Vec<bool>,
    single_faces: Vec<bool>,
    layout: Layout,
    table: CellTable,
    /// The binned surface nodes by cell, increasing within a cell, and the cells' row
    /// starts (one more than the cells). Node numbers fit in `u32`
    /// (`ContactSurface::validate` checks the count); half the bytes of `usize` keep more
    /// of the rows in cache for the scan's queries.
    by_cell: cell_sort::CellSort,
    /// The surface nodes binned in the grid (those of bodies without a frame when the
    /// build has frames), increasing.
    binned: Vec<u32>,
    /// Per binned node, its cell number.
    node_cells: Vec<u32>,
    /// Reference positions and bodies of the nodes of `by_cell`, in its order.
    cell_payload: Vec<([f64; 3], u32)>,
    /// Pairs `(surface node, candidate)` found by the build, before they are placed.
    found: FoundPairs,
    /// Per surface node, the next free slot of its list while the pairs are placed.
    cursor: Vec<usize>,
    /// The direction bins of the rigid bodies' templates ([`framed`]).
    bins: framed::BinCache,
    /// When the scan queries the grid once for a run of one body's faces.
    segments: SegmentPolicy,
    /// Which axis the grid's rows follow.
    rows: RowAxis,
}

/// The axis a build's grid numbers its cells along first, its rows' axis: by default the
/// one along which the scan moves most from body to body ([`BroadPhase::row_axis`]). It
/// sets only the work, never the lists.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum RowAxis {
    #[default]
    Advance,
    /// Axis `0`, `1` or `2` (`x`, `y`, `z`).
    #[cfg_attr(not(test), allow(dead_code))]
    Along(usize),
}

/// How cells are numbered: a dense box of cells when the occupied region is compact
/// (cheap index arithmetic), else the hash table (any spread of positions).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Layout {
    #[default]
    Hash,
    Dense {
        dims: [i64; 3],
    },
}

/// Dense layouts are used up to this many cells per surface node (and at least this
/// floor).
const DENSE_CELLS_PER_NODE: usize = 8;
const DENSE_MIN_CELLS: usize = 1 << 12;

/// The grid's cell size over the mean enlarged triangle box (see
/// `BroadPhase::size_boxes`; docs/PERFORMANCE.md has the sizes tried).
const CELL_PER_MEAN_BOX: f64 = 0.75;

/// Triangles per parallel work item of the scan (fixed, so the lists never depend on the
/// thread count).
const TRIANGLE_CHUNK: usize = 2048;

/// Nodes per parallel work item of the grid's bounds ([`bounds`]).
const BOUNDS_CHUNK: usize = 4096;

/// Nodes per parallel work item of the gather of the binned nodes' positions and bodies
/// in cell order ([`gather_payload`]).
const GATHER_CHUNK: usize = 4096;

/// How many nodes ahead the gather in cell order asks for a node's position and body.
const GATHER_AHEAD: usize = 16;

/// The number of cell `c` (within the grid; coordinates in the frame's axis order) in a
/// dense layout of `dims` cells, the first coordinate fastest: a row along the rows' axis
/// has consecutive numbers.
#[inline(always)]
fn dense_index(dims: [i64; 3], c: [i64; 3]) -> usize {
    (c[0] + dims[0] * (c[1] + dims[1] * c[2])) as usize
}

/// Where the grid lies: the corner of cell `[0, 0, 0]`, the inverse cell size, and the
/// order of the axes in cell coordinates (the first is the rows' axis, numbered fastest).
#[derive(Clone, Copy, Debug)]
struct Frame {
    origin: [f64; 3],
    inv: f64,
    axes: [usize; 3],
}

impl Frame {
    /// Integer coordinates of the cell that holds `x`, in the order of `axes`.
    #[inline(always)]
    fn cell(self, x: [f64; 3]) -> [i64; 3] {
        let (origin, inv) = (self.origin, self.inv);
        self.axes.map(|a| floor_to_i64((x[a] - origin[a]) * inv))
    }

    /// The lowest and highest integer coordinates of the cells box `bx` overlaps, within
    /// the grid's cells in a dense layout (the others hold no node).
    #[inline(always)]
    fn cell_range(self, layout: Layout, bx: &[f64; 6]) -> ([i64; 3], [i64; 3]) {
        let mut lo = self.cell([bx[0], bx[1], bx[2]]);
        let mut hi = self.cell([bx[3], bx[4], bx[5]]);
        if let Layout::Dense { dims } = layout {
            for d in 0..3 {
                lo[d] = lo[d].max(0);
                hi[d] = hi[d].min(dims[d] - 1);
            }
        }
        (lo, hi)
    }

    /// Appends to `runs` the runs of `cell_nodes` (through the row starts `cell_start`)
    /// that hold the nodes of every cell a box overlaps, in the order of the cells (the
    /// rows' axis fastest) and of the nodes within each: with a dense layout, one run per
    /// row of cells (consecutive cell numbers, whose nodes lie consecutively), only the
    /// cells of its grid (the others hold no node); with the hash table, one run per cell.
    #[inline(always)]
    fn runs_within(
        self,
        (layout, table, cell_start): (Layout, &CellTable, &[u32]),
        bx: &[f64; 6],
        runs: &mut Vec<std::ops::Range<usize>>,
    ) {
        let (lo, hi) = self.cell_range(layout, bx);
        if let Layout::Dense { dims } = layout {
            if lo[0] > hi[0] {
                return;
            }
            for k in lo[2]..=hi[2] {
                for j in lo[1]..=hi[1] {
                    let first = dense_index(dims, [lo[0], j, k]);
                    let last = first + (hi[0] - lo[0]) as usize;
                    let run = cell_start[first] as usize..cell_start[last + 1] as usize;
                    if !run.is_empty() {
                        runs.push(run);
                    }
                }
            }
            return;
        }
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    if let Some(cell) = table.get(pack(i, j, k)) {
                        let cell = cell as usize;
                        runs.push(cell_start[cell] as usize..cell_start[cell + 1] as usize);
                    }
                }
            }
        }
    }
}

/// `v.floor() as i64`, without the library call `floor` becomes on targets without
/// SSE4.1: the conversion truncates towards zero (saturating, NaN to 0), and a negative
/// non-integer is one below its truncation. Exact for every `f64`: where `v` has no
/// fraction, or lies beyond the `i64` range, the truncation is already the answer.
#[inline(always)]
fn floor_to_i64(v: f64) -> i64 {
    let t = v as i64;
    if (t as f64) > v {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// A node in front of a face's plane (or on it) is a candidate only within this many skins
/// of the face. Justification: between builds the node and every point of the face move
/// at most half a skin each. A node that ends in contact lies behind the moved face at
/// depth z with its foot inside it; the same barycentric point of the face at the build
/// is within half a skin of that foot, so a node in front at the build had `z cos(theta)
/// <= skin` and was within `skin sqrt(1 + (1 + tan(theta))^2)` of the face, theta the
/// face's tilt since the build: two skins cover tilts up to 36 degrees, far beyond what an
/// elastic face whose edges are longer than the skin can turn between builds. Sheets keep
/// every face within reach (their edge contacts and fold filter need faces in front).
pub(crate) const FRONT_SKINS: f64 = 2.0;

/// Relative slack of the plane pre-filter of the query: a pair is skipped before its
/// point-triangle distance only when its plane distance exceeds the reach by this fraction,
/// far above the round-off of either, so the candidates are those of the distance test
/// alone.
const PLANE_PREFILTER_SLACK: f64 = 1e-6;

/// How far from one face the candidate test lists a node (squared lengths, m^2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum FaceReach {
    /// A solid body's face: within `reach2` of it, and behind its plane near its window
    /// ([`window`]) or in front of it within `front2`.
    Solid { reach2: f64, front2: f64 },
    /// A sheet's face: within `reach2` of it in any direction (its closest point and the
    /// pseudo-normal there need the faces in front as well).
    Sheet { reach2: f64 },
}

/// The reaches of a set of lists (m): the enlargement of a solid face (skin, depth limit
/// and tolerance band), the front reach ([`FRONT_SKINS`]) and the enlargement of a
/// sheet's face (skin, the sheets' listing depth and the band).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Reaches {
    pub(crate) enlargement: f64,
    pub(crate) front: f64,
    pub(crate) sheet: f64,
}

impl Reaches {
    /// The candidate test's reach for a face of a sheet (`sheet`) or of a solid body.
    #[inline(always)]
    pub(crate) fn of_face(&self, sheet: bool) -> FaceReach {
        if sheet {
            FaceReach::Sheet {
                reach2: self.sheet * self.sheet,
            }
        } else {
            FaceReach::Solid {
                reach2: self.enlargement * self.enlargement,
                front2: self.front * self.front,
            }
        }
    }
}

/// The candidate test of node `x` against a face of another body: within the face's
/// `reach2` (squared) of the face, and for a solid body's face either behind its plane
/// (strictly; outward normal by the right-hand rule of its corners) and within `window.1()`
/// of its window of depth `window.0` ([`window`]; the reach is asked for only here, at
/// most once per pair), or within `front2` (squared) of it; for a sheet's face the
/// distance alone.
///
/// The plane distance is a lower bound of the distance to the face, so a pair whose plane
/// distance exceeds its reach (beyond [`PLANE_PREFILTER_SLACK`]) is skipped before the
/// point-triangle distance; most faces near a node are in front of it, beyond the front
/// reach, and are skipped this way.
#[inline(always)]
fn is_candidate(
    x: [f64; 3],
    face: [[f64; 3]; 3],
    reach: FaceReach,
    window: &mut FaceWindow,
) -> bool {
    use crate::vec3::{cross, dot, norm2, sub};
    let (reach2, front2, two_sided) = match reach {
        FaceReach::Solid { reach2, front2 } => (reach2, front2, false),
        FaceReach::Sheet { reach2 } => (reach2, reach2, true),
    };
    let [a, b, c] = face;
    let n = cross(sub(b, a), sub(c, a));
    let s = dot(n, sub(x, a));
    let behind = s < 0.0;
    let limit2 = if behind || two_sided {
        reach2
    } else {
        front2.min(reach2)
    };
    let n2 = norm2(n);
    if s * s > limit2 * n2 * (1.0 + PLANE_PREFILTER_SLACK) {
        return false;
    }
    let d2 = distance2_to_triangle(x, face);
    if d2 > reach2 {
        return false;
    }
    if two_sided {
        return true;
    }
    if !behind {
        return d2 <= front2;
    }
    window.holds(d2, -s / n2.sqrt())
}

/// The box of a triangle (lower corner, upper corner).
#[inline(always)]
fn face_box(face: [[f64; 3]; 3]) -> [f64; 6] {
    let [a, b, c] = face;
    let mut bx = [0.0; 6];
    for d in 0..3 {
        bx[d] = lower(lower(a[d], b[d]), c[d]);
        bx[d + 3] = upper(upper(a[d], b[d]), c[d]);
    }
    bx
}

/// The smaller of two finite numbers. Positions are finite (the model checks them), so a
/// comparison does: `f64::min` adds its handling of NaN to each of the many calls of a
/// build.
#[inline(always)]
fn lower(p: f64, q: f64) -> f64 {
    if p < q { p } else { q }
}

/// The larger of two finite numbers (see [`lower`]).
#[inline(always)]
fn upper(p: f64, q: f64) -> f64 {
    if p > q { p } else { q }
}

/// A box holding nothing: its lower corner above its upper.
const EMPTY_BOX: [f64; 6] = [
    f64::INFINITY,
    f64::INFINITY,
    f64::INFINITY,
    f64::NEG_INFINITY,
    f64::NEG_INFINITY,
    f64::NEG_INFINITY,
];

/// The smallest box holding boxes `a` and `b` (of equal coordinates, `b`'s: [`lower`],
/// [`upper`]).
#[inline(always)]
fn enclose(mut a: [f64; 6], b: &[f64; 6]) -> [f64; 6] {
    for d in 0..3 {
        a[d] = lower(a[d], b[d]);
        a[d + 3] = upper(a[d + 3], b[d + 3]);
    }
    a
}

/// The box of the positions `x[k]` of nodes `nodes` ([`EMPTY_BOX`] for none): per fixed
/// run of nodes in parallel, then the runs in order, so that of equal coordinates the
/// same is kept as by one pass in order.
fn bounds(x: &[[f64; 3]], nodes: &[u32]) -> [f64; 6] {
    let mut runs: Vec<[f64; 6]> = Vec::new();
    runs.par_extend(nodes.par_chunks(BOUNDS_CHUNK).map(|run| {
        run.iter().fold(EMPTY_BOX, |b, &k| {
            let [p, q, r] = x[k as usize];
            enclose(b, &[p, q, r, p, q, r])
        })
    }));
    runs.iter().fold(EMPTY_BOX, enclose)
}

/// Box `bx` grown by `e` on every side.
#[inline(always)]
fn grow(bx: &[f64; 6], e: f64) -> [f64; 6] {
    [
        bx[0] - e,
        bx[1] - e,
        bx[2] - e,
        bx[3] + e,
        bx[4] + e,
        bx[5] + e,
    ]
}

/// The box of a triangle, grown by `e` on every side (the build's enlarged boxes, bit for
/// bit, when `e` is the enlargement).
#[inline(always)]
fn grown_box(face: [[f64; 3]; 3], e: f64) -> [f64; 6] {
    grow(&face_box(face), e)
}

/// Whether `x` lies in the box `b` (lower corner, upper corner), without a branch per
/// comparison: the scans meet a few nodes per face, in or out at random, where
/// short-circuit tests would be mispredicted jumps.
#[inline(always)]
fn in_box(b: &[f64; 6], x: [f64; 3]) -> bool {
    (x[0] >= b[0])
        & (x[1] >= b[1])
        & (x[2] >= b[2])
        & (x[0] <= b[3])
        & (x[1] <= b[4])
        & (x[2] <= b[5])
}

/// The faces of a run that share one first test of the run's foreign nodes: consecutive
/// faces of a mesh are mostly neighbours, so the group's union box is small and holds few
/// of them, and each face then tests only those.
const FACES_PER_GROUP: usize = 8;

/// When a run of consecutive faces of one body takes one query of the grid for all of
/// them ([`GridView::foreign_nodes`]) instead of one query per face: the choice sets only
/// the work, never the lists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct SegmentPolicy {
    /// The most cells the union of the run's boxes may overlap, per face (a face's own
    /// query visits two or three cells per axis).
    cells_per_face: usize,
    /// The most nodes of other bodies the union may hold, which each face then tests
    /// directly (a face's own query costs about as much as testing this many).
    max_foreign: usize,
}

impl SegmentPolicy {
    const DEFAULT: SegmentPolicy = SegmentPolicy {
        cells_per_face: 4,
        max_foreign: 64,
    };
}

impl Default for SegmentPolicy {
    fn default() -> Self {
        SegmentPolicy::DEFAULT
    }
}

/// The positions and bodies of the surface nodes `cell_nodes` (in the grid's cell order)
/// into `payload`, side by side, in parallel over fixed runs of nodes. A cell's nodes lie
/// anywhere in `reference`: each read asks for a later node's as it goes.
fn gather_payload(
    (reference, node_body): (&[[f64; 3]], &[u32]),
    cell_nodes: &[u32],
    payload: &mut Vec<([f64; 3], u32)>,
) {
    payload.resize(cell_nodes.len(), ([0.0; 3], 0));
    payload
        .par_chunks_mut(GATHER_CHUNK)
        .zip(cell_nodes.par_chunks(GATHER_CHUNK))
        .for_each(|(payload, nodes)| {
            for (i, (slot, &k)) in payload.iter_mut().zip(nodes).enumerate() {
                if let Some(&ahead) = nodes.get(i + GATHER_AHEAD) {
                    prefetch(reference, ahead as usize);
                    prefetch(node_body, ahead as usize);
                }
                *slot = (reference[k as usize], node_body[k as usize]);
            }
        });
}

/// The binned nodes of a build, as the scan reads them.
#[derive(Clone, Copy)]
struct GridView<'a> {
    frame: Frame,
    layout: Layout,
    table: &'a CellTable,
    cell_start: &'a [u32],
    cell_nodes: &'a [u32],
    /// The nodes' positions and bodies, in the order of `cell_nodes`.
    cell_payload: &'a [([f64; 3], u32)],
}

/// Buffers one piece of the scan keeps from face to face.
#[derive(Default)]
struct SegmentScratch {
    runs: Vec<std::ops::Range<usize>>,
    /// Per face, the grid slots of the nodes in its box.
    inside: Vec<usize>,
    /// The grid slots and positions of the other bodies' nodes in a run's union box.
    foreign: Vec<usize>,
    foreign_x: Vec<[f64; 3]>,
    /// Those of them in the union of the current group of faces' boxes.
    near: Vec<usize>,
    near_x: Vec<[f64; 3]>,
}

impl SegmentScratch {
    /// Keeps, of the foreign nodes (found by [`GridView::foreign_nodes`]), those in the
    /// union of the triangle boxes `boxes` (a group of the run's faces) grown by `e` as the
    /// near nodes, in their order.
    fn gather_near(&mut self, boxes: &[[f64; 6]], e: f64) {
        let union = grow(&union_of(boxes), e);
        let n = self.foreign.len();
        self.near.resize(n, 0);
        self.near_x.resize(n, [0.0; 3]);
        // Without a branch per node (in or out at random).
        let mut m = 0;
        for (&i, &x) in self.foreign.iter().zip(&self.foreign_x) {
            self.near[m] = i;
            self.near_x[m] = x;
            m += usize::from(in_box(&union, x));
        }
        self.near.truncate(m);
        self.near_x.truncate(m);
    }

    /// The slots of the near nodes (of [`SegmentScratch::gather_near`]) in box `bx`.
    #[inline]
    fn in_box_of_near(&mut self, bx: &[f64; 6]) -> &[usize] {
        let (near, inside) = (&self.near, &mut self.inside);
        if inside.len() < near.len() {
            inside.resize(near.len(), 0);
        }
        let mut n = 0;
        for (&i, &x) in near.iter().zip(&self.near_x) {
            inside[n] = i;
            n += usize::from(in_box(bx, x));
        }
        &inside[..n]
    }
}

/// The smallest box holding `boxes` ([`EMPTY_BOX`] for none). Growing it by `e` gives the
/// union of the grown boxes, bit for bit: a rounded difference never decreases with its
/// first term.
fn union_of(boxes: &[[f64; 6]]) -> [f64; 6] {
    boxes.iter().fold(EMPTY_BOX, enclose)
}

impl GridView<'_> {
    /// The number of cells a box overlaps (those within the grid in a dense layout).
    fn cells_within(&self, bx: &[f64; 6]) -> usize {
        let (lo, hi) = self.frame.cell_range(self.layout, bx);
        (0..3)
            .map(|d| usize::try_from(hi[d].saturating_sub(lo[d]).saturating_add(1)).unwrap_or(0))
            .fold(1, usize::saturating_mul)
    }

    /// The slots of the nodes of bodies other than `owner` in box `bx` (one query of the
    /// grid), in `inside`.
    #[inline]
    fn in_box<'s>(
        &self,
        bx: &[f64; 6],
        owner: u32,
        (runs, inside): (&mut Vec<std::ops::Range<usize>>, &'s mut Vec<usize>),
    ) -> &'s [usize] {
        runs.clear();
        self.frame
            .runs_within((self.layout, self.table, self.cell_start), bx, runs);
        let total = runs.iter().map(|r| r.len()).sum::<usize>();
        if inside.len() < total {
            inside.resize(total, 0);
        }
        // Without a branch per node (in or out at random).
        let mut n = 0;
        for run in runs.iter() {
            for (i, &(x, body)) in self.cell_payload[run.clone()].iter().enumerate() {
                inside[n] = run.start + i;
                n += usize::from((body != owner) & in_box(bx, x));
            }
        }
        &inside[..n]
    }

    /// Finds the nodes of bodies other than `owner` in the union of `boxes` (the triangle
    /// boxes of a run of the owner's faces) grown by `e` into `scratch.foreign`, when the
    /// union's cells and those nodes are few enough that one query and a direct test per
    /// face is cheaper than a query per face; returns whether it did. Every node of another
    /// body in one of the grown boxes is in their union, so the faces' pairs are the same
    /// either way.
    fn foreign_nodes(
        &self,
        (boxes, e, owner): (&[[f64; 6]], f64, u32),
        policy: SegmentPolicy,
        scratch: &mut SegmentScratch,
    ) -> bool {
        let union = grow(&union_of(boxes), e);
        if self.cells_within(&union) > policy.cells_per_face.saturating_mul(boxes.len()) {
            return false;
        }
        let found = self.in_box(&union, owner, (&mut scratch.runs, &mut scratch.foreign));
        if found.len() > policy.max_foreign {
            return false;
        }
        let n = found.len();
        scratch.foreign.truncate(n);
        scratch.foreign_x.clear();
        scratch
            .foreign_x
            .extend(scratch.foreign.iter().map(|&i| self.cell_payload[i].0));
        true
    }
}

impl BroadPhase {
    /// An empty broad phase for `surface` (no build yet).
    pub(crate) fn for_surface(surface: &ContactSurface) -> BroadPhase {
        BroadPhase {
            bodies: BodyIndex::of(surface),
            ..BroadPhase::default()
        }
    }

    /// The reaches of the last build's lists.
    pub(crate) fn reaches(&self) -> Reaches {
        Reaches {
            enlargement: self.enlargement,
            front: self.front,
            sheet: self.sheet_enlargement,
        }
    }

    /// The number of bodies of the surface.
    pub(crate) fn n_bodies(&self) -> usize {
        self.bodies.bodies()
    }

    /// Rebuilds grid and candidates from the current positions; positions must be finite
    /// (the model checks them first).
    ///
    /// A pair (node, face of another body) is a candidate when the node is within
    /// `skin + depth_limit` of the face (plus the tolerance band) and either behind the
    /// face's plane, or within [`FRONT_SKINS`] skins of the face (plus the band); or, when
    /// the face's body is `two_sided` (a sheet, whose closest point needs the faces in
    /// front as well), within `skin + sheet_depth` of the face (plus the band) in any
    /// direction. `sheet_depth` (at most the depth limit) is the sheets' listing depth,
    /// `crate::sheet::Sheets::listing_depth`.
    ///
    /// With `frames` (in use at these positions), the pairs with the framed bodies' faces
    /// and nodes are found body by body ([`framed`]), the same pairs as the grid scan's:
    /// the grid holds only the other bodies' nodes.
    pub(crate) fn build(
        &mut self,
        positions: &[[f64; 3]],
        surface: &ContactSurface,
        (skin, depth_limit, sheet_depth): (f64, f64, f64),
        frames: Option<&RigidFrames>,
        two_sided: impl Fn(u32) -> bool + Sync,
    ) {
        let reach = skin + depth_limit;
        self.window = WindowReach::of_build(skin, depth_limit);
        self.reference.clear();
        self.reference
            .par_extend(surface.surface_nodes.par_iter().map(|&g| positions[g]));
        let e = self.size_boxes(positions, surface, reach);
        // The reach in front of a face's plane: see FRONT_SKINS.
        self.front = FRONT_SKINS * skin + (e - reach);
        self.sheet_enlargement = skin + sheet_depth.min(depth_limit) + (e - reach);
        let framed_body = |body: u32| frames.is_some_and(|f| f.has(body));
        let spheres = frames.map(|f| {
            let at = framed::NodeAt {
                positions: &self.reference,
                ids: None,
            };
            let nodes = (at, &self.bodies);
            framed::SphereGrid::of(nodes, f, &mut self.bins, e)
        });
        let frame = self.bin_nodes(&surface.node_body, framed_body);
        // The faces the grid scan visits: all, or those without a frame.
        let pieces: Vec<std::ops::Range<usize>> = match frames {
            Some(f) => f.unframed_faces().to_vec(),
            None => {
                let n = surface.triangles.len();
                (0..n.div_ceil(TRIANGLE_CHUNK))
                    .map(|c| c * TRIANGLE_CHUNK..((c + 1) * TRIANGLE_CHUNK).min(n))
                    .collect()
            }
        };
        self.scan_triangles(
            frame,
            (positions, surface),
            (&pieces, spheres.as_ref()),
            &two_sided,
        );
        if let (Some(frames), Some(spheres)) = (frames, &spheres) {
            let input = framed::ScanInput {
                nodes: framed::NodeAt {
                    positions: &self.reference,
                    ids: None,
                },
                positions,
                surface,
                bodies: &self.bodies,
                reaches: self.reaches(),
                window: self.window,
            };
            let pairs = framed::framed_pairs(&input, frames, (spheres, &self.bins), &two_sided);
            self.found.extend(pairs);
        }
        self.place_pairs(surface);
        self.pairs = self.chunk_cands.iter().map(Vec::len).sum();
        self.built = true;
        self.builds += 1;
        self.refreshed_nodes = 0;
    }

    /// Sizes the triangle boxes at `positions`: sets the enlargement (`reach` plus the
    /// tolerance band), by which the scan grows each box where it reads it, and the cell
    /// size, and returns the enlargement. The boxes themselves are not kept: the scan makes
    /// them again chunk by chunk, where they stay in cache.
    fn size_boxes(&mut self, positions: &[[f64; 3]], surface: &ContactSurface, reach: f64) -> f64 {
        // Per fixed run of triangles the largest extent and the sum of the extents (added in
        // run order below: the same cell size for every thread count).
        let runs: Vec<(f64, f64)> = surface
            .triangles
            .par_chunks(TRIANGLE_CHUNK)
            .map(|triangles| {
                let (mut largest, mut sum) = (0.0_f64, 0.0_f64);
                for tri in triangles {
                    let bx = face_box(tri.map(|i| positions[i]));
                    let mut extent = 0.0_f64;
                    for d in 0..3 {
                        extent = upper(extent, bx[d + 3] - bx[d]);
                    }
                    largest = upper(largest, extent);
                    sum += extent;
                }
                (largest, sum)
            })
            .collect();
        let largest = runs.iter().fold(0.0_f64, |l, r| l.max(r.0));
        let sum: f64 = runs.iter().map(|r| r.1).sum();
        // margin + depth limit: both the node and the face may move margin/2 before the next
        // build, and the node may sit up to the depth limit behind the face; the tolerance
        // band lets a foot fall slightly outside the triangle.
        let e = reach + 2.0 * BARYCENTRIC_TOLERANCE * largest;
        self.enlargement = e;
        // Three quarters of the mean enlarged box: a box overlaps two or three cells per
        // axis (two or three rows of cells per layer, each one run of nodes for the scan),
        // each with a few nodes; an eighth of the largest bounds the cells a large face
        // visits. The size only sets the work: the scan's own tests decide the lists.
        let mean = sum / surface.triangles.len().max(1) as f64;
        self.cell_size = (CELL_PER_MEAN_BOX * (mean + 2.0 * e)).max((largest + 2.0 * e) / 8.0);
        e
    }

    /// Bins the surface nodes (their reference positions) of the bodies not `skipped` into
    /// the grid: numbers the cells (rows along [`BroadPhase::row_axis`] unless `rows` names
    /// an axis), dense when the nodes' region holds at most [`DENSE_CELLS_PER_NODE`] cells
    /// per node, else through the hash table, and sorts the nodes by cell (a counting sort,
    /// increasing node order within a cell, [`cell_sort`]). Returns the grid's frame.
    fn bin_nodes(&mut self, node_body: &[u32], skipped: impl Fn(u32) -> bool) -> Frame {
        // Without a branch per node.
        let n_all = self.reference.len();
        self.binned.resize(n_all, 0);
        let mut m = 0;
        for k in 0..n_all as u32 {
            self.binned[m] = k;
            m += usize::from(!skipped(node_body[k as usize]));
        }
        self.binned.truncate(m);
        let inv = 1.0 / self.cell_size;
        let mut b = bounds(&self.reference, &self.binned);
        if !b.iter().all(|o| o.is_finite()) {
            b = [0.0; 6];
        }
        let (origin, top) = ([b[0], b[1], b[2]], [b[3], b[4], b[5]]);
        let first = match self.rows {
            RowAxis::Advance => self.row_axis(&skipped),
            RowAxis::Along(axis) => axis,
        };
        let axes = match first {
            0 => [0, 1, 2],
            1 => [1, 0, 2],
            _ => [2, 0, 1],
        };
        let frame = Frame { origin, inv, axes };
        let dims = frame.cell(top).map(|e| e.saturating_add(1).max(1));
        let n = self.binned.len();
        let budget = (DENSE_CELLS_PER_NODE * n).max(DENSE_MIN_CELLS);
        let cells = dims
            .iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(usize::try_from(d).ok()?));
        self.layout = match cells {
            Some(c) if c <= budget => Layout::Dense { dims },
            _ => Layout::Hash,
        };
        // Number every binned node's cell (a node always lies in the grid: its own cell).
        self.node_cells.clear();
        let (reference, binned) = (&self.reference, &self.binned);
        match self.layout {
            Layout::Dense { dims } => {
                self.node_cells.par_extend(binned.par_iter().map(|&k| {
                    let c = frame.cell(reference[k as usize]);
                    let within = (0..3).all(|d| c[d] >= 0 && c[d] < dims[d]);
                    if within {
                        dense_index(dims, c) as u32
                    } else {
                        0
                    }
                }));
            }
            Layout::Hash => {
                let table = &mut self.table;
                table.reset(n);
                let positions = binned.iter().map(|&k| reference[k as usize]);
                self.node_cells.extend(positions.map(|x| {
                    let [i, j, k] = frame.cell(x);
                    table.insert(pack(i, j, k))
                }));
            }
        }
        let n_cells = match self.layout {
            Layout::Dense { .. } => cells.unwrap_or(0),
            Layout::Hash => self.table.len,
        };
        // Counting sort: row starts, then the nodes in increasing order into their rows.
        self.by_cell.sort(&self.binned, &self.node_cells, n_cells);
        // Positions and bodies in the same order, side by side, so the scan reads a cell's
        // nodes sequentially.
        let nodes = (&self.reference[..], node_body);
        gather_payload(nodes, &self.by_cell.nodes, &mut self.cell_payload);
        frame
    }

    /// The axis the grid numbers its cells along first (its rows): the one along which the
    /// scan moves most from one body to the next, so that consecutive queries read rows
    /// that continue each other in memory. The move is summed over consecutive bodies with
    /// faces and binned nodes (not `skipped`), between their first nodes' reference
    /// positions. Ties go to the first axis; the choice sets only the work.
    fn row_axis(&self, skipped: impl Fn(u32) -> bool) -> usize {
        let mut advance = [0.0_f64; 3];
        let mut last: Option<[f64; 3]> = None;
        for body in 0..self.bodies.bodies() {
            let (nodes, faces) = (self.bodies.nodes(body), self.bodies.triangles(body));
            let Some(&first) = nodes.first() else {
                continue;
            };
            if faces.is_empty() || skipped(body as u32) {
                continue;
            }
            let x = self.reference[first as usize];
            if let Some(p) = last {
                for d in 0..3 {
                    advance[d] += (x[d] - p[d]).abs();
                }
            }
            last = Some(x);
        }
        (1..3).fold(
            0,
            |best, d| if advance[d] > advance[best] { d } else { best },
        )
    }

    /// The scan, parallel over `pieces` (fixed runs of triangles): every triangle visits the
    /// cells its enlarged box overlaps and keeps the nodes of other bodies there whose
    /// position lies in the box and that pass [`is_candidate`], and with `spheres` the
    /// nodes of the framed bodies that meet the box (which the grid does not hold); each
    /// piece lists its pairs in triangle order. A run of consecutive faces of one body
    /// within a piece finds the other bodies' nodes in its boxes' union once when the
    /// policy allows ([`GridView::foreign_nodes`]); each group of [`FACES_PER_GROUP`] faces
    /// keeps those in its own union, and each face then tests the group's instead of
    /// visiting the cells; a face with no node to test is passed over.
    ///
    /// A node farther than the enlargement from the triangle itself cannot reach it
    /// before the next build (every point of the face moves at most half the skin, as
    /// the node does): the box only finds the cells, the distance decides. A node in
    /// front of the face's plane must first cross the face or the sides of the prism
    /// behind it; see FRONT_SKINS. A node behind the plane must be able to reach the
    /// face's window ([`window`]); the reach depends on the face's shape, so it is
    /// computed once per triangle, when a node behind the face first needs it.
    fn scan_triangles(
        &mut self,
        frame: Frame,
        (positions, surface): (&[[f64; 3]], &ContactSurface),
        (pieces, spheres): (&[std::ops::Range<usize>], Option<&framed::SphereGrid>),
        two_sided: &(impl Fn(u32) -> bool + Sync),
    ) {
        self.found.reset(surface.surface_nodes.len(), pieces.len());
        let parts = self.found.parts();
        let reaches = self.reaches();
        let window = self.window;
        let (policy, e) = (self.segments, self.enlargement);
        let bodies = &self.bodies;
        let at = framed::NodeAt {
            positions: &self.reference,
            ids: None,
        };
        let grid = GridView {
            frame,
            layout: self.layout,
            table: &self.table,
            cell_start: &self.by_cell.start,
            cell_nodes: &self.by_cell.nodes,
            cell_payload: &self.cell_payload,
        };
        self.found
            .pieces_mut()
            .enumerate()
            .for_each(|(chunk, lists)| {
                // The pairs by the part of their node, and the framed bodies' pairs.
                let (split, mixed) = lists.split_at_mut(parts.count);
                let mut scratch = Default::default();
                let mut local = SegmentScratch::default();
                let triangles = pieces[chunk].clone();
                // The piece's raw boxes, indexed from its first triangle.
                let boxes: Vec<[f64; 6]> = surface.triangles[triangles.clone()]
                    .iter()
                    .map(|tri| face_box(tri.map(|i| positions[i])))
                    .collect();
                let first = triangles.start;
                let mut t = triangles.start;
                while t < triangles.end {
                    // A run of faces of one body: the nodes of other bodies near all of
                    // them are found once, when that is cheaper than a query per face.
                    let owner = surface.triangle_body[t];
                    let end = (t..triangles.end)
                        .find(|&u| surface.triangle_body[u] != owner)
                        .unwrap_or(triangles.end);
                    let run = (&boxes[t - first..end - first], e, owner);
                    let foreign = grid.foreign_nodes(run, policy, &mut local);
                    let reach = reaches.of_face(two_sided(owner));
                    let run_start = t;
                    for (t, raw) in (t..end).zip(&boxes[t - first..end - first]) {
                        let bx = &grow(raw, e);
                        let inside = if foreign {
                            // Each group of faces first keeps the foreign nodes near it.
                            if (t - run_start) % FACES_PER_GROUP == 0 {
                                let group =
                                    &boxes[t - first..(t + FACES_PER_GROUP).min(end) - first];
                                local.gather_near(group, e);
                            }
                            local.in_box_of_near(bx)
                        } else {
                            grid.in_box(bx, owner, (&mut local.runs, &mut local.inside))
                        };
                        if inside.is_empty() && spheres.is_none() {
                            continue;
                        }
                        let ids = surface.triangles[t];
                        let face = ids.map(|i| positions[i]);
                        let mut face_window = window.of_face_lazily(face);
                        let candidate = Candidate {
                            // Node ids fit in u32: ContactSurface::validate checks the count.
                            nodes: ids.map(|i| i as u32),
                            triangle: t as u32,
                            body: owner,
                        };
                        let mut test = |x| is_candidate(x, face, reach, &mut face_window);
                        // The framed bodies' nodes, which the grid does not hold.
                        if let Some(spheres) = spheres {
                            let mut test = |x| in_box(bx, x) && test(x);
                            let nodes = (at, bodies);
                            let face = (bx, candidate);
                            let pairs = &mut mixed[0];
                            spheres.pairs_of_face(face, nodes, &mut test, &mut scratch, pairs);
                        }
                        for &i in inside {
                            if test(grid.cell_payload[i].0) {
                                let node = grid.cell_nodes[i];
                                split[parts.of(node)].push((node, candidate));
                            }
                        }
                    }
                    t = end;
                }
            });
    }

    /// Places the pairs into the nodes' lists (compressed rows per chunk of [`CHUNK`]
    /// nodes): counts per node, row starts, then the pairs; a list that is not then
    /// sorted by (owner body, triangle) is sorted so. In parallel over the parts of the
    /// chunks the scan split its pairs by ([`found`]), each reading its own pairs and the
    /// mixed ones: every list is the same for every thread count.
    fn place_pairs(&mut self, surface: &ContactSurface) {
        let n_surface = surface.surface_nodes.len();
        let n_chunks = n_surface.div_ceil(CHUNK);
        self.chunk_cands.resize_with(n_chunks, Vec::new);
        self.chunk_cands.truncate(n_chunks);
        self.chunk_starts.resize_with(n_chunks, Vec::new);
        self.chunk_starts.truncate(n_chunks);
        self.cursor.clear();
        self.cursor.resize(n_surface, 0);
        let found = &self.found;
        let part_len = found.parts().len;
        let chunks_per_part = part_len / CHUNK;
        self.chunk_cands
            .par_chunks_mut(chunks_per_part)
            .zip(self.chunk_starts.par_chunks_mut(chunks_per_part))
            .zip(self.cursor.par_chunks_mut(part_len))
            .enumerate()
            .for_each(|(part, ((cands, starts), cursor))| {
                found.place_part(part, cursor, (cands, starts));
            });
    }

    /// Candidate faces of surface node `k`.
    #[inline]
    pub(crate) fn candidates(&self, k: usize) -> &[Candidate] {
        self.chunk_lists(k / CHUNK).of(k % CHUNK)
    }

    /// The candidate lists of the surface nodes of chunk `chunk` (`chunk * CHUNK ..`).
    #[inline]
    pub(crate) fn chunk_lists(&self, chunk: usize) -> ChunkLists<'_> {
        ChunkLists {
            starts: &self.chunk_starts[chunk],
            cands: &self.chunk_cands[chunk],
        }
    }
}

/// The candidate lists of one chunk of surface nodes ([`BroadPhase::chunk_lists`]): a pass
/// over the chunk's nodes reads them without looking the chunk up per node.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ChunkLists<'a> {
    starts: &'a [usize],
    cands: &'a [Candidate],
}

impl<'a> ChunkLists<'a> {
    /// Candidate faces of the chunk's `i`-th surface node.
    #[inline(always)]
    pub(crate) fn of(&self, i: usize) -> &'a [Candidate] {
        &self.cands[self.starts[i]..self.starts[i + 1]]
    }
}

#[cfg(test)]
mod tests {
    use super::{BroadPhase, RowAxis, SegmentPolicy, floor_to_i64};
    use crate::ContactSurface;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    impl SegmentPolicy {
        const NEVER: SegmentPolicy = SegmentPolicy {
            cells_per_face: 0,
            max_foreign: 0,
        };
        const ALWAYS: SegmentPolicy = SegmentPolicy {
            cells_per_face: usize::MAX,
            max_foreign: usize::MAX,
        };
    }

    /// A large sphere (level 2, diameter 4) among 40 small ones (level 1, diameter 1) at
    /// random, overlapping or near each other: runs of faces of both sizes, and runs cut
    /// by the scan's fixed pieces of triangles.
    fn cluster() -> (ContactSurface, Vec<[f64; 3]>) {
        use fdem_mesh::{ElementOrder, MeshAssembly, Placement, Sizing, SphereSpec};
        let sphere = |level, diameter| {
            let spec = SphereSpec {
                level,
                order: ElementOrder::Linear,
                diameter,
                sizing: Sizing::Inscribed,
            };
            fdem_mesh::sphere_mesh(&spec).expect("a valid sphere")
        };
        let (large, small) = (sphere(2, 4.0), sphere(1, 1.0));
        let mut rng = Pcg64::seed_from_u64(5);
        let mut assembly = MeshAssembly::new();
        assembly
            .push_instance(&large, &Placement::default())
            .expect("the large sphere");
        for _ in 0..40 {
            let at = [0, 1, 2].map(|_| rng.random_range(-3.0..3.0));
            assembly
                .push_instance(&small, &Placement::at(at))
                .expect("a small sphere");
        }
        let surface = ContactSurface::from_assembly(&assembly).expect("a surface");
        (surface, assembly.nodes)
    }

    /// The lists are the same whether a run of one body's faces queries the grid once or
    /// each face queries it, under the default choice between the two, for solid faces
    /// and for a sheet's.
    #[test]
    fn one_query_per_run_of_faces_gives_the_lists_of_one_query_per_face() {
        let (surface, positions) = cluster();
        for sheet in [None, Some(0)] {
            let lists = |segments| {
                let mut broad = BroadPhase::for_surface(&surface);
                broad.segments = segments;
                let reaches = (0.05, 0.1, 0.08);
                broad.build(&positions, &surface, reaches, None, |b| Some(b) == sheet);
                (broad.pairs, broad.chunk_starts, broad.chunk_cands)
            };
            let each_face = lists(SegmentPolicy::NEVER);
            assert!(each_face.0 > 1000, "{} pairs", each_face.0);
            assert_eq!(lists(SegmentPolicy::ALWAYS), each_face);
            assert_eq!(lists(SegmentPolicy::DEFAULT), each_face);
        }
    }

    /// The lists are the same whichever axis the grid's rows follow, and the default
    /// follows the axis along which the bodies lie one after the other.
    #[test]
    fn the_lists_are_the_same_along_every_row_axis() {
        // The cluster stretched along y, so that the grid's sides differ.
        let (surface, positions) = cluster();
        let positions: Vec<[f64; 3]> = positions.iter().map(|x| [x[0], 3.0 * x[1], x[2]]).collect();
        let lists = |rows| {
            let mut broad = BroadPhase::for_surface(&surface);
            broad.rows = rows;
            broad.build(&positions, &surface, (0.05, 0.1, 0.08), None, |_| false);
            (broad.pairs, broad.chunk_starts, broad.chunk_cands)
        };
        let along_x = lists(RowAxis::Along(0));
        assert!(along_x.0 > 500, "{} pairs", along_x.0);
        for rows in [RowAxis::Along(1), RowAxis::Along(2), RowAxis::Advance] {
            assert_eq!(lists(rows), along_x, "{rows:?}");
        }
        // Bodies in a row along y, each a corner of one face: the rows follow y.
        let line = ContactSurface {
            triangles: (0..4).map(|b| [3 * b, 3 * b + 1, 3 * b + 2]).collect(),
            triangle_body: (0..4).collect(),
            surface_nodes: (0..12).collect(),
            node_body: (0..12).map(|k| k as u32 / 3).collect(),
            control_areas: vec![1e-4; 12],
        };
        let corners = [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.0, 0.1]];
        let at: Vec<[f64; 3]> = (0..4)
            .flat_map(|b| corners.map(|c| [c[0] + 0.01 * b as f64, c[1] + b as f64, c[2]]))
            .collect();
        let mut broad = BroadPhase::for_surface(&line);
        broad.reference = at;
        assert_eq!(broad.row_axis(|_| false), 1);
        assert_eq!(broad.row_axis(|b| b % 2 == 1), 1);
    }

    /// The lists are the same for every thread count: the scan's pieces are fixed, and the
    /// pairs are placed by parts of the node chunks, one per thread, each keeping the
    /// pairs' order.
    #[test]
    fn the_lists_are_the_same_for_every_thread_count() {
        let (surface, positions) = cluster();
        let chunks = surface.surface_nodes.len().div_ceil(super::CHUNK);
        assert!(chunks >= 4, "{chunks} chunks: too few for parts");
        let lists = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a pool");
            pool.install(|| {
                let mut broad = BroadPhase::for_surface(&surface);
                broad.build(&positions, &surface, (0.05, 0.1, 0.08), None, |_| false);
                (broad.pairs, broad.chunk_starts, broad.chunk_cands)
            })
        };
        let serial = lists(1);
        assert!(serial.0 > 1000, "{} pairs", serial.0);
        for threads in [2, 3, 4] {
            assert_eq!(lists(threads), serial, "{threads} threads");
        }
    }

    /// A box as wide as the numbers allow counts as many cells as a `usize` holds, in
    /// either layout, without overflowing on the way (the choice of scan then queries
    /// face by face).
    #[test]
    fn the_cells_of_a_huge_box_saturate() {
        let frame = super::Frame {
            origin: [0.0; 3],
            inv: 1.0,
            axes: [0, 1, 2],
        };
        let table = super::CellTable::default();
        let huge = [-1e300, -1e300, -1e300, 1e300, 1e300, 1e300];
        let dims = [4, 5, 6];
        for (layout, cells) in [
            (super::Layout::Hash, usize::MAX),
            (super::Layout::Dense { dims }, 4 * 5 * 6),
        ] {
            let grid = super::GridView {
                frame,
                layout,
                table: &table,
                cell_start: &[],
                cell_nodes: &[],
                cell_payload: &[],
            };
            assert_eq!(grid.cells_within(&huge), cells, "{layout:?}");
            assert_eq!(grid.cells_within(&[0.5, 0.5, 0.5, 1.5, 2.5, 0.5]), 6);
        }
    }

    /// The branch-free floor agrees with the library's `floor` followed by the same
    /// saturating conversion, at the edges and on random values of every magnitude.
    #[test]
    fn floor_to_i64_is_the_floor() {
        let edges = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1.0 - f64::EPSILON,
            -1e-300,
            2.0_f64.powi(52) + 0.5,
            -(2.0_f64.powi(52) + 0.5),
            2.0_f64.powi(63),
            -(2.0_f64.powi(63)),
            -(2.0_f64.powi(63)) - 4096.0,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        let mut r = Pcg64::seed_from_u64(3);
        let random = (0..100_000).map(|_| {
            let exponent = r.random_range(-20.0..70.0);
            let sign = if r.random_range(0.0..1.0) < 0.5 {
                -1.0
            } else {
                1.0
            };
            sign * 2.0_f64.powf(exponent) * r.random_range(1.0..2.0)
        });
        for v in edges.into_iter().chain(random) {
            assert_eq!(floor_to_i64(v), v.floor() as i64, "{v:e}");
        }
    }
}
