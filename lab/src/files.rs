//! Writing a command's outputs: each file whole or not at all (a temporary
//! file and a rename), a run's files all or none, and their names checked
//! before the work.

use std::path::{Path, PathBuf};

use crate::error::LabError;

/// Writes `bytes` to `path` through a temporary file and a rename, so that a
/// failure never leaves a partial file behind.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), LabError> {
    let tmp = path.with_extension("partial");
    std::fs::write(&tmp, bytes).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        LabError(format!("{}: {e}", tmp.display()))
    })?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        LabError(format!("{}: {e}", path.display()))
    })
}

/// Checks that `p` can be written: its folder exists and it is not one.
pub fn check_writable(p: &Path) -> Result<(), LabError> {
    let dir = p.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.is_dir() {
        return Err(LabError(format!("{}: folder {} does not exist", p.display(), dir.display())));
    }
    if p.is_dir() {
        return Err(LabError(format!("{}: is a folder, not a file name", p.display())));
    }
    Ok(())
}

/// Writes every output, each atomically; if one fails, the ones already
/// written are removed again, so a run leaves all of its files or none.
pub fn write_all(outputs: &[(PathBuf, Vec<u8>)]) -> Result<(), LabError> {
    for (k, (p, bytes)) in outputs.iter().enumerate() {
        if let Err(e) = write_atomically(p, bytes) {
            for (q, _) in &outputs[..k] {
                let _ = std::fs::remove_file(q);
            }
            return Err(e);
        }
    }
    Ok(())
}

/// `OUT.png` → `OUT-error.png` (`OUT.svg` → `OUT-error.svg`).
pub fn error_plot_path(p: &Path) -> PathBuf {
    let stem = p.file_stem().and_then(|s| s.to_str()).unwrap_or("simulate");
    let ext = if crate::figure::Format::of(p) == crate::figure::Format::Svg { "svg" } else { "png" };
    p.with_file_name(format!("{stem}-error.{ext}"))
}
