//! The model builder: typed handles reach contributions between steps, constraints run
//! after every force, contributions' bounds enter the stable step, a hand-built model is
//! the scene's model bit for bit, and inconsistent models are refused with one message.

// Component loops over x, y, z read best with an index.
#![allow(clippy::needless_range_loop)]

use fdem_contact::{ContactParams, Wall};
use fdem_elastic::Material;
use fdem_mesh::{ElementOrder, Placement, Sizing, SphereSpec, TetMesh, sphere_mesh};
use fdem_solver::{
    Constraint, ContactSettings, ForceContribution, InitialMotion, ModelBuilder, NodeView, Powers,
    Scene, SheetBody, SolverError, StepBound, TimeStep,
};
use std::ops::Range;

fn template(order: ElementOrder) -> TetMesh {
    sphere_mesh(&SphereSpec {
        level: 1,
        order,
        diameter: 1.0,
        sizing: Sizing::Inscribed,
    })
    .unwrap()
}

fn material() -> Material {
    Material::new(2650.0, 40.0e9, 0.2).unwrap()
}

fn at(x: f64) -> Placement {
    Placement {
        scale: 0.01,
        ..Placement::at([x, 0.0, 0.0])
    }
}

/// A uniform force on a range of nodes, changed by the driver between steps; its power
/// `f . v` is external work.
struct Load {
    nodes: Range<usize>,
    force: [f64; 3],
}

impl ForceContribution for Load {
    fn name(&self) -> &str {
        "load"
    }
    fn stable_time_step(&self, _masses: &[f64]) -> Option<StepBound> {
        None
    }
    fn add_forces(
        &mut self,
        nodes: NodeView<'_>,
        forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError> {
        let mut power = 0.0;
        for i in self.nodes.clone() {
            for k in 0..3 {
                forces[i][k] += self.force[k];
                power += self.force[k] * nodes.velocities[i][k];
            }
        }
        Ok(Powers {
            external: power,
            ..Powers::default()
        })
    }
    fn potential_energy(&self, _nodes: NodeView<'_>) -> f64 {
        0.0
    }
}

/// Holds nodes at rest: zeroes their force (their velocity starts at zero).
struct Hold {
    nodes: Range<usize>,
    seen: [f64; 3],
}

impl Constraint for Hold {
    fn name(&self) -> &str {
        "hold"
    }
    fn apply(
        &mut self,
        nodes: NodeView<'_>,
        forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError> {
        let mut power = 0.0;
        self.seen = [0.0; 3];
        for i in self.nodes.clone() {
            for k in 0..3 {
                self.seen[k] += forces[i][k];
                power -= forces[i][k] * nodes.velocities[i][k];
            }
            forces[i] = [0.0; 3];
        }
        Ok(Powers {
            external: power,
            ..Powers::default()
        })
    }
}

/// A spring of stiffness `k` on node 0 towards its reference position: its bound is
/// `2 sqrt(m / k)`.
struct Spring {
    k: f64,
}

impl ForceContribution for Spring {
    fn name(&self) -> &str {
        "spring"
    }
    fn stable_time_step(&self, masses: &[f64]) -> Option<StepBound> {
        Some(StepBound {
            dt: 2.0 * (masses[0] / self.k).sqrt(),
            source: "spring on node 0".into(),
        })
    }
    fn add_forces(&mut self, _: NodeView<'_>, _: &mut [[f64; 3]]) -> Result<Powers, SolverError> {
        Ok(Powers::default())
    }
    fn potential_energy(&self, _nodes: NodeView<'_>) -> f64 {
        0.0
    }
}

/// A free particle under a load switched on through its handle: velocity Verlet moves
/// the centre of mass exactly as `p = F t` for a constant force from its first kick (1e-12 relative for
/// round-off), the energy balance closes to 1e-5 of the load's work (the half-step
/// booking of a force switched on between steps; measured 1.7e-6), and the load switched off again leaves the momentum constant after its last half kick.
#[test]
fn a_driver_changes_a_contribution_through_its_handle() {
    let mut model = ModelBuilder::new();
    let body = model
        .add_deformable(
            &template(ElementOrder::Linear),
            &at(0.0),
            &material(),
            InitialMotion::default(),
        )
        .unwrap();
    let nodes = model.body(body).unwrap().nodes.clone();
    let n = nodes.len() as f64;
    let load = model.add_contribution(Load {
        nodes,
        force: [0.0; 3],
    });
    let mut sim = model.build().unwrap();
    for _ in 0..10 {
        sim.advance().unwrap();
    }
    let v = sim.bodies()[0].motion(sim.state()).velocity;
    assert!(v.iter().all(|c| c.abs() < 1e-20), "{v:?}");
    let f = 1e-3;
    sim.get_mut(load).force = [0.0, 0.0, f];
    let (t0, steps) = (sim.time(), 400);
    for _ in 0..steps {
        sim.advance().unwrap();
    }
    // The load set between steps acts from the next force evaluation, after the first
    // half kick: velocity Verlet gives p = F (t - t0 - dt/2).
    let m = sim.bodies()[0].motion(sim.state());
    let expected = n * f * (sim.time() - t0 - 0.5 * sim.dt());
    assert!(
        (m.mass * m.velocity[2] / expected - 1.0).abs() < 1e-12,
        "{} vs {expected}",
        m.mass * m.velocity[2]
    );
    let e = sim.energy();
    assert!(e.external_work > 0.0);
    assert!(e.balance_error.abs() < 1e-5 * e.external_work, "{e:?}");
    sim.get_mut(load).force = [0.0; 3];
    // The force of the last evaluation still gives its half kick: p + F dt/2 from then on.
    let p = m.mass * m.velocity[2] + 0.5 * n * f * sim.dt();
    for _ in 0..100 {
        sim.advance().unwrap();
    }
    let m = sim.bodies()[0].motion(sim.state());
    assert!((m.mass * m.velocity[2] / p - 1.0).abs() < 1e-12);
    assert_eq!(sim.get(load).force, [0.0; 3]);
}

/// A constraint added before the load still sees it: constraints are a pass after all
/// forces. The held particle stays at rest (bit for bit: its forces are zeroed), the
/// constraint saw the whole load, and the reaction's work cancels the load's.
#[test]
fn constraints_run_after_every_force_whatever_the_order_added() {
    let mut model = ModelBuilder::new();
    let body = model
        .add_deformable(
            &template(ElementOrder::Linear),
            &at(0.0),
            &material(),
            InitialMotion::default(),
        )
        .unwrap();
    let nodes = model.body(body).unwrap().nodes.clone();
    let n = nodes.len() as f64;
    let hold = model.add_constraint(Hold {
        nodes: nodes.clone(),
        seen: [0.0; 3],
    });
    model.add_contribution(Load {
        nodes,
        force: [0.0, 0.0, 1.0],
    });
    let mut sim = model.build().unwrap();
    let x0 = sim.state().positions.clone();
    for _ in 0..50 {
        sim.advance().unwrap();
    }
    assert_eq!(sim.state().positions, x0);
    assert!((sim.constraint(hold).seen[2] - n).abs() < 1e-9 * n);
    let e = sim.energy();
    assert_eq!(e.external_work, 0.0);
    assert_eq!(e.kinetic, 0.0);
}

/// The smallest bound of a contribution sets the step when it is below the elastic one;
/// summary and errors then name it.
#[test]
fn a_contribution_bound_enters_the_stable_step() {
    let build = |k: f64| {
        let mut model = ModelBuilder::new();
        model
            .add_deformable(
                &template(ElementOrder::Linear),
                &at(0.0),
                &material(),
                InitialMotion::default(),
            )
            .unwrap();
        model.add_contribution(Spring { k });
        model.set_time_step(TimeStep::Automatic { safety: 0.5 });
        model.build().unwrap()
    };
    let soft = build(1.0);
    assert!(
        soft.bound().source.starts_with("elastic"),
        "{}",
        soft.bound().source
    );
    let stiff = build(1e15);
    let m0 = stiff.state().masses[0];
    let bound = 2.0 * (m0 / 1e15).sqrt();
    assert_eq!(stiff.bound().source, "spring on node 0");
    assert_eq!(stiff.bound().dt, bound);
    assert_eq!(stiff.dt(), 0.5 * bound);
}

/// Two particles with contact and a wall assembled by hand are the scene's model: the
/// same step, bound and, after 1000 steps (in contact), the same positions bit for bit.
#[test]
fn a_model_built_by_hand_is_the_scene_model() {
    let scene = Scene::from_toml_str(
        r#"
[simulation]
duration = 1.0
dt_safety = 0.4
[material]
density = 2650.0
youngs_modulus = 40.0e9
poisson_ratio = 0.2
[[particle]]
diameter = 0.01
center = [0.0, 0.0, 0.0]
velocity = [2.0, 0.0, 0.0]
[[particle]]
diameter = 0.01
center = [0.01002, 0.0, 0.0]
[[wall]]
type = "plane"
point = [0.0, 0.0, -0.0051]
normal = [0.0, 0.0, 1.0]
"#,
        "test",
    )
    .unwrap();
    let mut by_scene = scene.build().unwrap();
    let mut model = ModelBuilder::new();
    let t = template(ElementOrder::Linear);
    let moving = InitialMotion {
        velocity: [2.0, 0.0, 0.0],
        ..InitialMotion::default()
    };
    model
        .add_deformable(&t, &at(0.0), &material(), moving)
        .unwrap();
    model
        .add_deformable(&t, &at(0.01002), &material(), InitialMotion::default())
        .unwrap();
    let margin = 0.25 * model.shortest_surface_edge().unwrap();
    model.add_wall(Wall::plane([0.0, 0.0, -0.0051], [0.0, 0.0, 1.0]));
    model.set_contact(ContactSettings {
        params: ContactParams::default(),
        margin,
        depth_limit: None,
        depth_limit_cap: None,
        sheet_fold_depth: None,
    });
    model.set_time_step(TimeStep::Automatic { safety: 0.4 });
    let mut by_hand = model.build().unwrap();
    assert_eq!(by_hand.dt(), by_scene.dt());
    assert_eq!(by_hand.bound(), by_scene.bound());
    let mut touched = false;
    for _ in 0..1000 {
        by_scene.advance().unwrap();
        by_hand.advance().unwrap();
        touched |= !by_hand
            .contact()
            .unwrap()
            .model()
            .node_contacts()
            .is_empty();
    }
    assert!(
        touched,
        "the particles never touched: {:e} s",
        by_hand.time()
    );
    assert_eq!(by_hand.state().positions, by_scene.state().positions);
}

fn refusal(model: ModelBuilder) -> String {
    match model.build() {
        Ok(_) => panic!("the model was accepted"),
        Err(e) => e.to_string(),
    }
}

fn sheet(faces: Vec<[usize; 3]>) -> SheetBody {
    SheetBody {
        positions: vec![[0.1, 0.0, 0.0], [0.1, 0.01, 0.0], [0.1, 0.0, 0.01]],
        masses: vec![1e-3; 3],
        triangles: faces,
        control_areas: vec![1e-5; 3],
    }
}

/// Linear and quadratic particles sit side by side in one model: each keeps its own
/// element order in the connectivity, body by body.
#[test]
fn linear_and_quadratic_particles_share_a_model() {
    let (linear, quadratic) = (
        template(ElementOrder::Linear),
        template(ElementOrder::Quadratic),
    );
    let mut mixed = ModelBuilder::new();
    let still = InitialMotion::default();
    mixed
        .add_deformable(&linear, &at(0.0), &material(), still)
        .unwrap();
    mixed
        .add_deformable(&quadratic, &at(0.1), &material(), still)
        .unwrap();
    let sim = mixed.build().unwrap();
    let elements = sim.connectivity();
    assert_eq!(elements.len(), linear.n_elements() + quadratic.n_elements());
    let counts = elements.node_counts();
    for (b, npe) in sim.bodies().iter().zip([4, 10]) {
        assert!(counts[b.elements.clone()].iter().all(|&n| n == npe));
        // Every element's nodes belong to its body.
        for e in b.elements.clone() {
            let nodes = elements.element(e).unwrap();
            assert!(nodes.iter().all(|n| b.nodes.contains(n)), "{nodes:?}");
        }
    }
    assert_eq!(elements.element(elements.len()), None);
}

/// Inconsistent models are refused with one message that says what to change.
#[test]
fn inconsistent_models_are_refused_with_what_to_change() {
    let linear = template(ElementOrder::Linear);
    let still = InitialMotion::default();
    let mut walls = ModelBuilder::new();
    walls
        .add_deformable(&linear, &at(0.0), &material(), still)
        .unwrap();
    walls.add_wall(Wall::plane([0.0; 3], [0.0, 0.0, 1.0]));
    assert!(refusal(walls).contains("give it contact settings"));

    let mut folds = ModelBuilder::new();
    folds
        .add_deformable(&linear, &at(0.0), &material(), still)
        .unwrap();
    folds.add_sheet(sheet(vec![[0, 1, 2]])).unwrap();
    folds.set_contact(ContactSettings {
        params: ContactParams::default(),
        margin: 1e-4,
        depth_limit: None,
        depth_limit_cap: None,
        sheet_fold_depth: None,
    });
    assert!(refusal(folds).contains("sheet fold depth"));

    let e = ModelBuilder::new()
        .add_sheet(sheet(vec![[0, 1, 3]]))
        .unwrap_err();
    assert!(e.to_string().contains("beyond the sheet's 3 nodes"), "{e}");
}

/// A handle is typed and belongs to its model: one of another model's contributions of
/// another type is refused loudly, not silently misread.
#[test]
#[should_panic(expected = "a handle of another model")]
fn a_handle_of_another_model_is_refused() {
    let build = || {
        let mut model = ModelBuilder::new();
        model
            .add_deformable(
                &template(ElementOrder::Linear),
                &at(0.0),
                &material(),
                InitialMotion::default(),
            )
            .unwrap();
        model
    };
    let mut a = build();
    let spring = a.add_contribution(Spring { k: 1.0 });
    let mut b = build();
    b.add_contribution(Load {
        nodes: 0..1,
        force: [0.0; 3],
    });
    let b = b.build().unwrap();
    let _ = b.get(spring);
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// A contribution that adds no force and, when it reads every node (`reads` is `None`),
/// records how far the velocities it is given are from a rigid motion on each body's
/// nodes: `|(v_i - v_0) . (x_i - x_0)| / (|v_i - v_0| |x_i - x_0|)` over every node `i` of a
/// body and its first node `0`, zero for `omega x (x_i - x_0)` but of the order of
/// `omega dt` for velocities of the step before.
struct RigidProbe {
    bodies: Vec<Range<usize>>,
    reads: Option<Range<usize>>,
    worst: f64,
    evaluations: usize,
}

impl ForceContribution for RigidProbe {
    fn name(&self) -> &str {
        "rigid probe"
    }
    fn stable_time_step(&self, _masses: &[f64]) -> Option<StepBound> {
        None
    }
    fn node_range(&self) -> Option<Range<usize>> {
        self.reads.clone()
    }
    fn add_forces(
        &mut self,
        nodes: NodeView<'_>,
        _forces: &mut [[f64; 3]],
    ) -> Result<Powers, SolverError> {
        self.evaluations += 1;
        if self.reads.is_some() {
            return Ok(Powers::default());
        }
        for r in &self.bodies {
            let (x0, v0) = (nodes.positions[r.start], nodes.velocities[r.start]);
            for i in r.clone().skip(1) {
                let dx = sub(nodes.positions[i], x0);
                let dv = sub(nodes.velocities[i], v0);
                let along = (dx[0] * dv[0] + dx[1] * dv[1] + dx[2] * dv[2]).abs();
                self.worst = self.worst.max(along / (norm(dx) * norm(dv)));
            }
        }
        Ok(Powers::default())
    }
    fn potential_energy(&self, _nodes: NodeView<'_>) -> f64 {
        0.0
    }
}

/// A rigid body's nodes hold their half-step velocities at an evaluation when a
/// contribution may read them: one that may read any node sees a rigid motion on every
/// body's nodes (1e-9). One that keeps to other nodes leaves them out, and the run is the
/// same bit for bit, step by step (the contact model takes those velocities from the
/// bodies' motions): a spinning rigid particle strikes another obliquely, with friction.
#[test]
fn rigid_nodes_get_their_half_step_velocities_when_a_contribution_may_read_them() {
    let build = |reads: Option<Range<usize>>| {
        let mut model = ModelBuilder::new();
        let t = template(ElementOrder::Linear);
        let spinning = InitialMotion {
            velocity: [2.0, 0.0, 0.0],
            angular_velocity: [300.0, -200.0, 500.0],
        };
        model
            .add_rigid(&t, &at(0.0), &material(), spinning)
            .unwrap();
        let beside = Placement {
            scale: 0.01,
            ..Placement::at([0.01003, 0.0015, 0.0])
        };
        model
            .add_rigid(&t, &beside, &material(), InitialMotion::default())
            .unwrap();
        let margin = 0.25 * model.shortest_surface_edge().unwrap();
        model.set_contact(ContactSettings {
            params: ContactParams {
                friction: 0.3,
                ..ContactParams::default()
            },
            margin,
            depth_limit: None,
            depth_limit_cap: None,
            sheet_fold_depth: None,
        });
        model.set_time_step(TimeStep::Automatic { safety: 0.1 });
        let probe = model.add_contribution(RigidProbe {
            bodies: Vec::new(),
            reads,
            worst: 0.0,
            evaluations: 0,
        });
        let mut sim = model.build().unwrap();
        sim.get_mut(probe).bodies = sim.bodies().iter().map(|b| b.nodes.clone()).collect();
        (sim, probe)
    };
    let (mut read, probe) = build(None);
    let (mut left_out, _) = build(Some(0..0));
    let (mut contacts, mut after) = (0, 0);
    while after < 2000 && read.step() < 100_000 {
        read.advance().unwrap();
        left_out.advance().unwrap();
        let (a, b) = (read.state(), left_out.state());
        let step = read.step();
        assert!(
            a.positions == b.positions,
            "positions differ at step {step}"
        );
        assert!(
            a.velocities == b.velocities,
            "velocities differ at step {step}"
        );
        contacts += read.contact().unwrap().model().node_contacts().len();
        after += usize::from(contacts > 0);
    }
    assert!(
        contacts >= 20,
        "{contacts} node contacts by step {}",
        read.step()
    );
    let p = read.get(probe);
    assert!(
        p.evaluations as u64 > read.step(),
        "{} evaluations",
        p.evaluations
    );
    assert!(p.worst < 1e-9, "{}", p.worst);
}
