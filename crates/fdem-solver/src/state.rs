//! Node state in structure-of-arrays form (ARCHITECTURE.md, "Data layout").

use std::ops::Range;

/// Positions, velocities, forces and lumped masses of every node, one array each.
///
/// Index `i` is the same node in every array. Bodies are contiguous ranges of nodes
/// ([`crate::Body`]), so per-body loops work on disjoint slices without locks.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NodeState {
    /// Current positions (m).
    pub positions: Vec<[f64; 3]>,
    /// Reference (initial, undeformed) positions (m); displacement = position - reference.
    pub reference: Vec<[f64; 3]>,
    /// Velocities (m/s).
    pub velocities: Vec<[f64; 3]>,
    /// Total force on each node at the current positions (N).
    pub forces: Vec<[f64; 3]>,
    /// Lumped masses (kg).
    pub masses: Vec<f64>,
    /// Reciprocal masses (1/kg), cached for the update loop.
    pub inverse_masses: Vec<f64>,
}

impl NodeState {
    /// A state with the given reference positions and masses, at rest.
    pub fn new(reference: Vec<[f64; 3]>, masses: Vec<f64>) -> Self {
        let n = reference.len();
        let inverse_masses = masses.iter().map(|&m| 1.0 / m).collect();
        NodeState {
            positions: reference.clone(),
            reference,
            velocities: vec![[0.0; 3]; n],
            forces: vec![[0.0; 3]; n],
            masses,
            inverse_masses,
        }
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there are no nodes.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Kinetic energy `sum 1/2 m |v|^2` of the nodes in `range` (J), summed in node order.
    pub fn kinetic_energy(&self, range: Range<usize>) -> f64 {
        self.velocities[range.clone()]
            .iter()
            .zip(&self.masses[range])
            .map(|(v, &m)| 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
            .sum()
    }
}
