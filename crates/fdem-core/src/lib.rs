//! # fdem-core: the small helpers every fdem crate shares, defined once
//!
//! The bottom layer of the workspace: it depends on no other fdem crate, and the crates
//! above use it instead of keeping copies, so a convention (a rounding, a temporary file
//! name, a column order, a colour) is the same everywhere.
//!
//! # What this crate owns
//! - **Geometry** ([`geometry`]): `[f64; 3]` vector arithmetic and the triangle and
//!   tetrahedron formulas (area vectors, signed volumes, dihedral angles), written out
//!   in a fixed operation order so that every crate gets the same bits.
//! - **Atomic file output** ([`fs`]): [`fs::write_atomically`] and the streaming
//!   [`fs::AtomicFile`]; every file goes to `NAME.part` in its own directory and is renamed
//!   when complete.
//! - **The contact snapshot format** ([`snapshot`]): the node-level and pair-level CSV
//!   files (docs/MICRO.md): headers, rows, their writer and the header-driven reader.
//! - **A stable hash** ([`hash`]): FNV-1a, for file checksums and run keys.
//! - **Space order** ([`space_order`]): the Morton (Z-order) curve, to number items that
//!   are near in space near in memory.
//! - **Order statistics** ([`statistics`]): the median of samples.
//! - **Numbers in messages** ([`number`]): [`number::Number`] prints a value plain where
//!   that is short and in exponent form otherwise.
//! - **Run identifiers** ([`run_id`]): the UTC start and the input's hash that name a
//!   run in its `summary.json`.
//! - **Sections files** ([`sections`]): named arrays of numbers and texts in one
//!   checksummed binary file, read back bit for bit (run checkpoints).
//! - **The plot style** ([`plot`]): palette, fonts, chart layout, axes, legend and series
//!   for the SVG figures.
//! - **Huge pages** ([`huge_pages`]): the system allocator asking for transparent huge
//!   pages for large blocks, for the binaries that run large models.
//!
//! # What it does not own
//! No physics and no project types: no meshes (`fdem-mesh`), element kernels or their
//! 3x3 matrices (`fdem-elastic`), contact detection (`fdem-contact`), node state or run
//! outputs beyond the file mechanics (`fdem-solver`), no analysis of the snapshots
//! (`fdem-micro`) and no figure's content (the crates that draw them). Errors are
//! [`std::io::Error`], [`snapshot::CsvError`] or plotting messages; each crate maps them
//! into its own error type.
//!
//! # Example
//! ```
//! use fdem_core::geometry::{cross, tet_signed_volume};
//! use fdem_core::snapshot::{Counterpart, PairRow, pairs_text, parse_pairs};
//!
//! assert_eq!(cross([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]), [0.0, 0.0, 1.0]);
//! let unit = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
//! assert_eq!(tet_signed_volume(unit[0], unit[1], unit[2], unit[3]), 1.0 / 6.0);
//!
//! let row = PairRow {
//!     body: 0,
//!     counterpart: Counterpart::Wall(1),
//!     normal_force: [0.0, 0.0, 2.5],
//!     tangential_force: [0.0; 3],
//!     nodes: 3,
//! };
//! let text = pairs_text(0.5, [row]);
//! assert_eq!(parse_pairs(text.as_bytes(), "<input>")?, [row]);
//! # Ok::<(), fdem_core::snapshot::CsvError>(())
//! ```
#![warn(missing_docs)]

pub mod fs;
pub mod geometry;
pub mod hash;
pub mod huge_pages;
pub mod number;
pub mod plot;
pub mod rows;
pub mod run_id;
pub mod sections;
pub mod snapshot;
pub mod space_order;
pub mod statistics;
