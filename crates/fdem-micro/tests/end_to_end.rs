//! End to end on a real run: a small packing squeezed between six walls is run by
//! fdem-solver with contact snapshots on; every snapshot is clustered and validated
//! against the per-pair sums that contact detection wrote (pairs_NNNNNN.csv).
//!
//! Expected: fdem's snapshots record each node's counterpart, so every pair is found and
//! its force is the same sum of the same node forces in another order: recall and
//! precision 1 and force error at round-off (asserted < 1e-9; the bar is a
//! recall of at least 95 % and an error below 5 % for pairs above 1 % of the mean force). The same snapshots
//! turned label-free (each body-contact row mirrored onto the other body as its
//! reaction, counterparts erased) test the geometric action/reaction pairing on real
//! contact geometry, to the same bar.

mod common;

use fdem_micro::{
    AnalysisOptions, ClusterParams, ContactKind, Counterpart, NodeRow, SnapshotChoice, analyse,
    cluster, locate_snapshot, read_nodes, read_pairs, statistics, summary_bodies, validate,
};
use fdem_solver::{RunOptions, Scene, Silent, run};
use std::sync::atomic::AtomicBool;

fn mirrored(rows: &[NodeRow]) -> Vec<NodeRow> {
    let mut out = Vec::with_capacity(2 * rows.len());
    for r in rows {
        match r.counterpart {
            Counterpart::Body(b) => {
                out.push(NodeRow {
                    counterpart: Counterpart::Unknown,
                    ..*r
                });
                out.push(NodeRow {
                    body: b,
                    counterpart: Counterpart::Unknown,
                    normal_force: r.normal_force.map(|f| -f),
                    tangential_force: r.tangential_force.map(|f| -f),
                    ..*r
                });
            }
            _ => out.push(*r),
        }
    }
    out
}

#[test]
fn real_snapshots_validate_against_pair_sums() {
    let dir = tempfile::tempdir().unwrap();
    let text = common::pressed_packing([3, 2, 2], 1.0, 1.0, 1.8e11, 3.0e-4, 4);
    let scene = Scene::from_toml_str(&text, "pressed_packing").unwrap();
    let options = RunOptions {
        out_dir: dir.path().to_path_buf(),
        vtk: false,
        contacts: true,
    };
    let summary = run(&scene, &options, &mut Silent, &AtomicBool::new(false)).unwrap();
    assert_eq!(summary.status, "completed");
    assert!(summary.outputs >= 5);

    let mut particle_contacts = 0;
    let mut two_sided = 0;
    for index in 0..summary.outputs {
        let files = locate_snapshot(dir.path(), SnapshotChoice::Index(index)).unwrap();
        assert!(files.pairs.is_some());
        let options = AnalysisOptions {
            particles: summary_bodies(dir.path()),
            ..AnalysisOptions::default()
        };
        let a = analyse(&files, &options).unwrap();
        let v = a.validation.as_ref().unwrap();
        for (kind, pv) in [("body", &v.body_pairs), ("wall", &v.wall_pairs)] {
            if pv.significant_truth_pairs == 0 {
                continue;
            }
            let at = format!("snapshot {index}, {kind} pairs: {pv:?}");
            assert_eq!(pv.recall, Some(1.0), "{at}");
            assert_eq!(pv.precision, Some(1.0), "{at}");
            assert!(pv.max_force_error.unwrap() < 1e-9, "{at}");
            assert!(pv.max_tangential_error.unwrap() < 1e-9, "{at}");
        }
        // Convex particles: one contact per touching pair.
        assert_eq!(
            a.statistics.pairs_with_several_contacts, 0,
            "snapshot {index}"
        );
        assert_eq!(a.statistics.particles, 12);
        particle_contacts = particle_contacts.max(a.statistics.contacts);
        two_sided += a
            .clustering
            .contacts
            .iter()
            .filter(|c| c.kind == ContactKind::Particle && c.clusters == 2)
            .count();

        // Label-free: mirror the reactions and pair them back geometrically.
        let snapshot = read_nodes(&files.nodes).unwrap();
        let truth = read_pairs(files.pairs.as_ref().unwrap()).unwrap();
        let mut label_free = snapshot.clone();
        label_free.rows = mirrored(&snapshot.rows);
        let params = ClusterParams {
            eps: a
                .clustering
                .eps_range
                .map(|r| r[1])
                .filter(|e| e.is_finite()),
            ..ClusterParams::default()
        };
        let c = cluster(&label_free, &params).unwrap();
        let pv = validate(&c, &truth, 0.01).body_pairs;
        if pv.significant_truth_pairs > 0 {
            let at = format!("snapshot {index}, label-free: {pv:?}");
            assert_eq!(pv.recall, Some(1.0), "{at}");
            assert_eq!(pv.precision, Some(1.0), "{at}");
            assert!(pv.max_force_error.unwrap() < 1e-9, "{at}");
        }
        assert_eq!(
            statistics(&c, None).contacts,
            a.statistics.contacts,
            "snapshot {index}"
        );
    }
    eprintln!(
        "{} snapshots; at most {particle_contacts} particle contacts; {two_sided} contacts seen \
         from both sides",
        summary.outputs
    );
    // The run must have produced something to validate, including contacts seen from
    // both sides (the merge), or this test proves nothing.
    assert!(
        particle_contacts >= 8,
        "{particle_contacts} particle contacts"
    );
    assert!(two_sided >= 3, "{two_sided} two-sided contacts");
}
