//! Clustering and pairing on synthetic node clouds with a known answer: single-node
//! contacts, touching clusters, split patches, both sides of a contact, label-free
//! action/reaction pairing, thresholds, and an E2-size synthetic specimen.

use fdem_micro::synthetic::{SyntheticSpec, generate};
use fdem_micro::{
    ClusterParams, Contact, ContactKind, Counterpart, MicroError, NodeRow, Snapshot, cluster,
    statistics, validate,
};

/// Mesh spacing of the hand-made clouds (m).
const S: f64 = 1e-3;

fn row(node: u64, body: u32, other: Counterpart, p: [f64; 3], f: [f64; 3]) -> NodeRow {
    NodeRow {
        node,
        body,
        counterpart: other,
        position: p,
        depth: 0.0,
        normal_force: f,
        tangential_force: [0.0; 3],
        sliding: false,
    }
}

/// A square patch of `n x n` nodes at spacing S centred at `c` in the plane x = c[0],
/// each node carrying `f / n^2`; node ids from `first`.
fn patch(
    first: u64,
    body: u32,
    other: Counterpart,
    c: [f64; 3],
    n: usize,
    f: [f64; 3],
) -> Vec<NodeRow> {
    let k = (n * n) as f64;
    let half = (n as f64 - 1.0) / 2.0;
    (0..n * n)
        .map(|i| {
            let (a, b) = ((i / n) as f64 - half, (i % n) as f64 - half);
            row(
                first + i as u64,
                body,
                other,
                [c[0], c[1] + a * S, c[2] + b * S],
                f.map(|x| x / k),
            )
        })
        .collect()
}

fn snapshot(rows: Vec<NodeRow>) -> Snapshot {
    Snapshot { time: 1.0, rows }
}

fn particle_contacts(c: &[Contact]) -> Vec<&Contact> {
    c.iter()
        .filter(|c| c.kind == ContactKind::Particle)
        .collect()
}

fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() <= tol)
}

/// Isolated nodes are contacts of their own (min_points 1), and a patch is one contact
/// whatever its size; the spacing is measured from the patches.
#[test]
fn single_node_contacts_and_patches() {
    let mut rows = patch(0, 0, Counterpart::Body(1), [0.0; 3], 3, [-9.0, 0.0, 0.0]);
    rows.push(row(
        100,
        0,
        Counterpart::Body(2),
        [0.0, 0.02, 0.0],
        [0.0, -4.0, 0.0],
    ));
    rows.push(row(
        101,
        0,
        Counterpart::Body(3),
        [0.0, -0.02, 0.0],
        [0.0, 5.0, 0.0],
    ));
    rows.push(row(
        102,
        0,
        Counterpart::Wall(0),
        [0.0, 0.0, 0.02],
        [0.0, 0.0, -1.0],
    ));
    let c = cluster(&snapshot(rows), &ClusterParams::default()).unwrap();
    assert_eq!(c.spacing, Some(S));
    let p = particle_contacts(&c.contacts);
    assert_eq!(p.len(), 3);
    assert_eq!((p[0].other, p[0].nodes), (Counterpart::Body(1), 9));
    assert!(close(p[0].normal_force, [-9.0, 0.0, 0.0], 1e-12));
    assert!(close(p[0].position, [0.0; 3], 1e-15));
    assert_eq!((p[1].other, p[1].nodes), (Counterpart::Body(2), 1));
    assert_eq!((p[2].other, p[2].nodes), (Counterpart::Body(3), 1));
    let walls: Vec<_> = c
        .contacts
        .iter()
        .filter(|c| c.kind == ContactKind::Boundary)
        .collect();
    assert_eq!(walls.len(), 1);
    assert_eq!(walls[0].other, Counterpart::Wall(0));
    let s = statistics(&c, None);
    assert_eq!(s.contacts, 3);
    assert_eq!(s.particles, 4); // bodies 0..3 seen
    assert!((s.coordination_number - 1.5).abs() < 1e-15);
    assert!((s.mean_normal_force - 6.0).abs() < 1e-12);
}

/// Node-to-face contact is symmetric: a contact may show nodes of both bodies. The two
/// sides merge into one contact whose force is the one on the lower body: its side minus
/// the other side. A contact seen from the higher body's nodes alone is reported on the
/// lower body with the opposite sign.
#[test]
fn both_sides_of_a_contact_merge_with_fdem_sign_convention() {
    let mut rows = patch(0, 0, Counterpart::Body(1), [0.0; 3], 2, [-3.0, 0.0, 0.0]);
    rows.extend(patch(
        10,
        1,
        Counterpart::Body(0),
        [1e-5, 0.3 * S, 0.0],
        2,
        [5.0, 0.0, 0.0],
    ));
    // Body 4's nodes pressed into body 2: reported on body 2.
    rows.push(row(
        20,
        4,
        Counterpart::Body(2),
        [0.0, 0.05, 0.0],
        [0.0, 2.0, 1.0],
    ));
    let c = cluster(&snapshot(rows), &ClusterParams::default()).unwrap();
    let p = particle_contacts(&c.contacts);
    assert_eq!(p.len(), 2);
    assert_eq!((p[0].body, p[0].other), (0, Counterpart::Body(1)));
    assert_eq!((p[0].nodes, p[0].clusters), (8, 2));
    assert!(close(p[0].normal_force, [-8.0, 0.0, 0.0], 1e-12));
    assert_eq!((p[1].body, p[1].other), (2, Counterpart::Body(4)));
    assert!(close(p[1].normal_force, [0.0, -2.0, -1.0], 1e-15));
}

/// Two patches of the same body pair far apart are two contacts; within the pair
/// distance (2 eps) they are one.
#[test]
fn same_pair_patches_merge_only_when_close() {
    let far = |dy: f64| {
        let mut rows = patch(0, 0, Counterpart::Body(1), [0.0; 3], 2, [-1.0, 0.0, 0.0]);
        rows.extend(patch(
            10,
            1,
            Counterpart::Body(0),
            [0.0, dy, 0.0],
            2,
            [1.0, 0.0, 0.0],
        ));
        cluster(&snapshot(rows), &ClusterParams::default()).unwrap()
    };
    // eps = 1.5 S, pair distance 3 S.
    let c = far(2.9 * S);
    assert_eq!(particle_contacts(&c.contacts).len(), 1);
    let c = far(3.1 * S);
    assert_eq!(particle_contacts(&c.contacts).len(), 2);
    assert_eq!(statistics(&c, None).pairs_with_several_contacts, 1);
    // Two patches on the same side never merge through the pair distance.
    let mut rows = patch(0, 0, Counterpart::Body(1), [0.0; 3], 2, [-1.0, 0.0, 0.0]);
    rows.extend(patch(
        10,
        0,
        Counterpart::Body(1),
        [0.0, 2.6 * S, 0.0],
        2,
        [-1.0, 0.0, 0.0],
    ));
    let c = cluster(&snapshot(rows), &ClusterParams::default()).unwrap();
    assert_eq!(particle_contacts(&c.contacts).len(), 2);
}

/// Touching clusters: two patches of body 0 against bodies 1 and 2 whose nodes are
/// closer than eps. With recorded counterparts they stay two contacts; without them
/// (label-free) DBSCAN cannot separate them and, their force matching neither partner,
/// the merged cluster stays unpaired: the documented limit of the label-free method.
#[test]
fn touching_clusters_separate_by_counterpart() {
    let labelled = |a: Counterpart, b: Counterpart| {
        let mut rows = patch(0, 0, a, [0.0; 3], 2, [-2.0, 0.0, 0.0]);
        rows.extend(patch(10, 0, b, [0.0, 2.0 * S, 0.0], 2, [-1.0, -1.0, 0.0]));
        rows
    };
    let c = cluster(
        &snapshot(labelled(Counterpart::Body(1), Counterpart::Body(2))),
        &ClusterParams::default(),
    )
    .unwrap();
    let p = particle_contacts(&c.contacts);
    assert_eq!(p.len(), 2);
    assert!(close(p[0].normal_force, [-2.0, 0.0, 0.0], 1e-12));
    assert!(close(p[1].normal_force, [-1.0, -1.0, 0.0], 1e-12));

    // Label-free: the reactions sit on bodies 1 and 2.
    let mut rows = labelled(Counterpart::Unknown, Counterpart::Unknown);
    rows.extend(patch(
        20,
        1,
        Counterpart::Unknown,
        [S, 0.0, 0.0],
        2,
        [2.0, 0.0, 0.0],
    ));
    rows.extend(patch(
        30,
        2,
        Counterpart::Unknown,
        [S, 2.0 * S, 0.0],
        2,
        [1.0, 1.0, 0.0],
    ));
    let c = cluster(&snapshot(rows.clone()), &ClusterParams::default()).unwrap();
    assert_eq!(particle_contacts(&c.contacts).len(), 0);
    assert_eq!(c.unpaired_clusters, 3);
    // Moved apart beyond eps, the same clouds pair exactly.
    for r in rows.iter_mut() {
        if r.node >= 10 && r.node < 20 || r.node >= 30 {
            r.position[1] += 2.0 * S;
        }
    }
    let c = cluster(&snapshot(rows), &ClusterParams::default()).unwrap();
    let p = particle_contacts(&c.contacts);
    assert_eq!(p.len(), 2);
    assert_eq!((p[0].body, p[0].other), (0, Counterpart::Body(1)));
    assert!(close(p[0].normal_force, [-2.0, 0.0, 0.0], 1e-12));
    assert!(close(p[1].normal_force, [-1.0, -1.0, 0.0], 1e-12));
    assert_eq!(c.unpaired_clusters, 0);
}

/// Label-free pairing needs equal and opposite forces within the tolerance, and the
/// positions within the pair distance; otherwise the clusters are boundary contacts.
#[test]
fn label_free_pairing_tolerances() {
    let pair = |reaction: f64, offset: f64, tolerance: f64| {
        let mut rows = patch(0, 0, Counterpart::Unknown, [0.0; 3], 2, [-10.0, 0.0, 0.0]);
        rows.extend(patch(
            10,
            1,
            Counterpart::Unknown,
            [0.0, offset, 0.0],
            2,
            [reaction, 0.0, 0.0],
        ));
        let params = ClusterParams {
            force_tolerance: tolerance,
            ..ClusterParams::default()
        };
        let c = cluster(&snapshot(rows), &params).unwrap();
        particle_contacts(&c.contacts).len()
    };
    assert_eq!(pair(10.0, 0.0, 0.1), 1);
    assert_eq!(pair(9.2, 0.0, 0.1), 1); // |F_a + F_b| = 0.8 <= 0.1 x 10
    assert_eq!(pair(8.8, 0.0, 0.1), 0);
    assert_eq!(pair(8.8, 0.0, 0.2), 1);
    assert_eq!(pair(-10.0, 0.0, 0.1), 0); // same direction: not a reaction
    assert_eq!(pair(10.0, 2.9 * S, 0.1), 1);
    assert_eq!(pair(10.0, 3.1 * S, 0.1), 0);
    // The best candidate wins: a cluster between two candidates pairs with the better.
    let mut rows = patch(0, 0, Counterpart::Unknown, [0.0; 3], 1, [-10.0, 0.0, 0.0]);
    rows.extend(patch(
        10,
        1,
        Counterpart::Unknown,
        [0.0, 0.5 * S, 0.0],
        1,
        [9.5, 0.0, 0.0],
    ));
    rows.extend(patch(
        20,
        2,
        Counterpart::Unknown,
        [0.0, -0.5 * S, 0.0],
        1,
        [10.0, 0.0, 0.0],
    ));
    let params = ClusterParams {
        eps: Some(0.4 * S),
        ..ClusterParams::default()
    };
    let c = cluster(&snapshot(rows), &params).unwrap();
    let p = particle_contacts(&c.contacts);
    assert_eq!(p.len(), 1);
    assert_eq!(p[0].other, Counterpart::Body(2));
}

/// A chain of nodes splits where a gap exceeds eps; an explicit eps overrides the
/// automatic one; min_points > 1 leaves noise; zero-force rows are ignored; duplicated
/// rows of one node are summed.
#[test]
fn eps_min_points_thresholds_and_duplicates() {
    let chain = |gaps: &[f64]| {
        let mut y = 0.0;
        let mut rows = vec![row(0, 0, Counterpart::Body(1), [0.0; 3], [-1.0, 0.0, 0.0])];
        for (i, g) in gaps.iter().enumerate() {
            y += g;
            rows.push(row(
                i as u64 + 1,
                0,
                Counterpart::Body(1),
                [0.0, y, 0.0],
                [-1.0, 0.0, 0.0],
            ));
        }
        rows
    };
    let gaps = [S, S, S, 1.6 * S, S, S, 3.5 * S];
    let c = cluster(&snapshot(chain(&gaps)), &ClusterParams::default()).unwrap();
    assert!((c.spacing.unwrap() / S - 1.0).abs() < 1e-12);
    assert_eq!(c.clusters, 3);
    // Pair distance 2 eps = 3 S: the clusters are on the same side, so they stay apart.
    assert_eq!(particle_contacts(&c.contacts).len(), 3);
    let explicit = ClusterParams {
        eps: Some(1.7 * S),
        ..ClusterParams::default()
    };
    assert_eq!(
        cluster(&snapshot(chain(&gaps)), &explicit)
            .unwrap()
            .clusters,
        2
    );
    let dense = ClusterParams {
        min_points: 3,
        ..ClusterParams::default()
    };
    let c = cluster(&snapshot(chain(&gaps)), &dense).unwrap();
    assert_eq!((c.clusters, c.noise_nodes), (2, 1));

    let mut rows = chain(&[S]);
    rows.push(row(7, 0, Counterpart::Body(1), [0.0, 5.0, 0.0], [0.0; 3]));
    rows.push(row(
        1,
        0,
        Counterpart::Body(1),
        [0.0, S, 0.0],
        [-2.0, 0.0, 0.0],
    ));
    let c = cluster(&snapshot(rows.clone()), &ClusterParams::default()).unwrap();
    assert_eq!((c.rows, c.ignored_rows, c.nodes), (4, 1, 2));
    let p = particle_contacts(&c.contacts);
    assert_eq!(p.len(), 1);
    assert!(close(p[0].normal_force, [-4.0, 0.0, 0.0], 1e-15));
    // Force-weighted position: (1 x 0 + 3 x S) / 4.
    assert!(close(p[0].position, [0.0, 0.75 * S, 0.0], 1e-18));
    let strict = ClusterParams {
        min_normal_force: 1.5,
        ..ClusterParams::default()
    };
    let c = cluster(&snapshot(rows), &strict).unwrap();
    assert_eq!((c.ignored_rows, c.nodes), (2, 1));
}

/// Contacts with a boundary body (a meshed membrane or platen) are boundary contacts and
/// the boundary body is not a particle.
#[test]
fn boundary_bodies() {
    let mut rows = patch(0, 0, Counterpart::Body(1), [0.0; 3], 2, [-1.0, 0.0, 0.0]);
    rows.extend(patch(
        10,
        0,
        Counterpart::Body(9),
        [0.0, 0.05, 0.0],
        2,
        [0.0, -1.0, 0.0],
    ));
    let params = ClusterParams {
        boundary_bodies: vec![9],
        ..ClusterParams::default()
    };
    let c = cluster(&snapshot(rows), &params).unwrap();
    let s = statistics(&c, None);
    assert_eq!((s.contacts, s.boundary_contacts, s.particles), (1, 1, 2));
    let b = c
        .contacts
        .iter()
        .find(|c| c.kind == ContactKind::Boundary)
        .unwrap();
    assert_eq!(b.other, Counterpart::Body(9));
}

#[test]
fn parameters_out_of_range_are_refused() {
    let s = snapshot(Vec::new());
    for params in [
        ClusterParams {
            eps: Some(0.0),
            ..ClusterParams::default()
        },
        ClusterParams {
            eps_factor: f64::NAN,
            ..ClusterParams::default()
        },
        ClusterParams {
            min_points: 0,
            ..ClusterParams::default()
        },
        ClusterParams {
            pair_distance_factor: -1.0,
            ..ClusterParams::default()
        },
        ClusterParams {
            force_tolerance: f64::INFINITY,
            ..ClusterParams::default()
        },
        ClusterParams {
            min_normal_force: -1.0,
            ..ClusterParams::default()
        },
    ] {
        let e = cluster(&s, &params).unwrap_err();
        assert!(matches!(e, MicroError::InvalidParameter { .. }), "{e}");
    }
    let bad = snapshot(vec![row(
        5,
        2,
        Counterpart::Wall(0),
        [0.0, f64::NAN, 0.0],
        [1.0; 3],
    )]);
    let e = cluster(&bad, &ClusterParams::default())
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("snapshot row 0 (node 5, body 2): "), "{e}");
    // An empty snapshot is fine: no contacts, zero statistics.
    let c = cluster(&s, &ClusterParams::default()).unwrap();
    let st = statistics(&c, None);
    assert_eq!(
        (st.contacts, st.mean_normal_force, st.coordination_number),
        (0, 0.0, 0.0)
    );
    let v = validate(&c, &[], 0.01);
    assert_eq!(v.body_pairs.recall, None);
}

/// An E2-size synthetic specimen (1,872 particles), labelled as fdem writes it and
/// label-free: every generated contact is found, once, with its exact force.
#[test]
fn e2_size_synthetic_specimen_is_recovered() {
    for labelled in [true, false] {
        let mut spec = SyntheticSpec::e2(11);
        spec.labelled = labelled;
        let data = generate(&spec);
        assert!(
            data.snapshot.rows.len() > 30_000,
            "{}",
            data.snapshot.rows.len()
        );
        let c = cluster(&data.snapshot, &ClusterParams::default()).unwrap();
        assert!((c.spacing.unwrap() / data.spacing - 1.0).abs() < 1e-9);
        let s = statistics(&c, Some(data.particles));
        assert_eq!(s.contacts, data.particle_contacts, "labelled {labelled}");
        assert_eq!(s.pairs_with_several_contacts, 0);
        let v = validate(&c, &data.truth, 0.01);
        for (kind, pv) in [("body", &v.body_pairs), ("wall", &v.wall_pairs)] {
            assert_eq!(
                pv.recall_all,
                Some(1.0),
                "{kind} pairs, labelled {labelled}"
            );
            assert_eq!(
                pv.precision_all,
                Some(1.0),
                "{kind} pairs, labelled {labelled}"
            );
            // Sums of a few terms in another order: round-off only.
            assert!(pv.max_force_error.unwrap() < 1e-12, "{pv:?}");
            assert!(pv.max_tangential_error.unwrap() < 1e-12, "{pv:?}");
        }
        // Exponential force law: strong share e^-4 = 1.8 %, weak 1 - e^-0.2 = 18.1 %
        // (4,378 contacts: binomial standard deviations 0.2 % and 0.6 %).
        assert!(
            (s.strong_share - (-4f64).exp()).abs() < 0.008,
            "{}",
            s.strong_share
        );
        assert!(
            (s.weak_share - (1.0 - (-0.2f64).exp())).abs() < 0.025,
            "{}",
            s.weak_share
        );
    }
}
