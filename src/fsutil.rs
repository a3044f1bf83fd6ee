//! "Nothing is lost": every output is built under a temporary sibling name and renamed into
//! place only when complete, so an interrupted or failed run never leaves half an output and
//! never replaces a good one.
//!
//! Every temporary is also listed in a process-wide register while it exists, so that a
//! signal handler (the CLI installs one for SIGINT and SIGTERM) can remove them all with
//! [`remove_staged`] before the process exits.

use crate::{Error, Result};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

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
        let staging = temp_sibling(target, TEMPORARY)?;
        register(&staging);
        if let Err(e) = std::fs::create_dir_all(&staging) {
            unregister(&staging);
            return Err(Error::io(target, e));
        }
        hold_for_tests();
        Ok(StagedDir { staging, target: target.to_path_buf(), committed: false })
    }

    /// Where the files are written while the output is incomplete.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Moves the finished directory into place, replacing an old one only now.
    pub fn commit(mut self) -> Result<PathBuf> {
        // Holding the register keeps a signal handler from deleting the staging directory
        // between the two renames, which would lose both the old and the new output.
        let mut register = lock_register();
        let old = if self.target.exists() {
            let old = temp_sibling(&self.target, REPLACED)?;
            std::fs::rename(&self.target, &old).map_err(|e| Error::io(&self.target, e))?;
            register.push(old.clone());
            Some(old)
        } else {
            None
        };
        std::fs::rename(&self.staging, &self.target).map_err(|e| Error::io(&self.target, e))?;
        register.retain(|p| *p != self.staging);
        self.committed = true;
        drop(register);
        if let Some(old) = old {
            // The new output is in place; a leftover old copy is only wasted space.
            let _ = std::fs::remove_dir_all(&old);
            unregister(&old);
        }
        Ok(self.target.clone())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
            unregister(&self.staging);
        }
    }
}

/// Fails early, before any long work, if `target` could not be written: it exists and
/// `overwrite` is false, its parent directory is missing, or nothing can be created there
/// (a read-only file system, `/proc`, a directory without write permission).
pub fn check_target(target: &Path, overwrite: bool) -> Result<()> {
    if target.exists() && !overwrite {
        return Err(Error::invalid(format!(
            "{} already exists (pass --force to replace it)",
            target.display()
        )));
    }
    let probe = temp_sibling(target, PROBE)?;
    register(&probe);
    let created = std::fs::OpenOptions::new().write(true).create_new(true).open(&probe);
    if created.is_ok() {
        let _ = std::fs::remove_file(&probe);
    }
    unregister(&probe);
    match created {
        Ok(_) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(()),
        Err(e) => Err(Error::invalid(format!(
            "{}: cannot write in {}: {e}",
            target.display(),
            parent_of(target).display()
        ))),
    }
}

/// Writes a file atomically: the bytes go to a temporary sibling that is renamed over `path`.
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_with_temp(path, |tmp| std::fs::write(tmp, bytes).map_err(|e| Error::io(path, e)))
}

/// Runs `write` on a temporary sibling of `path`, then renames it into place. The temporary
/// is removed if `write` fails (or the process is interrupted, see [`remove_staged`]).
pub fn write_with_temp(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let tmp = temp_sibling(path, TEMPORARY)?;
    register(&tmp);
    let written = write(&tmp).map(|()| hold_for_tests());
    let result = written.and_then(|()| {
        let _register = lock_register();
        std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    unregister(&tmp);
    result
}

/// Removes every temporary output of this process that is still registered (staging
/// directories, temporary files, replaced outputs not yet deleted). Meant for a signal
/// handler that exits right after: it keeps the register locked, so no commit can start.
pub fn remove_staged() {
    let register = lock_register();
    for path in register.iter() {
        // Workers may still be creating files inside a staging directory. Renamed away
        // first, the directory takes no new files (their paths no longer resolve), so its
        // removal cannot lose a race with them however loaded the machine is; the
        // attempts cover files opened before the rename.
        let doomed = temp_sibling(path, REMOVED).ok().filter(|d| std::fs::rename(path, d).is_ok());
        let doomed = doomed.as_deref().unwrap_or(path);
        for _ in 0..200 {
            let removed =
                if doomed.is_dir() { std::fs::remove_dir_all(doomed) } else { std::fs::remove_file(doomed) };
            if removed.is_ok() || !doomed.exists() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
    }
    // Exiting with the register held keeps other threads from staging anything new.
    std::mem::forget(register);
}

/// `text` with this process's temporary names replaced by the outputs they stand for
/// (`dir/.frames.tmp-123/frame_0000.exr` → `dir/frames/frame_0000.exr`), so that messages
/// name what the user asked for.
pub fn without_temporary_names(text: &str) -> String {
    let pid = std::process::id();
    let mut out = text.to_string();
    for tag in [TEMPORARY, REPLACED, PROBE] {
        let marker = format!(".{tag}-{pid}");
        let mut rest = out.as_str();
        let mut cleaned = String::with_capacity(out.len());
        while let Some(at) = rest.find(&marker) {
            let head = &rest[..at];
            let start = head.rfind(['/', ' ', '\'', '"', '`']).map_or(0, |k| k + 1);
            cleaned.push_str(&head[..start]);
            cleaned.push_str(head[start..].strip_prefix('.').unwrap_or(&head[start..]));
            rest = &rest[at + marker.len()..];
        }
        cleaned.push_str(rest);
        out = cleaned;
    }
    out
}

/// `target` relative to the directory `base`, both absolute and resolved (as
/// `std::fs::canonicalize` gives them): `/a/b/analysis` from `/a/c` is `../b/analysis`.
pub fn relative_path(target: &Path, base: &Path) -> PathBuf {
    let (target, base): (Vec<_>, Vec<_>) = (target.components().collect(), base.components().collect());
    let common = target.iter().zip(&base).take_while(|(a, b)| a == b).count();
    let mut relative: PathBuf = std::iter::repeat_n("..", base.len() - common).collect();
    relative.extend(&target[common..]);
    if relative.as_os_str().is_empty() {
        relative.push(".");
    }
    relative
}

/// The tags of temporary names: being written, replaced by a commit, probing writability.
const TEMPORARY: &str = "tmp";
const REPLACED: &str = "old";
const REMOVED: &str = "removed";
const PROBE: &str = "probe";

/// `dir/.name.TAG-PID` (the extension is kept last so format detection still works).
fn temp_sibling(path: &Path, tag: &str) -> Result<PathBuf> {
    let name = path
        .file_name()
        .ok_or_else(|| Error::invalid(format!("{}: not a file or directory name", path.display())))?
        .to_string_lossy();
    let parent = parent_of(path);
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
    Ok(parent.join(format!(".{stem}.{tag}-{}{ext}", std::process::id())))
}

fn parent_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Temporaries that exist right now (see [`remove_staged`]).
static REGISTER: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn lock_register() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    REGISTER.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

fn register(path: &Path) {
    lock_register().push(path.to_path_buf());
}

fn unregister(path: &Path) {
    lock_register().retain(|p| p != path);
}

/// Tests of the interruption clean-up set this to keep each temporary on disk for that many
/// milliseconds once it exists, so that a signal reliably arrives while it does.
#[doc(hidden)]
pub const HOLD_STAGING_ENV: &str = "BTFSYNTH_TEST_HOLD_STAGING_MS";

fn hold_for_tests() {
    if let Some(ms) = std::env::var(HOLD_STAGING_ENV).ok().and_then(|v| v.parse::<u64>().ok()) {
        std::thread::sleep(std::time::Duration::from_millis(ms));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporary_names_are_replaced_by_their_outputs_in_messages() {
        let pid = std::process::id();
        let text = format!(
            "/a/.frames.tmp-{pid}/frame_0000.exr: disk full; '/b/.bunny.tmp-{pid}.ply' and .out.old-{pid}"
        );
        assert_eq!(
            without_temporary_names(&text),
            "/a/frames/frame_0000.exr: disk full; '/b/bunny.ply' and out"
        );
        let other = "/a/.frames.tmp-1/x and /keep/.hidden";
        assert_eq!(without_temporary_names(other), other, "other processes' names are left alone");
    }

    #[test]
    fn relative_paths_climb_to_the_common_ancestor() {
        let p = |s: &str| PathBuf::from(s);
        assert_eq!(relative_path(&p("/a/b/analysis"), &p("/a/c")), p("../b/analysis"));
        assert_eq!(relative_path(&p("/a/analysis"), &p("/a")), p("analysis"));
        assert_eq!(relative_path(&p("/a"), &p("/a")), p("."));
        assert_eq!(relative_path(&p("/x/y"), &p("/a/b")), p("../../x/y"));
    }

    #[test]
    fn an_unwritable_parent_is_refused_before_any_work() {
        let e = check_target(Path::new("/proc/btfsynth-out"), false).unwrap_err().to_string();
        assert!(e.starts_with("/proc/btfsynth-out: cannot write in /proc"), "{e}");
        assert!(!e.contains(".tmp-") && !e.contains(".probe-"), "{e}");
        let dir = tempfile::tempdir().expect("temp dir");
        check_target(&dir.path().join("out"), false).expect("a writable directory passes");
        assert!(std::fs::read_dir(dir.path()).expect("lists").next().is_none(), "the probe is removed");
    }

    #[test]
    fn staged_outputs_are_registered_until_committed_or_dropped() {
        let dir = tempfile::tempdir().expect("temp dir");
        let staged = StagedDir::new(&dir.path().join("out"), false).expect("stages");
        let staging = staged.path().to_path_buf();
        assert!(lock_register().contains(&staging));
        staged.commit().expect("commits");
        assert!(!lock_register().contains(&staging));
        let dropped = StagedDir::new(&dir.path().join("other"), false).expect("stages");
        let staging = dropped.path().to_path_buf();
        drop(dropped);
        assert!(!staging.exists() && !lock_register().contains(&staging));
    }

    #[test]
    fn a_commit_replaces_an_existing_output_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().expect("temp dir");
        let target = dir.path().join("out");
        std::fs::create_dir(&target).expect("creates");
        std::fs::write(target.join("old.txt"), b"old").expect("writes");
        let staged = StagedDir::new(&target, true).expect("stages");
        std::fs::write(staged.path().join("new.txt"), b"new").expect("writes");
        staged.commit().expect("commits");
        assert!(target.join("new.txt").is_file() && !target.join("old.txt").exists());
        let names: Vec<_> =
            std::fs::read_dir(dir.path()).expect("lists").map(|e| e.expect("entry").file_name()).collect();
        assert_eq!(names, ["out"]);
    }
}
