//! Patch tests on a 2x2x2-cell cube (48 Kuhn tetrahedra, and its 10-node version): a
//! linear displacement field is represented exactly, so every element carries the same
//! stress `C : eps`, interior nodes are in equilibrium, and the forces equal `-K u`.

use nalgebra::{DMatrix, DVector, Matrix3};

use crate::common::{
    E, Lcg, Mesh, assemble_stiffness, forces, from_voigt, hooke, kuhn_cube, linear_field, matmul,
    max_abs, norm, rock, sub, transpose,
};
use fdem_elastic::Mat3;

const H: f64 = 1e-2;

fn meshes() -> [Mesh; 2] {
    [kuhn_cube(2, H, false), kuhn_cube(2, H, true)]
}

fn interior(mesh: &Mesh) -> Vec<usize> {
    let l = 2.0 * H;
    let inside = |v: f64| v > 1e-9 * l && v < l * (1.0 - 1e-9);
    (0..mesh.nodes.len())
        .filter(|&i| mesh.nodes[i].iter().all(|&v| inside(v)))
        .collect()
}

/// A symmetric small strain (so that `F = I + A` is symmetric positive definite, `R = I`).
const A_SYM: Mat3 = [
    [1.0e-4, 3.0e-5, -2.0e-5],
    [3.0e-5, -5.0e-5, 4.0e-5],
    [-2.0e-5, 4.0e-5, 2.0e-4],
];

fn displacement_vector(mesh: &Mesh, x: &[[f64; 3]]) -> DVector<f64> {
    DVector::from_iterator(
        3 * x.len(),
        x.iter().zip(&mesh.nodes).flat_map(|(a, b)| sub(*a, *b)),
    )
}

fn force_vector(f: &[[f64; 3]]) -> DVector<f64> {
    DVector::from_iterator(3 * f.len(), f.iter().flatten().copied())
}

#[test]
fn linear_field_gives_uniform_exact_stress_and_interior_equilibrium() {
    for mesh in meshes() {
        let set = mesh.element_set();
        let x = linear_field(&mesh.nodes, &A_SYM);
        let exact = hooke(&rock(), &A_SYM);
        let scale = max_abs(&exact);
        let mut s = vec![[0.0; 6]; set.n_elements()];
        set.cauchy_stresses(&x, &mut s).unwrap();
        for (e, se) in s.iter().enumerate() {
            let d = max_abs(&sub_m(&from_voigt(*se), &exact));
            // Tolerance 1e-9 relative: strain 1e-4 is computed from coordinate differences
            // with round-off ~1e-16, i.e. a relative error ~1e-12 of the strain.
            assert!(d < 1e-9 * scale, "element {e}: {se:?} vs {exact:?}");
        }
        let f = forces(&set, &x);
        // Force scale of one element: |sigma| h^2 ~ E |A| h^2.
        let f_scale = E * 2e-4 * H * H;
        let inner = interior(&mesh);
        assert!(!inner.is_empty());
        for &i in &inner {
            assert!(norm(f[i]) < 1e-9 * f_scale, "node {i}: {:?}", f[i]);
        }
        // Global equilibrium: zero resultant and zero moment (to round-off).
        let mut total = [0.0; 3];
        let mut moment = [0.0; 3];
        for (p, fi) in x.iter().zip(&f) {
            for k in 0..3 {
                total[k] += fi[k];
            }
            let c = [
                p[1] * fi[2] - p[2] * fi[1],
                p[2] * fi[0] - p[0] * fi[2],
                p[0] * fi[1] - p[1] * fi[0],
            ];
            for k in 0..3 {
                moment[k] += c[k];
            }
        }
        assert!(norm(total) < 1e-9 * f_scale);
        assert!(norm(moment) < 1e-9 * f_scale * H);
        // The forces are minus the assembled linear stiffness times u (R = I exactly here).
        let k = assemble_stiffness(&set);
        let u = displacement_vector(&mesh, &x);
        let ku = &k * &u;
        let err = (force_vector(&f) + &ku).amax();
        assert!(err < 1e-9 * ku.amax(), "{err} vs {}", ku.amax());
        // Energy: 1/2 u^T K u = V sigma:eps / 2 (uniform field), to 1e-9 relative.
        let w = set.strain_energy(&x);
        let w_k = 0.5 * u.dot(&ku);
        let w_exact = 0.5
            * set.total_volume()
            * (0..3)
                .flat_map(|i| (0..3).map(move |j| (i, j)))
                .map(|(i, j)| exact[i][j] * A_SYM[i][j])
                .sum::<f64>();
        assert!(((w - w_k) / w_k).abs() < 1e-9, "{w} vs {w_k}");
        assert!(((w - w_exact) / w_exact).abs() < 1e-9, "{w} vs {w_exact}");
    }
}

fn sub_m(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = *a;
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] -= b[i][j];
        }
    }
    c
}

/// Polar decomposition by SVD (nalgebra), independent of the crate's iteration.
fn polar_svd(f: &Mat3) -> (Mat3, Mat3) {
    let m = Matrix3::from_fn(|i, j| f[i][j]);
    let svd = m.svd(true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
    let r = u * vt;
    let s = vt.transpose() * Matrix3::from_diagonal(&svd.singular_values) * vt;
    let to =
        |m: Matrix3<f64>| -> Mat3 { std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)])) };
    (to(r), to(s))
}

#[test]
fn linear_field_with_rotation_part_gives_uniform_corotated_stress() {
    // A non-symmetric gradient: the co-rotated stress is R C:(U - I) R^T with F = R U.
    let a: Mat3 = [
        [1.0e-4, 2.0e-3, -2.0e-5],
        [-1.5e-3, -5.0e-5, 4.0e-5],
        [3.0e-4, 4.0e-5, 2.0e-4],
    ];
    let mut f = a;
    for (i, row) in f.iter_mut().enumerate() {
        row[i] += 1.0;
    }
    let (r, u) = polar_svd(&f);
    let mut eps = u;
    for (i, row) in eps.iter_mut().enumerate() {
        row[i] -= 1.0;
    }
    let expect = matmul(&matmul(&r, &hooke(&rock(), &eps)), &transpose(&r));
    for mesh in meshes() {
        let set = mesh.element_set();
        let x = linear_field(&mesh.nodes, &a);
        let mut s = vec![[0.0; 6]; set.n_elements()];
        set.cauchy_stresses(&x, &mut s).unwrap();
        for se in &s {
            // 1e-9 relative: round-off of SVD and of the strain from coordinates.
            assert!(max_abs(&sub_m(&from_voigt(*se), &expect)) < 1e-9 * max_abs(&expect));
        }
        let f = forces(&set, &x);
        for &i in &interior(&mesh) {
            assert!(norm(f[i]) < 1e-9 * E * 2e-4 * H * H);
        }
    }
}

#[test]
fn forces_linearize_to_minus_k_u_for_arbitrary_small_displacements() {
    for mesh in meshes() {
        let set = mesh.element_set();
        let k = assemble_stiffness(&set);
        let mut rng = Lcg(7);
        let dir: Vec<[f64; 3]> = (0..mesh.nodes.len())
            .map(|_| [rng.next(), rng.next(), rng.next()])
            .collect();
        let rel_err = |alpha: f64| {
            let x: Vec<[f64; 3]> = mesh
                .nodes
                .iter()
                .zip(&dir)
                .map(|(p, d)| {
                    [
                        p[0] + alpha * d[0],
                        p[1] + alpha * d[1],
                        p[2] + alpha * d[2],
                    ]
                })
                .collect();
            let f = force_vector(&forces(&set, &x));
            let ku: DVector<f64> = &k * displacement_vector(&mesh, &x);
            (f + &ku).amax() / ku.amax()
        };
        // Strain ~ alpha/h: the co-rotational terms are second order, so the relative
        // difference is O(alpha/h) and must shrink linearly with alpha.
        let e1 = rel_err(1e-6 * H);
        let e2 = rel_err(1e-7 * H);
        assert!(e1 < 1e-4, "{e1}");
        assert!(e2 < e1 / 5.0, "{e2} vs {e1}");
    }
}

#[test]
fn element_stiffness_is_symmetric_and_has_six_rigid_modes() {
    for mesh in meshes() {
        let set = mesh.element_set();
        let k: DMatrix<f64> = set.element_stiffness(0).unwrap();
        let asym = (&k - k.transpose()).amax();
        assert!(asym < 1e-12 * k.amax());
        let ev = k.symmetric_eigenvalues();
        let kmax = ev.amax();
        let zeros = ev.iter().filter(|v| v.abs() < 1e-10 * kmax).count();
        assert_eq!(zeros, 6, "{ev}");
        assert!(ev.iter().all(|v| *v > -1e-10 * kmax));
    }
}
