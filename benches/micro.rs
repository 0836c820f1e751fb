//! Contact-force micro-analysis (fdem-micro): clustering a snapshot of the E2 specimen's
//! size, reading its CSV, and the two neighbourhood searches of DBSCAN.
//!
//! `cargo bench -p fdem-benches --bench micro`. The snapshots are synthetic
//! (`fdem_micro::synthetic::SyntheticSpec::e2`): 1,872 particles, about 4,400 particle
//! and 800 wall contacts, 3.7 x 10^4 node rows as fdem writes them (counterparts
//! recorded) and 4.8 x 10^4 label-free (action and reaction on both bodies). Criterion's
//! throughput is in node rows per second.

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use fdem_micro::dbscan::{Search, dbscan_with};
use fdem_micro::synthetic::{SyntheticSpec, generate};
use fdem_micro::{ClusterParams, cluster, parse_nodes, statistics, write_nodes};

fn snapshots(c: &mut Criterion) {
    let mut group = c.benchmark_group("micro_e2");
    group.measurement_time(Duration::from_secs(5));
    for labelled in [true, false] {
        let mut spec = SyntheticSpec::e2(1);
        spec.labelled = labelled;
        let data = generate(&spec);
        let name = if labelled { "labelled" } else { "label_free" };
        let rows = data.snapshot.rows.len() as u64;
        group.throughput(Throughput::Elements(rows));
        let params = ClusterParams::default();
        group.bench_function(BenchmarkId::new("cluster_and_statistics", name), |b| {
            b.iter(|| {
                let c = cluster(black_box(&data.snapshot), &params).expect("valid");
                black_box(statistics(&c, Some(data.particles)))
            })
        });
        // CSV parsing of the same snapshot, from memory.
        let dir = std::env::temp_dir().join(format!("fdem_micro_bench_{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join(format!("nodes_{name}.csv"));
        write_nodes(&path, &data.snapshot).expect("write");
        let text = std::fs::read(&path).expect("read");
        let _ = std::fs::remove_dir_all(&dir);
        group.bench_function(BenchmarkId::new("parse_csv", name), |b| {
            b.iter(|| black_box(parse_nodes(black_box(text.as_slice()), "bench").expect("valid")))
        });
    }
    group.finish();
}

/// One cloud of `n` nodes on a square grid of spacing 1 (eps 1.5): where the k-d tree
/// starts to beat brute force (fdem_micro::dbscan::BRUTE_FORCE_LIMIT).
fn dbscan_search(c: &mut Criterion) {
    let mut group = c.benchmark_group("dbscan_cloud");
    for n in [8usize, 16, 32, 48, 64, 128, 512] {
        let side = (n as f64).sqrt().ceil() as usize;
        let points: Vec<[f64; 3]> = (0..n)
            .map(|i| [(i % side) as f64, (i / side) as f64, 0.0])
            .collect();
        group.throughput(Throughput::Elements(n as u64));
        for (name, search) in [
            ("brute_force", Search::BruteForce),
            ("kd_tree", Search::KdTree),
        ] {
            group.bench_with_input(BenchmarkId::new(name, n), &points, |b, p| {
                b.iter(|| black_box(dbscan_with(black_box(p), 1.5, 1, search)))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, snapshots, dbscan_search);
criterion_main!(benches);
