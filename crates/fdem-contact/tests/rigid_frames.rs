//! Rigid bodies' faces met in their template's frame (`ContactModel::set_rigid_frames`):
//! the contacts and forces are those of the world planes, bit for bit, and the frames
//! stand aside when their poses are not of the evaluation's time or do not reproduce the
//! positions.

mod common;

use common::{linear_sphere, model_for, random_rotation, rng};
use fdem_contact::{ContactModel, ContactParams, RigidMotion, RigidPose, RigidTemplate, Wall};
use fdem_core::geometry::{rigid_velocity, rotation_matrix};
use fdem_mesh::{MeshAssembly, Placement, TetMesh};
use rand::RngExt;

type Mat = [[f64; 3]; 3];

fn mul(a: Mat, b: Mat) -> Mat {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

fn transpose(a: Mat) -> Mat {
    std::array::from_fn(|i| std::array::from_fn(|j| a[j][i]))
}

fn apply(a: Mat, v: [f64; 3]) -> [f64; 3] {
    a.map(|row| row[0] * v[0] + row[1] * v[1] + row[2] * v[2])
}

/// The rotation by `angle` about the unit `axis`.
fn turn(axis: [f64; 3], angle: f64) -> Mat {
    let h = 0.5 * angle;
    rotation_matrix([
        h.cos(),
        axis[0] * h.sin(),
        axis[1] * h.sin(),
        axis[2] * h.sin(),
    ])
}

/// The template's surface in the order a placed instance of it has its faces.
fn template_of(mesh: &TetMesh) -> RigidTemplate {
    let mut one = MeshAssembly::new();
    one.push_instance(mesh, &Placement::default()).unwrap();
    RigidTemplate {
        nodes: mesh.nodes.clone(),
        triangles: one.triangles.clone(),
    }
}

/// Eight level-1 spheres of diameter 1 cm and scales 0.9 to 1.1 on a cube's corners,
/// their surfaces overlapping by up to about 0.2 mm, each turning about its own random
/// axis and swaying along another: node positions and poses at `step`.
struct Cluster {
    mesh: TetMesh,
    placements: Vec<Placement>,
    spins: Vec<([f64; 3], f64)>,
    sways: Vec<[f64; 3]>,
}

impl Cluster {
    fn new(seed: u64) -> Cluster {
        let mut r = rng(seed);
        let mesh = linear_sphere(1, 0.01);
        let mut placements = Vec::new();
        for k in 0..8 {
            let corner = [k & 1, (k >> 1) & 1, (k >> 2) & 1].map(|b| 0.0096 * b as f64);
            placements.push(Placement {
                scale: r.random_range(0.99..1.01),
                rotation: random_rotation(&mut r),
                translation: corner,
            });
        }
        let spins = (0..8)
            .map(|_| (common::random_unit(&mut r), r.random_range(-2e-3..2e-3)))
            .collect();
        let sways = (0..8)
            .map(|_| common::scale(common::random_unit(&mut r), 4e-5))
            .collect();
        Cluster {
            mesh,
            placements,
            spins,
            sways,
        }
    }

    fn assembly(&self) -> MeshAssembly {
        let mut a = MeshAssembly::new();
        for p in &self.placements {
            a.push_instance(&self.mesh, p).unwrap();
        }
        a
    }

    /// Each body's map `x = origin + A t` at `step`: origin and `A` (a rotation times the
    /// scale).
    fn maps(&self, step: usize) -> Vec<([f64; 3], Mat, f64)> {
        self.placements
            .iter()
            .zip(&self.spins)
            .zip(&self.sways)
            .map(|((p, &(axis, rate)), &sway)| {
                let turned = mul(turn(axis, rate * step as f64), rotation_matrix(p.rotation));
                let shift = common::scale(sway, (0.2 * step as f64).sin());
                let a = turned.map(|row| row.map(|v| v * p.scale));
                (common::add(p.translation, shift), a, p.scale)
            })
            .collect()
    }

    fn positions(&self, step: usize) -> Vec<[f64; 3]> {
        let mut x = Vec::new();
        for (origin, a, _) in self.maps(step) {
            x.extend(
                self.mesh
                    .nodes
                    .iter()
                    .map(|&t| common::add(origin, apply(a, t))),
            );
        }
        x
    }

    /// Each body's velocity, spin and centre at `step` (1 microsecond steps): the sway's
    /// rate and the turn's.
    fn moves(&self, step: usize) -> Vec<RigidMove> {
        self.maps(step)
            .into_iter()
            .zip(self.spins.iter().zip(&self.sways))
            .map(|((origin, _, _), (&(axis, rate), &sway))| {
                let velocity = common::scale(sway, 0.2e6 * (0.2 * step as f64).cos());
                [velocity, common::scale(axis, 1e6 * rate), origin]
            })
            .collect()
    }

    fn poses(&self, step: usize) -> Vec<RigidPose> {
        self.maps(step)
            .into_iter()
            .map(|(origin, a, s)| RigidPose {
                to_template: transpose(a).map(|row| row.map(|v| v / (s * s))),
                origin,
                scale: s,
            })
            .collect()
    }
}

fn models(cluster: &Cluster) -> (ContactModel, ContactModel, MeshAssembly) {
    models_with(cluster, vec![])
}

fn models_with(cluster: &Cluster, walls: Vec<Wall>) -> (ContactModel, ContactModel, MeshAssembly) {
    let assembly = cluster.assembly();
    let params = ContactParams {
        friction: 0.3,
        ..ContactParams::default()
    };
    let margin = 2e-4;
    let mut plain = model_for(&assembly, params, walls, 1e-4, Some(margin));
    plain.set_depth_limit(2e-3).unwrap();
    let mut framed = plain.clone();
    let template = template_of(&cluster.mesh);
    let bodies: Vec<(u32, usize)> = (0..8).map(|b| (b, 0)).collect();
    framed
        .set_rigid_frames(
            &[template],
            &bodies,
            (0.0, &cluster.poses(0)),
            &cluster.positions(0),
        )
        .unwrap();
    (plain, framed, assembly)
}

/// Each body's motion as a caller gives it, its nodes' largest speed in `v` (the eight
/// bodies' nodes in order) times `room` as the bound; `rigid` the bodies' velocities, spins
/// and centres (none: at rest).
fn motions(v: &[[f64; 3]], room: f64, rigid: Option<&[RigidMove]>) -> Vec<RigidMotion> {
    v.chunks(v.len() / 8)
        .enumerate()
        .map(|(b, body)| {
            let [velocity, angular_velocity, centre] = rigid.map_or([[0.0; 3]; 3], |r| r[b]);
            RigidMotion {
                speed_bound: room * body.iter().map(|&a| common::norm(a)).fold(0.0, f64::max),
                finite: true,
                velocity,
                angular_velocity,
                centre,
            }
        })
        .collect()
}

/// A body's velocity, spin and centre.
type RigidMove = [[f64; 3]; 3];

#[test]
fn frames_give_the_contacts_and_forces_of_the_world_planes_bit_for_bit() {
    let cluster = Cluster::new(3);
    let (mut plain, mut framed, assembly) = models(&cluster);
    let n = assembly.n_nodes();
    let mut max_contacts = 0;
    for step in 0..300 {
        let (x, t) = (cluster.positions(step), step as f64 * 1e-6);
        // Node velocities of rigid motions, as a solver places them.
        let (v, moves) = velocities(&cluster, &x, step);
        if step % 3 == 0 {
            framed.set_rigid_poses(t, &cluster.poses(step)).unwrap();
        } else {
            // Exchanged, not copied: the vector comes back with the poses held before.
            let mut given = cluster.poses(step);
            framed.exchange_rigid_poses(t, &mut given).unwrap();
            assert_eq!(given, cluster.poses(step - 1));
            // A wrong count is refused and leaves the vector as it was.
            let mut short = cluster.poses(step)[1..].to_vec();
            assert!(framed.exchange_rigid_poses(t, &mut short).is_err());
            assert_eq!(short, cluster.poses(step)[1..]);
        }
        // With their motions on every other step: the scan need not read their nodes, nor
        // the narrow phase their faces' velocities.
        if step % 2 == 0 {
            let mut m = motions(&v, 1.0 + 1e-9, Some(&moves));
            if step % 4 == 0 {
                framed.set_rigid_motions(t, &m).unwrap();
            } else {
                framed.exchange_rigid_motions(t, &mut m).unwrap();
                let (v_before, moves_before) =
                    velocities(&cluster, &cluster.positions(step - 2), step - 2);
                assert_eq!(m, motions(&v_before, 1.0 + 1e-9, Some(&moves_before)));
            }
        }
        let (mut fa, mut fb) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        let a = plain.add_forces(&x, &v, t, 1e-6, &mut fa).unwrap();
        let b = framed.add_forces(&x, &v, t, 1e-6, &mut fb).unwrap();
        assert!(framed.rigid_frames_in_use() && !plain.rigid_frames_in_use());
        assert_eq!(fa, fb, "step {step}");
        assert_eq!(a.contacts, b.contacts, "step {step}");
        assert_eq!(
            plain.candidate_pairs(),
            framed.candidate_pairs(),
            "step {step}"
        );
        assert_eq!(a.stored_energy.to_bits(), b.stored_energy.to_bits());
        max_contacts = max_contacts.max(a.contacts);
    }
    eprintln!(
        "up to {max_contacts} contacts, {} builds, {} refreshes",
        plain.rebuild_count(),
        plain.refresh_count()
    );
    assert!(max_contacts >= 10, "{max_contacts} contacts");
    assert!(plain.rebuild_count() + plain.refresh_count() > 2);
    // The poses' drift bounds renewed the lists when the nodes did.
    assert_eq!(plain.rebuild_count(), framed.rebuild_count());
    assert_eq!(plain.refresh_count(), framed.refresh_count());
}

/// Node velocities of the cluster's rigid motions at `step`, as a solver places them, and
/// those motions.
fn velocities(cluster: &Cluster, x: &[[f64; 3]], step: usize) -> (Vec<[f64; 3]>, Vec<RigidMove>) {
    let moves = cluster.moves(step);
    let per_body = x.len() / 8;
    let v = x
        .iter()
        .enumerate()
        .map(|(i, &xi)| {
            let [velocity, spin, centre] = moves[i / per_body];
            rigid_velocity(velocity, spin, centre, xi)
        })
        .collect();
    (v, moves)
}

/// With poses and motions, the narrow phase passes over the nodes without candidates of
/// the bodies clear of the walls (a ball from the pose, the margin and a step's motion
/// away): the contacts, forces and errors are those of the model that visits every node.
/// A floor rises into the cluster's lower bodies while the upper ones stay clear of it;
/// then a floor too fast for the depth limit must trip the same tunnelling check.
#[test]
fn nodes_clear_of_the_walls_are_passed_over_with_the_same_contacts_and_errors() {
    let cluster = Cluster::new(5);
    let floor = Wall::plane([0.0, 0.0, -0.0062], [0.0, 0.0, 1.0]).moving([0.0, 0.0, 10.0]);
    let side = Wall::plane([0.1, 0.0, 0.0], [-1.0, 0.0, 0.0]);
    let (mut plain, mut framed, assembly) = models_with(&cluster, vec![floor, side]);
    let n = assembly.n_nodes();
    let mut wall_contacts = 0;
    for step in 0..300 {
        let (x, t) = (cluster.positions(step), step as f64 * 1e-6);
        let (v, moves) = velocities(&cluster, &x, step);
        framed.set_rigid_poses(t, &cluster.poses(step)).unwrap();
        let m = motions(&v, 1.0 + 1e-9, Some(&moves));
        framed.set_rigid_motions(t, &m).unwrap();
        let (mut fa, mut fb) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        let a = plain.add_forces(&x, &v, t, 1e-6, &mut fa).unwrap();
        let b = framed.add_forces(&x, &v, t, 1e-6, &mut fb).unwrap();
        assert_eq!(fa, fb, "step {step}");
        assert_eq!(a.contacts, b.contacts, "step {step}");
        assert_eq!(a.wall_contacts, b.wall_contacts, "step {step}");
        assert_eq!(plain.wall_forces(), framed.wall_forces(), "step {step}");
        wall_contacts = wall_contacts.max(a.wall_contacts);
    }
    assert!(wall_contacts >= 10, "{wall_contacts} wall contacts");

    // A floor that moves farther in a step than the reach, a millimetre and a half below
    // the lower bodies: farther than the margin, nearer than the margin and its travel.
    let fast = Wall::plane([0.0, 0.0, -0.0065], [0.0, 0.0, 1.0]).moving([0.0, 0.0, 3000.0]);
    let (mut plain, mut framed, _) = models_with(&cluster, vec![fast, side]);
    let (x, t) = (cluster.positions(0), 0.0);
    let (v, moves) = velocities(&cluster, &x, 0);
    framed.set_rigid_poses(t, &cluster.poses(0)).unwrap();
    framed
        .set_rigid_motions(t, &motions(&v, 1.0 + 1e-9, Some(&moves)))
        .unwrap();
    let (mut fa, mut fb) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
    let a = plain.add_forces(&x, &v, t, 1e-6, &mut fa).unwrap_err();
    let b = framed.add_forces(&x, &v, t, 1e-6, &mut fb).unwrap_err();
    assert!(a.to_string().contains("wall"), "{a}");
    assert_eq!(a.to_string(), b.to_string());
}

/// The scan takes a body's motion for its nodes' speeds: nodes moving too fast for the
/// depth limit (at the limit's cap) are refused when the scan reads them (no motion, or a
/// bound that says so; with a motion their speeds are the motion's) and not when the
/// caller's bound says the bodies are slow. A caller must give a true bound.
#[test]
fn the_scan_takes_the_motions_bound_for_the_nodes_speeds() {
    let cluster = Cluster::new(6);
    let (_, framed, assembly) = models(&cluster);
    let n = assembly.n_nodes();
    let x = cluster.positions(0);
    let dt = 1e-6;
    let limit = framed.depth_limit();
    // Every body moving as one at 0.6 depth limits per step: twice that passes the
    // bound, while no node moves relative to a face.
    let fast = [0.6 * limit / dt, 0.0, 0.0];
    let v = vec![fast; n];
    let moves = vec![[fast, [0.0; 3], [0.0; 3]]; 8];
    // Each body's velocity, with its nodes' largest speed times `room` as the bound.
    let given = |room: f64| Some(motions(&v, room, Some(&moves)));
    let refused = |motions: Option<Vec<RigidMotion>>| {
        let mut model = framed.clone();
        model.set_rigid_poses(0.0, &cluster.poses(0)).unwrap();
        if let Some(m) = motions {
            model.set_rigid_motions(0.0, &m).unwrap();
        }
        let mut f = vec![[0.0; 3]; n];
        match model.add_forces(&x, &v, 0.0, dt, &mut f) {
            Ok(_) => {
                assert!(model.rigid_frames_in_use());
                false
            }
            Err(e) => {
                let message = e.to_string();
                assert!(message.contains("twice its speed"), "{message}");
                true
            }
        }
    };
    assert!(refused(None));
    assert!(refused(given(1.0)));
    assert!(!refused(given(0.5)));
}

/// With the motions of its time, an evaluation takes every framed node's velocity from
/// its body's motion and never reads that node's entry of the velocities (the node's own,
/// a face corner's, the tunnelling check's, the scan's): with absurd entries the contacts,
/// forces and wall forces are those of a model given the placed velocities, bit for bit.
/// A floor rises into the lower bodies (wall contacts), the step is long enough that the
/// faces' tunnelling check runs, and every other step the motions' speed bounds are
/// infinite, so that the scan reads the nodes.
#[test]
fn with_the_motions_of_its_time_an_evaluation_reads_no_framed_node_velocity() {
    let cluster = Cluster::new(5);
    let floor = Wall::plane([0.0, 0.0, -0.0062], [0.0, 0.0, 1.0]).moving([0.0, 0.0, 10.0]);
    let (mut plain, mut framed, assembly) = models_with(&cluster, vec![floor]);
    let n = assembly.n_nodes();
    let absurd = vec![[1e6, -1e6, 1e6]; n];
    let (mut contacts, mut wall_contacts) = (0, 0);
    for step in 0..300 {
        let (x, t) = (cluster.positions(step), step as f64 * 1e-6);
        let (v, moves) = velocities(&cluster, &x, step);
        // Twice the fastest node's travel in a step is the margin (2e-4 m): above the
        // reach (half the margin) that turns the faces' tunnelling check on, below the one
        // that trips it (half the depth limit, 1e-3 m).
        let v_max = v.iter().map(|&a| common::norm(a)).fold(0.0, f64::max);
        let dt = 1e-4 / v_max;
        framed.set_rigid_poses(t, &cluster.poses(step)).unwrap();
        // Every other step a speed bound that decides nothing: the scan reads the nodes.
        let room = if step % 2 == 0 {
            1.0 + 1e-9
        } else {
            f64::INFINITY
        };
        let m = motions(&v, room, Some(&moves));
        framed.set_rigid_motions(t, &m).unwrap();
        let (mut fa, mut fb) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        let a = plain.add_forces(&x, &v, t, dt, &mut fa).unwrap();
        let b = framed.add_forces(&x, &absurd, t, dt, &mut fb).unwrap();
        assert_eq!(fa, fb, "step {step}");
        assert_eq!(a.contacts, b.contacts, "step {step}");
        assert_eq!(a.wall_contacts, b.wall_contacts, "step {step}");
        assert_eq!(plain.wall_forces(), framed.wall_forces(), "step {step}");
        assert_eq!(a.stored_energy.to_bits(), b.stored_energy.to_bits());
        contacts = contacts.max(a.contacts);
        wall_contacts = wall_contacts.max(a.wall_contacts);
    }
    assert!(contacts >= 10, "{contacts} contacts");
    assert!(wall_contacts >= 10, "{wall_contacts} wall contacts");
}

#[test]
fn frames_stand_aside_without_poses_of_the_time_or_when_off_the_positions() {
    let cluster = Cluster::new(4);
    let (_, mut framed, assembly) = models(&cluster);
    let n = assembly.n_nodes();
    let x = cluster.positions(5);
    let v = vec![[0.0; 3]; n];
    let mut f = vec![[0.0; 3]; n];
    // Poses of step 0, positions of step 5 at another time: the world planes serve.
    framed.add_forces(&x, &v, 5e-6, 1e-6, &mut f).unwrap();
    assert!(!framed.rigid_frames_in_use());
    framed.set_rigid_poses(5e-6, &cluster.poses(5)).unwrap();
    framed.add_forces(&x, &v, 5e-6, 1e-6, &mut f).unwrap();
    assert!(framed.rigid_frames_in_use());
    // Poses a micrometre off the positions they were set with: never used.
    let mut off = cluster.poses(0);
    off[3].origin[0] += 1e-6;
    let mut model = models(&cluster).0;
    let bodies: Vec<(u32, usize)> = (0..8).map(|b| (b, 0)).collect();
    model
        .set_rigid_frames(
            &[template_of(&cluster.mesh)],
            &bodies,
            (0.0, &off),
            &cluster.positions(0),
        )
        .unwrap();
    model
        .add_forces(&cluster.positions(0), &v, 0.0, 1e-6, &mut f)
        .unwrap();
    assert!(!model.rigid_frames_in_use());
}

#[test]
fn frames_that_do_not_fit_the_surface_are_refused() {
    let cluster = Cluster::new(5);
    let (mut plain, _, _) = models(&cluster);
    let x = cluster.positions(0);
    let poses = cluster.poses(0);
    let template = template_of(&cluster.mesh);
    let mut short = template.clone();
    short.triangles.pop();
    let all: Vec<(u32, usize)> = (0..8).map(|b| (b, 0)).collect();
    // (templates, bodies with their template, poses given)
    type Case = (Vec<RigidTemplate>, Vec<(u32, usize)>, usize);
    let cases: Vec<Case> = vec![
        (vec![short], all.clone(), 8),
        (vec![template.clone()], vec![(0, 1)], 1),
        (vec![template.clone()], vec![(0, 0), (0, 0)], 2),
        (vec![template.clone()], all.clone(), 7),
    ];
    for (templates, bodies, n_poses) in cases {
        let message = plain
            .set_rigid_frames(&templates, &bodies, (0.0, &poses[..n_poses]), &x)
            .unwrap_err()
            .to_string();
        assert!(message.contains("rigid"), "{message}");
    }
    assert!(
        plain.set_rigid_poses(0.0, &poses).is_err(),
        "poses before frames"
    );
    // A face naming a node the template does not have, a pose that is not a number, a
    // scale that is not positive, a map that is not a rotation: refused, nothing panics.
    let mut beyond = template.clone();
    beyond.triangles[0][1] = beyond.nodes.len();
    let mut nan = poses.clone();
    nan[2].origin[1] = f64::NAN;
    let mut flat = poses.clone();
    flat[5].scale = 0.0;
    let mut stretched = poses.clone();
    stretched[1].to_template[0] = stretched[1].to_template[0].map(|v| 1.01 * v);
    for (templates, poses) in [
        (vec![beyond], poses.clone()),
        (vec![template.clone()], nan),
        (vec![template.clone()], flat),
        (vec![template.clone()], stretched),
    ] {
        assert!(
            plain
                .set_rigid_frames(&templates, &all, (0.0, &poses), &x)
                .is_err()
        );
    }
    // A body is a sheet or a rigid body with a frame, never both, in either order.
    let mut sheet_first = plain.clone();
    sheet_first.set_sheet_bodies(&[2], 1e-4).unwrap();
    let message = sheet_first
        .set_rigid_frames(std::slice::from_ref(&template), &all, (0.0, &poses), &x)
        .unwrap_err()
        .to_string();
    assert!(message.contains("sheet"), "{message}");
    plain
        .set_rigid_frames(&[template], &all, (0.0, &poses), &x)
        .unwrap();
    assert!(plain.set_sheet_bodies(&[2], 1e-4).is_err());
}

/// Full builds and refreshes meet the framed bodies body by body (the broad phase's
/// `framed` module): their lists are the grids', pair for pair, in a packing of 27 bodies
/// of two templates (a sphere and an ellipsoid of axes 1, 0.8, 0.6) and several sizes, the
/// middle one without a frame, moved by random rigid motions: at every build, then at
/// every refresh of a few bodies (framed or not, dirty or beside dirty ones).
#[test]
fn builds_and_refreshes_with_frames_list_the_pairs_of_the_grids() {
    let mut r = rng(21);
    let sphere = linear_sphere(1, 0.01);
    let mut egg = sphere.clone();
    for n in &mut egg.nodes {
        n[1] *= 0.8;
        n[2] *= 0.6;
    }
    let meshes = [sphere, egg];
    let mut bodies = Vec::new();
    for k in 0..27usize {
        let cell = [k % 3, (k / 3) % 3, k / 9].map(|c| 0.0091 * c as f64);
        let jitter = common::scale(common::random_unit(&mut r), 1e-4);
        let rotation = rotation_matrix(random_rotation(&mut r));
        let s = r.random_range(0.985..1.015);
        bodies.push((k % 2, common::add(cell, jitter), rotation, s));
    }
    let assembly = {
        let mut a = MeshAssembly::new();
        for &(mesh, _, _, _) in &bodies {
            a.push_instance(&meshes[mesh], &Placement::default())
                .unwrap();
        }
        a
    };
    let params = ContactParams {
        friction: 0.3,
        ..ContactParams::default()
    };
    let mut plain = model_for(&assembly, params, vec![], 1e-4, Some(1e-3));
    plain.set_depth_limit(3e-3).unwrap();
    let mut framed = plain.clone();
    let templates = [template_of(&meshes[0]), template_of(&meshes[1])];
    let unframed = 13;
    let with_frames: Vec<(u32, usize)> = (0..27)
        .filter(|&b| b != unframed)
        .map(|b| (b as u32, bodies[b].0))
        .collect();
    let place = |bodies: &[(usize, [f64; 3], Mat, f64)]| {
        let mut x = Vec::new();
        for &(mesh, origin, rotation, s) in bodies {
            let a = rotation.map(|row| row.map(|v| v * s));
            x.extend(
                meshes[mesh]
                    .nodes
                    .iter()
                    .map(|&t| common::add(origin, apply(a, t))),
            );
        }
        let poses: Vec<RigidPose> = with_frames
            .iter()
            .map(|&(b, _)| {
                let (_, origin, rotation, s) = bodies[b as usize];
                RigidPose {
                    to_template: transpose(rotation).map(|row| row.map(|v| v / s)),
                    origin,
                    scale: s,
                }
            })
            .collect();
        (x, poses)
    };
    let (x, poses) = place(&bodies);
    framed
        .set_rigid_frames(&templates, &with_frames, (0.0, &poses), &x)
        .unwrap();
    let n = assembly.n_nodes();
    let v = vec![[0.0; 3]; n];
    for round in 0..8 {
        let t = round as f64 * 1e-6;
        if round > 0 {
            for body in &mut bodies {
                let spin = turn(common::random_unit(&mut r), r.random_range(-0.05..0.05));
                body.2 = mul(spin, body.2);
                let shift = common::scale(common::random_unit(&mut r), r.random_range(0.0..1e-4));
                body.1 = common::add(body.1, shift);
            }
        }
        let (x, poses) = place(&bodies);
        framed.set_rigid_poses(t, &poses).unwrap();
        plain.request_rebuild();
        framed.request_rebuild();
        let (mut fa, mut fb) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        let a = plain.add_forces(&x, &v, t, 1e-6, &mut fa).unwrap();
        let b = framed.add_forces(&x, &v, t, 1e-6, &mut fb).unwrap();
        assert!(framed.rigid_frames_in_use(), "round {round}");
        let pairs = plain.candidate_pairs();
        eprintln!(
            "round {round}: {} pairs, {} contacts",
            pairs.len(),
            a.contacts
        );
        assert!(pairs.len() > 500, "round {round}: {} pairs", pairs.len());
        assert_eq!(pairs, framed.candidate_pairs(), "round {round}");
        assert_eq!(fa, fb, "round {round}");
        assert!(
            a.contacts > 20 && a.contacts == b.contacts,
            "{} contacts",
            a.contacts
        );
    }
    assert_eq!(framed.rebuild_count(), 8);
    // Then a refresh at a time: three bodies drift past half the skin, the others stay (a
    // policy that refreshes up to half the nodes).
    let policy = fdem_contact::RefreshPolicy {
        max_fraction: 0.5,
        max_refreshed_fraction: 1.0,
        ..fdem_contact::RefreshPolicy::default()
    };
    plain.set_refresh_policy(policy).unwrap();
    framed.set_refresh_policy(policy).unwrap();
    for round in 8..16 {
        let t = round as f64 * 1e-6;
        // Every other round the body without a frame stays and two of its neighbours move.
        let (a, b) = ((round * 5) % 27, (round * 11 + 3) % 27);
        let moved = if round % 2 == 0 {
            [13, a, b]
        } else {
            [4, 22, a]
        };
        for &b in &moved {
            let spin = turn(common::random_unit(&mut r), r.random_range(-0.05..0.05));
            bodies[b].2 = mul(spin, bodies[b].2);
            let shift = common::scale(common::random_unit(&mut r), 6e-4);
            bodies[b].1 = common::add(bodies[b].1, shift);
        }
        let (x, poses) = place(&bodies);
        framed.set_rigid_poses(t, &poses).unwrap();
        let (mut fa, mut fb) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        plain.add_forces(&x, &v, t, 1e-6, &mut fa).unwrap();
        framed.add_forces(&x, &v, t, 1e-6, &mut fb).unwrap();
        assert!(framed.rigid_frames_in_use(), "round {round}");
        assert_eq!(
            plain.candidate_pairs(),
            framed.candidate_pairs(),
            "round {round}"
        );
        assert_eq!(fa, fb, "round {round}");
    }
    assert_eq!(plain.refresh_count(), framed.refresh_count());
    assert!(
        framed.refresh_count() >= 6,
        "{} refreshes",
        framed.refresh_count()
    );
}
