//! The rigid bodies' share of a step: a whole `Simulation::advance` of spinning rigid
//! spheres that never touch (no contact model, gravity on), so that the step is the
//! rigid bodies' passes alone: the half kick, the drift of the centre and the
//! orientation, the nodes placed from the new pose and their forces cleared, then the
//! force and torque gathered from the nodes, the second half kick and the node
//! velocities.
//!
//! `cargo bench -p fdem-benches --bench rigid` builds simple cubic lattices of level-1
//! linear spheres (d = 15 mm, 42 surface nodes each, as E1's rigid particles), each with
//! its own velocity and spin, and times one step with 1 and 2 rayon threads. Criterion's
//! throughput is in rigid-body nodes per second. The 16k lattice's node arrays (about
//! 16 MB each) leave the cache, as E1's do; the 1k lattice's stay in it.

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use fdem_elastic::Material;
use fdem_mesh::{ElementOrder, Placement, Sizing, SphereSpec, sphere_mesh};
use fdem_solver::{InitialMotion, ModelBuilder, Simulation, TimeStep};

/// Lattice spacing over the sphere diameter: the spheres never meet.
const SPACING: f64 = 2.0;

/// A lattice of `n^3` spinning rigid spheres, stepped with a fixed step.
fn lattice(n: usize) -> Simulation {
    let d = 0.015;
    let template = sphere_mesh(&SphereSpec {
        level: 1,
        order: ElementOrder::Linear,
        diameter: 1.0,
        sizing: Sizing::Inscribed,
    })
    .expect("sphere mesh");
    let material = Material::new(2650.0, 40.0e9, 0.2).expect("material");
    let mut model = ModelBuilder::new();
    for i in 0..n * n * n {
        let site = [i % n, (i / n) % n, i / (n * n)].map(|k| k as f64 * SPACING * d);
        // A velocity and a spin of their own, about every axis (a fixed pattern).
        let phase = i as f64;
        let motion = InitialMotion {
            velocity: [0.01 * phase.sin(), 0.01 * phase.cos(), -0.02],
            angular_velocity: [
                30.0 * (0.7 * phase).sin(),
                20.0 * (1.3 * phase).cos(),
                10.0 + phase % 7.0,
            ],
        };
        let placement = Placement {
            scale: d,
            ..Placement::at(site)
        };
        model
            .add_rigid(&template, &placement, &material, motion)
            .expect("rigid sphere");
    }
    model.set_gravity([0.0, 0.0, -9.81]);
    model.set_time_step(TimeStep::Fixed(2e-6));
    model.build().expect("simulation")
}

fn step(c: &mut Criterion) {
    let mut group = c.benchmark_group("rigid_step");
    group.sample_size(20);
    group.measurement_time(Duration::from_secs(3));
    group.warm_up_time(Duration::from_secs(1));
    for (n, label) in [(10, "1k"), (25, "16k")] {
        let mut sim = lattice(n);
        let nodes = sim.state().positions.len();
        eprintln!("{label}: {} rigid bodies, {nodes} nodes", n * n * n);
        group.throughput(Throughput::Elements(nodes as u64));
        for threads in [1usize, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("thread pool");
            let id = BenchmarkId::new(format!("{threads}t"), label);
            group.bench_function(id, |b| {
                // On a worker of the pool, as the command line runs its time loops.
                pool.install(|| b.iter(|| sim.advance().expect("step")));
            });
        }
        black_box(sim.state().positions[0]);
    }
    group.finish();
}

criterion_group!(benches, step);
criterion_main!(benches);
