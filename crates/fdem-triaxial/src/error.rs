//! The crate's error type.

use fdem_core::number::Number;
use std::path::PathBuf;

/// Everything that can refuse a specimen definition, stop a preparation or refuse a
/// specimen file. Every message is one line saying what was wrong, where (file, line, key)
/// and how to fix it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TriaxialError {
    /// A specimen definition that does not parse or breaks a rule of the schema
    /// (docs/SPECIMENS.md). Raised before any work is done.
    #[error("{origin}{}: {key}: {message}", location(*line, *column))]
    Definition {
        /// The file, or `preset E1` for a built-in test.
        origin: String,
        /// 1-based line of the offending value (0 when the rule spans several keys).
        line: usize,
        /// 1-based column (0 when unknown).
        column: usize,
        /// Key path such as `gradation[1].size`.
        key: String,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// A test name that is not in the catalogue.
    #[error("unknown test `{name}`; the catalogue holds {known} (see `fdem specimen --list`)")]
    UnknownTest {
        /// The name given.
        name: String,
        /// The known names, comma separated.
        known: String,
    },
    /// Random placement could not fit the particles, even in the tallest column tried.
    #[error(
        "could not place particle {particle} of {total} (diameter {} m) without overlap \
         in a column {:.4} m tall after {sweeps} relaxation sweeps; lower \
         preparation.loose_solid_fraction",
        Number(*.diameter),
        Number(*.height)
    )]
    Placement {
        /// Index of the particle that did not fit (large ones are placed first).
        particle: usize,
        /// Number of particles to place.
        total: usize,
        /// Its diameter (m).
        diameter: f64,
        /// Height of the last column tried (m).
        height: f64,
        /// Relaxation sweeps run in the last column.
        sweeps: usize,
    },
    /// The solver refused a set-up or a step during preparation.
    #[error("preparation, phase `{phase}`: {cause}")]
    Solver {
        /// The phase (`compact`, `settle`, `restore`).
        phase: &'static str,
        /// The solver's error.
        cause: fdem_solver::SolverError,
    },
    /// The solver stopped the compaction: usually the assembly jammed before the target
    /// height (overlaps grew past the contact's depth limit) or particles hit too fast.
    #[error(
        "compaction stopped at a platen gap of {:.5} m (target {} m, nominal solid \
         fraction {:.4} there): {cause}; if the assembly jammed before the \
         target, lower solid_fraction or preparation.friction (or raise contact.margin to \
         accept deeper overlaps); if particles hit too fast, lower preparation.platen_speed",
        Number(*.gap),
        Number(*.target),
        Number(*.solid_fraction)
    )]
    Compaction {
        /// Distance between the platens when it stopped (m).
        gap: f64,
        /// Target height (m).
        target: f64,
        /// Nominal solid fraction at that gap.
        solid_fraction: f64,
        /// The solver's error.
        cause: fdem_solver::SolverError,
    },
    /// The contact model refused the friction history of a specimen.
    #[error("restoring the contact history: {0}")]
    History(fdem_contact::ContactError),
    /// A specimen file that cannot be read as this version's format.
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong with it (truncated, bad checksum, other version...).
        message: String,
    },
    /// Reading or writing a file failed.
    #[error("{action} {path}: {cause}")]
    Io {
        /// What was being done.
        action: &'static str,
        /// The path.
        path: PathBuf,
        /// The underlying error.
        cause: std::io::Error,
    },
    /// The triaxial test could not be set up or stopped: a refused membrane, a step the
    /// membrane or contact bound does not allow, a particle that escaped, a consolidation
    /// that did not reach equilibrium in time, or a solver error during a phase.
    #[error("triaxial test, phase `{phase}`: {message}")]
    Test {
        /// The phase (`set-up`, `consolidation`, `shear`, `output`).
        phase: &'static str,
        /// What happened and how to fix it.
        message: String,
    },
    /// The preparation was interrupted by the caller (its observer asked to stop).
    #[error("preparation interrupted in phase `{phase}` at step {step}")]
    Interrupted {
        /// The phase.
        phase: &'static str,
        /// Steps taken so far.
        step: u64,
    },
}

fn location(line: usize, column: usize) -> String {
    match (line, column) {
        (0, _) => String::new(),
        (l, 0) => format!(":{l}"),
        (l, c) => format!(":{l}:{c}"),
    }
}

impl TriaxialError {
    pub(crate) fn io(
        action: &'static str,
        path: impl Into<PathBuf>,
        cause: std::io::Error,
    ) -> Self {
        TriaxialError::Io {
            action,
            path: path.into(),
            cause,
        }
    }

    pub(crate) fn file(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        TriaxialError::File {
            path: path.into(),
            message: message.into(),
        }
    }
}
