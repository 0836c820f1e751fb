//! # fdem-solver: the explicit dynamics engine
//!
//! This crate owns the time integration of an FDEM system: node state in
//! structure-of-arrays form ([`NodeState`]), bodies as contiguous node and element ranges
//! ([`Body`]), the [`ForceContribution`] interface that elements now, and contact, walls
//! and membranes later, implement, explicit central differences (velocity Verlet) with a
//! fixed or automatic step ([`Simulation`]), energy bookkeeping with a stability guard,
//! TOML scenes ([`Scene`], schema in `docs/SCENES.md`) and run outputs ([`run`]).
//!
//! It does not own element kernels (fdem-elastic), meshes (fdem-mesh) or contact
//! (fdem-contact); it composes them.
//!
//! **Determinism.** Per-body element loops run in parallel with rayon, but bodies own
//! disjoint node ranges, so every force is summed in the same order whatever the thread
//! count: runs are bit-for-bit repeatable.
#![warn(missing_docs)]

mod auto_model;
mod body;
mod checkpoint;
mod contact;
mod dimensions;
mod engine;
mod error;
mod forces;
mod initial_overlap;
mod memory;
mod model;
pub mod output;
mod rigid;
mod run;
mod scene;
mod state;
mod team;
pub mod toml_input;

pub use auto_model::{
    DEFAULT_AUTO_THRESHOLD, DeflectionEstimate, DeflectionInputs, PatchRegime, deflection_estimate,
    mean_contact_force, mean_node_area,
};
pub use body::{Body, BodyKind, BodyMotion, Connectivity};
pub use checkpoint::{RigidCheckpoint, SimulationCheckpoint};
pub use contact::ContactForces;
pub use dimensions::{Applied, Field, Role};
pub use engine::{EnergyReport, Guard, NodesMut, Simulation, TimeStep};
pub use error::SolverError;
pub use forces::{
    BodyElements, Constraint, ElasticForces, ElementInput, ForceContribution, NodeView, Powers,
    StepBound, VerletWork, node_span,
};
pub use memory::{
    BYTES_BASE, BYTES_PER_ELEMENT, BYTES_PER_NODE, BYTES_PER_SURFACE_NODE, ModelSize, ParticleSize,
    bytes_text,
};
pub use model::{
    BodyId, ConstraintHandle, ContactSettings, Handle, InitialMotion, ModelBuilder, SheetBody,
    WallId,
};
pub use rigid::{RigidInertia, RigidState};
pub use run::{
    MAX_OUTPUTS, MAX_STEPS, Observer, RunOptions, RunPlan, RunSummary, Silent, check_memory, run,
    step_count,
};
pub use scene::{
    AutoSection, ContactSection, DEFAULT_DT_SAFETY, DEFAULT_MARGIN_FRACTION, DEFAULT_OUTPUTS,
    MaterialSection, MeshSection, ParticleModel, ParticleSection, Scene, SimulationSection,
    WallSection, WallType, sphere_axes,
};
pub use state::NodeState;
