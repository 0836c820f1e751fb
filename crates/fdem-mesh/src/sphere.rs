//! Tetrahedral meshes of spheres: a subdivided icosahedron plus one centre node, optionally
//! refined along the radius into concentric shells.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

use crate::geometry::{dot, midpoint, norm};
use crate::{ElementOrder, MeshError, Surface, TetMesh};

/// Largest supported subdivision level (5120 tetrahedra).
pub const MAX_LEVEL: u32 = 4;

/// Largest supported number of concentric shells ([`sphere_mesh_in_shells`]).
pub const MAX_SHELLS: u32 = 8;

/// How the mesh is sized relative to the nominal sphere of diameter `d`.
///
/// Specimen counts (how many particles fill a given solid fraction) always use the nominal
/// sphere volume `pi d^3 / 6`; the sizing decides how much real solid each particle holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Sizing {
    /// Surface vertices lie on the sphere of the nominal diameter (the polyhedron is
    /// inscribed). The mesh holds less than the sphere: 0.6055 of it at level 0, 0.8735 at
    /// level 1, 0.9662 at level 2. A specimen of nominal solid fraction `phi` then has a
    /// real solid fraction of about `phi` times that ratio (0.65 x 0.8735 = 0.57 for the
    /// source paper's level-1 particles). This is the paper's reading and the default.
    #[default]
    Inscribed,
    /// The mesh is scaled uniformly so that its volume equals `pi d^3 / 6`. Vertices then
    /// lie slightly outside the nominal sphere, and the real solid fraction equals the
    /// nominal one.
    VolumeEquivalent,
}

/// What sphere to mesh.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SphereSpec {
    /// Icosahedron subdivision level, `0..=MAX_LEVEL`: 20 * 4^level tetrahedra.
    pub level: u32,
    /// Element order.
    pub order: ElementOrder,
    /// Nominal sphere diameter (m), finite and > 0.
    pub diameter: f64,
    /// How the mesh relates to the nominal sphere.
    #[serde(default)]
    pub sizing: Sizing,
}

impl SphereSpec {
    /// The source paper's particle: level 1, quadratic (80 tets, 205 nodes), inscribed.
    pub fn paper(diameter: f64) -> SphereSpec {
        SphereSpec {
            level: 1,
            order: ElementOrder::Quadratic,
            diameter,
            sizing: Sizing::Inscribed,
        }
    }
}

/// Meshes a sphere centred at the origin: [`sphere_mesh_in_shells`] with one shell, the
/// source paper's particle.
///
/// The surface is an icosahedron subdivided `level` times (each triangle split in four,
/// new vertices projected on the sphere); every surface triangle and the centre node form
/// one tetrahedron. Quadratic meshes add one node at the midpoint of every straight edge,
/// shared by the elements around that edge.
///
/// Node numbering: surface vertices first, then (quadratic only) the mid-edge nodes of the
/// surface edges, then the centre node, then (quadratic only) the mid-edge nodes of the
/// radial edges in the order of their surface vertex. Hence the surface nodes are exactly
/// `0..surface.nodes.len()`. Element `f` is built on surface face `f` with corners
/// `[centre, a, b, c]` where `a b c` is the face seen counter-clockwise from outside.
///
/// | level | tets | linear nodes | quadratic nodes |
/// |---|---|---|---|
/// | 0 | 20 | 13 | 55 |
/// | 1 | 80 | 43 | 205 |
/// | 2 | 320 | 163 | 805 |
/// | 3 | 1280 | 643 | 3205 |
/// | 4 | 5120 | 2563 | 12805 |
///
/// # Errors
/// [`MeshError::LevelOutOfRange`] for a level above [`MAX_LEVEL`],
/// [`MeshError::InvalidDiameter`] for a diameter that is not finite and positive.
pub fn sphere_mesh(spec: &SphereSpec) -> Result<TetMesh, MeshError> {
    sphere_mesh_in_shells(spec, 1)
}

/// Meshes a sphere centred at the origin in `shells` concentric layers of tetrahedra.
///
/// The outer surface is [`sphere_mesh`]'s, node for node (same ids, positions, triangles
/// and control areas) for any number of shells; only the interior is refined along the
/// radius. Inner shell `s` (`1..shells`) is the surface icosphere scaled to the radius
/// `r_s = s R / shells` (equal thickness; `R` the radius of the surface vertices). The
/// innermost layer joins shell 1 to the centre node (one tetrahedron per face, as in the
/// one-shell mesh); every other layer is one prism per surface face between shells `s` and
/// `s + 1`, split into three tetrahedra by the vertex-order rule: for a face with surface
/// vertex ids `p < q < r` (lower case on the inner shell, upper case on the outer one) the
/// tetrahedra are `p q r R`, `p q Q R` and `p P Q R`, so the quadrilateral over the edge
/// `i < j` is always cut along `i`-inner to `j`-outer and neighbouring prisms conform.
/// Quadratic elements have their mid-edge nodes at the midpoints of the straight edges.
///
/// Node numbering: the surface nodes as in [`sphere_mesh`] (vertices, then for quadratic
/// meshes the surface mid-edge nodes), the centre node, the vertices of inner shells
/// `1..shells` (shell by shell, in surface-vertex order), then (quadratic only) the
/// mid-edge nodes of the innermost layer's radial edges in surface-vertex order and the
/// remaining mid-edge nodes in order of first use by the elements. Elements: the innermost
/// layer (one per face, in face order), then each prism layer outward (three per face).
/// With `shells = k` a mesh of `F` faces and `V` surface vertices has `F (3k - 2)`
/// tetrahedra and `k V + 1` corner nodes.
///
/// # Errors
/// As [`sphere_mesh`], and [`MeshError::ShellsOutOfRange`] unless
/// `1 <= shells <= MAX_SHELLS`.
pub fn sphere_mesh_in_shells(spec: &SphereSpec, shells: u32) -> Result<TetMesh, MeshError> {
    if spec.level > MAX_LEVEL {
        return Err(MeshError::LevelOutOfRange {
            level: spec.level,
            max: MAX_LEVEL,
        });
    }
    if !(1..=MAX_SHELLS).contains(&shells) {
        return Err(MeshError::ShellsOutOfRange {
            shells,
            max: MAX_SHELLS,
        });
    }
    if !(spec.diameter.is_finite() && spec.diameter > 0.0) {
        return Err(MeshError::InvalidDiameter {
            diameter: spec.diameter,
        });
    }
    let (unit_vertices, faces) = icosphere(spec.level);
    let radius = outer_radius(spec, &unit_vertices, &faces);
    let layout = ShellLayout {
        n_vertices: unit_vertices.len(),
        shells: shells as usize,
        // Quadratic meshes number the surface mid-edge nodes before the centre.
        centre: unit_vertices.len()
            + match spec.order {
                ElementOrder::Linear => 0,
                ElementOrder::Quadratic => 3 * faces.len() / 2,
            },
    };
    let mut nodes: Vec<[f64; 3]> = unit_vertices.iter().map(|&p| scaled(radius, p)).collect();
    let mut mids = match spec.order {
        ElementOrder::Linear => HashMap::new(),
        ElementOrder::Quadratic => surface_mid_edge_nodes(&faces, &mut nodes),
    };
    debug_assert_eq!(nodes.len(), layout.centre);
    nodes.push([0.0; 3]);
    for s in 1..layout.shells {
        let r = radius * s as f64 / layout.shells as f64;
        nodes.extend(unit_vertices.iter().map(|&p| scaled(r, p)));
    }
    let corners = shell_tetrahedra(&faces, &layout, &nodes);
    match spec.order {
        ElementOrder::Linear => {
            let surface = Surface::from_triangles(faces, &nodes);
            Ok(TetMesh {
                order: ElementOrder::Linear,
                nodes,
                elements: corners.into_iter().flatten().collect(),
                surface,
            })
        }
        ElementOrder::Quadratic => {
            let elements = quadratic_elements(&corners, &layout, &mut mids, &mut nodes);
            let surface = Surface::from_triangles(quadratic_surface(&faces, &mids), &nodes);
            Ok(TetMesh {
                order: ElementOrder::Quadratic,
                nodes,
                elements,
                surface,
            })
        }
    }
}

/// Radius of the surface vertices for the sizing: the nominal radius (inscribed), or the
/// radius that gives the unit polyhedron the volume `pi d^3 / 6` (volume equivalent).
fn outer_radius(spec: &SphereSpec, unit_vertices: &[[f64; 3]], faces: &[[usize; 3]]) -> f64 {
    let radius = 0.5 * spec.diameter;
    match spec.sizing {
        Sizing::Inscribed => radius,
        Sizing::VolumeEquivalent => {
            // Volume of the unit-radius polyhedron: sum of the centre-based tets.
            let unit_volume: f64 = faces
                .iter()
                .map(|&[a, b, c]| {
                    let (pa, pb, pc) = (unit_vertices[a], unit_vertices[b], unit_vertices[c]);
                    dot(pa, crate::geometry::cross(pb, pc)) / 6.0
                })
                .sum();
            radius * (4.0 / 3.0 * std::f64::consts::PI / unit_volume).cbrt()
        }
    }
}

fn scaled(r: f64, p: [f64; 3]) -> [f64; 3] {
    [r * p[0], r * p[1], r * p[2]]
}

/// Where the corner nodes of a shelled sphere are numbered.
struct ShellLayout {
    /// Vertices per shell (the icosphere's).
    n_vertices: usize,
    /// Number of shells, >= 1.
    shells: usize,
    /// Id of the centre node; the inner shells' vertices follow it.
    centre: usize,
}

impl ShellLayout {
    /// Node id of icosphere vertex `v` on shell `s` (`1..=shells`; `shells` is the surface).
    fn vertex(&self, s: usize, v: usize) -> usize {
        if s == self.shells {
            v
        } else {
            self.centre + 1 + (s - 1) * self.n_vertices + v
        }
    }
}

/// Corner nodes of every tetrahedron, positively oriented: the innermost layer
/// `[centre, a, b, c]` per face, then three tetrahedra per face and prism layer (the
/// vertex-order split of [`sphere_mesh_in_shells`]).
fn shell_tetrahedra(
    faces: &[[usize; 3]],
    layout: &ShellLayout,
    nodes: &[[f64; 3]],
) -> Vec<[usize; 4]> {
    let mut tets = Vec::with_capacity(faces.len() * (3 * layout.shells - 2));
    for &[a, b, c] in faces {
        tets.push([layout.centre, a, b, c].map(|v| {
            if v == layout.centre {
                v
            } else {
                layout.vertex(1, v)
            }
        }));
    }
    for s in 1..layout.shells {
        for face in faces {
            let mut sorted = *face;
            sorted.sort_unstable();
            let [p, q, r] = sorted.map(|v| layout.vertex(s, v));
            let [pp, qq, rr] = sorted.map(|v| layout.vertex(s + 1, v));
            for tet in [[p, q, r, rr], [p, q, qq, rr], [p, pp, qq, rr]] {
                tets.push(positively_oriented(tet, nodes));
            }
        }
    }
    tets
}

/// The tetrahedron with corners 2 and 3 swapped if its signed volume is negative.
fn positively_oriented(t: [usize; 4], nodes: &[[f64; 3]]) -> [usize; 4] {
    let v = crate::geometry::tet_signed_volume(nodes[t[0]], nodes[t[1]], nodes[t[2]], nodes[t[3]]);
    if v < 0.0 { [t[0], t[1], t[3], t[2]] } else { t }
}

/// Adds the midpoints of the surface edges to `nodes`, numbered in order of first
/// encounter over the faces (edges `ab`, `bc`, `ca` of each), and returns them by edge.
fn surface_mid_edge_nodes(
    faces: &[[usize; 3]],
    nodes: &mut Vec<[f64; 3]>,
) -> HashMap<(usize, usize), usize> {
    let mut mids = HashMap::new();
    for &[a, b, c] in faces {
        for (i, j) in [(a, b), (b, c), (c, a)] {
            mid_edge_node(&mut mids, nodes, i, j);
        }
    }
    mids
}

/// The mid-edge node of the edge `i`-`j`: the existing one, or a new node at the midpoint
/// of the straight edge.
fn mid_edge_node(
    mids: &mut HashMap<(usize, usize), usize>,
    nodes: &mut Vec<[f64; 3]>,
    i: usize,
    j: usize,
) -> usize {
    *mids.entry((i.min(j), i.max(j))).or_insert_with(|| {
        nodes.push(midpoint(nodes[i], nodes[j]));
        nodes.len() - 1
    })
}

/// 10-node elements on the corner tetrahedra: the innermost layer's radial mid-edge nodes
/// first (in surface-vertex order), then the others in order of first use; mid-edge nodes
/// in VTK_QUADRATIC_TETRA order ([`crate::TET_EDGES`]).
fn quadratic_elements(
    corners: &[[usize; 4]],
    layout: &ShellLayout,
    mids: &mut HashMap<(usize, usize), usize>,
    nodes: &mut Vec<[f64; 3]>,
) -> Vec<usize> {
    for v in 0..layout.n_vertices {
        mid_edge_node(mids, nodes, layout.centre, layout.vertex(1, v));
    }
    let mut elements = Vec::with_capacity(10 * corners.len());
    for t in corners {
        elements.extend_from_slice(t);
        for (i, j) in crate::TET_EDGES {
            elements.push(mid_edge_node(mids, nodes, t[i], t[j]));
        }
    }
    elements
}

/// The outward flat triangles of a quadratic sphere: each surface face `a b c` split into
/// `a ab ca`, `ab b bc`, `ca bc c` and `ab bc ca` (`ab` the mid-edge node of `a`-`b`).
fn quadratic_surface(
    faces: &[[usize; 3]],
    mids: &HashMap<(usize, usize), usize>,
) -> Vec<[usize; 3]> {
    let m = |a: usize, b: usize| mids[&(a.min(b), a.max(b))];
    let mut triangles = Vec::with_capacity(4 * faces.len());
    for &[a, b, c] in faces {
        let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
        triangles.push([a, ab, ca]);
        triangles.push([ab, b, bc]);
        triangles.push([ca, bc, c]);
        triangles.push([ab, bc, ca]);
    }
    triangles
}

/// Golden ratio.
const PHI: f64 = 1.618_033_988_749_895;

/// The 12 icosahedron vertices (before normalisation).
const ICO_VERTICES: [[f64; 3]; 12] = [
    [-1.0, PHI, 0.0],
    [1.0, PHI, 0.0],
    [-1.0, -PHI, 0.0],
    [1.0, -PHI, 0.0],
    [0.0, -1.0, PHI],
    [0.0, 1.0, PHI],
    [0.0, -1.0, -PHI],
    [0.0, 1.0, -PHI],
    [PHI, 0.0, -1.0],
    [PHI, 0.0, 1.0],
    [-PHI, 0.0, -1.0],
    [-PHI, 0.0, 1.0],
];

/// The 20 icosahedron faces, counter-clockwise seen from outside.
const ICO_FACES: [[usize; 3]; 20] = [
    [0, 11, 5],
    [0, 5, 1],
    [0, 1, 7],
    [0, 7, 10],
    [0, 10, 11],
    [1, 5, 9],
    [5, 11, 4],
    [11, 10, 2],
    [10, 7, 6],
    [7, 1, 8],
    [3, 9, 4],
    [3, 4, 2],
    [3, 2, 6],
    [3, 6, 8],
    [3, 8, 9],
    [4, 9, 5],
    [2, 4, 11],
    [6, 2, 10],
    [8, 6, 7],
    [9, 8, 1],
];

/// Unit-sphere icosphere: vertices on the unit sphere and outward faces.
fn icosphere(level: u32) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let unit = |p: [f64; 3]| {
        let n = norm(p);
        [p[0] / n, p[1] / n, p[2] / n]
    };
    let mut vertices: Vec<[f64; 3]> = ICO_VERTICES.iter().map(|&p| unit(p)).collect();
    let mut faces: Vec<[usize; 3]> = ICO_FACES.to_vec();
    for _ in 0..level {
        let mut cache: HashMap<(usize, usize), usize> = HashMap::new();
        let mut mid = |a: usize, b: usize, vertices: &mut Vec<[f64; 3]>| -> usize {
            let key = (a.min(b), a.max(b));
            *cache.entry(key).or_insert_with(|| {
                vertices.push(unit(midpoint(vertices[a], vertices[b])));
                vertices.len() - 1
            })
        };
        let mut next = Vec::with_capacity(4 * faces.len());
        for &[a, b, c] in &faces {
            let ab = mid(a, b, &mut vertices);
            let bc = mid(b, c, &mut vertices);
            let ca = mid(c, a, &mut vertices);
            next.push([a, ab, ca]);
            next.push([ab, b, bc]);
            next.push([ca, bc, c]);
            next.push([ab, bc, ca]);
        }
        faces = next;
    }
    (vertices, faces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{cross, sub};

    #[test]
    fn icosahedron_table_is_outward_and_regular() {
        let (v, f) = icosphere(0);
        let edge = crate::geometry::distance(v[0], v[1]);
        for &[a, b, c] in &f {
            let n = cross(sub(v[b], v[a]), sub(v[c], v[a]));
            assert!(dot(n, v[a]) > 0.0, "face {a} {b} {c} points inward");
            for (p, q) in [(a, b), (b, c), (c, a)] {
                let l = crate::geometry::distance(v[p], v[q]);
                assert!(
                    (l - edge).abs() < 1e-14,
                    "edge {p}-{q} has length {l}, not {edge}"
                );
            }
        }
    }
}
