//! The rigid-body integrator against closed forms: exact motion under a constant force,
//! torque-free precession of a symmetric top, the intermediate-axis flips of a free
//! ellipsoid (Dzhanibekov) with energy and angular momentum conserved, and the principal
//! axes of a rotated inertia tensor.

use fdem_solver::{RigidInertia, RigidState};

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// One velocity-Verlet step of a free body (no force, no torque).
fn free_step(s: &mut RigidState, inertia: &RigidInertia, dt: f64) {
    s.kick(inertia, [0.0; 3], [0.0; 3], 0.5 * dt);
    s.drift(inertia, dt);
    s.kick(inertia, [0.0; 3], [0.0; 3], 0.5 * dt);
}

/// A solid ellipsoid of mass `m` and semi-axes `a, b, c` along x, y, z:
/// `I = m diag(b^2 + c^2, a^2 + c^2, a^2 + b^2) / 5`.
fn ellipsoid(m: f64, [a, b, c]: [f64; 3]) -> RigidInertia {
    RigidInertia {
        mass: m,
        principal: [b * b + c * c, a * a + c * c, a * a + b * b].map(|s| m * s / 5.0),
        principal_frame: [1.0, 0.0, 0.0, 0.0],
    }
}

/// Velocity Verlet integrates a constant force exactly: `x = x0 + v0 t + F t^2 / 2m`
/// (1e-12 relative for round-off).
#[test]
fn a_constant_force_moves_the_centre_exactly() {
    let inertia = ellipsoid(2.0, [1.0, 0.7, 0.5]);
    let mut s = RigidState::new(
        &inertia,
        [1.0, 2.0, 3.0],
        [0.5, 0.0, -1.0],
        [1.0, 0.0, 0.0, 0.0],
        [0.0; 3],
    );
    let (f, dt, n) = ([0.0, 0.0, -19.62], 1e-3, 1000);
    for _ in 0..n {
        s.kick(&inertia, f, [0.0; 3], 0.5 * dt);
        s.drift(&inertia, dt);
        s.kick(&inertia, f, [0.0; 3], 0.5 * dt);
    }
    let t = dt * n as f64;
    let z = 3.0 - t - 0.5 * 9.81 * t * t;
    assert!(
        (s.position[2] - z).abs() < 1e-12 * z.abs().max(1.0),
        "{} vs {z}",
        s.position[2]
    );
    assert!((s.position[0] - (1.0 + 0.5 * t)).abs() < 1e-12);
    assert_eq!(s.body_momentum, [0.0; 3]);
}

/// A free symmetric top (`I1 = I2 = I`, `I3`): by Euler's equations the body-frame
/// `omega` turns about the symmetry axis at `Omega = (I3 - I) / I omega_3`, so
/// `omega_1 + i omega_2` rotates by `+Omega t`. The splitting is second order: its phase
/// error is of order `(Omega dt)^2` times the phase, 5e-5 rad after two turns with
/// `Omega dt = 2e-3`; the test allows 2e-4 rad.
#[test]
fn a_symmetric_top_precesses_at_the_analytic_rate() {
    let inertia = RigidInertia {
        mass: 1.0,
        principal: [2.0, 2.0, 3.0],
        principal_frame: [1.0, 0.0, 0.0, 0.0],
    };
    let (w1, w3) = (0.3, 10.0);
    let mut s = RigidState::new(
        &inertia,
        [0.0; 3],
        [0.0; 3],
        [1.0, 0.0, 0.0, 0.0],
        [w1, 0.0, w3],
    );
    let omega = (3.0 - 2.0) / 2.0 * w3;
    let dt = 2e-3 / omega;
    let n = (2.0 * std::f64::consts::TAU / omega / dt).round() as usize;
    for _ in 0..n {
        free_step(&mut s, &inertia, dt);
    }
    let t = n as f64 * dt;
    let pi = s.body_momentum;
    let phase = (pi[1] / 2.0).atan2(pi[0] / 2.0);
    let expected = (omega * t).rem_euclid(std::f64::consts::TAU);
    let diff = (phase.rem_euclid(std::f64::consts::TAU) - expected + std::f64::consts::PI)
        .rem_euclid(std::f64::consts::TAU)
        - std::f64::consts::PI;
    assert!(diff.abs() < 2e-4, "phase {phase} vs {expected}: {diff}");
    assert!((pi[2] - 3.0 * w3).abs() < 1e-12 * 3.0 * w3);
}

/// A free ellipsoid (semi-axes 1, 0.7, 0.5) spun about its intermediate axis with a small
/// perturbation flips over and back (the Dzhanibekov effect): the intermediate component
/// of the body-frame momentum changes sign again and again. Over the flips the world
/// angular momentum is conserved to 1e-11 relative (each sub-rotation keeps it to
/// round-off) and the energy to 1e-6 (the scheme's bounded second-order error).
#[test]
fn a_free_ellipsoid_flips_about_its_intermediate_axis_and_conserves_its_invariants() {
    let inertia = ellipsoid(1.0, [1.0, 0.7, 0.5]);
    let q: [f64; 4] = [0.9, 0.1, -0.3, 0.2];
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let q = q.map(|x| x / n);
    let i = inertia.principal;
    // Spinning at 10 rad/s about the intermediate axis, slightly off it; turned by q, so
    // that the world quantities checked are not aligned with the axes.
    let mut s = RigidState {
        position: [0.0; 3],
        velocity: [0.0; 3],
        orientation: q,
        body_momentum: [1e-3 * i[0], 10.0 * i[1], 1e-3 * i[2]],
    };
    let l0 = s.angular_momentum();
    let e0 = s.kinetic_energy(&inertia);
    let dt = 1e-4;
    let (mut flips, mut sign) = (0, s.body_momentum[1].signum());
    let (mut worst_l, mut worst_e) = (0.0f64, 0.0f64);
    for _ in 0..500_000 {
        free_step(&mut s, &inertia, dt);
        if s.body_momentum[1].signum() != sign {
            flips += 1;
            sign = -sign;
        }
        let l = s.angular_momentum();
        let dl = norm([l[0] - l0[0], l[1] - l0[1], l[2] - l0[2]]) / norm(l0);
        worst_l = worst_l.max(dl);
        worst_e = worst_e.max((s.kinetic_energy(&inertia) / e0 - 1.0).abs());
    }
    eprintln!("{flips} flips in 50 s; |dL|/|L| <= {worst_l:.2e}, |dE|/E <= {worst_e:.2e}");
    assert!(flips >= 4, "{flips} flips");
    assert!(worst_l < 1e-11, "{worst_l}");
    assert!(worst_e < 1e-6, "{worst_e}");
}

/// The principal moments of a rotated diagonal tensor are the diagonal (1e-12
/// relative), and the principal frame maps the axes back; an isotropic tensor keeps the
/// given axes; a tensor that is not positive definite is refused.
#[test]
fn principal_axes_undo_a_rotation_and_bad_tensors_are_refused() {
    let (c, s) = (0.6f64, 0.8f64);
    // R = rotation by atan(4/3) about z; I = R diag(1, 2, 3) R^T.
    let d = [1.0, 2.0, 3.0];
    let r = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
    let mut tensor = [[0.0; 3]; 3];
    for (j, row) in tensor.iter_mut().enumerate() {
        for (k, t) in row.iter_mut().enumerate() {
            *t = (0..3).map(|m| r[j][m] * d[m] * r[k][m]).sum();
        }
    }
    let inertia = RigidInertia::new(5.0, tensor).unwrap();
    let mut moments = inertia.principal;
    moments.sort_by(f64::total_cmp);
    for (m, e) in moments.iter().zip(d) {
        assert!((m - e).abs() < 1e-12 * e, "{moments:?}");
    }
    // A body spinning about a principal axis keeps its angular velocity.
    let state = RigidState::new(
        &inertia,
        [0.0; 3],
        [0.0; 3],
        inertia.principal_frame,
        [0.0, 0.0, 1.0],
    );
    let mut spun = state;
    for _ in 0..1000 {
        free_step(&mut spun, &inertia, 1e-3);
    }
    let w = spun.angular_velocity(&inertia);
    assert!(
        (w[2] - 1.0).abs() < 1e-12 && w[0].abs() < 1e-12 && w[1].abs() < 1e-12,
        "{w:?}"
    );
    // Equal moments leave the axes to the geometry, not to round-off: a tensor isotropic
    // up to round-off keeps the mesh's axes and the mean moment, whatever its scale.
    for scale in [1.0, 3.7e-9] {
        let noisy = [
            [2.0, 1e-15, 0.0],
            [1e-15, 2.0 + 4e-16, -2e-16],
            [0.0, -2e-16, 2.0],
        ]
        .map(|row| row.map(|x| x * scale));
        let iso = RigidInertia::new(1.0, noisy).unwrap();
        assert_eq!(iso.principal_frame, [1.0, 0.0, 0.0, 0.0]);
        assert!(iso.principal.iter().all(|&m| m == iso.principal[0]));
    }
    assert!(RigidInertia::new(1.0, [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]]).is_err());
    assert!(RigidInertia::new(0.0, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_err());
}

mod in_the_engine {
    /// The `[material]` of these scenes: rock (docs/MODEL.md section 8).
    const ROCK: &str = "[material]\ndensity = 2650.0\nyoungs_modulus = 40.0e9\npoisson_ratio = 0.2";

    use fdem_contact::{ContactParams, Wall};
    use fdem_elastic::Material;
    use fdem_mesh::{ElementOrder, Placement, Sizing, SphereSpec, TetMesh, sphere_mesh};
    use fdem_solver::{BodyKind, ContactSettings, InitialMotion, ModelBuilder, TimeStep};

    fn sphere(level: u32) -> TetMesh {
        sphere_mesh(&SphereSpec {
            level,
            order: ElementOrder::Linear,
            diameter: 1.0,
            sizing: Sizing::Inscribed,
        })
        .unwrap()
    }

    fn material() -> Material {
        Material::new(2650.0, 40.0e9, 0.2).unwrap()
    }

    fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
        super::norm([a[0] - b[0], a[1] - b[1], a[2] - b[2]])
    }

    /// A meshed rigid ellipsoid (`mesh.axes = [1, 0.7, 0.5]`, level 2) from a scene,
    /// spun about its intermediate axis with a small perturbation, flips over and back in
    /// the engine (Dzhanibekov): its body-frame intermediate momentum changes sign again
    /// and again, while the world angular momentum holds to 1e-10 relative and the
    /// kinetic energy to 1e-6 (the splitting's bounded error). Its mass is the density
    /// times the meshed ellipsoid's volume, abc times the sphere mesh's (1e-12), in both
    /// models.
    #[test]
    fn a_rigid_ellipsoid_from_a_scene_flips_about_its_intermediate_axis() {
        let scene = |axes: &str| {
            fdem_solver::Scene::from_toml_str(
                &format!(
                    r#"
[simulation]
duration = 60.0
dt = 1.0e-4
{ROCK}
[[particle]]
diameter = 0.01
center = [0.0, 0.0, 0.0]
angular_velocity = [0.01, 10.0, 0.01]
model = "rigid"
mesh = {{ level = 2, axes = {axes} }}
"#
                ),
                "ellipsoid",
            )
            .unwrap()
        };
        let mut sim = scene("[1.0, 0.7, 0.5]").build().unwrap();
        let sphere = scene("[1.0, 1.0, 1.0]").build().unwrap();
        let ratio = sim.body_motion(0).mass / sphere.body_motion(0).mass;
        assert!((ratio - 0.35).abs() < 1e-12, "{ratio}");
        // The deformable ellipsoid's lumped masses add up to the same mass.
        let mut deformable = scene("[1.0, 0.7, 0.5]");
        deformable.particles[0].model = fdem_solver::ParticleModel::Deformable;
        let lumped = deformable.build().unwrap().body_motion(0).mass;
        let m = sim.body_motion(0).mass;
        assert!((lumped / m - 1.0).abs() < 1e-12, "{lumped} vs {m}");
        let m0 = sim.body_motion(0);
        let energy = |m: &fdem_solver::BodyMotion| {
            0.5 * (0..3)
                .map(|k| m.angular_velocity[k] * m.angular_momentum[k])
                .sum::<f64>()
        };
        let (l0, e0) = (m0.angular_momentum, energy(&m0));
        let intermediate = |sim: &fdem_solver::Simulation| sim.rigid_states()[0].body_momentum[1];
        let (mut flips, mut sign) = (0, intermediate(&sim).signum());
        let (mut worst_l, mut worst_e) = (0.0f64, 0.0f64);
        for _ in 0..300_000 {
            sim.advance().unwrap();
            if intermediate(&sim).signum() != sign {
                flips += 1;
                sign = -sign;
            }
            let m = sim.body_motion(0);
            worst_l = worst_l.max(dist(m.angular_momentum, l0) / super::norm(l0));
            worst_e = worst_e.max((energy(&m) / e0 - 1.0).abs());
        }
        eprintln!("{flips} flips in 30 s; |dL|/|L| <= {worst_l:.2e}, |dE|/E <= {worst_e:.2e}");
        assert!(flips >= 4, "{flips} flips");
        assert!(worst_l < 1e-10, "{worst_l}");
        assert!(worst_e < 1e-6, "{worst_e}");
    }

    /// A free rigid particle spinning in the engine keeps its shape exactly (node
    /// distances to 1e-12 relative), its angular momentum (1e-11) and its energy (1e-6),
    /// and its nodes move with `v + omega x r`; `bodies.csv`'s summary comes from its own
    /// state.
    #[test]
    fn a_free_rigid_particle_spins_as_one_body() {
        let mut model = ModelBuilder::new();
        let motion = InitialMotion {
            velocity: [0.1, 0.0, 0.0],
            angular_velocity: [0.0, 300.0, 400.0],
        };
        let d = 0.015;
        let id = model
            .add_rigid(
                &sphere(1),
                &Placement {
                    scale: d,
                    ..Placement::identity()
                },
                &material(),
                motion,
            )
            .unwrap();
        model.set_time_step(TimeStep::Fixed(1e-6));
        let mut sim = model.build().unwrap();
        assert_eq!(sim.bodies()[id.0].kind, BodyKind::Rigid);
        let x0 = sim.state().positions.clone();
        let (m0, e0) = (sim.body_motion(0), sim.energy());
        for _ in 0..2000 {
            sim.advance().unwrap();
        }
        let x = &sim.state().positions;
        for (i, j) in [(0, 1), (0, 7), (3, 20), (11, 41)] {
            let (a, b) = (dist(x0[i], x0[j]), dist(x[i], x[j]));
            assert!((a - b).abs() < 1e-12 * a, "nodes {i}, {j}: {a} vs {b}");
        }
        let m = sim.body_motion(0);
        let dl = dist(m.angular_momentum, m0.angular_momentum) / super::norm(m0.angular_momentum);
        assert!(dl < 1e-11, "{dl}");
        let e = sim.energy();
        assert!((e.kinetic / e0.kinetic - 1.0).abs() < 1e-6, "{e:?}");
        assert!((m.centroid[0] - (m0.centroid[0] + 0.1 * sim.time())).abs() < 1e-12);
        // Node velocities are the rigid field.
        let (v, w, c) = (m.velocity, m.angular_velocity, m.centroid);
        for i in [0, 5, 17] {
            let r = [x[i][0] - c[0], x[i][1] - c[1], x[i][2] - c[2]];
            let u = fdem_core::geometry::cross(w, r);
            let vi = sim.state().velocities[i];
            for k in 0..3 {
                assert!((vi[k] - (v[k] + u[k])).abs() < 1e-9, "node {i}: {vi:?}");
            }
        }
    }

    /// Oblique impact of a rigid sphere on a plane wall in the sliding regime (Chung and
    /// Ooi's benchmark, test 4): with the normal restitution `e` measured in the same run,
    /// Coulomb sliding over the whole contact gives `v_t' = v_t - mu (1 + e) v_n` and
    /// `omega' = m R mu (1 + e) v_n / I` (R the contact lever arm). Both within 5 % of the
    /// predicted change.
    #[test]
    fn an_oblique_impact_in_the_sliding_regime_matches_coulomb_sliding() {
        let d = 0.01;
        let (vn, vt) = (0.2, 1.0);
        let mut model = ModelBuilder::new();
        let placement = Placement {
            scale: d,
            ..Placement::at([0.0, 0.0, 0.5 * d + 2e-5])
        };
        let motion = InitialMotion {
            velocity: [vt, 0.0, -vn],
            angular_velocity: [0.0; 3],
        };
        model
            .add_rigid(&sphere(3), &placement, &material(), motion)
            .unwrap();
        let margin = 0.25 * model.shortest_surface_edge().unwrap();
        model.add_wall(Wall::plane([0.0; 3], [0.0, 0.0, 1.0]));
        model.set_contact(ContactSettings {
            params: ContactParams::default(),
            margin,
            depth_limit: None,
            depth_limit_cap: None,
            sheet_fold_depth: None,
        });
        model.set_time_step(TimeStep::Automatic { safety: 0.5 });
        let mut sim = model.build().unwrap();
        let mut touched = false;
        for _ in 0..200_000 {
            sim.advance().unwrap();
            let contacts = sim.contact().unwrap().model().node_contacts().len();
            touched |= contacts > 0;
            if touched && contacts == 0 && sim.body_motion(0).velocity[2] > 0.0 {
                break;
            }
        }
        assert!(touched, "no impact");
        let m = sim.body_motion(0);
        let e = m.velocity[2] / vn;
        assert!(e > 0.2 && e < 1.0, "restitution {e}");
        let mu = ContactParams::default().friction;
        let dvt = mu * (1.0 + e) * vn;
        let measured_dvt = vt - m.velocity[0];
        assert!(
            (measured_dvt - dvt).abs() < 0.05 * dvt,
            "dv_t {measured_dvt} vs {dvt}"
        );
        // Lever arm: the lowest node's distance below the centre at rest (inscribed mesh).
        let lowest = sim
            .state()
            .positions
            .iter()
            .map(|x| m.centroid[2] - x[2])
            .fold(0.0, f64::max);
        // I from the body's own L / omega about y (the mesh's inertia is isotropic).
        let inertia = m.angular_momentum[1] / m.angular_velocity[1];
        let omega = m.mass * lowest * dvt / inertia;
        let w = m.angular_velocity[1];
        eprintln!(
            "e = {e:.3}, dv_t = {measured_dvt:.4} (pred {dvt:.4}), omega = {w:.2} (pred {omega:.2})"
        );
        assert!((w - omega).abs() < 0.05 * omega, "omega {w} vs {omega}");
    }

    /// A scene that mixes a rigid, a linear and a quadratic particle: in frictional
    /// oblique collisions the total linear momentum (the rigid body's `m V` plus the
    /// deformable nodes' `sum m v`) is conserved to 1e-10 relative, since contact forces
    /// come in equal and opposite pairs and the rigid body gathers its nodes' forces whole.
    #[test]
    fn a_mixed_scene_conserves_linear_momentum_in_a_frictional_collision() {
        let scene = fdem_solver::Scene::from_toml_str(
            &format!(
                r#"
[simulation]
duration = 1.0
dt_safety = 0.5
{ROCK}
[[particle]]
diameter = 0.01
center = [0.0, 0.0, 0.0]
velocity = [2.0, 0.5, 0.0]
model = "rigid"
[[particle]]
diameter = 0.01
center = [0.01003, 0.003, 0.0]
mesh = {{ level = 1, order = "quadratic" }}
[[particle]]
diameter = 0.01
center = [0.0, -0.01003, 0.001]
velocity = [0.0, 1.0, 0.0]
mesh = {{ level = 1, order = "linear" }}
"#
            ),
            "mixed",
        )
        .unwrap();
        let mut sim = scene.build().unwrap();
        assert_eq!(sim.bodies()[0].kind, BodyKind::Rigid);
        assert_eq!(sim.bodies()[1].kind, BodyKind::Deformable);
        let counts = sim.connectivity().node_counts();
        assert_eq!(counts[sim.bodies()[1].elements.clone()][0], 10);
        assert_eq!(counts[sim.bodies()[2].elements.clone()][0], 4);
        let momentum = |sim: &fdem_solver::Simulation| {
            let m: Vec<_> = (0..3).map(|b| sim.body_motion(b)).collect();
            [0, 1, 2].map(|k| m.iter().map(|m| m.mass * m.velocity[k]).sum::<f64>())
        };
        let p0 = momentum(&sim);
        // Until both deformable particles have been hit (the linear one deflected).
        let deflected = |sim: &fdem_solver::Simulation| sim.body_motion(2).velocity[0].abs() > 0.01;
        let (mut touched, mut after) = (false, 0);
        while (after < 2000 || !deflected(&sim)) && sim.step() < 200_000 {
            sim.advance().unwrap();
            let c = sim.contact().unwrap().model().node_contacts();
            touched |= c.iter().any(|c| c.tangential_force != [0.0; 3]);
            after += usize::from(touched);
        }
        assert!(touched, "no frictional contact by {:e} s", sim.time());
        assert!(deflected(&sim), "the linear particle was not hit");
        let p = momentum(&sim);
        let scale = super::norm(p0);
        for k in 0..3 {
            assert!((p[k] - p0[k]).abs() < 1e-10 * scale, "{p:?} vs {p0:?}");
        }
        // The deformable particle was pushed.
        assert!(sim.body_motion(1).velocity[0] > 0.1);
    }

    /// Two particles of diameter 1 cm and mesh `level` (linear) collide obliquely at 2 m/s
    /// (impact parameter 0.4 diameters) with Coulomb friction `mu` and normal damping
    /// ratio `beta`, both in `model` at `dt_safety`: particle 0's motion once they have
    /// parted (200 steps without contact), and the steps with contact.
    fn oblique_rebound(
        model: &str,
        level: u32,
        mu: f64,
        beta: f64,
        dt_safety: f64,
    ) -> (fdem_solver::BodyMotion, usize) {
        let text = format!(
            r#"
[simulation]
duration = 1.0
dt_safety = {dt_safety}
# The faceted surfaces' node-to-face depth jumps when a node changes face, which the
# balance books as an error of some percent in an oblique collision of rigid facets
# (docs/TRIAXIAL.md, "Energy balance"); these tests are about the rebound.
energy_tolerance = 0.3
{ROCK}
[contact]
friction = {mu}
damping = {beta}
[[particle]]
diameter = 0.01
center = [0.0, 0.0, 0.0]
velocity = [1.0, 0.0, 0.0]
model = "{model}"
mesh = {{ level = {level} }}
[[particle]]
diameter = 0.01
center = [0.01003, 0.004, 0.0]
velocity = [-1.0, 0.0, 0.0]
model = "{model}"
mesh = {{ level = {level} }}
"#
        );
        let mut sim = fdem_solver::Scene::from_toml_str(&text, model)
            .unwrap()
            .build()
            .unwrap();
        if model == "rigid" {
            // An edit of a rigid body's node between steps is undone by the next force
            // evaluation (the contact's frames rely on the nodes following the poses).
            let before = sim.state().positions[3];
            sim.nodes_mut().positions[3][0] += 1e-4;
            sim.rebase_energy().unwrap();
            assert_eq!(sim.state().positions[3], before);
        }
        let (mut touching, mut apart) = (0, 0);
        while apart < 200 && sim.step() < 400_000 {
            sim.advance().unwrap();
            let n = sim.contact().unwrap().model().node_contacts().len();
            touching += (n > 0) as usize;
            apart = if touching > 0 && n == 0 { apart + 1 } else { 0 };
        }
        assert!(
            touching > 0 && apart == 200,
            "{model}: no complete collision"
        );
        // Rigid faces are met in their template's frame (the plane filter), deformable
        // ones by their world planes.
        let framed = sim.contact().unwrap().model().rigid_frames_in_use();
        assert_eq!(framed, model == "rigid", "{model}");
        (sim.body_motion(0), touching)
    }

    /// Two level-1 linear particles collide obliquely (friction and damping on, the
    /// defaults), once deformable and once rigid, from the same start, each at the
    /// default `dt_safety`: the measured difference, guarded so that a change of either
    /// model shows. Three causes, each isolated by the tests below (docs/VERIFICATION.md,
    /// "Rigid particles"): the rigid collision is resolved in a few steps at that step;
    /// the deformable particle's lumped masses carry 1.3669 times the solid's rotational
    /// inertia at level 1, which the facets' lever arm turns into a different impulse;
    /// and friction's sticking phase acts on different masses in the two models. The
    /// bounds are the measured numbers with a margin.
    #[test]
    fn deformable_and_rigid_particles_rebound_from_an_oblique_collision_as_measured() {
        let ((d, _), (r, _)) = (
            oblique_rebound("deformable", 1, 0.3, 0.2, 0.5),
            oblique_rebound("rigid", 1, 0.3, 0.2, 0.5),
        );
        let dv = super::norm([0, 1, 2].map(|k| d.velocity[k] - r.velocity[k]));
        let spin = d.angular_velocity[2] / r.angular_velocity[2];
        eprintln!(
            "rebound: deformable v = {:?}, w_z = {:.3}; rigid v = {:?}, w_z = {:.3}; |dv| = {dv:.4} m/s, spin ratio {spin:.4}",
            d.velocity, d.angular_velocity[2], r.velocity, r.angular_velocity[2]
        );
        assert!(r.angular_velocity[2].abs() > 1.0, "no spin: {r:?}");
        // Measured: |dv| = 0.126 m/s (of a 2 m/s approach), spin ratio 0.846.
        assert!(dv < 0.15, "centre velocities differ by {dv} m/s");
        assert!(spin > 0.80 && spin < 0.90, "spin ratio {spin}");
    }

    /// The rigid collision converges as its step shrinks. An impact lasts half a period
    /// of the contact's oscillation, about `pi / omega`, and the default `dt_safety` 0.5
    /// takes half the stability bound `2 / omega`: a rigid impact spans about pi steps (a
    /// deformable one many more, its step set by the elements). From an eighth of the
    /// bound on (more than ten steps of contact) halving the step moves the rebound by
    /// under 1.5 % of the approach speed, and by less each time.
    #[test]
    fn a_rigid_collision_converges_as_the_step_shrinks() {
        let runs: Vec<_> = [0.5, 0.125, 0.0625, 0.03125]
            .map(|s| oblique_rebound("rigid", 1, 0.3, 0.2, s))
            .into_iter()
            .collect();
        for (s, (m, steps)) in [0.5, 0.125, 0.0625, 0.03125].iter().zip(&runs) {
            eprintln!(
                "dt_safety {s}: {steps} steps of contact, v = {:?}",
                m.velocity
            );
        }
        assert!(
            runs[0].1 < 8 && runs[1].1 > 10,
            "contact steps {:?}",
            runs.iter().map(|r| r.1).collect::<Vec<_>>()
        );
        let change = |a: usize, b: usize| {
            super::norm([0, 1, 2].map(|k| runs[a].0.velocity[k] - runs[b].0.velocity[k])) / 2.0
        };
        let (coarse, fine, finer) = (change(0, 1), change(1, 2), change(2, 3));
        assert!(
            coarse > 0.03,
            "the default step's rebound is off by {coarse} of the approach"
        );
        assert!(
            fine < 0.015 && finer < fine,
            "changes {fine}, {finer} of the approach"
        );
    }

    /// Without friction the two models differ by the inertia alone: two level-2 particles
    /// collide obliquely, frictionless and undamped, and then with damping only, rigid
    /// (resolved in many steps) and deformable; the rebound velocities agree within 1 % of
    /// the approach speed, and the deformable spin is the rigid one divided by the lumped
    /// masses' inertia ratio (1.2790 at level 2) within 1 %: the same impulse on more
    /// inertia. (At level 1 the facets' larger lever arm turns the inertia difference into
    /// a different impulse too.)
    #[test]
    fn without_friction_rigid_and_deformable_differ_by_the_inertia_alone() {
        let ratio = super::lumped_inertia_ratio(2, fdem_mesh::ElementOrder::Linear);
        for beta in [0.0, 0.2] {
            let ((d, _), (r, _)) = (
                oblique_rebound("deformable", 2, 0.0, beta, 0.5),
                oblique_rebound("rigid", 2, 0.0, beta, 0.03125),
            );
            let dv = super::norm([0, 1, 2].map(|k| d.velocity[k] - r.velocity[k])) / 2.0;
            let spin = d.angular_velocity[2] / r.angular_velocity[2] * ratio;
            eprintln!(
                "beta {beta}: deformable v = {:?}, w_z = {:.3}; rigid v = {:?}, w_z = {:.3}; |dv| / 2 m/s = {dv:.4}, spin ratio x inertia ratio {spin:.4}",
                d.velocity, d.angular_velocity[2], r.velocity, r.angular_velocity[2]
            );
            assert!(
                dv < 0.01,
                "beta {beta}: rebounds differ by {dv} of the approach"
            );
            assert!((spin - 1.0).abs() < 0.01, "beta {beta}: {spin}");
        }
    }

    /// At level 1 the two models' frictionless rebounds differ (by about 3 % of the
    /// velocity change), and the inertia explains it: one elastic impulse `J` along the
    /// contact normal at lever arm `l` from each centre changes the velocity by `J / m =
    /// v_n / (1 + m l^2 / I)` and the spin by `J l / I`. From the rigid run (`I` the
    /// solid's) follows `l`; with the same `l` and the lumped inertia (1.3669 times the
    /// solid's) the model predicts the deformable particle's velocity change within 0.5 %,
    /// in the same direction.
    #[test]
    fn at_level_1_the_inertia_explains_the_frictionless_difference() {
        use fdem_mesh::{ElementOrder, Sizing, SphereSpec, sphere_mesh};
        let ((d, _), (r, _)) = (
            oblique_rebound("deformable", 1, 0.0, 0.0, 0.5),
            oblique_rebound("rigid", 1, 0.0, 0.0, 0.03125),
        );
        let change = |m: &fdem_solver::BodyMotion| [m.velocity[0] - 1.0, m.velocity[1]];
        let (dv_r, dv_d) = (change(&r), change(&d));
        let len = |v: [f64; 2]| v[0].hypot(v[1]);
        // The solid's moment per mass at diameter 0.01 m: I / m = (2/3) tr(S) / V.
        let shape = sphere_mesh(&SphereSpec {
            level: 1,
            order: ElementOrder::Linear,
            diameter: 1.0,
            sizing: Sizing::Inscribed,
        })
        .unwrap()
        .volume_properties();
        let s = shape.second_moment;
        let i_per_m = 2.0 / 3.0 * (s[0][0] + s[1][1] + s[2][2]) / shape.volume * 1e-4;
        let lever = r.angular_velocity[2].abs() * i_per_m / len(dv_r);
        let x_rigid = lever * lever / i_per_m;
        let x_deformable = x_rigid / super::lumped_inertia_ratio(1, ElementOrder::Linear);
        let predicted = len(dv_r) * (1.0 + x_rigid) / (1.0 + x_deformable);
        let angle = |v: [f64; 2]| v[1].atan2(v[0]);
        eprintln!(
            "level 1: |dv| rigid {:.5}, deformable {:.5}, predicted {predicted:.5} (lever {:.3e} m, m l^2 / I = {x_rigid:.4}); directions {:.5} and {:.5} rad",
            len(dv_r),
            len(dv_d),
            lever,
            angle(dv_r),
            angle(dv_d)
        );
        assert!(len(dv_d) / len(dv_r) > 1.02, "no difference to explain");
        assert!(
            (len(dv_d) / predicted - 1.0).abs() < 0.005,
            "{} vs {predicted}",
            len(dv_d)
        );
        assert!((angle(dv_r) - angle(dv_d)).abs() < 0.005);
    }
}

/// The ratio of the lumped rotational inertia `sum m_i |r_i|^2` of a deformable sphere of
/// mesh `level` and element `order` to the solid's `rho tr(S)` (both isotropic, so one
/// number each).
fn lumped_inertia_ratio(level: u32, order: fdem_mesh::ElementOrder) -> f64 {
    use fdem_mesh::{Sizing, SphereSpec, sphere_mesh};
    let material = fdem_elastic::Material::new(2650.0, 40.0e9, 0.2).unwrap();
    let mesh = sphere_mesh(&SphereSpec {
        level,
        order,
        diameter: 1.0,
        sizing: Sizing::Inscribed,
    })
    .unwrap();
    let set = fdem_elastic::ElementSet::new(
        &material,
        order.nodes_per_element(),
        &mesh.nodes,
        &mesh.elements,
    )
    .unwrap();
    let masses = set.lumped_masses(mesh.n_nodes());
    let shape = mesh.volume_properties();
    let c = shape.centroid;
    let lumped: f64 = mesh
        .nodes
        .iter()
        .zip(&masses)
        .map(|(x, m)| m * norm([x[0] - c[0], x[1] - c[1], x[2] - c[2]]).powi(2))
        .sum();
    let s = shape.second_moment;
    lumped / (material.density * (s[0][0] + s[1][1] + s[2][2]))
}

/// The deformable particle's lumped masses carry more rotational inertia than the solid
/// it meshes (a share of the mass sits on the surface nodes, a share on the centre): for
/// every mesh the ratio of the lumped inertia `sum m_i |r_i|^2` to the solid's
/// `rho tr(S)` (both isotropic, so one number each) is above 1 and falls as the mesh is
/// refined; linear meshes tend to `0.5 / 0.4` (a quarter of the mass on the centre node,
/// the rest on the surface), level 3 within 1 % of it. The ratios are printed for docs/VERIFICATION.md (`cargo test -p fdem-solver --test rigid --
/// --nocapture lumped`).
#[test]
fn lumped_masses_carry_more_rotational_inertia_than_the_solid() {
    use fdem_mesh::ElementOrder;
    for order in [ElementOrder::Linear, ElementOrder::Quadratic] {
        let mut previous = f64::INFINITY;
        for level in 0..=3 {
            let ratio = lumped_inertia_ratio(level, order);
            eprintln!("lumped inertia / solid inertia, level {level} {order:?}: {ratio:.4}");
            assert!(
                ratio > 1.0 && ratio < previous,
                "level {level} {order:?}: {ratio}"
            );
            previous = ratio;
        }
        if order == ElementOrder::Linear {
            // A quarter of the mass on the centre, the rest on the sphere: 0.5 / 0.4.
            assert!((previous / 1.25 - 1.0).abs() < 0.01, "{previous}");
        }
    }
}

/// Many rigid bodies (more than one parallel task's worth) spinning freely: each body's
/// nodes follow it, its angular momentum is conserved (1e-11 relative) and the run is bit for bit the same on
/// one thread and on two (the rigid passes split the bodies over threads).
#[test]
fn many_rigid_bodies_run_identically_on_one_and_two_threads() {
    use fdem_mesh::{ElementOrder, Placement, Sizing, SphereSpec, sphere_mesh};
    use fdem_solver::{InitialMotion, ModelBuilder, TimeStep};
    let template = sphere_mesh(&SphereSpec {
        level: 0,
        order: ElementOrder::Linear,
        diameter: 1.0,
        sizing: Sizing::Inscribed,
    })
    .unwrap();
    let material = fdem_elastic::Material::new(2650.0, 40.0e9, 0.2).unwrap();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut model = ModelBuilder::new();
            for i in 0..300 {
                let f = i as f64;
                let placement = Placement {
                    scale: 0.01,
                    rotation: [0.8, 0.6 * (f * 0.7).cos(), 0.6 * (f * 0.7).sin(), 0.0],
                    translation: [0.02 * f, 0.0, 0.0],
                };
                let motion = InitialMotion {
                    velocity: [0.0, 0.1, 0.0],
                    angular_velocity: [(f * 1.3).sin() * 50.0, 30.0, (f * 0.9).cos() * 40.0],
                };
                model
                    .add_rigid(&template, &placement, &material, motion)
                    .unwrap();
            }
            model.set_time_step(TimeStep::Fixed(1e-5));
            let mut sim = model.build().unwrap();
            let l0: Vec<[f64; 3]> = (0..300)
                .map(|b| sim.body_motion(b).angular_momentum)
                .collect();
            for _ in 0..200 {
                sim.advance().unwrap();
            }
            for (b, l) in l0.iter().enumerate() {
                // The icosahedron's vertices average to its centre: each body's nodes
                // moved with it (a wrong node range in a parallel pass would not).
                let nodes = sim.bodies()[b].nodes.clone();
                let n = nodes.len() as f64;
                let c = sim.body_motion(b).centroid;
                for k in 0..3 {
                    let mean: f64 = sim.state().positions[nodes.clone()]
                        .iter()
                        .map(|x| x[k])
                        .sum();
                    assert!((mean / n - c[k]).abs() < 1e-12, "body {b}");
                }
                let m = sim.body_motion(b).angular_momentum;
                let d = norm([m[0] - l[0], m[1] - l[1], m[2] - l[2]]) / norm(*l);
                assert!(d < 1e-11, "body {b}: {d}");
            }
            sim.state().positions.clone()
        })
    };
    assert_eq!(run(1), run(2));
}
