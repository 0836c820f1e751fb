//! The contact law (paper eqs 1-3) at the level of one node: normal penalty, clamping,
//! friction threshold and cut-back, history rotation, and one node against one face.

mod common;

use common::{add, cross, dot, norm, scale, sub};
use fdem_contact::{
    ContactModel, ContactParams, ContactSurface, Counterpart, LawInput, NodeCoefficients,
    evaluate_law,
};

fn coefficients() -> NodeCoefficients {
    ContactParams::default().coefficients(2.0e-5, 3.0e-4)
}

fn input(normal: [f64; 3], depth: f64, v: [f64; 3]) -> LawInput {
    LawInput {
        normal,
        depth,
        relative_velocity: v,
        dt: 1e-7,
        coefficients: coefficients(),
    }
}

#[test]
fn coefficients_follow_eqs_2_and_3() {
    let p = ContactParams {
        penalty_ratio: 0.5,
        damping_ratio: 0.4,
        ..ContactParams::default()
    };
    let (area, mass) = (2.0e-5, 3.0e-4);
    let c = p.coefficients(area, mass);
    let k_n = 1.8e11 * area;
    assert_eq!(c.normal_stiffness, k_n);
    assert_eq!(c.tangential_stiffness, 0.5 * k_n);
    assert!((c.normal_damping - 2.0 * 0.2 * (mass * k_n).sqrt()).abs() < 1e-14 * c.normal_damping);
    assert!(
        (c.tangential_damping - 2.0 * 0.08 * (mass * 0.5 * k_n).sqrt()).abs()
            < 1e-14 * c.tangential_damping
    );
}

#[test]
fn params_validation_names_the_field() {
    let bad = ContactParams {
        friction: -0.1,
        ..ContactParams::default()
    };
    let err = bad.validate().unwrap_err().to_string();
    assert!(err.contains("`friction`"), "{err}");
    assert!(err.contains(">= 0"), "{err}");
    let bad = ContactParams {
        normal_penalty: 0.0,
        ..ContactParams::default()
    };
    assert!(
        bad.validate()
            .unwrap_err()
            .to_string()
            .contains("`normal_penalty`")
    );
    assert!(ContactParams::default().validate().is_ok());
    // Serde: a JSON round trip keeps every field; unknown fields are rejected.
    let json = serde_json::to_string(&ContactParams::default()).unwrap();
    let back: ContactParams = serde_json::from_str(&json).unwrap();
    assert_eq!(back, ContactParams::default());
    let typo = json.replace("friction", "fricton");
    assert!(serde_json::from_str::<ContactParams>(&typo).is_err());
}

#[test]
fn static_normal_force_is_penalty_times_depth() {
    // No velocity: F_n = k_n d_n exactly (eq 1 without damping).
    let c = coefficients();
    let d = 3.7e-6;
    let out = evaluate_law(&input([0.0, 0.0, 1.0], d, [0.0; 3]), &mut [0.0; 3]);
    assert_eq!(out.normal_force, [0.0, 0.0, c.normal_stiffness * d]);
    assert_eq!(out.tangential_force, [0.0; 3]);
    assert_eq!(out.stored_energy, 0.5 * c.normal_stiffness * d * d);
}

#[test]
fn approaching_contact_adds_viscous_force() {
    // v_approach = 0.2 m/s into the face: F_n = k d + c_n v (eq 3), damping power c v^2.
    let c = coefficients();
    let d = 1e-6;
    let out = evaluate_law(&input([0.0, 0.0, 1.0], d, [0.0, 0.0, -0.2]), &mut [0.0; 3]);
    let expect = c.normal_stiffness * d + c.normal_damping * 0.2;
    assert!((out.normal_magnitude - expect).abs() < 1e-12 * expect);
    let p = c.normal_damping * 0.04;
    assert!((out.normal_damping_power - p).abs() < 1e-12 * p);
}

#[test]
fn separating_fast_never_attracts() {
    // k d + c v_approach < 0: the paper's |k d - f| would push; we release (F_n = 0).
    let c = coefficients();
    let d = 1e-7;
    let v_sep = 10.0 * c.normal_stiffness * d / c.normal_damping;
    let mut h = [1e-7, 0.0, 0.0];
    let out = evaluate_law(&input([0.0, 0.0, 1.0], d, [0.0, 0.0, v_sep]), &mut h);
    assert_eq!(out.normal_magnitude, 0.0);
    assert_eq!(out.normal_force, [0.0, 0.0, 0.0]);
    // No normal force, no friction: the history is cut back to zero.
    assert_eq!(out.tangential_force, [0.0; 3]);
    assert_eq!(h, [0.0; 3]);
    // The clamp dissipates the spring power it removes: -k d v_approach > 0.
    let p = c.normal_stiffness * d * v_sep;
    assert!((out.normal_damping_power - p).abs() < 1e-12 * p);
    for v in [0.0, 1e-3, 1.0, 1e3] {
        let out = evaluate_law(&input([0.0, 0.0, 1.0], d, [0.0, 0.0, v]), &mut [0.0; 3]);
        assert!(out.normal_magnitude >= 0.0);
    }
}

#[test]
fn tangential_sticks_below_coulomb_limit() {
    let c = coefficients();
    let d = 2e-6;
    let f_n = c.normal_stiffness * d;
    let limit = c.friction * f_n / c.tangential_stiffness;
    let mut h = [0.6 * limit, 0.0, 0.0];
    let out = evaluate_law(&input([0.0, 0.0, 1.0], d, [0.0; 3]), &mut h);
    assert!(!out.sliding);
    assert_eq!(
        out.tangential_force,
        [-c.tangential_stiffness * 0.6 * limit, 0.0, 0.0]
    );
    assert_eq!(h, [0.6 * limit, 0.0, 0.0]);
    assert_eq!(out.friction_dissipation, 0.0);
}

#[test]
fn sliding_cuts_back_to_exactly_mu_fn() {
    let c = coefficients();
    let d = 2e-6;
    let f_n = c.normal_stiffness * d;
    let limit = c.friction * f_n / c.tangential_stiffness;
    let before = [3.0 * limit, 4.0 * limit, 0.0]; // |d_s| = 5 limit
    let mut h = before;
    let out = evaluate_law(&input([0.0, 0.0, 1.0], d, [0.0; 3]), &mut h);
    assert!(out.sliding);
    let mu_fn = c.friction * f_n;
    assert!((norm(out.tangential_force) - mu_fn).abs() < 1e-12 * mu_fn);
    assert!((c.tangential_stiffness * norm(h) - mu_fn).abs() < 1e-12 * mu_fn);
    // The cut-back keeps the direction of d_s and the force opposes it.
    assert!((h[0] / h[1] - 0.75).abs() < 1e-12);
    assert!(dot(out.tangential_force, h) < 0.0);
    // Dissipated: the capped spring force times the slip cut away,
    // k_s d_s . (d_trial - d_s) = k_s |d_s| (|d_trial| - |d_s|) = k_s limit (5 - 1) limit.
    let diss = c.tangential_stiffness * 4.0 * limit * limit;
    assert!((out.friction_dissipation - diss).abs() < 1e-12 * diss);
}

#[test]
fn friction_threshold_separates_stick_from_slip() {
    // Slide the node by L in one step (d_s = L, no dashpot): the trial force k_s L sticks
    // below mu F_n and is capped at mu F_n above, with d_s cut back to mu F_n / k_s.
    let c = coefficients();
    let d = 2e-6;
    let mu_fn = c.friction * c.normal_stiffness * d;
    for ratio in [0.25, 0.9, 0.999, 1.001, 1.5, 10.0] {
        let length = ratio * mu_fn / c.tangential_stiffness;
        let mut h = [0.0; 3];
        let dt = 1e-7;
        let mut inp = input([0.0, 0.0, 1.0], d, [0.0, length / dt, 0.0]);
        inp.coefficients.tangential_damping = 0.0;
        let out = evaluate_law(&inp, &mut h);
        let f = norm(out.tangential_force);
        if ratio < 1.0 {
            assert!(!out.sliding, "ratio {ratio}");
            assert!((f - ratio * mu_fn).abs() < 1e-9 * mu_fn, "ratio {ratio}");
            assert!((h[1] - length).abs() < 1e-9 * length);
        } else {
            assert!(out.sliding, "ratio {ratio}");
            assert!((f - mu_fn).abs() < 1e-12 * mu_fn, "ratio {ratio}");
            assert!((c.tangential_stiffness * h[1] - mu_fn).abs() < 1e-12 * mu_fn);
        }
        assert!(out.tangential_force[1] < 0.0, "opposes the motion");
    }
}

#[test]
fn history_rotates_with_the_tangent_plane() {
    let c = coefficients();
    let d = 2e-6;
    let limit = c.friction * c.normal_stiffness * d / c.tangential_stiffness;
    let h0 = [0.3 * limit, 0.2 * limit, 0.0];
    for theta in [0.05_f64, 0.3, 1.0] {
        // Normal tilted by theta about the x axis.
        let n = [0.0, -theta.sin(), theta.cos()];
        let mut h = h0;
        let out = evaluate_law(&input(n, d, [0.0; 3]), &mut h);
        assert!(
            dot(h, n).abs() < 1e-15 * limit,
            "history in the tangent plane"
        );
        assert!((norm(h) - norm(h0)).abs() < 1e-14 * norm(h0), "length kept");
        // Rotated, not just projected: the direction is the projection's.
        let proj = sub(h0, scale(n, dot(h0, n)));
        assert!(norm(cross(h, proj)) < 1e-14 * norm(h) * norm(proj));
        assert!(dot(out.tangential_force, n).abs() < 1e-12 * norm(out.tangential_force));
    }
}

/// One triangle (body 0) in the plane z = 0, one node (body 1) below it.
fn face_and_node(node: [f64; 3]) -> (ContactSurface, Vec<[f64; 3]>) {
    let surface = ContactSurface {
        triangles: vec![[0, 1, 2]],
        triangle_body: vec![0],
        surface_nodes: vec![0, 1, 2, 3],
        node_body: vec![0, 0, 0, 1],
        control_areas: vec![1e-4, 1e-4, 1e-4, 2.5e-5],
    };
    let positions = vec![[0.0, 0.0, 0.0], [1e-2, 0.0, 0.0], [0.0, 1e-2, 0.0], node];
    (surface, positions)
}

#[test]
fn node_pressed_into_face_gets_pn_a_d_and_face_gets_the_reaction() {
    let d = 1.25e-6;
    let (surface, x) = face_and_node([2e-3, 3e-3, -d]);
    let params = ContactParams::default();
    let mut model = ContactModel::new(params, surface, vec![], &[1e-4; 4], 1e-4).unwrap();
    let v = vec![[0.0; 3]; 4];
    let mut f = vec![[0.0; 3]; 4];
    let report = model.add_forces(&x, &v, 0.0, 1e-7, &mut f).unwrap();
    assert_eq!(report.contacts, 1);
    let expect = params.normal_penalty * 2.5e-5 * d;
    // Exact up to the round-off of the depth (1e-14 relative).
    assert!(
        (f[3][2] - expect).abs() < 1e-14 * expect,
        "{} vs {expect}",
        f[3][2]
    );
    assert_eq!([f[3][0], f[3][1]], [0.0, 0.0]);
    // Barycentric weights of (2 mm, 3 mm): (0.5, 0.2, 0.3).
    for (i, w) in [0.5, 0.2, 0.3].into_iter().enumerate() {
        assert!((f[i][2] + w * expect).abs() < 1e-14 * expect, "node {i}");
    }
    let c = &model.node_contacts()[0];
    assert_eq!(
        (c.node, c.body, c.counterpart, c.face),
        (3, 1, Counterpart::Body(0), Some(0))
    );
    assert!((c.contact_point[0] - 2e-3).abs() < 1e-15 && c.contact_point[2].abs() < 1e-15);
    let e = 0.5 * expect * d;
    assert!((model.stored_energy() - e).abs() < 1e-13 * e);
}

#[test]
fn node_in_front_of_or_beside_the_face_is_free() {
    for node in [[2e-3, 3e-3, 1e-6], [2e-2, 3e-3, -1e-6], [2e-3, 3e-3, -1e-3]] {
        let (surface, x) = face_and_node(node);
        let mut model =
            ContactModel::new(ContactParams::default(), surface, vec![], &[1e-4; 4], 1e-4).unwrap();
        let mut f = vec![[0.0; 3]; 4];
        let r = model.add_forces(&x, &[[0.0; 3]; 4], 0.0, 1e-7, &mut f);
        // In front or outside the triangle: no contact; 1 mm deep with a 0.1 mm limit:
        // beyond the depth limit, so no contact either.
        assert_eq!(r.unwrap().contacts, 0, "{node:?}");
        assert!(f.iter().all(|v| *v == [0.0; 3]));
    }
}

#[test]
fn tangential_history_accumulates_across_evaluations() {
    // The node slides along x at 1 mm/s under a face: d_s grows by v dt per step while
    // sticking, and the model keeps it between evaluations.
    let d = 2e-6;
    let (surface, x) = face_and_node([2e-3, 3e-3, -d]);
    let params = ContactParams {
        damping: 0.0,
        ..ContactParams::default()
    };
    let mut model = ContactModel::new(params, surface, vec![], &[1e-4; 4], 1e-4).unwrap();
    let mut v = vec![[0.0; 3]; 4];
    v[3] = [1e-3, 0.0, 0.0];
    let dt = 1e-7;
    for step in 1..=3 {
        let mut f = vec![[0.0; 3]; 4];
        model.add_forces(&x, &v, 0.0, dt, &mut f).unwrap();
        let c = &model.node_contacts()[0];
        let expect = step as f64 * 1e-3 * dt;
        assert!((c.tangential_displacement[0] - expect).abs() < 1e-12 * expect);
        let k_s = params.normal_penalty * 2.5e-5;
        assert!((f[3][0] + k_s * expect).abs() < 1e-12 * k_s * expect);
        // Equal and opposite on the face.
        let sum = add(add(add(f[0], f[1]), f[2]), f[3]);
        assert!(norm(sum) < 1e-15 * norm(f[3]));
    }
    // Lift the node out: the contact opens and the history is dropped.
    let mut x2 = x.clone();
    x2[3][2] = 1e-6;
    let mut f = vec![[0.0; 3]; 4];
    model.add_forces(&x2, &v, 0.0, dt, &mut f).unwrap();
    assert!(model.node_contacts().is_empty());
    model.add_forces(&x, &v, 0.0, dt, &mut f).unwrap();
    let c = &model.node_contacts()[0];
    assert!((c.tangential_displacement[0] - 1e-3 * dt).abs() < 1e-12 * 1e-3 * dt);
}
