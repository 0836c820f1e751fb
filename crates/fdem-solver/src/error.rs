//! Errors of the solver crate.

use std::path::PathBuf;

/// Everything that can stop scene loading, set-up or a run.
#[derive(Debug, thiserror::Error)]
pub enum SolverError {
    /// A scene file that does not parse or does not satisfy the schema: printed as
    /// `file:line:column: key: message`, or `file: key: message` for a rule across keys,
    /// which has no line (as [`crate::toml_input::InputError`]).
    #[error("{}", located(file, *line, *column, key, message))]
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

/// `file:line:column: key: message`, without the parts of the location that are unknown
/// (0): a rule across keys prints as `file: key: message`, not `file:0:0: ...`.
fn located(file: &str, line: usize, column: usize, key: &str, message: &str) -> String {
    crate::toml_input::InputError {
        file: file.to_string(),
        line,
        column,
        key: key.to_string(),
        message: message.to_string(),
    }
    .to_string()
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

#[cfg(test)]
mod tests {
    /// A rule across keys has no line: the scene's error prints without `:0:0`; a rule of
    /// one key keeps its line and column.
    #[test]
    fn a_scene_error_prints_only_the_location_it_knows() {
        let text = "[simulation]\nduration = 1e-6\noutput_interval = 1e-5\n\
            [material]\ndensity = 2650.0\nyoungs_modulus = 40.0e9\npoisson_ratio = 0.2\n\
            [[particle]]\ndiameter = 0.015\ncenter = [0.0, 0.0, 0.0]\n";
        let across = crate::Scene::from_toml_str(text, "s.toml").unwrap_err();
        assert!(
            across
                .to_string()
                .starts_with("s.toml: simulation.output_interval: "),
            "{across}"
        );
        let one = crate::Scene::from_toml_str(&text.replace("1e-6", "-1.0"), "s.toml")
            .unwrap_err()
            .to_string();
        assert!(
            one.starts_with("s.toml:2:12: simulation.duration: "),
            "{one}"
        );
    }
}
