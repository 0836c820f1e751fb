//! The contacts of the last evaluation, kept where the narrow phase wrote them.
//!
//! The narrow phase writes each fixed chunk of surface nodes' contacts into that chunk's
//! scratch ([`crate::detect`]), in increasing key order; the next evaluation of the chunk
//! reads its tangential history from the same chunk's contacts, since a key names its
//! surface node ([`crate::model::history_key`]). Keeping an evaluation's contacts is then a
//! swap of buffers per chunk rather than a copy of every record; the flat list the
//! public accessors return is assembled on first demand after each evaluation.

use crate::broad::CHUNK;
use crate::detect::ChunkScratch;
use crate::model::{NodeContact, key_surface_index};
use std::sync::OnceLock;

/// The last evaluation's contacts, chunk by chunk, each chunk's sorted by key.
#[derive(Clone, Debug, Default)]
pub(crate) struct History {
    chunks: Vec<Vec<NodeContact>>,
    /// Every chunk's contacts one after the other, assembled on demand.
    flat: OnceLock<Vec<NodeContact>>,
}

impl History {
    /// An empty history over `n_chunks` chunks of surface nodes.
    pub(crate) fn new(n_chunks: usize) -> History {
        History {
            chunks: vec![Vec::new(); n_chunks],
            flat: OnceLock::new(),
        }
    }

    /// The contacts of chunk `chunk` (surface nodes `chunk * CHUNK ..`), sorted by key.
    pub(crate) fn chunk(&self, chunk: usize) -> &[NodeContact] {
        self.chunks.get(chunk).map_or(&[], Vec::as_slice)
    }

    /// How many contacts there are.
    pub(crate) fn len(&self) -> usize {
        self.chunks.iter().map(Vec::len).sum()
    }

    /// Every contact, sorted by key (surface node, then counterpart).
    pub(crate) fn iter(&self) -> impl Iterator<Item = &NodeContact> + '_ {
        self.chunks.iter().flatten()
    }

    /// Every contact, sorted by key, as one slice (assembled on the first call after a
    /// change).
    pub(crate) fn flat(&self) -> &[NodeContact] {
        self.flat.get_or_init(|| self.iter().copied().collect())
    }

    /// Every contact, mutably, sorted by key.
    pub(crate) fn iter_mut(&mut self) -> impl Iterator<Item = &mut NodeContact> + '_ {
        self.flat = OnceLock::new();
        self.chunks.iter_mut().flatten()
    }

    /// Takes the chunks' contacts as the history (the chunks get the old buffers, which
    /// their next evaluation clears).
    pub(crate) fn keep(&mut self, scratch: &mut [ChunkScratch]) {
        debug_assert_eq!(scratch.len(), self.chunks.len());
        for (kept, s) in self.chunks.iter_mut().zip(scratch) {
            std::mem::swap(kept, &mut s.contacts);
        }
        self.flat = OnceLock::new();
    }

    /// Replaces the history by `contacts`, sorted by key.
    pub(crate) fn replace(&mut self, contacts: &[NodeContact]) {
        debug_assert!(contacts.windows(2).all(|p| p[0].key < p[1].key));
        for c in &mut self.chunks {
            c.clear();
        }
        for c in contacts {
            let chunk = key_surface_index(c.key) / CHUNK;
            if let Some(list) = self.chunks.get_mut(chunk) {
                list.push(*c);
            }
        }
        self.flat = OnceLock::new();
    }
}

/// A reader of one chunk's history that only moves forward: the narrow phase asks for
/// keys in increasing order within a chunk, so finding them is a merge, not a search per
/// contact.
pub(crate) struct Cursor<'a> {
    list: &'a [NodeContact],
    at: usize,
}

impl<'a> Cursor<'a> {
    /// A cursor at the start of `list` (sorted by key).
    pub(crate) fn new(list: &'a [NodeContact]) -> Cursor<'a> {
        Cursor { list, at: 0 }
    }

    /// The contact with key `key`, if there is one; no later call may ask for a smaller
    /// key.
    #[inline]
    pub(crate) fn find(&mut self, key: u64) -> Option<&'a NodeContact> {
        let list = self.list;
        while self.at < list.len() && list[self.at].key < key {
            self.at += 1;
        }
        list.get(self.at).filter(|c| c.key == key)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Counterpart, history_key};

    fn contact(k: usize, wall: u32) -> NodeContact {
        let counterpart = Counterpart::Wall(wall);
        NodeContact {
            key: history_key(k, counterpart),
            node: k,
            body: 0,
            counterpart,
            face: None,
            weights: [0.0; 3],
            position: [0.0; 3],
            contact_point: [0.0; 3],
            depth: k as f64,
            normal_force: [0.0; 3],
            tangential_force: [0.0; 3],
            tangential_displacement: [0.0; 3],
            sliding: false,
            damping_force: [0.0; 3],
            relative_velocity: [0.0; 3],
            edge: false,
        }
    }

    #[test]
    fn a_replaced_history_lists_its_contacts_in_their_chunks_and_in_order() {
        let contacts: Vec<NodeContact> = [3, CHUNK - 1, CHUNK, 2 * CHUNK + 5, 2 * CHUNK + 7]
            .iter()
            .flat_map(|&k| [contact(k, 0), contact(k, 1)])
            .collect();
        let mut h = History::new(3);
        h.replace(&contacts);
        assert_eq!(h.len(), contacts.len());
        assert_eq!(h.flat(), contacts.as_slice());
        assert_eq!(h.chunk(0).len(), 4);
        assert_eq!(h.chunk(1).len(), 2);
        assert_eq!(h.chunk(2).len(), 4);
        assert!(h.chunk(3).is_empty());
        // A cursor finds each key once, in order, and nothing in between.
        let mut cursor = Cursor::new(h.chunk(2));
        assert!(
            cursor
                .find(history_key(2 * CHUNK, Counterpart::Wall(0)))
                .is_none()
        );
        let found = cursor.find(history_key(2 * CHUNK + 5, Counterpart::Wall(1)));
        assert_eq!(found.map(|c| c.node), Some(2 * CHUNK + 5));
        assert!(
            cursor
                .find(history_key(2 * CHUNK + 6, Counterpart::Wall(0)))
                .is_none()
        );
        let found = cursor.find(history_key(2 * CHUNK + 7, Counterpart::Wall(0)));
        assert_eq!(found.map(|c| c.depth), Some((2 * CHUNK + 7) as f64));
    }

    #[test]
    fn keeping_swaps_the_chunks_contacts_in_and_forgets_the_flat_list() {
        let mut h = History::new(2);
        h.replace(&[contact(1, 0)]);
        assert_eq!(h.flat().len(), 1);
        let mut scratch = vec![ChunkScratch::default(); 2];
        scratch[1].contacts = vec![contact(CHUNK + 2, 0), contact(CHUNK + 3, 0)];
        h.keep(&mut scratch);
        assert_eq!(h.flat().len(), 2);
        assert_eq!(h.chunk(1)[0].node, CHUNK + 2);
        assert!(h.chunk(0).is_empty());
        // The scratch got the old buffers back.
        assert_eq!(scratch[0].contacts.len(), 1);
        assert!(scratch[1].contacts.is_empty());
        h.iter_mut().for_each(|c| c.depth = -1.0);
        assert!(h.flat().iter().all(|c| c.depth == -1.0));
    }
}
