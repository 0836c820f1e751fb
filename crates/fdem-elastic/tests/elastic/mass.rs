//! Lumped masses.

use fdem_elastic::{HRZ_CORNER_FRACTION, HRZ_MID_EDGE_FRACTION};

use crate::common::{RHO, kuhn_cube, rock, single_tet};

#[test]
fn lumped_masses_are_positive_and_sum_to_rho_v() {
    for quadratic in [false, true] {
        for mesh in [kuhn_cube(2, 3e-3, quadratic), single_tet(quadratic)] {
            let set = mesh.element_set();
            let v: f64 = set.total_volume();
            let m = set.lumped_masses(mesh.nodes.len());
            assert_eq!(m.len(), mesh.nodes.len());
            assert!(m.iter().all(|&mi| mi > 0.0));
            let sum: f64 = m.iter().sum();
            // Tolerance 1e-12 relative: a sum of O(100) positive terms, round-off only.
            assert!(
                ((sum - RHO * v) / (RHO * v)).abs() < 1e-12,
                "{sum} vs {}",
                RHO * v
            );
            assert!(((set.total_mass() - RHO * v) / (RHO * v)).abs() < 1e-14);
        }
    }
    // The cube mesh's volume is exactly (2 h)^3.
    let set = kuhn_cube(2, 3e-3, true).element_set();
    assert!(((set.total_volume() - 216e-9) / 216e-9).abs() < 1e-12);
}

#[test]
fn single_element_fractions() {
    let set = single_tet(false).element_set();
    let me = set.total_mass();
    for mi in set.lumped_masses(4) {
        assert!((mi - me / 4.0).abs() < 1e-15 * me);
    }
    let set = single_tet(true).element_set();
    let me = set.total_mass();
    let m = set.lumped_masses(12); // two extra unused nodes get zero
    assert_eq!(m.len(), 12);
    assert_eq!(&m[10..], &[0.0, 0.0]);
    for (i, mi) in m[..10].iter().enumerate() {
        let expect = if i < 4 { me / 36.0 } else { 4.0 * me / 27.0 };
        assert!((mi - expect).abs() < 1e-15 * me);
    }
}

/// n! as f64.
fn fact(n: u32) -> f64 {
    (1..=n).map(f64::from).product()
}

/// HRZ from first principles: diagonal of the consistent mass matrix, integral of N_i^2,
/// with the exact rule  integral L1^a L2^b L3^c L4^d dV = 6 V a! b! c! d! / (a+b+c+d+3)!,
/// scaled so that the diagonal sums to the element mass.
#[test]
fn hrz_fractions_follow_from_the_consistent_mass_diagonal() {
    // Corner: N = L (2L - 1), N^2 = 4 L^4 - 4 L^3 + L^2.
    let corner = 6.0 * (4.0 * fact(4) / fact(7) - 4.0 * fact(3) / fact(6) + fact(2) / fact(5));
    // Mid-edge: N = 4 L1 L2, N^2 = 16 L1^2 L2^2.
    let mid = 6.0 * 16.0 * fact(2) * fact(2) / fact(7);
    // Known values rho V/70 and 8 rho V/105 (e.g. Zienkiewicz & Taylor, vol. 1).
    assert!((corner - 1.0 / 70.0).abs() < 1e-15);
    assert!((mid - 8.0 / 105.0).abs() < 1e-15);
    let total = 4.0 * corner + 6.0 * mid;
    assert!((HRZ_CORNER_FRACTION - corner / total).abs() < 1e-15);
    assert!((HRZ_MID_EDGE_FRACTION - mid / total).abs() < 1e-15);
    assert!((4.0 * HRZ_CORNER_FRACTION + 6.0 * HRZ_MID_EDGE_FRACTION - 1.0).abs() < 1e-15);
}

/// The masses without a set are the set's, bit for bit, and a mesh the set refuses is
/// refused with the same error.
#[test]
fn lumped_masses_without_a_set_are_the_sets() {
    for quadratic in [false, true] {
        for mesh in [kuhn_cube(2, 3e-3, quadratic), single_tet(quadratic)] {
            let set = mesh.element_set();
            let npe = set.nodes_per_element();
            let alone = fdem_elastic::lumped_masses(&rock(), npe, &mesh.nodes, &mesh.conn)
                .expect("a valid mesh");
            let from_set = set.lumped_masses(mesh.nodes.len());
            let bits = |m: &[f64]| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&alone), bits(&from_set));
        }
    }
    let mut flipped = single_tet(false);
    flipped.conn.swap(0, 1);
    let npe = 4;
    let set = fdem_elastic::ElementSet::new(&rock(), npe, &flipped.nodes, &flipped.conn);
    let alone = fdem_elastic::lumped_masses(&rock(), npe, &flipped.nodes, &flipped.conn);
    assert_eq!(
        alone.expect_err("an inverted element").to_string(),
        set.expect_err("an inverted element").to_string()
    );
}
