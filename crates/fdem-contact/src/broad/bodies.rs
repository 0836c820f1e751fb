//! Each body's surface nodes and triangles, listed once: a refresh reads the few bodies it
//! renews and their neighbours instead of passing over every node and triangle.

use crate::ContactSurface;

/// Per body, its surface nodes and triangles in increasing order (compressed rows; a
/// surface need not number a body's items consecutively).
#[derive(Clone, Debug, Default)]
pub(crate) struct BodyIndex {
    node_start: Vec<u32>,
    nodes: Vec<u32>,
    triangle_start: Vec<u32>,
    triangles: Vec<u32>,
}

/// The rows of `owner` (an owner per item) over `bodies` bodies, items in increasing
/// order within a row (a counting sort).
pub(super) fn rows(owner: &[u32], bodies: usize) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; bodies + 1];
    for &b in owner {
        start[b as usize + 1] += 1;
    }
    for b in 1..start.len() {
        start[b] += start[b - 1];
    }
    let mut cursor = start.clone();
    let mut items = vec![0u32; owner.len()];
    for (i, &b) in owner.iter().enumerate() {
        items[cursor[b as usize] as usize] = i as u32;
        cursor[b as usize] += 1;
    }
    (start, items)
}

impl BodyIndex {
    /// The index of `surface` (whose counts fit in u32: `ContactSurface::validate`).
    pub(crate) fn of(surface: &ContactSurface) -> BodyIndex {
        let bodies = surface.n_bodies();
        let (node_start, nodes) = rows(&surface.node_body, bodies);
        let (triangle_start, triangles) = rows(&surface.triangle_body, bodies);
        BodyIndex {
            node_start,
            nodes,
            triangle_start,
            triangles,
        }
    }

    /// The number of bodies.
    pub(crate) fn bodies(&self) -> usize {
        self.node_start.len().saturating_sub(1)
    }

    /// The surface nodes of `body`, in increasing order.
    pub(crate) fn nodes(&self, body: usize) -> &[u32] {
        &self.nodes[self.node_start[body] as usize..self.node_start[body + 1] as usize]
    }

    /// The triangles of `body`, in increasing order.
    pub(crate) fn triangles(&self, body: usize) -> &[u32] {
        let row = self.triangle_start[body] as usize..self.triangle_start[body + 1] as usize;
        &self.triangles[row]
    }

    /// The surface nodes of the bodies marked in `which` (one flag per body), in
    /// increasing order.
    pub(crate) fn nodes_of(&self, which: &[bool]) -> Vec<u32> {
        self.gather(which, |b| self.nodes(b))
    }

    /// The triangles of the bodies marked in `which`, in increasing order.
    pub(crate) fn triangles_of(&self, which: &[bool]) -> Vec<u32> {
        self.gather(which, |b| self.triangles(b))
    }

    fn gather<'a>(&'a self, which: &[bool], row: impl Fn(usize) -> &'a [u32]) -> Vec<u32> {
        let mut out: Vec<u32> = (0..self.bodies().min(which.len()))
            .filter(|&b| which[b])
            .flat_map(|b| row(b).iter().copied())
            .collect();
        out.sort_unstable();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_list_every_item_of_a_body_in_order_whatever_the_numbering() {
        let surface = ContactSurface {
            triangles: vec![[0, 1, 2], [3, 4, 5], [0, 2, 1]],
            triangle_body: vec![1, 0, 1],
            surface_nodes: vec![0, 1, 2, 3, 4, 5],
            node_body: vec![1, 1, 1, 0, 0, 0],
            control_areas: vec![1.0; 6],
        };
        let index = BodyIndex::of(&surface);
        assert_eq!(index.bodies(), 2);
        assert_eq!(index.nodes(0), &[3, 4, 5]);
        assert_eq!(index.nodes(1), &[0, 1, 2]);
        assert_eq!(index.triangles(1), &[0, 2]);
        assert_eq!(index.nodes_of(&[true, true]), vec![0, 1, 2, 3, 4, 5]);
        assert_eq!(index.triangles_of(&[true, false]), vec![1]);
    }
}
