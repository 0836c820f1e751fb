//! Errors of the solver crate.

use std::path::PathBuf;

/// Everything that can stop scene loading, set-up or a run.
#[derive(Debug, thiserror::Error)]
pub enum SolverError {
    /// A scene file that does not parse or does not satisfy the schema.
    #[error("{file}:{line}:{column}: {key}: {message}")]
    Scene {
        /// The scene file (or `<string>` for scenes given as text).
        file: String,
        /// 1-based line of the offending key or value (0 when unknown).
        line: usize,
        /// 1-based column (0 when unknown).
        column: usize,
        /// Key path such as `particle[2].diameter` (`<document>` for syntax errors).
        key: String,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// A scene that parses but cannot be built (e.g. a degenerate rigid shape).
    #[error("invalid scene: {0}")]
    InvalidScene(String),
    /// Mesh construction failed.
    #[error(transparent)]
    Mesh(#[from] fdem_mesh::MeshError),
    /// Element set-up or evaluation failed (inverted element, bad material...).
    #[error("body {body}: {source}")]
    Elastic {
        /// Body whose elements failed.
        body: usize,
        /// The element error.
        source: fdem_elastic::ElasticError,
    },
    /// Contact detection or evaluation refused the step (tunnelling, too deep, bad input).
    #[error(transparent)]
    Contact(#[from] fdem_contact::ContactError),
    /// The explicit integration became unstable; the run was stopped before writing garbage.
    #[error(
        "unstable integration at step {step}, t = {time:.6e} s: {reason} (dt used {dt:.6e} s, \
         stable bound {bound:.6e} s set by {bound_source}); reduce dt or dt_safety"
    )]
    Unstable {
        /// Step number at which the guard tripped.
        step: u64,
        /// Simulated time.
        time: f64,
        /// The step size used.
        dt: f64,
        /// The computed stable bound.
        bound: f64,
        /// What sets the bound.
        bound_source: String,
        /// What the guard saw.
        reason: String,
    },
    /// Reading or writing a file failed.
    #[error("{action} {path}: {cause}")]
    Io {
        /// What was being done ("writing", "reading", "creating directory").
        action: &'static str,
        /// The path involved.
        path: PathBuf,
        /// The underlying error (in the message, not chained, so it is printed once).
        cause: std::io::Error,
    },
    /// The run was interrupted by the user; outputs up to the last output time are kept.
    #[error(
        "interrupted at t = {time:.6e} s (step {step}); outputs up to the last output time were kept"
    )]
    Interrupted {
        /// Simulated time reached.
        time: f64,
        /// Step reached.
        step: u64,
    },
}

impl SolverError {
    pub(crate) fn io(
        action: &'static str,
        path: impl Into<PathBuf>,
        cause: std::io::Error,
    ) -> Self {
        SolverError::Io {
            action,
            path: path.into(),
            cause,
        }
    }
}

impl From<crate::toml_input::InputError> for SolverError {
    fn from(e: crate::toml_input::InputError) -> Self {
        SolverError::Scene {
            file: e.file,
            line: e.line,
            column: e.column,
            key: e.key,
            message: e.message,
        }
    }
}
