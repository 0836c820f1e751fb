//! The crate's error type.

use crate::Counterpart;
use fdem_core::number::Number;

/// Everything that can go wrong while setting up or evaluating contact.
///
/// Every message says what was wrong, where (field, node, body, triangle, wall) and what
/// would fix it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ContactError {
    /// A contact parameter is out of its range.
    #[error(
        "contact parameter `{field}` = {} is invalid: it must be {requirement}; \
         fix it in the contact parameters (paper Table 3 gives normal_penalty 1.8e11 N/m^3, \
         penalty_ratio 1, friction 0.3, damping 0.2, damping_ratio 1)",
        Number(*.value)
    )]
    InvalidParameter {
        /// Name of the field of [`crate::ContactParams`].
        field: &'static str,
        /// The value that was given.
        value: f64,
        /// What the value must satisfy.
        requirement: &'static str,
    },

    /// Two arrays that must be parallel have different lengths.
    #[error(
        "`{array}` has {found} entries but {expected} were expected ({reason}); \
         build the arrays from the same mesh assembly"
    )]
    LengthMismatch {
        /// Name of the offending array.
        array: &'static str,
        /// Required length.
        expected: usize,
        /// Actual length.
        found: usize,
        /// Which other array fixes the length.
        reason: &'static str,
    },

    /// A node id in the surface description does not exist.
    #[error(
        "{what} refers to node {node}, but only {n_nodes} nodes exist (the length of the mass \
         array); pass the masses of all nodes of the assembly"
    )]
    NodeOutOfRange {
        /// Which entry (for example `"triangle 12"` or `"surface node 3"`).
        what: String,
        /// The node id.
        node: usize,
        /// Number of nodes known to the model.
        n_nodes: usize,
    },

    /// Forces were asked of an evaluation that did not happen or failed.
    #[error(
        "no contact evaluation waits for its forces: call ContactModel::evaluate (and check \
         its result) before ContactModel::add_evaluated_forces, once per evaluation"
    )]
    NotEvaluated,

    /// The surface description is inconsistent.
    #[error("inconsistent contact surface: {what}; {fix}")]
    InconsistentSurface {
        /// What is inconsistent, with the entry that shows it.
        what: String,
        /// How to fix it.
        fix: &'static str,
    },

    /// A control area is not finite and positive.
    #[error(
        "control area {} m^2 of surface node {node} (body {body}) is not finite and > 0; \
         control areas are one third of the areas of the triangles around a node \
         (fdem_mesh::Surface::from_triangles computes them)",
        Number(*.area)
    )]
    InvalidControlArea {
        /// Global node id.
        node: usize,
        /// Body of the node.
        body: u32,
        /// The area that was given.
        area: f64,
    },

    /// A node mass is not finite and positive.
    #[error(
        "lumped mass {} kg of surface node {node} (body {body}) is not finite and > 0; \
         pass the lumped masses of the assembled bodies (every surface node needs a mass)",
        Number(*.mass)
    )]
    InvalidMass {
        /// Global node id.
        node: usize,
        /// Body of the node.
        body: u32,
        /// The mass that was given.
        mass: f64,
    },

    /// A contact length other than the margin (depth limit, sheet fold depth) is invalid.
    #[error(
        "contact {what} {} m is not finite and > 0; give a positive length",
        Number(*.value)
    )]
    InvalidLength {
        /// `"depth limit"` or `"sheet fold depth"`.
        what: &'static str,
        /// The value that was given.
        value: f64,
    },

    /// A field of a [`crate::RefreshPolicy`] is out of its range.
    #[error(
        "refresh policy's {field} = {} is not in {range}; give a value in that range (the \
         default policy: RefreshPolicy::default())",
        Number(*.value)
    )]
    InvalidRefreshPolicy {
        /// `"near"`, `"max_fraction"` or `"max_refreshed_fraction"`.
        field: &'static str,
        /// The value that was given.
        value: f64,
        /// The allowed range, as text.
        range: &'static str,
    },

    /// A mean motion ([`crate::ContactModel::set_mean_motion`]) with a value that is not
    /// finite.
    #[error(
        "mean motion's {what} is not finite ({value}); give finite numbers (the origin in m, \
         the rate in 1/s, the time in s)"
    )]
    InvalidMeanMotion {
        /// `"origin"`, `"rate"` or `"time"`.
        what: &'static str,
        /// The values given, as text.
        value: String,
    },

    /// The Verlet-skin margin is not finite and positive.
    #[error(
        "contact margin {} m is not finite and > 0; use for example \
         ContactModel::suggested_margin (a tenth of the shortest surface edge)",
        Number(*.margin)
    )]
    InvalidMargin {
        /// The margin that was given.
        margin: f64,
    },

    /// A wall description is invalid.
    #[error("wall {wall} is invalid: {reason}")]
    InvalidWall {
        /// Index of the wall.
        wall: usize,
        /// What is wrong and how to fix it.
        reason: String,
    },

    /// The time step or the time passed to an evaluation is invalid.
    #[error(
        "{quantity} = {} is invalid for a contact evaluation: {requirement}",
        Number(*.value)
    )]
    InvalidStep {
        /// `"dt"` or `"time"`.
        quantity: &'static str,
        /// The value that was given.
        value: f64,
        /// What the value must satisfy.
        requirement: &'static str,
    },

    /// A node position or velocity is NaN or infinite.
    #[error(
        "{quantity} of surface node {node} (body {body}) is not finite (NaN or infinite); \
         the simulation has diverged: reduce the time step (check the stable step of the \
         elastic and contact bounds) or the loading rate"
    )]
    NonFinite {
        /// `"position"` or `"velocity"`.
        quantity: &'static str,
        /// Global node id.
        node: usize,
        /// Body of the node.
        body: u32,
        /// The offending vector (not printed: the message names the node and its body).
        value: [f64; 3],
    },

    /// A node moves too far relative to nearby faces in one step: a contact could be lost.
    #[error(
        "tunnelling risk: surface node {node} (body {body}) moves {displacement:.3e} m \
         relative to {relative_to} in one step of dt = {dt:.3e} s, more than half of the \
         {scale} {limit:.3e} m; reduce the time step or enlarge the {scale}"
    )]
    Tunnelling {
        /// Global node id.
        node: usize,
        /// Body of the node.
        body: u32,
        /// What the node moves relative to (a face of a body, a wall, or any other body).
        relative_to: String,
        /// Relative displacement in one step (m): relative speed times dt.
        displacement: f64,
        /// The length of which half may be crossed in one step (m): the margin against a
        /// sheet, the depth limit against a solid or a wall.
        limit: f64,
        /// Which length `limit` is.
        scale: TunnellingScale,
        /// The time step (s).
        dt: f64,
    },

    /// A node penetrated a face deeper than half the depth limit: the next step could lose
    /// the contact.
    #[error(
        "surface node {node} (body {body}) penetrates {counterpart} by {depth:.3e} m, more \
         than half of the depth limit {depth_limit:.3e} m beyond which a contact is no longer \
         detected (and no larger than its cap, where it may grow); raise the depth limit \
         (contact.depth_limit, or the margin it defaults to), raise the normal penalty, \
         reduce the loading, or remove initial overlaps"
    )]
    PenetrationTooDeep {
        /// Global node id.
        node: usize,
        /// Body of the node.
        body: u32,
        /// The body whose face is penetrated.
        counterpart: Counterpart,
        /// Penetration depth (m).
        depth: f64,
        /// Depth limit (m).
        depth_limit: f64,
    },

    /// More surface nodes or triangles than the 32-bit indices of the contact arrays hold.
    #[error(
        "{what} count {count} exceeds the limit {limit} of the contact index arrays; split \
         the problem or run with fewer particles"
    )]
    TooLarge {
        /// `"surface node"` or `"triangle"`.
        what: &'static str,
        /// The count.
        count: usize,
        /// The limit.
        limit: usize,
    },
}

/// The length that bounds a node's motion relative to a counterpart in one step
/// ([`ContactError::Tunnelling`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TunnellingScale {
    /// The contact margin (the Verlet skin): against a sheet.
    Margin,
    /// The depth limit: against a solid face or a wall, and between bodies not yet
    /// candidates of each other.
    DepthLimit,
}

impl std::fmt::Display for TunnellingScale {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            TunnellingScale::Margin => "contact margin",
            TunnellingScale::DepthLimit => "depth limit",
        })
    }
}
