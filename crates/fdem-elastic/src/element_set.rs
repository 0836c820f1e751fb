//! All elements of one body, with reference data precomputed once.

use nalgebra::DMatrix;

use crate::ElasticError;
use crate::kernels::{
    EDGES, Lame, TetRef, element_time_step, reference_stiffness, tet4_energy, tet4_stress,
    tet10_energy, tet10_stress,
};
use crate::lanes::{Linear, Path, Quadratic, Tet4Block, Tet10Block, add_block_forces};
use crate::mat3::{Mat3, cofactor, det, dot, sub, transpose};
use crate::material::Material;

/// Element type of an [`ElementSet`]. [`ElementSet::new`] takes the equivalent
/// `nodes_per_element` (4 or 10); see [`TetKind::from_nodes_per_element`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TetKind {
    /// 4-node linear tetrahedron; corner nodes positively oriented.
    Linear4,
    /// 10-node quadratic tetrahedron, corners 0..3 then mid-edge nodes in
    /// VTK_QUADRATIC_TETRA order 4:(0,1) 5:(1,2) 6:(0,2) 7:(0,3) 8:(1,3) 9:(2,3);
    /// straight-sided in the rest configuration.
    Quadratic10,
}

impl TetKind {
    /// `4 -> Linear4`, `10 -> Quadratic10`, anything else is an error.
    pub fn from_nodes_per_element(nodes_per_element: usize) -> Result<Self, ElasticError> {
        match nodes_per_element {
            4 => Ok(Self::Linear4),
            10 => Ok(Self::Quadratic10),
            _ => Err(ElasticError::UnsupportedElement { nodes_per_element }),
        }
    }

    /// 4 or 10.
    pub fn nodes_per_element(self) -> usize {
        match self {
            Self::Linear4 => 4,
            Self::Quadratic10 => 10,
        }
    }
}

/// HRZ lumped-mass fractions of a straight-sided 10-node tetrahedron (Hinton, Rock &
/// Zienkiewicz 1976): the consistent mass diagonal is `rho V / 70` at a corner and
/// `8 rho V / 105` at a mid-edge node (`integral N_i^2 dV`), which sums to `18/35 rho V` per
/// direction; scaling it to the element mass gives `m/36` per corner and `4m/27` per mid-edge
/// node (`4/36 + 6 * 4/27 = 1`).
pub const HRZ_CORNER_FRACTION: f64 = 1.0 / 36.0;
/// See [`HRZ_CORNER_FRACTION`].
pub const HRZ_MID_EDGE_FRACTION: f64 = 4.0 / 27.0;

/// Relative flatness below which a rest element is rejected: `6 V < 1e-10 l_max^3`.
const DEGENERATE_RATIO: f64 = 1e-10;
/// Mid-edge nodes must be within this fraction of the edge length from the midpoint.
const MID_EDGE_TOLERANCE: f64 = 1e-9;

#[derive(Debug, Clone)]
enum Elements {
    Linear(Vec<TetRef<4>>),
    Quadratic(Vec<TetRef<10>>),
}

/// Lumped nodal masses, kg, of a body's mesh (one entry per rest position): the values
/// and errors of [`ElementSet::new`] followed by [`ElementSet::lumped_masses`], without the
/// rest of a set (each element's stable step, the lane kernel's blocks). A rigid body's
/// nodes need only these.
pub fn lumped_masses(
    material: &Material,
    nodes_per_element: usize,
    rest_positions: &[[f64; 3]],
    connectivity: &[usize],
) -> Result<Vec<f64>, ElasticError> {
    let (_, elements) =
        checked_elements(material, nodes_per_element, rest_positions, connectivity)?;
    Ok(lumped(&elements, material.density, rest_positions.len()))
}

/// The checks of [`ElementSet::new`] and its elements' reference data.
fn checked_elements(
    material: &Material,
    nodes_per_element: usize,
    rest_positions: &[[f64; 3]],
    connectivity: &[usize],
) -> Result<(TetKind, Elements), ElasticError> {
    material.validate()?;
    let kind = TetKind::from_nodes_per_element(nodes_per_element)?;
    if !connectivity.len().is_multiple_of(nodes_per_element) {
        return Err(ElasticError::ConnectivityLength {
            len: connectivity.len(),
            nodes_per_element,
        });
    }
    let n_nodes = rest_positions.len();
    if n_nodes > u32::MAX as usize {
        return Err(ElasticError::TooManyNodes {
            n_nodes,
            max: u32::MAX as usize,
        });
    }
    for (node, p) in rest_positions.iter().enumerate() {
        if !p.iter().all(|v| v.is_finite()) {
            return Err(ElasticError::NonFiniteRestPosition { node, position: *p });
        }
    }
    let elements = match kind {
        TetKind::Linear4 => Elements::Linear(build::<4>(rest_positions, connectivity)?),
        TetKind::Quadratic10 => Elements::Quadratic(build::<10>(rest_positions, connectivity)?),
    };
    Ok((kind, elements))
}

/// Lumped nodal masses of `elements` of density `rho`, `len` entries (see
/// [`ElementSet::lumped_masses`]).
fn lumped(elements: &Elements, rho: f64, len: usize) -> Vec<f64> {
    let mut m = vec![0.0; len];
    match elements {
        Elements::Linear(els) => {
            for el in els {
                let share = 0.25 * rho * el.volume;
                for &n in &el.nodes {
                    m[n as usize] += share;
                }
            }
        }
        Elements::Quadratic(els) => {
            for el in els {
                let me = rho * el.volume;
                for (i, &n) in el.nodes.iter().enumerate() {
                    m[n as usize] += me
                        * if i < 4 {
                            HRZ_CORNER_FRACTION
                        } else {
                            HRZ_MID_EDGE_FRACTION
                        };
                }
            }
        }
    }
    m
}

/// All elements of one body (particle, membrane, ...), with reference data precomputed
/// once: shape-function gradients, volumes, lumped masses and the per-element stable time
/// step. Node ids are body-local: indices into the node slice passed to every method.
///
/// Formulation: co-rotational linear elasticity (see the [crate documentation](crate)).
/// The set holds no per-step state, so every method takes `&self` and the set is
/// `Send + Sync`; bodies can be processed in parallel.
///
/// Element storage is compact and contiguous: node ids as `u32` plus three gradient
/// vectors and the volume, 96 bytes per linear and 120 bytes per quadratic element; the
/// elements are kept a second time in the lane kernel's blocks (98 bytes per linear and
/// 122 bytes per quadratic element).
#[derive(Debug, Clone)]
pub struct ElementSet {
    material: Material,
    lame: Lame,
    kind: TetKind,
    n_nodes: usize,
    elements: Elements,
    /// The linear elements again, in blocks for the lane kernel (empty for 10-node sets).
    blocks4: Vec<Tet4Block>,
    /// The quadratic elements again, in blocks for the lane kernel (empty for 4-node sets).
    blocks10: Vec<Tet10Block>,
    time_steps: Vec<f64>,
    stable_time_step: f64,
}

impl ElementSet {
    /// Builds the element set of one body.
    ///
    /// * `material`: validated with [`Material::validate`].
    /// * `nodes_per_element`: 4 (linear) or 10 (quadratic, VTK_QUADRATIC_TETRA order).
    /// * `rest_positions`: the body's nodes in the stress-free configuration, metres.
    /// * `connectivity`: `nodes_per_element` body-local node ids per element, corners
    ///   positively oriented.
    ///
    /// Rejects: an unsupported element type, a connectivity length that is not a multiple of
    /// `nodes_per_element`, out-of-range or repeated node ids, non-finite rest positions,
    /// inverted (negative volume) or degenerate (`6 V < 1e-10 l_max^3`) rest elements, and
    /// 10-node elements whose mid-edge nodes are further than `1e-9` edge lengths from the
    /// edge midpoints. Every error names the element (0-based, in connectivity order).
    ///
    /// An empty connectivity gives an empty set whose stable time step is `+inf`.
    ///
    /// Cost: one symmetric eigenvalue problem per element for the stable time step (6x6 for
    /// linear, 24x24 for quadratic elements; docs/PERFORMANCE.md, "Setting up", has its
    /// timing).
    pub fn new(
        material: &Material,
        nodes_per_element: usize,
        rest_positions: &[[f64; 3]],
        connectivity: &[usize],
    ) -> Result<Self, ElasticError> {
        let (kind, elements) =
            checked_elements(material, nodes_per_element, rest_positions, connectivity)?;
        let lame = Lame {
            lambda: material.lame_lambda(),
            mu: material.shear_modulus(),
        };
        let time_steps: Vec<f64> = match &elements {
            Elements::Linear(els) => els
                .iter()
                .map(|el| element_time_step(el, lame, material.density))
                .collect(),
            Elements::Quadratic(els) => els
                .iter()
                .map(|el| element_time_step(el, lame, material.density))
                .collect(),
        };
        let stable_time_step = time_steps.iter().copied().fold(f64::INFINITY, f64::min);
        let (blocks4, blocks10) = match &elements {
            Elements::Linear(els) => (Tet4Block::blocks(els), Vec::new()),
            Elements::Quadratic(els) => (Vec::new(), Tet10Block::blocks(els)),
        };
        Ok(Self {
            material: *material,
            lame,
            kind,
            n_nodes: rest_positions.len(),
            elements,
            blocks4,
            blocks10,
            time_steps,
            stable_time_step,
        })
    }

    /// Number of elements.
    pub fn n_elements(&self) -> usize {
        match &self.elements {
            Elements::Linear(e) => e.len(),
            Elements::Quadratic(e) => e.len(),
        }
    }

    /// Number of nodes of the body (length of `rest_positions` given to [`ElementSet::new`]);
    /// `positions` and `forces` passed to the methods must have exactly this length.
    pub fn n_nodes(&self) -> usize {
        self.n_nodes
    }

    /// Element type.
    pub fn kind(&self) -> TetKind {
        self.kind
    }

    /// 4 or 10.
    pub fn nodes_per_element(&self) -> usize {
        self.kind.nodes_per_element()
    }

    /// The material.
    pub fn material(&self) -> &Material {
        &self.material
    }

    /// Rest volume of every element, m^3.
    pub fn element_volumes(&self) -> Vec<f64> {
        match &self.elements {
            Elements::Linear(e) => e.iter().map(|el| el.volume).collect(),
            Elements::Quadratic(e) => e.iter().map(|el| el.volume).collect(),
        }
    }

    /// Total rest volume, m^3.
    pub fn total_volume(&self) -> f64 {
        self.element_volumes().iter().sum()
    }

    /// Total mass `density x total volume`, kg.
    pub fn total_mass(&self) -> f64 {
        self.material.density * self.total_volume()
    }

    /// Lumped nodal masses, kg, of length `n_nodes.max(self.n_nodes())` (nodes no element
    /// uses get 0). Each element's mass `m = density x V` is spread as: 4-node, `m/4` per
    /// node (row sum); 10-node, HRZ: `m/36` per corner and `4m/27` per mid-edge node
    /// ([`HRZ_CORNER_FRACTION`], [`HRZ_MID_EDGE_FRACTION`]). Every used node gets a strictly
    /// positive mass and the masses sum to the body mass.
    pub fn lumped_masses(&self, n_nodes: usize) -> Vec<f64> {
        lumped(
            &self.elements,
            self.material.density,
            n_nodes.max(self.n_nodes),
        )
    }

    /// Stable time step of central differences for the elastic elements, s:
    /// `min_e 2 / omega_max(e)`, `omega_max(e)^2` the largest eigenvalue of
    /// `M_e^{-1/2} K_e M_e^{-1/2}` (element rest stiffness, element lumped mass). By the
    /// element eigenvalue inequality (Irons 1970; Hughes, *The Finite Element Method*, 2000,
    /// section 9.3) the assembled system's `omega_max` does not exceed the largest element
    /// one, so this bound is rigorous for the linearized system about the rest state (large
    /// pre-stress adds geometric stiffness of relative order strain). `+inf` for an empty set.
    pub fn stable_time_step(&self) -> f64 {
        self.stable_time_step
    }

    /// `2 / omega_max(e)` of every element, s (see [`ElementSet::stable_time_step`]).
    pub fn element_time_steps(&self) -> &[f64] {
        &self.time_steps
    }

    /// Reference (rest-configuration) stiffness matrix `K_e` of one element in global axes,
    /// `3N x 3N`, degree of freedom `3 i + k` for local node `i` and direction `k`, N/m.
    /// The internal force of the element for a small displacement `u` from rest is `K_e u`
    /// (the force on the nodes is `-K_e u`).
    pub fn element_stiffness(&self, element: usize) -> Result<DMatrix<f64>, ElasticError> {
        let n_elements = self.n_elements();
        let (k, n) = match &self.elements {
            Elements::Linear(e) => (
                e.get(element).map(|el| reference_stiffness(el, self.lame)),
                12,
            ),
            Elements::Quadratic(e) => (
                e.get(element).map(|el| reference_stiffness(el, self.lame)),
                30,
            ),
        };
        let k = k.ok_or(ElasticError::ElementOutOfRange {
            element,
            n_elements,
        })?;
        Ok(DMatrix::from_row_slice(n, n, &k))
    }

    /// Rest stiffness matrices of all elements (row-major `3N x 3N`, concatenated) and
    /// their body-local node ids (`N` per element, concatenated).
    pub(crate) fn rest_stiffness_and_nodes(&self) -> (Vec<f64>, Vec<usize>) {
        fn collect<const N: usize>(els: &[TetRef<N>], lame: Lame) -> (Vec<f64>, Vec<usize>) {
            let k = els
                .iter()
                .flat_map(|el| reference_stiffness(el, lame))
                .collect();
            let n = els
                .iter()
                .flat_map(|el| el.nodes.iter().map(|&n| n as usize))
                .collect();
            (k, n)
        }
        match &self.elements {
            Elements::Linear(e) => collect(e, self.lame),
            Elements::Quadratic(e) => collect(e, self.lame),
        }
    }

    /// Body-local node ids of one element, in local order.
    pub fn element_nodes(&self, element: usize) -> Result<Vec<usize>, ElasticError> {
        let n_elements = self.n_elements();
        let nodes: Option<Vec<usize>> = match &self.elements {
            Elements::Linear(e) => e
                .get(element)
                .map(|el| el.nodes.iter().map(|&n| n as usize).collect()),
            Elements::Quadratic(e) => e
                .get(element)
                .map(|el| el.nodes.iter().map(|&n| n as usize).collect()),
        };
        nodes.ok_or(ElasticError::ElementOutOfRange {
            element,
            n_elements,
        })
    }

    fn check_len(&self, field: &'static str, len: usize) -> Result<(), ElasticError> {
        if len != self.n_nodes {
            return Err(ElasticError::LengthMismatch {
                field,
                len,
                expected: self.n_nodes,
                per: "node of the body",
            });
        }
        Ok(())
    }

    /// ADDS the elastic forces on the nodes (minus the internal-force vector, N) for the
    /// current `positions` to `forces`. Both slices have one entry per node of the body.
    ///
    /// Per element: `F` from the current positions, `R` its polar rotation (centroid `F`
    /// for 10-node elements), co-rotated strain `eps = sym(R^T F) - I`, stress
    /// `sigma = lambda tr(eps) I + 2 G eps`, forces `-R K_e u` evaluated as
    /// `-V R sigma grad N` (exactly integrated for 10-node elements, plus the rotation-
    /// derivative term that makes them the exact gradient of the energy). A rigid motion
    /// gives zero force to round-off. No allocation.
    ///
    /// Errors: wrong slice lengths; an element whose positions are not finite, or that is
    /// inverted or flat (`det F <= 0`; for 10-node elements at the centroid or any corner),
    /// named by element id. On error `forces` holds a partial sum and should be discarded.
    pub fn add_forces(
        &self,
        positions: &[[f64; 3]],
        forces: &mut [[f64; 3]],
    ) -> Result<(), ElasticError> {
        self.check_len("positions", positions.len())?;
        self.check_len("forces", forces.len())?;
        match &self.elements {
            Elements::Linear(els) => {
                add_block_forces::<Linear, 4>(
                    Path::best(),
                    &self.blocks4,
                    els,
                    self.lame,
                    positions,
                    forces,
                )?;
            }
            Elements::Quadratic(els) => {
                add_block_forces::<Quadratic, 10>(
                    Path::best(),
                    &self.blocks10,
                    els,
                    self.lame,
                    positions,
                    forces,
                )?;
            }
        }
        Ok(())
    }

    /// Elastic strain energy `sum_e (1/2) u_e^T K_e u_e` in the co-rotated frames, J.
    /// Errors as [`ElementSet::add_forces`].
    pub fn try_strain_energy(&self, positions: &[[f64; 3]]) -> Result<f64, ElasticError> {
        self.check_len("positions", positions.len())?;
        let mut w = 0.0;
        match &self.elements {
            Elements::Linear(els) => {
                for (e, el) in els.iter().enumerate() {
                    w += tet4_energy(el, self.lame, positions, e)?;
                }
            }
            Elements::Quadratic(els) => {
                for (e, el) in els.iter().enumerate() {
                    w += tet10_energy(el, self.lame, positions, e)?;
                }
            }
        }
        Ok(w)
    }

    /// [`ElementSet::try_strain_energy`], returning `+inf` when it fails (an inverted
    /// element, non-finite positions or a wrong `positions` length): never NaN.
    pub fn strain_energy(&self, positions: &[[f64; 3]]) -> f64 {
        self.try_strain_energy(positions).unwrap_or(f64::INFINITY)
    }

    /// Stress of every element, Pa, Voigt order `(xx, yy, zz, yz, xz, xy)`, into `out`
    /// (one entry per element): `R sigma R^T` with the co-rotated stress
    /// `sigma = lambda tr(eps) I + 2 G eps`. This is the small-strain Cauchy stress (not
    /// divided by `det F`, a relative difference of the order of the strain). 4-node: uniform
    /// in the element. 10-node: at the centroid, which equals the volume average since the
    /// stress is linear in the element. Errors as [`ElementSet::add_forces`], plus a wrong
    /// `out` length.
    pub fn cauchy_stresses(
        &self,
        positions: &[[f64; 3]],
        out: &mut [[f64; 6]],
    ) -> Result<(), ElasticError> {
        self.check_len("positions", positions.len())?;
        if out.len() != self.n_elements() {
            return Err(ElasticError::LengthMismatch {
                field: "out",
                len: out.len(),
                expected: self.n_elements(),
                per: "element",
            });
        }
        match &self.elements {
            Elements::Linear(els) => {
                for (e, (el, o)) in els.iter().zip(out.iter_mut()).enumerate() {
                    *o = tet4_stress(el, self.lame, positions, e)?;
                }
            }
            Elements::Quadratic(els) => {
                for (e, (el, o)) in els.iter().zip(out.iter_mut()).enumerate() {
                    *o = tet10_stress(el, self.lame, positions, e)?;
                }
            }
        }
        Ok(())
    }
}

/// Validates connectivity and geometry and computes the reference data of every element.
pub(crate) fn build<const N: usize>(
    x: &[[f64; 3]],
    connectivity: &[usize],
) -> Result<Vec<TetRef<N>>, ElasticError> {
    let n_nodes = x.len();
    let mut out = Vec::with_capacity(connectivity.len() / N);
    for (element, ids) in connectivity.chunks_exact(N).enumerate() {
        let mut nodes = [0u32; N];
        for (local, (&node, slot)) in ids.iter().zip(nodes.iter_mut()).enumerate() {
            if node >= n_nodes {
                return Err(ElasticError::NodeOutOfRange {
                    element,
                    local,
                    node,
                    n_nodes,
                });
            }
            if ids[..local].contains(&node) {
                return Err(ElasticError::RepeatedNode { element, node });
            }
            // n_nodes <= u32::MAX was checked by the caller.
            *slot = node as u32;
        }
        let c = [x[ids[0]], x[ids[1]], x[ids[2]], x[ids[3]]];
        // D_m = [X1 - X0, X2 - X0, X3 - X0] (columns).
        let mut dm: Mat3 = [[0.0; 3]; 3];
        for k in 0..3 {
            let d = sub(c[k + 1], c[0]);
            for i in 0..3 {
                dm[i][k] = d[i];
            }
        }
        let det_dm = det(&dm);
        let volume = det_dm / 6.0;
        let mut l_max2: f64 = 0.0;
        for a in 0..4 {
            for b in a + 1..4 {
                let e = sub(c[b], c[a]);
                l_max2 = l_max2.max(dot(e, e));
            }
        }
        let l_max = l_max2.sqrt();
        if det_dm.abs() < DEGENERATE_RATIO * l_max * l_max * l_max || !det_dm.is_finite() {
            return Err(ElasticError::DegenerateReferenceElement { element, volume });
        }
        if det_dm < 0.0 {
            return Err(ElasticError::InvertedReferenceElement { element, volume });
        }
        if N == 10 {
            for (m, &(a, b)) in EDGES.iter().enumerate() {
                let p = x[ids[4 + m]];
                let mid = [
                    0.5 * (c[a][0] + c[b][0]),
                    0.5 * (c[a][1] + c[b][1]),
                    0.5 * (c[a][2] + c[b][2]),
                ];
                let off = sub(p, mid);
                let edge = sub(c[b], c[a]);
                let offset = dot(off, off).sqrt();
                let edge_length = dot(edge, edge).sqrt();
                if offset.is_nan() || offset > MID_EDGE_TOLERANCE * edge_length {
                    return Err(ElasticError::MidEdgeNodeOffset {
                        element,
                        local: 4 + m,
                        node: ids[4 + m],
                        offset,
                        edge_length,
                    });
                }
            }
        }
        // Rows of D_m^{-1} = cof(D_m)^T / det are grad N_1..3.
        let inv = transpose(&cofactor(&dm));
        let s = 1.0 / det_dm;
        let grad = [
            [inv[0][0] * s, inv[0][1] * s, inv[0][2] * s],
            [inv[1][0] * s, inv[1][1] * s, inv[1][2] * s],
            [inv[2][0] * s, inv[2][1] * s, inv[2][2] * s],
        ];
        out.push(TetRef {
            nodes,
            grad,
            volume,
        });
    }
    Ok(out)
}
