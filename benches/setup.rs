//! Set-up costs that scale with the specimen: each particle's assembled stable step (power
//! iteration on its rest stiffness, `ElementSet::assembled_time_step`) and the relaxed
//! random placement of a specimen's spheres (`fdem_triaxial::place_spheres`).
//!
//! `cargo bench -p fdem-benches --bench setup` (one thread: both run once per body or per
//! specimen; the solver spreads the bodies over the threads).

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use fdem_elastic::{ElementSet, Material};
use fdem_mesh::{ElementOrder, SphereSpec, sphere_mesh};
use fdem_triaxial::{Column, Preset, place_spheres};
use std::hint::black_box;

fn assembled_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("assembled_step");
    group.sample_size(20);
    let material = Material::new(2650.0, 40.0e9, 0.2).expect("material");
    for (order, name) in [
        (ElementOrder::Linear, "level1_linear"),
        (ElementOrder::Quadratic, "level1_quadratic"),
    ] {
        let mesh = sphere_mesh(&SphereSpec {
            level: 1,
            order,
            diameter: 0.06,
            sizing: Default::default(),
        })
        .expect("mesh");
        let set = ElementSet::new(
            &material,
            order.nodes_per_element(),
            &mesh.nodes,
            &mesh.elements,
        )
        .expect("element set");
        let iterations = set.assembled_time_step().iterations;
        group.bench_function(BenchmarkId::new(name, iterations), |b| {
            b.iter(|| black_box(&set).assembled_time_step())
        });
    }
    group.finish();
}

fn placement(c: &mut Criterion) {
    let mut group = c.benchmark_group("placement");
    group.sample_size(10);
    for name in ["E4s", "E3", "B3s"] {
        let spec = Preset::find(name).expect("preset").spec();
        let counts = spec.counts().expect("counts");
        let diameters = counts.diameters();
        let d_min = counts
            .classes
            .iter()
            .map(|k| k.diameter)
            .fold(f64::INFINITY, f64::min);
        let loose = spec.preparation.loose_solid_fraction;
        let column = Column {
            radius: spec.inner_radius(),
            bottom: 0.0,
            top: counts.solid_volume / (loose * spec.inner_area()),
        };
        let clearance = spec.preparation.clearance * d_min;
        group.bench_function(BenchmarkId::new(name, diameters.len()), |b| {
            b.iter(|| place_spheres(black_box(&diameters), &column, clearance, spec.seed))
        });
    }
    group.finish();
}

criterion_group!(benches, assembled_step, placement);
criterion_main!(benches);
