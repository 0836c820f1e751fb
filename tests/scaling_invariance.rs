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
//! differ only by round-off (about 1e-16 per operation, grown by the dynamics over the
//! thousand steps; for h a power of two the runs are identical bit for bit). Some
//! trajectories amplify round-off past 1e-9 (rigid icosahedra colliding while spinning
//! fast); where the scaled run deviates by more, the case's own sensitivity sets the bar:
//! the scaled run must stay within ten times the deviation of a copy whose initial
//! positions, velocities and spins differ by 1e-12 relative, and a case whose copy
//! deviates by more than 1e-6 is drawn again. A single wrong factor in Table 1 changes the
//! result far beyond that (see the tests at the end, which break one factor at a time and
//! measure the damage; docs/SCALING.md has the numbers).

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
/// that the `time` and `time_step` rows of Table 1 are exercised by the scaling); `Err`
/// with the step at which the stability guard stopped it. The guard stops a run whose
/// energy balance error passes 5 % of its energy scale; rigid icosahedra meeting at a few
/// m/s get there without any instability, since each contact starts one step's approach
/// deep (a vertex carries the whole contact, docs/SCALING.md).
fn try_run(scene: &Scene) -> Result<Observed, u64> {
    let mut sim: Simulation = scene.build().expect("builds");
    let steps = step_count(scene.simulation.duration, sim.dt());
    let mut contacts = 0;
    for _ in 0..steps {
        match sim.advance() {
            Err(fdem_solver::SolverError::Unstable { step, .. }) => return Err(step),
            other => other.expect("no other error"),
        }
        contacts = contacts.max(sim.contact().map_or(0, |c| c.last_report().contacts));
    }
    let e = sim.energy();
    Ok(Observed {
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
    })
}

/// Fixes the scene's step to its automatic value and its duration to `steps` steps, then
/// runs it and its exact scaling by h, after `tamper(original, scaled)` (the failure
/// tests undo one factor there).
fn try_run_pair_with(
    original: &Scene,
    h: f64,
    steps: usize,
    tamper: impl Fn(&Scene, &mut Scene),
) -> (Result<Observed, u64>, Result<Observed, u64>) {
    let dt = original.build().expect("builds").dt();
    let mut original = original.clone();
    original.simulation.dt = Some(dt);
    original.simulation.duration = steps as f64 * dt;
    let (mut scaled, _) = original.scaled(&ScaleLaw::exact(h).unwrap());
    tamper(&original, &mut scaled);
    (try_run(&original), try_run(&scaled))
}

fn try_run_pair(
    original: &Scene,
    h: f64,
    steps: usize,
) -> (Result<Observed, u64>, Result<Observed, u64>) {
    try_run_pair_with(original, h, steps, |_, _| {})
}

/// [`try_run_pair_with`] for scenes that must run to the end.
fn run_pair_with(
    original: &Scene,
    h: f64,
    steps: usize,
    tamper: impl Fn(&Scene, &mut Scene),
) -> (Observed, Observed) {
    let (a, b) = try_run_pair_with(original, h, steps, tamper);
    (
        a.expect("the original is stable"),
        b.expect("the scaled run is stable"),
    )
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

/// Relative change of every initial centre, velocity and spin in the sensitivity probe:
/// thousands of units in the last place, far above one rounding and far below any
/// physical effect.
const PROBE: f64 = 1e-12;

/// The scaled run may deviate by up to this many times the probe's deviation: where the
/// original sits at a near-tie of a discrete event (a contact starting at one step or the
/// next), any perturbation flips it and the scaled run and the probe deviate by about the
/// same amount.
const PROBE_MARGIN: f64 = 10.0;

/// A case whose probe deviates by more than this is too ill-conditioned to test a
/// scaling law on (its own round-off would hide an error of this size); it is rejected
/// and another drawn. A wrong factor of Table 1 deviates by far more (the failure tests
/// below).
const PROBE_CAP: f64 = 1e-6;

/// The case's own sensitivity: deviations of the original from a copy whose initial
/// centres, velocities and spins differ by the relative [`PROBE`]; `None` when the guard
/// stops the copy.
fn sensitivity(c: &Case, original: &Observed) -> Option<[f64; 5]> {
    let mut probe = c.clone();
    for p in &mut probe.particles {
        p.1 = p.1.map(|x| x * (1.0 + PROBE));
        p.2 = p.2.map(|v| v * (1.0 + PROBE));
        p.3 = p.3.map(|w| w * (1.0 + PROBE));
    }
    let (perturbed, _) = try_run_pair(&scene(&probe), 1.0, STEPS);
    Some(compare(original, &perturbed.ok()?, 1.0))
}

const NAMES: [&str; 5] = [
    "positions",
    "velocities",
    "wall forces",
    "energies",
    "stresses",
];

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    /// The scaled run must match the original to [`TOLERANCE`], or, where the dynamics
    /// amplify round-off beyond it (rigid polyhedra colliding while spinning fast), to
    /// [`PROBE_MARGIN`] times the deviation of the sensitivity probe: the two runs round
    /// differently at every step, which acts like a perturbation of the initial state.
    #[test]
    fn exactly_scaled_scenes_reproduce_the_original(c in case(), h in 0.1f64..10.0) {
        let (a, b) = try_run_pair(&scene(&c), h, STEPS);
        // Where the guard stops the original it stops the scaled run at the same step
        // (the energy balance scales by h^3 like its scale).
        let (a, b) = match (a, b) {
            (Ok(a), Ok(b)) => (a, b),
            (a, b) => {
                prop_assert_eq!(a.err(), b.err(), "only one of the runs was stopped");
                return Ok(());
            }
        };
        prop_assert_eq!(a.steps, b.steps);
        prop_assert_eq!(a.contacts, b.contacts);
        let d = compare(&a, &b, h);
        if d.iter().any(|&dev| dev >= TOLERANCE) {
            let s = sensitivity(&c, &a);
            prop_assume!(
                s.is_some_and(|s| s.iter().all(|&x| x < PROBE_CAP)),
                "ill-conditioned case: probe deviates by {:?}", s
            );
            for ((name, dev), allowed) in NAMES.iter().zip(d).zip(s.unwrap_or_default()) {
                prop_assert!(
                    dev < TOLERANCE.max(PROBE_MARGIN * allowed),
                    "{} deviate by {:e}, more than the tolerance {:e} and {} times the case's sensitivity {:e} (h = {}, {} node contacts)",
                    name, dev, TOLERANCE, PROBE_MARGIN, allowed, h, a.contacts
                );
            }
        }
    }
}

/// The failing case the continuous integration drew (kept in
/// `proptest-regressions/scaling_invariance.txt`): three rigid icosahedra spinning at up
/// to 100 rad/s, one node contact. Its scaled run deviates by more than [`TOLERANCE`]
/// only because the trajectory amplifies round-off: h = 2 (exact in floating point)
/// reproduces it bit for bit, and the sensitivity probe deviates by more than the
/// scaled run does.
#[test]
fn an_ill_conditioned_case_is_judged_by_its_sensitivity() {
    let c = Case {
        particles: vec![
            (
                0.018378464053817118,
                [-0.009097339706639474; 3],
                [1.7320508075688774; 3],
                [42.57061949580941, 0.0, -65.94214294701301],
                [
                    -0.7463217070184653,
                    0.2949260714126866,
                    0.2096454759587194,
                    -0.5586334186603634,
                ],
                true,
            ),
            (
                0.018,
                [
                    0.009097339706639474,
                    -0.009097339706639474,
                    -0.009097339706639474,
                ],
                [-1.7320508075688774, 1.7320508075688774, 1.7320508075688774],
                [0.0, 87.80595890934697, -37.44177212841513],
                [-0.044044522205166955, 0.0, 0.0, -0.9990295691638553],
                true,
            ),
            (
                0.018,
                [
                    -0.009097339706639474,
                    0.009097339706639474,
                    -0.009097339706639474,
                ],
                [1.7320508075688774, -1.7320508075688774, 1.7320508075688774],
                [0.0, -98.30935499064935, 0.0],
                [0.0, -0.9580081946851982, -0.28674082185138433, 0.0],
                true,
            ),
        ],
        level: 0,
        quadratic: false,
        floor: false,
        friction: 0.13638757376452496,
        damping: 0.46855697788276485,
        gravity: 179.8201261975379,
    };
    let h = 2.158585932597263;
    let (a, b) = run_pair(&scene(&c), h, STEPS);
    assert!(a.contacts > 0);
    let d = compare(&a, &b, h);
    eprintln!("scaled by {h}: deviations {d:?}");
    assert!(
        d[1] > TOLERANCE,
        "the case no longer exceeds the plain tolerance: {d:?}"
    );
    let (exact_a, exact_b) = run_pair(&scene(&c), 2.0, STEPS);
    assert_eq!(compare(&exact_a, &exact_b, 2.0), [0.0; 5]);
    let s = sensitivity(&c, &a).expect("the probe runs to the end");
    eprintln!("sensitivity probe: deviations {s:?}");
    for k in 0..5 {
        assert!(
            d[k] <= s[k],
            "{}: {:e} against the probe's {:e}",
            NAMES[k],
            d[k],
            s[k]
        );
    }
    assert!(s.iter().all(|&x| x < PROBE_CAP));
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

/// The property test's criterion over many cases, for the record in docs/SCALING.md
/// (slow; run with `cargo test --release -p fdem-tests --test scaling_invariance --
/// --ignored --nocapture`). `FDEM_SWEEP_CASES` sets the number of cases (default 500),
/// `FDEM_SWEEP_ICOSAHEDRA=1` makes every particle a rigid icosahedron (level 0), the
/// cases that amplify round-off most. Deterministic: the same cases on every run.
#[test]
#[ignore]
fn sweep_of_random_cases() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let cases: usize = std::env::var("FDEM_SWEEP_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(500);
    let icosahedra = std::env::var("FDEM_SWEEP_ICOSAHEDRA").is_ok_and(|v| v == "1");
    let mut runner = TestRunner::deterministic();
    let (mut worst, mut worst_ratio) = ([0.0f64; 5], 0.0f64);
    let (mut stopped, mut flagged, mut rejected) = (0, 0, 0);
    for i in 0..cases {
        let mut c = case().new_tree(&mut runner).unwrap().current();
        let h = (0.1f64..10.0).new_tree(&mut runner).unwrap().current();
        if icosahedra {
            c.level = 0;
            for p in &mut c.particles {
                p.5 = true;
            }
        }
        let (a, b) = try_run_pair(&scene(&c), h, STEPS);
        let (a, b) = match (a, b) {
            (Ok(a), Ok(b)) => (a, b),
            (a, b) => {
                assert_eq!(
                    a.err(),
                    b.err(),
                    "case {i}: only one of the runs was stopped"
                );
                stopped += 1;
                continue;
            }
        };
        let d = compare(&a, &b, h);
        for k in 0..5 {
            worst[k] = worst[k].max(d[k]);
        }
        if d.iter().any(|&x| x >= TOLERANCE) {
            flagged += 1;
            match sensitivity(&c, &a) {
                Some(s) if s.iter().all(|&x| x < PROBE_CAP) => {
                    for k in 0..5 {
                        if d[k] >= TOLERANCE {
                            worst_ratio = worst_ratio.max(d[k] / s[k]);
                        }
                    }
                }
                _ => rejected += 1,
            }
        }
    }
    println!(
        "{cases} cases{}: {stopped} stopped by the guard in both runs at the same step; largest deviations {worst:?}; {flagged} above {TOLERANCE:e}, {rejected} of them \
         rejected (probe above {PROBE_CAP:e}); largest deviation over the probe's among the rest {worst_ratio:.3}",
        if icosahedra {
            " of rigid icosahedra"
        } else {
            ""
        }
    );
    assert!(worst_ratio < PROBE_MARGIN);
}
