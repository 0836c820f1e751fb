//! Exact scaling (docs/MODEL.md section 4): a snapshot with positions x h and forces x h^2 is
//! the same state at another size. The micro-analysis must see the same contacts, a mean
//! normal force x h^2 and the same normalised distribution (Table 5's "mean contact force
//! grows as h^2"). Tolerance: 1e-12 relative, round-off of a few hundred additions; the
//! contact structure and the histogram counts must be identical.

use fdem_micro::synthetic::{SyntheticSpec, generate};
use fdem_micro::{ClusterParams, Snapshot, cluster, statistics, validate};
use proptest::prelude::*;

fn scaled(s: &Snapshot, h: f64) -> Snapshot {
    let mut out = s.clone();
    for r in &mut out.rows {
        r.position = r.position.map(|x| x * h);
        r.depth *= h;
        r.normal_force = r.normal_force.map(|f| f * h * h);
        r.tangential_force = r.tangential_force.map(|f| f * h * h);
    }
    out
}

fn check(seed: u64, h: f64, labelled: bool) -> Result<(), TestCaseError> {
    let mut spec = SyntheticSpec::e2(seed);
    spec.grid = [4, 4, 5];
    spec.labelled = labelled;
    let data = generate(&spec);
    let params = ClusterParams::default();
    let a = cluster(&data.snapshot, &params).unwrap();
    let b = cluster(&scaled(&data.snapshot, h), &params).unwrap();
    let rel = |x: f64, y: f64| (x - y).abs() <= 1e-12 * x.abs().max(y.abs());
    prop_assert_eq!(a.contacts.len(), b.contacts.len());
    prop_assert_eq!(a.clusters, b.clusters);
    prop_assert!(rel(a.spacing.unwrap() * h, b.spacing.unwrap()));
    for (ca, cb) in a.contacts.iter().zip(&b.contacts) {
        prop_assert_eq!(
            (ca.kind, ca.body, ca.other, ca.nodes),
            (cb.kind, cb.body, cb.other, cb.nodes)
        );
    }
    let (sa, sb) = (statistics(&a, None), statistics(&b, None));
    prop_assert!(sa.contacts > 50);
    prop_assert_eq!(sa.contacts, sb.contacts);
    prop_assert!(rel(sa.mean_normal_force * h * h, sb.mean_normal_force));
    prop_assert!(rel(
        sa.mean_tangential_force * h * h,
        sb.mean_tangential_force
    ));
    prop_assert_eq!(&sa.histogram.counts, &sb.histogram.counts);
    prop_assert_eq!(sa.histogram.overflow, sb.histogram.overflow);
    prop_assert_eq!(sa.strong_share, sb.strong_share);
    prop_assert_eq!(sa.weak_share, sb.weak_share);
    prop_assert_eq!(sa.coordination_number, sb.coordination_number);
    // The validation against the scaled truth scores the same.
    let truth: Vec<_> = data
        .truth
        .iter()
        .map(|p| {
            let mut p = *p;
            p.normal_force = p.normal_force.map(|f| f * h * h);
            p.tangential_force = p.tangential_force.map(|f| f * h * h);
            p
        })
        .collect();
    let (va, vb) = (validate(&a, &data.truth, 0.01), validate(&b, &truth, 0.01));
    prop_assert_eq!(va.body_pairs.recall, vb.body_pairs.recall);
    prop_assert_eq!(va.body_pairs.precision, vb.body_pairs.precision);
    Ok(())
}

/// The paper's factors h = 2, 3, 4 (and a shrink), both snapshot flavours.
#[test]
fn paper_scale_factors() {
    for h in [2.0, 3.0, 4.0, 0.5] {
        for labelled in [true, false] {
            check(3, h, labelled).unwrap();
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Any factor and any specimen.
    #[test]
    fn any_scale_factor(seed in 0u64..1_000_000, h in 0.05f64..20.0, labelled in any::<bool>()) {
        check(seed, h, labelled)?;
    }
}
