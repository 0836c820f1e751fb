//! # fdem-study: coarse-graining studies
//!
//! A study runs series of triaxial tests (an original, h = 1, and its coarse-grained
//! members with and without exact scaling; docs/MODEL.md sections 3-8) over several
//! independent packings, measures what each run cost and how far each result lies from
//! its series' original, and charts speed against accuracy (docs/STUDY.md).
//!
//! # What it owns
//! - **Series** ([`series`]): the presets (`quick`, `equal`, `binary`, `paper`) and custom
//!   series files, expanded over seeds, model and element order into runs, each keyed by
//!   its whole definition ([`RunDef::key`]).
//! - **Running** ([`run`]): the plan and its cost estimate, each run prepared (or its
//!   specimen reused) and tested in turn, its record (`runs/LABEL/run.json`); finished
//!   runs are reused under their key, so an interrupted study resumes.
//! - **Accuracy** ([`metrics`]): the landmarks of each curve, the contact forces at the
//!   peak (through `fdem-micro`), errors against the original, means and spreads over
//!   seeds.
//! - **Results** ([`report`], [`charts`], [`document`]): `runs.csv`, the charts and
//!   `RESULTS.md` with the paper's findings checked.
//! - **Stability maps** ([`stability`]): probes of a dense packing over the step, the
//!   penalty and the damping, for each particle model, and `STABILITY.md`.
//!
//! # What it does not own
//! Specimens, preparation and the test (`fdem-triaxial`), the clustering of contact
//! forces (`fdem-micro`), the plot style (`fdem-core`), progress bars and arguments
//! (`fdem-cli`).
#![warn(missing_docs)]

pub mod charts;
pub mod cost;
pub mod document;
mod error;
pub mod limits;
pub mod metrics;
pub mod report;
pub mod run;
pub mod series;
pub mod stability;

pub use document::{Provenance, results_markdown, write_results};
pub use error::StudyError;
pub use report::{Results, gather};
pub use run::{RunRecord, SilentStudy, StudyObserver, StudyPlan, failed_record, plan, run_study};
pub use series::{
    Member, OrderChoice, RunDef, Series, StudyOptions, StudyPreset, expand, load_series,
    quick_series,
};
