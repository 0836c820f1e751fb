//! The study's one error type.

use std::path::{Path, PathBuf};

/// What can go wrong in a study.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// A series, option or run definition that cannot be used, with the fix.
    #[error("{0}")]
    Definition(String),
    /// A specimen, preparation or test error of one run.
    #[error(transparent)]
    Triaxial(#[from] fdem_triaxial::TriaxialError),
    /// The micro-analysis of a run's peak snapshot.
    #[error(transparent)]
    Micro(#[from] fdem_micro::MicroError),
    /// A file that cannot be read or written.
    #[error("{action} {}: {cause}", path.display())]
    Io {
        /// What was being done.
        action: &'static str,
        /// The file.
        path: PathBuf,
        /// The cause.
        cause: std::io::Error,
    },
    /// A file with unexpected content (a run record, a curve), named with the problem.
    #[error("{}: {message}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The study was interrupted; finished runs are kept and reused by the next call.
    #[error("interrupted during {run}; finished runs are kept and the next call resumes")]
    Interrupted {
        /// The run that was going on.
        run: String,
    },
}

impl StudyError {
    /// An I/O error on `path`.
    pub fn io(action: &'static str, path: &Path, cause: std::io::Error) -> StudyError {
        StudyError::Io {
            action,
            path: path.to_path_buf(),
            cause,
        }
    }

    /// A file whose content is wrong.
    pub fn file(path: &Path, message: impl Into<String>) -> StudyError {
        StudyError::File {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}
