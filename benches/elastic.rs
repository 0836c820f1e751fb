//! Co-rotational tet force + integration throughput (issue 3 targets: >= 1e7 linear and
//! >= 2e6 quadratic tet-steps per second per core).
//!
//! `cargo bench -p fdem-benches --bench elastic` times one full velocity-Verlet step
//! (`Simulation::advance`: kick, drift, element forces, kick, guard) of a cloud of free,
//! spinning and vibrating level-1 particles, with 1 and 2 rayon threads, and the element
//! forces alone (`ElementSet::add_forces` of one rotated, strained particle mesh, one
//! thread). Criterion's throughput is in elements (tet-steps) per second.

// Component loops over x, y, z read best with an index.
#![allow(clippy::needless_range_loop)]

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use fdem_elastic::{ElementSet, Material};
use fdem_mesh::{ElementOrder, Sizing, SphereSpec, sphere_mesh_in_shells};
use fdem_solver::{Scene, Simulation};
use std::hint::black_box;

/// A scene of `n` particles on a line, 5 mm apart, each spinning and breathing so that
/// rotations and strains are non-trivial. Contact is off: the particles never touch, and
/// this bench times the elastic step (the contact bench times contact; with contact on,
/// the broad-phase renewals of these spinning particles would be timed here too).
fn simulation(n: usize, order: &str) -> Simulation {
    let mut text = String::from(
        "[simulation]\nduration = 1.0\n[material]\ndensity = 2650.0\nyoungs_modulus = 40.0e9\npoisson_ratio = 0.2\n[contact]\nenabled = false\n",
    );
    for i in 0..n {
        text.push_str(&format!(
            "[[particle]]\ndiameter = 0.015\ncenter = [{}, 0.0, 0.0]\nangular_velocity = [{}, 200.0, 50.0]\norientation = [0.6, 0.8, 0.0, 0.0]\nmesh = {{ level = 1, order = \"{order}\" }}\n",
            0.02 * i as f64,
            100.0 + i as f64
        ));
    }
    let scene = Scene::from_toml_str(&text, "bench").expect("bench scene");
    let mut sim = scene.build().expect("bench scene builds");
    let nodes = sim.nodes_mut();
    for (v, x) in nodes.velocities.iter_mut().zip(nodes.positions.iter()) {
        for k in 0..3 {
            v[k] += 0.01 * (x[k] * 1e3).sin();
        }
    }
    // Guard checks at their default interval are part of the cost of a real step.
    sim
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("elastic_step");
    group.sample_size(20);
    group.measurement_time(std::time::Duration::from_secs(4));
    for order in ["linear", "quadratic"] {
        let particles = 250; // 20,000 tets
        for threads in [1usize, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("thread pool");
            let mut sim = pool.install(|| simulation(particles, order));
            let tets: usize = sim.bodies().iter().map(|b| b.elements.len()).sum();
            group.throughput(Throughput::Elements(tets as u64));
            group.bench_function(BenchmarkId::new(format!("{order}_{threads}t"), tets), |b| {
                // The steps run on a worker of the pool, as the command line runs them.
                pool.install(|| b.iter(|| black_box(&mut sim).advance().expect("stable")))
            });
        }
    }
    group.finish();
}

/// The element forces alone: one level-2 particle of 4 shells (3,200 elements), its nodes
/// rotated by about 53 degrees and strained by about 1e-4 (a particle in contact), so
/// that the polar decomposition takes its usual iterations.
fn bench_kernel(c: &mut Criterion) {
    let mut group = c.benchmark_group("elastic_kernel");
    group.sample_size(30);
    group.measurement_time(std::time::Duration::from_secs(3));
    let material = Material::new(2650.0, 40.0e9, 0.2).expect("material");
    for (name, order) in [
        ("linear", ElementOrder::Linear),
        ("quadratic", ElementOrder::Quadratic),
    ] {
        let spec = SphereSpec {
            level: 2,
            order,
            diameter: 0.015,
            sizing: Sizing::Inscribed,
        };
        let mesh = sphere_mesh_in_shells(&spec, 4).expect("mesh");
        let set = ElementSet::new(
            &material,
            order.nodes_per_element(),
            &mesh.nodes,
            &mesh.elements,
        )
        .expect("element set");
        // x = R (1 + e) X with R a rotation about z by asin(0.8) and a small varying strain.
        let x: Vec<[f64; 3]> = mesh
            .nodes
            .iter()
            .map(|p| {
                let s = 1.0 + 1e-4 * (p[0] * 700.0).sin();
                let q = [p[0] * s, p[1] * (2.0 - s), p[2]];
                [0.6 * q[0] - 0.8 * q[1], 0.8 * q[0] + 0.6 * q[1], q[2]]
            })
            .collect();
        let mut forces = vec![[0.0; 3]; x.len()];
        group.throughput(Throughput::Elements(set.n_elements() as u64));
        group.bench_function(BenchmarkId::new(name, set.n_elements()), |b| {
            b.iter(|| {
                set.add_forces(black_box(&x), &mut forces)
                    .expect("valid mesh");
                black_box(&mut forces);
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench, bench_kernel);
criterion_main!(benches);
