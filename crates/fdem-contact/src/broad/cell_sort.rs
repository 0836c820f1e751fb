//! The grid's counting sort: the binned nodes in the order of their cells, each cell's in
//! their order in the input, so that the scan reads a cell's nodes (and a row of cells')
//! one after the other.
//!
//! It runs in parallel over one range of cells per thread of the current pool. Each part
//! reads every node and counts, then places, only those in its cells: its counts and its
//! slots are its own, so no part waits for another, and the result is the same for every
//! thread count (integer sums, each node placed by its cell's owner in input order).

use rayon::prelude::*;

/// The row starts and the nodes of a grid sorted by cell.
#[derive(Clone, Debug, Default)]
pub(super) struct CellSort {
    /// `n_cells + 1` row starts into `nodes`: cell `c` holds `nodes[start[c]..start[c + 1]]`.
    pub(super) start: Vec<u32>,
    /// The nodes, cell by cell.
    pub(super) nodes: Vec<u32>,
    /// Each cell's next free slot while placing (scratch).
    cursor: Vec<u32>,
}

impl CellSort {
    /// Sorts `items` by their cells `cells` (parallel to `items`, each below `n_cells`),
    /// stably: within a cell, the items keep their order in `items`.
    pub(super) fn sort(&mut self, items: &[u32], cells: &[u32], n_cells: usize) {
        debug_assert_eq!(items.len(), cells.len());
        let per_part = n_cells.div_ceil(rayon::current_num_threads()).max(1);
        self.start.clear();
        self.start.resize(n_cells + 1, 0);
        // Each part counts its cells' items into `start[c + 1]` and sums them up within
        // its range; the parts' totals then shift the later parts' rows.
        let totals: Vec<u32> = self.start[1..]
            .par_chunks_mut(per_part)
            .enumerate()
            .map(|(p, rows)| count_part(cells, p * per_part, rows))
            .collect();
        let offsets: Vec<u32> = totals
            .iter()
            .scan(0, |sum, &t| {
                let before = *sum;
                *sum += t;
                Some(before)
            })
            .collect();
        self.start[1..]
            .par_chunks_mut(per_part)
            .zip(&offsets)
            .for_each(|(rows, &offset)| rows.iter_mut().for_each(|r| *r += offset));
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.start[..n_cells]);
        self.nodes.clear();
        self.nodes.resize(items.len(), 0);
        // Each part's slots: from its first cell's start to its last cell's end.
        let mut slots = Vec::with_capacity(totals.len());
        let mut rest = self.nodes.as_mut_slice();
        for &total in &totals {
            let (mine, after) = rest.split_at_mut(total as usize);
            slots.push(mine);
            rest = after;
        }
        self.cursor
            .par_chunks_mut(per_part)
            .zip(slots)
            .enumerate()
            .for_each(|(p, (cursor, slots))| {
                place_part((items, cells), p * per_part, cursor, slots);
            });
    }
}

/// Counts the items of cells `first..first + rows.len()` into `rows` (cell `first + i`
/// into `rows[i]`, zero on entry), then turns the counts into sums up to each cell
/// (inclusive); returns the part's total.
fn count_part(cells: &[u32], first: usize, rows: &mut [u32]) -> u32 {
    for &c in cells {
        if let Some(row) = (c as usize)
            .checked_sub(first)
            .and_then(|i| rows.get_mut(i))
        {
            *row += 1;
        }
    }
    let mut sum = 0;
    for row in rows.iter_mut() {
        sum += *row;
        *row = sum;
    }
    sum
}

/// Places the items of cells `first..first + cursor.len()` in input order: each at its
/// cell's next slot (`cursor`, absolute), into `slots`, which begin at the first cell's
/// start.
fn place_part(
    (items, cells): (&[u32], &[u32]),
    first: usize,
    cursor: &mut [u32],
    slots: &mut [u32],
) {
    let Some(&base) = cursor.first() else {
        return;
    };
    for (&item, &c) in items.iter().zip(cells) {
        if let Some(next) = (c as usize)
            .checked_sub(first)
            .and_then(|i| cursor.get_mut(i))
        {
            slots[(*next - base) as usize] = item;
            *next += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sort_is_stable_and_the_same_on_every_thread_count() {
        // Items in increasing order, cells scattered over a grid with empty cells, and
        // every cell of the last part empty.
        let n_cells = 1_000;
        let items: Vec<u32> = (0..5_000).map(|i| 3 * i + 1).collect();
        let cells: Vec<u32> = (0..5_000u64)
            .map(|i| ((i * 7_919 + i * i * 104_729) % 600) as u32 + u32::from(i % 3 == 0))
            .collect();
        let mut want: Vec<(u32, u32)> = cells.iter().copied().zip(items.iter().copied()).collect();
        want.sort_by_key(|&(c, _)| c); // stable
        for threads in 1..=4 {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut s = CellSort::default();
            pool.install(|| s.sort(&items, &cells, n_cells));
            let got: Vec<u32> = s.nodes.clone();
            assert_eq!(
                got,
                want.iter().map(|p| p.1).collect::<Vec<_>>(),
                "{threads}"
            );
            assert_eq!(s.start.len(), n_cells + 1);
            for c in 0..n_cells {
                let row = &want[s.start[c] as usize..s.start[c + 1] as usize];
                assert!(row.iter().all(|p| p.0 == c as u32), "{threads}: cell {c}");
            }
            assert_eq!(s.start[n_cells] as usize, items.len());
        }
    }

    #[test]
    fn no_items_and_no_cells_sort_to_nothing() {
        let mut s = CellSort::default();
        s.sort(&[], &[], 0);
        assert_eq!((s.start.as_slice(), s.nodes.len()), (&[0][..], 0));
        s.sort(&[], &[], 5);
        assert_eq!(s.start, vec![0; 6]);
    }
}
