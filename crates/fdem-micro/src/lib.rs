//! Contact-force micro-analysis (docs/MODEL.md section 9, paper section 2.4 and Table 5).
//!
//! In FDEM one particle-particle contact is spread over several surface nodes. This crate
//! clusters node-level contact forces into particle-level contacts and reports their
//! statistics, as the paper does at the peak of the triaxial test.
//!
//! # What this crate owns
//! - **Reading and writing snapshots** ([`snapshot`]): node-level snapshots
//!   (`contacts/nodes_NNNNNN.csv`, the format `fdem run --contacts` writes, usable by any
//!   other code: docs/MICRO.md) and per body-pair ground truth (`pairs_NNNNNN.csv`), with
//!   errors that name file, line and column. The format itself (headers, rows, the
//!   header-driven reader) is defined once in `fdem-core`, shared with the solver that
//!   writes it.
//! - **Clustering** ([`cluster()`]): per particle DBSCAN ([`dbscan()`]) over the nodes
//!   that carry a normal force, with a neighbourhood radius tied to the local node
//!   spacing, and pairing of clusters into contacts (both sides of a body pair merged;
//!   action and reaction matched geometrically when the counterpart is not recorded);
//!   walls, boundary bodies and unpaired clusters are boundary contacts.
//! - **Statistics** ([`statistics()`]): contact count, coordination number, mean forces,
//!   the distribution of `F_n / mean(F_n)` in fixed bins, strong (> 4) and weak (< 0.2)
//!   shares; a Table 5-style comparison of runs ([`table`]).
//! - **Validation** ([`validate()`]): recall, precision and force error of the clustered
//!   pairs against the ground truth.
//! - **The plot** ([`plot_distributions`]): `force_distribution.svg`.
//! - **Run directories** ([`locate_snapshot`], [`analyse`]) and synthetic snapshots with a
//!   known answer for tests and benchmarks ([`synthetic`]).
//!
//! # What it does not own
//! It reads snapshots, never solver state: it depends on no other fdem crate but
//! `fdem-core` (the snapshot format, vector helpers, atomic files, plot style), and knows
//! nothing of meshes, contact detection or time integration. Running a scene (with
//! `--contacts`) belongs to `fdem-solver`, argument parsing and printing to `fdem-cli`.
//!
//! # Example
//! ```
//! use fdem_micro::{ClusterParams, cluster, statistics, synthetic, validate};
//! let mut spec = synthetic::SyntheticSpec::e2(7);
//! spec.grid = [3, 3, 3];
//! let data = synthetic::generate(&spec);
//! let contacts = cluster(&data.snapshot, &ClusterParams::default())?;
//! let stats = statistics(&contacts, Some(data.particles));
//! assert_eq!(stats.contacts, data.particle_contacts);
//! let check = validate(&contacts, &data.truth, 0.01);
//! assert_eq!(check.body_pairs.recall, Some(1.0));
//! # Ok::<(), fdem_micro::MicroError>(())
//! ```
#![warn(missing_docs)]

pub mod cluster;
pub mod dbscan;
mod error;
pub mod plot;
pub mod run;
pub mod snapshot;
pub mod stats;
pub mod synthetic;
pub mod validate;
mod vec3;

pub use cluster::{ClusterParams, Clustering, Contact, ContactKind, cluster, write_contacts};
pub use dbscan::dbscan;
pub use error::MicroError;
pub use plot::{Series, plot_distributions};
pub use run::{
    Analysis, AnalysisOptions, SnapshotChoice, SnapshotFiles, all_snapshots, analyse,
    locate_snapshot, summary_bodies,
};
pub use snapshot::{
    Counterpart, NodeRow, PairRow, Snapshot, parse_nodes, parse_pairs, read_nodes, read_pairs,
    write_nodes, write_pairs,
};
pub use stats::{Histogram, Statistics, TableRow, statistics, table};
pub use validate::{PairValidation, Validation, validate};
