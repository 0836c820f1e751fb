//! Stored-energy jumps: a diagnostic log of the contacts whose stored energy changed in
//! one evaluation by more than continuous motion explains.
//!
//! # Why
//! The penalty law (eqs 1-3) conserves energy along a smooth path: the force on the node is
//! minus the gradient of `k_n d_n^2 / 2` for a fixed face, and the reactions spread by the
//! barycentric weights are the gradient with respect to the face's nodes. Energy is
//! created or destroyed only where the contact itself is discontinuous: it appears at a
//! finite depth, disappears at one, or moves to another face whose depth differs. Each of
//! those adds `E_after - E_before` to the energy balance without any work. This log names
//! every such event above a threshold with its cause, so that the balance error of a run
//! can be broken down by mechanism.
//!
//! # Causes
//! Per evaluation, the contacts are merged with the previous evaluation's by their key
//! (surface node, counterpart):
//! - **appeared**: a contact without a predecessor, stored energy above the threshold; the
//!   cause is why the previous evaluation had none ([`Reason`]).
//! - **vanished**: a predecessor without a successor, its stored energy above the threshold;
//!   the cause is why this evaluation has none.
//! - **face switch**: the same key on another face (or from a face to a sheet's edge, or
//!   back), with a stored-energy change above the threshold.
//!
//! The log costs nothing when it is off (the default): the narrow phase records its
//! rejections only while it is on.

use serde::{Deserialize, Serialize};

/// Why a (node, counterpart) pair has no contact in an evaluation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Reason {
    /// The counterpart had candidate faces, but the node was behind none of them with its
    /// foot inside (and, for a sheet, behind no edge).
    NoFaceBehind,
    /// The node was behind a face, but a nearer face of the same body covered it from the
    /// front (the closest-face rule).
    ClosestFace,
    /// A hit on a sheet deeper than the fold depth, discarded as a fold artefact.
    FoldDiscard,
    /// A new hit on a sheet deeper than a node can move in one step, discarded as a fold
    /// artefact.
    DeepStart,
    /// The counterpart had no candidate face near the node (broad phase).
    NoCandidate,
    /// A wall the node is in front of.
    InFrontOfWall,
}

impl Reason {
    /// Name used in logs and summaries.
    pub fn name(self) -> &'static str {
        match self {
            Reason::NoFaceBehind => "no_face_behind",
            Reason::ClosestFace => "closest_face",
            Reason::FoldDiscard => "fold_discard",
            Reason::DeepStart => "deep_start",
            Reason::NoCandidate => "no_candidate",
            Reason::InFrontOfWall => "in_front_of_wall",
        }
    }
}

/// What kind of discontinuity a jump is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JumpKind {
    /// The contact appeared at a finite depth; the reason is why it had none before.
    Appeared(Reason),
    /// The contact disappeared at a finite depth; the reason is why it has none now.
    Vanished(Reason),
    /// The contact moved to another face (or to or from a sheet's edge).
    FaceSwitch,
}

impl JumpKind {
    /// Name used in logs and summaries, e.g. `vanished:fold_discard`.
    pub fn name(self) -> String {
        match self {
            JumpKind::Appeared(r) => format!("appeared:{}", r.name()),
            JumpKind::Vanished(r) => format!("vanished:{}", r.name()),
            JumpKind::FaceSwitch => "face_switch".to_string(),
        }
    }
}

/// One stored-energy jump of one contact.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EnergyJump {
    /// Global id of the surface node.
    pub node: usize,
    /// Body of the node.
    pub body: u32,
    /// What the node touches (or touched).
    pub counterpart: crate::Counterpart,
    /// The discontinuity.
    pub kind: JumpKind,
    /// Stored energy of the contact before (J); 0 for an appeared contact.
    pub energy_before: f64,
    /// Stored energy after (J); 0 for a vanished contact.
    pub energy_after: f64,
    /// Depth before and after (m); 0 where there was no contact.
    pub depth_before: f64,
    /// See `depth_before`.
    pub depth_after: f64,
    /// Whether the contact was a sheet's edge hit before / after.
    pub edge_before: bool,
    /// See `edge_before`.
    pub edge_after: bool,
}

impl EnergyJump {
    /// The stored energy the jump added to the model (J): `energy_after - energy_before`.
    pub fn change(&self) -> f64 {
        self.energy_after - self.energy_before
    }
}

/// A rejected (node, counterpart) pair of one evaluation, recorded while the log is on.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rejection {
    pub(crate) key: u64,
    pub(crate) reason: Reason,
}

/// The log's state inside the contact model.
#[derive(Clone, Debug, Default)]
pub(crate) struct JumpLog {
    /// Jumps whose stored-energy change is at most this (J) are not logged.
    pub(crate) threshold: f64,
    /// The previous evaluation's rejections, sorted by key.
    pub(crate) previous_rejections: Vec<Rejection>,
    /// Jumps logged since the caller last took them.
    pub(crate) events: Vec<EnergyJump>,
}
