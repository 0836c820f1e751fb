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
/// relative), and the principal frame maps the axes back; a tensor that is not positive
/// definite is refused.
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
    assert!(RigidInertia::new(1.0, [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]]).is_err());
    assert!(RigidInertia::new(0.0, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_err());
}
