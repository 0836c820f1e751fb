//! The assembled model: conservation, restitution against rigid walls, walls, guards,
//! determinism, reports and set-up errors.

mod common;

use common::{add, cross, linear_sphere, model_for, norm, overlapping_pair, rng, scale, sub};
use fdem_contact::{
    ContactError, ContactModel, ContactParams, ContactSurface, Counterpart, DEPTH_LIMIT_GROWTH,
    TunnellingScale, Wall, spring_dashpot_time_step,
};
use fdem_mesh::{MeshAssembly, Placement};
use rand::RngExt;

/// Random node/face configurations: two randomly rotated level-1 spheres overlapping along
/// a random direction, random velocities, two steps so that friction histories exist.
#[test]
fn forces_sum_to_zero_and_torques_to_the_tangential_couple() {
    for seed in 0..16 {
        let mut r = rng(seed);
        let d = 0.01;
        // About a fifth of the suggested margin (0.1 x the shortest edge, 2.7e-4 m).
        let assembly = overlapping_pair(&mut r, 1, d, 5e-5);
        let n = assembly.n_nodes();
        let velocities: Vec<[f64; 3]> = (0..n)
            .map(|_| std::array::from_fn(|_| r.random_range(-1.0..1.0)))
            .collect();
        for friction in [0.0, 0.3] {
            let params = ContactParams {
                friction,
                ..ContactParams::default()
            };
            let mut model = model_for(&assembly, params, vec![], 1e-4, None);
            let mut forces = vec![[0.0; 3]; n];
            for _ in 0..2 {
                forces = vec![[0.0; 3]; n];
                model
                    .add_forces(&assembly.nodes, &velocities, 0.0, 1e-7, &mut forces)
                    .unwrap();
            }
            assert!(!model.node_contacts().is_empty(), "seed {seed}: no contact");
            let total: [f64; 3] = forces.iter().fold([0.0; 3], |s, f| add(s, *f));
            let scale_f: f64 = forces.iter().map(|f| norm(*f)).sum();
            assert!(
                norm(total) <= 1e-12 * scale_f,
                "seed {seed}: {total:?} vs {scale_f}"
            );
            // Torque about the origin: the normal part cancels (it acts along node ->
            // contact point); what remains is sum (x_node - x_contact) x F_s.
            let torque: [f64; 3] = assembly
                .nodes
                .iter()
                .zip(&forces)
                .fold([0.0; 3], |s, (x, f)| add(s, cross(*x, *f)));
            let couple: [f64; 3] = model.node_contacts().iter().fold([0.0; 3], |s, c| {
                add(
                    s,
                    cross(sub(c.position, c.contact_point), c.tangential_force),
                )
            });
            let torque_scale: f64 = assembly
                .nodes
                .iter()
                .zip(&forces)
                .map(|(x, f)| norm(*x) * norm(*f))
                .sum();
            assert!(
                norm(sub(torque, couple)) <= 1e-12 * torque_scale,
                "seed {seed} mu {friction}: {torque:?} vs {couple:?}"
            );
            if friction == 0.0 {
                assert_eq!(couple, [0.0; 3]);
            } else {
                assert!(
                    model
                        .node_contacts()
                        .iter()
                        .any(|c| norm(c.tangential_force) > 0.0)
                );
            }
        }
    }
}

/// Analytic coefficient of restitution of the linear spring-dashpot (damping ratio beta)
/// when the force may pull: e = exp(-beta pi / sqrt(1 - beta^2)).
fn e_unclamped(beta: f64) -> f64 {
    (-beta * std::f64::consts::PI / (1.0 - beta * beta).sqrt()).exp()
}

/// The same oscillator when the force is clamped at zero (Schwager & Poeschel 2007): the
/// contact ends at omega_d t_c = pi - atan(2 beta sqrt(1 - beta^2) / (1 - 2 beta^2)),
/// where k x + c x' = 0, and e = |x'(t_c)| / v0. Valid for beta < 1/sqrt(2).
fn e_clamped(beta: f64) -> f64 {
    let s = (1.0 - beta * beta).sqrt();
    let phase = std::f64::consts::PI - (2.0 * beta * s / (1.0 - 2.0 * beta * beta)).atan();
    // x'(t)/v0 = exp(-beta omega t) (cos(omega_d t) - beta/s sin(omega_d t)), omega t = phase/s.
    ((-beta * phase / s).exp() * (phase.cos() - beta / s * phase.sin())).abs()
}

/// A single node of mass m and control area A dropped at v0 on the plane z = 0, integrated
/// with velocity Verlet at dt = T/4000; returns the coefficient of restitution.
fn bounce(beta: f64) -> f64 {
    let (m, area, v0) = (2e-3, 1e-5, 0.05);
    let params = ContactParams {
        damping: beta,
        friction: 0.0,
        ..ContactParams::default()
    };
    let surface = ContactSurface {
        triangles: vec![],
        triangle_body: vec![],
        surface_nodes: vec![0],
        node_body: vec![0],
        control_areas: vec![area],
    };
    let wall = Wall::plane([0.0; 3], [0.0, 0.0, 1.0]);
    let mut model = ContactModel::new(params, surface, vec![wall], &[m], 1e-4).unwrap();
    let k = params.normal_penalty * area;
    let period = 2.0 * std::f64::consts::PI / (k / m).sqrt();
    let dt = period / 4000.0;
    let mut x = [0.0, 0.0, 0.5 * v0 * dt];
    let mut v = [0.0, 0.0, -v0];
    let mut a = [0.0; 3];
    for _ in 0..20_000 {
        let v_half = add(v, scale(a, 0.5 * dt));
        x = add(x, scale(v_half, dt));
        let mut f = [[0.0; 3]];
        model.add_forces(&[x], &[v_half], 0.0, dt, &mut f).unwrap();
        a = scale(f[0], 1.0 / m);
        v = add(v_half, scale(a, 0.5 * dt));
        if x[2] > 0.0 && v[2] > 0.0 {
            return v[2] / v0;
        }
    }
    panic!("the node did not bounce off");
}

#[test]
fn restitution_matches_the_spring_dashpot() {
    let betas = [0.005, 0.05, 0.1, 0.2, 0.3, 0.5];
    let mut last = 1.0;
    for beta in betas {
        let e = bounce(beta);
        // Clamped law (ours): the known clamped solution within 1 %.
        let ec = e_clamped(beta);
        assert!(
            (e - ec).abs() < 0.01 * ec,
            "beta {beta}: e {e} vs clamped {ec}"
        );
        // The clamp releases the contact before the spring pulls back, so less energy is
        // damped than with the unclamped law: e >= e_unclamped.
        assert!(e >= e_unclamped(beta), "beta {beta}");
        assert!(e < last, "e decreases with beta");
        last = e;
    }
    // For small beta the two laws coincide: within 1 % of exp(-beta pi / sqrt(1-beta^2)).
    let beta = 0.005;
    assert!((bounce(beta) - e_unclamped(beta)).abs() < 0.01 * e_unclamped(beta));
    // Without damping, energy is conserved: e = 1 within the O(dt^2) Verlet error.
    assert!((bounce(0.0) - 1.0).abs() < 1e-3);
}

#[test]
fn cylinder_and_moving_plane_walls() {
    let surface = ContactSurface {
        triangles: vec![],
        triangle_body: vec![],
        surface_nodes: vec![0, 1],
        node_body: vec![0, 1],
        control_areas: vec![1e-5, 1e-5],
    };
    let params = ContactParams {
        damping: 0.0,
        ..ContactParams::default()
    };
    let k = params.normal_penalty * 1e-5;
    // Cylinder of radius 0.1 about the z axis, plane z = 0.05 + 0.01 t facing down.
    let walls = vec![
        Wall::cylinder([0.0; 3], [0.0, 0.0, 2.0], 0.1),
        Wall::plane([0.0, 0.0, 0.05], [0.0, 0.0, -1.0]).moving([0.0, 0.0, 0.01]),
    ];
    let mut model = ContactModel::new(params, surface, walls, &[1e-3, 1e-3], 1e-4).unwrap();
    let (d0, d1): (f64, f64) = (2e-6, 3e-6);
    let t = 0.5; // the plane is at z = 0.055
    // Node 0 at radius 0.1 + d0 (outside the cylinder), node 1 d1 above the plane.
    let grow: f64 = (0.1 + d0) / 0.1;
    let x: [[f64; 3]; 2] = [[0.06 * grow, 0.08 * grow, 0.0], [0.0, 0.0, 0.055 + d1]];
    let r0: f64 = (x[0][0] * x[0][0] + x[0][1] * x[0][1]).sqrt();
    let depth0 = r0 - 0.1;
    let v = [[0.0; 3], [0.0, 0.0, 0.01]];
    let mut f = [[0.0; 3]; 2];
    let report = model.add_forces(&x, &v, t, 1e-7, &mut f).unwrap();
    assert_eq!((report.contacts, report.wall_contacts), (2, 2));
    // Cylinder: inward radial force k depth.
    let inward = [-x[0][0] / r0, -x[0][1] / r0, 0.0];
    assert!(norm(sub(f[0], scale(inward, k * depth0))) < 1e-9 * k * depth0);
    // Plane moving with the node: no relative velocity, force -k d1 along z.
    assert!((f[1][2] + k * d1).abs() < 1e-9 * k * d1);
    // Walls receive the opposite forces; the moving plane does work v_w . F_wall->node.
    let wf = model.wall_forces();
    assert!(norm(add(wf[0], f[0])) < 1e-15 * norm(f[0]));
    assert!(norm(add(wf[1], f[1])) < 1e-15 * norm(f[1]));
    assert!((report.wall_power - 0.01 * f[1][2]).abs() < 1e-12 * norm(f[1]) * 0.01);
    let sums = model.pair_sums();
    assert_eq!(sums.len(), 2);
    assert_eq!(
        (sums[0].body, sums[0].counterpart),
        (0, Counterpart::Wall(0))
    );
    assert_eq!(
        (sums[1].body, sums[1].counterpart),
        (1, Counterpart::Wall(1))
    );
}

#[test]
fn pair_sums_equal_the_force_between_two_bodies() {
    let mut r = rng(7);
    let assembly = overlapping_pair(&mut r, 1, 0.01, 5e-5);
    let n = assembly.n_nodes();
    let mut model = model_for(&assembly, ContactParams::default(), vec![], 1e-4, None);
    let v: Vec<[f64; 3]> = (0..n)
        .map(|_| std::array::from_fn(|_| r.random_range(-0.1..0.1)))
        .collect();
    let mut f = vec![[0.0; 3]; n];
    model
        .add_forces(&assembly.nodes, &v, 0.0, 1e-7, &mut f)
        .unwrap();
    let sums = model.pair_sums();
    assert_eq!(sums.len(), 1);
    let s = sums[0];
    assert_eq!((s.body, s.counterpart), (0, Counterpart::Body(1)));
    assert_eq!(s.nodes, model.node_contacts().len());
    let on_body0 = assembly.bodies[0]
        .nodes
        .clone()
        .fold([0.0; 3], |acc, i| add(acc, f[i]));
    let total = add(s.normal_force, s.tangential_force);
    assert!(norm(sub(total, on_body0)) < 1e-12 * norm(on_body0));
}

#[test]
fn detection_is_symmetric() {
    // Two identical spheres stacked along z: the top vertex of the lower one is inside the
    // upper one and the bottom vertex of the upper one inside the lower one; both nodes
    // are found, against the other body's faces.
    let d = 0.01;
    let mesh = linear_sphere(1, d);
    let mut assembly = MeshAssembly::new();
    assembly
        .push_instance(&mesh, &Placement::at([0.0; 3]))
        .unwrap();
    assembly
        .push_instance(&mesh, &Placement::at([0.0, 0.0, d - 2e-5]))
        .unwrap();
    let n = assembly.n_nodes();
    let mut model = model_for(&assembly, ContactParams::default(), vec![], 1e-4, None);
    let mut f = vec![[0.0; 3]; n];
    model
        .add_forces(&assembly.nodes, &vec![[0.0; 3]; n], 0.0, 1e-7, &mut f)
        .unwrap();
    let c = model.node_contacts();
    assert_eq!(c.len(), 2);
    assert_eq!((c[0].body, c[0].counterpart), (0, Counterpart::Body(1)));
    assert_eq!((c[1].body, c[1].counterpart), (1, Counterpart::Body(0)));
    // Each tip is 2e-5 m past the other tip, and is pushed back along z.
    assert!(c[0].normal_force[2] < 0.0 && c[1].normal_force[2] > 0.0);
}

#[test]
fn histories_persist_per_contact_across_chunks() {
    // 27 spheres (1134 surface nodes: three parallel chunks) on an overlapping lattice,
    // each translating rigidly at its own velocity, positions held fixed for three
    // evaluations, friction high enough to stick: every contact's tangential displacement
    // must be exactly 3 v_t,rel dt, so each found its own history every time.
    let d = 0.01;
    let mesh = linear_sphere(1, d);
    let half = mesh.nodes.iter().map(|x| x[0]).fold(f64::MIN, f64::max);
    let mut assembly = MeshAssembly::new();
    for i in 0..27 {
        let t = [i % 3, (i / 3) % 3, i / 9].map(|c| c as f64 * (2.0 * half - 3e-5));
        assembly.push_instance(&mesh, &Placement::at(t)).unwrap();
    }
    let n = assembly.n_nodes();
    let mut r = rng(8);
    let body_v: Vec<[f64; 3]> = (0..27)
        .map(|_| std::array::from_fn(|_| r.random_range(-1e-3..1e-3)))
        .collect();
    let mut v = vec![[0.0; 3]; n];
    for (b, range) in assembly.bodies.iter().enumerate() {
        for i in range.nodes.clone() {
            v[i] = body_v[b];
        }
    }
    let params = ContactParams {
        friction: 100.0,
        damping: 0.0,
        ..ContactParams::default()
    };
    let mut model = model_for(&assembly, params, vec![], 1e-4, Some(2e-4));
    let dt = 1e-7;
    for _ in 0..3 {
        let mut f = vec![[0.0; 3]; n];
        model
            .add_forces(&assembly.nodes, &v, 0.0, dt, &mut f)
            .unwrap();
    }
    let contacts = model.node_contacts();
    assert_eq!(contacts.len(), 2 * 54, "two tips per touching pair");
    for c in contacts {
        let Counterpart::Body(other) = c.counterpart else {
            panic!("no walls here")
        };
        let rel = sub(body_v[c.body as usize], body_v[other as usize]);
        let nrm = scale(c.normal_force, 1.0 / norm(c.normal_force));
        let vt = sub(rel, scale(nrm, common::dot(rel, nrm)));
        let expect = scale(vt, 3.0 * dt);
        assert!(
            norm(sub(c.tangential_displacement, expect)) < 1e-12 * norm(expect),
            "node {}: {:?} vs {expect:?}",
            c.node,
            c.tangential_displacement
        );
        assert!(!c.sliding);
    }
}

#[test]
fn stored_energy_is_half_k_d_squared() {
    let mut r = rng(3);
    let assembly = overlapping_pair(&mut r, 1, 0.01, 5e-5);
    let n = assembly.n_nodes();
    let params = ContactParams::default();
    let mut model = model_for(&assembly, params, vec![], 1e-4, None);
    let mut f = vec![[0.0; 3]; n];
    let report = model
        .add_forces(&assembly.nodes, &vec![[0.0; 3]; n], 0.0, 1e-7, &mut f)
        .unwrap();
    let surface = model.surface();
    let expect: f64 = model
        .node_contacts()
        .iter()
        .map(|c| {
            let k = surface
                .surface_nodes
                .iter()
                .position(|&g| g == c.node)
                .unwrap();
            0.5 * params.normal_penalty * surface.control_areas[k] * c.depth * c.depth
        })
        .sum();
    assert!(expect > 0.0);
    assert!((report.stored_energy - expect).abs() < 1e-12 * expect);
    assert_eq!(report.normal_damping_power, 0.0);
    assert_eq!(report.friction_dissipation, 0.0);
}

#[test]
fn stable_time_step_is_the_smallest_spring_dashpot_bound() {
    let surface = ContactSurface {
        triangles: vec![],
        triangle_body: vec![],
        surface_nodes: vec![0, 1, 2],
        node_body: vec![0, 0, 1],
        control_areas: vec![1e-5, 4e-5, 1e-5],
    };
    let params = ContactParams {
        penalty_ratio: 2.0,
        damping_ratio: 0.5,
        ..ContactParams::default()
    };
    let masses = [1e-3, 1e-3, 3e-3];
    let model = ContactModel::new(params, surface, vec![], &masses, 1e-4).unwrap();
    let s = model.stable_time_step().unwrap();
    // Node 1: k_s = 2 p_n A = 1.44e7 N/m is the larger stiffness, beta_s = 0.1.
    // Its spring also pushes the lightest node of the other body (3e-3 kg): reduced
    // mass 1 / (1 / 1e-3 + 1 / 3e-3) = 7.5e-4 kg.
    assert_eq!((s.node, s.body), (1, 0));
    let k = 2.0 * 1.8e11 * 4e-5;
    let reduced = 7.5e-4;
    assert!((s.mass - reduced).abs() < 1e-15);
    let expect = 2.0 * ((1.0f64 + 0.01).sqrt() - 0.1) / (k / reduced).sqrt();
    assert!((s.time_step - expect).abs() < 1e-14 * expect);
    assert_eq!(s.time_step, spring_dashpot_time_step(k, s.mass, 0.1));
    assert!(s.to_string().contains("surface node 1 (body 0)"), "{s}");

    // Other masses for the bound (a rigid body's effective masses): node 2 heavier, so
    // node 1's counterpart is 1 kg and its reduced mass about its own.
    let mut model = model;
    model.set_bound_masses(&[1e-3, 1e-3, 1.0]).unwrap();
    let s = model.stable_time_step().unwrap();
    assert_eq!(s.node, 1);
    assert!((s.mass - 1.0 / (1e3 + 1.0)).abs() < 1e-15);
    assert!(model.set_bound_masses(&[1e-3, 1e-3]).is_err());
    assert!(model.set_bound_masses(&[1e-3, 0.0, 1.0]).is_err());
}

#[test]
fn stable_time_step_of_a_lone_body_is_its_nodes_against_a_wall() {
    let surface = ContactSurface {
        triangles: vec![],
        triangle_body: vec![],
        surface_nodes: vec![0, 1],
        node_body: vec![0, 0],
        control_areas: vec![1e-5, 1e-5],
    };
    let params = ContactParams::default();
    let model = ContactModel::new(params, surface, vec![], &[2e-3, 1e-3], 1e-4).unwrap();
    let s = model.stable_time_step().unwrap();
    assert_eq!((s.node, s.mass), (1, 1e-3));
}

#[test]
fn tunnelling_guard_fires_on_a_too_large_step() {
    let mut r = rng(11);
    let assembly = overlapping_pair(&mut r, 1, 0.01, 0.0);
    let n = assembly.n_nodes();
    let mut model = model_for(&assembly, ContactParams::default(), vec![], 1e-4, None);
    let margin = model.margin();
    // The bodies fly at each other with 0.3 margin per step each: 0.6 margin relative.
    let centre1: [f64; 3] = assembly.nodes[assembly.bodies[1].nodes.start..]
        .iter()
        .fold([0.0; 3], |s, x| add(s, *x));
    let towards = scale(centre1, -1.0 / norm(centre1));
    let dt = 1e-6;
    let mut v = vec![[0.0; 3]; n];
    for i in assembly.bodies[1].nodes.clone() {
        v[i] = scale(towards, 0.3 * margin / dt);
    }
    for i in assembly.bodies[0].nodes.clone() {
        v[i] = scale(towards, -0.3 * margin / dt);
    }
    let mut f = vec![[0.0; 3]; n];
    let err = model
        .add_forces(&assembly.nodes, &v, 0.0, dt, &mut f)
        .unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, ContactError::Tunnelling { .. }), "{msg}");
    assert!(
        msg.contains("reduce the time step or enlarge the depth limit"),
        "{msg}"
    );
    // The first node in order inside a window of the other body's faces, moving
    // towards that body.
    assert!(
        (msg.contains("(body 0)") && msg.contains("a face of body 1"))
            || (msg.contains("(body 1)") && msg.contains("a face of body 0")),
        "{msg}"
    );
    assert!(f.iter().all(|x| *x == [0.0; 3]), "nothing added on error");
    // A tenth of that speed is fine.
    for vi in &mut v {
        *vi = scale(*vi, 0.1);
    }
    model
        .add_forces(&assembly.nodes, &v, 0.0, dt, &mut f)
        .unwrap();
    // Far faster than any margin: the global bound fires.
    for vi in &mut v {
        *vi = scale(*vi, 100.0);
    }
    let err = model
        .add_forces(&assembly.nodes, &v, 0.0, dt, &mut f)
        .unwrap_err();
    assert!(matches!(err, ContactError::Tunnelling { .. }), "{err}");
}

/// Asserts that `err` is a tunnelling error on `scale`; returns its message.
fn tunnelling_on_scale(err: ContactError, scale: TunnellingScale) -> String {
    let msg = err.to_string();
    assert!(
        matches!(err, ContactError::Tunnelling { scale: s, .. } if s == scale),
        "{msg}"
    );
    msg
}

/// Two bodies of `overlapping_pair` flying at each other, each at `per_step` metres per
/// step of `dt`: the velocities.
fn approach(assembly: &MeshAssembly, per_step: f64, dt: f64) -> Vec<[f64; 3]> {
    let centre1: [f64; 3] = assembly.nodes[assembly.bodies[1].nodes.start..]
        .iter()
        .fold([0.0; 3], |s, x| add(s, *x));
    let towards = scale(centre1, -1.0 / norm(centre1));
    let mut v = vec![[0.0; 3]; assembly.n_nodes()];
    for i in assembly.bodies[1].nodes.clone() {
        v[i] = scale(towards, per_step / dt);
    }
    for i in assembly.bodies[0].nodes.clone() {
        v[i] = scale(towards, -per_step / dt);
    }
    v
}

#[test]
fn tunnelling_reach_is_the_depth_limit_against_solids_and_the_margin_against_sheets() {
    let mut r = rng(11);
    let assembly = overlapping_pair(&mut r, 1, 0.01, 0.0);
    let dt = 1e-6;
    let solid = || {
        let mut model = model_for(&assembly, ContactParams::default(), vec![], 1e-4, None);
        let margin = model.margin();
        model.set_depth_limit(4.0 * margin).unwrap();
        (model, margin)
    };
    let mut f = vec![[0.0; 3]; assembly.n_nodes()];
    // 0.6 margin relative per step: more than half the margin, less than half the depth
    // limit of 4 margins, and less than the depth limit between any two nodes.
    let (mut model, margin) = solid();
    let v = approach(&assembly, 0.3 * margin, dt);
    model
        .add_forces(&assembly.nodes, &v, 0.0, dt, &mut f)
        .unwrap();
    // 2.4 margins relative per step: more than half the depth limit.
    let (mut model, margin) = solid();
    let v = approach(&assembly, 1.2 * margin, dt);
    let err = model
        .add_forces(&assembly.nodes, &v, 0.0, dt, &mut f)
        .unwrap_err();
    let msg = tunnelling_on_scale(err, TunnellingScale::DepthLimit);
    assert!(msg.contains("enlarge the depth limit"), "{msg}");
    // The same 0.6 margin per step against a sheet: refused on the margin's scale.
    let (mut model, margin) = solid();
    model.set_sheet_bodies(&[1], margin).unwrap();
    let v = approach(&assembly, 0.3 * margin, dt);
    let err = model
        .add_forces(&assembly.nodes, &v, 0.0, dt, &mut f)
        .unwrap_err();
    let msg = tunnelling_on_scale(err, TunnellingScale::Margin);
    assert!(
        msg.contains("a face of body 1") && msg.contains("enlarge the contact margin"),
        "{msg}"
    );
}

#[test]
fn a_step_longer_than_the_sheets_listing_depth_is_refused() {
    // A sheet's faces are listed to about its fold depth (or half the margin, if more),
    // not to the depth limit: a node crossing the sheet in one step must land within that
    // depth, where the guard watches the faces. With the fold depth at half a margin, the
    // pair approaching 0.6 margin per step (below the depth limit of 4 margins) is refused
    // on the margin's scale as a step too long for the sheets, and nothing is added; with
    // the fold depth at one margin the same step passes that check and is refused by the
    // faces' own check (test above).
    let assembly = overlapping_pair(&mut rng(11), 1, 0.01, 0.0);
    let dt = 1e-6;
    let sheet_model = |fold_margins: f64| {
        let mut model = model_for(&assembly, ContactParams::default(), vec![], 1e-4, None);
        let margin = model.margin();
        model.set_depth_limit(4.0 * margin).unwrap();
        model.set_sheet_bodies(&[1], fold_margins * margin).unwrap();
        (model, margin)
    };
    let mut f = vec![[0.0; 3]; assembly.n_nodes()];
    let (mut model, margin) = sheet_model(0.5);
    let v = approach(&assembly, 0.3 * margin, dt);
    let err = model
        .add_forces(&assembly.nodes, &v, 0.0, dt, &mut f)
        .unwrap_err();
    let msg = tunnelling_on_scale(err, TunnellingScale::Margin);
    assert!(msg.contains("relative to the sheets"), "{msg}");
    assert!(f.iter().all(|x| *x == [0.0; 3]), "nothing added on error");
    let (mut model, _) = sheet_model(1.0);
    let err = model
        .add_forces(&assembly.nodes, &v, 0.0, dt, &mut f)
        .unwrap_err();
    let msg = tunnelling_on_scale(err, TunnellingScale::Margin);
    assert!(msg.contains("a face of body 1"), "{msg}");
}

#[test]
fn a_node_too_fast_for_the_depth_limit_grows_it_within_its_cap() {
    // The pair of the test above at 2.4 margins relative per step, the depth limit at 4
    // margins (a reach of 2 against solids): with a cap of 10 margins the limit grows to
    // three times the displacement and the forces are those of a model built with that
    // limit; with a cap of 4.4 margins (half of it below the displacement) the step is
    // refused and nothing changes.
    let assembly = overlapping_pair(&mut rng(11), 1, 0.01, 0.0);
    let n = assembly.n_nodes();
    let dt = 1e-6;
    let build = |cap: Option<f64>| {
        let mut model = model_for(&assembly, ContactParams::default(), vec![], 1e-4, None);
        let margin = model.margin();
        model.set_depth_limit(4.0 * margin).unwrap();
        model.set_depth_limit_cap(cap.map(|c| c * margin)).unwrap();
        (model, margin)
    };
    let (_, margin) = build(None);
    let v = approach(&assembly, 1.2 * margin, dt);
    let evaluate = |model: &mut ContactModel| {
        let mut f = vec![[0.0; 3]; n];
        let report = model.add_forces(&assembly.nodes, &v, 0.0, dt, &mut f);
        (report, f)
    };
    let (mut grown, _) = build(Some(10.0));
    let (report, f_grown) = evaluate(&mut grown);
    assert!(report.unwrap().rebuilt);
    let limit = grown.depth_limit();
    assert!(
        (limit - DEPTH_LIMIT_GROWTH * 2.4 * margin).abs() < 0.05 * limit,
        "{limit}"
    );
    let (mut fixed, _) = build(None);
    fixed.set_depth_limit(limit).unwrap();
    let (_, f_fixed) = evaluate(&mut fixed);
    assert_eq!(f_grown, f_fixed);

    let (mut capped, _) = build(Some(4.4));
    let (err, f) = evaluate(&mut capped);
    let msg = tunnelling_on_scale(err.unwrap_err(), TunnellingScale::DepthLimit);
    assert!(msg.contains("enlarge the depth limit"), "{msg}");
    assert!(f.iter().all(|x| *x == [0.0; 3]), "nothing added on error");
    assert_eq!(capped.depth_limit(), 4.0 * margin);
}

#[test]
fn tunnelling_guard_watches_walls() {
    let surface = ContactSurface {
        triangles: vec![],
        triangle_body: vec![],
        surface_nodes: vec![0],
        node_body: vec![0],
        control_areas: vec![1e-5],
    };
    let wall = Wall::plane([0.0; 3], [0.0, 0.0, 1.0]).moving([0.0, 0.0, 30.0]);
    let mut model =
        ContactModel::new(ContactParams::default(), surface, vec![wall], &[1e-3], 1e-4).unwrap();
    let mut f = [[0.0; 3]];
    // The wall moves 30 m/s * 2e-6 s = 0.6 margin per step and is 0.5 margin away.
    let err = model
        .add_forces(&[[0.0, 0.0, 5e-5]], &[[0.0; 3]], 0.0, 2e-6, &mut f)
        .unwrap_err();
    assert!(err.to_string().contains("wall 0"), "{err}");
    // Far from the wall, the same speed is harmless.
    model
        .add_forces(&[[0.0, 0.0, 1.0]], &[[0.0; 3]], 0.0, 2e-6, &mut f)
        .unwrap();
}

#[test]
fn too_deep_penetration_is_an_error_not_a_lost_contact() {
    // A node 0.7 margin deep: detected (the depth limit is the margin), but the next step
    // could carry it beyond the limit, so the model stops.
    let margin = 1e-4;
    let mut r = rng(5);
    let assembly = overlapping_pair(&mut r, 1, 0.01, 0.7 * margin);
    let mut model = model_for(
        &assembly,
        ContactParams::default(),
        vec![],
        1e-4,
        Some(margin),
    );
    let n = assembly.n_nodes();
    let x = assembly.nodes.clone();
    let mut f = vec![[0.0; 3]; n];
    let err = model
        .add_forces(&x, &vec![[0.0; 3]; n], 0.0, 1e-7, &mut f)
        .unwrap_err();
    assert!(
        matches!(err, ContactError::PenetrationTooDeep { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("raise the depth limit"), "{err}");
}

#[test]
fn a_too_deep_contact_grows_the_depth_limit_within_its_cap() {
    // The pair of `too_deep_penetration_is_an_error_not_a_lost_contact`, 0.7 margin deep,
    // with the depth limit at the margin: with a cap of 4 margins the limit grows to three
    // times the deepest contact and the forces are those of a model built with that limit;
    // with a cap of 1.2 margins (half of it below the contact) the step is refused.
    let margin = 1e-4;
    let deep = overlapping_pair(&mut rng(5), 1, 0.01, 0.7 * margin);
    let n = deep.n_nodes();
    let plain = || model_for(&deep, ContactParams::default(), vec![], 1e-4, Some(margin));
    let evaluate = |model: &mut ContactModel| {
        let mut f = vec![[0.0; 3]; n];
        let report = model.add_forces(&deep.nodes, &vec![[0.0; 3]; n], 0.0, 1e-7, &mut f);
        (report, f)
    };
    let mut grown = plain();
    grown.set_depth_limit_cap(Some(4.0 * margin)).unwrap();
    let (report, f_grown) = evaluate(&mut grown);
    let report = report.unwrap();
    assert!(report.rebuilt && report.contacts > 0);
    let limit = grown.depth_limit();
    assert!(
        limit > 2.0 * report.max_depth && limit <= 4.0 * margin,
        "{limit}"
    );
    assert!(
        (limit - DEPTH_LIMIT_GROWTH * 0.7 * margin).abs() < 0.05 * limit,
        "{limit}"
    );
    let mut fixed = plain();
    fixed.set_depth_limit(limit).unwrap();
    let (_, f_fixed) = evaluate(&mut fixed);
    assert_eq!(f_grown, f_fixed);
    // The grown limit is part of the checkpoint.
    let mut restored = plain();
    restored.restore_checkpoint(&grown.checkpoint()).unwrap();
    assert_eq!(restored.depth_limit(), limit);

    let mut capped = plain();
    capped.set_depth_limit_cap(Some(1.2 * margin)).unwrap();
    let (err, f) = evaluate(&mut capped);
    assert!(
        matches!(err, Err(ContactError::PenetrationTooDeep { .. })),
        "{err:?}"
    );
    assert!(f.iter().all(|x| *x == [0.0; 3]), "nothing added on error");
    assert_eq!(capped.depth_limit(), margin);
    for bad in [0.0, f64::NAN] {
        let e = capped.set_depth_limit_cap(Some(bad)).unwrap_err();
        assert!(e.to_string().contains("depth limit cap"), "{e}");
    }
}

#[test]
fn sheet_hits_deeper_than_the_fold_depth_are_discarded_and_counted() {
    // Body 1 declared a sheet: body 0's nodes found behind its faces deeper than the fold
    // depth are discarded (counted, no force); with a fold depth above the penetration
    // they are contacts as usual.
    let margin = 1e-4;
    let pair = overlapping_pair(&mut rng(7), 1, 0.01, 0.3 * margin);
    let n = pair.n_nodes();
    let run = |fold_depth: f64| {
        let mut model = model_for(&pair, ContactParams::default(), vec![], 1e-4, Some(margin));
        model.set_sheet_bodies(&[1], fold_depth).unwrap();
        let mut f = vec![[0.0; 3]; n];
        model
            .add_forces(&pair.nodes, &vec![[0.0; 3]; n], 0.0, 1e-7, &mut f)
            .unwrap()
    };
    let deep = run(0.01 * margin);
    let shallow = run(margin);
    assert!(deep.discarded_sheet_hits > 0, "{deep:?}");
    assert_eq!(shallow.discarded_sheet_hits, 0);
    assert!(shallow.contacts > deep.contacts);
    // Declared after an evaluation, the sheet's rules need new lists: the next evaluation
    // rebuilds them (nothing has moved, so nothing else would).
    let mut late = model_for(&pair, ContactParams::default(), vec![], 1e-4, Some(margin));
    let (v, mut f) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
    late.add_forces(&pair.nodes, &v, 0.0, 1e-7, &mut f).unwrap();
    late.set_sheet_bodies(&[1], 0.01 * margin).unwrap();
    let report = late
        .add_forces(&pair.nodes, &v, 1e-7, 1e-7, &mut f)
        .unwrap();
    assert!(report.rebuilt, "{report:?}");
    let mut model = model_for(&pair, ContactParams::default(), vec![], 1e-4, Some(margin));
    for bad in [0.0, f64::NAN] {
        let e = model.set_sheet_bodies(&[1], bad).unwrap_err().to_string();
        assert!(e.contains("sheet fold depth"), "{e}");
    }
}

#[test]
fn a_raised_depth_limit_keeps_deep_contacts_and_changes_no_shallow_force() {
    // The pair of `too_deep_penetration_is_an_error_not_a_lost_contact`, 0.7 margin deep:
    // refused with the default depth limit (= margin), accepted with a depth limit of 2
    // margins. The candidate boxes grow to `margin + depth_limit` (the detection property
    // test checks the candidate lists against brute force for depth limits of 1-3 margins).
    let margin = 1e-4;
    let plain =
        |a: &MeshAssembly| model_for(a, ContactParams::default(), vec![], 1e-4, Some(margin));
    let mut r = rng(5);
    let deep = overlapping_pair(&mut r, 1, 0.01, 0.7 * margin);
    let mut model = plain(&deep);
    model.set_depth_limit(2.0 * margin).unwrap();
    assert_eq!(model.depth_limit(), 2.0 * margin);
    assert_eq!(model.margin(), margin);
    let n = deep.n_nodes();
    let mut f = vec![[0.0; 3]; n];
    let report = model
        .add_forces(&deep.nodes, &vec![[0.0; 3]; n], 0.0, 1e-7, &mut f)
        .unwrap();
    assert!(report.contacts > 0);
    assert!(report.max_depth > 0.5 * margin && report.max_depth < margin);
    assert!(model.candidate_enlargement() >= 3.0 * margin);
    // A deeper contact than half the new limit is refused again.
    let deeper = overlapping_pair(&mut rng(5), 1, 0.01, 1.2 * margin);
    let mut model = plain(&deeper);
    model.set_depth_limit(2.0 * margin).unwrap();
    let err = model
        .add_forces(&deeper.nodes, &vec![[0.0; 3]; n], 0.0, 1e-7, &mut f)
        .unwrap_err();
    assert!(
        matches!(err, ContactError::PenetrationTooDeep { .. }),
        "{err}"
    );

    // A shallow pair: the same forces, bit for bit, with either depth limit.
    let shallow = overlapping_pair(&mut rng(6), 1, 0.01, 0.2 * margin);
    let forces = |depth_limit: Option<f64>| {
        let mut model = plain(&shallow);
        if let Some(d) = depth_limit {
            model.set_depth_limit(d).unwrap();
        }
        let mut f = vec![[0.0; 3]; n];
        let report = model
            .add_forces(&shallow.nodes, &vec![[0.0; 3]; n], 0.0, 1e-7, &mut f)
            .unwrap();
        (report.contacts, f)
    };
    let (c1, f1) = forces(None);
    let (c3, f3) = forces(Some(3.0 * margin));
    assert!(c1 > 0);
    assert_eq!(c1, c3);
    assert_eq!(f1, f3);

    // Bad depth limits are refused.
    let mut model = plain(&shallow);
    for bad in [0.0, -1e-4, f64::NAN, f64::INFINITY] {
        let e = model.set_depth_limit(bad).unwrap_err().to_string();
        assert!(e.contains("depth limit"), "{e}");
    }
    assert_eq!(
        model.depth_limit(),
        margin,
        "a refused value changes nothing"
    );
}

#[test]
fn evaluations_are_bit_for_bit_repeatable_for_any_thread_count() {
    // Eight spheres in a 2x2x2 lattice, slightly overlapping, random velocities.
    let mesh = linear_sphere(1, 0.01);
    let mut assembly = MeshAssembly::new();
    let mut r = rng(21);
    let spacing = 0.00995;
    for i in 0..8 {
        let t = [(i & 1) as f64, ((i >> 1) & 1) as f64, (i >> 2) as f64].map(|c| c * spacing);
        assembly.push_instance(&mesh, &Placement::at(t)).unwrap();
    }
    let n = assembly.n_nodes();
    let v: Vec<[f64; 3]> = (0..n)
        .map(|_| std::array::from_fn(|_| r.random_range(-0.5..0.5)))
        .collect();
    let base = model_for(
        &assembly,
        ContactParams::default(),
        vec![],
        1e-4,
        Some(2e-4),
    );
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut model = base.clone();
            let mut out = Vec::new();
            for step in 0..3 {
                let mut f = vec![[0.0; 3]; n];
                let report = model
                    .add_forces(&assembly.nodes, &v, step as f64 * 1e-7, 1e-7, &mut f)
                    .unwrap();
                out.push((f, report, model.node_contacts().to_vec()));
            }
            out
        })
    };
    let a = run(1);
    assert!(a[2].1.contacts > 20, "contacts {}", a[2].1.contacts);
    for threads in [1, 2, 3] {
        let b = run(threads);
        for (sa, sb) in a.iter().zip(&b) {
            let fa: Vec<u64> = sa.0.iter().flatten().map(|x| x.to_bits()).collect();
            let fb: Vec<u64> = sb.0.iter().flatten().map(|x| x.to_bits()).collect();
            assert_eq!(fa, fb, "{threads} threads");
            assert_eq!(sa.1, sb.1);
            assert_eq!(sa.2, sb.2);
        }
    }
}

/// `evaluate` then `add_evaluated_forces` is `add_forces` split in two (the engine computes
/// the element forces between them): the same forces, reports and histories to the bit,
/// with other forces already in the array; forces without a waiting evaluation, or after a
/// failed one, are refused and add nothing.
#[test]
fn an_evaluation_split_in_two_adds_the_same_forces() {
    let mut r = rng(5);
    let assembly = overlapping_pair(&mut r, 1, 0.01, 5e-5);
    let n = assembly.n_nodes();
    let v: Vec<[f64; 3]> = (0..n)
        .map(|_| std::array::from_fn(|_| r.random_range(-0.5..0.5)))
        .collect();
    let params = ContactParams {
        friction: 0.3,
        ..ContactParams::default()
    };
    let mut whole = model_for(&assembly, params, vec![], 1e-4, None);
    let mut split = whole.clone();
    // Forces already in the array (the elements' in the engine).
    let others: Vec<[f64; 3]> = (0..n)
        .map(|_| std::array::from_fn(|_| r.random_range(-1.0..1.0)))
        .collect();
    for step in 0..3 {
        let t = step as f64 * 1e-7;
        let mut fa = others.clone();
        let ra = whole
            .add_forces(&assembly.nodes, &v, t, 1e-7, &mut fa)
            .unwrap();
        let mut fb = others.clone();
        split.evaluate(&assembly.nodes, &v, t, 1e-7).unwrap();
        let rb = split.add_evaluated_forces(&mut fb).unwrap();
        let bits =
            |f: &[[f64; 3]]| -> Vec<u64> { f.iter().flatten().map(|x| x.to_bits()).collect() };
        assert_eq!(bits(&fa), bits(&fb), "step {step}");
        assert_eq!(ra, rb);
        assert_eq!(whole.node_contacts(), split.node_contacts());
    }
    assert!(!whole.node_contacts().is_empty());
    // No evaluation waits: refused, the array untouched.
    let mut f = others.clone();
    let err = split.add_evaluated_forces(&mut f).unwrap_err();
    assert!(matches!(err, ContactError::NotEvaluated), "{err}");
    assert!(err.to_string().contains("ContactModel::evaluate"), "{err}");
    assert_eq!(f, others);
    // A failed evaluation (a non-finite position) leaves nothing to add.
    let mut bad = assembly.nodes.clone();
    bad[0][0] = f64::NAN;
    assert!(split.evaluate(&bad, &v, 4e-7, 1e-7).is_err());
    let err = split.add_evaluated_forces(&mut f).unwrap_err();
    assert!(matches!(err, ContactError::NotEvaluated), "{err}");
    assert_eq!(f, others);
}

#[test]
fn set_up_and_input_errors_say_what_and_where() {
    let surface = ContactSurface {
        triangles: vec![[0, 1, 2]],
        triangle_body: vec![0],
        surface_nodes: vec![0, 1, 2, 3],
        node_body: vec![0, 0, 0, 1],
        control_areas: vec![1e-4, 1e-4, 1e-4, 1e-5],
    };
    let p = ContactParams::default();
    let masses = [1e-3; 4];
    let new = |s: ContactSurface, m: &[f64], margin: f64, walls: Vec<Wall>| {
        ContactModel::new(p, s, walls, m, margin)
            .map(|_| ())
            .unwrap_err()
            .to_string()
    };
    let mut s = surface.clone();
    s.control_areas[3] = 0.0;
    assert!(new(s, &masses, 1e-4, vec![]).contains("surface node 3 (body 1)"));
    let msg = new(surface.clone(), &[1e-3, 1e-3, -1.0, 1e-3], 1e-4, vec![]);
    assert!(
        msg.contains("node 2 (body 0)") && msg.contains("mass"),
        "{msg}"
    );
    let msg = new(surface.clone(), &masses[..3], 1e-4, vec![]);
    assert!(msg.contains("refers to node 3"), "{msg}");
    assert!(new(surface.clone(), &masses, 0.0, vec![]).contains("margin"));
    let mut s = surface.clone();
    s.node_body[1] = 1;
    let msg = new(s, &masses, 1e-4, vec![]);
    assert!(
        msg.contains("triangle 0") && msg.contains("bodies must not share"),
        "{msg}"
    );
    let msg = new(
        surface.clone(),
        &masses,
        1e-4,
        vec![Wall::plane([0.0; 3], [0.0; 3])],
    );
    assert!(
        msg.contains("wall 0") && msg.contains("plane normal"),
        "{msg}"
    );
    let msg = new(
        surface.clone(),
        &masses,
        1e-4,
        vec![Wall::cylinder([0.0; 3], [0.0, 0.0, 1.0], -1.0)],
    );
    assert!(msg.contains("radius"), "{msg}");

    let mut model = ContactModel::new(p, surface, vec![], &masses, 1e-4).unwrap();
    let mut x = vec![
        [0.0, 0.0, 0.0],
        [1e-2, 0.0, 0.0],
        [0.0, 1e-2, 0.0],
        [1e-3, 1e-3, 1e-3],
    ];
    let v = vec![[0.0; 3]; 4];
    let mut f = vec![[0.0; 3]; 4];
    let msg = model
        .add_forces(&x[..3], &v, 0.0, 1e-7, &mut f)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("`positions` has 3 entries but 4"), "{msg}");
    let msg = model
        .add_forces(&x, &v, 0.0, 0.0, &mut f)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("dt"), "{msg}");
    x[3][1] = f64::NAN;
    let msg = model
        .add_forces(&x, &v, 0.0, 1e-7, &mut f)
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("position of surface node 3 (body 1)") && msg.contains("reduce the time step"),
        "{msg}"
    );
}

/// A servo changes a platen's velocity mid-run: the position stays continuous and moves
/// with the new velocity afterwards; bad indices and velocities are refused.
#[test]
fn wall_velocity_changes_keep_the_position_continuous() {
    let assembly = {
        let mut a = MeshAssembly::new();
        a.push_instance(&linear_sphere(1, 0.01), &Placement::default())
            .unwrap();
        a
    };
    let top = Wall::plane([0.0, 0.0, 0.02], [0.0, 0.0, -1.0]).moving([0.0, 0.0, -0.5]);
    let mut model = model_for(&assembly, ContactParams::default(), vec![top], 1e-4, None);
    let z = |m: &ContactModel, t: f64| match m.walls()[0].shape_at(t) {
        fdem_contact::WallShape::Plane { point, .. } => point[2],
        _ => unreachable!(),
    };
    let before = z(&model, 0.01);
    assert!((before - (0.02 - 0.005)).abs() < 1e-15);
    model.set_wall_velocity(0, [0.0, 0.0, 0.25], 0.01).unwrap();
    assert!((z(&model, 0.01) - before).abs() < 1e-15);
    assert!((z(&model, 0.03) - (before + 0.25 * 0.02)).abs() < 1e-15);
    assert!(matches!(
        model.set_wall_velocity(1, [0.0; 3], 0.0),
        Err(ContactError::InvalidWall { wall: 1, .. })
    ));
    assert!(
        model
            .set_wall_velocity(0, [f64::NAN, 0.0, 0.0], 0.0)
            .is_err()
    );
}
