//! The crate's error type.

use thiserror::Error;

/// Everything that can go wrong in this crate. Each message says what was wrong, where
/// (field name, element id, node id) and how to fix it.
///
/// Element ids are 0-based positions in the connectivity passed to
/// [`ElementSet::new`](crate::ElementSet::new); node ids are indices into the node slice of
/// that body (body-local).
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ElasticError {
    /// A material parameter is out of its admissible range.
    #[error(
        "invalid material: {field} = {} {requirement}",
        fdem_core::number::Number(*.value)
    )]
    InvalidMaterial {
        /// Name of the offending field (`density`, `youngs_modulus`, `poisson_ratio`).
        field: &'static str,
        /// The value given.
        value: f64,
        /// What the value must satisfy and how to fix it.
        requirement: &'static str,
    },

    /// `nodes_per_element` is neither 4 nor 10.
    #[error(
        "nodes_per_element = {nodes_per_element} is not supported: use 4 (linear tetrahedron) \
         or 10 (quadratic tetrahedron, VTK_QUADRATIC_TETRA node order)"
    )]
    UnsupportedElement {
        /// The value given.
        nodes_per_element: usize,
    },

    /// The connectivity length is not a multiple of `nodes_per_element`.
    #[error(
        "connectivity has {len} entries, which is not a multiple of nodes_per_element = \
         {nodes_per_element}: pass exactly nodes_per_element node ids per element"
    )]
    ConnectivityLength {
        /// Length of the connectivity slice.
        len: usize,
        /// Nodes per element.
        nodes_per_element: usize,
    },

    /// A connectivity entry points past the end of the node slice.
    #[error(
        "element {element}: local node {local} refers to node {node}, but the body has only \
         {n_nodes} nodes: connectivity must hold body-local node indices in 0..{n_nodes}"
    )]
    NodeOutOfRange {
        /// Element id.
        element: usize,
        /// Position of the entry inside the element (0-based).
        local: usize,
        /// The node id given.
        node: usize,
        /// Number of nodes in the body.
        n_nodes: usize,
    },

    /// The same node id appears twice in one element.
    #[error(
        "element {element}: node {node} appears more than once in its connectivity: every \
         node of an element must be distinct"
    )]
    RepeatedNode {
        /// Element id.
        element: usize,
        /// The repeated node id.
        node: usize,
    },

    /// The body has more nodes than the compact `u32` node ids can address.
    #[error(
        "the body has {n_nodes} nodes, more than the {max} an element set can address: split \
         the body"
    )]
    TooManyNodes {
        /// Number of nodes given.
        n_nodes: usize,
        /// The maximum supported.
        max: usize,
    },

    /// A rest (reference) position is NaN or infinite.
    #[error(
        "rest_positions[{node}] = {position:?} is not finite: give finite coordinates in metres"
    )]
    NonFiniteRestPosition {
        /// Node id.
        node: usize,
        /// The position given.
        position: [f64; 3],
    },

    /// A reference element has negative volume (corner nodes ordered clockwise).
    #[error(
        "element {element} is inverted in the reference configuration (signed volume \
         {volume:e} m^3): corner nodes 0..3 must be positively oriented, i.e. \
         (x1-x0).((x2-x0)x(x3-x0)) > 0; swap corner nodes 1 and 2 (and, for 10-node elements, \
         mid-edge nodes 4<->6 and 8<->9)"
    )]
    InvertedReferenceElement {
        /// Element id.
        element: usize,
        /// Signed volume found.
        volume: f64,
    },

    /// A reference element is (nearly) flat.
    #[error(
        "element {element} is degenerate in the reference configuration: volume {volume:e} \
         m^3 is below 1e-10 x (longest edge)^3 / 6; remesh so that no tetrahedron is flat"
    )]
    DegenerateReferenceElement {
        /// Element id.
        element: usize,
        /// Signed volume found.
        volume: f64,
    },

    /// A 10-node element's mid-edge node is not at the midpoint of its straight edge.
    #[error(
        "element {element}: mid-edge node {node} (local {local}) is {offset:e} m from the \
         midpoint of its edge (edge length {edge_length:e} m); 10-node elements must be \
         straight-sided in the reference configuration, with local nodes 4..9 on the midpoints \
         of edges (0,1) (1,2) (0,2) (0,3) (1,3) (2,3) (VTK_QUADRATIC_TETRA order)"
    )]
    MidEdgeNodeOffset {
        /// Element id.
        element: usize,
        /// Local position (4..9) in the element.
        local: usize,
        /// Body-local node id.
        node: usize,
        /// Distance from the edge midpoint.
        offset: f64,
        /// Length of the edge.
        edge_length: f64,
    },

    /// A slice passed to a method has the wrong length.
    #[error(
        "{field} has length {len} but this element set needs {expected}: pass one entry per \
         {per}"
    )]
    LengthMismatch {
        /// Name of the argument (`positions`, `forces`, `out`).
        field: &'static str,
        /// Length given.
        len: usize,
        /// Length required.
        expected: usize,
        /// What one entry stands for (`node of the body`, `element`).
        per: &'static str,
    },

    /// An element is inverted or flat in the current configuration.
    #[error(
        "element {element} is inverted or degenerate in the current configuration (det F = \
         {det_f:e} <= 0): the body is over-compressed or the run is unstable; reduce the time \
         step (see ElementSet::stable_time_step) or the contact penalty"
    )]
    InvertedElement {
        /// Element id.
        element: usize,
        /// Determinant of the deformation gradient found (at the centroid or at the corner
        /// where it is smallest, for 10-node elements).
        det_f: f64,
    },

    /// Current positions of an element are NaN or infinite.
    #[error(
        "element {element}: current node positions are not finite (NaN or infinite): the run \
         has already diverged; reduce the time step"
    )]
    NonFinitePosition {
        /// Element id.
        element: usize,
    },

    /// The polar decomposition did not converge (only for deformation gradients so close to
    /// singular that the iteration leaves the floating-point range).
    #[error(
        "element {element}: the rotation of its deformation gradient could not be computed \
         (stretch ratios beyond the floating-point range): the element is crushed; reduce the \
         time step"
    )]
    PolarDecomposition {
        /// Element id.
        element: usize,
    },

    /// An element id passed to a method is out of range.
    #[error("element {element} does not exist: the set has {n_elements} elements")]
    ElementOutOfRange {
        /// The id given.
        element: usize,
        /// Number of elements.
        n_elements: usize,
    },
}
