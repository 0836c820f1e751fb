//! Cross-crate checks of the element kernels on real particle meshes (fdem-mesh +
//! fdem-elastic): the patch test and rigid-rotation objectivity on meshed spheres.

// Component loops over x, y, z read best with an index.
#![allow(clippy::needless_range_loop)]

use fdem_elastic::{ElementSet, Material};
use fdem_mesh::{ElementOrder, Sizing, SphereSpec, sphere_mesh};

fn material() -> Material {
    Material::new(2650.0, 40.0e9, 0.2).unwrap()
}

fn sphere(level: u32, order: ElementOrder) -> fdem_mesh::TetMesh {
    sphere_mesh(&SphereSpec {
        level,
        order,
        diameter: 0.015,
        sizing: Sizing::Inscribed,
    })
    .unwrap()
}

/// Patch test: the displacement `u = G X` with a small constant symmetric gradient G
/// (a pure strain, so the polar rotation is the identity) reproduces the uniform analytic
/// stress `sigma = lambda tr(eps) I + 2 mu eps`, `eps = G`, in every element, for every
/// level and both orders, and puts no force on interior nodes. Tolerance 1e-9 relative to
/// |sigma|: the only error is round-off, about 1e-16 x (R / h_min) / |G| = 1e-11 here
/// for |G| = 1e-4 (a non-symmetric G would rotate the stress by skew(G), a real
/// second-order effect), and any kernel mistake shows at order 1.
#[test]
fn patch_test_on_meshed_spheres() {
    let m = material();
    let (lambda, mu) = (m.lame_lambda(), m.shear_modulus());
    let g = [
        [1.0e-4, 0.3e-4, -0.2e-4],
        [0.3e-4, -0.5e-4, 0.4e-4],
        [-0.2e-4, 0.4e-4, 0.7e-4],
    ];
    let eps = |i: usize, j: usize| 0.5 * (g[i][j] + g[j][i]);
    let tr = eps(0, 0) + eps(1, 1) + eps(2, 2);
    let sigma = |i: usize, j: usize| if i == j { lambda * tr } else { 0.0 } + 2.0 * mu * eps(i, j);
    let expected = [
        sigma(0, 0),
        sigma(1, 1),
        sigma(2, 2),
        sigma(1, 2),
        sigma(0, 2),
        sigma(0, 1),
    ];
    let scale = expected.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    for order in [ElementOrder::Linear, ElementOrder::Quadratic] {
        for level in 0..=2 {
            let mesh = sphere(level, order);
            let set = ElementSet::new(&m, order.nodes_per_element(), &mesh.nodes, &mesh.elements)
                .unwrap();
            let x: Vec<[f64; 3]> = mesh
                .nodes
                .iter()
                .map(|p| {
                    let mut q = *p;
                    for i in 0..3 {
                        q[i] += g[i][0] * p[0] + g[i][1] * p[1] + g[i][2] * p[2];
                    }
                    q
                })
                .collect();
            let mut stresses = vec![[0.0; 6]; set.n_elements()];
            set.cauchy_stresses(&x, &mut stresses).unwrap();
            for (e, s) in stresses.iter().enumerate() {
                for k in 0..6 {
                    assert!(
                        (s[k] - expected[k]).abs() < 1e-9 * scale,
                        "{order:?} level {level} element {e} component {k}: {} vs {}",
                        s[k],
                        expected[k]
                    );
                }
            }
            // Interior nodes (not on the surface) carry no net force under a uniform stress.
            let mut f = vec![[0.0; 3]; x.len()];
            set.add_forces(&x, &mut f).unwrap();
            let on_surface: std::collections::HashSet<usize> =
                mesh.surface.nodes.iter().copied().collect();
            let fscale = scale * 0.015 * 0.015;
            for (i, fi) in f
                .iter()
                .enumerate()
                .filter(|(i, _)| !on_surface.contains(i))
            {
                let n = (fi[0] * fi[0] + fi[1] * fi[1] + fi[2] * fi[2]).sqrt();
                assert!(
                    n < 1e-8 * fscale,
                    "{order:?} level {level} interior node {i}: |f| = {n:e} N"
                );
            }
        }
    }
}

/// Objectivity on a whole particle: rotating the deformed sphere by a large rotation
/// rotates the stress (sigma' = Q sigma Q^T) and the forces (f' = Q f), to 1e-9 relative.
#[test]
fn rotating_a_strained_sphere_rotates_its_stress() {
    let m = material();
    let mesh = sphere(1, ElementOrder::Quadratic);
    let set = ElementSet::new(&m, 10, &mesh.nodes, &mesh.elements).unwrap();
    // Uniaxial strain 1e-4 along x plus a little shear.
    let x: Vec<[f64; 3]> = mesh
        .nodes
        .iter()
        .map(|p| [p[0] * (1.0 + 1e-4) + 2e-5 * p[1], p[1], p[2]])
        .collect();
    // Rotation by 2.5 rad about (1, 2, 2)/3.
    let (angle, axis) = (2.5f64, [1.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0]);
    let (c, s) = (angle.cos(), angle.sin());
    let mut q = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let delta = if i == j { 1.0 } else { 0.0 };
            let cross = match (i, j) {
                (0, 1) => -axis[2],
                (0, 2) => axis[1],
                (1, 0) => axis[2],
                (1, 2) => -axis[0],
                (2, 0) => -axis[1],
                (2, 1) => axis[0],
                _ => 0.0,
            };
            q[i][j] = c * delta + s * cross + (1.0 - c) * axis[i] * axis[j];
        }
    }
    let rot = |v: [f64; 3]| [0, 1, 2].map(|i| q[i][0] * v[0] + q[i][1] * v[1] + q[i][2] * v[2]);
    let xr: Vec<[f64; 3]> = x.iter().map(|&p| rot(p)).collect();
    let (mut s0, mut s1) = (vec![[0.0; 6]; 80], vec![[0.0; 6]; 80]);
    set.cauchy_stresses(&x, &mut s0).unwrap();
    set.cauchy_stresses(&xr, &mut s1).unwrap();
    let full = |v: [f64; 6]| [[v[0], v[5], v[4]], [v[5], v[1], v[3]], [v[4], v[3], v[2]]];
    let scale = 40.0e9 * 1e-4;
    for e in 0..80 {
        let a = full(s0[e]);
        let b = full(s1[e]);
        for i in 0..3 {
            for j in 0..3 {
                let mut expect = 0.0;
                for k in 0..3 {
                    for l in 0..3 {
                        expect += q[i][k] * a[k][l] * q[j][l];
                    }
                }
                assert!(
                    (b[i][j] - expect).abs() < 1e-9 * scale,
                    "element {e} ({i},{j})"
                );
            }
        }
    }
    let (mut f0, mut f1) = (vec![[0.0; 3]; x.len()], vec![[0.0; 3]; x.len()]);
    set.add_forces(&x, &mut f0).unwrap();
    set.add_forces(&xr, &mut f1).unwrap();
    let fscale = scale * 0.015 * 0.015;
    for (a, b) in f0.iter().zip(&f1) {
        let ra = rot(*a);
        for k in 0..3 {
            assert!((b[k] - ra[k]).abs() < 1e-9 * fscale);
        }
    }
}
