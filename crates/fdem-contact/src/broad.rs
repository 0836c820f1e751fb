//! Broad phase: a spatial hash over the surface triangles with a Verlet skin.
//!
//! Every triangle's bounding box, enlarged by `margin + depth limit` (plus the barycentric tolerance
//! band), is registered in every cell of a uniform grid it overlaps; the cell size is the
//! largest enlarged box extent, so a box overlaps at most 2 cells per axis. Cells are
//! numbered densely (`i + nx (j + ny k)`) when the occupied region holds at most 4 cells
//! per triangle, and otherwise through their packed integer coordinates in a deterministic
//! open-addressing table (fixed hash function, slots numbered in insertion order); their
//! triangles are stored as compressed rows, so a build costs O(triangles + surface
//! nodes). A surface node's candidates are the triangles of other bodies listed in its
//! own cell whose enlarged box contains it and that lie within the enlargement of it (the
//! point-triangle distance; the box's corners hold many pairs farther than that), sorted
//! by (owner body, triangle).
//!
//! Verlet skin: while every surface node stays within `margin / 2` of its position at the
//! last build, a node and a triangle that were not candidates were more than `margin +
//! depth limit` apart and still are more than the depth limit apart (each moved less than
//! `margin / 2`), so no contact within the depth limit can be missed. The model rebuilds
//! as soon as one node has moved farther.

use rayon::prelude::*;

use crate::ContactSurface;
use crate::narrow::{BARYCENTRIC_TOLERANCE, distance2_to_triangle};

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
    /// Global node ids of the face.
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
    /// Number of builds so far.
    pub(crate) builds: usize,
    /// Enlargement of the triangle boxes at the last build (m).
    pub(crate) enlargement: f64,
    /// Reach in front of a face's plane at the last build (m), see [`FRONT_SKINS`].
    pub(crate) front: f64,
    /// Cell size at the last build (m).
    pub(crate) cell_size: f64,
    /// Surface node positions at the last build.
    pub(crate) reference: Vec<[f64; 3]>,
    /// Candidate faces per chunk of [`CHUNK`] surface nodes, sorted by (owner body,
    /// triangle) per node: the query writes each chunk's list in parallel and the narrow
    /// phase reads it in place (no serial gather into one array).
    chunk_cands: Vec<Vec<Candidate>>,
    /// Per chunk, the row starts of its nodes in `chunk_cands` (one more than its nodes).
    chunk_starts: Vec<Vec<usize>>,
    /// Number of candidate pairs of the last build.
    pub(crate) pairs: usize,
    boxes: Vec<[f64; 6]>,
    /// Per surface node, its cell at the last build ([`NO_CELL`] when not listed).
    node_cells: Vec<u32>,
    /// Counting-sort cursor of [`BroadPhase::order_nodes_by_cell`].
    node_cursor: Vec<u32>,
    /// The surface nodes in listed cells, ordered by cell: the query's order of visits.
    order: Vec<u32>,
    /// The query's work items (fixed runs of [`CHUNK`] nodes of `order`).
    items: Vec<QueryItem>,
    /// Per surface node, `[item, start, length]` of its list in `items`.
    located: Vec<[u32; 3]>,
    layout: Layout,
    table: CellTable,
    cell_start: Vec<usize>,
    cell_cursor: Vec<usize>,
    cell_tris: Vec<u32>,
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

/// Dense layouts are used up to this many cells per triangle (and at least this floor).
const DENSE_CELLS_PER_TRIANGLE: usize = 4;
const DENSE_MIN_CELLS: usize = 1 << 12;

/// The cell number of integer cell coordinates, `None` for an empty cell.
#[inline(always)]
fn lookup(layout: Layout, table: &CellTable, c: [i64; 3]) -> Option<usize> {
    match layout {
        Layout::Dense { dims } => {
            if (0..3).all(|d| c[d] >= 0 && c[d] < dims[d]) {
                Some((c[0] + dims[0] * (c[1] + dims[1] * c[2])) as usize)
            } else {
                None
            }
        }
        Layout::Hash => table.get(pack(c[0], c[1], c[2])).map(|v| v as usize),
    }
}

/// Where the grid lies: the corner of cell `[0, 0, 0]` and the inverse cell size.
#[derive(Clone, Copy, Debug)]
struct Frame {
    origin: [f64; 3],
    inv: f64,
}

impl Frame {
    /// Integer coordinates of the cell that holds `x`.
    #[inline(always)]
    fn cell(self, x: [f64; 3]) -> [i64; 3] {
        let (origin, inv) = (self.origin, self.inv);
        [
            ((x[0] - origin[0]) * inv).floor() as i64,
            ((x[1] - origin[1]) * inv).floor() as i64,
            ((x[2] - origin[2]) * inv).floor() as i64,
        ]
    }

    /// Calls `f` with the coordinates of every cell a box overlaps, `x` fastest.
    #[inline(always)]
    fn for_each_cell(self, bx: &[f64; 6], mut f: impl FnMut([i64; 3])) {
        let lo = self.cell([bx[0], bx[1], bx[2]]);
        let hi = self.cell([bx[3], bx[4], bx[5]]);
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    f([i, j, k]);
                }
            }
        }
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

/// The candidate test of node `x` against a face of another body: within `reach2`
/// (squared) of the face, and either behind its plane (strictly; outward normal by the
/// right-hand rule of its corners), or `two_sided`, or within `front2` (squared) of it.
///
/// The plane distance is a lower bound of the distance to the face, so a pair whose plane
/// distance exceeds its reach (beyond [`PLANE_PREFILTER_SLACK`]) is skipped before the
/// point-triangle distance; most faces near a node are in front of it, beyond the front
/// reach, and are skipped this way.
#[inline(always)]
fn is_candidate(
    x: [f64; 3],
    face: [[f64; 3]; 3],
    reach2: f64,
    front2: f64,
    two_sided: bool,
) -> bool {
    use crate::vec3::{cross, dot, norm2, sub};
    let [a, b, c] = face;
    let n = cross(sub(b, a), sub(c, a));
    let s = dot(n, sub(x, a));
    let behind = s < 0.0;
    let limit2 = if behind || two_sided {
        reach2
    } else {
        front2.min(reach2)
    };
    if s * s > limit2 * norm2(n) * (1.0 + PLANE_PREFILTER_SLACK) {
        return false;
    }
    let d2 = distance2_to_triangle(x, face);
    d2 <= reach2 && (d2 <= front2 || two_sided || behind)
}

#[inline(always)]
fn in_box(b: &[f64; 6], x: [f64; 3]) -> bool {
    x[0] >= b[0] && x[1] >= b[1] && x[2] >= b[2] && x[0] <= b[3] && x[1] <= b[4] && x[2] <= b[5]
}

/// A node's cell is not listed (no triangle's box reaches it).
const NO_CELL: u32 = u32::MAX;

/// What one work item of the query wrote: the candidates of the nodes it visited, and per
/// visited node `[node, start, length]` of its list.
#[derive(Clone, Debug, Default)]
struct QueryItem {
    cands: Vec<Candidate>,
    rows: Vec<[u32; 3]>,
}

/// The grid and the reaches of one query: the candidate test of a node against the
/// triangles listed in its cell.
struct CellTest<'a> {
    reference: &'a [[f64; 3]],
    boxes: &'a [[f64; 6]],
    cell_start: &'a [usize],
    cell_tris: &'a [u32],
    reach2: f64,
    front2: f64,
}

impl CellTest<'_> {
    /// Appends to `out` the candidate faces of surface node `k` (in cell `cell`) sorted by
    /// (owner body, triangle): the triangles of other bodies listed in the cell whose
    /// enlarged box holds the node and that pass [`is_candidate`].
    ///
    /// A node farther than the enlargement from the triangle itself cannot reach it
    /// before the next build (every point of the face moves at most half the skin, as
    /// the node does): the box only finds the cell, the distance decides. A node in
    /// front of the face's plane must first cross the face or the sides of the prism
    /// behind it; see FRONT_SKINS.
    #[inline]
    fn node_candidates(
        &self,
        k: usize,
        cell: u32,
        positions: &[[f64; 3]],
        surface: &ContactSurface,
        two_sided: &impl Fn(u32) -> bool,
        out: &mut Vec<Candidate>,
    ) {
        let x = self.reference[k];
        let body = surface.node_body[k];
        let before = out.len();
        let cell = cell as usize;
        for &t in &self.cell_tris[self.cell_start[cell]..self.cell_start[cell + 1]] {
            let tu = t as usize;
            let owner = surface.triangle_body[tu];
            if owner == body || !in_box(&self.boxes[tu], x) {
                continue;
            }
            let face = surface.triangles[tu].map(|i| positions[i]);
            if is_candidate(x, face, self.reach2, self.front2, two_sided(owner)) {
                out.push(Candidate {
                    // Node ids fit in u32: ContactSurface::validate checks the node count.
                    nodes: surface.triangles[tu].map(|i| i as u32),
                    triangle: t,
                    body: owner,
                });
            }
        }
        let mine = &mut out[before..];
        if !mine.is_sorted_by_key(|c| c.body) {
            mine.sort_unstable_by_key(|c| (c.body, c.triangle));
        }
    }
}

impl BroadPhase {
    /// Rebuilds grid and candidates from the current positions; positions must be finite
    /// (the model checks them first).
    ///
    /// A pair (node, face of another body) is a candidate when the node is within
    /// `skin + depth_limit` of the face (plus the tolerance band) and either behind the
    /// face's plane, or within [`FRONT_SKINS`] skins of the face (plus the band), or the
    /// face's body is `two_sided` (sheets, whose edges also make contacts and whose edge
    /// filter looks at faces in front).
    pub(crate) fn build(
        &mut self,
        positions: &[[f64; 3]],
        surface: &ContactSurface,
        skin: f64,
        depth_limit: f64,
        two_sided: impl Fn(u32) -> bool + Sync,
    ) {
        let reach = skin + depth_limit;
        self.reference.clear();
        self.reference
            .extend(surface.surface_nodes.iter().map(|&g| positions[g]));
        let e = self.enlarged_boxes(positions, surface, reach);
        let (frame, cells) = self.choose_layout(surface.triangles.len());
        self.bin_triangles(frame, cells, surface.triangles.len());
        // The reach in front of a face's plane: see FRONT_SKINS.
        let front = FRONT_SKINS * skin + (e - reach);
        self.front = front;
        self.query(frame, positions, surface, two_sided);
        self.pairs = self.chunk_cands.iter().map(Vec::len).sum();
        self.built = true;
        self.builds += 1;
    }

    /// The triangle boxes at `positions`, enlarged by `reach` plus the tolerance band;
    /// sets the enlargement and the cell size, and returns the enlargement.
    fn enlarged_boxes(
        &mut self,
        positions: &[[f64; 3]],
        surface: &ContactSurface,
        reach: f64,
    ) -> f64 {
        // Raw triangle boxes and the largest extent.
        self.boxes.clear();
        let mut largest = 0.0_f64;
        for tri in &surface.triangles {
            let [a, b, c] = tri.map(|i| positions[i]);
            let mut bx = [0.0; 6];
            for d in 0..3 {
                bx[d] = a[d].min(b[d]).min(c[d]);
                bx[d + 3] = a[d].max(b[d]).max(c[d]);
                largest = largest.max(bx[d + 3] - bx[d]);
            }
            self.boxes.push(bx);
        }
        // margin + depth limit: both the node and the face may move margin/2 before the next
        // build, and the node may sit up to the depth limit behind the face; the tolerance
        // band lets a foot fall slightly outside the triangle.
        let e = reach + 2.0 * BARYCENTRIC_TOLERANCE * largest;
        self.enlargement = e;
        for bx in &mut self.boxes {
            for d in 0..3 {
                bx[d] -= e;
                bx[d + 3] += e;
            }
        }
        self.cell_size = largest + 2.0 * e;
        e
    }

    /// The grid's frame over the reference positions and the enlarged boxes, and the cell
    /// numbering: dense when the occupied region holds at most
    /// [`DENSE_CELLS_PER_TRIANGLE`] cells per triangle (then also its number of cells),
    /// else the hash table.
    fn choose_layout(&mut self, n_triangles: usize) -> (Frame, Option<usize>) {
        let inv = 1.0 / self.cell_size;
        let mut origin = [f64::INFINITY; 3];
        let mut top = [f64::NEG_INFINITY; 3];
        for x in &self.reference {
            for d in 0..3 {
                origin[d] = origin[d].min(x[d]);
                top[d] = top[d].max(x[d]);
            }
        }
        for bx in &self.boxes {
            for d in 0..3 {
                origin[d] = origin[d].min(bx[d]);
                top[d] = top[d].max(bx[d + 3]);
            }
        }
        if !origin.iter().chain(&top).all(|o| o.is_finite()) {
            origin = [0.0; 3];
            top = [0.0; 3];
        }
        let frame = Frame { origin, inv };
        let extent = frame.cell(top);
        let dims = extent.map(|e| e.saturating_add(1).max(1));
        let budget = (DENSE_CELLS_PER_TRIANGLE * n_triangles).max(DENSE_MIN_CELLS);
        let cells = dims
            .iter()
            .try_fold(1usize, |acc, &n| acc.checked_mul(usize::try_from(n).ok()?));
        self.layout = match cells {
            Some(n) if n <= budget => Layout::Dense { dims },
            _ => Layout::Hash,
        };
        (frame, cells)
    }

    /// Lists every triangle in the cells its enlarged box overlaps (compressed rows,
    /// triangles in increasing order within each cell); `cells` is the dense layout's
    /// number of cells.
    fn bin_triangles(&mut self, frame: Frame, cells: Option<usize>, n_triangles: usize) {
        // Count pass: number every overlapped cell, count its triangles.
        self.cell_start.clear();
        let counts = &mut self.cell_start;
        match self.layout {
            Layout::Dense { .. } => {
                counts.resize(cells.unwrap_or(0), 0);
                let (layout, table) = (self.layout, &self.table);
                for bx in &self.boxes {
                    frame.for_each_cell(bx, |c| {
                        if let Some(c) = lookup(layout, table, c) {
                            counts[c] += 1;
                        }
                    });
                }
            }
            Layout::Hash => {
                let table = &mut self.table;
                table.reset(n_triangles / 2);
                for bx in &self.boxes {
                    frame.for_each_cell(bx, |[i, j, k]| {
                        let c = table.insert(pack(i, j, k)) as usize;
                        if c == counts.len() {
                            counts.push(0);
                        }
                        counts[c] += 1;
                    });
                }
            }
        }
        // Prefix sums into row starts.
        let mut running = 0usize;
        for s in &mut self.cell_start {
            let count = *s;
            *s = running;
            running += count;
        }
        self.cell_start.push(running);
        self.cell_cursor.clear();
        self.cell_cursor.extend_from_slice(&self.cell_start);
        self.cell_tris.clear();
        self.cell_tris.resize(running, 0);
        // Fill pass, triangles in increasing order within each cell.
        let (layout, table) = (self.layout, &self.table);
        let (cursor, cell_tris) = (&mut self.cell_cursor, &mut self.cell_tris);
        for (t, bx) in self.boxes.iter().enumerate() {
            frame.for_each_cell(bx, |c| {
                if let Some(c) = lookup(layout, table, c) {
                    let slot = &mut cursor[c];
                    cell_tris[*slot] = t as u32;
                    *slot += 1;
                }
            });
        }
    }

    /// Query pass: the candidate faces of every surface node (sorted by owner body, then
    /// triangle), as rows per chunk of [`CHUNK`] nodes.
    ///
    /// The nodes are visited cell by cell ([`BroadPhase::order_nodes_by_cell`]), in fixed
    /// work items of [`CHUNK`] nodes run in parallel: consecutive nodes then read the same
    /// cell row, boxes and face nodes while they are in the cache (in node order, which
    /// jumps between bodies anywhere in the specimen, every node fetched its cell's data
    /// from memory). A serial pass notes where each node's list lies, and a parallel pass
    /// copies the lists into node order. Each node's list depends only on the node and its
    /// cell, so neither the order of visits nor the thread count changes it.
    fn query(
        &mut self,
        frame: Frame,
        positions: &[[f64; 3]],
        surface: &ContactSurface,
        two_sided: impl Fn(u32) -> bool + Sync,
    ) {
        self.order_nodes_by_cell(frame);
        let n_items = self.order.len().div_ceil(CHUNK);
        self.items.resize_with(n_items, QueryItem::default);
        self.items.truncate(n_items);
        let test = CellTest {
            reference: &self.reference,
            boxes: &self.boxes,
            cell_start: &self.cell_start,
            cell_tris: &self.cell_tris,
            reach2: self.enlargement * self.enlargement,
            front2: self.front * self.front,
        };
        let (order, node_cells) = (&self.order, &self.node_cells);
        self.items.par_iter_mut().enumerate().for_each(|(i, item)| {
            item.cands.clear();
            item.rows.clear();
            let visits = &order[i * CHUNK..((i + 1) * CHUNK).min(order.len())];
            for &k in visits {
                let k = k as usize;
                let start = item.cands.len();
                test.node_candidates(
                    k,
                    node_cells[k],
                    positions,
                    surface,
                    &two_sided,
                    &mut item.cands,
                );
                item.rows
                    .push([k as u32, start as u32, (item.cands.len() - start) as u32]);
            }
        });
        self.locate_rows(surface.surface_nodes.len());
        self.assemble_rows();
    }

    /// Numbers the cell of every surface node (its reference position) and orders the
    /// nodes that lie in a listed cell by cell, in increasing node order within a cell (a
    /// counting sort); nodes outside every listed cell have no candidates.
    fn order_nodes_by_cell(&mut self, frame: Frame) {
        let (layout, table) = (self.layout, &self.table);
        self.node_cells.clear();
        self.node_cells.extend(
            self.reference
                .iter()
                .map(|&x| lookup(layout, table, frame.cell(x)).map_or(NO_CELL, |c| c as u32)),
        );
        let n_cells = self.cell_start.len().saturating_sub(1);
        let cursor = &mut self.node_cursor;
        cursor.clear();
        cursor.resize(n_cells + 1, 0);
        for &c in &self.node_cells {
            if c != NO_CELL {
                cursor[c as usize + 1] += 1;
            }
        }
        for c in 1..cursor.len() {
            cursor[c] += cursor[c - 1];
        }
        let listed = cursor[n_cells] as usize;
        self.order.clear();
        self.order.resize(listed, 0);
        for (k, &c) in self.node_cells.iter().enumerate() {
            if c != NO_CELL {
                let slot = &mut cursor[c as usize];
                self.order[*slot as usize] = k as u32;
                *slot += 1;
            }
        }
    }

    /// Where each surface node's list lies: `located[k] = [item, start, length]` (nodes
    /// never visited keep an empty list).
    fn locate_rows(&mut self, n_surface: usize) {
        self.located.clear();
        self.located.resize(n_surface, [0; 3]);
        for (i, item) in self.items.iter().enumerate() {
            for &[k, start, len] in &item.rows {
                self.located[k as usize] = [i as u32, start, len];
            }
        }
    }

    /// Copies the lists into node order, in parallel over the chunks of [`CHUNK`] nodes.
    fn assemble_rows(&mut self) {
        let n_surface = self.located.len();
        let n_chunks = n_surface.div_ceil(CHUNK);
        self.chunk_cands.resize_with(n_chunks, Vec::new);
        self.chunk_cands.truncate(n_chunks);
        self.chunk_starts.resize_with(n_chunks, Vec::new);
        self.chunk_starts.truncate(n_chunks);
        let (items, located) = (&self.items, &self.located);
        self.chunk_cands
            .par_iter_mut()
            .zip(self.chunk_starts.par_iter_mut())
            .enumerate()
            .for_each(|(chunk, (tris, starts))| {
                tris.clear();
                starts.clear();
                starts.push(0);
                for &[i, start, len] in
                    &located[chunk * CHUNK..((chunk + 1) * CHUNK).min(n_surface)]
                {
                    if len > 0 {
                        let (start, len) = (start as usize, len as usize);
                        tris.extend_from_slice(&items[i as usize].cands[start..start + len]);
                    }
                    starts.push(tris.len());
                }
            });
    }

    /// Candidate faces of surface node `k`.
    #[inline]
    pub(crate) fn candidates(&self, k: usize) -> &[Candidate] {
        let (chunk, i) = (k / CHUNK, k % CHUNK);
        let starts = &self.chunk_starts[chunk];
        &self.chunk_cands[chunk][starts[i]..starts[i + 1]]
    }
}
