//! The penalty contact law of one node against one face or wall (paper eqs 1-3).
//!
//! The law is purely local: it knows the contact normal, the penetration depth, the
//! relative velocity and the tangential history of one contact, and returns the force on
//! the node. [`crate::ContactModel`] finds the contacts and spreads the reactions.

use serde::{Deserialize, Serialize};

use crate::NodeCoefficients;
use crate::vec3::{add, dot, norm, norm2, scale, sub};

/// What the law needs to know about one contact in one evaluation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LawInput {
    /// Unit contact normal, pointing from the face (or wall) towards the side the node
    /// belongs on: the normal force on the node is along `+normal`.
    pub normal: [f64; 3],
    /// Penetration depth `d_n >= 0` (m) of the node behind the face.
    pub depth: f64,
    /// Velocity of the node minus the velocity of the face at the contact point (m/s).
    pub relative_velocity: [f64; 3],
    /// Time step (s) by which the tangential displacement is incremented.
    pub dt: f64,
    /// Spring and dashpot coefficients of the node (eqs 2-3).
    pub coefficients: NodeCoefficients,
}

/// What the law returns for one contact.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LawOutput {
    /// Normal force on the node (N), `F_n normal` with `F_n >= 0`.
    pub normal_force: [f64; 3],
    /// Tangential force on the node (N), `|F_s| <= mu F_n`.
    pub tangential_force: [f64; 3],
    /// Magnitude `F_n` of the normal force (N).
    pub normal_magnitude: f64,
    /// Whether the contact slides (the Coulomb cap was reached).
    pub sliding: bool,
    /// Stored elastic energy `k_n d_n^2 / 2 + k_s |d_s|^2 / 2` (J), after the cut-back.
    pub stored_energy: f64,
    /// Power dissipated by the normal dashpot (W), `(F_n - k_n d_n) v_approach`: equal to
    /// `c_n v_approach^2` while the force is not clamped, and to the spring power that the
    /// clamp removes (`-k_n d_n v_approach >= 0`) while it is.
    pub normal_damping_power: f64,
    /// Power dissipated by the tangential dashpot (W): minus the power of the non-elastic
    /// part `F_s + k_s d_s` of the tangential force at the relative tangential velocity;
    /// `c_s |v_t|^2` while sticking.
    pub tangential_damping_power: f64,
    /// Energy dissipated by frictional sliding in this evaluation (J): the work
    /// `k_s d_s . (d_s,trial - d_s)` of the capped spring force over the slip removed by
    /// the Coulomb cut-back.
    pub friction_dissipation: f64,
}

impl LawOutput {
    /// Total force on the node (N): normal plus tangential part.
    pub fn force(&self) -> [f64; 3] {
        add(self.normal_force, self.tangential_force)
    }
}

/// Evaluates the contact law for one node (docs/MODEL.md section 2, paper eqs 1-3).
///
/// - Normal (eq 1 with eqs 2-3): `F_n = max(0, k_n d_n + c_n v_approach)` with
///   `v_approach = -(v_rel . n)`. The paper writes `|k_n d_n - f_vd|`; we clamp at zero
///   instead, so the normal force **never attracts** (no adhesion). This is a deliberate
///   deviation: with the absolute value a fast-separating contact would be pushed apart
///   harder, not released.
/// - Tangential (eq 1): the elastic displacement `d_s` (`history`, m) is first rotated
///   into the current tangent plane (projected, then rescaled to its former length), then
///   incremented by `v_t dt`, `v_t` the relative tangential velocity. The trial force is
///   `F_s = -(k_s d_s + c_s v_t)`; if `|F_s| > mu F_n` the contact slides, the force is
///   scaled to `mu F_n`, and if `k_s |d_s| > mu F_n`, `d_s` is cut back along itself so
///   that `k_s |d_s| = mu F_n`.
///
/// `history` is updated in place: pass `[0.0; 3]` for a new contact.
pub fn evaluate_law(input: &LawInput, history: &mut [f64; 3]) -> LawOutput {
    let c = &input.coefficients;
    let n = input.normal;
    let v = input.relative_velocity;
    let v_normal = dot(v, n);
    // Eq 1: approach speed > 0 while the node moves into the face.
    let v_approach = -v_normal;
    let spring_n = c.normal_stiffness * input.depth;
    // Eq 1 with eq 3 damping, clamped so that the force never pulls.
    let f_n = (spring_n + c.normal_damping * v_approach).max(0.0);
    let normal_damping_power = (f_n - spring_n) * v_approach;

    // Eq 1 tangential part: history rotated into the current tangent plane.
    let v_t = sub(v, scale(n, v_normal));
    let h = *history;
    let h_plane = sub(h, scale(n, dot(h, n)));
    let hp2 = norm2(h_plane);
    let mut d_s = if hp2 > 0.0 {
        scale(h_plane, (norm2(h) / hp2).sqrt())
    } else {
        [0.0; 3]
    };
    d_s = add(d_s, scale(v_t, input.dt));
    let trial = scale(
        add(
            scale(d_s, c.tangential_stiffness),
            scale(v_t, c.tangential_damping),
        ),
        -1.0,
    );
    let cap = c.friction * f_n;
    let trial_magnitude = norm(trial);
    let sliding = trial_magnitude > cap;
    let f_s = if sliding {
        if trial_magnitude > 0.0 {
            scale(trial, cap / trial_magnitude)
        } else {
            [0.0; 3]
        }
    } else {
        trial
    };
    // Coulomb cut-back of the elastic displacement: k_s |d_s| = mu F_n.
    let spring_t = c.tangential_stiffness * norm(d_s);
    let mut friction_dissipation = 0.0;
    if spring_t > cap {
        let trial_d = d_s;
        d_s = scale(d_s, cap / spring_t);
        // Work of the capped spring force over the slip that is cut away,
        // `k_s d_s . (d_trial - d_s)`. With it the discrete energy balance closes in steady
        // sliding; the spring-energy difference `k_s (|d_trial|^2 - |d_s|^2) / 2` would
        // over-count by `k_s |slip|^2 / 2` every step (all of it when mu = 0).
        friction_dissipation = c.tangential_stiffness * dot(d_s, sub(trial_d, d_s));
    }
    *history = d_s;
    let non_elastic = add(f_s, scale(d_s, c.tangential_stiffness));
    LawOutput {
        normal_force: scale(n, f_n),
        tangential_force: f_s,
        normal_magnitude: f_n,
        sliding,
        stored_energy: 0.5 * spring_n * input.depth + 0.5 * c.tangential_stiffness * norm2(d_s),
        normal_damping_power,
        tangential_damping_power: -dot(non_elastic, v_t),
        friction_dissipation,
    }
}
