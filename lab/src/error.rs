//! The lab's error: a message that names the file (and, where known, the
//! place in it). Every command returns it; the modules' own typed errors
//! (`ImportError`, `LogError`, `BagError`, `LidarError`, …) convert into it.

use std::fmt;

/// An error that names the file (and, where known, the place in it).
#[derive(Debug)]
pub struct LabError(pub String);

impl fmt::Display for LabError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for LabError {}
