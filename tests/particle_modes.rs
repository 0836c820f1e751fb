//! Particles that converge (fdem-mesh + fdem-elastic): Lamb's oblate (n = 2 spheroidal)
//! and breathing (n = 0) frequencies of a free sphere against the meshes' lumped-mass
//! vibration modes, for levels and radial shells, and the lumped-mass rotational inertia
//! against the solid shape's. docs/VERIFICATION.md ("Particle meshes that converge") has
//! the table, made by
//! `cargo test --release -p fdem-tests --test particle_modes -- --ignored --nocapture`.

use std::f64::consts::PI;

use fdem_elastic::{ElementSet, Material, VIBRATION_MODE_TOLERANCE, lamb_spheroidal_frequency};
use fdem_mesh::{ElementOrder, Sizing, SphereSpec, TetMesh, sphere_mesh_in_shells};

/// The paper's grain: d = 15 mm, rho = 2650 kg/m^3, E = 40 GPa, nu = 0.2.
const D: f64 = 0.015;

fn material() -> Material {
    Material::new(2650.0, 40.0e9, 0.2).unwrap()
}

/// Largest number of Lanczos steps per mode.
const MAX_STEPS: usize = 1500;

/// One meshed particle with its elements.
struct Particle {
    mesh: TetMesh,
    elements: ElementSet,
}

fn particle(level: u32, order: ElementOrder, shells: u32) -> Particle {
    let spec = SphereSpec {
        level,
        order,
        diameter: D,
        sizing: Sizing::Inscribed,
    };
    let mesh = sphere_mesh_in_shells(&spec, shells).unwrap();
    let elements = ElementSet::new(
        &material(),
        order.nodes_per_element(),
        &mesh.nodes,
        &mesh.elements,
    )
    .unwrap();
    Particle { mesh, elements }
}

/// The five degree-2 start shapes `u = grad p` for the harmonic quadratics
/// `p = xy, yz, zx, (x^2 - y^2) / 2, (2 z^2 - x^2 - y^2) / 2`: uniform pure shears, the
/// long-wave limit of the n = 2 spheroidal modes.
fn degree_two_shapes(nodes: &[[f64; 3]]) -> [Vec<[f64; 3]>; 5] {
    let map = |f: fn([f64; 3]) -> [f64; 3]| nodes.iter().map(|&x| f(x)).collect();
    [
        map(|[x, y, _]| [y, x, 0.0]),
        map(|[_, y, z]| [0.0, z, y]),
        map(|[x, _, z]| [z, 0.0, x]),
        map(|[x, y, _]| [x, -y, 0.0]),
        map(|[x, y, z]| [-x, -y, 2.0 * z]),
    ]
}

/// Frequencies (Hz) of the mesh's n = 2 spheroidal modes: the five modes that the start
/// block [`degree_two_shapes`] excites most (one five-fold mode, split by the mesh).
fn oblate_frequencies(p: &Particle) -> [f64; 5] {
    let starts = degree_two_shapes(&p.mesh.nodes);
    let f = frequencies(p, &starts);
    [f[0], f[1], f[2], f[3], f[4]]
}

/// Frequency (Hz) of the mesh's breathing mode: the mode that `u = x` excites most.
fn breathing_frequency(p: &Particle) -> f64 {
    frequencies(p, std::slice::from_ref(&p.mesh.nodes))[0]
}

/// Frequencies (Hz) of the modes the start shapes excite most. Panics unless every mode
/// converged and the modes carry most of the start block.
fn frequencies(p: &Particle, starts: &[Vec<[f64; 3]>]) -> Vec<f64> {
    let modes = p.elements.vibration_modes(&p.mesh.nodes, starts, MAX_STEPS);
    let weight: f64 = modes.iter().map(|m| m.weight).sum::<f64>() / starts.len() as f64;
    assert!(weight > 0.5, "the modes carry {weight} of the start block");
    modes
        .iter()
        .map(|m| {
            assert!(
                m.relative_residual <= VIBRATION_MODE_TOLERANCE,
                "not converged in {} steps: residual {}",
                m.steps,
                m.relative_residual
            );
            m.angular_frequency / (2.0 * PI)
        })
        .collect()
}

/// Lamb's frequency (Hz) of degree `n` for the grain.
fn lamb(n: u32) -> f64 {
    lamb_spheroidal_frequency(&material(), 0.5 * D, n) / (2.0 * PI)
}

/// Rotational inertia of the lumped masses and of the solid meshed shape about the centre,
/// each `tr(I) / 3` over `m R^2` (`m` the body mass, `R = d / 2`).
fn inertia(p: &Particle) -> (f64, f64) {
    let masses = p.elements.lumped_masses(p.mesh.n_nodes());
    let m: f64 = masses.iter().sum();
    let r2 = 0.25 * D * D;
    // tr(sum m (|x|^2 1 - x x^T)) / 3 = 2/3 sum m |x|^2.
    let lumped: f64 = masses
        .iter()
        .zip(&p.mesh.nodes)
        .map(|(mi, x)| mi * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]))
        .sum::<f64>()
        * 2.0
        / 3.0;
    let solid = p.mesh.volume_properties().inertia(material().density);
    let solid = (solid[0][0] + solid[1][1] + solid[2][2]) / 3.0;
    (lumped / (m * r2), solid / (m * r2))
}

fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len() as f64
}

#[test]
fn one_shell_linear_puts_a_quarter_of_the_mass_on_the_centre() {
    // Surface vertices at R carry 3/4 of the mass: lumped I = 3/4 m 2/3 R^2 = m R^2 / 2,
    // against the solid's 2/5 m R^2 (less for the inscribed polyhedron).
    for level in 1..=3 {
        let (lumped, solid) = inertia(&particle(level, ElementOrder::Linear, 1));
        assert!((lumped - 0.5).abs() < 1e-12, "level {level}: {lumped}");
        assert!(solid < 0.4 && solid > 0.36, "level {level}: {solid}");
    }
}

#[test]
fn lumped_inertia_converges_with_shells() {
    for order in [ElementOrder::Linear, ElementOrder::Quadratic] {
        let errors: Vec<f64> = (1..=4)
            .map(|k| {
                let (lumped, solid) = inertia(&particle(2, order, k));
                (lumped / solid - 1.0).abs()
            })
            .collect();
        assert!(
            errors.windows(2).all(|w| w[1] < w[0]),
            "{order:?}: {errors:?}"
        );
    }
}

/// Relative errors of the mean n = 2 and the breathing frequency against Lamb's.
fn errors(p: &Particle) -> (f64, f64) {
    (
        mean(&oblate_frequencies(p)) / lamb(2) - 1.0,
        breathing_frequency(p) / lamb(0) - 1.0,
    )
}

#[test]
fn linear_meshes_converge_from_above_with_shells_and_level() {
    // From two shells on (one shell is the uniform-strain limit of the mesh, below Lamb
    // for the breathing mode): both modes above Lamb's, falling with the shells at each
    // level and with the level.
    let table: Vec<Vec<(f64, f64)>> = (1..=2)
        .map(|level| {
            (2..=4)
                .map(|k| errors(&particle(level, ElementOrder::Linear, k)))
                .collect()
        })
        .collect();
    for row in &table {
        for w in row.windows(2) {
            assert!(w[1].0 < w[0].0 && w[1].1 < w[0].1, "{table:?}");
        }
        assert!(row.iter().all(|&(a, b)| a > 0.0 && b > 0.0), "{table:?}");
    }
    // Level: n = 2 falls at every shell count; breathing from three shells on (at two
    // shells level 2 is a few hundredths of a percent above level 1).
    for (k, (fine, coarse)) in table[1].iter().zip(&table[0]).enumerate() {
        assert!(fine.0 < coarse.0, "{table:?}");
        assert!(k == 0 || fine.1 < coarse.1, "{table:?}");
    }
}

#[test]
#[ignore = "the issue's tolerance on level 3, 4 shells linear (about 45 s in release)"]
fn level_three_four_shells_linear_within_ten_percent() {
    let (oblate, breathing) = errors(&particle(3, ElementOrder::Linear, 4));
    assert!(oblate.abs() < 0.10, "n = 2: {oblate:+.4}");
    assert!(breathing.abs() < 0.10, "n = 0: {breathing:+.4}");
}

#[test]
#[ignore = "the issue's tolerance on level 2, 3 shells quadratic (slow in the dev profile)"]
fn level_two_three_shells_quadratic_within_three_percent() {
    let (oblate, breathing) = errors(&particle(2, ElementOrder::Quadratic, 3));
    assert!(oblate.abs() < 0.03, "n = 2: {oblate:+.4}");
    assert!(breathing.abs() < 0.03, "n = 0: {breathing:+.4}");
}

/// The table of docs/VERIFICATION.md: every level 1-3, shells 1-4, both orders.
#[test]
#[ignore = "prints the convergence table (about seven minutes in release)"]
fn convergence_table() {
    let (f2, f0) = (lamb(2), lamb(0));
    println!("Lamb: n = 2 {:.1} Hz, n = 0 {:.1} Hz", f2, f0);
    println!(
        "| order | level | shells | nodes | tets | min dihedral (deg) | max aspect | \
         element dt (ns) | assembled dt (ns) | n = 2 / Lamb - 1 (spread) | n = 0 / Lamb - 1 | \
         I lumped / m R^2 | I solid / m R^2 | I lumped / I solid - 1 |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for order in [ElementOrder::Linear, ElementOrder::Quadratic] {
        for level in 1..=3 {
            for shells in 1..=4 {
                let start = std::time::Instant::now();
                let p = particle(level, order, shells);
                let q = p.mesh.quality();
                let step = p.elements.assembled_time_step();
                let n2 = oblate_frequencies(&p);
                let (lo, hi) = n2
                    .iter()
                    .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
                let n0 = breathing_frequency(&p);
                let (lumped, solid) = inertia(&p);
                println!(
                    "| {:?} | {level} | {shells} | {} | {} | {:.1} | {:.2} | {:.1} | {:.1} | \
                     {:+.2} % ({:.2} %) | {:+.2} % | {:.4} | {:.4} | {:+.2} % |",
                    order,
                    p.mesh.n_nodes(),
                    p.mesh.n_elements(),
                    q.min_dihedral_deg,
                    q.max_aspect_ratio,
                    step.element_time_step * 1e9,
                    step.time_step * 1e9,
                    100.0 * (mean(&n2) / f2 - 1.0),
                    100.0 * (hi - lo) / f2,
                    100.0 * (n0 / f0 - 1.0),
                    lumped,
                    solid,
                    100.0 * (lumped / solid - 1.0),
                );
                eprintln!("  ({:.1} s)", start.elapsed().as_secs_f64());
            }
        }
    }
}
