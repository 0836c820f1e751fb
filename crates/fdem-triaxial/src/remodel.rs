//! One prepared packing in another particle model: the same particles at the same poses,
//! so that the two models can be compared from the same start.

use crate::prepare::{Snapshot, solver, specimen_time_step};
use crate::{PreparedSpecimen, TriaxialError};
use fdem_solver::{BodyKind, ParticleModel, RigidState, Simulation};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// A rigid motion `x -> R x + t` of one particle from its reference placement.
#[derive(Clone, Copy, Debug)]
struct Motion {
    rotation: Rotation3<f64>,
    translation: Vector3<f64>,
}

impl Motion {
    fn apply(&self, x: [f64; 3]) -> [f64; 3] {
        let y = self.rotation * Vector3::from(x) + self.translation;
        [y.x, y.y, y.z]
    }
}

impl PreparedSpecimen {
    /// The same packing in `model`: every particle keeps its place and orientation, at
    /// rest. A particle that was deformable moves as the rigid motion that best fits its
    /// nodes (the mass-weighted centroid and the rotation of the polar decomposition of
    /// `sum m (x - c)(X - C)^T`, Kabsch's fit); a rigid particle places a deformable mesh
    /// undeformed at its pose. The friction history is dropped (its node ids belong to the
    /// old model), and the fixed step is the new model's specimen step. The preparation
    /// report is the original's: it describes how the packing was made.
    ///
    /// # Errors
    /// A definition the new model cannot build, or a state that does not fit it.
    pub fn in_model(&self, model: ParticleModel) -> Result<PreparedSpecimen, TriaxialError> {
        self.in_model_and_order(model, self.spec.mesh.order)
    }

    /// The same packing in `model` with particle meshes of element `order`: as
    /// [`PreparedSpecimen::in_model`], the undeformed mesh of the other order placed at
    /// each particle's fitted motion.
    ///
    /// # Errors
    /// As [`PreparedSpecimen::in_model`].
    pub fn in_model_and_order(
        &self,
        model: ParticleModel,
        order: fdem_mesh::ElementOrder,
    ) -> Result<PreparedSpecimen, TriaxialError> {
        let mut spec = self.spec.clone();
        spec.model = model;
        spec.mesh.order = order;
        spec.validate(&spec.name)?;
        let (dt, _, _) = specimen_time_step(&spec)?;
        let target = PreparedSpecimen {
            spec,
            particles: self.particles.clone(),
            dt,
            state: self.state.clone(),
            report: self.report.clone(),
        };
        let from = self.simulation()?;
        let mut to = target.scene()?.build().map_err(solver("restore"))?;
        let motions = particle_motions(&from);
        let reference: Vec<RigidState> = to.rigid_states();
        let mut rigid = Vec::with_capacity(reference.len());
        let bodies: Vec<_> = to.particles().map(|(_, b)| b.clone()).collect();
        for (body, motion) in bodies.iter().zip(&motions) {
            match body.kind {
                BodyKind::Rigid => rigid.push(moved_state(&reference[rigid.len()], motion)),
                _ => {
                    let reference: Vec<[f64; 3]> =
                        to.state().reference[body.nodes.clone()].to_vec();
                    let nodes = to.nodes_mut();
                    for (x, x0) in nodes.positions[body.nodes.clone()]
                        .iter_mut()
                        .zip(&reference)
                    {
                        *x = motion.apply(*x0);
                    }
                    nodes.velocities[body.nodes.clone()].fill([0.0; 3]);
                }
            }
        }
        to.set_rigid_states(&rigid).map_err(solver("restore"))?;
        let state = Snapshot {
            positions: to.state().positions.clone(),
            velocities: to.state().velocities.clone(),
            history: Vec::new(),
            rigid,
            time: self.state.time,
            step: self.state.step,
        };
        Ok(PreparedSpecimen { state, ..target })
    }
}

/// The rigid motion of every particle of `sim` from its reference placement (a rigid
/// particle's nodes are placed from its pose, so the fit recovers the pose's motion).
fn particle_motions(sim: &Simulation) -> Vec<Motion> {
    sim.particles()
        .map(|(_, b)| fitted_motion(sim, b))
        .collect()
}

/// Kabsch's fit of a rigid motion to the body's nodes: mass-weighted centroids `c`
/// (current) and `C` (reference), and the rotation of the polar decomposition of
/// `H = sum m (x - c)(X - C)^T` (the proper rotation closest to `H`, from its SVD with
/// the sign of the smallest singular direction fixed so that `det R = +1`).
fn fitted_motion(sim: &Simulation, body: &fdem_solver::Body) -> Motion {
    let s = sim.state();
    let nodes = body.nodes.clone();
    let mass: f64 = s.masses[nodes.clone()].iter().sum();
    let centroid = |xs: &[[f64; 3]]| {
        let mut c = Vector3::zeros();
        for (x, m) in xs.iter().zip(&s.masses[nodes.clone()]) {
            c += *m * Vector3::from(*x);
        }
        c / mass
    };
    let (x, x0) = (&s.positions[nodes.clone()], &s.reference[nodes.clone()]);
    let (c, c0) = (centroid(x), centroid(x0));
    let mut h = Matrix3::zeros();
    for ((p, p0), m) in x.iter().zip(x0).zip(&s.masses[nodes.clone()]) {
        h += *m * (Vector3::from(*p) - c) * (Vector3::from(*p0) - c0).transpose();
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u.unwrap_or_default(), svd.v_t.unwrap_or_default());
    let mut d = Matrix3::identity();
    if (u * v_t).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let rotation = Rotation3::from_matrix_unchecked(u * d * v_t);
    Motion {
        rotation,
        translation: c - rotation * c0,
    }
}

/// A rigid body's reference state moved by `motion`, at rest.
fn moved_state(reference: &RigidState, motion: &Motion) -> RigidState {
    let [w, i, j, k] = reference.orientation;
    let q0 = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, i, j, k));
    let q = UnitQuaternion::from_rotation_matrix(&motion.rotation) * q0;
    RigidState {
        position: motion.apply(reference.position),
        velocity: [0.0; 3],
        orientation: [q.w, q.i, q.j, q.k],
        body_momentum: [0.0; 3],
    }
}
