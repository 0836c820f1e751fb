//! The crate's error type.

use std::path::PathBuf;

/// Everything that can go wrong while reading snapshots, clustering or writing results.
///
/// Every message says what was wrong, where (file, line, column) and what would fix it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MicroError {
    /// A file could not be read, written or renamed.
    #[error("{action} {}: {source}", path.display())]
    Io {
        /// What was being done (`"reading"`, `"writing"`, ...).
        action: &'static str,
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },

    /// A CSV file is malformed: a missing column, an unparsable or out-of-range value, a
    /// row with the wrong number of fields.
    #[error("{file}:{line}:{column}: {message}")]
    Csv {
        /// The file (or `"<input>"` for text given in memory).
        file: String,
        /// 1-based line number (1 is the header).
        line: u64,
        /// The column: its header name, or its 1-based position when there is no name.
        column: String,
        /// What was wrong and how to fix it.
        message: String,
    },

    /// A snapshot built in memory holds a value the CSV reader would have refused.
    #[error("snapshot row {row} (node {node}, body {body}): {message}")]
    InvalidRow {
        /// 0-based index of the row in [`crate::Snapshot::rows`].
        row: usize,
        /// Its node id.
        node: u64,
        /// Its body.
        body: u32,
        /// What is wrong.
        message: String,
    },

    /// A clustering or analysis parameter is out of its range.
    #[error(
        "parameter `{name}` = {} is invalid: it must be {requirement}",
        fdem_core::number::Number(*.value)
    )]
    InvalidParameter {
        /// The parameter's name (as in [`crate::ClusterParams`] or the CLI flag).
        name: &'static str,
        /// The value that was given.
        value: f64,
        /// What the value must satisfy.
        requirement: &'static str,
    },

    /// No snapshot was found where one was asked for.
    #[error("no contact snapshot in {}: {detail}", path.display())]
    NoSnapshot {
        /// The run directory (or file) that was searched.
        path: PathBuf,
        /// What was looked for and how to produce it.
        detail: String,
    },

    /// The force-distribution plot could not be drawn.
    #[error("drawing {}: {message}", path.display())]
    Plot {
        /// The SVG file.
        path: PathBuf,
        /// The plotting library's message.
        message: String,
    },
}

impl MicroError {
    pub(crate) fn io(action: &'static str, path: &std::path::Path, source: std::io::Error) -> Self {
        MicroError::Io {
            action,
            path: path.to_path_buf(),
            source,
        }
    }
}
