//! Tetrahedra several at a time: blocks of [`LANES`] elements (linear or quadratic) whose
//! reference data is stored lane by lane (structure of arrays within a block), evaluated
//! with the operations of [`crate::kernels`] on vectors of lanes.
//!
//! # Same result as one element at a time
//! Every lane runs the operations of the one-element kernel in the same order: the 3x3
//! products, the strain, the stress and the forces are the same generic functions
//! ([`crate::mat3::Real`]), and the Newton–Schulz iteration of [`crate::polar`] runs
//! per lane until that lane has taken the step the one-element iteration stops after
//! (a lane that is done keeps its value while the others go on). Rust never fuses a
//! multiply and an add unless told to, so the vector code and the scalar code round
//! alike, and the forces are added to the nodes element by element in element order. So
//! the forces are identical to the last bit to those of the one-element kernel, on every
//! code path (tested).
//!
//! # Fallback
//! A block with an element that is inverted, flat or not finite (for a 10-node element at
//! its centroid or any corner), whose stretch needs the scaled-Newton phase of the polar
//! decomposition (far outside elastic strains), or whose energy correction (Q5) cannot be
//! solved, is evaluated one element at a time instead, which also names the failing
//! element. The fallback happens before the block adds anything, so it changes nothing.
//!
//! # Code paths
//! The same source is compiled for the baseline instruction set and, on x86-64, with
//! AVX2 and with AVX-512 enabled; the widest one the processor has is chosen at run time
//! (no build flag needed).

// Lane loops index several arrays at once: an index reads best.
#![allow(clippy::needless_range_loop)]

use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

use crate::ElasticError;
use crate::kernels::{
    Lame, TetRef, grads4, scatter, tet4_add_forces, tet4_forces, tet4_gradient,
    tet10_add_correction, tet10_add_forces, tet10_corner_strains, tet10_corotational_forces,
    tet10_gradients, tet10_smoothed_stresses,
};
use crate::mat3::{IDENTITY, Real, det, gram, mul};
use crate::polar::{CONVERGED2, MAX_NS, NS_REGION2};

/// Elements per block: eight `f64` lanes, one AVX-512 register, two AVX2 registers.
pub(crate) const LANES: usize = 8;

/// A vector of `f64` lanes with element-wise operations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct V(pub(crate) [f64; LANES]);

impl V {
    #[inline(always)]
    fn zip(self, o: V, op: impl Fn(f64, f64) -> f64) -> V {
        let mut r = [0.0; LANES];
        for l in 0..LANES {
            r[l] = op(self.0[l], o.0[l]);
        }
        V(r)
    }
}

impl Add for V {
    type Output = V;
    #[inline(always)]
    fn add(self, o: V) -> V {
        self.zip(o, |a, b| a + b)
    }
}

impl Sub for V {
    type Output = V;
    #[inline(always)]
    fn sub(self, o: V) -> V {
        self.zip(o, |a, b| a - b)
    }
}

impl Mul for V {
    type Output = V;
    #[inline(always)]
    fn mul(self, o: V) -> V {
        self.zip(o, |a, b| a * b)
    }
}

impl Div for V {
    type Output = V;
    #[inline(always)]
    fn div(self, o: V) -> V {
        self.zip(o, |a, b| a / b)
    }
}

impl Neg for V {
    type Output = V;
    #[inline(always)]
    fn neg(self) -> V {
        let mut r = self.0;
        for v in &mut r {
            *v = -*v;
        }
        V(r)
    }
}

impl AddAssign for V {
    #[inline(always)]
    fn add_assign(&mut self, o: V) {
        *self = *self + o;
    }
}

impl Real for V {
    const ZERO: V = V([0.0; LANES]);
    #[inline(always)]
    fn splat(value: f64) -> V {
        V([value; LANES])
    }
}

type M = [[V; 3]; 3];

/// Reference data of up to [`LANES`] elements of `N` nodes, lane by lane. Unused lanes
/// repeat lane 0 (so that they compute finite values) and are never added to the nodes.
#[derive(Clone, Debug)]
pub(crate) struct Block<const N: usize> {
    /// Node ids of each lane's element.
    nodes: [[u32; N]; LANES],
    /// `grad[a][k]`: component `k` of `g_(a+1)`, per lane.
    grad: M,
    /// Rest volumes.
    volume: V,
    /// Id of the element in lane 0; lane `l` holds element `first + l`.
    first: usize,
    /// Lanes in use.
    len: usize,
}

/// A block of linear elements.
pub(crate) type Tet4Block = Block<4>;
/// A block of quadratic elements.
pub(crate) type Tet10Block = Block<10>;

impl<const N: usize> Block<N> {
    /// The blocks of `elements`, in order: [`LANES`] per block, the last one partial.
    pub(crate) fn blocks(elements: &[TetRef<N>]) -> Vec<Block<N>> {
        elements
            .chunks(LANES)
            .enumerate()
            .map(|(b, els)| {
                let mut block = Block {
                    nodes: [[0; N]; LANES],
                    grad: [[V::ZERO; 3]; 3],
                    volume: V::ZERO,
                    first: b * LANES,
                    len: els.len(),
                };
                for l in 0..LANES {
                    let el = els.get(l).unwrap_or(&els[0]);
                    block.nodes[l] = el.nodes;
                    block.volume.0[l] = el.volume;
                    for a in 0..3 {
                        for k in 0..3 {
                            block.grad[a][k].0[l] = el.grad[a][k];
                        }
                    }
                }
                block
            })
            .collect()
    }

    /// The current positions of every lane's nodes, lane by lane, in local node order.
    #[inline(always)]
    fn gather(&self, x: &[[f64; 3]]) -> [[V; 3]; N] {
        let mut xs = [[V::ZERO; 3]; N];
        for l in 0..LANES {
            for (a, &n) in self.nodes[l].iter().enumerate() {
                let p = x[n as usize];
                for k in 0..3 {
                    xs[a][k].0[l] = p[k];
                }
            }
        }
        xs
    }
}

/// An element kind the lane kernel evaluates: the node forces of a whole block, and of
/// one element (the fallback, which also names a failing element).
pub(crate) trait LaneKernel<const N: usize> {
    /// The node forces of every lane of `b`, in local node order; `None` when a lane needs
    /// the one-element kernel (see the module documentation).
    fn block_forces(b: &Block<N>, x: &[[f64; 3]], lambda: V, mu: V) -> Option<[[V; 3]; N]>;
    /// Adds the forces of element `e` to `forces`.
    fn add_one(
        el: &TetRef<N>,
        lame: Lame,
        x: &[[f64; 3]],
        forces: &mut [[f64; 3]],
        e: usize,
    ) -> Result<(), ElasticError>;
}

/// Linear 4-node tetrahedra ([`crate::kernels::tet4_forces`]).
pub(crate) struct Linear;
/// Quadratic 10-node tetrahedra ([`crate::kernels::tet10_forces`]).
pub(crate) struct Quadratic;

/// Which compilation of the block kernel to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Path {
    /// The baseline instruction set of the target.
    Portable,
    /// x86-64 with AVX2.
    #[cfg(target_arch = "x86_64")]
    Avx2,
    /// x86-64 with AVX-512 (foundation).
    #[cfg(target_arch = "x86_64")]
    Avx512,
}

impl Path {
    /// The widest path this processor runs.
    pub(crate) fn best() -> Path {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                return Path::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                return Path::Avx2;
            }
        }
        Path::Portable
    }

    /// Every path this processor runs (for tests).
    #[cfg(test)]
    pub(crate) fn available() -> Vec<Path> {
        let mut paths = vec![Path::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                paths.push(Path::Avx2);
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                paths.push(Path::Avx512);
            }
        }
        paths
    }
}

/// Adds the elastic forces of `blocks` (the blocks of `elements`) to `forces`, on `path`.
/// Same contract and errors as the one-element kernel, element by element.
pub(crate) fn add_block_forces<K: LaneKernel<N>, const N: usize>(
    path: Path,
    blocks: &[Block<N>],
    elements: &[TetRef<N>],
    lame: Lame,
    x: &[[f64; 3]],
    forces: &mut [[f64; 3]],
) -> Result<(), ElasticError> {
    match path {
        Path::Portable => add_all::<K, N>(blocks, elements, lame, x, forces),
        // SAFETY: `Path::best` and `Path::available` offer these paths only when the
        // processor reports the feature.
        #[cfg(target_arch = "x86_64")]
        Path::Avx2 => unsafe { add_all_avx2::<K, N>(blocks, elements, lame, x, forces) },
        #[cfg(target_arch = "x86_64")]
        Path::Avx512 => unsafe { add_all_avx512::<K, N>(blocks, elements, lame, x, forces) },
    }
}

/// [`add_all`] compiled with a target feature enabled (one function per path).
macro_rules! add_all_with {
    ($name:ident, $feature:literal) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $feature)]
        unsafe fn $name<K: LaneKernel<N>, const N: usize>(
            blocks: &[Block<N>],
            elements: &[TetRef<N>],
            lame: Lame,
            x: &[[f64; 3]],
            forces: &mut [[f64; 3]],
        ) -> Result<(), ElasticError> {
            add_all::<K, N>(blocks, elements, lame, x, forces)
        }
    };
}

add_all_with!(add_all_avx2, "avx2");
add_all_with!(add_all_avx512, "avx512f");

/// Every block, each one at a time when it cannot be done in lanes.
#[inline(always)]
fn add_all<K: LaneKernel<N>, const N: usize>(
    blocks: &[Block<N>],
    elements: &[TetRef<N>],
    lame: Lame,
    x: &[[f64; 3]],
    forces: &mut [[f64; 3]],
) -> Result<(), ElasticError> {
    let (lambda, mu) = (V::splat(lame.lambda), V::splat(lame.mu));
    for b in blocks {
        match K::block_forces(b, x, lambda, mu) {
            Some(fa) => {
                for l in 0..b.len {
                    let mut lane = [[0.0; 3]; N];
                    for (a, node) in fa.iter().enumerate() {
                        for k in 0..3 {
                            lane[a][k] = node[k].0[l];
                        }
                    }
                    scatter(&b.nodes[l], lane, forces);
                }
            }
            None => {
                for e in b.first..b.first + b.len {
                    K::add_one(&elements[e], lame, x, forces, e)?;
                }
            }
        }
    }
    Ok(())
}

/// A condition per lane: every bit set where it holds, none where it does not. Tests and
/// selections run on all lanes at once, without a branch per lane, so the compiler keeps
/// them in vector registers (a branch per lane made it take the vectors apart).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Mask([u64; LANES]);

impl Mask {
    /// Every lane.
    const ALL: Mask = Mask([u64::MAX; LANES]);

    /// The lanes where `test` holds.
    #[inline(always)]
    fn lanes(a: V, b: V, test: impl Fn(f64, f64) -> bool) -> Mask {
        let mut m = [0; LANES];
        for l in 0..LANES {
            m[l] = if test(a.0[l], b.0[l]) { u64::MAX } else { 0 };
        }
        Mask(m)
    }

    /// `a < b`, per lane (false where either is NaN).
    #[inline(always)]
    fn lt(a: V, b: V) -> Mask {
        Mask::lanes(a, b, |a, b| a < b)
    }

    /// `a >= b`, per lane (false where either is NaN).
    #[inline(always)]
    fn ge(a: V, b: V) -> Mask {
        Mask::lanes(a, b, |a, b| a >= b)
    }

    /// The lanes of both.
    #[inline(always)]
    fn and(self, o: Mask) -> Mask {
        let mut m = self.0;
        for l in 0..LANES {
            m[l] &= o.0[l];
        }
        Mask(m)
    }

    /// The lanes of `self` that are not in `o`.
    #[inline(always)]
    fn and_not(self, o: Mask) -> Mask {
        let mut m = self.0;
        for l in 0..LANES {
            m[l] &= !o.0[l];
        }
        Mask(m)
    }

    /// `true` when some lane holds.
    #[inline(always)]
    fn any(self) -> bool {
        self.0.iter().fold(0, |a, &m| a | m) != 0
    }

    /// `true` when every lane holds.
    #[inline(always)]
    fn all(self) -> bool {
        self.0.iter().fold(u64::MAX, |a, &m| a & m) == u64::MAX
    }

    /// `a` where the mask holds, `b` elsewhere: the values themselves, bit for bit.
    #[inline(always)]
    fn select(self, a: V, b: V) -> V {
        let mut r = [0.0; LANES];
        for l in 0..LANES {
            let m = self.0[l];
            r[l] = f64::from_bits((a.0[l].to_bits() & m) | (b.0[l].to_bits() & !m));
        }
        V(r)
    }

    /// [`Mask::select`] for every entry of two matrices.
    #[inline(always)]
    fn select_m(self, a: &M, b: &M) -> M {
        let mut r = *b;
        for i in 0..3 {
            for j in 0..3 {
                r[i][j] = self.select(a[i][j], b[i][j]);
            }
        }
        r
    }
}

/// `true` when every lane of `v` is finite and positive: `0 < v`, and `v - v` is zero
/// (NaN for an infinite `v`; NaN fails both). Written as arithmetic, not as `is_finite`
/// or `v < inf`, which the compiler turns into integer tests lane by lane.
#[inline(always)]
fn all_positive(v: V) -> bool {
    positive(v).all()
}

/// The lanes of `v` that are finite and positive (see [`all_positive`]).
#[allow(clippy::eq_op)] // `v - v` is the finiteness test, on purpose.
#[inline(always)]
fn positive(v: V) -> Mask {
    Mask::lt(V::ZERO, v).and(Mask::lanes(v - v, V::ZERO, |a, b| a == b))
}

impl LaneKernel<4> for Linear {
    #[inline(always)]
    fn block_forces(b: &Tet4Block, x: &[[f64; 3]], lambda: V, mu: V) -> Option<[[V; 3]; 4]> {
        // Edge vectors `d_a = x_a - x_0`, lane by lane.
        let mut d: M = [[V::ZERO; 3]; 3];
        for l in 0..LANES {
            let n = b.nodes[l];
            let x0 = x[n[0] as usize];
            for a in 0..3 {
                let xa = x[n[a + 1] as usize];
                for k in 0..3 {
                    d[a][k].0[l] = xa[k] - x0[k];
                }
            }
        }
        let f = tet4_gradient(&d, &b.grad);
        if !all_positive(det(&f)) {
            return None;
        }
        let r = polar_rotation_lanes(&f)?;
        Some(tet4_forces(&r, &f, &b.grad, b.volume, lambda, mu))
    }

    #[inline(always)]
    fn add_one(
        el: &TetRef<4>,
        lame: Lame,
        x: &[[f64; 3]],
        forces: &mut [[f64; 3]],
        e: usize,
    ) -> Result<(), ElasticError> {
        tet4_add_forces(el, lame, x, forces, e)
    }
}

impl LaneKernel<10> for Quadratic {
    /// The steps of [`crate::kernels::tet10_forces`], lane by lane.
    #[inline(always)]
    fn block_forces(b: &Tet10Block, x: &[[f64; 3]], lambda: V, mu: V) -> Option<[[V; 3]; 10]> {
        let xs = b.gather(x);
        let g = grads4(&b.grad);
        let (fc, fbar) = tet10_gradients(&xs, &g);
        let mut ok = positive(det(&fbar));
        for f in &fc {
            ok = ok.and(positive(det(f)));
        }
        if !ok.all() {
            return None;
        }
        let r = polar_rotation_lanes(&fbar)?;
        let eps = tet10_corner_strains(&r, &fc);
        let k = b.volume / V::splat(20.0);
        let (s, _) = tet10_smoothed_stresses(k, lambda, mu, &eps);
        let mut out = tet10_corotational_forces(&g, &s, &r);
        let det_a = tet10_add_correction(&xs, &g, &fbar, &r, &mut out);
        all_positive(det_a).then_some(out)
    }

    #[inline(always)]
    fn add_one(
        el: &TetRef<10>,
        lame: Lame,
        x: &[[f64; 3]],
        forces: &mut [[f64; 3]],
        e: usize,
    ) -> Result<(), ElasticError> {
        tet10_add_forces(el, lame, x, forces, e)
    }
}

/// `||X^T X - I||_F^2` and `X^T X`, per lane (as `polar::orthogonality_defect`).
#[inline(always)]
fn orthogonality_defect(x: &M) -> (V, M) {
    let m = gram(x);
    let mut r2 = V::ZERO;
    for i in 0..3 {
        for j in 0..3 {
            let d = m[i][j] - V::splat(IDENTITY[i][j]);
            r2 += d * d;
        }
    }
    (r2, m)
}

/// The Newton–Schulz phase of [`crate::polar::polar_rotation`], lane by lane: each lane
/// stops after the step taken below the convergence threshold, exactly as the one-matrix
/// iteration does. `None` when a lane starts outside the Newton–Schulz region or leaves it
/// (the one-element kernel then handles the block).
#[inline(always)]
fn polar_rotation_lanes(f: &M) -> Option<M> {
    let region = V::splat(NS_REGION2);
    let mut x = *f;
    let (mut r2, mut m) = orthogonality_defect(&x);
    // `r2 < NS_REGION2` fails for NaN too.
    if !Mask::lt(r2, region).all() {
        return None;
    }
    let mut active = Mask::ALL;
    for _ in 0..MAX_NS {
        let mut t = m;
        for i in 0..3 {
            for j in 0..3 {
                t[i][j] = V::splat(0.5) * (V::splat(3.0 * IDENTITY[i][j]) - t[i][j]);
            }
        }
        x = active.select_m(&mul(&x, &t), &x);
        active = active.and(Mask::ge(r2, V::splat(CONVERGED2)));
        if !active.any() {
            return Some(x);
        }
        let (r2_next, m_next) = orthogonality_defect(&x);
        if active.and_not(Mask::lt(r2_next, region)).any() {
            return None;
        }
        r2 = active.select(r2_next, r2);
        m = active.select_m(&m_next, &m);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (no dependency needed for test data).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64) / ((1u64 << 53) as f64) - 0.5
        }
    }

    /// Elements on random nodes, and positions: the rest nodes rotated by up to a half
    /// turn and strained by up to `strain`; every few elements one strained far beyond
    /// the Newton–Schulz region, so that blocks also take the fallback.
    fn case(n_el: usize, strain: f64, seed: u64) -> (Vec<TetRef<4>>, Vec<[f64; 3]>) {
        let mut g = Lcg(seed);
        let mut rest = Vec::new();
        let mut now = Vec::new();
        let mut els = Vec::new();
        for e in 0..n_el {
            let base = rest.len() as u32;
            let corners = [
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ];
            let (s, c) = (3.0 * g.next()).sin_cos();
            let big = if e % 13 == 5 { 0.6 } else { strain };
            let mut stretch = [[0.0; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    stretch[i][j] = f64::from(u8::from(i == j)) + big * g.next();
                }
            }
            for p in corners {
                let q = [
                    p[0] + 0.1 * g.next(),
                    p[1] + 0.1 * g.next(),
                    p[2] + 0.1 * g.next(),
                ];
                rest.push(q);
                let u = crate::mat3::mul_vec(&stretch, q);
                now.push([c * u[0] - s * u[1] + 2.0, s * u[0] + c * u[1], u[2] - 1.0]);
            }
            let b = base as usize;
            els.extend(crate::element_set::build::<4>(&rest, &[b, b + 1, b + 2, b + 3]).unwrap());
        }
        (els, now)
    }

    #[test]
    fn every_path_gives_the_one_element_forces_to_the_last_bit() {
        let lame = Lame {
            lambda: 1.1e10,
            mu: 1.6e10,
        };
        for (strain, seed) in [(1e-5, 1), (1e-4, 2), (1e-3, 3), (3e-2, 4)] {
            // 61 elements: seven full blocks and a partial one.
            let (els, x) = case(61, strain, seed);
            let mut reference = vec![[0.0; 3]; x.len()];
            for (e, el) in els.iter().enumerate() {
                tet4_add_forces(el, lame, &x, &mut reference, e).unwrap();
            }
            assert_every_path_gives::<Linear, 4>(&els, lame, &x, &reference, strain);
        }
    }

    #[test]
    fn the_positive_mask_is_finite_and_positive_lane_by_lane() {
        let special = [
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            -1.0,
            1.0,
            -f64::MAX,
            f64::EPSILON,
        ];
        // Every special value in every lane, beside finite positive values in the others.
        for &value in &special {
            for lane in 0..LANES {
                let mut v = V([1.0; LANES]);
                v.0[lane] = value;
                let expected = value.is_finite() && value > 0.0;
                assert_eq!(all_positive(v), expected, "{value:e} in lane {lane}");
                let m = positive(v);
                for l in 0..LANES {
                    assert_eq!(m.0[l] == u64::MAX, l != lane || expected, "{value:e}");
                    assert!(m.0[l] == u64::MAX || m.0[l] == 0);
                }
            }
        }
    }

    #[test]
    fn a_mask_selects_the_bits_of_each_lane() {
        let a = V([-0.0, f64::NAN, 1.0, -2.5, f64::INFINITY, 3.0, 5e-324, 7.0]);
        let b = V([0.0, 4.0, f64::NAN, 2.5, -1.0, -3.0, 6.0, -0.0]);
        let m = Mask::lt(V([0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0]), V::splat(0.5));
        let r = m.select(a, b);
        for l in 0..LANES {
            let want = if l % 2 == 0 { a.0[l] } else { b.0[l] };
            assert_eq!(r.0[l].to_bits(), want.to_bits(), "lane {l}");
        }
        // NaN compares false either way; `and_not`, `any` and `all` by lane.
        let nan = V::splat(f64::NAN);
        assert!(!Mask::lt(nan, V::ZERO).any() && !Mask::ge(nan, V::ZERO).any());
        assert!(Mask::ALL.all() && !m.all() && m.any());
        assert!(!m.and_not(m).any() && m.and(Mask::ALL) == m);
    }

    #[test]
    fn a_block_holds_eight_elements_in_784_or_976_bytes() {
        // 98 bytes per linear and 122 per quadratic element (docs/PERFORMANCE.md, "Memory").
        assert_eq!(std::mem::size_of::<Tet4Block>(), 784);
        assert_eq!(std::mem::size_of::<Tet10Block>(), 976);
    }

    /// Quadratic elements on random nodes (straight-sided at rest), and positions: the rest
    /// nodes rotated by up to a half turn, strained by up to `strain`, and each node moved
    /// by up to `strain` of the element's size on its own (so that the corner gradients
    /// differ and the energy correction (Q5) is not zero); every few elements one strained
    /// far beyond the Newton–Schulz region, so that blocks also take the fallback.
    fn case10(n_el: usize, strain: f64, seed: u64) -> (Vec<TetRef<10>>, Vec<[f64; 3]>) {
        let mut g = Lcg(seed);
        let mut rest = Vec::new();
        let mut now = Vec::new();
        let mut els = Vec::new();
        for e in 0..n_el {
            let base = rest.len();
            let mut corners = [
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ];
            for c in &mut corners {
                for v in c.iter_mut() {
                    *v += 0.1 * g.next();
                }
            }
            let mut nodes10 = corners.to_vec();
            for (a, b) in crate::kernels::EDGES {
                nodes10.push([
                    0.5 * (corners[a][0] + corners[b][0]),
                    0.5 * (corners[a][1] + corners[b][1]),
                    0.5 * (corners[a][2] + corners[b][2]),
                ]);
            }
            let (s, c) = (3.0 * g.next()).sin_cos();
            let big = if e % 13 == 5 { 0.6 } else { strain };
            let mut stretch = [[0.0; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    stretch[i][j] = f64::from(u8::from(i == j)) + big * g.next();
                }
            }
            let jitter = big.min(0.05);
            for q in nodes10 {
                rest.push(q);
                let mut u = crate::mat3::mul_vec(&stretch, q);
                for v in &mut u {
                    *v += jitter * g.next();
                }
                now.push([c * u[0] - s * u[1] + 2.0, s * u[0] + c * u[1], u[2] - 1.0]);
            }
            let ids: Vec<usize> = (base..base + 10).collect();
            els.extend(crate::element_set::build::<10>(&rest, &ids).unwrap());
        }
        (els, now)
    }

    #[test]
    fn every_path_gives_the_one_element_quadratic_forces_to_the_last_bit() {
        let lame = Lame {
            lambda: 1.1e10,
            mu: 1.6e10,
        };
        for (strain, seed) in [(1e-5, 1), (1e-4, 2), (1e-3, 3), (3e-2, 4)] {
            let (els, x) = case10(61, strain, seed);
            let mut reference = vec![[0.0; 3]; x.len()];
            let mut correction = 0.0_f64;
            for (e, el) in els.iter().enumerate() {
                crate::kernels::tet10_add_forces(el, lame, &x, &mut reference, e).unwrap();
                // The size of (Q5) relative to the forces, so that the test covers it.
                let st = crate::kernels::tet10_kinematics(el, &x, e).unwrap();
                let g = el.grads4();
                let (s, _) =
                    tet10_smoothed_stresses(el.volume / 20.0, lame.lambda, lame.mu, &st.eps);
                let plain = tet10_corotational_forces(&g, &s, &st.r);
                let mut full = plain;
                tet10_add_correction(&st.xs, &g, &st.fbar, &st.r, &mut full);
                let scale = plain.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
                for (a, b) in full.iter().flatten().zip(plain.iter().flatten()) {
                    correction = correction.max((a - b).abs() / scale);
                }
            }
            assert!(
                correction > 1e-9,
                "strain {strain}: (Q5) too small to test: {correction}"
            );
            assert_every_path_gives::<Quadratic, 10>(&els, lame, &x, &reference, strain);
        }
    }

    #[test]
    fn an_inverted_quadratic_element_is_named_on_every_path() {
        let (els, mut x) = case10(20, 1e-4, 9);
        // Element 11: swap two corners' current positions (det F < 0).
        x.swap(110, 111);
        assert_element_11_is_named::<Quadratic, 10>(&els, &x);
    }

    /// Every path's forces for `els` at `x` equal `reference` to the last bit.
    fn assert_every_path_gives<K: LaneKernel<N>, const N: usize>(
        els: &[TetRef<N>],
        lame: Lame,
        x: &[[f64; 3]],
        reference: &[[f64; 3]],
        strain: f64,
    ) {
        let blocks = Block::blocks(els);
        for path in Path::available() {
            let mut forces = vec![[0.0; 3]; x.len()];
            add_block_forces::<K, N>(path, &blocks, els, lame, x, &mut forces).unwrap();
            for (a, b) in forces.iter().zip(reference) {
                for k in 0..3 {
                    assert_eq!(a[k].to_bits(), b[k].to_bits(), "{path:?}, strain {strain}");
                }
            }
        }
    }

    /// Element 11 of `els`, inverted at `x`, is named on every path.
    fn assert_element_11_is_named<K: LaneKernel<N>, const N: usize>(
        els: &[TetRef<N>],
        x: &[[f64; 3]],
    ) {
        let lame = Lame {
            lambda: 1.0,
            mu: 1.0,
        };
        let blocks = Block::blocks(els);
        for path in Path::available() {
            let mut forces = vec![[0.0; 3]; x.len()];
            let err =
                add_block_forces::<K, N>(path, &blocks, els, lame, x, &mut forces).unwrap_err();
            assert!(
                matches!(err, ElasticError::InvertedElement { element: 11, .. }),
                "{path:?}: {err}"
            );
        }
    }

    #[test]
    fn an_inverted_element_is_named_on_every_path() {
        let (els, mut x) = case(20, 1e-4, 9);
        // Element 11: swap two corners' current positions (det F < 0).
        x.swap(44, 45);
        assert_element_11_is_named::<Linear, 4>(&els, &x);
    }
}
