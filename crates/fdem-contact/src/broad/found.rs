//! The pairs a full build finds, and their placing into the nodes' candidate lists.
//!
//! The lists are placed in parallel, one part of the node chunks per thread, each part
//! counting and then placing the pairs of its own nodes. The grid scan knows a pair's part
//! as it finds it (the part follows from the node's number), so each scan piece keeps one
//! vector per part: a part then reads its own pairs (twice: to count, then to place), not
//! every pair. The framed bodies' pairs (found body by body, or beside the grid scan) stay
//! in vectors that mix the parts, which every part reads and filters. The order in which a
//! list receives its pairs does not matter: each list is sorted by (owner body, triangle)
//! at the end, and a candidate is set by its triangle (its nodes and body follow), so equal
//! keys are equal candidates and every list is the same for every thread count and split.

use rayon::prelude::*;

use super::{CHUNK, Candidate};

/// One found pair: the surface node and its candidate face.
pub(super) type Pair = (u32, Candidate);

/// How the surface nodes are split into parts: consecutive runs of `len` nodes.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Parts {
    /// The number of parts (at least one).
    pub(super) count: usize,
    /// Surface nodes per part (a whole number of chunks).
    pub(super) len: usize,
}

impl Parts {
    /// The part of surface node `node` (the last for one beyond it).
    #[inline(always)]
    pub(super) fn of(self, node: u32) -> usize {
        (node as usize / self.len).min(self.count - 1)
    }
}

/// The pairs of a build before they are placed.
#[derive(Clone, Debug, Default)]
pub(super) struct FoundPairs {
    /// First `pieces` groups of `parts.count + 1` vectors (a scan piece's pairs of each
    /// part, then its mixed pairs), then vectors of mixed pairs.
    vecs: Vec<Vec<Pair>>,
    parts: Parts,
    /// The scan pieces that lead `vecs`.
    pieces: usize,
}

impl FoundPairs {
    /// Empties the pairs for a build of `n_surface` surface nodes whose scan runs over
    /// `pieces` pieces, with one part of the node chunks per thread of the current pool.
    pub(super) fn reset(&mut self, n_surface: usize, pieces: usize) {
        let chunks = n_surface.div_ceil(CHUNK);
        let chunks_per_part = chunks.div_ceil(rayon::current_num_threads()).max(1);
        self.parts = Parts {
            count: chunks.div_ceil(chunks_per_part).max(1),
            len: chunks_per_part * CHUNK,
        };
        self.pieces = pieces;
        let n = pieces * (self.parts.count + 1);
        self.vecs.resize_with(n, Vec::new);
        self.vecs.truncate(n);
        self.vecs.iter_mut().for_each(Vec::clear);
    }

    /// How the nodes are split into parts.
    pub(super) fn parts(&self) -> Parts {
        self.parts
    }

    /// Each scan piece's vectors, in parallel: one per part, then its mixed one.
    pub(super) fn pieces_mut(&mut self) -> rayon::slice::ChunksMut<'_, Vec<Pair>> {
        let group = self.parts.count + 1;
        self.vecs[..self.pieces * group].par_chunks_mut(group)
    }

    /// Adds vectors of mixed pairs.
    pub(super) fn extend(&mut self, mixed: impl IntoIterator<Item = Vec<Pair>>) {
        self.vecs.extend(mixed);
    }

    /// Calls `f` on each pair part `part` reads: its own of every piece, and every mixed
    /// one (slice by slice, so that each is a plain loop).
    #[inline(always)]
    fn for_each_of_part(&self, part: usize, mut f: impl FnMut(&Pair)) {
        let group = self.parts.count + 1;
        let (split, mixed) = self.vecs.split_at(self.pieces * group);
        for g in split.chunks(group) {
            g[part].iter().for_each(&mut f);
            g[group - 1].iter().for_each(&mut f);
        }
        mixed.iter().for_each(|v| v.iter().for_each(&mut f));
    }

    /// Places the pairs of part `part` (nodes `part * parts.len ..`, `cursor.len()` of
    /// them) into the lists of that part's chunks (`cands`, `starts`): counts per node into
    /// `cursor` (zero on entry), row starts, the pairs in their order, then each list
    /// sorted by (owner body, triangle) unless it already is.
    pub(super) fn place_part(
        &self,
        part: usize,
        cursor: &mut [usize],
        (cands, starts): (&mut [Vec<Candidate>], &mut [Vec<usize>]),
    ) {
        let (first, len) = (part * self.parts.len, cursor.len());
        let mine = |k: u32| (k as usize).checked_sub(first).filter(|&i| i < len);
        self.for_each_of_part(part, |&(k, _)| {
            if let Some(i) = mine(k) {
                cursor[i] += 1;
            }
        });
        // Row starts per chunk, and each node's first slot.
        for ((rows, chunk_starts), slots) in cands
            .iter_mut()
            .zip(starts.iter_mut())
            .zip(cursor.chunks_mut(CHUNK))
        {
            chunk_starts.clear();
            chunk_starts.push(0);
            let mut running = 0;
            for slot in slots {
                let count = *slot;
                *slot = running;
                running += count;
                chunk_starts.push(running);
            }
            rows.clear();
            rows.resize(running, Candidate::default());
        }
        self.for_each_of_part(part, |&(k, cand)| {
            if let Some(i) = mine(k) {
                let slot = &mut cursor[i];
                cands[i / CHUNK][*slot] = cand;
                *slot += 1;
            }
        });
        for (rows, chunk_starts) in cands.iter_mut().zip(starts.iter()) {
            for row in chunk_starts.windows(2) {
                let list = &mut rows[row[0]..row[1]];
                if !list.is_sorted_by_key(|c| (c.body, c.triangle)) {
                    list.sort_unstable_by_key(|c| (c.body, c.triangle));
                }
            }
        }
    }
}
