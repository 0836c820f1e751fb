//! Rigid motions of any angle give zero force, stress and energy to round-off.
//!
//! Scale of "zero": a strain of round-off size `1e-15` (coordinate round-off `1e-16` times
//! `|x| / h <= ~10`) gives nodal forces ~ `1e-15 E h^2`; we require
//! `|f| <= 1e-12 E V^(2/3)` (with `V^(2/3) ~ h^2 / 3.3` for the Kuhn tetrahedra, a margin of
//! about 300), `|sigma| <= 1e-12 E` and `W <= 1e-20 E V_total` (`W ~ E eps^2 V`).

use proptest::prelude::*;

use fdem_elastic::{ElementSet, Mat3};

use crate::common::{
    E, Mesh, forces, kuhn_cube, matmul, max_force, quat_rotation, rigid, rotation,
};

const H: f64 = 1e-2;

fn check_rigid(mesh: &Mesh, set: &ElementSet, q: &Mat3, t: [f64; 3]) -> Result<(), String> {
    let x = rigid(&mesh.nodes, q, t);
    let v_mean = set.total_volume() / set.n_elements() as f64;
    let f_tol = 1e-12 * E * v_mean.powf(2.0 / 3.0);
    let fmax = max_force(&forces(set, &x));
    if fmax > f_tol {
        return Err(format!("force {fmax:e} > {f_tol:e}"));
    }
    let mut s = vec![[0.0; 6]; set.n_elements()];
    set.cauchy_stresses(&x, &mut s).map_err(|e| e.to_string())?;
    let smax = s.iter().flatten().fold(0.0_f64, |a, v| a.max(v.abs()));
    if smax > 1e-12 * E {
        return Err(format!("stress {smax:e}"));
    }
    let w = set.try_strain_energy(&x).map_err(|e| e.to_string())?;
    if !(0.0..=1e-20 * E * set.total_volume()).contains(&w) {
        return Err(format!("energy {w:e}"));
    }
    Ok(())
}

#[test]
fn half_turns_and_their_compositions() {
    let axes = [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 0.0],
        [1.0, 1.0, 1.0],
        [-0.3, 0.7, 0.2],
    ];
    let pi = std::f64::consts::PI;
    for quadratic in [false, true] {
        let mesh = kuhn_cube(2, H, quadratic);
        let set = mesh.element_set();
        for axis in axes {
            for angle in [pi, -pi, pi - 1e-12, pi - 1e-6, 0.5 * pi, 1e-9, 2.0 * pi] {
                let q = rotation(axis, angle);
                check_rigid(&mesh, &set, &q, [0.3, -0.2, 0.1]).unwrap();
            }
            // Two half-turns about different axes compose to a rotation by twice the angle
            // between the axes.
            let q = matmul(&rotation(axis, pi), &rotation([0.2, -1.0, 0.4], pi));
            check_rigid(&mesh, &set, &q, [0.0; 3]).unwrap();
        }
    }
}

#[test]
fn continuous_tumbling_over_several_turns() {
    // 3 turns about a precessing axis in 600 increments; the set is reused (as in a run).
    for quadratic in [false, true] {
        let mesh = kuhn_cube(1, H, quadratic);
        let set = mesh.element_set();
        for k in 0..=600 {
            let s = k as f64 / 600.0;
            let axis = [(7.0 * s).cos(), (7.0 * s).sin(), 0.5];
            let q = rotation(axis, 6.0 * std::f64::consts::PI * s);
            check_rigid(&mesh, &set, &q, [s * H, 0.0, -s * H]).unwrap();
        }
    }
}

fn quaternion() -> impl Strategy<Value = [f64; 4]> {
    prop::array::uniform4(-1.0f64..1.0).prop_filter("non-degenerate", |q| {
        q.iter().map(|v| v * v).sum::<f64>() > 1e-2
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// Random rotations (the sampled quaternions include w ~ 0, i.e. ~180 degrees) plus
    /// translations up to 10 element sizes.
    #[test]
    fn random_rigid_motions_give_zero_force(
        q in quaternion(),
        t in prop::array::uniform3(-10.0 * H..10.0 * H),
        quadratic in any::<bool>(),
    ) {
        let mesh = kuhn_cube(1, H, quadratic);
        let set = mesh.element_set();
        let r = check_rigid(&mesh, &set, &quat_rotation(q), t);
        prop_assert!(r.is_ok(), "{:?}", r);
    }
}
