//! Exact-scaling invariance of whole simulations (docs/MODEL.md section 4, issue 5).
//!
//! Random small scenes (2 to 8 particles of mixed sizes, contacts, walls, friction,
//! damping, gravity, linear and quadratic meshes) are run as given and exactly scaled by
//! `Scene::scaled(&ScaleLaw::exact(h))`, h in [0.1, 10], for the same number of steps.
//! At corresponding times positions must scale by h, velocities by 1, wall forces by
//! h^2, energies by h^3 and stresses by 1.
//!
//! Tolerance: 1e-9 relative to each quantity's scale. The scaled run performs the same
//! floating-point operations on numbers multiplied by powers of h, so the two runs
//! differ only by round-off (about 1e-16 per operation, grown by the dynamics over a few
//! hundred steps to at most ~1e-12 here); a single wrong factor in Table 1 changes the
//! result at order 1 (see the tests at the end, which break one factor at a time and
//! measure the damage).

// Component loops over x, y, z read best with an index.
#![allow(clippy::needless_range_loop)]

use fdem_scaling::ScaleLaw;
use fdem_solver::{Scene, Simulation, step_count};
use proptest::prelude::*;

const TOLERANCE: f64 = 1e-9;

/// Stresses are compared relative to at least 1e-4 E = 4 MPa. Without contact a
/// particle's stress is at the noise level of the polar decomposition, which stops once
/// the rotation is orthogonal to about 1e-14 (a strain error of 1e-14, 4e-4 Pa here); a
/// relative comparison of noise with noise measures nothing. 1e-9 of the floor is
/// 4e-3 Pa: ten times that noise, and far below the stresses contacts make (MPa).
const STRESS_FLOOR: f64 = 1e-4 * 40.0e9;

/// Diameter, centre, velocity, spin, orientation, rigid.
type Particle = (f64, [f64; 3], [f64; 3], [f64; 3], [f64; 4], bool);

/// A random small scene: particles on a loose jittered lattice, each heading for the
/// centre at up to 1 m/s and spinning, each deformable or rigid, optionally a floor wall,
/// random contact law.
#[derive(Clone, Debug)]
struct Case {
    particles: Vec<Particle>,
    level: u32,
    quadratic: bool,
    floor: bool,
    friction: f64,
    damping: f64,
    gravity: f64,
}

fn case() -> impl Strategy<Value = Case> {
    (
        2usize..=8,
        prop::collection::vec(
            (
                0.018f64..0.02,
                [-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0],
                [-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0],
            ),
            8,
        ),
        0u32..=1,
        any::<bool>(),
        any::<bool>(),
        0.0f64..0.5,
        0.0f64..0.5,
        0.0f64..200.0,
        prop::collection::vec(any::<bool>(), 8),
    )
        .prop_map(
            |(n, raw, level, quadratic, floor, friction, damping, gravity, rigid)| {
                // Lattice 2 x 2 x 2 with spacing just under the largest diameter, so that
                // neighbours touch within a few hundred steps.
                let spacing = 0.99 * raw.iter().take(n).map(|p| p.0).fold(0.0, f64::max);
                let particles = raw
                    .iter()
                    .take(n)
                    .enumerate()
                    .map(|(i, &(d, spin, q))| {
                        let cell = [(i % 2) as f64, ((i / 2) % 2) as f64, (i / 4) as f64];
                        let centre = cell.map(|k| (k - 0.5) * spacing);
                        let norm = (centre.iter().map(|x| x * x).sum::<f64>()).sqrt();
                        let velocity = centre.map(|x| -3.0 * x / norm);
                        // Random orientation: identical, aligned meshes would meet vertex on
                        // vertex, an exact tie of the node-to-face test that round-off decides.
                        let qn = q.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-3);
                        let q = if qn > 1e-3 {
                            q.map(|x| x / qn)
                        } else {
                            [1.0, 0.0, 0.0, 0.0]
                        };
                        (d, centre, velocity, spin.map(|x| 100.0 * x), q, rigid[i])
                    })
                    .collect();
                Case {
                    particles,
                    level,
                    quadratic,
                    floor,
                    friction,
                    damping,
                    gravity,
                }
            },
        )
}

fn scene(c: &Case) -> Scene {
    let order = if c.quadratic { "quadratic" } else { "linear" };
    let mut text = format!(
        "[simulation]\nduration = 1.0\ngravity = [0.0, 0.0, {}]\n\
         [material]\ndensity = 2650.0\nyoungs_modulus = 40.0e9\npoisson_ratio = 0.2\n\
         [contact]\nfriction = {}\ndamping = {}\n",
        -c.gravity, c.friction, c.damping
    );
    if c.floor {
        // Touching the lowest particle and moving up faster than the particles move
        // inwards, so that it keeps pushing: a moving wall does work.
        let z = c
            .particles
            .iter()
            .map(|p| p.1[2] - 0.5 * p.0)
            .fold(f64::MAX, f64::min)
            + 1e-5;
        text.push_str(&format!(
            "[[wall]]\ntype = \"plane\"\npoint = [0.0, 0.0, {z}]\nnormal = [0.0, 0.0, 1.0]\nvelocity = [0.0, 0.0, 2.5]\n"
        ));
    }
    for (d, x, v, w, q, rigid) in &c.particles {
        let model = if *rigid { "rigid" } else { "deformable" };
        text.push_str(&format!(
            "[[particle]]\ndiameter = {d}\ncenter = {x:?}\nvelocity = {v:?}\nangular_velocity = {w:?}\n\
             orientation = {q:?}\nmesh = {{ level = {}, order = \"{order}\" }}\nmodel = \"{model}\"\n",
            c.level
        ));
    }
    Scene::from_toml_str(&text, "case").expect("generated scene is valid")
}

/// What is compared between the runs, in the original's units.
struct Observed {
    positions: Vec<[f64; 3]>,
    velocities: Vec<[f64; 3]>,
    wall_forces: Vec<[f64; 3]>,
    energies: [f64; 5],
    stresses: Vec<[f64; 6]>,
    contacts: usize,
    steps: u64,
}

/// Runs a scene for its own duration with its own time step (both given in the scene, so
/// that the `time` and `time_step` rows of Table 1 are exercised by the scaling).
fn run(scene: &Scene) -> Observed {
    let mut sim: Simulation = scene.build().expect("builds");
    let steps = step_count(scene.simulation.duration, sim.dt());
    let mut contacts = 0;
    for _ in 0..steps {
        sim.advance().expect("stable");
        contacts = contacts.max(sim.contact().map_or(0, |c| c.last_report().contacts));
    }
    let e = sim.energy();
    Observed {
        positions: sim.state().positions.clone(),
        velocities: sim.state().velocities.clone(),
        wall_forces: sim
            .contact()
            .map_or(vec![], |c| c.model().wall_forces().to_vec()),
        energies: [
            e.kinetic,
            e.strain,
            e.other_potential,
            e.external_work,
            e.dissipated,
        ],
        stresses: sim.elastic().stresses(&sim.state().positions).unwrap(),
        contacts,
        steps,
    }
}

/// Fixes the scene's step to its automatic value and its duration to `steps` steps, then
/// runs it and its exact scaling by h, after `tamper(original, scaled)` (the failure
/// tests undo one factor there).
fn run_pair_with(
    original: &Scene,
    h: f64,
    steps: usize,
    tamper: impl Fn(&Scene, &mut Scene),
) -> (Observed, Observed) {
    let dt = original.build().expect("builds").dt();
    let mut original = original.clone();
    original.simulation.dt = Some(dt);
    original.simulation.duration = steps as f64 * dt;
    let (mut scaled, _) = original.scaled(&ScaleLaw::exact(h).unwrap());
    tamper(&original, &mut scaled);
    (run(&original), run(&scaled))
}

fn run_pair(original: &Scene, h: f64, steps: usize) -> (Observed, Observed) {
    run_pair_with(original, h, steps, |_, _| {})
}

/// Largest deviation of `b` from `factor * a`, relative to the largest |a| (or to
/// `floor`, whichever is larger).
fn deviation<const N: usize>(a: &[[f64; N]], b: &[[f64; N]], factor: f64, floor: f64) -> f64 {
    let scale = a.iter().flatten().fold(floor, |m, x| m.max(x.abs())) * factor;
    if scale == 0.0 {
        return b.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
    }
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .fold(0.0f64, |m, (x, y)| m.max((y - factor * x).abs() / scale))
}

/// Deviations of the scaled run from the exact-scaling prediction:
/// [positions, velocities, wall forces, energies, stresses].
fn compare(a: &Observed, b: &Observed, h: f64) -> [f64; 5] {
    let e_scale = a.energies.iter().fold(0.0f64, |m, x| m.max(x.abs())) * h.powi(3);
    let energies = a
        .energies
        .iter()
        .zip(&b.energies)
        .fold(0.0f64, |m, (x, y)| {
            m.max((y - h.powi(3) * x).abs() / e_scale)
        });
    [
        deviation(&a.positions, &b.positions, h, 0.0),
        deviation(&a.velocities, &b.velocities, 1.0, 0.0),
        deviation(&a.wall_forces, &b.wall_forces, h * h, 0.0),
        energies,
        deviation(&a.stresses, &b.stresses, 1.0, STRESS_FLOOR),
    ]
}

const STEPS: usize = 1000;

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    #[test]
    fn exactly_scaled_scenes_reproduce_the_original(c in case(), h in 0.1f64..10.0) {
        let (a, b) = run_pair(&scene(&c), h, STEPS);
        prop_assert_eq!(a.steps, b.steps);
        prop_assert_eq!(a.contacts, b.contacts);
        let d = compare(&a, &b, h);
        for (name, dev) in ["positions", "velocities", "wall forces", "energies", "stresses"].iter().zip(d) {
            prop_assert!(dev < TOLERANCE, "{} deviate by {:e} (h = {}, {} node contacts)", name, dev, h, a.contacts);
        }
    }
}

/// A fixed collision scene for the failure tests: two particles meeting head-on with
/// gravity, on a floor.
fn collision_case() -> Case {
    Case {
        particles: vec![
            (
                0.015,
                [-0.00745, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 50.0, 0.0],
                [1.0, 0.0, 0.0, 0.0],
                false,
            ),
            (
                0.015,
                [0.00745, 0.001, 0.0],
                [-1.0, 0.0, 0.0],
                [0.0, 0.0, 0.0],
                [0.8, 0.0, 0.6, 0.0],
                false,
            ),
        ],
        level: 1,
        quadratic: false,
        floor: true,
        friction: 0.3,
        damping: 0.2,
        gravity: 1000.0,
    }
}

/// The collision scene itself obeys exact scaling to the tolerance (the control of the
/// failure tests below) and really collides.
#[test]
fn the_control_case_scales_exactly() {
    let h = 3.0;
    let (a, b) = run_pair(&scene(&collision_case()), h, 1500);
    assert!(a.contacts > 0);
    let d = compare(&a, &b, h);
    assert!(d.iter().all(|&x| x < TOLERANCE), "{d:?}");
}

/// Where exact scaling fails: leaving gravity unscaled (g instead of g / h) breaks the
/// invariance. On the collision scene with g = 1000 m/s^2 and h = 3 the test asserts that
/// positions deviate by more than 1e-6 of their scale, over a thousand times the tolerance
/// (docs/SCALING.md, "Where it fails", has the measured deviation).
#[test]
fn unscaled_gravity_breaks_invariance() {
    let h = 3.0;
    let (a, b) = run_pair_with(&scene(&collision_case()), h, 1500, |original, scaled| {
        scaled.simulation.gravity = original.simulation.gravity;
    });
    let d = compare(&a, &b, h);
    eprintln!("unscaled gravity: deviations {d:?}");
    assert!(d[0] > 1e-6, "positions deviate only by {:e}", d[0]);
}

/// Leaving the penalty unscaled (p_n instead of p_n / h): contacts are h times too stiff,
/// so the collision differs at order one. On the collision scene, h = 3, the test asserts
/// that velocities deviate by more than 1 % of their scale (docs/SCALING.md, "Where it
/// fails", has the measured deviation).
#[test]
fn unscaled_penalty_breaks_invariance() {
    let h = 3.0;
    let (a, b) = run_pair_with(&scene(&collision_case()), h, 1500, |original, scaled| {
        scaled.contact = original.contact.clone();
    });
    let d = compare(&a, &b, h);
    eprintln!("unscaled penalty: deviations {d:?}");
    assert!(d[1] > 1e-2, "velocities deviate only by {:e}", d[1]);
}

/// docs/SCALING.md embeds the table fdem-scaling derives; regenerate it with
/// `cargo xtask docs` when this fails.
#[test]
fn the_documented_scaling_table_is_the_derived_one() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/SCALING.md");
    let text = std::fs::read_to_string(path).expect("docs/SCALING.md exists");
    let begin = "<!-- BEGIN GENERATED: cargo xtask docs -->\n";
    let start = text.find(begin).expect("begin marker") + begin.len();
    let end = text.find("<!-- END GENERATED -->").expect("end marker");
    assert_eq!(
        &text[start..end],
        fdem_scaling::markdown_table().unwrap(),
        "docs/SCALING.md is stale: run `cargo xtask docs`"
    );
}
