//! Typed errors of the credence commands; each names the file (and line and
//! field) it is about.

use std::fmt;
use std::path::{Path, PathBuf};

/// What went wrong in `synth` or `train`.
#[derive(Debug)]
pub enum CredenceError {
    /// A file could not be read or written.
    Io {
        /// The file.
        path: PathBuf,
        /// The system's reason.
        source: std::io::Error,
    },
    /// A data file is malformed.
    Csv {
        /// The file.
        path: PathBuf,
        /// Line, from 1.
        line: usize,
        /// The column, when one field is at fault.
        field: Option<&'static str>,
        /// What is wrong with it.
        message: String,
    },
    /// The command's arguments do not make sense together.
    Usage(String),
    /// A trained weight does not fit the firmware's Q16.16.
    Quantise(String),
}

impl CredenceError {
    /// An I/O error about `path`.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io { path: path.to_path_buf(), source }
    }
}

impl fmt::Display for CredenceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Io { path, source } => write!(f, "{}: {source}", path.display()),
            Self::Csv { path, line, field: Some(field), message } => {
                write!(f, "{}:{line}: field `{field}`: {message}", path.display())
            }
            Self::Csv { path, line, field: None, message } => write!(f, "{}:{line}: {message}", path.display()),
            Self::Usage(m) | Self::Quantise(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for CredenceError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}
