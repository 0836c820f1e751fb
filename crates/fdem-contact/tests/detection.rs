//! Detection: the broad phase against brute force (with and without a Verlet rebuild), and
//! the two narrow-phase kernels against each other.

mod common;

use std::collections::BTreeSet;

use common::{add, cross, dot, linear_sphere, model_for, random_rotation, rng, scale, sub};
use fdem_contact::narrow::{project_hand, project_parry};
use fdem_contact::{BARYCENTRIC_TOLERANCE, ContactModel, ContactParams, RefreshPolicy};
use fdem_mesh::{MeshAssembly, Placement};
use proptest::prelude::*;
use rand::RngExt;

/// Distance from `p` to a triangle, written independently of the library's: the plane
/// distance when the foot falls inside, else the nearest of the three edges (segments).
fn distance_to_triangle(p: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> f64 {
    let n = cross(sub(b, a), sub(c, a));
    let nn = dot(n, n);
    let ap = sub(p, a);
    let wb = dot(cross(ap, sub(c, a)), n) / nn;
    let wc = dot(cross(sub(b, a), ap), n) / nn;
    if wb >= 0.0 && wc >= 0.0 && wb + wc <= 1.0 {
        return dot(ap, n).abs() / nn.sqrt();
    }
    let segment = |u: [f64; 3], v: [f64; 3]| {
        let uv = sub(v, u);
        let s = (dot(sub(p, u), uv) / dot(uv, uv)).clamp(0.0, 1.0);
        let q = add(u, scale(uv, s));
        dot(sub(p, q), sub(p, q)).sqrt()
    };
    segment(a, b).min(segment(b, c)).min(segment(c, a))
}

/// Every (surface node, other body's triangle) pair, brute force over all pairs, for which
/// `keep(node position, triangle corners)` holds.
fn pairs_where(
    assembly: &MeshAssembly,
    x: &[[f64; 3]],
    keep: impl Fn([f64; 3], [[f64; 3]; 3]) -> bool,
) -> BTreeSet<(usize, usize)> {
    let mut out = BTreeSet::new();
    for (b, range) in assembly.bodies.iter().enumerate() {
        for &node in &assembly.surface_nodes[range.surface_nodes.clone()] {
            for (t, tri) in assembly.triangles.iter().enumerate() {
                if assembly.triangle_body[t] as usize != b && keep(x[node], tri.map(|i| x[i])) {
                    out.insert((node, t));
                }
            }
        }
    }
    out
}

/// Pairs within `e` of each other where the node is behind the triangle's plane or within
/// `front` of the triangle.
fn brute_force(
    assembly: &MeshAssembly,
    x: &[[f64; 3]],
    (e, front): (f64, f64),
    window: (f64, &dyn Fn([[f64; 3]; 3]) -> f64),
) -> BTreeSet<(usize, usize)> {
    let (depth_limit, reach) = window;
    pairs_where(assembly, x, |p, [a, b, c]| {
        let d = distance_to_triangle(p, [a, b, c]);
        let n = cross(sub(b, a), sub(c, a));
        let signed = dot(n, sub(p, a)) / dot(n, n).sqrt();
        if signed >= 0.0 {
            return d <= e && d <= front;
        }
        // Behind: within the reach of the window (the prism over the face, the depth
        // limit deep): the foot's distance from the face and the depth beyond the limit.
        let lateral2 = (d * d - signed * signed).max(0.0);
        let beyond = (-signed - depth_limit).max(0.0);
        let r = reach([a, b, c]);
        d <= e && lateral2 + beyond * beyond <= r * r
    })
}

/// Pairs where the node is behind the triangle's plane by at most `depth` with its foot
/// inside the triangle (a face contact the narrow phase can report).
fn contact_capable(
    assembly: &MeshAssembly,
    x: &[[f64; 3]],
    depth: f64,
) -> BTreeSet<(usize, usize)> {
    pairs_where(assembly, x, |p, [a, b, c]| {
        let n = cross(sub(b, a), sub(c, a));
        let nn = dot(n, n);
        let ap = sub(p, a);
        let wb = dot(cross(ap, sub(c, a)), n) / nn;
        let wc = dot(cross(sub(b, a), ap), n) / nn;
        let signed = dot(ap, n) / nn.sqrt();
        wb >= 0.0 && wc >= 0.0 && wb + wc <= 1.0 && signed < 0.0 && -signed <= depth
    })
}

/// A cluster of `n` spheres of diameter `d`: each new one is placed next to a random
/// earlier one with a gap (between the polyhedra) drawn from `gap`, and kept only if it
/// keeps at least `gap.start` from every other sphere.
fn scene(seed: u64, n: usize, level: u32, d: f64, gap: std::ops::Range<f64>) -> MeshAssembly {
    let mut r = rng(seed);
    let mesh = linear_sphere(level, d);
    let mut placed = vec![Placement {
        scale: 1.0,
        rotation: random_rotation(&mut r),
        translation: [0.0; 3],
    }];
    let mut tries = 0;
    while placed.len() < n && tries < 200 {
        tries += 1;
        let anchor = placed[r.random_range(0..placed.len())];
        let g = r.random_range(gap.clone());
        let p = common::place_near(&mut r, &mesh, d, &anchor, -g);
        if placed.iter().all(|o| {
            common::norm(common::sub(o.translation, p.translation)) > 1.05 * d
                || common::max_penetration(&common::pair_of(&mesh, o, &p)) <= -gap.start
        }) {
            placed.push(p);
        }
    }
    let mut assembly = MeshAssembly::new();
    for p in &placed {
        assembly.push_instance(&mesh, p).unwrap();
    }
    assembly
}

fn evaluate(model: &mut ContactModel, x: &[[f64; 3]]) -> fdem_contact::ContactReport {
    let n = x.len();
    let mut f = vec![[0.0; 3]; n];
    model
        .add_forces(x, &vec![[0.0; 3]; n], 0.0, 1e-7, &mut f)
        .unwrap()
}

/// A refresh policy that refreshes any body past the allowance, however many.
fn refresh_any_body_that_drifted(model: &mut ContactModel) {
    let policy = RefreshPolicy {
        near: 1.0,
        max_fraction: 1.0,
        max_refreshed_fraction: 1.0,
    };
    model.set_refresh_policy(policy).unwrap();
}

/// A cluster of `n` spheres of 10 mm (`scene`) whose surfaces start 1 to 1.9 margins apart
/// (`margin_fraction` of the diameter), and its contact model with a depth limit of
/// `depth_factor` margins. Every motion of the property tests stays contact-free or
/// shallow, and each new sphere is nearer to its anchor than the boxes' enlargement (at
/// least 2 margins), so neighbours are always candidates (with gaps up to 3 margins a lone
/// pair 2.5 margins apart had none: seed 173242).
fn cluster(
    seed: u64,
    n: usize,
    level: u32,
    margin_fraction: f64,
    depth_factor: f64,
) -> (MeshAssembly, ContactModel) {
    let d = 0.01;
    let margin = margin_fraction * d;
    let assembly = scene(seed, n, level, d, margin..1.9 * margin);
    let mut model = model_for(
        &assembly,
        ContactParams::default(),
        vec![],
        1e-4,
        Some(margin),
    );
    model.set_depth_limit(depth_factor * margin).unwrap();
    (assembly, model)
}

fn evaluate_at(model: &mut ContactModel, x: &[[f64; 3]], t: f64) -> fdem_contact::ContactReport {
    let n = x.len();
    let mut f = vec![[0.0; 3]; n];
    model
        .add_forces(x, &vec![[0.0; 3]; n], t, 1e-7, &mut f)
        .unwrap()
}

/// `origin + (I + t rate) (x - origin)`.
fn mapped(origin: [f64; 3], rate: [[f64; 3]; 3], t: f64, x: [f64; 3]) -> [f64; 3] {
    let d = sub(x, origin);
    std::array::from_fn(|i| origin[i] + d[i] + t * dot(rate[i], d))
}

/// The drift allowance of `fdem_contact::mean_motion`, written out here: half the margin
/// less `2 g / (1 - g)` times the refresh's reaches, `g = |t rate|` (Frobenius).
fn allowance(model: &ContactModel, rate: [[f64; 3]; 3], t: f64) -> f64 {
    let g = t * rate.iter().flatten().map(|r| r * r).sum::<f64>().sqrt();
    let (e, front) = model.candidate_refresh_reaches();
    0.5 * model.margin() - 2.0 * g / (1.0 - g) * (e + front)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn broad_phase_equals_brute_force(
        seed in 0u64..1_000_000,
        n in 2usize..7,
        level in 0u32..2,
        margin_fraction in 0.01f64..0.05,
        depth_factor in 1.0f64..3.0,
    ) {
        // The depth limit varies from 1 to 3 margins; the boxes grow to margin + depth
        // limit.
        let (assembly, mut model) = cluster(seed, n, level, margin_fraction, depth_factor);
        let (margin, depth_limit) = (model.margin(), model.depth_limit());
        let x0 = assembly.nodes.clone();
        let report = evaluate(&mut model, &x0);
        prop_assert!(report.rebuilt);
        let e = model.candidate_enlargement();
        let reach = margin + depth_limit;
        prop_assert!(e >= reach && e < reach * 1.001);
        let got: Vec<(usize, usize)> = model.candidate_pairs();
        let set: BTreeSet<_> = got.iter().copied().collect();
        prop_assert_eq!(set.len(), got.len(), "no duplicates");
        prop_assert!(assembly.n_bodies() < 2 || !got.is_empty(), "neighbours give candidates");
        let front = model.candidate_front_reach();
        prop_assert!(front >= 2.0 * margin && front < 2.0 * margin + (e - reach) * 1.001);
        let window = |f: [[f64; 3]; 3]| model.candidate_window_reaches(f).0;
        prop_assert_eq!(&set, &brute_force(&assembly, &x0, (e, front), (depth_limit, &window)));

        // Small motion: every node moves less than margin / 2, no rebuild; the candidate
        // lists still hold every pair that can be in contact now: the node behind the
        // current triangle's plane, its foot inside the triangle, within the depth limit.
        let mut r = rng(seed ^ 0x5eed);
        let x1: Vec<[f64; 3]> = x0
            .iter()
            .map(|&p| {
                let u = common::random_unit(&mut r);
                add(p, scale(u, r.random_range(0.0..0.49) * margin))
            })
            .collect();
        let report = evaluate(&mut model, &x1);
        prop_assert!(!report.rebuilt);
        prop_assert_eq!(model.candidate_pairs(), got.clone());
        let needed = contact_capable(&assembly, &x1, depth_limit);
        prop_assert!(needed.is_subset(&set), "a contact-capable pair is missing");

        // One body moves rigidly by 0.6 margin; under a policy that refreshes any body
        // that drifted past half the margin, only its pairs are renewed: the pairs without
        // it are kept, and those with it (its nodes, its faces) equal brute force at the
        // new positions with the refresh's reaches.
        refresh_any_body_that_drifted(&mut model);
        let mover = seed as usize % assembly.n_bodies();
        let shift = scale(common::random_unit(&mut r), 0.6 * margin);
        let mut x2 = x1.clone();
        for i in assembly.bodies[mover].nodes.clone() {
            x2[i] = add(x2[i], shift);
        }
        let report = evaluate(&mut model, &x2);
        prop_assert!(!report.rebuilt);
        prop_assert_eq!(report.refreshed_bodies, 1);
        let set2: BTreeSet<_> = model.candidate_pairs().into_iter().collect();
        let involves = |&(node, t): &(usize, usize)| {
            assembly.bodies[mover].nodes.contains(&node)
                || assembly.triangle_body[t] as usize == mover
        };
        let (e, front) = model.candidate_refresh_reaches();
        let mut expect: BTreeSet<_> = set.iter().copied().filter(|p| !involves(p)).collect();
        let window = |f: [[f64; 3]; 3]| model.candidate_window_reaches(f).1;
        expect.extend(
            brute_force(&assembly, &x2, (e, front), (depth_limit, &window))
                .into_iter()
                .filter(|p| involves(p)),
        );
        prop_assert!(contact_capable(&assembly, &x2, depth_limit).is_subset(&set2));
        prop_assert_eq!(set2, expect);
    }

    #[test]
    fn a_mean_motion_keeps_every_contact_capable_pair_listed(
        seed in 0u64..1_000_000,
        n in 2usize..7,
        level in 0u32..2,
        margin_fraction in 0.01f64..0.05,
        depth_factor in 1.5f64..3.0,
        distortion in 0.001f64..0.003,
    ) {
        // A cluster deformed by a uniform map (a random gradient rate, a few per mille)
        // moves its nodes by several margins, and each node drifts by up to the allowance
        // beyond it: the lists are kept and hold every pair that can be in contact.
        let (assembly, mut model) = cluster(seed, n, level, margin_fraction, depth_factor);
        let margin = model.margin();
        let mut r = rng(seed ^ 0xa11);
        let mut rate = [[0.0; 3]; 3];
        for row in &mut rate {
            for v in row.iter_mut() {
                *v = r.random_range(-1.0..1.0);
            }
        }
        let norm = rate.iter().flatten().map(|v| v * v).sum::<f64>().sqrt();
        let t = distortion / norm;
        let x0 = assembly.nodes.clone();
        // The fixed point 0.3 m off the cluster: the map moves every node by much more
        // than its allowance.
        let corner = x0.iter().fold([f64::INFINITY; 3], |o, p| std::array::from_fn(|i| o[i].min(p[i])));
        let origin = corner.map(|c| c - 0.3);
        model.set_mean_motion(origin, rate, 0.0).unwrap();
        prop_assert!(evaluate_at(&mut model, &x0, 0.0).rebuilt);
        let got: BTreeSet<_> = model.candidate_pairs().into_iter().collect();
        let rho = allowance(&model, rate, t);
        prop_assume!(rho > 0.25 * margin);
        let x1: Vec<[f64; 3]> = x0
            .iter()
            .map(|&p| {
                let u = common::random_unit(&mut r);
                add(mapped(origin, rate, t, p), scale(u, r.random_range(0.0..0.98) * rho))
            })
            .collect();
        let report = evaluate_at(&mut model, &x1, t);
        prop_assert!(!report.rebuilt && report.refreshed_bodies == 0);
        prop_assert!(contact_capable(&assembly, &x1, model.depth_limit()).is_subset(&got));

        // One body drifts past the allowance: only it is refreshed, the lists still hold
        // every contact-capable pair, and its new reference is where the mean motion
        // expects it, so the same positions renew nothing again.
        refresh_any_body_that_drifted(&mut model);
        let mover = seed as usize % assembly.n_bodies();
        let shift = scale(common::random_unit(&mut r), 1.1 * rho);
        let mut x2 = x1.clone();
        for i in assembly.bodies[mover].nodes.clone() {
            x2[i] = add(mapped(origin, rate, t, x0[i]), shift);
        }
        let report = evaluate_at(&mut model, &x2, t);
        prop_assert!(!report.rebuilt);
        prop_assert_eq!(report.refreshed_bodies, 1);
        let set2: BTreeSet<_> = model.candidate_pairs().into_iter().collect();
        prop_assert!(contact_capable(&assembly, &x2, model.depth_limit()).is_subset(&set2));
        let again = evaluate_at(&mut model, &x2, t);
        prop_assert!(!again.rebuilt && again.refreshed_bodies == 0);
    }
}

/// Eight spheres in contact squeezed along z at a constant rate (3 % over 300 steps: the
/// far nodes move about nine margins, neighbours approach by up to three) with the
/// oscillations of `oscillating` on top (`rattle` for one sphere, `wobble` for the
/// others). Three models: one told the squeeze, one not, one rebuilding at every
/// evaluation; forces, contacts and energies must agree bit for bit. Returns the renewals
/// (full builds plus refreshes) of the told and the untold model and the most contacts.
fn squeezed(rattle: f64, wobble: f64) -> (usize, usize, usize) {
    let margin = 1e-4;
    let assembly = scene(7, 8, 1, 0.01, 1e-6..0.1 * margin);
    let params = ContactParams {
        friction: 0.3,
        ..ContactParams::default()
    };
    let mut told = model_for(&assembly, params, vec![], 1e-4, Some(margin));
    let mut untold = model_for(&assembly, params, vec![], 1e-4, Some(margin));
    let mut rebuilding = model_for(&assembly, params, vec![], 1e-4, Some(margin));
    for m in [&mut told, &mut untold, &mut rebuilding] {
        m.set_depth_limit(10.0 * margin).unwrap();
        // A rattler (an eighth of the nodes) is refreshed alone.
        m.set_refresh_policy(RefreshPolicy {
            max_fraction: 0.2,
            ..RefreshPolicy::default()
        })
        .unwrap();
    }
    let (steps, dt) = (300, 1e-7);
    // The fixed point 0.1 m below the cluster, as for a patch of a tall specimen: the
    // squeeze carries the cluster by far more than its size.
    let corner = assembly.nodes.iter().fold([f64::INFINITY; 3], |o, p| {
        std::array::from_fn(|i| o[i].min(p[i]))
    });
    let origin = [corner[0], corner[1], corner[2] - 0.1];
    let mut rate = [[0.0; 3]; 3];
    rate[2][2] = -0.03 / (steps as f64 * dt);
    told.set_mean_motion(origin, rate, 0.0).unwrap();
    let positions = oscillating(&assembly, 5, rattle * margin, wobble * margin);
    let n = assembly.n_nodes();
    let v = vec![[0.0; 3]; n];
    let mut contacts = 0;
    for step in 0..steps {
        let t = step as f64 * dt;
        let x: Vec<[f64; 3]> = positions(step)
            .iter()
            .map(|&p| mapped(origin, rate, t, p))
            .collect();
        let mut f = [vec![[0.0; 3]; n], vec![[0.0; 3]; n], vec![[0.0; 3]; n]];
        rebuilding.request_rebuild();
        let a = told.add_forces(&x, &v, t, dt, &mut f[0]).unwrap();
        let b = untold.add_forces(&x, &v, t, dt, &mut f[1]).unwrap();
        let c = rebuilding.add_forces(&x, &v, t, dt, &mut f[2]).unwrap();
        assert_eq!(f[0], f[2], "step {step}");
        assert_eq!(f[1], f[2], "step {step}");
        for r in [&a, &b] {
            assert_eq!(r.contacts, c.contacts, "step {step}");
            assert_eq!(r.stored_energy.to_bits(), c.stored_energy.to_bits());
        }
        contacts = contacts.max(a.contacts);
    }
    eprintln!(
        "rattle {rattle}, wobble {wobble}: told {} builds, {} refreshes; untold {} builds, \
         {} refreshes; up to {contacts} contacts",
        told.rebuild_count(),
        told.refresh_count(),
        untold.rebuild_count(),
        untold.refresh_count()
    );
    let renewals = |m: &ContactModel| m.rebuild_count() + m.refresh_count();
    (renewals(&told), renewals(&untold), contacts)
}

#[test]
fn a_mean_motion_gives_the_forces_of_full_builds_bit_for_bit() {
    // With a rattler and contacts that open and close; the rattler's refreshes dominate
    // the renewals of both models.
    let (told, untold, contacts) = squeezed(1.0, 0.12);
    assert!(contacts >= 5, "{contacts} contacts");
    assert!(
        told <= untold,
        "told {told} against untold {untold} renewals"
    );
}

#[test]
fn a_mean_motion_spares_the_renewals_of_a_squeeze() {
    // Without a rattler the squeeze alone renews the untold model's lists; the told one
    // renews them when its distortion has used up the allowance (every percent or so).
    let (told, untold, _) = squeezed(0.05, 0.05);
    assert!(
        3 * told <= untold,
        "told {told} against untold {untold} renewals"
    );
}

#[test]
fn a_mean_motion_that_is_not_finite_is_refused() {
    let (_, mut model) = cluster(5, 2, 0, 0.02, 1.0);
    let mut rate = [[0.0; 3]; 3];
    rate[1][2] = f64::NAN;
    let e = model.set_mean_motion([0.0; 3], rate, 0.0).unwrap_err();
    assert!(e.to_string().contains("mean motion's rate"), "{e}");
    let e = model
        .set_mean_motion([f64::INFINITY, 0.0, 0.0], [[0.0; 3]; 3], 0.0)
        .unwrap_err();
    assert!(e.to_string().contains("origin"), "{e}");
}

#[test]
fn a_refresh_policy_out_of_range_is_refused() {
    let assembly = scene(5, 3, 1, 0.01, 1e-3..2e-3);
    let mut model = model_for(
        &assembly,
        ContactParams::default(),
        vec![],
        1e-4,
        Some(2e-4),
    );
    let good = RefreshPolicy::default();
    for bad in [
        RefreshPolicy { near: 0.0, ..good },
        RefreshPolicy { near: 1.5, ..good },
        RefreshPolicy {
            max_fraction: -0.1,
            ..good
        },
        RefreshPolicy {
            max_refreshed_fraction: f64::NAN,
            ..good
        },
    ] {
        let e = model.set_refresh_policy(bad).unwrap_err();
        assert!(e.to_string().contains("refresh policy's"), "{e}");
    }
    model
        .set_refresh_policy(RefreshPolicy {
            max_fraction: 0.0,
            ..good
        })
        .unwrap();
}

/// Rigid oscillations of the bodies of `assembly` about where they are, each along a random
/// direction: body 0 with amplitude `rattle`, the others with `amplitude`; periods of 30
/// to 60 steps.
fn oscillating(
    assembly: &MeshAssembly,
    seed: u64,
    rattle: f64,
    amplitude: f64,
) -> impl Fn(usize) -> Vec<[f64; 3]> {
    let mut r = rng(seed);
    let motions: Vec<([f64; 3], f64)> = (0..assembly.n_bodies())
        .map(|b| {
            let a = if b == 0 { rattle } else { amplitude };
            let omega = std::f64::consts::TAU / r.random_range(30.0..60.0);
            (scale(common::random_unit(&mut r), a), omega)
        })
        .collect();
    let assembly = assembly.clone();
    move |step| {
        let mut x = assembly.nodes.clone();
        for (b, &(u, omega)) in motions.iter().enumerate() {
            let shift = scale(u, (omega * step as f64).sin());
            for i in assembly.bodies[b].nodes.clone() {
                x[i] = add(x[i], shift);
            }
        }
        x
    }
}

/// One evaluation of both models at positions `x` (zero velocities, time step 1e-7 s), the
/// second rebuilt from scratch; their forces, contact counts and stored energies must agree
/// bit for bit. Returns the first model's report.
fn evaluate_against_a_full_build(
    (refreshing, rebuilding): (&mut ContactModel, &mut ContactModel),
    x: &[[f64; 3]],
    step: usize,
) -> fdem_contact::ContactReport {
    let n = x.len();
    let v = vec![[0.0; 3]; n];
    let mut fa = vec![[0.0; 3]; n];
    let mut fb = vec![[0.0; 3]; n];
    let t = step as f64 * 1e-7;
    let a = refreshing.add_forces(x, &v, t, 1e-7, &mut fa).unwrap();
    rebuilding.request_rebuild();
    let b = rebuilding.add_forces(x, &v, t, 1e-7, &mut fb).unwrap();
    assert_eq!(fa, fb, "step {step}");
    assert_eq!(a.contacts, b.contacts, "step {step}");
    assert_eq!(
        a.stored_energy.to_bits(),
        b.stored_energy.to_bits(),
        "step {step}"
    );
    a
}

/// Asserts that `model`'s lists hold every pair that can be in contact at `x`: a node
/// behind a solid face within `depth_limit` with its foot inside, or one of the nodes
/// `others` within `depth_limit` of a face of the sheet `sheet`. Returns how many of those
/// pairs have a sheet face.
fn assert_lists_hold_the_contact_capable_pairs(
    (model, assembly): (&ContactModel, &MeshAssembly),
    x: &[[f64; 3]],
    (sheet, others): (u32, &[usize]),
    depth_limit: f64,
    step: usize,
) -> usize {
    let listed: BTreeSet<_> = model.candidate_pairs().into_iter().collect();
    let mut needed = contact_capable(assembly, x, depth_limit);
    for (t, tri) in assembly.triangles.iter().enumerate() {
        if assembly.triangle_body[t] != sheet {
            continue;
        }
        for &node in others {
            if distance_to_triangle(x[node], tri.map(|i| x[i])) <= depth_limit {
                needed.insert((node, t));
            }
        }
    }
    let missing: Vec<_> = needed.difference(&listed).collect();
    assert!(
        missing.is_empty(),
        "step {step}: pairs missing from the lists: {missing:?}"
    );
    needed
        .iter()
        .filter(|&&(_, t)| assembly.triangle_body[t] == sheet)
        .count()
}

/// One step of the sheet tests: both models evaluated at `x` against each other
/// ([`evaluate_against_a_full_build`]) and the refreshing model's lists checked
/// ([`assert_lists_hold_the_contact_capable_pairs`]). Returns the report, whether a
/// refresh renewed no whole body (the sheet's nodes alone), and the needed sheet pairs.
fn sheet_step(
    (refreshing, rebuilding): (&mut ContactModel, &mut ContactModel),
    (assembly, x): (&MeshAssembly, &[[f64; 3]]),
    (sheet, others, depth_limit): (u32, &[usize], f64),
    step: usize,
) -> (fdem_contact::ContactReport, bool, usize) {
    let refreshes = refreshing.refresh_count();
    let a = evaluate_against_a_full_build((refreshing, rebuilding), x, step);
    let alone = refreshing.refresh_count() > refreshes && a.refreshed_bodies == 0;
    let models = (&*refreshing, assembly);
    let needed =
        assert_lists_hold_the_contact_capable_pairs(models, x, (sheet, others), depth_limit, step);
    (a, alone, needed)
}

/// Two models of `assembly` for the sheet tests (time step 1e-4 s), with the skin and
/// depth limit given and body `sheet` declared a sheet with the first and the second fold
/// depth respectively.
fn sheet_models(
    (assembly, params): (&MeshAssembly, ContactParams),
    (skin, depth_limit): (f64, f64),
    (sheet, folds): (u32, [f64; 2]),
) -> (ContactModel, ContactModel) {
    let [a, b] = folds.map(|fold| {
        let mut m = model_for(assembly, params, vec![], 1e-4, Some(skin));
        m.set_depth_limit(depth_limit).unwrap();
        m.set_sheet_bodies(&[sheet], fold).unwrap();
        m
    });
    (a, b)
}

/// The positions of the sheet tests at each step: the cluster's bodies oscillating 0.12
/// margin, and the sheet's surface node nearest to another body's (a vertex) pushed
/// towards it, poking into the neighbour by up to half a margin (its own pairs) while the
/// faces around it sweep over the neighbour's nodes (their pairs). It slides steadily
/// across the neighbour, perpendicular to the push: six margins in 200 steps, farther than
/// the lists of a full build reach, so the pairs around the vertex must be found anew as
/// it goes.
fn poking_vertex(
    assembly: &MeshAssembly,
    sheet: u32,
    margin: f64,
) -> impl Fn(usize) -> Vec<[f64; 3]> {
    let own = &assembly.surface_nodes[assembly.bodies[sheet as usize].surface_nodes.clone()];
    let others = surface_nodes_but(assembly, sheet as usize);
    let (rattler, target) = own
        .iter()
        .flat_map(|&i| others.iter().map(move |&j| (i, j)))
        .min_by(|a, b| {
            let d =
                |(i, j): (usize, usize)| common::norm(sub(assembly.nodes[i], assembly.nodes[j]));
            d(*a).total_cmp(&d(*b))
        })
        .expect("nodes");
    let towards = sub(assembly.nodes[target], assembly.nodes[rattler]);
    let direction = scale(towards, 1.0 / common::norm(towards));
    let side = cross(direction, common::random_unit(&mut rng(11)));
    let tangent = scale(side, 1.0 / common::norm(side));
    let bodies = oscillating(assembly, 5, 0.12 * margin, 0.12 * margin);
    move |step| {
        let mut x = bodies(step);
        let poke = scale(
            direction,
            0.5 * margin * (0.23 * step as f64).sin().max(0.0),
        );
        let shift = add(poke, scale(tangent, 0.03 * margin * step as f64));
        x[rattler] = add(x[rattler], shift);
        x
    }
}

/// The surface nodes of every body but `body`.
fn surface_nodes_but(assembly: &MeshAssembly, body: usize) -> Vec<usize> {
    (0..assembly.n_bodies())
        .filter(|&b| b != body)
        .flat_map(|b| assembly.surface_nodes[assembly.bodies[b].surface_nodes.clone()].to_vec())
        .collect()
}

/// The cluster tests' common ending: contacts formed, and the refreshing model rebuilt
/// everything only now and then.
fn assert_contacts_and_few_builds(refreshing: &ContactModel, contacts: usize) {
    assert!(contacts >= 5, "{contacts} contacts");
    assert!(
        refreshing.rebuild_count() < 20,
        "{} full builds",
        refreshing.rebuild_count()
    );
}

/// The refresh tests' cluster: eight spheres of 1 cm with gaps up to 0.1 `margin`, and a
/// frictional contact law.
fn frictional_cluster(margin: f64) -> (MeshAssembly, ContactParams) {
    let assembly = scene(7, 8, 1, 0.01, 1e-6..0.1 * margin);
    assert!(assembly.n_bodies() >= 5, "{} bodies", assembly.n_bodies());
    let params = ContactParams {
        friction: 0.3,
        ..ContactParams::default()
    };
    (assembly, params)
}

#[test]
fn refreshing_the_drifted_bodies_gives_the_forces_of_full_builds_bit_for_bit() {
    // Eight spheres in a cluster, surfaces up to 0.1 margin apart, oscillating: a
    // rattler (amplitude one margin) drifts past half the margin several times per
    // period, the others (0.12 margin) never past a quarter of it (the default policy
    // refreshes those too); no contact gets deeper than 1.12 margins, below
    // half the depth limit of 3 margins. One model refreshes what drifted, the
    // other rebuilds everything at every evaluation; forces and contacts must agree bit
    // for bit, and the first must have refreshed.
    let margin = 2e-4;
    let (assembly, params) = frictional_cluster(margin);
    let mut refreshing = model_for(&assembly, params, vec![], 1e-4, Some(margin));
    // The rattler holds an eighth of the surface nodes, more than the default policy
    // refreshes alone.
    refreshing
        .set_refresh_policy(RefreshPolicy {
            max_fraction: 0.2,
            ..RefreshPolicy::default()
        })
        .unwrap();
    let mut rebuilding = model_for(&assembly, params, vec![], 1e-4, Some(margin));
    for m in [&mut refreshing, &mut rebuilding] {
        m.set_depth_limit(3.0 * margin).unwrap();
    }
    let positions = oscillating(&assembly, 5, margin, 0.12 * margin);
    let (mut refreshes, mut contacts) = (0, 0);
    for step in 0..200 {
        let x = positions(step);
        let models = (&mut refreshing, &mut rebuilding);
        let a = evaluate_against_a_full_build(models, &x, step);
        refreshes += usize::from(a.refreshed_bodies > 0);
        contacts = contacts.max(a.contacts);
    }
    eprintln!(
        "{refreshes} refreshes, {} full builds, up to {contacts} contacts",
        refreshing.rebuild_count()
    );
    assert!(refreshes >= 5, "{refreshes} refreshes");
    assert_contacts_and_few_builds(&refreshing, contacts);
}

#[test]
fn a_sheet_refreshed_node_by_node_gives_the_forces_of_full_builds_bit_for_bit() {
    // The cluster of the test above with body 1 declared a sheet, its bodies oscillating
    // 0.12 margin, and one surface node of the sheet (a vertex) moving on its own
    // ([`poking_vertex`]): it slides six margins across its nearest neighbour while poking
    // into it by up to half a margin, so it drifts past half the margin again and again
    // while the rest of the sheet stays below a quarter of it. The refresh renews
    // the sheet node by node (its drifted node and the faces around it). Forces and
    // contacts must agree bit for bit with full builds at every evaluation, and refreshes
    // that renewed no whole body (the sheet's node alone) must have happened.
    let margin = 2e-4;
    let (assembly, params) = frictional_cluster(margin);
    let sheet = 1u32;
    let depth_limit = 3.0 * margin;
    let (mut refreshing, mut rebuilding) = sheet_models(
        (&assembly, params),
        (margin, depth_limit),
        (sheet, [depth_limit; 2]),
    );
    let others = surface_nodes_but(&assembly, sheet as usize);
    let positions = poking_vertex(&assembly, sheet, margin);
    let (mut node_only, mut contacts, mut sheet_pairs) = (0, 0, 0);
    for step in 0..200 {
        let x = positions(step);
        let (a, alone, needed) = sheet_step(
            (&mut refreshing, &mut rebuilding),
            (&assembly, &x),
            (sheet, &others, depth_limit),
            step,
        );
        node_only += usize::from(alone);
        sheet_pairs += needed;
        contacts = contacts.max(a.contacts);
    }
    eprintln!(
        "{node_only} refreshes of the sheet's node alone, {} in all, {} full builds, up to {contacts} contacts, {sheet_pairs} needed sheet pairs over the steps",
        refreshing.refresh_count(),
        refreshing.rebuild_count()
    );
    assert!(
        node_only >= 5,
        "{node_only} refreshes of the sheet's node alone"
    );
    assert_contacts_and_few_builds(&refreshing, contacts);
}

#[test]
fn a_sheet_listed_to_its_fold_depth_gives_the_forces_of_one_listed_to_the_depth_limit() {
    // The sliding, poking sheet vertex of the test above with the depth limit at six
    // margins and the sheet's fold depth at one: the sheet's faces are listed to about the
    // fold depth, not the depth limit. A hit deeper than the fold depth would be discarded
    // anyway, so the forces must equal bit for bit those of a model whose fold depth is the
    // depth limit (its sheet lists reach the depth limit), rebuilt at every evaluation.
    // The shorter lists must hold every pair within the fold depth, and be shorter.
    let margin = 2e-4;
    let (assembly, params) = frictional_cluster(margin);
    let sheet = 1u32;
    let depth_limit = 6.0 * margin;
    let fold = margin;
    // A skin of a quarter margin, as the triaxial test's: the lists reach little beyond
    // the listing depth, so lists too short would miss pairs within the fold depth.
    let skin = 0.25 * margin;
    let (mut short, mut long) = sheet_models(
        (&assembly, params),
        (skin, depth_limit),
        (sheet, [fold, depth_limit]),
    );
    let others = surface_nodes_but(&assembly, sheet as usize);
    let positions = poking_vertex(&assembly, sheet, margin);
    let sheet_pairs = |m: &ContactModel| {
        (m.candidate_pairs().iter())
            .filter(|&&(_, t)| assembly.triangle_body[t] == sheet)
            .count()
    };
    let (mut short_pairs, mut long_pairs, mut contacts) = (0, 0, 0);
    for step in 0..200 {
        let x = positions(step);
        let a = evaluate_against_a_full_build((&mut short, &mut long), &x, step);
        contacts = contacts.max(a.contacts);
        let models = (&short, &assembly);
        assert_lists_hold_the_contact_capable_pairs(models, &x, (sheet, &others), fold, step);
        short_pairs += sheet_pairs(&short);
        long_pairs += sheet_pairs(&long);
    }
    eprintln!(
        "sheet pairs over the steps: {short_pairs} listed to the fold depth, {long_pairs} to the depth limit; up to {contacts} contacts"
    );
    assert!(contacts >= 5, "{contacts} contacts");
    assert!(
        short_pairs < long_pairs,
        "{short_pairs} against {long_pairs}"
    );
}

#[test]
fn a_sheet_coming_back_to_its_neighbours_has_its_faces_renewed() {
    // The outermost body of the cluster above, declared a sheet, starts six margins out
    // (beyond the lists' reach of the skin plus the depth limit, four margins) and comes
    // back to its place in 100 steps. Every sheet node drifts alike, so each refresh
    // renews them all one by one, and the sheet's faces with them: the neighbours' nodes
    // meet those faces only as the sheet comes near, so without renewed faces their pairs
    // would be missing. The lists must hold every pair that can be in contact, and the
    // forces must equal full builds' bit for bit.
    let margin = 2e-4;
    let assembly = scene(7, 8, 1, 0.01, 1e-6..0.1 * margin);
    let centre = |b: usize| {
        let nodes = &assembly.nodes[assembly.bodies[b].nodes.clone()];
        scale(
            nodes.iter().fold([0.0; 3], |c, &x| add(c, x)),
            1.0 / nodes.len() as f64,
        )
    };
    let n_bodies = assembly.n_bodies();
    let middle = scale(
        (0..n_bodies).fold([0.0; 3], |c, b| add(c, centre(b))),
        1.0 / n_bodies as f64,
    );
    let outermost = (0..n_bodies)
        .max_by(|&a, &b| {
            let d = |b: usize| common::norm(sub(centre(b), middle));
            d(a).total_cmp(&d(b))
        })
        .expect("bodies");
    let sheet = outermost as u32;
    let out = sub(centre(outermost), middle);
    let out = scale(out, 1.0 / common::norm(out));
    let depth_limit = 3.0 * margin;
    let (mut refreshing, mut rebuilding) = sheet_models(
        (&assembly, ContactParams::default()),
        (margin, depth_limit),
        (sheet, [depth_limit; 2]),
    );
    // The sheet holds an eighth of the surface nodes: let one refresh renew them all.
    refreshing
        .set_refresh_policy(RefreshPolicy {
            max_fraction: 0.5,
            max_refreshed_fraction: 1.0,
            ..RefreshPolicy::default()
        })
        .unwrap();
    let own = assembly.bodies[outermost].nodes.clone();
    let others = surface_nodes_but(&assembly, outermost);
    let (mut node_only, mut sheet_pairs) = (0, 0);
    for step in 0..=100 {
        let shift = scale(out, 6.0 * margin * (1.0 - step as f64 / 100.0));
        let mut x = assembly.nodes.clone();
        for i in own.clone() {
            x[i] = add(x[i], shift);
        }
        let (_, alone, needed) = sheet_step(
            (&mut refreshing, &mut rebuilding),
            (&assembly, &x),
            (sheet, &others, depth_limit),
            step,
        );
        node_only += usize::from(alone);
        sheet_pairs += needed;
    }
    eprintln!(
        "{node_only} refreshes of the sheet's nodes alone, {} full builds, {sheet_pairs} needed sheet pairs over the steps",
        refreshing.rebuild_count()
    );
    assert!(
        node_only >= 5,
        "{node_only} refreshes of the sheet's nodes alone"
    );
    assert!(sheet_pairs >= 50, "{sheet_pairs} needed sheet pairs");
    // The first evaluation's build, and one more once the refreshes have renewed as many
    // nodes as the surface has (the policy's limit).
    assert!(
        refreshing.rebuild_count() <= 2,
        "{} full builds",
        refreshing.rebuild_count()
    );
}

#[test]
fn candidate_lists_are_deterministic_and_ordered() {
    let assembly = scene(99, 6, 1, 0.01, 1e-4..3e-4);
    let build = || {
        let mut m = model_for(
            &assembly,
            ContactParams::default(),
            vec![],
            1e-4,
            Some(2e-4),
        );
        evaluate(&mut m, &assembly.nodes);
        m.candidate_pairs()
    };
    let a = build();
    assert!(!a.is_empty());
    assert_eq!(a, build());
    // Sorted by node, then (owner body, triangle).
    let body = |t: usize| assembly.triangle_body[t];
    assert!(
        a.windows(2)
            .all(|w| (w[0].0, body(w[0].1), w[0].1) < (w[1].0, body(w[1].1), w[1].1))
    );
}

#[test]
fn rebuild_happens_only_beyond_half_the_margin() {
    let assembly = scene(5, 3, 1, 0.01, 1e-3..2e-3);
    let margin = 2e-4;
    let mut model = model_for(
        &assembly,
        ContactParams::default(),
        vec![],
        1e-4,
        Some(margin),
    );
    let mut x = assembly.nodes.clone();
    evaluate(&mut model, &x);
    assert_eq!(model.rebuild_count(), 1);
    // Move one node by 0.49 margin, then 0.51 margin from its built position.
    x[0][0] += 0.49 * margin;
    assert!(!evaluate(&mut model, &x).rebuilt);
    x[0][0] += 0.02 * margin;
    assert!(evaluate(&mut model, &x).rebuilt);
    assert_eq!(model.rebuild_count(), 2);
    model.request_rebuild();
    assert!(evaluate(&mut model, &x).rebuilt);
}

#[test]
fn hand_and_parry_kernels_agree() {
    let mut r = rng(1234);
    let limit = 0.5;
    let (mut hits, mut misses) = (0, 0);
    for i in 0..20_000 {
        let face: [[f64; 3]; 3] =
            std::array::from_fn(|_| std::array::from_fn(|_| r.random_range(-1.0..1.0)));
        // Half the points anywhere, half near the face (barycentrics in -0.2..1.2).
        let x: [f64; 3] = if i % 2 == 0 {
            std::array::from_fn(|_| r.random_range(-1.0..1.0))
        } else {
            let [a, b, c] = face;
            let (u, v) = (r.random_range(-0.2..1.2), r.random_range(-0.2..1.2));
            let n = common::cross(common::sub(b, a), common::sub(c, a));
            let on = add(
                a,
                add(scale(common::sub(b, a), u), scale(common::sub(c, a), v)),
            );
            add(on, scale(n, r.random_range(-0.3..0.1) / common::norm(n)))
        };
        let h = project_hand(x, face, limit);
        let p = project_parry(x, face, limit);
        match (h, p) {
            (Some(h), Some(p)) => {
                hits += 1;
                assert!((h.depth - p.depth).abs() < 1e-12);
                for i in 0..3 {
                    assert!((h.normal[i] - p.normal[i]).abs() < 1e-12);
                    assert!((h.weights[i] - p.weights[i]).abs() < 1e-9, "{h:?} {p:?}");
                }
                let sum: f64 = h.weights.iter().sum();
                assert!((sum - 1.0).abs() < 1e-12 && h.weights.iter().all(|&w| w >= 0.0));
            }
            (None, None) => misses += 1,
            (h, p) => {
                // Disagreement is allowed only inside the tolerance band along an edge:
                // recompute the hand barycentrics and check one is within 1e-5 of zero.
                let w = raw_barycentrics(x, face);
                let near_edge = w.iter().any(|c| c.abs() < 1e-5);
                assert!(near_edge, "{h:?} vs {p:?}, w {w:?}");
            }
        }
    }
    assert!(hits > 2000 && misses > 2000, "{hits} hits, {misses} misses");
}

fn raw_barycentrics(x: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> [f64; 3] {
    let e1 = common::sub(b, a);
    let e2 = common::sub(c, a);
    let n = common::cross(e1, e2);
    let nn = common::dot(n, n);
    let p = common::sub(x, a);
    let wb = common::dot(common::cross(p, e2), n) / nn;
    let wc = common::dot(common::cross(e1, p), n) / nn;
    [1.0 - wb - wc, wb, wc]
}

#[test]
fn narrow_phase_edge_cases() {
    let face = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    for project in [project_hand, project_parry] {
        // On a shared edge (w_a = 0 within round-off) the node is still in contact.
        let hit = project([0.5, 0.5, -1e-3], face, 0.1).unwrap();
        assert!((hit.weights[0]).abs() < 1e-12 && (hit.weights[1] - 0.5).abs() < 1e-12);
        // Just beyond the tolerance band: outside.
        assert!(project([0.5, 0.5 + 10.0 * BARYCENTRIC_TOLERANCE, -1e-3], face, 0.1).is_none());
        // On the plane: no penetration, no contact; in front: none; beyond the limit: none.
        assert!(project([0.2, 0.2, 0.0], face, 0.1).is_none());
        assert!(project([0.2, 0.2, 1e-3], face, 0.1).is_none());
        assert!(project([0.2, 0.2, -0.2], face, 0.1).is_none());
        // Degenerate face: none, no NaN.
        let flat = [[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert!(project([0.5, 0.0, -1e-3], flat, 0.1).is_none());
        assert!(project([f64::NAN, 0.0, -1e-3], face, 0.1).is_none());
        let hit = project([0.25, 0.25, -0.05], face, 0.1).unwrap();
        assert!((hit.depth - 0.05).abs() < 1e-15);
        assert_eq!(hit.normal, [0.0, 0.0, 1.0]);
    }
}

#[test]
fn spread_scenes_use_the_hash_and_still_match_brute_force() {
    // Two touching clusters 2^21 cells apart: too spread for a dense grid (the hash table
    // takes over) and exactly one wrap of the packed 21-bit cell coordinates apart, so
    // cells of the two clusters share keys. The exact box test must remove the extra
    // triangles that this brings into a cell.
    let d = 0.01;
    let margin = 2e-4;
    let cluster = scene(17, 3, 1, d, margin..2.0 * margin);
    let probe = model_for(
        &cluster,
        ContactParams::default(),
        vec![],
        1e-4,
        Some(margin),
    );
    let mut probe = probe;
    evaluate(&mut probe, &cluster.nodes);
    let cell = probe.cell_size();
    let shift = [(1u64 << 21) as f64 * cell, 0.0, 0.0];
    let mesh = linear_sphere(1, d);
    let mut assembly = MeshAssembly::new();
    // Same topology twice; the positions are the cluster's, then the cluster's shifted.
    for _ in 0..2 {
        for _ in 0..cluster.n_bodies() {
            assembly
                .push_instance(&mesh, &Placement::identity())
                .unwrap();
        }
    }
    let n0 = cluster.n_nodes();
    let mut x = cluster.nodes.clone();
    x.extend(cluster.nodes.iter().map(|&p| add(p, shift)));
    assert_eq!(x.len(), assembly.n_nodes());
    assert_eq!(x.len(), 2 * n0);
    let mut model = model_for(
        &assembly,
        ContactParams::default(),
        vec![],
        1e-4,
        Some(margin),
    );
    evaluate(&mut model, &x);
    assert!((model.cell_size() - cell).abs() < 1e-9 * cell);
    let got: BTreeSet<_> = model.candidate_pairs().into_iter().collect();
    let window = |f: [[f64; 3]; 3]| model.candidate_window_reaches(f).0;
    let expect = brute_force(
        &assembly,
        &x,
        (model.candidate_enlargement(), model.candidate_front_reach()),
        (model.depth_limit(), &window),
    );
    assert!(!expect.is_empty());
    assert_eq!(got, expect);
    // Each cluster sees only itself: twice the single cluster's candidates.
    assert_eq!(got.len(), 2 * probe.candidate_pairs().len());
}
