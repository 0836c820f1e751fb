//! Sheets: the contact of a node with a faceted sheet is the distance to the sheet's
//! closest point, on the side the sheet's angle-weighted pseudo-normal says is behind it;
//! it is continuous over ridges, valleys and vertices, so a node sliding over a folded
//! sheet conserves energy.

mod common;

use common::rng;
use fdem_contact::{ContactModel, ContactParams, ContactSurface, Counterpart};
use rand::RngExt;

/// Height of the sheet: a ridge along y (peak at x = 0), a valley along x (bottom at
/// y = 0), a saddle vertex at the origin. Linear on each quadrant, so a grid with lines at
/// x = 0 and y = 0 represents it exactly.
fn height(x: f64, y: f64) -> f64 {
    -0.4 * x.abs() + 0.3 * y.abs()
}

/// A pyramid: ridges along both axes, its apex vertex at the origin.
fn pyramid(x: f64, y: f64) -> f64 {
    -0.4 * x.abs() - 0.3 * y.abs()
}

const CELL: f64 = 0.005;
const HALF: i32 = 8;

/// Node 0 (body 0, the probe) and the sheet's grid nodes (body 1), with the sheet's
/// triangles oriented so that their normals point down (-z): the particle side is below,
/// a node above the sheet is behind it.
fn sheet_surface(probe_area: f64, height: fn(f64, f64) -> f64) -> (ContactSurface, Vec<[f64; 3]>) {
    let n = (2 * HALF + 1) as usize;
    let id = |i: usize, j: usize| 1 + i * n + j;
    let mut nodes = vec![[0.0; 3]];
    for i in 0..n {
        for j in 0..n {
            let (x, y) = (
                (i as i32 - HALF) as f64 * CELL,
                (j as i32 - HALF) as f64 * CELL,
            );
            nodes.push([x, y, height(x, y)]);
        }
    }
    let mut triangles = Vec::new();
    for i in 0..n - 1 {
        for j in 0..n - 1 {
            let (p00, p10, p11, p01) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            // Counter-clockwise seen from below: normals along -z.
            triangles.push([p00, p11, p10]);
            triangles.push([p00, p01, p11]);
        }
    }
    let sheet_nodes: Vec<usize> = (1..nodes.len()).collect();
    let surface = ContactSurface {
        triangle_body: vec![1; triangles.len()],
        triangles,
        surface_nodes: std::iter::once(0)
            .chain(sheet_nodes.iter().copied())
            .collect(),
        node_body: std::iter::once(0)
            .chain(sheet_nodes.iter().map(|_| 1))
            .collect(),
        control_areas: std::iter::once(probe_area)
            .chain(sheet_nodes.iter().map(|_| 1e-6))
            .collect(),
    };
    (surface, nodes)
}

fn sheet_model(
    params: ContactParams,
    probe_mass: f64,
    height: fn(f64, f64) -> f64,
) -> (ContactModel, Vec<[f64; 3]>) {
    let (surface, nodes) = sheet_surface(1e-6, height);
    let mut masses = vec![1.0; nodes.len()];
    masses[0] = probe_mass;
    let mut model = ContactModel::new(params, surface, vec![], &masses, 0.004).unwrap();
    model.set_depth_limit(0.02).unwrap();
    model.set_sheet_bodies(&[1], 0.01).unwrap();
    (model, nodes)
}

/// Distance from `p` to the triangle `[a, b, c]`, independently of the crate: the plane
/// distance when the foot of the perpendicular falls inside, else the nearest of the three
/// edges as segments.
fn distance_to_triangle(p: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> f64 {
    let sub = |u: [f64; 3], v: [f64; 3]| [u[0] - v[0], u[1] - v[1], u[2] - v[2]];
    let dot = |u: [f64; 3], v: [f64; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    let cross = |u: [f64; 3], v: [f64; 3]| {
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    };
    let n = cross(sub(b, a), sub(c, a));
    let nn = dot(n, n);
    let s = dot(sub(p, a), n) / nn.sqrt();
    let inside = [(a, b), (b, c), (c, a)]
        .iter()
        .all(|&(u, v)| dot(cross(sub(v, u), sub(p, u)), n) >= 0.0);
    if inside {
        return s.abs();
    }
    [(a, b), (b, c), (c, a)]
        .iter()
        .map(|&(u, v)| {
            let e = sub(v, u);
            let t = (dot(sub(p, u), e) / dot(e, e)).clamp(0.0, 1.0);
            let q = [u[0] + t * e[0], u[1] + t * e[1], u[2] + t * e[2]];
            let d = sub(p, q);
            dot(d, d).sqrt()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The probe's contact with the sheet at `x`: (depth, contact point), if any. A fresh
/// model each time: this is the first evaluation, where a contact may start at any depth
/// (later a new contact deeper than a step's motion is a fold artefact).
fn probe(x: [f64; 3]) -> Option<(f64, [f64; 3])> {
    let (mut model, mut nodes) = sheet_model(ContactParams::default(), 1e-3, height);
    nodes[0] = x;
    let n = nodes.len();
    let mut f = vec![[0.0; 3]; n];
    model
        .add_forces(&nodes, &vec![[0.0; 3]; n], 0.0, 1e-7, &mut f)
        .unwrap();
    model
        .node_contacts()
        .iter()
        .find(|c| c.node == 0 && c.counterpart == Counterpart::Body(1))
        .map(|c| (c.depth, c.contact_point))
}

#[test]
fn a_node_behind_a_folded_sheet_is_at_the_distance_to_its_closest_point() {
    let (surface, nodes) = sheet_surface(1e-6, height);
    // Deterministic points around the ridge, the valley and the saddle vertex.
    let mut r = rng(17);
    let mut next = move || r.random_range(-1.0..1.0);
    let (mut behind, mut in_front) = (0, 0);
    for _ in 0..400 {
        let (x, y) = (0.006 * next(), 0.006 * next());
        let z = height(x, y) + 0.004 * next();
        let p = [x, y, z];
        let exact = surface
            .triangles
            .iter()
            .map(|t| distance_to_triangle(p, t.map(|i| nodes[i])))
            .fold(f64::INFINITY, f64::min);
        let contact = probe(p);
        // Behind the sheet is above it (the sheet's normals point down).
        if z > height(x, y) + 1e-9 {
            behind += 1;
            let (depth, point) = contact.unwrap_or_else(|| panic!("no contact at {p:?}"));
            assert!(
                (depth - exact).abs() <= 1e-12,
                "{p:?}: depth {depth}, distance {exact}"
            );
            // The contact point lies on the sheet.
            assert!((point[2] - height(point[0], point[1])).abs() < 1e-12);
        } else if z < height(x, y) - 1e-9 {
            in_front += 1;
            assert!(contact.is_none(), "{p:?} is in front: {contact:?}");
        }
    }
    assert!(behind > 150 && in_front > 150, "{behind} {in_front}");
}

/// A probe of mass m pressed into the pyramid sheet by a constant force F (the particle
/// pressing the membrane outwards), sliding from `start` at `velocity` for 24 mm,
/// without damping or friction, integrated by velocity Verlet with the step `factor`
/// `sqrt(m / k)`: the largest error of kinetic + stored - F z over the run, relative to
/// the kinetic plus the stored energy at the start.
fn slide(start: [f64; 2], velocity: [f64; 3], factor: f64) -> f64 {
    let params = ContactParams {
        friction: 0.0,
        damping: 0.0,
        ..ContactParams::default()
    };
    let m = 0.1;
    let (mut model, mut nodes) = sheet_model(params, m, pyramid);
    let k = params.normal_penalty * 1e-6;
    let force = k * 1e-3;
    let dt = factor * (m / k).sqrt();
    let mut x = [start[0], start[1], pyramid(start[0], start[1]) + 1e-3];
    let mut v = velocity;
    let n = nodes.len();
    let mut f = vec![[0.0; 3]; n];
    let mut forces = |model: &mut ContactModel, nodes: &mut [[f64; 3]], x, v| {
        nodes[0] = x;
        f.iter_mut().for_each(|fi| *fi = [0.0; 3]);
        let mut vel = vec![[0.0; 3]; n];
        vel[0] = v;
        let r = model.add_forces(nodes, &vel, 0.0, dt, &mut f).unwrap();
        ([f[0][0], f[0][1], f[0][2] + force], r.stored_energy)
    };
    let (mut a, mut stored) = forces(&mut model, &mut nodes, x, v);
    let energy = |x: [f64; 3], v: [f64; 3], stored: f64| {
        0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) + stored - force * x[2]
    };
    let e0 = energy(x, v, stored);
    let speed = velocity.iter().map(|c| c * c).sum::<f64>().sqrt();
    let scale = 0.5 * m * speed * speed + stored;
    let mut worst: f64 = 0.0;
    let steps = (0.024 / speed / dt) as usize;
    let (mut touching, mut crossed) = (0, false);
    for _ in 0..steps {
        for d in 0..3 {
            v[d] += 0.5 * dt * a[d] / m;
            x[d] += dt * v[d];
        }
        (a, stored) = forces(&mut model, &mut nodes, x, v);
        for d in 0..3 {
            v[d] += 0.5 * dt * a[d] / m;
        }
        worst = worst.max((energy(x, v, stored) - e0).abs() / scale);
        touching += usize::from(stored > 0.0);
        crossed |= x[0] * start[0] < 0.0 || x[1] * start[1] < 0.0;
    }
    // It crossed the fold, touching the sheet for a good part of the way (it flies off
    // where the ridge falls away, and bounces without damping).
    assert!(crossed, "{x:?}");
    assert!(
        4 * touching > steps,
        "{touching} of {steps} steps in contact"
    );
    worst
}

#[test]
fn a_node_sliding_over_ridges_conserves_energy() {
    // Velocity Verlet's energy error is O((omega dt)^2) where the force is the gradient of
    // a continuous energy: a four times smaller step divides it by about 16 (by 4 at
    // first order, where contacts start or end within a step). A jump of the stored
    // energy where the contact moves over an edge would not shrink with the step. Pressed
    // from below, the probe sits in the pyramid's apex (a well of -F z) and rocks across
    // its ridges, on paths across each ridge near the apex vertex.
    for (start, velocity) in [
        ([-0.012, 0.004], [1.0, 0.0, 0.0]),
        ([0.004, -0.012], [0.0, 1.0, 0.0]),
    ] {
        let (coarse, fine) = (slide(start, velocity, 0.05), slide(start, velocity, 0.0125));
        eprintln!("energy error {coarse:e} at 0.05 sqrt(m/k), {fine:e} at 0.0125");
        assert!(fine < 5e-4, "energy error {fine:e} of the scale");
        assert!(
            coarse / fine > 6.0,
            "{coarse:e} -> {fine:e}: does not converge"
        );
    }
}

#[test]
fn a_new_contact_deeper_than_a_step_can_reach_is_a_fold_artefact() {
    // Margin 4 mm: nodes and sheets move less than 2 mm relative to each other in a step
    // (the tunnelling guard), so a contact that starts deeper is an artefact of a folded
    // sheet (its closest point jumped to another layer) and is discarded; one that goes
    // that deep from the surface is kept.
    let (mut model, mut nodes) = sheet_model(ContactParams::default(), 1e-3, height);
    let n = nodes.len();
    let mut at = |z: f64| {
        let (x, y) = (0.003, 0.002);
        nodes[0] = [x, y, height(x, y) + z];
        let mut f = vec![[0.0; 3]; n];
        model
            .add_forces(&nodes, &vec![[0.0; 3]; n], 0.0, 1e-7, &mut f)
            .unwrap()
    };
    let r = at(-1e-3);
    assert_eq!((r.contacts, r.discarded_sheet_hits), (0, 0), "in front");
    let r = at(3e-3);
    assert_eq!((r.contacts, r.discarded_sheet_hits), (0, 1), "a deep start");
    let r = at(1e-3);
    assert_eq!(
        (r.contacts, r.discarded_sheet_hits),
        (1, 0),
        "a shallow start"
    );
    let r = at(3e-3);
    assert_eq!(
        (r.contacts, r.discarded_sheet_hits),
        (1, 0),
        "deeper from the surface"
    );
    assert!(r.max_depth > 2e-3);
}

/// A flat sheet (body 1, light nodes) draped on a flat particle face (body 0, heavy
/// nodes) that pokes `depth` through it: every sheet node is behind the particle's face
/// and every particle node behind the sheet's, the two-sided contact of a membrane
/// pressed onto a grain. The particle's grid is shifted by `shift` cells so that its
/// nodes press the sheet's faces off their edges.
fn draped(depth: f64, shift: [f64; 2]) -> (ContactModel, Vec<[f64; 3]>, usize) {
    let grid = |n: i32, offset: [f64; 2], z: f64| -> Vec<[f64; 3]> {
        let mut v = Vec::new();
        for i in -n..=n {
            for j in -n..=n {
                v.push([
                    (i as f64 + offset[0]) * CELL,
                    (j as f64 + offset[1]) * CELL,
                    z,
                ]);
            }
        }
        v
    };
    // Triangles of a (2n+1)^2 grid starting at node `first`, normals along `up` (+-z).
    let triangles = |n: i32, first: usize, up: bool| -> Vec<[usize; 3]> {
        let w = (2 * n + 1) as usize;
        let id = |i: usize, j: usize| first + i * w + j;
        let mut t = Vec::new();
        for i in 0..w - 1 {
            for j in 0..w - 1 {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                if up {
                    t.extend([[a, b, c], [a, c, d]]);
                } else {
                    t.extend([[a, c, b], [a, d, c]]);
                }
            }
        }
        t
    };
    // The particle: its face at z = depth, outward normal +z.
    let particle = grid(HALF, shift, depth);
    let sheet = grid(HALF, [0.0, 0.0], 0.0);
    let first_sheet = particle.len();
    let mut tris = triangles(HALF, 0, true);
    let n_particle_tris = tris.len();
    // The sheet's normals point to the particle side (-z): the particle lies below it.
    tris.extend(triangles(HALF, first_sheet, false));
    let nodes: Vec<[f64; 3]> = particle.iter().chain(&sheet).copied().collect();
    let n = nodes.len();
    let surface = ContactSurface {
        triangle_body: (0..tris.len())
            .map(|t| u32::from(t >= n_particle_tris))
            .collect(),
        triangles: tris,
        surface_nodes: (0..n).collect(),
        node_body: (0..n).map(|k| u32::from(k >= first_sheet)).collect(),
        control_areas: vec![CELL * CELL; n],
    };
    let masses: Vec<f64> = (0..n)
        .map(|k| if k >= first_sheet { 1e-3 } else { 1e6 })
        .collect();
    let params = ContactParams {
        damping: 0.0,
        friction: 0.0,
        ..ContactParams::default()
    };
    let mut model = ContactModel::new(params, surface, vec![], &masses, 0.004).unwrap();
    model.set_depth_limit(0.02).unwrap();
    model.set_sheet_bodies(&[1], 0.01).unwrap();
    (model, nodes, first_sheet)
}

/// The stiffness of the contact springs on the normal motion of the sheet's interior
/// nodes (two rings from its edge; the particle and the rest of the sheet held: the
/// membrane has no free edge where it wraps the grains), by central differences of the
/// forces of fresh models (no tangential history): `K[i][j] = -d f_z(i) / d z(j)`.
fn sheet_stiffness(model: &ContactModel, nodes: &[[f64; 3]], first_sheet: usize) -> Vec<Vec<f64>> {
    let n = nodes.len();
    let w = (2 * HALF + 1) as usize;
    let interior = |k: usize| {
        let (i, j) = ((k - first_sheet) / w, (k - first_sheet) % w);
        (2..w - 2).contains(&i) && (2..w - 2).contains(&j)
    };
    let sheet: Vec<usize> = (first_sheet..n).filter(|&k| interior(k)).collect();
    let h = 1e-7;
    let force = |x: &[[f64; 3]]| {
        let mut f = vec![[0.0; 3]; n];
        let mut m = model.clone();
        m.add_forces(x, &vec![[0.0; 3]; n], 0.0, 1e-9, &mut f)
            .unwrap();
        f
    };
    let mut k = vec![vec![0.0; sheet.len()]; sheet.len()];
    for (col, &j) in sheet.iter().enumerate() {
        let (mut up, mut down) = (nodes.to_vec(), nodes.to_vec());
        up[j][2] += h;
        down[j][2] -= h;
        let (fu, fd) = (force(&up), force(&down));
        for (row, &i) in sheet.iter().enumerate() {
            k[row][col] = -(fu[i][2] - fd[i][2]) / (2.0 * h);
        }
    }
    k
}

/// The largest eigenvalue of the symmetric part of `k` (power iteration).
fn largest_eigenvalue(k: &[Vec<f64>]) -> f64 {
    let n = k.len();
    let mut v = vec![1.0; n];
    let mut lambda = 0.0;
    for _ in 0..2000 {
        let w: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| 0.5 * (k[i][j] + k[j][i]) * v[j]).sum())
            .collect();
        let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
        lambda = norm / v.iter().map(|x| x * x).sum::<f64>().sqrt();
        v = w.iter().map(|x| x / norm).collect();
    }
    lambda
}

/// The membrane's two-sided contact in the step bound (docs/MODEL.md section 11): a sheet
/// node's own spring and the particle's nodes pressing its faces act on it together, so
/// the per-spring bound is exceeded, and the sheet nodes' bound `k_i + max(k_i, k_max)`
/// covers the measured highest frequency for grids shifted in several ways.
#[test]
fn a_draped_sheet_node_feels_both_sides_and_its_bound_covers_them() {
    for shift in [[0.3, 0.2], [0.5, 0.5], [0.0, 0.0]] {
        let (model, nodes, first_sheet) = draped(0.2 * CELL, shift);
        let k = sheet_stiffness(&model, &nodes, first_sheet);
        let omega2 = largest_eigenvalue(&k) / 1e-3;
        let per_spring = model.stable_time_step().unwrap().time_step;
        let sheet = model.sheet_stable_time_step().unwrap().time_step;
        let (w_spring, w_sheet) = ((2.0 / per_spring).powi(2), (2.0 / sheet).powi(2));
        assert!(
            omega2 > 1.3 * w_spring,
            "shift {shift:?}: omega^2 {omega2:.4e} not above the per-spring {w_spring:.4e}"
        );
        assert!(
            omega2 <= w_sheet * (1.0 + 1e-6),
            "shift {shift:?}: omega^2 {omega2:.4e} above the sheet bound's {w_sheet:.4e}"
        );
        eprintln!(
            "shift {shift:?}: omega^2 / per-spring {:.3}, / sheet bound {:.3}",
            omega2 / w_spring,
            omega2 / w_sheet
        );
    }
}
