//! The forces are the exact negative gradient of the strain energy (the model is
//! conservative) and carry no net force or torque, for large rotations and both element
//! orders.

use crate::common::{Lcg, Mesh, forces, kuhn_cube, norm, quat_rotation, rigid};

const H: f64 = 1e-2;

/// A deformed and rotated state: random nodal displacements of 1e-3 h (strain ~1e-3), then
/// a rotation by about 150 degrees and a translation.
fn deformed(mesh: &Mesh, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = Lcg(seed);
    let x: Vec<[f64; 3]> = mesh
        .nodes
        .iter()
        .map(|p| {
            [
                p[0] + 1e-3 * H * rng.next(),
                p[1] + 1e-3 * H * rng.next(),
                p[2] + 1e-3 * H * rng.next(),
            ]
        })
        .collect();
    rigid(&x, &quat_rotation([0.25, 0.6, -0.7, 0.3]), [0.1, 0.2, -0.3])
}

#[test]
fn forces_are_minus_the_energy_gradient() {
    for quadratic in [false, true] {
        let mesh = kuhn_cube(1, H, quadratic);
        let set = mesh.element_set();
        let x = deformed(&mesh, 21);
        let f = forces(&set, &x);
        let fmax = f.iter().map(|v| norm(*v)).fold(0.0, f64::max);
        // Central differences with step d = 1e-6 h: truncation error ~ (d/h)^2 ~ 1e-12 of the
        // force, round-off ~ 1e-16 W / d ~ 1e-13 of it. Tolerance 1e-7 relative.
        let d = 1e-6 * H;
        let mut worst: f64 = 0.0;
        for i in 0..x.len() {
            for k in 0..3 {
                let mut xp = x.clone();
                let mut xm = x.clone();
                xp[i][k] += d;
                xm[i][k] -= d;
                let g = (set.strain_energy(&xp) - set.strain_energy(&xm)) / (2.0 * d);
                worst = worst.max((f[i][k] + g).abs());
            }
        }
        assert!(
            worst < 1e-7 * fmax,
            "quadratic={quadratic}: {worst:e} vs {fmax:e}"
        );
    }
}

#[test]
fn forces_have_zero_resultant_and_zero_torque() {
    for quadratic in [false, true] {
        let mesh = kuhn_cube(2, H, quadratic);
        let set = mesh.element_set();
        for seed in 0..5 {
            let x = deformed(&mesh, seed);
            let f = forces(&set, &x);
            let fmax = f.iter().map(|v| norm(*v)).fold(0.0, f64::max);
            let (mut total, mut torque) = ([0.0; 3], [0.0; 3]);
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
                    torque[k] += c[k];
                }
            }
            // Round-off of sums of O(100) forces at lever arms |x| ~ 0.4 m: 1e-12 relative.
            let arm = x.iter().map(|p| norm(*p)).fold(0.0, f64::max);
            assert!(norm(total) < 1e-12 * fmax * 100.0, "{total:?}");
            assert!(
                norm(torque) < 1e-12 * fmax * arm * 100.0,
                "quadratic={quadratic}: {torque:?}"
            );
        }
    }
}
