//! Compressed rows: entries grouped by a key, each row in the order the entries came.
//!
//! A pass over the keys can then add each key's terms in the order a serial pass over the
//! entries adds them, so a sum split by key has the serial pass's bits.

/// Per key `0..keys`, its entries in the order given (a counting sort).
#[derive(Clone, Debug, Default)]
pub struct Rows<T> {
    /// Per key, the start of its row in `entries` (one more than the keys).
    start: Vec<usize>,
    entries: Vec<T>,
}

impl<T> Rows<T> {
    /// The rows of `pairs` (key, entry), every key below `keys`.
    ///
    /// # Panics
    /// If a key is `keys` or more (a caller's indexing error).
    pub fn by_key(keys: usize, pairs: Vec<(usize, T)>) -> Rows<T> {
        let mut start = vec![0usize; keys + 1];
        for &(k, _) in &pairs {
            start[k + 1] += 1;
        }
        for k in 1..start.len() {
            start[k] += start[k - 1];
        }
        let mut cursor = start.clone();
        let mut slots: Vec<Option<T>> = std::iter::repeat_with(|| None).take(pairs.len()).collect();
        for (k, entry) in pairs {
            slots[cursor[k]] = Some(entry);
            cursor[k] += 1;
        }
        // Every slot is filled once: the counts above are the rows' lengths.
        let entries = slots.into_iter().flatten().collect();
        Rows { start, entries }
    }

    /// The entries of key `k`, in the order given.
    #[inline]
    pub fn row(&self, k: usize) -> &[T] {
        &self.entries[self.start[k]..self.start[k + 1]]
    }

    /// The number of keys.
    pub fn keys(&self) -> usize {
        self.start.len().saturating_sub(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_keep_the_order_of_the_entries_within_a_key() {
        let pairs = vec![(2, 'a'), (0, 'b'), (2, 'c'), (3, 'd'), (0, 'e'), (2, 'f')];
        let rows = Rows::by_key(5, pairs);
        assert_eq!(rows.keys(), 5);
        assert_eq!(rows.row(0), ['b', 'e']);
        assert_eq!(rows.row(1), [] as [char; 0]);
        assert_eq!(rows.row(2), ['a', 'c', 'f']);
        assert_eq!(rows.row(3), ['d']);
        assert_eq!(rows.row(4), [] as [char; 0]);
    }
}
