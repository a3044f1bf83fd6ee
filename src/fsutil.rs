//! "Nothing is lost": every output is built under a temporary sibling name and renamed into
//! place only when complete, so an interrupted or failed run never leaves half an output and
//! never replaces a good one.

use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// An output directory under construction. Files go into [`StagedDir::path`]; [`StagedDir::commit`]
/// moves the directory to its final name. Dropping it uncommitted deletes the temporary.
pub struct StagedDir {
    staging: PathBuf,
    target: PathBuf,
    committed: bool,
}

impl StagedDir {
    /// Prepares to write `target`. Fails if `target` exists and `overwrite` is false, or if
    /// the parent directory cannot be written.
    pub fn new(target: &Path, overwrite: bool) -> Result<Self> {
        check_target(target, overwrite)?;
        let staging = temp_sibling(target)?;
        std::fs::create_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        Ok(StagedDir { staging, target: target.to_path_buf(), committed: false })
    }

    /// Where the files are written while the output is incomplete.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Moves the finished directory into place, replacing an old one only now.
    pub fn commit(mut self) -> Result<PathBuf> {
        if self.target.exists() {
            let old = temp_sibling(&self.target)?.with_extension("old");
            std::fs::rename(&self.target, &old).map_err(|e| Error::io(&self.target, e))?;
            std::fs::rename(&self.staging, &self.target).map_err(|e| Error::io(&self.target, e))?;
            // The new output is in place; a leftover old copy is only wasted space.
            let _ = std::fs::remove_dir_all(&old);
        } else {
            std::fs::rename(&self.staging, &self.target).map_err(|e| Error::io(&self.target, e))?;
        }
        self.committed = true;
        Ok(self.target.clone())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

/// Fails early, before any long work, if `target` could not be written: it exists and
/// `overwrite` is false, or its parent directory is missing.
pub fn check_target(target: &Path, overwrite: bool) -> Result<()> {
    if target.exists() && !overwrite {
        return Err(Error::invalid(format!(
            "{} already exists (pass --force to replace it)",
            target.display()
        )));
    }
    temp_sibling(target).map(|_| ())
}

/// Writes a file atomically: the bytes go to a temporary sibling that is renamed over `path`.
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_with_temp(path, |tmp| std::fs::write(tmp, bytes).map_err(|e| Error::io(path, e)))
}

/// Runs `write` on a temporary sibling of `path`, then renames it into place. The temporary
/// is removed if `write` fails.
pub fn write_with_temp(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let tmp = temp_sibling(path)?;
    match write(&tmp).and_then(|_| std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))) {
        Ok(()) => Ok(()),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// `dir/.name.tmp-PID` (the extension is kept last so format detection still works).
fn temp_sibling(path: &Path) -> Result<PathBuf> {
    let name = path
        .file_name()
        .ok_or_else(|| Error::invalid(format!("{}: not a file or directory name", path.display())))?
        .to_string_lossy();
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !parent.is_dir() {
        return Err(Error::invalid(format!(
            "{}: the directory {} does not exist",
            path.display(),
            parent.display()
        )));
    }
    let (stem, ext) = match name.rsplit_once('.') {
        Some((s, e)) if !s.is_empty() => (s.to_string(), format!(".{e}")),
        _ => (name.to_string(), String::new()),
    };
    Ok(parent.join(format!(".{stem}.tmp-{}{ext}", std::process::id())))
}
