//! Contact throughput: `add_forces` per step on dense packings, broad-phase rebuilds, and
//! the two narrow-phase kernels (hand-written projection vs parry3d-f64).
//!
//! `cargo bench -p fdem-benches --bench contact` builds simple cubic lattices of level-1
//! linear spheres (d = 15 mm, identity orientation) whose axis vertices overlap their
//! neighbours by 0.3 of the contact margin, with small random velocities, and times one
//! evaluation with 1 and 2 rayon threads, whole (`Hand`, `Parry`: the two narrow-phase
//! kernels) and in its two halves (`evaluate`: the parallel passes; `spread`: the serial
//! addition of the forces). Criterion's throughput is in surface-node contact evaluations
//! per second. The `-shuffled` lattices number their bodies at random in space, as a
//! prepared specimen does (placement order), so that the faces and nodes a surface node
//! meets lie anywhere in the arrays. `FDEM_BENCH_64K=1` adds the
//! 64k-particle lattices (2.7 M surface nodes, about 3 GB each).

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use fdem_contact::narrow::{project_hand, project_parry};
use fdem_contact::{ContactModel, ContactParams, ContactSurface, ProjectionKernel};
use fdem_mesh::{ElementOrder, MeshAssembly, Placement, Sizing, SphereSpec, sphere_mesh};

struct Packing {
    positions: Vec<[f64; 3]>,
    velocities: Vec<[f64; 3]>,
    model: ContactModel,
    surface_nodes: usize,
}

/// The lattice sites `0..n^3` in the order the bodies are numbered: lattice order, or with
/// `shuffled` a fixed random permutation (xorshift Fisher-Yates), as in a prepared
/// specimen, whose particles are numbered in placement order, at random in space.
fn site_order(n: usize, shuffled: bool) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n * n * n).collect();
    if shuffled {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        for i in (1..order.len()).rev() {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            order.swap(i, (state % (i as u64 + 1)) as usize);
        }
    }
    order
}

/// `n^3` spheres on a simple cubic lattice, overlapping by 0.3 margin along the axes,
/// numbered in lattice order or, with `shuffled`, at random.
fn packing(n: usize, shuffled: bool) -> Packing {
    let d = 0.015;
    let mesh = sphere_mesh(&SphereSpec {
        level: 1,
        order: ElementOrder::Linear,
        diameter: d,
        sizing: Sizing::Inscribed,
    })
    .expect("sphere");
    let half_extent = mesh.nodes.iter().map(|x| x[0]).fold(f64::MIN, f64::max);
    let template = ContactSurface {
        triangles: mesh.surface.triangles.clone(),
        triangle_body: vec![0; mesh.surface.triangles.len()],
        surface_nodes: mesh.surface.nodes.clone(),
        node_body: vec![0; mesh.surface.nodes.len()],
        control_areas: mesh.surface.control_areas.clone(),
    };
    let margin = ContactModel::suggested_margin(&template, &mesh.nodes).expect("margin");
    let spacing = 2.0 * half_extent - 0.3 * margin;
    let mut assembly = MeshAssembly::new();
    for site in site_order(n, shuffled) {
        let t = [site / (n * n), (site / n) % n, site % n].map(|c| c as f64 * spacing);
        assembly
            .push_instance(&mesh, &Placement::at(t))
            .expect("placement");
    }
    let node_mass = 2650.0 * mesh.volume() / mesh.n_nodes() as f64;
    let masses = vec![node_mass; assembly.n_nodes()];
    // Small deterministic velocities (mm/s) so that damping and friction paths run.
    let velocities = assembly
        .nodes
        .iter()
        .map(|x| x.map(|c| 1e-3 * (c * 1e3).sin()))
        .collect();
    let surface = ContactSurface::from_assembly(&assembly).expect("surface");
    let surface_nodes = surface.n_surface_nodes();
    let model = ContactModel::new(ContactParams::default(), surface, vec![], &masses, margin)
        .expect("model");
    Packing {
        positions: assembly.nodes,
        velocities,
        model,
        surface_nodes,
    }
}

/// The lattices: side, label, bodies numbered at random.
fn sizes() -> Vec<(usize, &'static str, bool)> {
    let mut s = vec![
        (10, "1k", false),
        (20, "8k", false),
        (20, "8k-shuffled", true),
    ];
    if std::env::var_os("FDEM_BENCH_64K").is_some() {
        s.push((40, "64k", false));
        s.push((40, "64k-shuffled", true));
    }
    s
}

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
