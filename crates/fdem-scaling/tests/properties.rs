//! Property tests of the scale laws (issue: foundation). Tolerances: factors are products of
//! at most a few powers, so 1e-12 relative covers round-off for h in [0.01, 1000].

use fdem_scaling::{CATALOGUE, Dimension, ScaleLaw, dimension_of};
use proptest::prelude::*;

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs())
}

/// Table 1 of docs/MODEL.md: (quantity, exponent of h), typed in from the paper to check the
/// derivation, which never reads it.
const TABLE_1: &[(&str, i32)] = &[
    ("length", 1),
    ("time", 1),
    ("mass", 3),
    ("force", 2),
    ("stress", 0),
    ("strain", 0),
    ("youngs_modulus", 0),
    ("poisson_ratio", 0),
    ("penalty_stiffness", -1),
    ("friction", 0),
    ("damping", 0),
    // Follow-ons stated in docs/MODEL.md section 4.
    ("density", 0),
    ("velocity", 0),
    ("acceleration", -1),
    ("contact_stiffness", 1),
    ("energy", 3),
    ("time_step", 1),
];

fn dimension() -> impl Strategy<Value = Dimension> {
    (-4i32..=4, -4i32..=4, -4i32..=4).prop_map(|(l, t, m)| Dimension::new(l, t, m))
}

proptest! {
    #[test]
    fn exact_law_reproduces_table_1(h in 0.01f64..1000.0) {
        let law = ScaleLaw::exact(h).unwrap();
        for &(name, exponent) in TABLE_1 {
            let factor = law.factor_of(name).unwrap();
            prop_assert!(close(factor, h.powi(exponent)), "{name}: {factor} vs h^{exponent}");
        }
    }

    #[test]
    fn factor_is_multiplicative(h in 0.01f64..1000.0, d1 in dimension(), d2 in dimension()) {
        let law = ScaleLaw::exact(h).unwrap();
        prop_assert!(close(law.factor(d1 * d2), law.factor(d1) * law.factor(d2)));
        prop_assert!(close(law.factor(d1 / d2), law.factor(d1) / law.factor(d2)));
        prop_assert!(close(law.factor(d1.powi(3)), law.factor(d1).powi(3)));
    }

    #[test]
    fn exact_laws_compose(h1 in 0.1f64..31.0, h2 in 0.1f64..31.0) {
        let composed = ScaleLaw::exact(h1).unwrap().then(&ScaleLaw::exact(h2).unwrap());
        let direct = ScaleLaw::exact(h1 * h2).unwrap();
        for q in CATALOGUE {
            prop_assert!(close(composed.factor(q.dimension), direct.factor(q.dimension)), "{}", q.name);
        }
    }

    #[test]
    fn inverse_undoes_the_law(h in 0.01f64..1000.0, d in dimension()) {
        let law = ScaleLaw::exact(h).unwrap();
        let round_trip = law.then(&law.inverse());
        prop_assert!(close(round_trip.factor(d), 1.0));
        prop_assert!(close(law.inverse().factor(d) * law.factor(d), 1.0));
    }

    #[test]
    fn exact_law_keeps_density_and_modulus(h in 0.01f64..1000.0) {
        let law = ScaleLaw::exact(h).unwrap();
        prop_assert!(close(law.factor(dimension_of("density").unwrap()), 1.0));
        prop_assert!(close(law.factor(dimension_of("youngs_modulus").unwrap()), 1.0));
    }
}
