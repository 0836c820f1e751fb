//! Rigid bodies: their mass properties and the explicit integrator of their motion.
//!
//! A rigid body moves with six degrees of freedom: its centre of mass with velocity
//! Verlet, like every node, and its orientation (a unit quaternion from the body's
//! principal frame to the world) with the symmetric splitting of the free rigid body of
//! Dullweber, Leimkuhler and McLachlan (J. Chem. Phys. 107, 1997; the NO_SQUISH scheme
//! of Miller et al., J. Chem. Phys. 116, 2002, is the same splitting in quaternions).
//! The angular momentum is kept in the principal frame, `pi = R^T L`; a step is
//!
//! 1. half kick: `v += dt/2 F / m`, `pi += dt/2 R^T tau`;
//! 2. drift: `x += dt v`, then the free rotation as exact rotations about the principal
//!    axes in the order 1 (dt/2), 2 (dt/2), 3 (dt), 2 (dt/2), 1 (dt/2);
//! 3. forces and torques at the new pose;
//! 4. half kick.
//!
//! Each sub-rotation is the exact flow of one term `pi_k^2 / (2 I_k)` of the kinetic
//! energy: the body turns by `phi = t pi_k / I_k` about axis `k` and `pi` turns by
//! `-phi` about the same axis, so `L = R pi` is unchanged to round-off. The composition
//! is symplectic and second order, so with no torque the angular momentum is conserved
//! exactly (gyroscopic term included: it is the rotation of `pi` in the body frame) and
//! the energy error stays bounded at `O(dt^2)` instead of drifting as Euler's method on
//! `omega` does.

use crate::SolverError;
use fdem_core::geometry::{is_finite, norm};
use fdem_core::number::Number;
use fdem_core::rows::Rows;
use nalgebra::{Matrix3, SymmetricEigen, UnitQuaternion, Vector3};

/// Mass properties of a rigid body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidInertia {
    /// Mass (kg).
    pub mass: f64,
    /// Principal moments of inertia about the centre of mass (kg m^2), > 0.
    pub principal: [f64; 3],
    /// Rotation from the principal frame to the frame the inertia tensor was given in,
    /// as a unit quaternion `[w, x, y, z]`.
    pub principal_frame: [f64; 4],
}

impl RigidInertia {
    /// The smallest principal moment (kg m^2).
    pub(crate) fn smallest_moment(&self) -> f64 {
        self.principal.iter().copied().fold(f64::INFINITY, f64::min)
    }

    /// The principal moments and axes of the inertia tensor `inertia` (kg m^2, about the
    /// centre of mass) of a body of mass `mass`.
    ///
    /// # Errors
    /// [`SolverError::InvalidScene`] for a mass or a principal moment that is not finite
    /// and > 0.
    pub fn new(mass: f64, inertia: [[f64; 3]; 3]) -> Result<RigidInertia, SolverError> {
        let refused = |what: String| {
            SolverError::InvalidScene(format!(
                "a rigid body needs a finite positive mass and principal moments; {what}"
            ))
        };
        if !mass.is_finite() {
            return Err(refused("got a mass that is not finite".into()));
        }
        if mass <= 0.0 {
            return Err(refused(format!("got mass {} kg", Number(mass))));
        }
        let tensor = Matrix3::from_fn(|j, k| 0.5 * (inertia[j][k] + inertia[k][j]));
        // A tensor that is not finite (an extreme size or density) has no moments: its
        // eigen-decomposition would only print NaN.
        if tensor.iter().any(|x| !x.is_finite()) {
            return Err(refused(format!(
                "got mass {} kg and an inertia tensor that is not finite",
                Number(mass)
            )));
        }
        let eigen = SymmetricEigen::new(tensor);
        // Ascending moments, so that the splitting's order of axes is fixed.
        let mut order = [0, 1, 2];
        order.sort_by(|&a, &b| eigen.eigenvalues[a].total_cmp(&eigen.eigenvalues[b]));
        let principal = order.map(|k| eigen.eigenvalues[k]);
        if principal.iter().any(|&i| !(i.is_finite() && i > 0.0)) {
            return Err(refused(format!(
                "got mass {} kg and moments [{}, {}, {}] kg m^2",
                Number(mass),
                Number(principal[0]),
                Number(principal[1]),
                Number(principal[2])
            )));
        }
        let axes = canonical_axes(
            principal,
            order.map(|k| eigen.eigenvectors.column(k).into_owned()),
        );
        let principal = averaged_equal_moments(principal);
        let rotation = nalgebra::Rotation3::from_matrix_unchecked(Matrix3::from_columns(&axes));
        let q = UnitQuaternion::from_rotation_matrix(&rotation);
        Ok(RigidInertia {
            mass,
            principal,
            principal_frame: [q.w, q.i, q.j, q.k],
        })
    }
}

/// Moments closer than this, relative to the largest, count as equal: their axes are
/// not defined by the tensor, and round-off would otherwise choose them.
const DEGENERATE: f64 = 1e-9;

/// Principal axes that depend on the body's geometry only, not on round-off: where moments
/// are equal (a sphere mesh's inertia is isotropic, an axisymmetric body's has a double
/// moment) the eigenvectors are arbitrary, and the splitting's `O(dt^2)` error depends on
/// the axes it rotates about, so a run would depend on rounding (and exact scaling would
/// not hold to round-off). Isotropic: the mesh's own axes. A double moment: the distinct
/// axis, then the mesh's x (or y) axis projected off it. Signs: the largest component of
/// each distinct axis positive; right-handed.
fn canonical_axes(moments: [f64; 3], vectors: [Vector3<f64>; 3]) -> [Vector3<f64>; 3] {
    let equal = |a: f64, b: f64| (a - b).abs() <= DEGENERATE * moments[2];
    let signed = |v: Vector3<f64>| {
        let k = v.iamax();
        if v[k] < 0.0 { -v } else { v }
    };
    let completed = |axis: Vector3<f64>| {
        let x = if axis.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let u = (x - axis * axis.dot(&x)).normalize();
        (u, axis.cross(&u))
    };
    let [a, b, c] = vectors;
    let axes = match (equal(moments[0], moments[1]), equal(moments[1], moments[2])) {
        (true, true) => [Vector3::x(), Vector3::y(), Vector3::z()],
        (true, false) => {
            let c = signed(c);
            let (u, v) = completed(c);
            [u, v, c]
        }
        (false, true) => {
            let a = signed(a);
            let (u, v) = completed(a);
            [a, u, v]
        }
        (false, false) => [signed(a), signed(b), signed(c)],
    };
    let mut axes = axes;
    if axes[0].cross(&axes[1]).dot(&axes[2]) < 0.0 {
        axes[2] = -axes[2];
    }
    axes
}

/// Moments that count as equal ([`DEGENERATE`]) replaced by their mean, so that the
/// tensor the integrator uses has exactly the symmetry its axes were chosen for.
fn averaged_equal_moments(m: [f64; 3]) -> [f64; 3] {
    let equal = |a: f64, b: f64| (a - b).abs() <= DEGENERATE * m[2];
    match (equal(m[0], m[1]), equal(m[1], m[2])) {
        (true, true) => [(m[0] + m[1] + m[2]) / 3.0; 3],
        (true, false) => [0.5 * (m[0] + m[1]), 0.5 * (m[0] + m[1]), m[2]],
        (false, true) => [m[0], 0.5 * (m[1] + m[2]), 0.5 * (m[1] + m[2])],
        (false, false) => m,
    }
}

/// The pose and momenta of a rigid body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidState {
    /// Centre of mass (m).
    pub position: [f64; 3],
    /// Velocity of the centre of mass (m/s).
    pub velocity: [f64; 3],
    /// Rotation from the principal frame to the world, unit quaternion `[w, x, y, z]`.
    pub orientation: [f64; 4],
    /// Angular momentum about the centre of mass in the principal frame, `R^T L`
    /// (kg m^2/s).
    pub body_momentum: [f64; 3],
}

/// Whether two rotations hold the same values, a NaN the same as a NaN: a body whose
/// state overflowed keeps NaNs in its rotation as in its orientation until the step's
/// finiteness check stops the run. (Type-checked in every build, as `debug_assert!`
/// compiles its condition in release builds too.)
fn same_values(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> bool {
    let same = |(x, y): (&f64, &f64)| x == y || (x.is_nan() && y.is_nan());
    a.coords.iter().zip(b.coords.iter()).all(same)
}

fn quaternion(q: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]))
}

/// The sub-rotations of the drift: principal axis and fraction of the step (module docs).
const SPLITTING: [(usize, f64); 5] = [(0, 0.5), (1, 0.5), (2, 1.0), (1, 0.5), (0, 0.5)];

/// One sub-rotation of the drift: the orientation `q` (`[w, x, y, z]`) turned by `phi`
/// about principal axis `a`, `q (cos(phi/2), sin(phi/2) e_a)`, and the body-frame
/// momentum `pi` turned by `-phi` about the same axis.
///
/// Written out without the terms of the turn's two zero components: the same numbers as
/// nalgebra's `from_axis_angle`, `inverse_transform_vector` (`pi + w t + u x t` with `u`
/// the conjugate's vector part and `t = 2 u x pi`) and quaternion product, whose terms
/// with those zeros add or subtract a zero and change no value (a zero's sign aside).
/// The axes `b`, `d` follow `a` cyclically.
#[inline(always)]
fn turn(a: usize, phi: f64, q: [f64; 4], pi: [f64; 3]) -> ([f64; 4], [f64; 3]) {
    let (s, c) = (phi / 2.0).sin_cos();
    let (b, d) = ((a + 1) % 3, (a + 2) % 3);
    // `t = 2 u x pi` with `u = -s e_a`: its a-component is zero.
    let tb = (s * pi[d]) * 2.0;
    let td = (-s * pi[b]) * 2.0;
    let mut turned = pi;
    // `(w t + u x t) + pi`, `(u x t)_b = s t_d`, `(u x t)_d = -s t_b`.
    turned[b] = (tb * c + s * td) + pi[b];
    turned[d] = (td * c + -s * tb) + pi[d];
    // The product with `(c, s e_a)`; `q[1 + k]` is the vector part's component k.
    let (w, qa, qb, qd) = (q[0], q[1 + a], q[1 + b], q[1 + d]);
    let mut product = [0.0; 4];
    product[0] = w * c - qa * s;
    product[1 + a] = w * s + qa * c;
    product[1 + b] = qb * c + qd * s;
    product[1 + d] = qd * c - qb * s;
    (product, turned)
}

fn array(v: Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

impl RigidState {
    /// A body at `position` moving at `velocity` and spinning at `angular_velocity`
    /// (world frame, rad/s), oriented by `orientation` (principal frame to world).
    pub fn new(
        inertia: &RigidInertia,
        position: [f64; 3],
        velocity: [f64; 3],
        orientation: [f64; 4],
        angular_velocity: [f64; 3],
    ) -> RigidState {
        let q = quaternion(orientation);
        let w = q.inverse_transform_vector(&Vector3::from(angular_velocity));
        let i = inertia.principal;
        RigidState {
            position,
            velocity,
            orientation: [q.w, q.i, q.j, q.k],
            body_momentum: [i[0] * w.x, i[1] * w.y, i[2] * w.z],
        }
    }

    /// Checks that every number is finite and the orientation a unit quaternion (to
    /// within `1e-9`), as a restored state must be.
    pub fn check(&self) -> Result<(), String> {
        let finite = self
            .position
            .iter()
            .chain(&self.velocity)
            .chain(&self.orientation)
            .chain(&self.body_momentum)
            .all(|v| v.is_finite());
        if !finite {
            return Err("a position, velocity, orientation or momentum is not finite".into());
        }
        let norm = self.orientation.iter().map(|q| q * q).sum::<f64>().sqrt();
        if (norm - 1.0).abs() > 1e-9 {
            return Err(format!(
                "orientation quaternion of norm {}, not 1",
                fdem_core::number::Number(norm)
            ));
        }
        Ok(())
    }

    /// Half kick (or any kick of duration `h`): `v += h F / m`, `pi += h R^T tau` with the
    /// force `force` (N) and the torque `torque` about the centre of mass (N m), both in
    /// the world frame.
    pub fn kick(&mut self, inertia: &RigidInertia, force: [f64; 3], torque: [f64; 3], h: f64) {
        self.kick_rotated(&quaternion(self.orientation), inertia, force, torque, h);
    }

    /// [`RigidState::kick`] with the orientation's rotation `r` made beforehand.
    #[inline(always)]
    fn kick_rotated(
        &mut self,
        r: &UnitQuaternion<f64>,
        inertia: &RigidInertia,
        force: [f64; 3],
        torque: [f64; 3],
        h: f64,
    ) {
        for (v, f) in self.velocity.iter_mut().zip(force) {
            *v += h * f / inertia.mass;
        }
        let t = r.inverse_transform_vector(&Vector3::from(torque));
        for (p, t) in self.body_momentum.iter_mut().zip(t.iter()) {
            *p += h * t;
        }
    }

    /// Drift over `dt`: the centre moves with its velocity; the orientation follows the
    /// free rotation by the symmetric splitting of the module docs.
    pub fn drift(&mut self, inertia: &RigidInertia, dt: f64) {
        self.drift_rotated(&quaternion(self.orientation), inertia, dt);
    }

    /// [`RigidState::drift`] with the orientation's rotation `r` made beforehand.
    #[inline(always)]
    fn drift_rotated(&mut self, r: &UnitQuaternion<f64>, inertia: &RigidInertia, dt: f64) {
        for (x, v) in self.position.iter_mut().zip(self.velocity) {
            *x += dt * v;
        }
        let mut q = [r.w, r.i, r.j, r.k];
        let mut pi = self.body_momentum;
        for (axis, t) in SPLITTING {
            let phi = t * dt * pi[axis] / inertia.principal[axis];
            (q, pi) = turn(axis, phi, q, pi);
        }
        let mut q =
            UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]));
        q.renormalize();
        self.orientation = [q.w, q.i, q.j, q.k];
        self.body_momentum = pi;
    }

    /// Angular velocity in the world frame (rad/s), `R I^-1 pi`.
    pub fn angular_velocity(&self, inertia: &RigidInertia) -> [f64; 3] {
        self.angular_velocity_rotated(&quaternion(self.orientation), inertia)
    }

    /// [`RigidState::angular_velocity`] with the orientation's rotation `r` made
    /// beforehand.
    #[inline(always)]
    fn angular_velocity_rotated(
        &self,
        r: &UnitQuaternion<f64>,
        inertia: &RigidInertia,
    ) -> [f64; 3] {
        let i = inertia.principal;
        let pi = self.body_momentum;
        let w = Vector3::new(pi[0] / i[0], pi[1] / i[1], pi[2] / i[2]);
        array(r.transform_vector(&w))
    }

    /// Angular momentum about the centre of mass in the world frame (kg m^2/s), `R pi`.
    pub fn angular_momentum(&self) -> [f64; 3] {
        array(quaternion(self.orientation).transform_vector(&Vector3::from(self.body_momentum)))
    }

    /// Kinetic energy `m |v|^2 / 2 + sum_k pi_k^2 / (2 I_k)` (J), the rotational part as
    /// `pi_k (pi_k / I_k)`: the square of a momentum overflows for a body of extreme mass
    /// long before its energy does.
    pub fn kinetic_energy(&self, inertia: &RigidInertia) -> f64 {
        let v = self.velocity;
        let pi = self.body_momentum;
        let i = inertia.principal;
        0.5 * inertia.mass * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
            + 0.5 * (pi[0] * (pi[0] / i[0]) + pi[1] * (pi[1] / i[1]) + pi[2] * (pi[2] / i[2]))
    }

    /// World position of the point at `offset` from the centre of mass in the principal
    /// frame (m).
    pub fn point(&self, offset: [f64; 3]) -> [f64; 3] {
        self.point_rotated_by(&quaternion(self.orientation), offset)
    }

    /// [`RigidState::point`] with the orientation's rotation `r` made once for many
    /// points (the same bits: `quaternion` normalises, a square root and divisions per
    /// call).
    fn point_rotated_by(&self, r: &UnitQuaternion<f64>, offset: [f64; 3]) -> [f64; 3] {
        let r = r.transform_vector(&Vector3::from(offset));
        [0, 1, 2].map(|k| self.position[k] + r[k])
    }
}

/// One rigid body of a simulation: its node range (the template's surface nodes), the
/// nodes' offsets from the centre of mass in the principal frame, mass properties, state,
/// and the force and torque of the last evaluation.
#[derive(Clone, Debug)]
pub(crate) struct RigidPart {
    pub(crate) body: usize,
    pub(crate) first: usize,
    pub(crate) offsets: Vec<[f64; 3]>,
    pub(crate) inertia: RigidInertia,
    /// The body's state. Its orientation changes only through [`RigidPart::set_state`]
    /// and [`RigidPart::drift`], which keep `rotation` its rotation.
    pub(crate) state: RigidState,
    /// The rotation of `state.orientation`, `quaternion(state.orientation)`, made once per
    /// change of the orientation: it normalises (a square root and four divisions), and
    /// every pass over the body turns by it.
    rotation: UnitQuaternion<f64>,
    /// Centre of mass at the reference of gravity's work (m).
    pub(crate) reference: [f64; 3],
    /// Where the body's template sits in its principal frame (for the contact's frames).
    pub(crate) template: Option<TemplateMap>,
    force: [f64; 3],
    torque: [f64; 3],
    /// The largest distance of a node from the centre of mass (m).
    reach: f64,
}

/// Relative room a node speed bound leaves for the round-off of placing the nodes (a few
/// units of the last place of the positions and velocities).
const SPEED_ROOM: f64 = 1e-12;

/// Below this size a body's position, velocity and spin cannot overflow a node's position
/// or velocity.
const FAR_FROM_OVERFLOW: f64 = 1e300;

/// How a rigid body's template lies in the body's principal frame: offsets `o = shift +
/// to_offsets t` of the template coordinates `t`, `to_offsets` a rotation times the
/// placement's scale. With the body's pose `(X, R)` a template point is at `X + R shift +
/// R to_offsets t`, which the contact model's frames take as `origin + A t`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TemplateMap {
    /// The template's index among the model's rigid templates.
    pub(crate) template: usize,
    to_offsets: Matrix3<f64>,
    shift: Vector3<f64>,
    scale: f64,
}

impl TemplateMap {
    /// The map of a template placed by `placement` (`x0 = R_p (s t) + T`, fdem-mesh's
    /// placement) into a body whose centre of mass is `centre` and whose principal frame is
    /// the unit quaternion `principal_frame`: `o = R_f^T (x0 - centre)`.
    pub(crate) fn new(
        template: usize,
        placement: &fdem_mesh::Placement,
        principal_frame: [f64; 4],
        centre: [f64; 3],
    ) -> TemplateMap {
        let placed = quaternion(placement.rotation).to_rotation_matrix();
        let frame = quaternion(principal_frame).to_rotation_matrix();
        let back = frame.transpose();
        let t = Vector3::from(placement.translation) - Vector3::from(centre);
        TemplateMap {
            template,
            to_offsets: back * placed.matrix() * placement.scale,
            shift: back * t,
            scale: placement.scale,
        }
    }
}

impl RigidPart {
    pub(crate) fn new(
        body: usize,
        first: usize,
        offsets: Vec<[f64; 3]>,
        inertia: RigidInertia,
        state: RigidState,
    ) -> Self {
        let reach = offsets.iter().map(|&o| norm(o)).fold(0.0, f64::max);
        RigidPart {
            body,
            first,
            offsets,
            reach,
            inertia,
            reference: state.position,
            rotation: quaternion(state.orientation),
            state,
            template: None,
            force: [0.0; 3],
            torque: [0.0; 3],
        }
    }

    /// The body's pose for the contact model's frames, if it has a template map:
    /// `origin = X + R shift`, `A = R to_offsets`, given by `A^-1 = A^T / s^2`.
    pub(crate) fn pose(&self) -> Option<fdem_contact::RigidPose> {
        let map = self.template.as_ref()?;
        let r = self.rotation().to_rotation_matrix();
        let a = r.matrix() * map.to_offsets;
        let origin = Vector3::from(self.state.position) + r * map.shift;
        let inv = a.transpose() / (map.scale * map.scale);
        Some(fdem_contact::RigidPose {
            to_template: std::array::from_fn(|i| std::array::from_fn(|j| inv[(i, j)])),
            origin: array(origin),
            scale: map.scale,
        })
    }

    /// The body's effective mass at each of its nodes, for the contact bound: a force
    /// `f n` at offset `r` from the centre accelerates the point along `n` by
    /// `f (1 / m + (r x n) . I^-1 (r x n))`, and `|r x n|^2 / I_min` bounds the second
    /// term over all directions `n`, so `1 / (1 / m + |r|^2 / I_min)` is the smallest
    /// effective mass at that node. `out` is the body's own node range.
    pub(crate) fn effective_masses(&self, out: &mut [f64]) {
        let m = self.inertia.mass;
        let i_min = self.inertia.smallest_moment();
        for (o, r) in out.iter_mut().zip(&self.offsets) {
            let r2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
            *o = 1.0 / (1.0 / m + r2 / i_min);
        }
    }

    /// The body's node range.
    pub(crate) fn nodes(&self) -> std::ops::Range<usize> {
        self.first..self.first + self.offsets.len()
    }

    /// The rotation of the body's orientation.
    #[inline]
    fn rotation(&self) -> &UnitQuaternion<f64> {
        debug_assert!(
            same_values(&self.rotation, &quaternion(self.state.orientation)),
            "the kept rotation {:?} is not that of the orientation {:?}",
            self.rotation,
            self.state.orientation
        );
        &self.rotation
    }

    /// Sets the body's state.
    pub(crate) fn set_state(&mut self, state: RigidState) {
        self.state = state;
        self.rotation = quaternion(state.orientation);
    }

    /// A kick of duration `h` with the force and torque of the last evaluation.
    #[inline]
    pub(crate) fn kick(&mut self, h: f64) {
        let r = *self.rotation();
        self.state
            .kick_rotated(&r, &self.inertia, self.force, self.torque, h);
    }

    /// The drift over `dt` ([`RigidState::drift`]), and the new orientation's rotation.
    #[inline]
    fn drift(&mut self, dt: f64) {
        let r = *self.rotation();
        self.state.drift_rotated(&r, &self.inertia, dt);
        self.rotation = quaternion(self.state.orientation);
    }

    /// Positions and velocities of the body's nodes (`x`, `v`: its own node range) from
    /// its pose: [`RigidPart::place_positions`], then [`RigidPart::place_velocities`].
    pub(crate) fn place_nodes(&self, x: &mut [[f64; 3]], v: &mut [[f64; 3]]) {
        self.place_positions(x);
        self.place_velocities(x, v);
    }

    /// Positions of the body's nodes (`x`: its own node range) from its pose:
    /// `x_i = X + R r_i`.
    fn place_positions(&self, x: &mut [[f64; 3]]) {
        let r = self.rotation();
        for (xi, offset) in x.iter_mut().zip(&self.offsets) {
            *xi = self.state.point_rotated_by(r, *offset);
        }
    }

    /// Velocities of the body's nodes at positions `x` (placed from the current pose):
    /// `v_i = V + omega x (x_i - X)`.
    pub(crate) fn place_velocities(&self, x: &[[f64; 3]], v: &mut [[f64; 3]]) {
        let motion = crate::InitialMotion {
            velocity: self.state.velocity,
            angular_velocity: self
                .state
                .angular_velocity_rotated(self.rotation(), &self.inertia),
        };
        for (vi, xi) in v.iter_mut().zip(x) {
            *vi = motion.velocity_at(*xi, self.state.position);
        }
    }

    /// The body's motion as the contact model's per-step scan takes it: a node at `r`
    /// from the centre moves at `V + omega x r`, so `|V| + |omega| |r|_max` bounds every
    /// node's speed (room added for the round-off of placing it: `r` is placed as `x - X`);
    /// a finite position, velocity and spin far from overflow make every node's position
    /// and velocity finite.
    fn motion(&self) -> fdem_contact::RigidMotion {
        let (x, v) = (self.state.position, self.state.velocity);
        let omega = self
            .state
            .angular_velocity_rotated(self.rotation(), &self.inertia);
        let r = self.reach + SPEED_ROOM * (self.reach + norm(x));
        let speed = norm(v) + norm(omega) * r;
        let finite = [x, v, omega].iter().all(|&a| is_finite(a))
            && norm(x) + self.reach < FAR_FROM_OVERFLOW
            && speed < FAR_FROM_OVERFLOW;
        fdem_contact::RigidMotion {
            speed_bound: speed * (1.0 + SPEED_ROOM),
            finite,
            // The inputs `place_velocities` gives its nodes (the same spin, computed from
            // the same state).
            velocity: v,
            angular_velocity: omega,
            centre: x,
        }
    }

    /// Sums the node forces into the body's force and torque about its centre, plus its
    /// weight `m g` (`positions`, `forces`: its own node range).
    fn gather(&mut self, positions: &[[f64; 3]], forces: &[[f64; 3]], g: [f64; 3]) {
        let c = self.state.position;
        let mut force = g.map(|gk| self.inertia.mass * gk);
        let mut torque = [0.0; 3];
        for (&x, &f) in positions.iter().zip(forces) {
            let r = [x[0] - c[0], x[1] - c[1], x[2] - c[2]];
            let t = fdem_core::geometry::cross(r, f);
            for j in 0..3 {
                force[j] += f[j];
                torque[j] += t[j];
            }
        }
        self.force = force;
        self.torque = torque;
    }

    /// Gravity's work since the reference, `m g . (X - X_ref)` (J).
    pub(crate) fn gravity_work(&self, g: [f64; 3]) -> f64 {
        let (x, x0) = (self.state.position, self.reference);
        self.inertia.mass * (g[0] * (x[0] - x0[0]) + g[1] * (x[1] - x0[1]) + g[2] * (x[2] - x0[2]))
    }
}

/// A rotation given as a unit quaternion `[w, x, y, z]`.
pub(crate) struct Frame(UnitQuaternion<f64>);

/// The rotation of the unit quaternion `q`.
pub(crate) fn rotation(q: [f64; 4]) -> Frame {
    Frame(quaternion(q))
}

impl Frame {
    /// `R^T v`.
    pub(crate) fn inverse_apply(&self, v: [f64; 3]) -> [f64; 3] {
        array(self.0.inverse_transform_vector(&Vector3::from(v)))
    }
}

/// The rigid bodies of a simulation, in increasing node order (their node ranges are
/// disjoint), and the passes of the step over them, in parallel over bodies.
#[derive(Clone, Debug, Default)]
pub(crate) struct RigidBodies {
    parts: Vec<RigidPart>,
    /// For each body id up to the last rigid one, its index in `parts` (`NOT_RIGID` for a
    /// body of another kind): the network bound looks up two bodies per contact.
    index: Vec<u32>,
}

/// [`RigidBodies::index`] of a body that is not rigid.
const NOT_RIGID: u32 = u32::MAX;

/// Bodies handled serially below this count per task (keeps rayon's overhead small).
const SERIAL_BODIES: usize = 64;

impl RigidBodies {
    pub(crate) fn new(parts: Vec<RigidPart>) -> Self {
        debug_assert!(parts.windows(2).all(|w| w[0].first < w[1].first));
        let mut index = vec![NOT_RIGID; parts.iter().map(|p| p.body + 1).max().unwrap_or(0)];
        for (i, p) in parts.iter().enumerate() {
            index[p.body] = i as u32;
        }
        RigidBodies { parts, index }
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.parts.is_empty()
    }

    /// Places every body's nodes in `x`, `v` from its pose (undoing edits of them).
    pub(crate) fn place_all(&self, x: &mut [[f64; 3]], v: &mut [[f64; 3]]) {
        for p in &self.parts {
            let r = p.nodes();
            p.place_nodes(&mut x[r.clone()], &mut v[r]);
        }
    }

    /// The motions of the bodies with a template map, in body order, into `out` (the
    /// contact model's scan, `ContactModel::set_rigid_motions`).
    pub(crate) fn motions(&self, out: &mut Vec<fdem_contact::RigidMotion>) {
        use rayon::prelude::*;
        out.clear();
        out.par_extend(
            self.parts
                .par_iter()
                .with_min_len(SERIAL_BODIES)
                .filter(|p| p.template.is_some())
                .map(RigidPart::motion),
        );
    }

    /// The poses of the bodies with a template map, in body order, into `out` (the
    /// contact model's frames, `ContactModel::set_rigid_poses`).
    pub(crate) fn poses(&self, out: &mut Vec<fdem_contact::RigidPose>) {
        use rayon::prelude::*;
        out.clear();
        // In parallel, as the step's other passes over the bodies (`par_extend` keeps
        // the order).
        out.par_extend(
            self.parts
                .par_iter()
                .with_min_len(SERIAL_BODIES)
                .filter_map(RigidPart::pose),
        );
    }

    pub(crate) fn iter(&self) -> impl Iterator<Item = &RigidPart> {
        self.parts.iter()
    }

    /// The rigid body of body id `body`, if it is one.
    pub(crate) fn get(&self, body: usize) -> Option<&RigidPart> {
        self.part_of(body).map(|k| &self.parts[k])
    }

    /// Sets every body's state (`states` in body order) and places its nodes in `x`, `v`.
    pub(crate) fn set_states(
        &mut self,
        states: &[RigidState],
        x: &mut [[f64; 3]],
        v: &mut [[f64; 3]],
    ) -> Result<(), SolverError> {
        if states.len() != self.parts.len() {
            return Err(SolverError::InvalidScene(format!(
                "{} rigid states given for {} rigid bodies; restore a state of the same model",
                states.len(),
                self.parts.len()
            )));
        }
        for (p, s) in self.parts.iter().zip(states) {
            s.check()
                .map_err(|e| SolverError::InvalidScene(format!("rigid body {}: {e}", p.body)))?;
        }
        for (p, s) in self.parts.iter_mut().zip(states) {
            p.set_state(*s);
        }
        self.place_all(x, v);
        Ok(())
    }

    /// Each body's part of a checkpoint, in body order.
    pub(crate) fn checkpoint(&self) -> Vec<crate::checkpoint::RigidCheckpoint> {
        self.parts
            .iter()
            .map(|p| crate::checkpoint::RigidCheckpoint {
                state: p.state,
                reference: p.reference,
                force: p.force,
                torque: p.torque,
            })
            .collect()
    }

    /// Restores [`RigidBodies::checkpoint`] (as [`RigidBodies::set_states`], then the
    /// reference, force and torque).
    pub(crate) fn restore(
        &mut self,
        saved: &[crate::checkpoint::RigidCheckpoint],
        x: &mut [[f64; 3]],
        v: &mut [[f64; 3]],
    ) -> Result<(), SolverError> {
        let states: Vec<RigidState> = saved.iter().map(|r| r.state).collect();
        let finite = saved
            .iter()
            .flat_map(|r| r.reference.into_iter().chain(r.force).chain(r.torque))
            .all(f64::is_finite);
        if !finite {
            return Err(SolverError::InvalidScene(
                "a rigid body's saved reference, force or torque is not finite".into(),
            ));
        }
        self.set_states(&states, x, v)?;
        for (p, r) in self.parts.iter_mut().zip(saved) {
            p.reference = r.reference;
            p.force = r.force;
            p.torque = r.torque;
        }
        Ok(())
    }

    /// First half of a step: half kick with the last force and torque, drift over `dt`,
    /// nodes placed from the new pose (their velocities as `velocities` says), their
    /// forces reset for the step's new ones.
    pub(crate) fn kick_drift(
        &mut self,
        half: f64,
        dt: f64,
        nodes: NodeRanges<'_>,
        velocities: HalfStepVelocities,
    ) {
        with_nodes(&mut self.parts, nodes, 0, &|parts, nodes, offset| {
            // The run's kicks and drifts first, apart from the node loops: a drift is a
            // chain of five dependent turns, and with the bodies' chains side by side the
            // processor works on several at once.
            for p in parts.iter_mut() {
                p.kick(half);
                p.drift(dt);
            }
            each_part(parts, nodes, offset, |p, [x, v, f]| {
                p.place_positions(x);
                if velocities == HalfStepVelocities::All || p.template.is_none() {
                    p.place_velocities(x, v);
                }
                f.fill([0.0; 3]);
                true
            })
        });
    }

    /// The node velocities of every body from its state (after a step that failed
    /// having left some out, [`HalfStepVelocities::Unframed`]).
    pub(crate) fn place_velocities(&self, x: &[[f64; 3]], v: &mut [[f64; 3]]) {
        for p in &self.parts {
            let r = p.nodes();
            p.place_velocities(&x[r.clone()], &mut v[r]);
        }
    }

    /// Whether node ids `range` hold a node of a rigid body.
    pub(crate) fn holds_any(&self, range: &std::ops::Range<usize>) -> bool {
        if range.is_empty() {
            return false;
        }
        // The first body whose nodes end after the range's start (the bodies' ranges are
        // increasing and disjoint).
        let i = self
            .parts
            .partition_point(|p| p.first + p.offsets.len() <= range.start);
        self.parts.get(i).is_some_and(|p| p.first < range.end)
    }

    /// Each body's force and torque from its nodes' forces (and its weight).
    pub(crate) fn gather(&mut self, g: [f64; 3], nodes: NodeRanges<'_>) {
        with_nodes(&mut self.parts, nodes, 0, &|parts, nodes, offset| {
            each_part(parts, nodes, offset, |p, [x, _, f]| {
                p.gather(x, f, g);
                true
            })
        });
    }

    /// Second half of a step, body by body in one pass over its nodes: its force and
    /// torque from its nodes' forces (and its weight), the half kick with them, its node
    /// velocities from the new momenta; false if a node velocity is not finite.
    pub(crate) fn gather_and_kick(
        &mut self,
        half: f64,
        g: [f64; 3],
        nodes: NodeRanges<'_>,
    ) -> bool {
        with_nodes(&mut self.parts, nodes, 0, &|parts, nodes, offset| {
            each_part(parts, nodes, offset, |p, [x, v, f]| {
                p.gather(x, f, g);
                p.kick(half);
                p.place_velocities(x, v);
                v.iter().flatten().all(|c| c.is_finite())
            })
        })
    }
}

/// Which rigid bodies' nodes a step's kick and drift give their half-step velocities.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum HalfStepVelocities {
    /// Every body's: a force contribution or constraint may read them.
    All,
    /// Only those of bodies without a template map: the contact model takes the others'
    /// from their motions (`ContactModel::set_rigid_motions`), and nothing else reads
    /// them before the step's end places them all.
    Unframed,
}

/// The step the contact network allows the rigid bodies: the smallest over the bodies,
/// with the body that sets it and how many springs act on it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct NetworkBound {
    pub(crate) dt: f64,
    pub(crate) body: usize,
    pub(crate) springs: usize,
}

/// One contact spring as the rigid bodies' step bound sees it: a node of `body` at `point`
/// pressed into a face of another body at that body's point (`other`), or into a wall
/// (`None`), with the stiffer of its springs (N/m) and the larger of its dashpots (N s/m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Spring {
    pub(crate) body: usize,
    pub(crate) point: [f64; 3],
    pub(crate) other: Option<(usize, [f64; 3])>,
    pub(crate) stiffness: f64,
    pub(crate) dashpot: f64,
}

/// Moments about a body's centre of coefficients `w` acting at points `r` from it: `sum
/// w`, `sum w r` and `sum w r r^T` (rows xx, yy, zz, xy, xz, yz). They make the body's
/// block of a stiffness or damping matrix built of isotropic point couplings.
#[derive(Clone, Copy, Default)]
struct Moments {
    w: f64,
    wr: [f64; 3],
    wrr: [f64; 6],
}

impl Moments {
    fn add(&mut self, r: [f64; 3], w: f64) {
        self.w += w;
        for (m, ri) in self.wr.iter_mut().zip(r) {
            *m += w * ri;
        }
        let [x, y, z] = r;
        for (m, v) in self
            .wrr
            .iter_mut()
            .zip([x * x, y * y, z * z, x * y, x * z, y * z])
        {
            *m += w * v;
        }
    }

    /// A bound of the largest eigenvalue of `M^-1 A` for the body's block `A = [[w I,
    /// -[wr]x], [[wr]x, tr(wrr) I - wrr]]`, `M` at least `diag(m I, I_min I)`: the largest
    /// row sum of absolute values of `M^-1/2 A M^-1/2` (Gershgorin).
    fn largest_eigenvalue(&self, mass: f64, i_min: f64) -> f64 {
        let [xx, yy, zz, xy, xz, yz] = self.wrr;
        let trace = xx + yy + zz;
        let c = 1.0 / (mass * i_min).sqrt();
        let a = self.wr.map(f64::abs);
        // |[wr]x| has rows (0, a_z, a_y), (a_z, 0, a_x), (a_y, a_x, 0) in absolute value.
        let coupling = [a[1] + a[2], a[0] + a[2], a[0] + a[1]];
        let rotation = [
            trace - xx + xy.abs() + xz.abs(),
            trace - yy + xy.abs() + yz.abs(),
            trace - zz + xz.abs() + yz.abs(),
        ];
        (0..3)
            .map(|i| {
                let translational = self.w / mass + c * coupling[i];
                let rotational = rotation[i] / i_min + c * coupling[i];
                translational.max(rotational)
            })
            .fold(0.0, f64::max)
    }
}

/// A rigid body's share of the contact network: the moments of its springs' stiffnesses
/// and dashpots, each with its coupling factor (each spring and dashpot taken isotropic
/// with its stiffer stiffness and larger dashpot, which only adds to them).
#[derive(Clone, Copy, Default)]
struct BodySprings {
    stiffness: Moments,
    damping: Moments,
    springs: usize,
}

impl RigidBodies {
    /// The stable step of the rigid bodies under the contact springs acting now. A rigid
    /// body gathers every spring that touches it, its own nodes' and the other bodies'
    /// nodes pressing its faces, so that its modes under several contacts are stiffer than
    /// any one node's spring-mass pair (the per-node bound of the contact model).
    ///
    /// The bound: the springs' stiffness is `K = sum_c k_c g_c g_c^T`, `g_c` a spring
    /// direction mapped onto the velocities of the two bodies it joins; in mass-weighted
    /// coordinates `u_c = M^-1/2 g_c`. With `(a + b)(a + b)^T <= 2 (a a^T + b b^T)` the
    /// matrix is at most the block-diagonal one whose block for body `B` is `2 sum_c k_c
    /// u_cB u_cB^T` (a wall does not move: no factor 2), so `omega_max^2` is at most the
    /// largest eigenvalue of any body's block, bounded by [`Moments::largest_eigenvalue`].
    /// The dashpots `C` the same way give `gamma >= ` every eigenvalue of `M^-1 C`, so a
    /// mode of frequency `omega` has `zeta omega = u^T C u / 2 <= gamma / 2`, and central
    /// differences are stable for every mode when `dt <= 2 / (sqrt(omega_max^2 + gamma^2 /
    /// 4) + gamma / 2)`, the spring-dashpot bound `(2 / omega)(sqrt(1 + zeta^2) - zeta)`
    /// of each mode at its worst. Deformable nodes keep the per-node and element bounds.
    /// `None` without rigid contacts.
    pub(crate) fn network_bound(
        &self,
        springs: impl Iterator<Item = Spring>,
    ) -> Option<NetworkBound> {
        let mut sums = vec![BodySprings::default(); self.parts.len()];
        let mut add = |part: usize, point: [f64; 3], factor: f64, spring: &Spring| {
            let c = self.parts[part].state.position;
            let r = [point[0] - c[0], point[1] - c[1], point[2] - c[2]];
            let s = &mut sums[part];
            s.stiffness.add(r, factor * spring.stiffness);
            s.damping.add(r, factor * spring.dashpot);
            s.springs += 1;
        };
        for spring in springs {
            // A spring between two bodies counts twice in each (the bound's factor 2).
            let factor = if spring.other.is_some() { 2.0 } else { 1.0 };
            if let Some(part) = self.part_of(spring.body) {
                add(part, spring.point, factor, &spring);
            }
            if let Some((body, point)) = spring.other
                && let Some(part) = self.part_of(body)
            {
                add(part, point, factor, &spring);
            }
        }
        sums.iter()
            .zip(&self.parts)
            .filter(|(s, _)| s.springs > 0)
            .map(|(s, p)| {
                let (m, i_min) = (p.inertia.mass, p.inertia.smallest_moment());
                let omega2 = s.stiffness.largest_eigenvalue(m, i_min);
                let half_gamma = 0.5 * s.damping.largest_eigenvalue(m, i_min);
                NetworkBound {
                    dt: 2.0 / ((omega2 + half_gamma * half_gamma).sqrt() + half_gamma),
                    body: p.body,
                    springs: s.springs,
                }
            })
            .min_by(|a, b| a.dt.total_cmp(&b.dt))
    }

    /// An estimate of the largest frequency squared (1/s^2) of the rigid bodies under the
    /// springs (undamped, each spring isotropic with its stiffness; a wall or a body that is
    /// not rigid holds still): the largest Ritz value of `iterations` Lanczos steps on
    /// `M^-1/2 K M^-1/2` over the rigid bodies' six degrees of freedom. It approaches the
    /// largest eigenvalue from below, where [`RigidBodies::network_bound`] bounds it from
    /// above: the pair says how much the bound gives away. `None` without rigid springs.
    pub(crate) fn network_frequency(&self, springs: &[Spring], iterations: usize) -> Option<f64> {
        let (network, scales) = self.network(springs)?;
        Some(network.largest(&scales, Coefficient::Stiffness, iterations))
    }

    /// The same estimate for the dashpots: the largest eigenvalue of `M^-1/2 C M^-1/2` (1/s),
    /// which bounds `2 zeta omega` of every mode.
    #[cfg(test)]
    pub(crate) fn network_damping(&self, springs: &[Spring], iterations: usize) -> Option<f64> {
        let (network, scales) = self.network(springs)?;
        Some(network.largest(&scales, Coefficient::Dashpot, iterations))
    }

    /// Both: [`RigidBodies::network_frequency`] and [`RigidBodies::network_damping`]
    /// (`(omega^2, gamma)`), from one network, the two Lanczos runs side by side. Each run
    /// is the serial estimate's, so the values are the same bits as the two calls'.
    pub(crate) fn network_frequency_and_damping(
        &self,
        springs: &[Spring],
        iterations: usize,
    ) -> Option<(f64, f64)> {
        let (network, scales) = self.network(springs)?;
        Some(rayon::join(
            || network.largest(&scales, Coefficient::Stiffness, iterations),
            || network.largest(&scales, Coefficient::Dashpot, iterations),
        ))
    }

    /// The springs' network over the rigid bodies, and per body `1/sqrt(m)` and the
    /// world-frame `I^-1/2` (the mass weighting); `None` without a spring on a rigid body.
    fn network(&self, springs: &[Spring]) -> Option<(Network, Vec<MassScale>)> {
        use rayon::prelude::*;
        if self.parts.is_empty() || !springs.iter().any(|s| self.part_of(s.body).is_some()) {
            return None;
        }
        let scales = (self.parts.par_iter())
            .with_min_len(SERIAL_BODIES)
            .map(|p| {
                let r = p.rotation().to_rotation_matrix();
                let d = Matrix3::from_diagonal(&Vector3::from(
                    p.inertia.principal.map(|i| 1.0 / i.sqrt()),
                ));
                (
                    1.0 / p.inertia.mass.sqrt(),
                    r.matrix() * d * r.matrix().transpose(),
                )
            })
            .collect();
        Some((Network::new(self, springs), scales))
    }

    /// The index in `parts` of rigid body `body`, if it is one.
    fn part_of(&self, body: usize) -> Option<usize> {
        match self.index.get(body) {
            Some(&i) if i != NOT_RIGID => Some(i as usize),
            _ => None,
        }
    }
}

/// The largest Ritz value of `iterations` Lanczos steps (at most `n`) on the symmetric
/// operator `apply` of dimension `n`, from a fixed start vector with every component
/// non-zero (so the result depends on the operator alone). It approaches the largest
/// eigenvalue from below; the extreme Ritz values converge first, so no
/// re-orthogonalisation is needed for it.
fn lanczos_largest(n: usize, iterations: usize, mut apply: impl FnMut(&[f64], &mut [f64])) -> f64 {
    let norm = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>().sqrt();
    let mut q: Vec<f64> = (0..n)
        .map(|i| 1.0 + 0.5 * ((i as f64) * 0.7).sin())
        .collect();
    let q_norm = norm(&q);
    q.iter_mut().for_each(|a| *a /= q_norm);
    let (mut previous, mut w) = (vec![0.0; n], vec![0.0; n]);
    let (mut alphas, mut betas) = (Vec::new(), Vec::new());
    let mut beta = 0.0;
    for _ in 0..iterations.min(n) {
        apply(&q, &mut w);
        let alpha: f64 = q.iter().zip(&w).map(|(a, b)| a * b).sum();
        for i in 0..n {
            w[i] -= alpha * q[i] + beta * previous[i];
        }
        alphas.push(alpha);
        beta = norm(&w);
        if beta <= 1e-12 * alpha.abs().max(f64::MIN_POSITIVE) {
            break;
        }
        betas.push(beta);
        std::mem::swap(&mut previous, &mut q);
        for (qi, wi) in q.iter_mut().zip(&w) {
            *qi = wi / beta;
        }
    }
    let m = alphas.len();
    let t = nalgebra::DMatrix::from_fn(m, m, |i, j| match i.abs_diff(j) {
        0 => alphas[i],
        1 => betas[i.min(j)],
        _ => 0.0,
    });
    SymmetricEigen::new(t)
        .eigenvalues
        .iter()
        .copied()
        .fold(0.0, f64::max)
}

/// The springs of a network estimate with their ends resolved once (the body's index and
/// the arm from its centre), and per body the springs acting on it in spring order: the
/// operator's forces are then summed body by body, in parallel, in the order a serial pass
/// over the springs adds them, so the estimate has the same bits.
struct Network {
    /// Per spring, its two ends.
    ends: Vec<SpringEnds>,
    /// Per spring, its stiffness (N/m) and its dashpot (N s/m).
    coefficients: Vec<[f64; 2]>,
    /// Per body, the springs acting on it, in spring order.
    acting: Rows<Acting>,
}

/// Which of a spring's coefficients a network operator is assembled from.
#[derive(Clone, Copy)]
enum Coefficient {
    Stiffness = 0,
    Dashpot = 1,
}

/// A network operator's scratch: per body its velocities, per spring its force.
struct NetworkScratch {
    velocities: Vec<(Vector3<f64>, Vector3<f64>)>,
    forces: Vec<Vector3<f64>>,
}

/// A spring acting on a body: the spring's index, whether the body is the spring's own
/// (pushed by `+f`) or the other end (`-f`), and the arm from the body's centre.
#[derive(Clone, Copy)]
struct Acting {
    spring: u32,
    own: bool,
    arm: Vector3<f64>,
}

impl Network {
    fn new(bodies: &RigidBodies, springs: &[Spring]) -> Self {
        use rayon::prelude::*;
        let arm = |j: usize, point: [f64; 3]| {
            let c = bodies.parts[j].state.position;
            Vector3::new(point[0] - c[0], point[1] - c[1], point[2] - c[2])
        };
        let ends: Vec<SpringEnds> = (springs.par_iter())
            .with_min_len(SPRINGS_PER_TASK)
            .map(|s| {
                let a = bodies.part_of(s.body).map(|j| (j, arm(j, s.point)));
                let b = s
                    .other
                    .and_then(|(body, point)| bodies.part_of(body).map(|j| (j, arm(j, point))));
                [a, b]
            })
            .collect();
        // Per body, the (spring, end) pairs acting on it, springs in order.
        let pairs = (ends.iter().enumerate())
            .flat_map(|(i, ends)| {
                (ends.iter().enumerate()).filter_map(move |(end, x)| {
                    x.map(|(j, arm)| {
                        let own = end == 0;
                        (
                            j,
                            Acting {
                                spring: i as u32,
                                own,
                                arm,
                            },
                        )
                    })
                })
            })
            .collect();
        Network {
            acting: Rows::by_key(bodies.parts.len(), pairs),
            coefficients: springs.iter().map(|s| [s.stiffness, s.dashpot]).collect(),
            ends,
        }
    }

    /// The largest Ritz value of `iterations` Lanczos steps on `M^-1/2 A M^-1/2`, `A`
    /// assembled from the springs' `coefficient`.
    fn largest(&self, scales: &[MassScale], coefficient: Coefficient, iterations: usize) -> f64 {
        let mut scratch = NetworkScratch {
            velocities: vec![(Vector3::zeros(), Vector3::zeros()); scales.len()],
            forces: vec![Vector3::zeros(); self.ends.len()],
        };
        let apply = |x: &[f64], y: &mut [f64]| {
            self.apply(coefficient, (scales, &mut scratch), x, y);
        };
        lanczos_largest(6 * scales.len(), iterations, apply)
    }

    /// `y = M^-1/2 A M^-1/2 x` over the bodies' six degrees of freedom (`scales`: per
    /// body `1 / sqrt(m)` and the world-frame `I^-1/2`): the bodies' velocities, each
    /// spring's force from the stretch rate of its ends, then per body the sum of its
    /// springs' forces and moments.
    fn apply(
        &self,
        coefficient: Coefficient,
        (scales, scratch): (&[MassScale], &mut NetworkScratch),
        x: &[f64],
        y: &mut [f64],
    ) {
        use rayon::prelude::*;
        // Velocities of the bodies from the mass-weighted coordinates, once per body (each
        // spring end reads its body's).
        scratch
            .velocities
            .par_iter_mut()
            .with_min_len(SPRINGS_PER_TASK)
            .zip(scales)
            .enumerate()
            .for_each(|(j, (v, (s, w)))| {
                let lin = Vector3::new(x[6 * j], x[6 * j + 1], x[6 * j + 2]) * *s;
                let ang = w * Vector3::new(x[6 * j + 3], x[6 * j + 4], x[6 * j + 5]);
                *v = (lin, ang);
            });
        let velocities = &scratch.velocities;
        let rate = |end: Option<(usize, Vector3<f64>)>| {
            end.map_or(Vector3::zeros(), |(j, r)| {
                let (lin, ang) = velocities[j];
                lin + ang.cross(&r)
            })
        };
        let k = coefficient as usize;
        scratch
            .forces
            .par_iter_mut()
            .with_min_len(SPRINGS_PER_TASK)
            .zip(&self.ends)
            .zip(&self.coefficients)
            .for_each(|((f, &[a, b]), c)| *f = (rate(a) - rate(b)) * c[k]);
        let (forces, acting) = (&scratch.forces, &self.acting);
        y.par_chunks_mut(6)
            .with_min_len(SERIAL_BODIES)
            .enumerate()
            .for_each(|(j, yj)| {
                let (mut force, mut moment) = (Vector3::zeros(), Vector3::zeros());
                for a in acting.row(j) {
                    let f = forces[a.spring as usize];
                    if a.own {
                        force += f;
                        moment += a.arm.cross(&f);
                    } else {
                        force -= f;
                        moment -= a.arm.cross(&f);
                    }
                }
                let (s, w) = &scales[j];
                yj[..3].copy_from_slice((force * *s).as_slice());
                yj[3..].copy_from_slice((w * moment).as_slice());
            });
    }
}

/// A body's mass weighting: `1 / sqrt(m)` and the world-frame `I^-1/2`.
type MassScale = (f64, Matrix3<f64>);

/// A spring's two ends: the body's index and the arm from its centre to the spring's point
/// (`None`: a wall or a body that is not rigid).
type SpringEnds = [Option<(usize, Vector3<f64>)>; 2];

/// Springs per parallel task of the network operator.
const SPRINGS_PER_TASK: usize = 4096;

/// Ranges of the node positions, velocities and forces.
type NodeRanges<'a> = [&'a mut [[f64; 3]]; 3];

/// A pass over a run of consecutive rigid bodies with their ranges of the node positions,
/// velocities and forces, which start at global node `offset`; false reports a failure
/// (the pass still runs over every body).
type BlockPass<'a> = dyn Fn(&mut [RigidPart], NodeRanges<'_>, usize) -> bool + Sync + 'a;

/// Calls `f` on runs of at most [`SERIAL_BODIES`] parts with their own ranges of the node
/// arrays (which start at global node `offset`), splitting the parts in halves with
/// `rayon::join`; true when every call returned true.
fn with_nodes(
    parts: &mut [RigidPart],
    [x, v, forces]: NodeRanges<'_>,
    offset: usize,
    f: &BlockPass<'_>,
) -> bool {
    if parts.len() <= SERIAL_BODIES {
        return f(parts, [x, v, forces], offset);
    }
    let mid = parts.len() / 2;
    let split = parts[mid].first;
    let (left, right) = parts.split_at_mut(mid);
    let (xl, xr) = x.split_at_mut(split - offset);
    let (vl, vr) = v.split_at_mut(split - offset);
    let (fl, fr) = forces.split_at_mut(split - offset);
    let (a, b) = rayon::join(
        || with_nodes(left, [xl, vl, fl], offset, f),
        || with_nodes(right, [xr, vr, fr], split, f),
    );
    a && b
}

/// Calls `f` on each of a run of parts with its own ranges of the node arrays (which start
/// at global node `offset`); true when every call returned true.
fn each_part(
    parts: &mut [RigidPart],
    [x, v, forces]: NodeRanges<'_>,
    offset: usize,
    f: impl Fn(&mut RigidPart, NodeRanges<'_>) -> bool,
) -> bool {
    let mut ok = true;
    for p in parts {
        let r = p.first - offset..p.first - offset + p.offsets.len();
        ok &= f(p, [&mut x[r.clone()], &mut v[r.clone()], &mut forces[r]]);
    }
    ok
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, SymmetricEigen as Eigen};
    use proptest::prelude::*;

    /// A body of mass `m` and principal moments `i` at `x`, in the world's axes.
    fn part(body: usize, m: f64, i: [f64; 3], x: [f64; 3]) -> RigidPart {
        let tensor = [[i[0], 0.0, 0.0], [0.0, i[1], 0.0], [0.0, 0.0, i[2]]];
        let inertia = RigidInertia::new(m, tensor).expect("valid inertia");
        let state = RigidState::new(&inertia, x, [0.0; 3], [1.0, 0.0, 0.0, 0.0], [0.0; 3]);
        // Node ranges in body order, as a simulation numbers them (empty here).
        RigidPart::new(body, body, Vec::new(), inertia, state)
    }

    /// The drift as nalgebra's quaternion operations compose it, the reference of
    /// [`turn`]'s written-out terms.
    fn drift_by_nalgebra(state: &mut RigidState, inertia: &RigidInertia, dt: f64) {
        use nalgebra::Unit;
        for (x, v) in state.position.iter_mut().zip(state.velocity) {
            *x += dt * v;
        }
        let mut q = quaternion(state.orientation);
        let mut pi = Vector3::from(state.body_momentum);
        for (axis, t) in SPLITTING {
            let phi = t * dt * pi[axis] / inertia.principal[axis];
            let turn =
                UnitQuaternion::from_axis_angle(&Unit::new_unchecked(Vector3::ith(axis, 1.0)), phi);
            pi = turn.inverse_transform_vector(&pi);
            q *= turn;
        }
        q.renormalize();
        state.orientation = [q.w, q.i, q.j, q.k];
        state.body_momentum = array(pi);
    }

    proptest! {
        /// The written-out drift gives nalgebra's numbers over many steps, spinning about
        /// any axes or about one alone (`==` on each number: the same bits, a zero's sign
        /// aside).
        #[test]
        fn the_drift_is_nalgebras_composition(
            moments in prop::array::uniform3(0.05f64..0.5),
            q in prop::array::uniform4(-1.0f64..1.0),
            w in prop::array::uniform3(-300.0f64..300.0),
            still in prop::array::uniform3(any::<bool>()),
            dt in 1e-6f64..1e-3,
        ) {
            prop_assume!(q.iter().map(|a| a * a).sum::<f64>() > 1e-2);
            let tensor = [
                [moments[0], 0.0, 0.0],
                [0.0, moments[1], 0.0],
                [0.0, 0.0, moments[2]],
            ];
            let inertia = RigidInertia::new(2.0, tensor).expect("valid inertia");
            let w = std::array::from_fn(|k| if still[k] { 0.0 } else { w[k] });
            let mut written = RigidState::new(&inertia, [1.0, -2.0, 3.0], [0.5, 0.0, -1.0], q, w);
            let mut reference = written;
            for _ in 0..50 {
                written.drift(&inertia, dt);
                drift_by_nalgebra(&mut reference, &inertia, dt);
                prop_assert_eq!(written.orientation, reference.orientation);
                prop_assert_eq!(written.body_momentum, reference.body_momentum);
                prop_assert_eq!(written.position, reference.position);
            }
        }
    }

    proptest! {
        /// The motion handed to the contact's scan bounds the speed of every node as the
        /// body places it, far from the origin too, and is finite exactly when the nodes
        /// are; a body with a spin that is not a number is not finite.
        #[test]
        fn the_motion_bounds_every_placed_node_speed(
            offsets in prop::collection::vec(prop::array::uniform3(-0.02f64..0.02), 1..40),
            x in prop::array::uniform3(-1e3f64..1e3),
            v in prop::array::uniform3(-5.0f64..5.0),
            w in prop::array::uniform3(-300.0f64..300.0),
            q in prop::array::uniform4(-1.0f64..1.0),
        ) {
            prop_assume!(q.iter().map(|a| a * a).sum::<f64>() > 1e-2);
            let inertia = RigidInertia::new(1.0, [[0.1, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.0, 0.3]])
                .expect("valid inertia");
            let n = offsets.len();
            let state = RigidState::new(&inertia, x, v, q, w);
            let mut part = RigidPart::new(0, 0, offsets, inertia, state);
            let (mut xs, mut vs) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
            part.place_nodes(&mut xs, &mut vs);
            let motion = part.motion();
            prop_assert!(motion.finite);
            let fastest = vs.iter().map(|&a| norm(a)).fold(0.0, f64::max);
            prop_assert!(fastest <= motion.speed_bound, "{fastest} > {}", motion.speed_bound);
            // Not a loose bound: the spin's and the shift's share at most.
            let spin = norm(part.state.angular_velocity(&part.inertia));
            prop_assert!(motion.speed_bound <= (norm(v) + spin * part.reach) * (1.0 + 1e-6));
            part.state.body_momentum[1] = f64::NAN;
            prop_assert!(!part.motion().finite);
        }
    }

    /// `[r]x`, the cross-product matrix.
    fn skew(r: [f64; 3]) -> DMatrix<f64> {
        DMatrix::from_row_slice(
            3,
            3,
            &[0.0, -r[2], r[1], r[2], 0.0, -r[0], -r[1], r[0], 0.0],
        )
    }

    /// The largest eigenvalue of `M^-1 K` for the bodies and isotropic springs, assembled
    /// densely: a spring's stretch rate is `v_A + w_A x r_A - (v_B + w_B x r_B)`.
    fn exact_omega2(bodies: &RigidBodies, springs: &[Spring]) -> f64 {
        let n = 6 * bodies.parts.len();
        let mut k = DMatrix::zeros(n, n);
        for s in springs {
            let mut g = DMatrix::zeros(3, n);
            let mut put = |body: usize, point: [f64; 3], sign: f64| {
                let j = bodies.part_of(body).expect("a rigid body");
                let c = bodies.parts[j].state.position;
                let r = [point[0] - c[0], point[1] - c[1], point[2] - c[2]];
                let block = DMatrix::identity(3, 3) * sign;
                g.view_mut((0, 6 * j), (3, 3)).copy_from(&block);
                g.view_mut((0, 6 * j + 3), (3, 3))
                    .copy_from(&(skew(r) * -sign));
            };
            put(s.body, s.point, 1.0);
            if let Some((b, p)) = s.other {
                put(b, p, -1.0);
            }
            k += g.transpose() * &g * s.stiffness;
        }
        let mut scale = DMatrix::zeros(n, n);
        for (j, p) in bodies.parts.iter().enumerate() {
            for a in 0..3 {
                scale[(6 * j + a, 6 * j + a)] = 1.0 / p.inertia.mass.sqrt();
                scale[(6 * j + 3 + a, 6 * j + 3 + a)] = 1.0 / p.inertia.principal[a].sqrt();
            }
        }
        let a = &scale * k * &scale;
        Eigen::new(a)
            .eigenvalues
            .iter()
            .copied()
            .fold(0.0, f64::max)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// The network bound is a bound: for random bodies joined by random springs (body
        /// pairs and walls, points anywhere near the bodies), its `omega^2` is at least the
        /// exact largest eigenvalue of `M^-1 K`, and within a modest factor of it.
        #[test]
        fn the_network_bound_bounds_the_exact_largest_frequency(
            masses in prop::collection::vec(0.5f64..2.0, 3),
            moments in prop::collection::vec((0.05f64..0.3, 0.05f64..0.3, 0.05f64..0.3), 3),
            springs in prop::collection::vec(
                (0usize..3, 0usize..4, prop::array::uniform3(-0.6f64..0.6), 1.0f64..10.0),
                1..24,
            ),
        ) {
            let centres = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
            let parts = (0..3)
                .map(|j| {
                    let (a, b, c) = moments[j];
                    part(2 * j, masses[j], [a, b, c], centres[j])
                })
                .collect();
            let bodies = RigidBodies::new(parts);
            let springs: Vec<Spring> = springs
                .iter()
                .map(|&(a, b, offset, k)| {
                    let point = |j: usize| {
                        let c = centres[j];
                        [c[0] + offset[0], c[1] + offset[1], c[2] + offset[2]]
                    };
                    Spring {
                        body: 2 * a,
                        point: point(a),
                        // 3 stands for a wall; otherwise another body's point.
                        other: (b < 3 && b != a).then(|| (2 * b, point(b))),
                        stiffness: k,
                        dashpot: 0.0,
                    }
                })
                .collect();
            let exact = exact_omega2(&bodies, &springs);
            let b = bodies.network_bound(springs.iter().copied()).expect("springs on rigid bodies");
            let bound = 4.0 / (b.dt * b.dt);
            prop_assert!(bound >= exact * (1.0 - 1e-9), "bound {bound} below exact {exact}");
            prop_assert!(bound <= 12.0 * exact, "bound {bound} far above exact {exact}");
        }
    }

    /// A range of node ids holds a rigid node when it meets one body's nodes: bodies on
    /// nodes 2..5 and 8..10 (a gap between them and after them).
    #[test]
    fn a_range_holds_a_rigid_node_when_it_meets_a_body() {
        let on = |body, first, n| {
            let mut p = part(body, 1.0, [0.1; 3], [0.0; 3]);
            p.first = first;
            p.offsets = vec![[0.0; 3]; n];
            p
        };
        let bodies = RigidBodies::new(vec![on(0, 2, 3), on(1, 8, 2)]);
        let holds = |r: std::ops::Range<usize>| bodies.holds_any(&r);
        for r in [0..2, 5..8, 10..20, 3..3, 0..0] {
            assert!(!holds(r.clone()), "{r:?}");
        }
        for r in [0..3, 4..5, 4..9, 9..10, 0..20, 7..9] {
            assert!(holds(r.clone()), "{r:?}");
        }
    }

    /// Springs on bodies that are not rigid give no bound, and a body's count includes
    /// the springs of other bodies' nodes on its faces.
    #[test]
    fn the_network_bound_names_the_body_and_counts_its_springs() {
        let bodies = RigidBodies::new(vec![part(1, 1.0, [0.1; 3], [0.0; 3])]);
        let on = |body, other| Spring {
            body,
            point: [0.0, 0.0, -0.5],
            other,
            stiffness: 1.0,
            dashpot: 0.0,
        };
        assert_eq!(bodies.network_bound([on(0, None)].into_iter()), None);
        let b = bodies
            .network_bound([on(1, None), on(0, Some((1, [0.5, 0.0, 0.0])))].into_iter())
            .expect("a rigid body");
        assert_eq!((b.body, b.springs), (1, 2));
    }

    /// One spring and dashpot on a wall through the centre: the body moves as one mass on
    /// one spring-dashpot, and the bound is that pair's (the contact model's formula).
    #[test]
    fn one_spring_through_the_centre_gives_the_spring_dashpot_step() {
        let (m, k, c) = (2.0, 3.0e6, 40.0);
        let bodies = RigidBodies::new(vec![part(0, m, [0.1; 3], [0.0; 3])]);
        let spring = Spring {
            body: 0,
            point: [0.0; 3],
            other: None,
            stiffness: k,
            dashpot: c,
        };
        let b = bodies
            .network_bound([spring].into_iter())
            .expect("a rigid body");
        let zeta = c / (2.0 * (k * m).sqrt());
        let expected = fdem_contact::spring_dashpot_time_step(k, m, zeta);
        assert!(
            (b.dt - expected).abs() <= 1e-12 * expected,
            "{} vs {expected}",
            b.dt
        );
    }

    /// The Lanczos estimate reaches the exact largest eigenvalue once its Krylov space is
    /// the whole space, and stays below the bound.
    #[test]
    fn the_network_frequency_estimate_meets_the_exact_eigenvalue() {
        let centres = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let bodies = RigidBodies::new(
            (0..3)
                .map(|j| part(j, 1.0 + 0.3 * j as f64, [0.1, 0.15, 0.2], centres[j]))
                .collect(),
        );
        let spring = |body: usize, other: Option<usize>, offset: [f64; 3], k: f64| Spring {
            body,
            point: std::array::from_fn(|i| centres[body][i] + offset[i]),
            other: other.map(|o| (o, std::array::from_fn(|i| centres[o][i] + offset[i]))),
            stiffness: k,
            dashpot: 0.0,
        };
        let springs = [
            spring(0, Some(1), [0.5, 0.1, 0.0], 3.0),
            spring(1, Some(2), [-0.5, 0.5, 0.2], 2.0),
            spring(2, None, [0.0, -0.5, 0.1], 5.0),
            spring(0, None, [-0.5, 0.0, 0.3], 1.0),
            spring(1, Some(0), [0.1, -0.2, 0.4], 4.0),
        ];
        let exact = exact_omega2(&bodies, &springs);
        let estimate = bodies
            .network_frequency(&springs, 18)
            .expect("rigid springs");
        assert!(
            (estimate - exact).abs() <= 1e-9 * exact,
            "{estimate} vs {exact}"
        );
        let b = bodies
            .network_bound(springs.iter().copied())
            .expect("rigid springs");
        assert!(4.0 / (b.dt * b.dt) >= estimate);
        assert!(
            bodies
                .network_frequency(&springs, 3)
                .expect("rigid springs")
                <= exact * (1.0 + 1e-12)
        );
        // The dashpots through the same operator: their largest eigenvalue.
        let dashpots: Vec<Spring> = springs
            .iter()
            .map(|s| Spring {
                dashpot: 0.1 * s.stiffness,
                ..*s
            })
            .collect();
        let as_springs: Vec<Spring> = dashpots
            .iter()
            .map(|s| Spring {
                stiffness: s.dashpot,
                ..*s
            })
            .collect();
        let gamma = bodies
            .network_damping(&dashpots, 18)
            .expect("rigid springs");
        let exact = exact_omega2(&bodies, &as_springs);
        assert!((gamma - exact).abs() <= 1e-9 * exact, "{gamma} vs {exact}");
        // Both runs side by side on one network give the two runs' values, bit for bit.
        let omega2 = bodies.network_frequency(&dashpots, 18);
        let both = bodies.network_frequency_and_damping(&dashpots, 18);
        assert_eq!(
            both.map(|(w, g)| (w.to_bits(), g.to_bits())),
            omega2.map(|w| (w.to_bits(), gamma.to_bits()))
        );
    }
}
