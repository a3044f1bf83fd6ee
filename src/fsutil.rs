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
    staged: Staged,
}

impl StagedDir {
    /// Prepares to write `target`. Fails if `target` exists and `overwrite` is false, if it
    /// is a device or FIFO (a directory cannot replace one), or if the parent directory
    /// cannot be written.
    pub fn new(target: &Path, overwrite: bool) -> Result<Self> {
        let staged = Staged::dir(target, overwrite)?;
        std::fs::create_dir_all(staged.path()).map_err(|e| Error::io(target, e))?;
        hold_for_tests();
        Ok(StagedDir { staged })
    }

    /// Where the files are written while the output is incomplete.
    pub fn path(&self) -> &Path {
        self.staged.path()
    }

    /// Moves the finished directory into place, replacing an old one only now.
    pub fn commit(self) -> Result<PathBuf> {
        self.staged.commit()
    }
}

/// An output (a file or a directory) reserved under a temporary sibling name: whoever
/// writes it creates [`Staged::path`] (a library writer may stage its own temporaries
/// inside or beside it), and [`Staged::commit`] (or [`commit_all`], for outputs that must
/// appear together) moves it to its final name as the last step. Dropped uncommitted,
/// whatever exists at the temporary name is deleted; an interrupted process deletes it too
/// (see [`remove_staged`]).
pub struct Staged {
    staging: PathBuf,
    target: PathBuf,
    committed: bool,
}

impl Staged {
    /// Reserves a temporary name for the file `target` (see [`check_file_target`]).
    pub fn file(target: &Path, overwrite: bool) -> Result<Self> {
        check_file_target(target, overwrite)?;
        Self::reserve(target)
    }

    /// Reserves a temporary name for the directory `target` (see [`check_dir_target`]).
    pub fn dir(target: &Path, overwrite: bool) -> Result<Self> {
        check_dir_target(target, overwrite)?;
        Self::reserve(target)
    }

    fn reserve(target: &Path) -> Result<Self> {
        let staging = temp_sibling(target, TEMPORARY)?;
        register(&staging);
        Ok(Staged { staging, target: target.to_path_buf(), committed: false })
    }

    /// The temporary name, which does not exist until the caller creates it.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// The final name.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Moves the finished output into place (replacing an old one only now), or copies a
    /// file output into the device or FIFO it names.
    pub fn commit(self) -> Result<PathBuf> {
        Ok(commit_all(vec![self])?.remove(0))
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.committed {
            remove_any(&self.staging);
            unregister(&self.staging);
        }
    }
}

/// Commits every one of `outputs` as one step: a signal handler waits until all are in
/// place (or, if one fails, until the rest are discarded). Outputs before a failed one stay
/// committed. A device or FIFO among them is written first, without that wait: opening a
/// FIFO blocks until something reads it, and a signal must still end the run meanwhile.
pub fn commit_all(mut outputs: Vec<Staged>) -> Result<Vec<PathBuf>> {
    let mut done = vec![PathBuf::new(); outputs.len()];
    let mut top_level = false;
    let specials: Vec<usize> =
        (0..outputs.len()).filter(|&i| special_kind(&outputs[i].target).is_some()).collect();
    for &i in &specials {
        copy_into_special(&outputs[i])?;
        let mut register = lock_register();
        top_level |= mark_committed(&mut outputs[i], &mut register);
        done[i] = outputs[i].target.clone();
    }
    // Holding the register keeps a signal handler from deleting a staged output between
    // the two renames of a replacement, which would lose both the old and the new output.
    let mut register = lock_register();
    for (i, staged) in outputs.iter_mut().enumerate().filter(|(i, _)| !specials.contains(i)) {
        commit_locked(staged, &mut register)?;
        top_level |= mark_committed(staged, &mut register);
        done[i] = staged.target.clone();
    }
    drop(register);
    if top_level {
        hold_committed_for_tests();
    }
    Ok(done)
}

/// Marks `staged` committed, and records it for messages if it is an output rather than a
/// file inside a staged one (then true).
fn mark_committed(staged: &mut Staged, register: &mut Vec<PathBuf>) -> bool {
    register.retain(|p| *p != staged.staging);
    staged.committed = true;
    let top_level = !register.iter().any(|s| staged.target.starts_with(s));
    if top_level {
        lock_committed().push(staged.target.clone());
    }
    top_level
}

/// Copies a finished file output into the device or FIFO it names (never replaced), then
/// removes the temporary. Blocks until a FIFO has a reader, so never with the register
/// held: a signal handler removes the temporary meanwhile (an open file reads on).
fn copy_into_special(staged: &Staged) -> Result<()> {
    let target = &staged.target;
    let copied = std::fs::File::open(&staged.staging).and_then(|mut from| {
        let mut into = std::fs::OpenOptions::new().write(true).open(target)?;
        std::io::copy(&mut from, &mut into)?;
        std::io::Write::flush(&mut into)
    });
    if let Err(e) = copied {
        let special = special_kind(target).map_or("special file", Special::name);
        return Err(Error::output_refused(
            target,
            format!("{}: cannot write into this {special}: {e}", target.display()),
        ));
    }
    remove_any(&staged.staging);
    Ok(())
}

fn commit_locked(staged: &mut Staged, register: &mut Vec<PathBuf>) -> Result<()> {
    let target = staged.target.clone();
    let staging_is_dir = std::fs::symlink_metadata(&staged.staging).is_ok_and(|m| m.is_dir());
    let existing = std::fs::symlink_metadata(&target).ok();
    if existing.as_ref().is_some_and(|m| m.is_dir()) && !staging_is_dir {
        return Err(Error::output_refused(
            &target,
            format!("{} is a directory; this output is a file, which never replaces one", target.display()),
        ));
    }
    // A file replaces a file (or a link) in one atomic rename; anything else moves the
    // old output aside first.
    let old = if existing.is_some() && staging_is_dir {
        let old = temp_sibling(&target, REPLACED)?;
        std::fs::rename(&target, &old).map_err(|e| Error::io(&target, e))?;
        register.push(old.clone());
        Some(old)
    } else {
        None
    };
    if let Err(e) = std::fs::rename(&staged.staging, &target) {
        // Put the old output back: nothing is lost by a failed commit.
        if let Some(old) = &old {
            if std::fs::rename(old, &target).is_ok() {
                register.retain(|p| p != old);
            }
        }
        return Err(Error::io(&target, e));
    }
    if let Some(old) = old {
        // The new output is in place; a leftover old copy is only wasted space.
        remove_any(&old);
        register.retain(|p| *p != old);
    }
    Ok(())
}

/// Removes a file, a link or a whole directory; nothing if `path` does not exist.
fn remove_any(path: &Path) {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.is_dir() => {
            let _ = std::fs::remove_dir_all(path);
        }
        Ok(_) => {
            let _ = std::fs::remove_file(path);
        }
        Err(_) => {}
    }
}

/// A special file an output may name: written into, never renamed over.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Special {
    /// A character device (`/dev/null`, a terminal).
    Device,
    /// A FIFO (a named pipe, or a shell's `>(…)`).
    Fifo,
}

impl Special {
    fn name(self) -> &'static str {
        match self {
            Special::Device => "device",
            Special::Fifo => "FIFO",
        }
    }
}

/// The special file at `path` (through links), when it names a character device or a FIFO:
/// outputs are written into those, never renamed over.
fn special_kind(path: &Path) -> Option<Special> {
    use std::os::unix::fs::FileTypeExt;
    let kind = std::fs::metadata(path).ok()?.file_type();
    if kind.is_char_device() {
        Some(Special::Device)
    } else if kind.is_fifo() {
        Some(Special::Fifo)
    } else {
        None
    }
}

/// Why nothing can be written at `path` even when overwriting is allowed: a block device or a
/// socket (a disk must never be overwritten by an output).
fn unwritable_kind(path: &Path) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    let kind = std::fs::metadata(path).ok()?.file_type();
    if kind.is_block_device() {
        Some("block device")
    } else if kind.is_socket() {
        Some("socket")
    } else {
        None
    }
}

/// Fails early, before any long work, if `target` could not be written: it exists and
/// `overwrite` is false, its parent directory is missing, or nothing can be created there
/// (a read-only file system, `/proc`, a directory without write permission). A character
/// device passes with `overwrite` and a FIFO always (an output is written into either: a
/// FIFO is a stream someone waits to read, a device exists like any file); a block device
/// or socket never does.
pub fn check_target(target: &Path, overwrite: bool) -> Result<()> {
    if let Some(kind) = unwritable_kind(target) {
        return Err(Error::output_refused(
            target,
            format!("{} is a {kind}; btfsynth writes no output there", target.display()),
        ));
    }
    match special_kind(target) {
        Some(Special::Fifo) => return Ok(()),
        Some(Special::Device) if overwrite => return Ok(()),
        _ => {}
    }
    if std::fs::symlink_metadata(target).is_ok() && !overwrite {
        return Err(Error::OutputExists(target.to_path_buf()));
    }
    probe_parent(target)
}

/// [`check_target`] for an output that is one file: a directory in its place is refused
/// (even with `overwrite`), a device or FIFO is written into.
pub fn check_file_target(target: &Path, overwrite: bool) -> Result<()> {
    if std::fs::metadata(target).is_ok_and(|m| m.is_dir()) {
        return Err(Error::output_refused(
            target,
            format!("{} is a directory; this output is a file (name a file instead)", target.display()),
        ));
    }
    check_target(target, overwrite)
}

/// [`check_target`] for an output that is a directory: a device or FIFO in its place is
/// refused (a directory cannot be written into one, and it is never replaced).
pub fn check_dir_target(target: &Path, overwrite: bool) -> Result<()> {
    if let Some(kind) = special_kind(target) {
        return Err(Error::output_refused(
            target,
            format!(
                "{} is a {}; this output is a directory, which cannot replace it",
                target.display(),
                kind.name()
            ),
        ));
    }
    check_target(target, overwrite)
}

fn probe_parent(target: &Path) -> Result<()> {
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
        Err(e) => Err(Error::output_refused(
            target,
            format!("{}: cannot write in {}: {e}", target.display(), parent_of(target).display()),
        )),
    }
}

/// Refuses an output that is one of `inputs`, holds one (replacing it would delete the
/// input) or lies inside one (writing it would change the input). Paths are compared
/// resolved, so `./a`, `a/` and a link to `a` are all `a`. `what` names the output in the
/// message (the front end's name for it: the output, the report).
pub fn check_not_input(what: &str, output: &Path, inputs: &[&Path]) -> Result<()> {
    for input in inputs {
        if let Some(why) = overlap(output, input) {
            return Err(Error::output_refused(
                output,
                format!(
                    "{what} {} {why} the input {}; inputs are never replaced: choose another output",
                    output.display(),
                    input.display()
                ),
            ));
        }
    }
    Ok(())
}

/// Refuses a second output (`what`, e.g. a report) that is, holds or lies inside the
/// first: one would overwrite the other.
pub fn check_apart(what: &str, second: &Path, first: &Path) -> Result<()> {
    match overlap(second, first) {
        Some(why) => Err(Error::output_refused(
            second,
            format!(
                "{what} {} {why} the output {}; give each output its own name",
                second.display(),
                first.display()
            ),
        )),
        None => Ok(()),
    }
}

/// Refuses a directory a run keeps files of its own in (`what` names it, e.g. a cache) that
/// is or lies inside one of `inputs` (its files would change them) or `outputs` (one would
/// replace the other). Holding them is no harm: its files have names of their own.
pub fn check_workspace(what: &str, dir: &Path, inputs: &[&Path], outputs: &[&Path]) -> Result<()> {
    for (others, kind) in [(inputs, "input"), (outputs, "output")] {
        for other in others {
            if let Some(why @ ("is" | "lies inside")) = overlap(dir, other) {
                return Err(Error::output_refused(
                    dir,
                    format!(
                        "{what} {} {why} the {kind} {}; give it a directory of its own",
                        dir.display(),
                        other.display()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// How `a` overlaps `b`: it "is" `b`, "holds" it or "lies inside" it (None: apart, or
/// unresolvable).
fn overlap(a: &Path, b: &Path) -> Option<&'static str> {
    let (a, b) = (resolved(a)?, resolved(b)?);
    if a == b {
        Some("is")
    } else if b.starts_with(&a) {
        Some("holds")
    } else if a.starts_with(&b) {
        Some("lies inside")
    } else {
        None
    }
}

/// `path` absolute with its links resolved; for a path that does not exist yet, its parent
/// resolved and its name appended. None if not even the parent can be resolved.
fn resolved(path: &Path) -> Option<PathBuf> {
    if let Ok(p) = std::fs::canonicalize(path) {
        return Some(p);
    }
    let name = path.file_name()?;
    let parent = std::fs::canonicalize(parent_of(path)).ok()?;
    Some(parent.join(name))
}

/// Writes a file atomically: the bytes go to a temporary sibling that is renamed over `path`
/// (or copied into it, if `path` is a device or FIFO).
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_with_temp(path, |tmp| std::fs::write(tmp, bytes).map_err(|e| Error::io(path, e)))
}

/// Runs `write` on a temporary sibling of `path`, then renames it into place (or copies it
/// into `path` if that is a device or FIFO: special files are never replaced). The temporary
/// is removed if `write` fails (or the process is interrupted, see [`remove_staged`]).
pub fn write_with_temp(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    if let Some(kind) = unwritable_kind(path) {
        return Err(Error::output_refused(
            path,
            format!("{} is a {kind}; btfsynth writes no output there", path.display()),
        ));
    }
    let staged = Staged::reserve(path)?;
    write(staged.path())?;
    hold_for_tests();
    staged.commit().map(|_| ())
}

/// Writes a file the program keeps for itself (a cache entry) atomically: under a temporary
/// name, renamed over whatever is in its place but a directory. Unlike an output, a device,
/// FIFO or link there is replaced, never written into or through, and the file is not one of
/// the run's outputs (an interrupted run's message names only those).
pub fn store_file(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut staged = Staged::reserve(path)?;
    std::fs::write(staged.path(), bytes).map_err(|e| Error::io(path, e))?;
    let mut register = lock_register();
    let renamed = std::fs::rename(&staged.staging, path);
    if renamed.is_ok() {
        register.retain(|p| *p != staged.staging);
        staged.committed = true;
    }
    // Unlocked before `staged` is dropped: its clean-up takes the register.
    drop(register);
    renamed.map_err(|e| Error::io(path, e))
}

/// Reads a whole input file. A device is refused (`/dev/zero` would never end), and a pipe
/// or socket is read up to [`MAX_STREAM_BYTES`].
pub fn read_input(path: &Path) -> Result<Vec<u8>> {
    use std::io::Read;
    use std::os::unix::fs::FileTypeExt;
    let kind = std::fs::metadata(path).map_err(|e| Error::io(path, e))?.file_type();
    if kind.is_char_device() || kind.is_block_device() {
        return Err(Error::format(path, "a device, not a file"));
    }
    if !(kind.is_fifo() || kind.is_socket()) {
        return std::fs::read(path).map_err(|e| Error::io(path, e));
    }
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut bytes = Vec::new();
    file.take(MAX_STREAM_BYTES + 1).read_to_end(&mut bytes).map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > MAX_STREAM_BYTES {
        return Err(Error::format(
            path,
            format!("a pipe that gives more than {} MiB; read from a file instead", MAX_STREAM_BYTES >> 20),
        ));
    }
    Ok(bytes)
}

/// [`read_input`] as UTF-8 text.
pub fn read_input_text(path: &Path) -> Result<String> {
    String::from_utf8(read_input(path)?).map_err(|_| Error::format(path, "not UTF-8 text"))
}

/// The most bytes read from a pipe or socket given as an input file.
pub const MAX_STREAM_BYTES: u64 = 1 << 30;

/// Removes every temporary output of this process that is still registered (staging
/// directories, temporary files, replaced outputs not yet deleted), and returns the outputs
/// that were already committed (so a message can say what is left). Meant for a signal
/// handler that exits right after: it waits for a commit under way, and keeps the register
/// locked, so no commit can start.
pub fn remove_staged() -> Vec<PathBuf> {
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
            if removed.is_ok() || std::fs::symlink_metadata(doomed).is_err() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
    }
    let committed = lock_committed().clone();
    // Exiting with the register held keeps other threads from staging anything new.
    std::mem::forget(register);
    committed
}

/// `text` with this process's temporary names replaced by the outputs they stand for
/// (`dir/.frames.tmp-123/frame_0000.exr` → `dir/frames/frame_0000.exr`, and a temporary of
/// a temporary, `..a.tmp-123.tmp-123.ply`, → `a.ply`), so that messages name what the user
/// asked for.
pub fn without_temporary_names(text: &str) -> String {
    let pid = std::process::id();
    let mut out = text.to_string();
    // Names cut short first, the latest (a temporary of a temporary) first.
    for (temporary, name) in lock_aliases().iter().rev() {
        out = out.replace(temporary, name);
    }
    for tag in [TEMPORARY, REPLACED, PROBE] {
        let marker = format!(".{tag}-{pid}");
        // Each pass removes one marker and the dot it added, so nested names unwind.
        while let Some(at) = out.find(&marker) {
            let head = &out[..at];
            let start = head.rfind(['/', ' ', '\'', '"', '`']).map_or(0, |k| k + 1);
            let name = &head[start..];
            let name = name.strip_prefix('.').unwrap_or(name);
            out = format!("{}{name}{}", &head[..start], &out[at + marker.len()..]);
        }
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

/// The longest file name most file systems take, in bytes (ext4, XFS, btrfs, tmpfs).
const NAME_MAX: usize = 255;

/// `dir/.name.TAG-PID` (the extension is kept last so format detection still works). A name
/// too long for that is cut short, so that every legal name can be written (its full form
/// is remembered for messages, see [`without_temporary_names`]).
fn temp_sibling(path: &Path, tag: &str) -> Result<PathBuf> {
    use std::os::unix::ffi::OsStrExt;
    let name = path
        .file_name()
        .ok_or_else(|| {
            Error::output_refused(path, format!("{}: not a file or directory name", path.display()))
        })?
        .as_bytes();
    let parent = parent_of(path);
    if !parent.is_dir() {
        return Err(Error::output_refused(
            path,
            format!("{}: the directory {} does not exist", path.display(), parent.display()),
        ));
    }
    let suffix = format!(".{tag}-{}", std::process::id());
    // An extension longer than this is no format's: it may be cut with the rest.
    let (stem, ext) = match name.iter().rposition(|&b| b == b'.') {
        Some(dot) if dot > 0 && name.len() - dot <= 16 => name.split_at(dot),
        _ => (name, &b""[..]),
    };
    let room = NAME_MAX - 1 - suffix.len() - ext.len();
    let temporary = [b".", &stem[..stem.len().min(room)], suffix.as_bytes(), ext].concat();
    let temporary = std::ffi::OsStr::from_bytes(&temporary);
    if stem.len() > room {
        let alias = (temporary.to_string_lossy().into_owned(), String::from_utf8_lossy(name).into_owned());
        let mut aliases = lock_aliases();
        if !aliases.contains(&alias) {
            aliases.push(alias);
        }
    }
    Ok(parent.join(temporary))
}

/// Temporary names cut short, with the names they stand for (see [`temp_sibling`]).
static ALIASES: Mutex<Vec<(String, String)>> = Mutex::new(Vec::new());

fn lock_aliases() -> std::sync::MutexGuard<'static, Vec<(String, String)>> {
    ALIASES.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
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

/// Outputs this process has committed (top-level ones, not files inside a staged directory).
static COMMITTED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn lock_committed() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    COMMITTED.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Tests of the interruption clean-up set this to keep each temporary on disk for that many
/// milliseconds once it exists, so that a signal reliably arrives while it does.
#[doc(hidden)]
pub const HOLD_STAGING_ENV: &str = "BTFSYNTH_TEST_HOLD_STAGING_MS";

fn hold_for_tests() {
    hold(HOLD_STAGING_ENV);
}

/// Tests of interruptions after a commit set this to pause that many milliseconds after
/// each output is committed, so that a signal reliably arrives then.
#[doc(hidden)]
pub const HOLD_COMMITTED_ENV: &str = "BTFSYNTH_TEST_HOLD_COMMITTED_MS";

fn hold_committed_for_tests() {
    hold(HOLD_COMMITTED_ENV);
}

fn hold(variable: &str) {
    if let Some(ms) = std::env::var(variable).ok().and_then(|v| v.parse::<u64>().ok()) {
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

    /// A name of 255 bytes (the most a file system takes) gets a temporary cut to fit, and
    /// messages still name the output.
    #[test]
    fn the_longest_legal_names_get_a_temporary_that_fits() {
        let dir = tempfile::tempdir().expect("temp dir");
        let names = ["a".repeat(255), format!("{}.ply", "b".repeat(251)), format!("c.{}", "x".repeat(253))];
        for name in &names {
            let target = dir.path().join(name);
            let temporary = temp_sibling(&target, TEMPORARY).expect("a temporary name");
            assert!(temporary.file_name().expect("a name").len() <= NAME_MAX, "{}", temporary.display());
            assert_eq!(
                without_temporary_names(&temporary.display().to_string()),
                target.display().to_string()
            );
            write_file_atomic(&target, b"x").expect("writes");
            assert_eq!(std::fs::read(&target).expect("reads"), b"x");
        }
        assert_eq!(
            std::fs::read_dir(dir.path()).expect("lists").count(),
            names.len(),
            "no temporary is left"
        );
    }

    /// An existing device is an existing output: written into only with `overwrite`. A FIFO
    /// is a stream someone waits to read, written into either way.
    #[test]
    fn a_device_needs_overwrite_and_a_fifo_does_not() {
        let e = check_target(Path::new("/dev/null"), false).unwrap_err();
        assert!(matches!(e, Error::OutputExists(_)), "{e}");
        check_target(Path::new("/dev/null"), true).expect("written into with overwrite");
        let dir = tempfile::tempdir().expect("temp dir");
        let fifo = dir.path().join("f");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().expect("mkfifo").success());
        check_target(&fifo, false).expect("a FIFO is written into");
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
