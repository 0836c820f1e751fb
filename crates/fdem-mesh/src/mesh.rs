//! Tetrahedral meshes, their surfaces and quality figures.

use serde::{Deserialize, Serialize};

use crate::MeshError;
use crate::geometry::{dihedral_angle, distance, sub, tet_signed_volume, triangle_area};

/// Polynomial order of the tetrahedral elements.
///
/// Serialised in lower case: `"linear"`, `"quadratic"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ElementOrder {
    /// 4-node tetrahedra (VTK_TETRA).
    Linear,
    /// 10-node tetrahedra with straight edges (VTK_QUADRATIC_TETRA).
    Quadratic,
}

impl ElementOrder {
    /// Nodes per element: 4 for [`ElementOrder::Linear`], 10 for [`ElementOrder::Quadratic`].
    pub fn nodes_per_element(self) -> usize {
        match self {
            ElementOrder::Linear => 4,
            ElementOrder::Quadratic => 10,
        }
    }

    /// VTK cell type number: 10 (VTK_TETRA) or 24 (VTK_QUADRATIC_TETRA).
    pub fn vtk_cell_type(self) -> u8 {
        match self {
            ElementOrder::Linear => 10,
            ElementOrder::Quadratic => 24,
        }
    }
}

/// Local corner pairs of the six tetrahedron edges, in the order of the mid-edge nodes
/// 4..=9 of a quadratic element (VTK_QUADRATIC_TETRA): `4:(0,1) 5:(1,2) 6:(0,2) 7:(0,3)
/// 8:(1,3) 9:(2,3)`.
pub const TET_EDGES: [(usize, usize); 6] = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)];

/// A tetrahedral mesh of one body, in body-local coordinates.
///
/// Element node ordering is the project's convention (see the crate docs): corners `0..4`
/// positively oriented, then, for quadratic elements, the mid-edge nodes in the order of
/// [`TET_EDGES`].
#[derive(Clone, Debug, PartialEq)]
pub struct TetMesh {
    /// Element order; fixes the number of nodes per element.
    pub order: ElementOrder,
    /// Node positions (m).
    pub nodes: Vec<[f64; 3]>,
    /// Element connectivity, flat: element `e` is
    /// `elements[e * npe .. (e + 1) * npe]` with `npe = order.nodes_per_element()`.
    pub elements: Vec<usize>,
    /// The closed outer surface.
    pub surface: Surface,
}

/// Volume integrals of a solid shape: what a rigid body's mass properties are made of.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeProperties {
    /// Volume `V = int dV` (m^3).
    pub volume: f64,
    /// Centroid `c = int x dV / V` (m).
    pub centroid: [f64; 3],
    /// Second moment about the centroid, `S = int (x - c)(x - c)^T dV` (m^5).
    pub second_moment: [[f64; 3]; 3],
}

impl VolumeProperties {
    /// Inertia tensor about the centroid of the shape filled with density `rho`
    /// (kg m^2): `I = rho (tr(S) 1 - S)`.
    pub fn inertia(&self, rho: f64) -> [[f64; 3]; 3] {
        let s = &self.second_moment;
        let trace = s[0][0] + s[1][1] + s[2][2];
        std::array::from_fn(|j| {
            std::array::from_fn(|k| {
                let delta = if j == k { trace } else { 0.0 };
                rho * (delta - s[j][k])
            })
        })
    }
}

/// [`TetMesh::volume_properties`] of the elements `elements` (`nodes_per_element` node
/// ids each, the first four the corners) over `nodes`.
///
/// # Panics
/// If a node id is out of range.
pub fn volume_properties(
    nodes: &[[f64; 3]],
    elements: &[usize],
    nodes_per_element: usize,
) -> VolumeProperties {
    // Integrals relative to the first node keep the round-off of far-off meshes small.
    let origin = nodes.first().copied().unwrap_or([0.0; 3]);
    let (mut volume, mut first, mut second) = (0.0, [0.0; 3], [[0.0; 3]; 3]);
    for el in elements.chunks_exact(nodes_per_element.max(4)) {
        let v = [0, 1, 2, 3].map(|i| sub(nodes[el[i]], origin));
        let tet = tet_moments(v);
        volume += tet.0;
        for j in 0..3 {
            first[j] += tet.1[j];
            for (s, t) in second[j].iter_mut().zip(tet.2[j]) {
                *s += t;
            }
        }
    }
    let c = first.map(|f| f / volume);
    // Parallel-axis shift to the centroid: S_c = S_o - V c c^T.
    let mut second_moment = second;
    for (row, cj) in second_moment.iter_mut().zip(c) {
        for (s, ck) in row.iter_mut().zip(c) {
            *s -= volume * cj * ck;
        }
    }
    VolumeProperties {
        volume,
        centroid: [c[0] + origin[0], c[1] + origin[1], c[2] + origin[2]],
        second_moment,
    }
}

/// Volume, first and second moments about the origin of the tetrahedron `v` (corners
/// relative to the origin): `V`, `int x dV = V s / 4` and
/// `int x x^T dV = V / 20 (sum_i v_i v_i^T + s s^T)` with `s = sum_i v_i` (the exact
/// quadrature of quadratics over a simplex).
fn tet_moments(v: [[f64; 3]; 4]) -> (f64, [f64; 3], [[f64; 3]; 3]) {
    let volume = tet_signed_volume(v[0], v[1], v[2], v[3]);
    let s = [0, 1, 2].map(|k| v[0][k] + v[1][k] + v[2][k] + v[3][k]);
    let first = s.map(|sk| volume * sk / 4.0);
    let mut second = [[0.0; 3]; 3];
    for (j, row) in second.iter_mut().enumerate() {
        for (k, out) in row.iter_mut().enumerate() {
            let corners: f64 = v.iter().map(|x| x[j] * x[k]).sum();
            *out = volume / 20.0 * (corners + s[j] * s[k]);
        }
    }
    (volume, first, second)
}

impl TetMesh {
    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Number of elements.
    pub fn n_elements(&self) -> usize {
        self.elements.len() / self.order.nodes_per_element()
    }

    /// The mesh stretched along its axes, `x_k -> axes[k] x_k`, with the surface's control
    /// areas recomputed: a sphere template of radius `r` becomes an ellipsoid of semi-axes
    /// `axes[k] r` (its vertices on the ellipsoid, as the sphere's are on the sphere). The
    /// map is affine, so straight edges stay straight and mid-edge nodes stay midpoints: a
    /// quadratic mesh stays a valid one, and volumes scale by `axes[0] axes[1] axes[2]`.
    ///
    /// # Errors
    /// [`MeshError::InvalidAxes`] unless every component is finite and > 0.
    pub fn stretched(&self, axes: [f64; 3]) -> Result<TetMesh, MeshError> {
        if !axes.iter().all(|a| a.is_finite() && *a > 0.0) {
            return Err(MeshError::InvalidAxes { axes });
        }
        let nodes: Vec<[f64; 3]> = self
            .nodes
            .iter()
            .map(|x| [axes[0] * x[0], axes[1] * x[1], axes[2] * x[2]])
            .collect();
        let surface = Surface::from_triangles(self.surface.triangles.clone(), &nodes);
        Ok(TetMesh {
            order: self.order,
            nodes,
            elements: self.elements.clone(),
            surface,
        })
    }

    /// Node ids of element `e` (4 or 10 of them).
    ///
    /// # Panics
    /// If `e >= self.n_elements()`, like slice indexing; see [`TetMesh::get_element`].
    pub fn element(&self, e: usize) -> &[usize] {
        let npe = self.order.nodes_per_element();
        &self.elements[e * npe..(e + 1) * npe]
    }

    /// Node ids of element `e`, or `None` if there is no such element.
    pub fn get_element(&self, e: usize) -> Option<&[usize]> {
        let npe = self.order.nodes_per_element();
        self.elements.get(e * npe..(e + 1) * npe)
    }

    /// Corner positions of element `e`.
    ///
    /// # Panics
    /// If `e` or one of its node ids is out of range (see [`TetMesh::validate`]).
    pub fn corners(&self, e: usize) -> [[f64; 3]; 4] {
        let el = self.element(e);
        [
            self.nodes[el[0]],
            self.nodes[el[1]],
            self.nodes[el[2]],
            self.nodes[el[3]],
        ]
    }

    /// Sum of the signed element volumes (m^3), from the corner nodes (straight edges).
    ///
    /// # Panics
    /// If a node id is out of range (see [`TetMesh::validate`]).
    pub fn volume(&self) -> f64 {
        (0..self.n_elements())
            .map(|e| {
                let [a, b, c, d] = self.corners(e);
                tet_signed_volume(a, b, c, d)
            })
            .sum()
    }

    /// Volume, centroid and second moment of the solid meshed shape, integrated exactly
    /// over the tetrahedra (straight edges: the corner nodes define each element, as in
    /// [`TetMesh::volume`]). The mass properties of a rigid particle of density `rho` are
    /// `rho` times these ([`VolumeProperties::inertia`]).
    ///
    /// # Panics
    /// If a node id is out of range (see [`TetMesh::validate`]).
    pub fn volume_properties(&self) -> VolumeProperties {
        volume_properties(&self.nodes, &self.elements, self.order.nodes_per_element())
    }

    /// Checks that the arrays fit together: the element array is a whole number of
    /// elements, every node id (elements, surface triangles, surface nodes) is in range,
    /// surface nodes are sorted and unique, control areas are parallel to them, and every
    /// coordinate is finite.
    pub fn validate(&self) -> Result<(), MeshError> {
        let npe = self.order.nodes_per_element();
        let n = self.nodes.len();
        let bad = |reason: String| Err(MeshError::InvalidMesh { reason });
        if !self.elements.len().is_multiple_of(npe) {
            return bad(format!(
                "the element array has {} entries, not a multiple of {npe} nodes per element",
                self.elements.len()
            ));
        }
        if let Some(i) = self
            .nodes
            .iter()
            .position(|p| p.iter().any(|c| !c.is_finite()))
        {
            return bad(format!(
                "node {i} has a non-finite coordinate {:?}",
                self.nodes[i]
            ));
        }
        if let Some(k) = self.elements.iter().position(|&i| i >= n) {
            return bad(format!(
                "element {} refers to node {}, but there are only {n} nodes",
                k / npe,
                self.elements[k]
            ));
        }
        let s = &self.surface;
        if let Some(t) = s.triangles.iter().position(|t| t.iter().any(|&i| i >= n)) {
            return bad(format!(
                "surface triangle {t} {:?} refers to a node beyond the {n} nodes",
                s.triangles[t]
            ));
        }
        if let Some(i) = s.nodes.iter().position(|&i| i >= n) {
            return bad(format!(
                "surface node entry {i} refers to node {}, but there are only {n} nodes",
                s.nodes[i]
            ));
        }
        if s.nodes.windows(2).any(|w| w[0] >= w[1]) {
            return bad("surface node ids are not sorted and unique".to_string());
        }
        if s.control_areas.len() != s.nodes.len() {
            return bad(format!(
                "{} control areas for {} surface nodes",
                s.control_areas.len(),
                s.nodes.len()
            ));
        }
        Ok(())
    }

    /// Quality figures of the mesh (corner nodes, straight edges).
    ///
    /// # Panics
    /// If a node id is out of range (see [`TetMesh::validate`]).
    pub fn quality(&self) -> MeshQuality {
        let mut q = MeshQuality {
            volume: 0.0,
            surface_area: self.surface.area_from_nodes(&self.nodes),
            min_edge: f64::INFINITY,
            max_edge: 0.0,
            min_altitude: f64::INFINITY,
            min_dihedral_deg: f64::INFINITY,
            max_dihedral_deg: 0.0,
            max_aspect_ratio: 0.0,
        };
        for e in 0..self.n_elements() {
            let x = self.corners(e);
            let v = tet_signed_volume(x[0], x[1], x[2], x[3]);
            q.volume += v;
            let mut longest: f64 = 0.0;
            let mut lowest = f64::INFINITY;
            for &(i, j) in &TET_EDGES {
                let len = distance(x[i], x[j]);
                longest = longest.max(len);
                q.min_edge = q.min_edge.min(len);
                q.max_edge = q.max_edge.max(len);
                let [k, l] = other_two(i, j);
                let angle = dihedral_angle(x[i], x[j], x[k], x[l]).to_degrees();
                q.min_dihedral_deg = q.min_dihedral_deg.min(angle);
                q.max_dihedral_deg = q.max_dihedral_deg.max(angle);
            }
            // Altitude of corner i over the plane of the opposite face: 3 |V| / area.
            for i in 0..4 {
                let [a, b, c] = [(i + 1) % 4, (i + 2) % 4, (i + 3) % 4];
                let area = triangle_area(x[a], x[b], x[c]);
                lowest = lowest.min(3.0 * v.abs() / area);
            }
            q.min_altitude = q.min_altitude.min(lowest);
            q.max_aspect_ratio = q
                .max_aspect_ratio
                .max(longest / lowest / REGULAR_EDGE_PER_ALTITUDE);
        }
        q
    }
}

/// Edge over altitude of the regular tetrahedron, `sqrt(3/2)`: the unit of
/// [`MeshQuality::max_aspect_ratio`].
const REGULAR_EDGE_PER_ALTITUDE: f64 = 1.224_744_871_391_589;

/// The two local corners of a tetrahedron that are not `i` or `j`.
fn other_two(i: usize, j: usize) -> [usize; 2] {
    let mut out = [0; 2];
    let mut k = 0;
    for c in 0..4 {
        if c != i && c != j {
            out[k] = c;
            k += 1;
        }
    }
    out
}

/// The outer surface of a body: flat 3-node triangles and the nodes on them.
///
/// For quadratic meshes each 6-node element face is split into 4 flat triangles
/// (corner-mid-mid three times, plus the middle mid-mid-mid one), as the contact model
/// uses them.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Surface {
    /// Triangles as node ids, oriented outward: counter-clockwise seen from outside, so
    /// `(b - a) × (c - a)` points out of the body.
    pub triangles: Vec<[usize; 3]>,
    /// Sorted, unique ids of the nodes that lie on the surface triangles.
    pub nodes: Vec<usize>,
    /// Control area of each surface node (m^2), parallel to `nodes`: one third of the
    /// areas of the triangles around it.
    pub control_areas: Vec<f64>,
}

impl Surface {
    /// Total surface area (m^2), as the sum of the control areas (each triangle's area is
    /// split in three equal parts among its corners). This is the area of the geometry the
    /// surface was built from; for the area of moved nodes use
    /// [`Surface::area_from_nodes`].
    pub fn area(&self) -> f64 {
        self.control_areas.iter().sum()
    }

    /// Total area (m^2) of the triangles at the given node positions.
    ///
    /// # Panics
    /// If a triangle refers to a node beyond `nodes`.
    pub fn area_from_nodes(&self, nodes: &[[f64; 3]]) -> f64 {
        self.triangles
            .iter()
            .map(|&[a, b, c]| triangle_area(nodes[a], nodes[b], nodes[c]))
            .sum()
    }

    /// Builds a surface from outward triangles: collects the sorted unique node ids and
    /// gives each one third of the area of every triangle around it.
    ///
    /// # Panics
    /// If a triangle refers to a node beyond `nodes`.
    pub fn from_triangles(triangles: Vec<[usize; 3]>, nodes: &[[f64; 3]]) -> Surface {
        let mut ids: Vec<usize> = triangles.iter().flatten().copied().collect();
        ids.sort_unstable();
        ids.dedup();
        // Map node id -> position in `ids` through a dense table over the id range.
        let max = ids.last().map_or(0, |&m| m + 1);
        let mut slot = vec![usize::MAX; max];
        for (k, &i) in ids.iter().enumerate() {
            slot[i] = k;
        }
        let mut control_areas = vec![0.0; ids.len()];
        for &[a, b, c] in &triangles {
            let third = triangle_area(nodes[a], nodes[b], nodes[c]) / 3.0;
            for i in [a, b, c] {
                control_areas[slot[i]] += third;
            }
        }
        Surface {
            triangles,
            nodes: ids,
            control_areas,
        }
    }
}

/// Quality figures of a tetrahedral mesh, computed from the corner nodes (straight edges).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeshQuality {
    /// Sum of the signed element volumes (m^3).
    pub volume: f64,
    /// Area of the surface triangles (m^2).
    pub surface_area: f64,
    /// Shortest corner-to-corner element edge (m).
    pub min_edge: f64,
    /// Longest corner-to-corner element edge (m).
    pub max_edge: f64,
    /// Smallest distance from an element corner to the plane of its opposite face (m);
    /// this bounds the stable explicit time step.
    pub min_altitude: f64,
    /// Smallest interior dihedral angle over all elements (degrees).
    pub min_dihedral_deg: f64,
    /// Largest interior dihedral angle over all elements (degrees).
    pub max_dihedral_deg: f64,
    /// Largest element aspect ratio: an element's longest edge over its smallest altitude,
    /// divided by that ratio of the regular tetrahedron (`sqrt(3/2)`), so 1 for a regular
    /// tetrahedron and unbounded for a flat one.
    pub max_aspect_ratio: f64,
}
