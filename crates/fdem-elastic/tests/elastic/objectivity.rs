//! Objectivity: deforming, then rotating by a large angle, rotates forces and stresses and
//! leaves the energy unchanged.
//!
//! Tolerance 1e-9 relative to the largest force / stress: the strains here are ~1e-4 and
//! are computed from coordinates with round-off ~1e-16 (times |x|/h ~ 10), so the relative
//! error is ~1e-11.

use proptest::prelude::*;

use fdem_elastic::Mat3;

use crate::common::{
    Lcg, forces, from_voigt, kuhn_cube, matmul, matvec, max_abs, max_force, norm, quat_rotation,
    rigid, sub, transpose,
};

const H: f64 = 1e-2;

fn check(quadratic: bool, q: &Mat3, t: [f64; 3], seed: u64) -> Result<(), String> {
    let mesh = kuhn_cube(2, H, quadratic);
    let set = mesh.element_set();
    // A general small deformation: random nodal displacements of 1e-4 h (strain ~1e-4).
    let mut rng = Lcg(seed);
    let x: Vec<[f64; 3]> = mesh
        .nodes
        .iter()
        .map(|p| {
            [
                p[0] + 1e-4 * H * rng.next(),
                p[1] + 1e-4 * H * rng.next(),
                p[2] + 1e-4 * H * rng.next(),
            ]
        })
        .collect();
    let xr = rigid(&x, q, t);
    let f = forces(&set, &x);
    let fr = forces(&set, &xr);
    let fscale = max_force(&f);
    for (a, b) in f.iter().zip(&fr) {
        let d = norm(sub(matvec(q, *a), *b));
        if d > 1e-9 * fscale {
            return Err(format!("force {d:e} vs {fscale:e}"));
        }
    }
    let n = set.n_elements();
    let (mut s, mut sr) = (vec![[0.0; 6]; n], vec![[0.0; 6]; n]);
    set.cauchy_stresses(&x, &mut s).map_err(|e| e.to_string())?;
    set.cauchy_stresses(&xr, &mut sr)
        .map_err(|e| e.to_string())?;
    let sscale = s
        .iter()
        .map(|v| max_abs(&from_voigt(*v)))
        .fold(0.0, f64::max);
    for (a, b) in s.iter().zip(&sr) {
        let rotated = matmul(&matmul(q, &from_voigt(*a)), &transpose(q));
        let mut d: f64 = 0.0;
        let bm = from_voigt(*b);
        for i in 0..3 {
            for j in 0..3 {
                d = d.max((rotated[i][j] - bm[i][j]).abs());
            }
        }
        if d > 1e-9 * sscale {
            return Err(format!("stress {d:e} vs {sscale:e}"));
        }
    }
    let (w, wr) = (set.strain_energy(&x), set.strain_energy(&xr));
    if ((w - wr) / w).abs() > 1e-9 || w <= 0.0 {
        return Err(format!("energy {w:e} vs {wr:e}"));
    }
    Ok(())
}

#[test]
fn half_turn_after_small_strain() {
    let q = quat_rotation([0.0, 0.3, -0.8, 0.5]); // w = 0: 180 degrees
    for quadratic in [false, true] {
        check(quadratic, &q, [1.0, 2.0, -0.5], 3).unwrap();
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    #[test]
    fn random_rotation_after_small_strain(
        q in prop::array::uniform4(-1.0f64..1.0)
            .prop_filter("non-degenerate", |q| q.iter().map(|v| v * v).sum::<f64>() > 1e-2),
        seed in 0u64..1000,
        quadratic in any::<bool>(),
    ) {
        let r = check(quadratic, &quat_rotation(q), [0.05, -0.02, 0.01], seed);
        prop_assert!(r.is_ok(), "{:?}", r);
    }
}
