//! Mesh builders and small helpers shared by the tests.

use std::collections::HashMap;

use fdem_elastic::{ElementSet, Mat3, Material};

/// Rock of docs/MODEL.md section 8: E = 40 GPa, nu = 0.2, rho = 2650 kg/m^3.
pub const E: f64 = 40e9;
pub const NU: f64 = 0.2;
pub const RHO: f64 = 2650.0;

pub fn rock() -> Material {
    Material::new(RHO, E, NU).unwrap()
}

/// Nodes and flat connectivity of one body.
#[derive(Debug, Clone)]
pub struct Mesh {
    pub nodes: Vec<[f64; 3]>,
    pub conn: Vec<usize>,
    pub npe: usize,
}

impl Mesh {
    pub fn element_set(&self) -> ElementSet {
        ElementSet::new(&rock(), self.npe, &self.nodes, &self.conn).unwrap()
    }
}

fn signed_volume(p: [[f64; 3]; 4]) -> f64 {
    let a = sub(p[1], p[0]);
    let b = sub(p[2], p[0]);
    let c = sub(p[3], p[0]);
    (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0]))
        / 6.0
}

pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// Cube of `n^3` cells of size `h` at the origin, each cell split into the 6 Kuhn
/// (Freudenthal) tetrahedra, which are conforming across cells. Corners positively
/// oriented. With `quadratic`, mid-edge nodes are added (shared between elements).
pub fn kuhn_cube(n: usize, h: f64, quadratic: bool) -> Mesh {
    let m = n + 1;
    let id = |i: usize, j: usize, k: usize| i + m * (j + m * k);
    let mut nodes = Vec::new();
    for k in 0..m {
        for j in 0..m {
            for i in 0..m {
                nodes.push([i as f64 * h, j as f64 * h, k as f64 * h]);
            }
        }
    }
    let perms = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut conn = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                for p in perms {
                    let mut c = [i, j, k];
                    let mut tet = [id(c[0], c[1], c[2]); 4];
                    for (s, axis) in p.iter().enumerate() {
                        c[*axis] += 1;
                        tet[s + 1] = id(c[0], c[1], c[2]);
                    }
                    let pts = tet.map(|t| nodes[t]);
                    if signed_volume(pts) < 0.0 {
                        tet.swap(1, 2);
                    }
                    conn.extend_from_slice(&tet);
                }
            }
        }
    }
    let mesh = Mesh {
        nodes,
        conn,
        npe: 4,
    };
    if quadratic {
        make_quadratic(&mesh)
    } else {
        mesh
    }
}

/// VTK_QUADRATIC_TETRA edge order.
pub const EDGES: [(usize, usize); 6] = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)];

/// Adds shared mid-edge nodes at edge midpoints.
pub fn make_quadratic(linear: &Mesh) -> Mesh {
    assert_eq!(linear.npe, 4);
    let mut nodes = linear.nodes.clone();
    let mut edge_ids: HashMap<(usize, usize), usize> = HashMap::new();
    let mut conn = Vec::new();
    for tet in linear.conn.chunks_exact(4) {
        conn.extend_from_slice(tet);
        for (a, b) in EDGES {
            let key = (tet[a].min(tet[b]), tet[a].max(tet[b]));
            let id = *edge_ids.entry(key).or_insert_with(|| {
                let (p, q) = (linear.nodes[tet[a]], linear.nodes[tet[b]]);
                nodes.push([
                    0.5 * (p[0] + q[0]),
                    0.5 * (p[1] + q[1]),
                    0.5 * (p[2] + q[2]),
                ]);
                nodes.len() - 1
            });
            conn.push(id);
        }
    }
    Mesh {
        nodes,
        conn,
        npe: 10,
    }
}

/// One irregular, positively oriented tetrahedron with edges of about 5 mm (a level-1
/// particle of d = 15 mm has edges of about 4-5 mm).
pub fn single_tet(quadratic: bool) -> Mesh {
    let s = 5e-3;
    let nodes = vec![
        [0.1 * s, 0.05 * s, 0.0],
        [1.05 * s, 0.1 * s, 0.05 * s],
        [0.3 * s, 0.95 * s, -0.05 * s],
        [0.2 * s, 0.25 * s, 0.9 * s],
    ];
    let mesh = Mesh {
        nodes,
        conn: vec![0, 1, 2, 3],
        npe: 4,
    };
    if quadratic {
        make_quadratic(&mesh)
    } else {
        mesh
    }
}

/// Rotation about `axis` by `angle` (Rodrigues).
pub fn rotation(axis: [f64; 3], angle: f64) -> Mat3 {
    let n = norm(axis);
    let (x, y, z) = (axis[0] / n, axis[1] / n, axis[2] / n);
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

/// Rotation of the unit quaternion `q / |q|` (w, x, y, z).
pub fn quat_rotation(q: [f64; 4]) -> Mat3 {
    fdem_core::geometry::rotation_matrix(q)
}

pub fn matvec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

pub fn matmul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

pub fn transpose(m: &Mat3) -> Mat3 {
    let mut t = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            t[i][j] = m[j][i];
        }
    }
    t
}

/// `x = Q X + t` for every node.
pub fn rigid(nodes: &[[f64; 3]], q: &Mat3, t: [f64; 3]) -> Vec<[f64; 3]> {
    nodes
        .iter()
        .map(|&p| {
            let r = matvec(q, p);
            [r[0] + t[0], r[1] + t[1], r[2] + t[2]]
        })
        .collect()
}

/// `x = X + A X` for every node.
pub fn linear_field(nodes: &[[f64; 3]], a: &Mat3) -> Vec<[f64; 3]> {
    nodes
        .iter()
        .map(|&p| {
            let d = matvec(a, p);
            [p[0] + d[0], p[1] + d[1], p[2] + d[2]]
        })
        .collect()
}

/// Voigt (xx, yy, zz, yz, xz, xy) to a symmetric matrix.
pub fn from_voigt(s: [f64; 6]) -> Mat3 {
    [[s[0], s[5], s[4]], [s[5], s[1], s[3]], [s[4], s[3], s[2]]]
}

/// Isotropic `C : eps` for a symmetric strain.
pub fn hooke(m: &Material, eps: &Mat3) -> Mat3 {
    let (l, g) = (m.lame_lambda(), m.shear_modulus());
    let tr = eps[0][0] + eps[1][1] + eps[2][2];
    let mut s = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            s[i][j] = 2.0 * g * eps[i][j] + if i == j { l * tr } else { 0.0 };
        }
    }
    s
}

pub fn max_abs(m: &Mat3) -> f64 {
    m.iter().flatten().fold(0.0_f64, |a, v| a.max(v.abs()))
}

pub fn max_force(f: &[[f64; 3]]) -> f64 {
    f.iter().map(|v| norm(*v)).fold(0.0, f64::max)
}

/// Deterministic pseudo-random numbers in [-1, 1) (64-bit LCG, Knuth's constants).
pub struct Lcg(pub u64);

impl Lcg {
    pub fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// Assembled global stiffness (dense, dof 3 i + k) from the element matrices.
pub fn assemble_stiffness(set: &ElementSet) -> nalgebra::DMatrix<f64> {
    let n = 3 * set.n_nodes();
    let mut k = nalgebra::DMatrix::zeros(n, n);
    for e in 0..set.n_elements() {
        let ke = set.element_stiffness(e).unwrap();
        let nodes = set.element_nodes(e).unwrap();
        for (a, &na) in nodes.iter().enumerate() {
            for (b, &nb) in nodes.iter().enumerate() {
                for i in 0..3 {
                    for j in 0..3 {
                        k[(3 * na + i, 3 * nb + j)] += ke[(3 * a + i, 3 * b + j)];
                    }
                }
            }
        }
    }
    k
}

/// Elastic forces for given positions (fresh zeroed buffer).
pub fn forces(set: &ElementSet, x: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mut f = vec![[0.0; 3]; x.len()];
    set.add_forces(x, &mut f).unwrap();
    f
}
