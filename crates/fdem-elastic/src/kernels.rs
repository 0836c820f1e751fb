//! Per-element kernels: co-rotated kinematics, internal forces, strain energy, stress, and the
//! reference stiffness used for the stable time step.
//!
//! Notation (docs/MODEL.md section 3, Felippa & Haugen 2005 for the co-rotational frame):
//! `X` rest positions, `x` current positions, `N_a` shape functions, `g_a = grad N_a` of the
//! *linear* tetrahedron in the rest configuration (constant; `g_0 = -(g_1 + g_2 + g_3)`),
//! `F` the deformation gradient, `F = R U` its polar decomposition,
//! `eps = sym(R^T F) - I` the co-rotated small strain, `sigma = lambda tr(eps) I + 2 G eps`
//! the co-rotated stress (eq. C1 below), `P = R sigma` the first Piola-type stress.
//!
//! (C1) `sigma = lambda tr(eps) I + 2 G eps`.
//! (C2) internal force on node `i`: `f_i = - integral over the element of P grad N_i dV`,
//!      which equals `- R K_e u` with `u_i = R^T x_i - X_i` (the local displacement; the
//!      rigid translation is annihilated because `K_e` kills translations).

use nalgebra::SMatrix;

use crate::ElasticError;
use crate::mat3::{
    IDENTITY, Mat3, Real, add_outer, cofactor, det, dot, mul, mul_tn, mul_vec, scale, sub,
    transpose, vcross, vsub,
};
use crate::material::Material;
use crate::polar::polar_rotation_positive;

/// Reference data of one element: node ids and the constant gradients of the linear shape
/// functions. 96 bytes for a linear tetrahedron, 120 for a quadratic one.
#[derive(Debug, Clone)]
pub(crate) struct TetRef<const N: usize> {
    /// Body-local node ids, in the element's local order.
    pub nodes: [u32; N],
    /// `g_1, g_2, g_3` (rows of `D_m^{-1}`, `D_m = [X_1 - X_0, X_2 - X_0, X_3 - X_0]`).
    pub grad: [[f64; 3]; 3],
    /// Rest volume `det(D_m) / 6`, m^3.
    pub volume: f64,
}

impl<const N: usize> TetRef<N> {
    /// `g_0..g_3`.
    #[inline(always)]
    pub fn grads4(&self) -> [[f64; 3]; 4] {
        grads4(&self.grad)
    }
}

/// `g_0..g_3` from `g_1, g_2, g_3`: `g_0 = -(g_1 + g_2 + g_3)`.
#[inline(always)]
pub(crate) fn grads4<T: Real>(grad: &[[T; 3]; 3]) -> [[T; 3]; 4] {
    let [g1, g2, g3] = *grad;
    let g0 = [
        -(g1[0] + g2[0] + g3[0]),
        -(g1[1] + g2[1] + g3[1]),
        -(g1[2] + g2[2] + g3[2]),
    ];
    [g0, g1, g2, g3]
}

/// Local id of the mid-edge node between corners `c` and `d` (VTK_QUADRATIC_TETRA:
/// 4:(0,1) 5:(1,2) 6:(0,2) 7:(0,3) 8:(1,3) 9:(2,3)); the diagonal is unused.
pub(crate) const MID: [[usize; 4]; 4] = [[0, 4, 6, 7], [4, 0, 5, 8], [6, 5, 0, 9], [7, 8, 9, 0]];

/// The corner pair of each mid-edge node 4..9.
pub(crate) const EDGES: [(usize, usize); 6] = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)];

/// Lamé constants of a validated material, cached by the element set.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Lame {
    pub lambda: f64,
    pub mu: f64,
}

/// Co-rotated frame of a deformation gradient: rotation `R` and the strain
/// `eps = sym(R^T F) - I` (not computed here; see [`corotated_strain`]).
#[inline(always)]
fn rotation(f: &Mat3, det_f: f64, element: usize) -> Result<Mat3, ElasticError> {
    if !det_f.is_finite() {
        return Err(ElasticError::NonFinitePosition { element });
    }
    if det_f <= 0.0 {
        return Err(ElasticError::InvertedElement { element, det_f });
    }
    polar_rotation_positive(f).ok_or(ElasticError::PolarDecomposition { element })
}

/// `eps = sym(R^T F) - I`, the co-rotated small strain.
#[inline(always)]
pub(crate) fn corotated_strain<T: Real>(r: &[[T; 3]; 3], f: &[[T; 3]; 3]) -> [[T; 3]; 3] {
    let h = mul_tn(r, f);
    let mut e = [[T::ZERO; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            e[i][j] = T::splat(0.5) * (h[i][j] + h[j][i]) - T::splat(IDENTITY[i][j]);
        }
    }
    e
}

/// `a : b`.
#[inline(always)]
fn ddot(a: &Mat3, b: &Mat3) -> f64 {
    dot(a[0], b[0]) + dot(a[1], b[1]) + dot(a[2], b[2])
}

/// `R S R^T` as Voigt `(xx, yy, zz, yz, xz, xy)`.
#[inline(always)]
fn rotate_to_voigt(r: &Mat3, s: &Mat3) -> [f64; 6] {
    let g = mul(&mul(r, s), &transpose(r));
    [g[0][0], g[1][1], g[2][2], g[1][2], g[0][2], g[0][1]]
}

// ----------------------------------------------------------------------------------------
// Linear 4-node tetrahedron.
// ----------------------------------------------------------------------------------------

/// `F = sum_{a=1..3} (x_a - x_0) (x) g_a` (= `D_s D_m^{-1}`; uses `sum_a g_a = 0`), from
/// the edge vectors `d_a = x_a - x_0` and the gradients `g_1, g_2, g_3`.
#[inline(always)]
pub(crate) fn tet4_gradient<T: Real>(d: &[[T; 3]; 3], grad: &[[T; 3]; 3]) -> [[T; 3]; 3] {
    let mut f = [[T::ZERO; 3]; 3];
    add_outer(&mut f, d[0], grad[0]);
    add_outer(&mut f, d[1], grad[1]);
    add_outer(&mut f, d[2], grad[2]);
    f
}

/// The node forces of a linear tetrahedron with deformation gradient `f`, rotation `r`,
/// gradients `g_1..g_3` and rest volume `volume`: `P = V R sigma`, `f_a = -P g_a`
/// (eq. C2 with constant `P`), `f_0 = -(f_1 + f_2 + f_3)`.
#[inline(always)]
pub(crate) fn tet4_forces<T: Real>(
    r: &[[T; 3]; 3],
    f: &[[T; 3]; 3],
    grad: &[[T; 3]; 3],
    volume: T,
    lambda: T,
    mu: T,
) -> [[T; 3]; 4] {
    let eps = corotated_strain(r, f);
    let s = Material::stress(lambda, mu, &eps);
    let p = scale(&mul(r, &s), -volume);
    let f1 = mul_vec(&p, grad[0]);
    let f2 = mul_vec(&p, grad[1]);
    let f3 = mul_vec(&p, grad[2]);
    let f0 = [
        -(f1[0] + f2[0] + f3[0]),
        -(f1[1] + f2[1] + f3[1]),
        -(f1[2] + f2[2] + f3[2]),
    ];
    [f0, f1, f2, f3]
}

/// Deformation gradient and rotation of a linear tetrahedron.
#[inline(always)]
pub(crate) fn tet4_frame(
    el: &TetRef<4>,
    x: &[[f64; 3]],
    element: usize,
) -> Result<(Mat3, Mat3), ElasticError> {
    let [n0, n1, n2, n3] = el.nodes;
    let x0 = x[n0 as usize];
    let d = [
        sub(x[n1 as usize], x0),
        sub(x[n2 as usize], x0),
        sub(x[n3 as usize], x0),
    ];
    let f = tet4_gradient(&d, &el.grad);
    let r = rotation(&f, det(&f), element)?;
    Ok((f, r))
}

/// Rotation and co-rotated strain of a linear tetrahedron.
#[inline(always)]
pub(crate) fn tet4_kinematics(
    el: &TetRef<4>,
    x: &[[f64; 3]],
    element: usize,
) -> Result<(Mat3, Mat3), ElasticError> {
    let (f, r) = tet4_frame(el, x, element)?;
    Ok((r, corotated_strain(&r, &f)))
}

/// Adds the elastic forces of one linear tetrahedron ([`tet4_forces`]).
#[inline(always)]
pub(crate) fn tet4_add_forces(
    el: &TetRef<4>,
    lame: Lame,
    x: &[[f64; 3]],
    forces: &mut [[f64; 3]],
    element: usize,
) -> Result<(), ElasticError> {
    let (f, r) = tet4_frame(el, x, element)?;
    let fa = tet4_forces(&r, &f, &el.grad, el.volume, lame.lambda, lame.mu);
    scatter(&el.nodes, fa, forces);
    Ok(())
}

/// Adds the element's node forces `f` to the body's `forces` at its nodes.
#[inline(always)]
pub(crate) fn scatter<const N: usize>(nodes: &[u32; N], f: [[f64; 3]; N], forces: &mut [[f64; 3]]) {
    for (n, fa) in nodes.iter().zip(f) {
        let t = &mut forces[*n as usize];
        t[0] += fa[0];
        t[1] += fa[1];
        t[2] += fa[2];
    }
}

/// Strain energy `V (G eps:eps + lambda/2 tr(eps)^2) = (V/2) eps:sigma` (= `u^T K u / 2`).
#[inline]
pub(crate) fn tet4_energy(
    el: &TetRef<4>,
    lame: Lame,
    x: &[[f64; 3]],
    element: usize,
) -> Result<f64, ElasticError> {
    let (_, eps) = tet4_kinematics(el, x, element)?;
    let s = Material::stress(lame.lambda, lame.mu, &eps);
    Ok(0.5 * el.volume * ddot(&eps, &s))
}

/// Stress `R sigma R^T` (uniform in a linear tetrahedron), Voigt `(xx, yy, zz, yz, xz, xy)`.
#[inline]
pub(crate) fn tet4_stress(
    el: &TetRef<4>,
    lame: Lame,
    x: &[[f64; 3]],
    element: usize,
) -> Result<[f64; 6], ElasticError> {
    let (r, eps) = tet4_kinematics(el, x, element)?;
    Ok(rotate_to_voigt(
        &r,
        &Material::stress(lame.lambda, lame.mu, &eps),
    ))
}

// ----------------------------------------------------------------------------------------
// Quadratic 10-node tetrahedron (straight-sided in the rest configuration).
// ----------------------------------------------------------------------------------------
//
// With barycentric coordinates L_a, the shape functions are N_a = L_a (2 L_a - 1) at the
// corners and N_ab = 4 L_a L_b at the mid-edge nodes, so their gradients are linear in L:
//   grad N_a = (4 L_a - 1) g_a,   grad N_ab = 4 (L_b g_a + L_a g_b).              (Q1)
// Hence F(L) = sum_i x_i (x) grad N_i(L) is linear too, F(L) = sum_c L_c F_c, with the
// value at corner c
//   F_c = sum_{d != c} (4 (x_cd - x_c) - (x_d - x_c)) (x) g_d.                      (Q2)
// With one rotation R per element the strain and stress are linear in L as well, and the
// force integral (C2) of a product of two linear fields is exact with
//   integral L_c L_d dV = V (1 + delta_cd) / 20:                                    (Q3)
//   s_d = V (sigma_d + sum_c sigma_c) / 20,  S = sum_d s_d,
//   f_a  = -R (4 s_a - S) g_a             (corner a),
//   f_ab = -4 R (s_b g_a + s_a g_b)       (mid-edge node of edge ab).               (Q4)
// This is the exact integral (the same as 4-point Gauss quadrature, degree 2), computed
// from 4 corner stresses instead of 4 quadrature-point B matrices. The rotation is the polar
// rotation of F at the centroid, F_bar = (F_0 + F_1 + F_2 + F_3) / 4.

/// Co-rotated state of a 10-node element.
pub(crate) struct Tet10State {
    /// Gathered current positions, local order.
    pub xs: [[f64; 3]; 10],
    /// `F` at the centroid.
    pub fbar: Mat3,
    /// Polar rotation of `fbar`.
    pub r: Mat3,
    /// Co-rotated strains at the corners.
    pub eps: [Mat3; 4],
}

/// `F` at the four corners (Q2) and at the centroid, `F_bar = (F_0 + F_1 + F_2 + F_3) / 4`,
/// from the gathered positions `xs` (local order) and the gradients `g_0..g_3`.
#[inline(always)]
pub(crate) fn tet10_gradients<T: Real>(
    xs: &[[T; 3]; 10],
    g: &[[T; 3]; 4],
) -> ([[[T; 3]; 3]; 4], [[T; 3]; 3]) {
    let mut fc = [[[T::ZERO; 3]; 3]; 4];
    for c in 0..4 {
        for d in 0..4 {
            if d == c {
                continue;
            }
            // (Q2)
            let a = vsub(xs[MID[c][d]], xs[c]);
            let b = vsub(xs[d], xs[c]);
            let four = T::splat(4.0);
            let v = [four * a[0] - b[0], four * a[1] - b[1], four * a[2] - b[2]];
            add_outer(&mut fc[c], v, g[d]);
        }
    }
    let mut fbar = [[T::ZERO; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            fbar[i][j] = T::splat(0.25) * (fc[0][i][j] + fc[1][i][j] + fc[2][i][j] + fc[3][i][j]);
        }
    }
    (fc, fbar)
}

/// Rotation and corner strains of a 10-node element; checks `det F > 0` at the centroid
/// and at the 4 corners.
#[inline(always)]
pub(crate) fn tet10_kinematics(
    el: &TetRef<10>,
    x: &[[f64; 3]],
    element: usize,
) -> Result<Tet10State, ElasticError> {
    let mut xs = [[0.0; 3]; 10];
    for (xi, n) in xs.iter_mut().zip(el.nodes) {
        *xi = x[n as usize];
    }
    let (fc, fbar) = tet10_gradients(&xs, &el.grads4());
    // The element is valid only if F is orientation-preserving at the centroid and at every
    // corner; report the smallest determinant.
    let dets = [
        det(&fbar),
        det(&fc[0]),
        det(&fc[1]),
        det(&fc[2]),
        det(&fc[3]),
    ];
    let mut det_min = f64::INFINITY;
    for d in dets {
        if !d.is_finite() {
            det_min = f64::NAN; // reported as non-finite positions
            break;
        }
        det_min = det_min.min(d);
    }
    let r = rotation(&fbar, det_min, element)?;
    let eps = tet10_corner_strains(&r, &fc);
    Ok(Tet10State { xs, fbar, r, eps })
}

/// Co-rotated strains at the corners, `eps_c = sym(R^T F_c) - I`.
#[inline(always)]
pub(crate) fn tet10_corner_strains<T: Real>(
    r: &[[T; 3]; 3],
    fc: &[[[T; 3]; 3]; 4],
) -> [[[T; 3]; 3]; 4] {
    [
        corotated_strain(r, &fc[0]),
        corotated_strain(r, &fc[1]),
        corotated_strain(r, &fc[2]),
        corotated_strain(r, &fc[3]),
    ]
}

/// Corner stresses scaled by (Q3): `s_d = V (sigma_d + sum_c sigma_c) / 20`, and
/// `sum_c sigma_c`; `k = V / 20`.
#[inline(always)]
pub(crate) fn tet10_smoothed_stresses<T: Real>(
    k: T,
    lambda: T,
    mu: T,
    eps: &[[[T; 3]; 3]; 4],
) -> ([[[T; 3]; 3]; 4], [[T; 3]; 3]) {
    let sig = [
        Material::stress(lambda, mu, &eps[0]),
        Material::stress(lambda, mu, &eps[1]),
        Material::stress(lambda, mu, &eps[2]),
        Material::stress(lambda, mu, &eps[3]),
    ];
    let mut sum = [[T::ZERO; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            sum[i][j] = sig[0][i][j] + sig[1][i][j] + sig[2][i][j] + sig[3][i][j];
        }
    }
    let mut s = [[[T::ZERO; 3]; 3]; 4];
    for d in 0..4 {
        for i in 0..3 {
            for j in 0..3 {
                s[d][i][j] = k * (sig[d][i][j] + sum[i][j]);
            }
        }
    }
    (s, sum)
}

/// Forces `-R K_e u` of one 10-node tetrahedron, (Q4), in local node order, from the
/// gradients `g_0..g_3`, the smoothed corner stresses `s` and the rotation `r`.
#[inline(always)]
pub(crate) fn tet10_corotational_forces<T: Real>(
    g: &[[T; 3]; 4],
    s: &[[[T; 3]; 3]; 4],
    r: &[[T; 3]; 3],
) -> [[T; 3]; 10] {
    // Rotate first: P_d = -R s_d, then every nodal force is a sum of P_d g_a.
    let minus = T::splat(-1.0);
    let p = [
        scale(&mul(r, &s[0]), minus),
        scale(&mul(r, &s[1]), minus),
        scale(&mul(r, &s[2]), minus),
        scale(&mul(r, &s[3]), minus),
    ];
    let mut psum = [[T::ZERO; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            psum[i][j] = p[0][i][j] + p[1][i][j] + p[2][i][j] + p[3][i][j];
        }
    }
    let four = T::splat(4.0);
    let mut out = [[T::ZERO; 3]; 10];
    for a in 0..4 {
        // f_a = (4 P_a - sum P) g_a
        let u = mul_vec(&p[a], g[a]);
        let w = mul_vec(&psum, g[a]);
        out[a] = [four * u[0] - w[0], four * u[1] - w[1], four * u[2] - w[2]];
    }
    for (m, &(a, b)) in EDGES.iter().enumerate() {
        // f_ab = 4 (P_b g_a + P_a g_b)
        let u = mul_vec(&p[b], g[a]);
        let w = mul_vec(&p[a], g[b]);
        out[4 + m] = [
            four * (u[0] + w[0]),
            four * (u[1] + w[1]),
            four * (u[2] + w[2]),
        ];
    }
    out
}

// Energy-consistent correction (Q5). With one rotation per element, -R K u is not the
// gradient of W = u^T K u / 2 (u_i = R^T x_i - X_i, R = polar(F_bar)): differentiating R
// adds a term. With the spin of the polar rotation,
//   (tr(V) I - V) dw = sum_i (R b_i) x dx_i,   V = F_bar R^T,  b_i = grad N_i(centroid),
// and tau = sum_i x_i x r_i the torque of the internal forces r_i = R (K u)_i (zero for
// linear elements), the exact gradient is
//   dW/dx_i = r_i - Z x (R b_i),   Z = (tr(V) I - V)^{-1} tau.                      (Q5)
// The corrected forces are the exact gradient of W (conservative, so energy is conserved
// by central differences) and are exactly torque-free (sum_i x_i x (Z x R b_i) = tau).
// At the centroid b_a = 0 for corners and b_ab = g_a + g_b for mid-edge nodes, and
// tau = O(|u|^2), so the correction is second order: the tangent at rest is still K.

/// Adds the correction (Q5) to the forces `out` of [`tet10_corotational_forces`]; returns
/// `det A`, which the caller must find finite and positive (else `out` is not valid).
#[inline(always)]
pub(crate) fn tet10_add_correction<T: Real>(
    xs: &[[T; 3]; 10],
    g: &[[T; 3]; 4],
    fbar: &[[T; 3]; 3],
    r: &[[T; 3]; 3],
    out: &mut [[T; 3]; 10],
) -> T {
    // tau = sum_i (x_i - x_0) x r_i with r_i = -out_i (internal force); sum_i r_i = 0.
    let mut tau = [T::ZERO; 3];
    for (xi, fi) in xs[1..].iter().zip(&out[1..]) {
        let d = vsub(*xi, xs[0]);
        let c = vcross(d, *fi);
        for k in 0..3 {
            tau[k] = tau[k] - c[k];
        }
    }
    // A = tr(V) I - V, V = F_bar R^T (symmetric positive definite; A is too).
    let v = mul(fbar, &transpose(r));
    let tr = v[0][0] + v[1][1] + v[2][2];
    let mut a = [[T::ZERO; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            a[i][j] = T::splat(-0.5) * (v[i][j] + v[j][i]);
        }
        a[i][i] += tr;
    }
    // Z = A^{-1} tau = cof(A) tau / det(A) (A symmetric).
    let det_a = det(&a);
    let z = mul_vec(&cofactor(&a), tau);
    let z = [z[0] / det_a, z[1] / det_a, z[2] / det_a];
    // Force on node = -dW/dx_i = out_i + Z x (R b_i), b_ab = g_a + g_b.
    let rg = [
        mul_vec(r, g[0]),
        mul_vec(r, g[1]),
        mul_vec(r, g[2]),
        mul_vec(r, g[3]),
    ];
    for (m, &(ea, eb)) in EDGES.iter().enumerate() {
        let rb = [
            rg[ea][0] + rg[eb][0],
            rg[ea][1] + rg[eb][1],
            rg[ea][2] + rg[eb][2],
        ];
        let c = vcross(z, rb);
        let o = &mut out[4 + m];
        o[0] += c[0];
        o[1] += c[1];
        o[2] += c[2];
    }
    det_a
}

/// The node forces of one 10-node tetrahedron, (Q4) plus the correction (Q5), in local
/// node order.
#[inline(always)]
pub(crate) fn tet10_forces(
    el: &TetRef<10>,
    lame: Lame,
    x: &[[f64; 3]],
    element: usize,
) -> Result<[[f64; 3]; 10], ElasticError> {
    let st = tet10_kinematics(el, x, element)?;
    let g = el.grads4();
    let (s, _) = tet10_smoothed_stresses(el.volume / 20.0, lame.lambda, lame.mu, &st.eps);
    let mut out = tet10_corotational_forces(&g, &s, &st.r);
    let det_a = tet10_add_correction(&st.xs, &g, &st.fbar, &st.r, &mut out);
    if !(det_a.is_finite() && det_a > 0.0) {
        // A is positive definite whenever det F > 0; this only triggers on overflow.
        return Err(ElasticError::PolarDecomposition { element });
    }
    Ok(out)
}

/// Adds the elastic forces of one 10-node tetrahedron ([`tet10_forces`]).
#[inline(always)]
pub(crate) fn tet10_add_forces(
    el: &TetRef<10>,
    lame: Lame,
    x: &[[f64; 3]],
    forces: &mut [[f64; 3]],
    element: usize,
) -> Result<(), ElasticError> {
    let out = tet10_forces(el, lame, x, element)?;
    scatter(&el.nodes, out, forces);
    Ok(())
}

/// Strain energy `(1/2) integral eps:sigma dV = (1/2) sum_d eps_d : s_d` by (Q3).
#[inline]
pub(crate) fn tet10_energy(
    el: &TetRef<10>,
    lame: Lame,
    x: &[[f64; 3]],
    element: usize,
) -> Result<f64, ElasticError> {
    let st = tet10_kinematics(el, x, element)?;
    let (s, _) = tet10_smoothed_stresses(el.volume / 20.0, lame.lambda, lame.mu, &st.eps);
    Ok(0.5 * (0..4).map(|d| ddot(&st.eps[d], &s[d])).sum::<f64>())
}

/// Stress at the centroid `R (sum_c sigma_c / 4) R^T`, which is also the volume average
/// (the stress is linear in `L`), Voigt `(xx, yy, zz, yz, xz, xy)`.
#[inline]
pub(crate) fn tet10_stress(
    el: &TetRef<10>,
    lame: Lame,
    x: &[[f64; 3]],
    element: usize,
) -> Result<[f64; 6], ElasticError> {
    let st = tet10_kinematics(el, x, element)?;
    let (_, sum) = tet10_smoothed_stresses(el.volume / 20.0, lame.lambda, lame.mu, &st.eps);
    Ok(rotate_to_voigt(&st.r, &scale(&sum, 0.25)))
}

// ----------------------------------------------------------------------------------------
// Reference stiffness (set-up only).
// ----------------------------------------------------------------------------------------

/// 3x3 block of the isotropic stiffness for shape-function gradients `a` (row node) and `b`
/// (column node), per unit volume: `lambda a b^T + G (a.b) I + G b a^T`.
#[inline]
fn stiffness_block(lame: Lame, a: [f64; 3], b: [f64; 3]) -> Mat3 {
    let ab = dot(a, b);
    let mut k = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            k[i][j] = lame.lambda * a[i] * b[j] + lame.mu * b[i] * a[j];
        }
        k[i][i] += lame.mu * ab;
    }
    k
}

/// Symmetric 4-point Gauss rule on the tetrahedron (degree 2), barycentric coordinates;
/// weights are all 1/4 of the volume.
const GAUSS4_A: f64 = 0.585_410_196_624_968_5;
const GAUSS4_B: f64 = 0.138_196_601_125_010_5;

/// Gradients of the 10 quadratic shape functions at barycentric point `l`, (Q1).
fn tet10_shape_gradients(g: &[[f64; 3]; 4], l: [f64; 4]) -> [[f64; 3]; 10] {
    let mut out = [[0.0; 3]; 10];
    for a in 0..4 {
        for i in 0..3 {
            out[a][i] = (4.0 * l[a] - 1.0) * g[a][i];
        }
    }
    for (m, &(a, b)) in EDGES.iter().enumerate() {
        for i in 0..3 {
            out[4 + m][i] = 4.0 * (l[b] * g[a][i] + l[a] * g[b][i]);
        }
    }
    out
}

/// Reference (rest-configuration, global axes) stiffness matrix of one element, row-major
/// `3N x 3N`, dof `3 i + k` for local node `i`, direction `k`. Linear: exact
/// `K_ab = V [lambda g_a g_b^T + G (g_a.g_b) I + G g_b g_a^T]`. Quadratic: the same block
/// integrated with the 4-point rule, exact for straight-sided elements.
pub(crate) fn reference_stiffness<const N: usize>(el: &TetRef<N>, lame: Lame) -> Vec<f64> {
    let n = 3 * N;
    let mut k = vec![0.0; n * n];
    let mut add = |grads: &[[f64; 3]], w: f64| {
        for (a, &ga) in grads.iter().enumerate() {
            for (b, &gb) in grads.iter().enumerate() {
                let blk = stiffness_block(lame, ga, gb);
                for i in 0..3 {
                    for j in 0..3 {
                        k[(3 * a + i) * n + 3 * b + j] += w * blk[i][j];
                    }
                }
            }
        }
    };
    let g = el.grads4();
    if N == 4 {
        add(&g, el.volume);
    } else {
        for q in 0..4 {
            let mut l = [GAUSS4_B; 4];
            l[q] = GAUSS4_A;
            add(&tet10_shape_gradients(&g, l), 0.25 * el.volume);
        }
    }
    k
}

/// The 6x3 block of the strain-displacement matrix of one node with shape-function gradient
/// `g`, in Mandel notation: strain vector `(e11, e22, e33, sqrt2 e23, sqrt2 e13, sqrt2 e12)`,
/// for which the isotropic stiffness is `C = lambda 1 1^T (normal block) + 2 G I` and the
/// energy density is `e^T C e / 2`.
fn mandel_b(g: [f64; 3]) -> SMatrix<f64, 6, 3> {
    let r = std::f64::consts::FRAC_1_SQRT_2;
    SMatrix::<f64, 6, 3>::new(
        g[0],
        0.0,
        0.0, //
        0.0,
        g[1],
        0.0, //
        0.0,
        0.0,
        g[2], //
        0.0,
        r * g[2],
        r * g[1], //
        r * g[2],
        0.0,
        r * g[0], //
        r * g[1],
        r * g[0],
        0.0,
    )
}

/// `C^{1/2}` in Mandel notation: `C` has eigenvalue `3 lambda + 2 G` (three times the bulk
/// modulus, > 0 for nu > -1) on `v = (1,1,1,0,0,0)/sqrt3` and `2 G` elsewhere, so
/// `C^{1/2} = sqrt(2G) I + (sqrt(3 lambda + 2G) - sqrt(2G)) v v^T`.
fn mandel_c_sqrt(lame: Lame) -> SMatrix<f64, 6, 6> {
    let a = (2.0 * lame.mu).sqrt();
    let b = (3.0 * lame.lambda + 2.0 * lame.mu).sqrt();
    let mut c = SMatrix::<f64, 6, 6>::identity() * a;
    for i in 0..3 {
        for j in 0..3 {
            c[(i, j)] += (b - a) / 3.0;
        }
    }
    c
}

/// `2 / omega_max` of one element, `omega_max^2` the largest eigenvalue of
/// `M^{-1/2} K M^{-1/2}` with the element's lumped masses (docs/MODEL.md section 11).
///
/// `K = sum_q w_q B_q^T C B_q = G^T G` with `G` the rows `sqrt(w_q) C^{1/2} B_q` stacked, so
/// the non-zero eigenvalues of `M^{-1/2} K M^{-1/2}` (12x12 or 30x30) are those of the
/// smaller `G M^{-1} G^T` (6x6 for one point, 24x24 for four): the same numbers from a
/// smaller problem (docs/PERFORMANCE.md, "Setting up").
pub(crate) fn element_time_step<const N: usize>(el: &TetRef<N>, lame: Lame, density: f64) -> f64 {
    let m_e = density * el.volume;
    let g = el.grads4();
    let cs = mandel_c_sqrt(lame);
    let omega2 = if N == 4 {
        // M = m_e/4 I: G M^{-1} G^T = (4 V / m_e) C^{1/2} (sum_a B_a B_a^T) C^{1/2}.
        let mut bb = SMatrix::<f64, 6, 6>::zeros();
        for ga in g {
            let b = mandel_b(ga);
            bb += b * b.transpose();
        }
        let a = (cs * bb * cs) * (4.0 * el.volume / m_e);
        a.symmetric_eigenvalues().max()
    } else {
        let mut gm = SMatrix::<f64, 24, 30>::zeros();
        let w = (0.25 * el.volume).sqrt();
        for q in 0..4 {
            let mut l = [GAUSS4_B; 4];
            l[q] = GAUSS4_A;
            let grads = tet10_shape_gradients(&g, l);
            for (i, gi) in grads.iter().enumerate() {
                let frac = if i < 4 {
                    crate::HRZ_CORNER_FRACTION
                } else {
                    crate::HRZ_MID_EDGE_FRACTION
                };
                let blk = cs * mandel_b(*gi) * (w / (frac * m_e).sqrt());
                gm.fixed_view_mut::<6, 3>(6 * q, 3 * i).copy_from(&blk);
            }
        }
        (gm * gm.transpose()).symmetric_eigenvalues().max()
    };
    if omega2 > 0.0 && omega2.is_finite() {
        2.0 / omega2.sqrt()
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With R = I exactly (symmetric centroid gradient), the 10-node force kernel (Q4) must
    /// equal -K u with K from 4-point quadrature, to round-off.
    #[test]
    fn tet10_kernel_equals_quadrature_stiffness_when_unrotated() {
        let corners = [
            [0.1, 0.0, 0.05],
            [1.0, 0.1, 0.0],
            [0.2, 0.9, 0.1],
            [0.05, 0.2, 1.1],
        ];
        let mut x0 = vec![[0.0; 3]; 10];
        x0[..4].copy_from_slice(&corners);
        for (m, &(a, b)) in EDGES.iter().enumerate() {
            for i in 0..3 {
                x0[4 + m][i] = 0.5 * (corners[a][i] + corners[b][i]);
            }
        }
        let mut dm = [[0.0; 3]; 3];
        for k in 0..3 {
            for i in 0..3 {
                dm[i][k] = corners[k + 1][i] - corners[0][i];
            }
        }
        let dd = det(&dm);
        let inv = transpose(&crate::mat3::cofactor(&dm));
        let el = TetRef::<10> {
            nodes: [0, 1, 2, 3, 4, 5, 6, 7, 8, 9],
            grad: [
                scale_v(inv[0], 1.0 / dd),
                scale_v(inv[1], 1.0 / dd),
                scale_v(inv[2], 1.0 / dd),
            ],
            volume: dd / 6.0,
        };
        let lame = Lame {
            lambda: 1.3,
            mu: 0.7,
        };
        // Displacement: quadratic-ish nodal pattern whose centroid gradient is symmetric.
        // Build u = random, then remove the skew part of the centroid gradient with a
        // linear field (which changes no symmetric part).
        let mut u = [[0.0; 3]; 10];
        for (i, ui) in u.iter_mut().enumerate() {
            for (k, v) in ui.iter_mut().enumerate() {
                *v = 1e-3 * (((i * 3 + k) as f64 * 1.7).sin());
            }
        }
        let centroid_grad = |u: &[[f64; 3]; 10]| {
            let gr = tet10_shape_gradients(&el.grads4(), [0.25; 4]);
            let mut h = [[0.0; 3]; 3];
            for (ui, gi) in u.iter().zip(gr) {
                add_outer(&mut h, *ui, gi);
            }
            h
        };
        let h = centroid_grad(&u);
        let w = [
            [0.0, 0.5 * (h[0][1] - h[1][0]), 0.5 * (h[0][2] - h[2][0])],
            [0.5 * (h[1][0] - h[0][1]), 0.0, 0.5 * (h[1][2] - h[2][1])],
            [0.5 * (h[2][0] - h[0][2]), 0.5 * (h[2][1] - h[1][2]), 0.0],
        ];
        for (ui, xi) in u.iter_mut().zip(&x0) {
            let d = mul_vec(&w, *xi);
            for k in 0..3 {
                ui[k] -= d[k];
            }
        }
        let h2 = centroid_grad(&u);
        assert!((h2[0][1] - h2[1][0]).abs() < 1e-18);
        let x: Vec<[f64; 3]> = x0
            .iter()
            .zip(&u)
            .map(|(a, b)| [a[0] + b[0], a[1] + b[1], a[2] + b[2]])
            .collect();
        let st = tet10_kinematics(&el, &x, 0).unwrap();
        let (s, _) = tet10_smoothed_stresses(el.volume / 20.0, lame.lambda, lame.mu, &st.eps);
        let f = tet10_corotational_forces(&el.grads4(), &s, &st.r);
        let k = reference_stiffness(&el, lame);
        let mut max_err: f64 = 0.0;
        let mut max_f: f64 = 0.0;
        for r in 0..30 {
            let ku: f64 = (0..30).map(|c| k[r * 30 + c] * u[c / 3][c % 3]).sum();
            max_err = max_err.max((f[r / 3][r % 3] + ku).abs());
            max_f = max_f.max(ku.abs());
        }
        // R = I up to round-off; the kernel and K then agree to round-off (1e-12 relative).
        assert!(max_err < 1e-12 * max_f, "{max_err} vs {max_f}");
    }

    fn scale_v(v: [f64; 3], s: f64) -> [f64; 3] {
        [v[0] * s, v[1] * s, v[2] * s]
    }
}

#[cfg(test)]
mod layout_tests {
    use super::TetRef;

    /// The per-element memory stated in docs/PERFORMANCE.md.
    #[test]
    fn element_records_are_compact() {
        assert_eq!(std::mem::size_of::<TetRef<4>>(), 96);
        assert_eq!(std::mem::size_of::<TetRef<10>>(), 120);
    }
}
