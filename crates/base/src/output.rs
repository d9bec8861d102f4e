//! Output: every file the tool writes goes through here, written atomically (a temporary file in
//! the target's directory, flushed, then renamed over the target), so a crash or a full disk never
//! leaves a half-written image, solution or report where a user or a CI pipeline would read it.
//!
//! Before a job does any work, [`check_outputs`] refuses (exit 2) every output path that is, or
//! resolves to, one of the job's input files (through `..`, symbolic links in its directories or
//! a hard link), that another output of the same run also names, or that exists and is not a
//! regular file (a directory, a symbolic link, a device node, a FIFO): replacing those would lose
//! data the user did not ask to lose. A job with several outputs for one result (a render's PNG,
//! EXR and statistics) writes them through a [`Batch`]: every file is written and flushed to its
//! temporary first, then all are renamed, so an error while encoding or writing any of them
//! leaves every target as it was; only a kill between two renames (microseconds) can leave some
//! replaced and some not. Temporaries of a failed batch are removed.
//!
//! Temporaries are named `.pfs-<pid>-<random>.tmp` (short, so any legal target name has one;
//! unpredictable, the random part from the standard library's per-process random hash keys) and
//! created exclusively (`O_CREAT | O_EXCL`): a file or symbolic link planted at the name makes
//! the creation fail and another name is drawn, so a write never follows a link or truncates a
//! file it did not create. A replaced target keeps its permission bits. The first write into a
//! directory removes the temporaries there whose process has died (a run killed by SIGKILL or a
//! power cut), recognised by name and by `/proc/<pid>` being gone.
//!
//! Every write goes through an [`Outputs`] value, the registry of the temporaries that exist
//! ([`Outputs::remove_temporaries`] deletes them): the caller owns it and hands a clone to
//! whatever must clean up (the binary's SIGINT/SIGTERM handler, before exiting), so an
//! interrupted run leaves no hidden temporary behind, and nothing here is process-wide state. A
//! batch's renames run under a lock the handler also takes, so a signal during a commit waits for
//! the renames to finish: a run's outputs are replaced all together or not at all (only SIGKILL
//! or a power cut, which no handler sees, can split them).
//!
//! The other direction lives here too: every input file (scene, OBJ, MTL, solution, image) is
//! read through [`read_limited`] at a cap its caller passes, so a path to an endless file
//! (`/dev/zero`, a FIFO that never closes) ends in an error at [`MAX_INPUT_BYTES`], or at the
//! smaller cap a job's memory limit gives ([`input_limit_for`]), instead of growing memory until
//! the allocator aborts.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

use crate::error::{Error, Result};

/// Largest input file read: 1 GiB, 300x the largest shipped file (gallery-fine's solution),
/// and what this machine reads in about a second.
pub const MAX_INPUT_BYTES: u64 = 1 << 30;

/// The input cap for a job that may hold `bytes` of data: an input file is held at least once
/// as bytes and once parsed, so half of it, at most [`MAX_INPUT_BYTES`] and at least 1 MiB (so
/// that a tiny limit still reads a scene file and refuses the job by its estimate). The cap
/// travels with the job (a scene's load options, a solution or image read), never as
/// process-wide state.
pub fn input_limit_for(bytes: u64) -> u64 {
    (bytes / 2).clamp(1 << 20, MAX_INPUT_BYTES)
}

/// Reads the whole file at `path`, failing with [`std::io::ErrorKind::FileTooLarge`] once it
/// holds more than `max` bytes (nothing beyond `max + 1` bytes is read or kept).
pub fn read_limited(path: &Path, max: u64) -> std::io::Result<Vec<u8>> {
    let f = std::fs::File::open(path)?;
    let mut out = Vec::new();
    f.take(max.saturating_add(1)).read_to_end(&mut out)?;
    if out.len() as u64 > max {
        return Err(std::io::Error::new(
            std::io::ErrorKind::FileTooLarge,
            format!(
                "larger than {max} bytes, the largest input read (1 GiB at most, and half of \
                 the memory limit less the program's own memory)"
            ),
        ));
    }
    Ok(out)
}

/// [`read_limited`] at `max` bytes, as UTF-8 text, without a leading byte-order mark (editors
/// on Windows write one; left in, it would make the first line of an OBJ, MTL or scene file
/// unrecognizable).
pub fn read_text(path: &Path, max: u64) -> std::io::Result<String> {
    let mut text = String::from_utf8(read_limited(path, max)?)
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidData, "not UTF-8 text"))?;
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

/// The folder that paths written inside the file at `path` are relative to: the folder of the
/// file a symbolic link at `path` leads to (a scene linked from elsewhere finds its OBJ files
/// beside the scene, not beside the link), else `path`'s own folder (also when the link cannot
/// be followed, so that reading it reports the problem).
pub fn folder_of(path: &Path) -> PathBuf {
    let is_link = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
    let target = is_link.then(|| std::fs::canonicalize(path).ok()).flatten();
    let file = target.as_deref().unwrap_or(path);
    file.parent().unwrap_or_else(|| Path::new("")).to_path_buf()
}

/// The directory `path` is written in (its temporary goes there, so the rename stays on one
/// file system).
fn directory_of(path: &Path) -> Result<PathBuf> {
    if path.file_name().is_none() {
        return Err(Error::invalid_option(
            "output",
            path.display().to_string(),
            "is not a file name",
        ));
    }
    Ok(match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    })
}

/// Prefix and suffix of every temporary's name.
const TEMPORARY_PREFIX: &str = ".pfs-";
const TEMPORARY_SUFFIX: &str = ".tmp";

/// Names tried before creating a temporary gives up (each collision is a planted file or a
/// 2^-64 coincidence).
const TEMPORARY_ATTEMPTS: u32 = 16;

/// A fresh temporary name for this process: `.pfs-<pid>-<16 hex digits>.tmp`, the digits from
/// a hash with the standard library's random per-process keys (not guessable from the pid or
/// the time).
fn temporary_name() -> String {
    use std::hash::{BuildHasher, Hasher};
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed));
    format!(
        "{TEMPORARY_PREFIX}{}-{:016x}{TEMPORARY_SUFFIX}",
        std::process::id(),
        h.finish()
    )
}

/// The process id in a temporary's file name, if it is one of ours.
fn temporary_pid(name: &std::ffi::OsStr) -> Option<u32> {
    let rest = name.to_str()?.strip_prefix(TEMPORARY_PREFIX)?;
    let rest = rest.strip_suffix(TEMPORARY_SUFFIX)?;
    let (pid, hex) = rest.split_once('-')?;
    (hex.len() == 16 && hex.bytes().all(|b| b.is_ascii_hexdigit())).then_some(())?;
    pid.parse().ok()
}

/// Removes the temporaries in `dir` left by processes that no longer exist (Linux: no
/// `/proc/<pid>`; elsewhere nothing is removed). Only regular files named as ours are touched.
fn remove_stale_temporaries(dir: &Path) {
    let proc_root = Path::new("/proc");
    if !proc_root.join("self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let Some(pid) = temporary_pid(&e.file_name()) else {
            continue;
        };
        let regular = e.file_type().is_ok_and(|t| t.is_file());
        if regular && pid != std::process::id() && !proc_root.join(pid.to_string()).exists() {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// The registry of the temporaries a set of writes has created and not yet renamed or removed,
/// and the lock batch commits hold. Cheap to clone (the clones share the registry): the writer
/// keeps one, the code that cleans up after a signal another.
#[derive(Clone, Debug, Default)]
pub struct Outputs {
    shared: Arc<Registry>,
}

#[derive(Debug, Default)]
struct Registry {
    /// Temporaries that may exist now (registered before they are created, removed from the
    /// list once renamed or deleted).
    live: Mutex<Vec<PathBuf>>,
    /// Held while a batch renames its temporaries, and by [`Outputs::remove_temporaries`].
    commit: Mutex<()>,
    /// Directories already swept of dead runs' temporaries.
    swept: Mutex<std::collections::HashSet<PathBuf>>,
    /// While a [`Hold`] is open: the `(temporary, target)` pairs every write has staged, renamed
    /// only when the hold commits.
    held: Mutex<Option<Vec<(PathBuf, PathBuf)>>>,
    /// Set by [`Outputs::interrupt`]: no batch starts its renames after it.
    interrupted: std::sync::atomic::AtomicBool,
}

impl Outputs {
    /// A new, empty registry.
    pub fn new() -> Outputs {
        Outputs::default()
    }

    fn live(&self) -> MutexGuard<'_, Vec<PathBuf>> {
        self.shared.live.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn forget(&self, tmp: &Path) {
        self.live().retain(|t| t != tmp);
    }

    /// Removes every temporary of this registry that was created and not yet renamed or
    /// removed, after any batch commit in progress has finished its renames; returns how many
    /// were removed. For a signal handler: after it, the process should exit (a write still
    /// running would recreate nothing, but its rename would fail).
    pub fn remove_temporaries(&self) -> usize {
        let _commit = self.shared.commit.lock().unwrap_or_else(|e| e.into_inner());
        let mut removed = 0;
        for t in self.live().drain(..) {
            if std::fs::remove_file(&t).is_ok() {
                removed += 1;
            }
        }
        removed
    }

    /// For a signal handler: marks the run interrupted, so that no batch starts renaming after
    /// it (a batch already renaming finishes first: all of a batch or none of it), then
    /// [`Outputs::remove_temporaries`]. The caller exits; a main thread that finishes a batch
    /// meanwhile checks [`Outputs::interrupted`] before it reports success.
    pub fn interrupt(&self) -> usize {
        self.shared
            .interrupted
            .store(true, std::sync::atomic::Ordering::SeqCst);
        self.remove_temporaries()
    }

    /// Whether [`Outputs::interrupt`] was called.
    pub fn interrupted(&self) -> bool {
        self.shared
            .interrupted
            .load(std::sync::atomic::Ordering::SeqCst)
    }

    /// Writes `bytes` for target `path` to a new temporary in `dir` (created if missing), with
    /// the target's permission bits if it exists, and flushes it to disk; returns the
    /// temporary's path. Removes it on failure.
    fn write_temporary(&self, dir: &Path, path: &Path, bytes: &[u8]) -> Result<PathBuf> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let first = self
            .shared
            .swept
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(dir.to_path_buf());
        if first {
            remove_stale_temporaries(dir);
        }
        let (tmp, mut f) = self.create_temporary(dir, path)?;
        let result = (|| {
            if let Ok(meta) = std::fs::symlink_metadata(path) {
                if meta.is_file() {
                    f.set_permissions(meta.permissions())?;
                }
            }
            f.write_all(bytes)?;
            f.sync_all()
        })();
        if let Err(e) = result {
            drop(f);
            let _ = std::fs::remove_file(&tmp);
            self.forget(&tmp);
            return Err(Error::io(path, e));
        }
        Ok(tmp)
    }

    /// Creates a new temporary in `dir` exclusively (never opening an existing file or
    /// following a link), registered before it exists; another name is drawn on a collision.
    /// The registry stays locked from the interrupt check to the file's creation, so a signal's
    /// cleanup either comes first (and nothing is created) or sees and removes the new file:
    /// a writer thread still running when the handler cleans up leaves nothing behind.
    fn create_temporary(&self, dir: &Path, path: &Path) -> Result<(PathBuf, std::fs::File)> {
        let mut last = None;
        for _ in 0..TEMPORARY_ATTEMPTS {
            let tmp = dir.join(temporary_name());
            let mut live = self.live();
            if self.interrupted() {
                return Err(Error::io(path, std::io::Error::other("interrupted")));
            }
            live.push(tmp.clone());
            let opened = std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&tmp);
            match opened {
                Ok(f) => return Ok((tmp, f)),
                Err(e) => {
                    live.retain(|t| t != &tmp);
                    drop(live);
                    if e.kind() != std::io::ErrorKind::AlreadyExists {
                        return Err(Error::io(path, e));
                    }
                    last = Some(e);
                }
            }
        }
        Err(Error::io(
            path,
            last.unwrap_or_else(|| std::io::Error::other("no temporary name was free")),
        ))
    }

    fn held(&self) -> MutexGuard<'_, Option<Vec<(PathBuf, PathBuf)>>> {
        self.shared.held.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Writes `bytes` to `path` atomically. Creates missing parent directories. While a
    /// [`Hold`] is open the file is only staged: it appears when the hold commits.
    pub fn write_atomic(&self, path: &Path, bytes: &[u8]) -> Result<()> {
        let mut batch = self.batch();
        batch.stage(path, bytes)?;
        batch.commit()
    }

    /// Makes every later write of this registry (and its clones) part of one all-or-nothing
    /// output, for commands that write many files over minutes (`results`, `experiment`,
    /// `sweep`): nothing is replaced until [`Hold::commit`]; dropping the hold, or
    /// [`Outputs::remove_temporaries`] after a signal, removes what was staged. Holds do not
    /// nest: opening one while another is open is an internal error.
    pub fn hold(&self) -> Result<Hold> {
        let mut held = self.held();
        if held.is_some() {
            return Err(Error::internal("an output hold is already open"));
        }
        *held = Some(Vec::new());
        Ok(Hold {
            outputs: self.clone(),
        })
    }

    /// An empty batch writing through this registry.
    pub fn batch(&self) -> Batch {
        Batch {
            outputs: self.clone(),
            staged: Vec::new(),
        }
    }
}

/// Several files written as one: [`Batch::stage`] writes each to its temporary, [`Batch::commit`]
/// renames them all over their targets. Dropping an uncommitted batch removes its temporaries.
#[derive(Debug)]
pub struct Batch {
    outputs: Outputs,
    staged: Vec<(PathBuf, PathBuf)>,
}

impl Batch {
    /// Writes `bytes` to `path`'s temporary (flushed); `path` is replaced on commit.
    pub fn stage(&mut self, path: &Path, bytes: &[u8]) -> Result<()> {
        if let Ok(meta) = std::fs::symlink_metadata(path) {
            if let Some(what) = not_regular(&meta) {
                return Err(Error::io(path, std::io::Error::other(what)));
            }
        }
        let dir = directory_of(path)?;
        let tmp = self.outputs.write_temporary(&dir, path, bytes)?;
        self.staged.push((tmp, path.to_path_buf()));
        Ok(())
    }

    /// Renames every staged temporary over its target, in staging order. On a failed rename the
    /// remaining temporaries are removed and the error names the target. While a [`Hold`] is
    /// open the batch joins it instead, and is renamed with the rest when the hold commits.
    pub fn commit(mut self) -> Result<()> {
        if let Some(held) = self.outputs.held().as_mut() {
            held.append(&mut self.staged);
            return Ok(());
        }
        self.rename_all()
    }

    fn rename_all(mut self) -> Result<()> {
        // A target that became a directory, a link or a device since it was staged would fail
        // its rename (or replace what it is not ours to replace) halfway through the batch:
        // refuse before the first rename instead.
        for (_, path) in &self.staged {
            if let Ok(meta) = std::fs::symlink_metadata(path) {
                if let Some(what) = not_regular(&meta) {
                    return Err(Error::io(path, std::io::Error::other(what)));
                }
            }
        }
        let staged = std::mem::take(&mut self.staged);
        let shared = Arc::clone(&self.outputs.shared);
        let _commit = shared.commit.lock().unwrap_or_else(|e| e.into_inner());
        if self.outputs.interrupted() {
            for (t, _) in &staged {
                let _ = std::fs::remove_file(t);
                self.outputs.forget(t);
            }
            return Err(Error::Runtime(
                "interrupted before the outputs were written: none was replaced".into(),
            ));
        }
        for (k, (tmp, path)) in staged.iter().enumerate() {
            if let Err(e) = std::fs::rename(tmp, path) {
                for (t, _) in &staged[k..] {
                    let _ = std::fs::remove_file(t);
                    self.outputs.forget(t);
                }
                return Err(Error::io(path, e));
            }
            self.outputs.forget(tmp);
        }
        Ok(())
    }
}

impl Drop for Batch {
    fn drop(&mut self) {
        for (tmp, _) in &self.staged {
            let _ = std::fs::remove_file(tmp);
            self.outputs.forget(tmp);
        }
    }
}

/// The open all-or-nothing output of [`Outputs::hold`].
#[derive(Debug)]
pub struct Hold {
    outputs: Outputs,
}

impl Hold {
    /// Renames every file written since the hold opened over its target, in writing order
    /// (a target written twice ends with its last bytes); returns the targets, each once.
    pub fn commit(self) -> Result<Vec<PathBuf>> {
        let staged = self.outputs.held().take().unwrap_or_default();
        let mut targets: Vec<PathBuf> = Vec::new();
        for (_, path) in &staged {
            if !targets.contains(path) {
                targets.push(path.clone());
            }
        }
        Batch {
            outputs: self.outputs.clone(),
            staged,
        }
        .rename_all()?;
        Ok(targets)
    }
}

impl Drop for Hold {
    fn drop(&mut self) {
        // After a commit this is empty; otherwise the staged files are dropped with the batch.
        let staged = self.outputs.held().take().unwrap_or_default();
        drop(Batch {
            outputs: self.outputs.clone(),
            staged,
        });
    }
}

/// What an existing path is, for the refusal message; `None` for a regular file.
fn not_regular(meta: &std::fs::Metadata) -> Option<&'static str> {
    let t = meta.file_type();
    if t.is_file() {
        None
    } else if t.is_symlink() {
        Some("is a symbolic link")
    } else if t.is_dir() {
        Some("is a directory")
    } else {
        Some("is not a regular file (a device, FIFO or socket)")
    }
}

/// The path `p` will be written at, resolved: its longest existing ancestor made canonical
/// (symbolic links and `..` resolved by the file system), the rest appended with `.` and `..`
/// resolved lexically, as `create_dir_all` and the write will resolve them.
fn resolved(p: &Path) -> PathBuf {
    let abs = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let mut rest = Vec::new();
    let mut base = abs.as_path();
    let canonical = loop {
        if let Ok(c) = std::fs::canonicalize(base) {
            break c;
        }
        match (base.parent(), base.file_name()) {
            (Some(parent), _) => {
                rest.push(base.components().next_back());
                base = parent;
            }
            (None, _) => break PathBuf::new(),
        }
    };
    let mut out = canonical;
    for c in rest.into_iter().rev().flatten() {
        match c {
            std::path::Component::ParentDir => {
                out.pop();
            }
            std::path::Component::CurDir => {}
            c => out.push(c.as_os_str()),
        }
    }
    out
}

/// Longest file name a file system takes (`NAME_MAX` on Linux, macOS and Windows).
pub const MAX_NAME_BYTES: usize = 255;

/// Longest path the system calls take (`PATH_MAX` on Linux, less its terminating zero).
pub const MAX_PATH_BYTES: usize = 4095;

/// Why `path` could never be written, found before any work: a file name or a path too long
/// for the file system, or an existing ancestor that is not a directory.
fn unwritable_name(path: &Path) -> Option<String> {
    let name = path.file_name().map_or(0, |n| n.as_encoded_bytes().len());
    if name > MAX_NAME_BYTES {
        return Some(format!(
            "has a file name of {name} bytes, over the {MAX_NAME_BYTES} a file system allows"
        ));
    }
    let long = std::path::absolute(path).map_or(0, |p| p.as_os_str().as_encoded_bytes().len());
    if long > MAX_PATH_BYTES {
        return Some(format!(
            "is {long} bytes long as an absolute path, over the {MAX_PATH_BYTES} the system allows"
        ));
    }
    for a in path.ancestors().skip(1) {
        if a.as_os_str().is_empty() {
            break;
        }
        if let Ok(m) = std::fs::metadata(a) {
            if !m.is_dir() {
                return Some(format!(
                    "cannot be created: {} is a file, not a directory",
                    a.display()
                ));
            }
            break;
        }
    }
    None
}

/// Whether two existing files are the same file (same device and inode: hard links too).
#[cfg(unix)]
fn same_file(a: &std::fs::Metadata, b: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    a.dev() == b.dev() && a.ino() == b.ino()
}

#[cfg(not(unix))]
fn same_file(_: &std::fs::Metadata, _: &std::fs::Metadata) -> bool {
    false
}

/// Checks every output of a job before it starts (module docs): `outputs` are `(option, path)`
/// pairs, `inputs` every file the job reads. Any refusal is an [`Error::InvalidOption`] (exit 2)
/// naming the option and the path.
pub fn check_outputs(inputs: &[PathBuf], outputs: &[(&str, &Path)]) -> Result<()> {
    let refuse = |option: &str, path: &Path, why: String| {
        Err(Error::invalid_option(
            option,
            path.display().to_string(),
            why,
        ))
    };
    let ins: Vec<(PathBuf, PathBuf, Option<std::fs::Metadata>)> = inputs
        .iter()
        .map(|p| (p.clone(), resolved(p), std::fs::metadata(p).ok()))
        .collect();
    // Hashed, not searched: a walkthrough has up to a million outputs.
    let mut seen: std::collections::HashMap<PathBuf, &str> = std::collections::HashMap::new();
    for &(option, path) in outputs {
        let text = path.as_os_str().to_string_lossy();
        if text.is_empty() {
            return refuse(option, path, "is empty; give a file name".into());
        }
        if text.ends_with('/') || text.ends_with(std::path::MAIN_SEPARATOR) {
            return refuse(option, path, "names a directory; give a file name".into());
        }
        if let Some(why) = unwritable_name(path) {
            return refuse(option, path, why);
        }
        let meta = std::fs::symlink_metadata(path).ok();
        if let Some(why) = meta.as_ref().and_then(not_regular) {
            return refuse(option, path, format!("{why}; refusing to replace it"));
        }
        let r = resolved(path);
        for (input, ri, im) in &ins {
            let same = *ri == r || matches!((&meta, im), (Some(a), Some(b)) if same_file(a, b));
            if same {
                return refuse(
                    option,
                    path,
                    format!(
                        "is the input file {}; refusing to overwrite an input",
                        input.display()
                    ),
                );
            }
        }
        if let Some(other) = seen.get(&r) {
            return refuse(
                option,
                path,
                format!("is also the output of `{other}`; give each output its own file"),
            );
        }
        seen.insert(r, option);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fresh_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("pfs-check-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// A byte-order mark used to hide an OBJ's first line (`\u{feff}v 0 0 0` is no vertex).
    #[test]
    fn a_byte_order_mark_is_not_read_as_text() {
        let dir = fresh_dir("bom");
        let path = dir.join("m.obj");
        std::fs::write(&path, "\u{feff}v 0 0 0\n").unwrap();
        assert_eq!(read_text(&path, MAX_INPUT_BYTES).unwrap(), "v 0 0 0\n");
        std::fs::write(&path, "v 0 0 0\n\u{feff}").unwrap();
        assert_eq!(
            read_text(&path, MAX_INPUT_BYTES).unwrap(),
            "v 0 0 0\n\u{feff}",
            "only a leading mark"
        );
    }

    #[test]
    fn outputs_that_are_inputs_or_not_regular_files_are_refused() {
        let dir = fresh_dir("refuse");
        let input = dir.join("scene.toml");
        std::fs::write(&input, "x").unwrap();
        let ins = vec![input.clone()];
        let refused = |path: &Path| -> String {
            match check_outputs(&ins, &[("output", path)]) {
                Err(e @ Error::InvalidOption { .. }) => {
                    assert_eq!(e.exit_code(), 2);
                    e.to_string()
                }
                other => panic!("{} not refused: {other:?}", path.display()),
            }
        };
        // The input itself, by another spelling, through a symlinked directory, a hard link.
        assert!(refused(&input).contains("input"));
        assert!(refused(&dir.join("sub/../scene.toml")).contains("input"));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        assert!(refused(&dir.join("sub/../scene.toml")).contains("input"));
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(&dir, dir.join("link")).unwrap();
            assert!(refused(&dir.join("link/scene.toml")).contains("input"));
            std::fs::hard_link(&input, dir.join("hard.toml")).unwrap();
            assert!(refused(&dir.join("hard.toml")).contains("input"));
            std::os::unix::fs::symlink(dir.join("elsewhere"), dir.join("dangling.png")).unwrap();
            assert!(refused(&dir.join("dangling.png")).contains("symbolic link"));
            assert!(refused(Path::new("/dev/null")).contains("not a regular file"));
        }
        assert!(refused(&dir.join("sub")).contains("directory"));
        assert!(refused(Path::new("some/dir/")).contains("directory"));
        // Two outputs naming one file.
        let a = dir.join("a.png");
        let e = check_outputs(&ins, &[("output", &a), ("exr", &dir.join("./a.png"))]).unwrap_err();
        assert!(e.to_string().contains("also the output of `output`"), "{e}");
        // Fresh files, and a replaceable regular file, are fine.
        std::fs::write(dir.join("old.png"), "old").unwrap();
        check_outputs(&ins, &[("output", &a), ("exr", &dir.join("old.png"))]).unwrap();
        check_outputs(&ins, &[("output", &dir.join("new/dir/out.png"))]).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn names_that_can_never_be_written_are_refused_up_front() {
        let dir = fresh_dir("names");
        let refused = |path: &Path| {
            check_outputs(&[], &[("output", path)])
                .unwrap_err()
                .to_string()
        };
        // The longest legal name is fine (its temporary's name is short); one byte more is not.
        let legal = dir.join("a".repeat(MAX_NAME_BYTES));
        check_outputs(&[], &[("output", &legal)]).unwrap();
        Outputs::new().write_atomic(&legal, b"x").unwrap();
        assert_eq!(std::fs::read(&legal).unwrap(), b"x");
        let e = refused(&dir.join("a".repeat(MAX_NAME_BYTES + 1)));
        assert!(e.contains("256 bytes"), "{e}");
        let deep = dir.join("d/".repeat(MAX_PATH_BYTES / 2)).join("x.png");
        assert!(refused(&deep).contains("bytes long"));
        // A directory component that is a file.
        std::fs::write(dir.join("file"), "x").unwrap();
        let e = refused(&dir.join("file/sub/x.toml"));
        assert!(e.contains("is a file, not a directory"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// What broke: the temporary of `out/x.png` had a predictable name and was opened
    /// following links, so a link planted there let a render overwrite the link's target.
    #[cfg(unix)]
    #[test]
    fn a_planted_link_is_never_followed_and_modes_are_kept() {
        use std::os::unix::fs::PermissionsExt;
        let dir = fresh_dir("planted");
        let victim = dir.join("victim.txt");
        std::fs::write(&victim, "precious").unwrap();
        // A link at every name this process could draw next is impossible to plant; plant
        // links at the old scheme's name and at names of ours, and check none is followed.
        std::os::unix::fs::symlink(
            &victim,
            dir.join(format!(".x.png.{}.tmp", std::process::id())),
        )
        .unwrap();
        for _ in 0..4 {
            std::os::unix::fs::symlink(&victim, dir.join(temporary_name())).unwrap();
        }
        let out = dir.join("x.png");
        std::fs::write(&out, "old").unwrap();
        std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o600)).unwrap();
        Outputs::new().write_atomic(&out, b"new").unwrap();
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
        assert_eq!(std::fs::read(&out).unwrap(), b"new");
        let mode = std::fs::metadata(&out).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_dead_runs_temporaries_are_removed_and_a_live_ones_kept() {
        let dir = fresh_dir("stale");
        // No process has pid 4,194,304 + 1 (Linux's pid_max is at most 2^22).
        let dead = dir.join(format!(".pfs-4194305-{:016x}.tmp", 7));
        let live = dir.join(temporary_name());
        let other = dir.join(".pfs-notes.tmp");
        for p in [&dead, &live, &other] {
            std::fs::write(p, "t").unwrap();
        }
        Outputs::new()
            .write_atomic(&dir.join("out.txt"), b"x")
            .unwrap();
        let proc_fs = Path::new("/proc/self").exists();
        assert_eq!(dead.exists(), !proc_fs);
        assert!(live.exists() && other.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn reads_stop_at_the_limit() {
        let dir = fresh_dir("limit");
        let p = dir.join("ten.bin");
        std::fs::write(&p, [7u8; 10]).unwrap();
        assert_eq!(read_limited(&p, 10).unwrap().len(), 10);
        let e = read_limited(&p, 9).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::FileTooLarge);
        // An endless file ends in the same error, after max + 1 bytes.
        #[cfg(unix)]
        assert_eq!(
            read_limited(Path::new("/dev/zero"), 1 << 20)
                .unwrap_err()
                .kind(),
            std::io::ErrorKind::FileTooLarge
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_failed_batch_leaves_every_target_as_it_was() {
        let dir = fresh_dir("batch");
        let (a, b) = (dir.join("a.png"), dir.join("b.exr"));
        std::fs::write(&a, "old a").unwrap();
        std::fs::write(&b, "old b").unwrap();
        let outputs = Outputs::new();
        {
            let mut batch = outputs.batch();
            batch.stage(&a, b"new a").unwrap();
            batch.stage(&b, b"new b").unwrap();
            // Dropped without commit (an error after staging): nothing replaced, no temporary.
        }
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert_eq!(std::fs::read(&b).unwrap(), b"old b");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
        let mut batch = outputs.batch();
        batch.stage(&a, b"new a").unwrap();
        batch.stage(&b, b"new b").unwrap();
        batch.commit().unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"new a");
        assert_eq!(std::fs::read(&b).unwrap(), b"new b");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// An interrupt that comes before a batch (or a hold) commits stops it whole: no target
    /// replaced, no temporary left, and the commit says so. What broke: a Ctrl-C during an
    /// export's final write was dropped and the run exited 0.
    #[test]
    fn an_interrupt_before_the_commit_replaces_nothing() {
        let dir = fresh_dir("interrupt");
        let (a, b) = (dir.join("a.png"), dir.join("b.exr"));
        std::fs::write(&a, "old a").unwrap();
        let outputs = Outputs::new();
        let mut batch = outputs.batch();
        batch.stage(&a, b"new a").unwrap();
        batch.stage(&b, b"new b").unwrap();
        assert!(!outputs.interrupted());
        outputs.interrupt();
        assert!(outputs.interrupted());
        let e = batch.commit().unwrap_err().to_string();
        assert!(e.contains("interrupted"), "{e}");
        // After the interrupt no new temporary is created at all.
        assert!(outputs.write_atomic(&dir.join("d.json"), b"{}").is_err());
        // A hold (every write of a run) likewise, the batches that joined it included.
        let outputs = Outputs::new();
        let hold = outputs.hold().unwrap();
        outputs.write_atomic(&dir.join("c.json"), b"{}").unwrap();
        let mut batch = outputs.batch();
        batch.stage(&a, b"new a").unwrap();
        batch.commit().unwrap();
        outputs.interrupt();
        assert!(hold.commit().is_err());
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("a.png")]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Regression: a walkthrough's writer thread created a frame's temporary just after the
    /// signal handler had cleaned up, and the process exited with it left behind.
    #[test]
    fn writers_racing_an_interrupt_leave_no_temporary() {
        let dir = fresh_dir("race");
        for round in 0..20 {
            let outputs = Outputs::new();
            let writers: Vec<_> = (0..4)
                .map(|w| {
                    let (outputs, dir) = (outputs.clone(), dir.clone());
                    std::thread::spawn(move || {
                        for i in 0.. {
                            let path = dir.join(format!("r{round}-w{w}-{i}.png"));
                            if outputs.write_atomic(&path, &[7; 4096]).is_err() {
                                break;
                            }
                        }
                    })
                })
                .collect();
            std::thread::sleep(std::time::Duration::from_millis(2));
            outputs.interrupt();
            // The handler exits right after the cleanup, so the writers never get to remove
            // what they create later: the directory must hold no temporary from now on, while
            // they are still running.
            for _ in 0..50 {
                let hidden: Vec<_> = std::fs::read_dir(&dir)
                    .unwrap()
                    .flatten()
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .filter(|n| n.starts_with('.'))
                    .collect();
                assert!(hidden.is_empty(), "round {round}: {hidden:?}");
            }
            for w in writers {
                w.join().unwrap();
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_held_output_appears_whole_on_commit_and_not_at_all_on_failure() {
        let dir = fresh_dir("hold");
        let (a, b) = (dir.join("a.txt"), dir.join("sub/b.txt"));
        std::fs::write(&a, "old").unwrap();
        let outputs = Outputs::new();
        {
            let _hold = outputs.hold().unwrap();
            outputs.write_atomic(&a, b"new").unwrap();
            outputs.write_atomic(&b, b"b").unwrap();
            assert_eq!(std::fs::read_to_string(&a).unwrap(), "old");
            assert!(!b.exists());
            // Dropped without commit: a job failed after staging both.
        }
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old");
        assert!(!b.exists());
        let hold = outputs.hold().unwrap();
        assert!(outputs.hold().is_err(), "holds do not nest");
        outputs.write_atomic(&a, b"first").unwrap();
        outputs.write_atomic(&b, b"b").unwrap();
        outputs.write_atomic(&a, b"last").unwrap();
        assert_eq!(hold.commit().unwrap(), vec![a.clone(), b.clone()]);
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "last");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "b");
        // Nothing hidden is left, and writes after the commit are immediate again.
        outputs.write_atomic(&a, b"now").unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "now");
        for d in [&dir, &dir.join("sub")] {
            let names: Vec<_> = std::fs::read_dir(d)
                .unwrap()
                .flatten()
                .map(|e| e.file_name())
                .collect();
            assert!(
                names
                    .iter()
                    .all(|n| !n.to_string_lossy().starts_with(".pfs-")),
                "{names:?}"
            );
        }
        // A signal's cleanup removes what a hold has staged.
        let _hold = outputs.hold().unwrap();
        outputs.write_atomic(&dir.join("c.txt"), b"c").unwrap();
        assert_eq!(outputs.remove_temporaries(), 1);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn writes_and_replaces_without_leaving_temporaries() {
        let dir = std::env::temp_dir().join(format!("pfs-out-{}", std::process::id()));
        let p = dir.join("sub/a.txt");
        let outputs = Outputs::new();
        outputs.write_atomic(&p, b"one").unwrap();
        outputs.write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        let names: Vec<_> = std::fs::read_dir(p.parent().unwrap())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1, "temporary left behind: {names:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_registry_removes_only_its_own_live_temporaries() {
        let dir = fresh_dir("registry");
        let (mine, theirs) = (Outputs::new(), Outputs::new());
        let mut a = mine.batch();
        a.stage(&dir.join("a.png"), b"a").unwrap();
        let mut b = theirs.batch();
        b.stage(&dir.join("b.png"), b"b").unwrap();
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
        // A clone shares the registry (a signal handler holds one).
        assert_eq!(mine.clone().remove_temporaries(), 1);
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        b.commit().unwrap();
        assert!(dir.join("b.png").exists() && !dir.join("a.png").exists());
        assert_eq!(theirs.remove_temporaries(), 0);
        drop(a);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
