//! Free vibration of one body about its rest state: the mass-scaled rest stiffness and a
//! block Lanczos estimate of the vibration modes that given displacement shapes excite.
//!
//! The linearised free body obeys `M u'' + K u = 0` (`K` the rest stiffness, the
//! co-rotational tangent at rest; `M` the lumped masses), so its modes solve
//! `K x = omega^2 M x`, or with `y = M^1/2 x` the symmetric problem
//! `A y = omega^2 y`, `A = M^-1/2 K M^-1/2`. [`MassScaledStiffness`] applies `A` element by
//! element, for the stable step's power iteration (`assembled_step`) and for
//! [`ElementSet::vibration_modes`].

use nalgebra::{DMatrix, SymmetricEigen};

use crate::ElementSet;

/// `A = M^-1/2 K M^-1/2` of one body, applied element by element from the element rest
/// stiffness matrices (no assembly).
pub(crate) struct MassScaledStiffness {
    /// `1 / sqrt(m_i)` per node (0 for massless nodes).
    pub(crate) scale: Vec<f64>,
    /// Element matrices, row-major `3N x 3N`, concatenated.
    stiffness: Vec<f64>,
    /// Body-local node ids, `N` per element.
    nodes: Vec<usize>,
    /// Nodes per element `N`.
    npe: usize,
}

impl MassScaledStiffness {
    /// The operator of `set` with its lumped masses.
    pub(crate) fn new(set: &ElementSet) -> MassScaledStiffness {
        let scale = set
            .lumped_masses(set.n_nodes())
            .iter()
            .map(|&m| if m > 0.0 { 1.0 / m.sqrt() } else { 0.0 })
            .collect();
        let (stiffness, nodes) = set.rest_stiffness_and_nodes();
        MassScaledStiffness {
            scale,
            stiffness,
            nodes,
            npe: set.nodes_per_element(),
        }
    }

    /// `ay = A y` (both of length `3 n`, degree of freedom `3 i + k`).
    pub(crate) fn apply(&self, y: &[f64], ay: &mut [f64]) {
        ay.fill(0.0);
        let dofs = 3 * self.npe;
        for (k, ids) in self
            .stiffness
            .chunks_exact(dofs * dofs)
            .zip(self.nodes.chunks_exact(self.npe))
        {
            for (row, k_row) in k.chunks_exact(dofs).enumerate() {
                let mut sum = 0.0;
                for (col, &kv) in k_row.iter().enumerate() {
                    let j = ids[col / 3];
                    sum += kv * self.scale[j] * y[3 * j + col % 3];
                }
                let i = ids[row / 3];
                ay[3 * i + row % 3] += self.scale[i] * sum;
            }
        }
    }
}

/// One result of [`ElementSet::vibration_modes`].
#[derive(Clone, Debug, PartialEq)]
pub struct VibrationMode {
    /// Angular frequency `omega = sqrt(theta)`, rad/s, `theta` the Ritz value.
    pub angular_frequency: f64,
    /// Residual norm of the Ritz pair over the Ritz value, `|A y - theta y| / theta`: an
    /// eigenvalue of `A` lies within this relative distance of `theta` (Krylov–Bogoliubov),
    /// so `omega` is within about half of it of a frequency of the body.
    pub relative_residual: f64,
    /// Share of this mode in the (mass-weighted, rigid-motion-free) start block: the
    /// squared norm of its components on the start vectors, in [0, 1].
    pub weight: f64,
    /// Products with the stiffness taken (the size of the Ritz basis).
    pub steps: usize,
    /// The mode shape (node displacements, unit mass norm `sum m_i |x_i|^2 = 1`).
    pub shape: Vec<[f64; 3]>,
}

/// Relative residual at which [`ElementSet::vibration_modes`] stops.
pub const VIBRATION_MODE_TOLERANCE: f64 = 1e-3;

impl ElementSet {
    /// The `b` vibration modes of the free body that the `b` displacement shapes `starts`
    /// excite most, lowest first: block Lanczos on `A = M^-1/2 K M^-1/2` (see the module
    /// docs) from the vectors `M^1/2 u`, `u` in `starts`, every vector kept orthogonal
    /// (full Gram–Schmidt, twice: "twice is enough") to the previous ones and to the six
    /// rigid motions about the centre of mass of `positions` (the rest positions). The
    /// basis `Q` grows by one vector per product (`q_{b+i}` from `A q_i`), so
    /// `H = Q^T A Q` is banded and known from the Gram–Schmidt coefficients. Every few
    /// steps the Rayleigh–Ritz pairs `(theta, s)` of `H` are computed and the `b` pairs
    /// with the largest share of the start block (the squared norm of the first `b`
    /// components of `s`) are kept; the residual of a pair is `|H_{m+1..m+b, 1..m} s|`
    /// (the part of `A Q s` outside the basis). A block finds a cluster of nearly equal
    /// frequencies (a degenerate mode split by the mesh) at once. The iteration stops when
    /// every kept pair's relative residual is at most [`VIBRATION_MODE_TOLERANCE`] or
    /// after `max_steps` products.
    ///
    /// # Panics
    /// If `positions` or a start shape does not have one entry per node, or the start
    /// shapes are linearly dependent modulo rigid motions.
    pub fn vibration_modes(
        &self,
        positions: &[[f64; 3]],
        starts: &[Vec<[f64; 3]>],
        max_steps: usize,
    ) -> Vec<VibrationMode> {
        let n = self.n_nodes();
        let b = starts.len();
        assert!(positions.len() == n && starts.iter().all(|u| u.len() == n));
        let op = MassScaledStiffness::new(self);
        let rigid = rigid_basis(positions, &op.scale);
        let mut basis: Vec<Vec<f64>> = Vec::new();
        for u in starts {
            let mut q: Vec<f64> = (0..3 * n)
                .map(|i| u[i / 3][i % 3] * nonzero_reciprocal(op.scale[i / 3]))
                .collect();
            for _ in 0..2 {
                orthogonalise(&mut q, &rigid);
                orthogonalise(&mut q, &basis);
            }
            assert!(normalise(&mut q) > 0.0, "dependent start shapes");
            basis.push(q);
        }
        // Column i of H: coefficients of A q_i on q_0..q_{b+i}.
        let mut h: Vec<Vec<f64>> = Vec::new();
        let mut w = vec![0.0; 3 * n];
        let mut best = Vec::new();
        let max_steps = max_steps.max(b);
        let mut next_check = b;
        for step in 1..=max_steps {
            let i = step - 1;
            op.apply(&basis[i], &mut w);
            let mut column = vec![0.0; basis.len() + 1];
            for _ in 0..2 {
                orthogonalise(&mut w, &rigid);
                for (c, q) in column.iter_mut().zip(&basis) {
                    let x = dot(&w, q);
                    *c += x;
                    w.iter_mut().zip(q).for_each(|(wi, qi)| *wi -= x * qi);
                }
            }
            let norm = normalise(&mut w);
            // A vector already in the span (an exactly invariant subspace) is dropped: a
            // zero basis vector keeps the numbering and adds nothing.
            if norm <= 1e-12 * h.first().map_or(norm, |c: &Vec<f64>| c[0].abs()) {
                w.fill(0.0);
                column[basis.len()] = 0.0;
            } else {
                column[basis.len()] = norm;
            }
            h.push(column);
            basis.push(w.clone());
            if step == next_check || step == max_steps {
                // Checks at b, then every 5 steps or every tenth of the basis, whichever
                // is longer (each check is a dense m x m eigenproblem).
                next_check = step + 5.max(step / 10);
                best = best_ritz_pairs(&h, b);
                if best
                    .iter()
                    .all(|p| p.relative_residual <= VIBRATION_MODE_TOLERANCE)
                {
                    break;
                }
            }
        }
        best.iter()
            .map(|pair| mode_from_ritz(pair, &basis, &op.scale))
            .collect()
    }
}

/// The [`VibrationMode`] of a Ritz pair: its vector `Q s` back in displacements.
fn mode_from_ritz(pair: &RitzPair, basis: &[Vec<f64>], scale: &[f64]) -> VibrationMode {
    let mut y = vec![0.0; basis[0].len()];
    for (s, q) in pair.vector.iter().zip(basis) {
        y.iter_mut().zip(q).for_each(|(yi, qi)| *yi += s * qi);
    }
    let shape = (0..y.len() / 3)
        .map(|i| std::array::from_fn(|k| y[3 * i + k] * scale[i]))
        .collect();
    VibrationMode {
        angular_frequency: pair.value.max(0.0).sqrt(),
        relative_residual: pair.relative_residual,
        weight: pair.weight,
        steps: pair.vector.len(),
        shape,
    }
}

/// One Rayleigh–Ritz pair of `H = Q^T A Q`.
struct RitzPair {
    value: f64,
    relative_residual: f64,
    weight: f64,
    /// Eigenvector of `H` (coefficients of the basis vectors).
    vector: Vec<f64>,
}

/// The `b` Ritz pairs of the leading `m x m` block of `H` (`m` = number of columns of
/// `h`, symmetrised) with the largest share of the first `b` basis vectors, lowest first.
fn best_ritz_pairs(h: &[Vec<f64>], b: usize) -> Vec<RitzPair> {
    let m = h.len();
    let entry = |k: usize, i: usize| h[i].get(k).copied().unwrap_or(0.0);
    let t = DMatrix::from_fn(m, m, |k, i| 0.5 * (entry(k, i) + entry(i, k)));
    let eig = SymmetricEigen::new(t);
    let mut pairs: Vec<RitzPair> = (0..m)
        .map(|j| {
            let s: Vec<f64> = eig.eigenvectors.column(j).iter().copied().collect();
            let value = eig.eigenvalues[j];
            // Residual: components of A Q s on the basis vectors beyond m.
            let outside: f64 = (m..m + b)
                .map(|k| (0..m).map(|i| entry(k, i) * s[i]).sum::<f64>().powi(2))
                .sum();
            RitzPair {
                value,
                relative_residual: outside.sqrt() / value.abs(),
                weight: s[..b.min(m)].iter().map(|x| x * x).sum(),
                vector: s,
            }
        })
        .collect();
    pairs.sort_by(|p, q| q.weight.total_cmp(&p.weight));
    pairs.truncate(b);
    pairs.sort_by(|p, q| p.value.total_cmp(&q.value));
    pairs
}

/// An orthonormal basis (Euclidean, in mass-scaled coordinates `y = M^1/2 u`) of the six
/// rigid motions of nodes at `positions` about their centre of mass: translations `e_k`
/// and rotations `e_k x (x - c)`. `scale` holds `1 / sqrt(m_i)`.
fn rigid_basis(positions: &[[f64; 3]], scale: &[f64]) -> Vec<Vec<f64>> {
    let mass: Vec<f64> = scale
        .iter()
        .map(|&s| nonzero_reciprocal(s).powi(2))
        .collect();
    let total: f64 = mass.iter().sum();
    let c: [f64; 3] = std::array::from_fn(|k| {
        positions
            .iter()
            .zip(&mass)
            .map(|(x, m)| m * x[k])
            .sum::<f64>()
            / total
    });
    let mut basis: Vec<Vec<f64>> = Vec::with_capacity(6);
    for k in 0..6 {
        let mut v: Vec<f64> = (0..3 * positions.len())
            .map(|i| {
                let (node, dir) = (i / 3, i % 3);
                let u = if k < 3 {
                    f64::from(u8::from(dir == k))
                } else {
                    // (e_a x r)_dir with a = k - 3, r = x - c.
                    let r: [f64; 3] = std::array::from_fn(|d| positions[node][d] - c[d]);
                    let a = k - 3;
                    let (b, e) = ((a + 1) % 3, (a + 2) % 3);
                    if dir == b {
                        -r[e]
                    } else if dir == e {
                        r[b]
                    } else {
                        0.0
                    }
                };
                u * nonzero_reciprocal(scale[node])
            })
            .collect();
        orthogonalise(&mut v, &basis);
        normalise(&mut v);
        basis.push(v);
    }
    basis
}

/// `1 / s`, or 0 for `s = 0` (`sqrt(m)` from `1 / sqrt(m)`, massless nodes kept at 0).
fn nonzero_reciprocal(s: f64) -> f64 {
    if s > 0.0 { 1.0 / s } else { 0.0 }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Removes from `v` its components along the orthonormal vectors `basis`.
fn orthogonalise(v: &mut [f64], basis: &[Vec<f64>]) {
    for b in basis {
        let c = dot(v, b);
        v.iter_mut().zip(b).for_each(|(x, y)| *x -= c * y);
    }
}

/// Scales `v` to unit norm and returns the former norm (`v` unchanged if it is 0).
fn normalise(v: &mut [f64]) -> f64 {
    let norm = dot(v, v).sqrt();
    if norm > 0.0 {
        v.iter_mut().for_each(|x| *x /= norm);
    }
    norm
}
