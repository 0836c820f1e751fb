//! Contact throughput: `add_forces` per step on dense packings, broad-phase rebuilds, and
//! the two narrow-phase kernels (hand-written projection vs parry3d-f64).
//!
//! `cargo bench -p fdem-benches --bench contact` builds the lattices of
//! `fdem_benches::lattice` and times one evaluation with 1 and 2 rayon threads, whole
//! (`Hand`, `Parry`: the two narrow-phase kernels) and in its two halves (`evaluate`: the
//! parallel passes; `spread`: the serial addition of the forces), and one with a full
//! rebuild (`rebuild+step`). Criterion's throughput is in surface-node contact evaluations
//! per second. On the `-shuffled` lattices the faces and nodes a surface node meets lie
//! anywhere in the arrays. `FDEM_BENCH_64K=1` adds the 64k-particle lattices (2.7 M
//! surface nodes each). A build's cost in steps, measured build by build, is
//! the `build_cost` example's.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use fdem_benches::lattice::{packing, sizes};
use fdem_contact::ProjectionKernel;
use fdem_contact::narrow::{project_hand, project_parry};

fn pools() -> Vec<(usize, rayon::ThreadPool)> {
    [1usize, 2]
        .into_iter()
        .map(|t| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .expect("thread pool");
            (t, pool)
        })
        .collect()
}

fn add_forces(c: &mut Criterion) {
    let mut group = c.benchmark_group("contact_step");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(3));
    group.warm_up_time(Duration::from_secs(1));
    for (n, label, shuffled) in sizes() {
        let mut p = packing(n, shuffled);
        let mut forces = vec![[0.0; 3]; p.positions.len()];
        let first = p
            .model
            .add_forces(&p.positions, &p.velocities, 0.0, 1e-7, &mut forces)
            .expect("first evaluation");
        eprintln!(
            "{label}: {} surface nodes, {} candidate pairs, {} contacts, margin {:.3e} m, cell {:.3e} m",
            p.surface_nodes,
            first.candidate_pairs,
            first.contacts,
            p.model.margin(),
            p.model.cell_size()
        );
        group.throughput(Throughput::Elements(p.surface_nodes as u64));
        for (threads, pool) in pools() {
            for kernel in [ProjectionKernel::Hand, ProjectionKernel::Parry] {
                p.model.set_projection_kernel(kernel);
                let id = BenchmarkId::new(format!("{kernel:?}/{threads}t"), label);
                group.bench_function(id, |b| {
                    pool.install(|| {
                        b.iter(|| {
                            let r = p
                                .model
                                .add_forces(&p.positions, &p.velocities, 0.0, 1e-7, &mut forces)
                                .expect("evaluation");
                            black_box(r.contacts)
                        })
                    })
                });
            }
            p.model.set_projection_kernel(ProjectionKernel::Hand);
            // The two halves of a step, each timed alone: the parallel passes (scan,
            // planes, narrow phase and law) and the serial spread of the forces.
            for (half, evaluate) in [("evaluate", true), ("spread", false)] {
                let id = BenchmarkId::new(format!("{half}/{threads}t"), label);
                group.bench_function(id, |b| {
                    pool.install(|| {
                        b.iter_custom(|iters| {
                            let mut timed = Duration::ZERO;
                            for _ in 0..iters {
                                let start = Instant::now();
                                p.model
                                    .evaluate(&p.positions, &p.velocities, 0.0, 1e-7)
                                    .expect("evaluation");
                                let between = Instant::now();
                                let r = p.model.add_evaluated_forces(&mut forces).expect("spread");
                                black_box(r.contacts);
                                timed += if evaluate {
                                    between - start
                                } else {
                                    between.elapsed()
                                };
                            }
                            timed
                        })
                    })
                });
            }
            let id = BenchmarkId::new(format!("rebuild+step/{threads}t"), label);
            group.bench_function(id, |b| {
                pool.install(|| {
                    b.iter(|| {
                        p.model.request_rebuild();
                        let r = p
                            .model
                            .add_forces(&p.positions, &p.velocities, 0.0, 1e-7, &mut forces)
                            .expect("evaluation");
                        black_box(r.rebuilt)
                    })
                })
            });
        }
    }
    group.finish();
}

/// The kernels alone on the candidate pairs of the 1k packing (node, face) in visiting
/// order, single-threaded.
fn kernels(c: &mut Criterion) {
    let mut p = packing(10, false);
    let mut forces = vec![[0.0; 3]; p.positions.len()];
    p.model
        .add_forces(&p.positions, &p.velocities, 0.0, 1e-7, &mut forces)
        .expect("evaluation");
    let surface = p.model.surface().clone();
    let pairs: Vec<([f64; 3], [[f64; 3]; 3])> = p
        .model
        .candidate_pairs()
        .into_iter()
        .map(|(node, t)| {
            (
                p.positions[node],
                surface.triangles[t].map(|i| p.positions[i]),
            )
        })
        .collect();
    let limit = p.model.depth_limit();
    let hits = pairs
        .iter()
        .filter(|(x, f)| project_hand(*x, *f, limit).is_some())
        .count();
    eprintln!("kernels: {} candidate pairs, {hits} hits", pairs.len());
    let mut group = c.benchmark_group("narrow_kernel");
    group.sample_size(20);
    group.measurement_time(Duration::from_secs(3));
    group.throughput(Throughput::Elements(pairs.len() as u64));
    group.bench_function("hand", |b| {
        b.iter(|| {
            pairs
                .iter()
                .filter(|(x, f)| project_hand(*x, *f, limit).is_some())
                .count()
        })
    });
    group.bench_function("parry", |b| {
        b.iter(|| {
            pairs
                .iter()
                .filter(|(x, f)| project_parry(*x, *f, limit).is_some())
                .count()
        })
    });
    // Worst case for the early exit: every node behind the face plane (mirror the nodes
    // in front through the plane), so both kernels compute the full location.
    let behind: Vec<([f64; 3], [[f64; 3]; 3])> = pairs
        .iter()
        .map(|&(x, [a, b, c])| {
            let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let n = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            let nn = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let u = n.map(|c| c / nn);
            let s = (x[0] - a[0]) * u[0] + (x[1] - a[1]) * u[1] + (x[2] - a[2]) * u[2];
            // Put the node 0.1 limit behind the plane, keeping its foot.
            let y = [0, 1, 2].map(|k| x[k] - (s + 0.1 * limit) * u[k]);
            (y, [a, b, c])
        })
        .collect();
    group.bench_function("hand_all_behind", |b| {
        b.iter(|| {
            behind
                .iter()
                .filter(|(x, f)| project_hand(*x, *f, limit).is_some())
                .count()
        })
    });
    group.bench_function("parry_all_behind", |b| {
        b.iter(|| {
            behind
                .iter()
                .filter(|(x, f)| project_parry(*x, *f, limit).is_some())
                .count()
        })
    });
    group.finish();
}

criterion_group!(benches, kernels, add_forces);
criterion_main!(benches);
