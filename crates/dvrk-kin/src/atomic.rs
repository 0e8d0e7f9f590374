//! Outputs written whole or not at all, the one discipline every writer follows (exports, the
//! CLI's outputs, camera frames, recordings, the Python package):
//!
//! - an output is checked before any work ([`check_outputs`]): its directory must exist (no
//!   directory is created), it must not be a directory, and it must be neither an input nor
//!   another output of the same command;
//! - it is written to a temporary file beside its target ([`Staged`]), and renamed over the target
//!   only when everything the command writes is ready ([`commit_all`]); a command with several
//!   outputs commits all of them or none;
//! - a staged file that is dropped is removed, and a signal handler can remove every staged file
//!   of the process ([`remove_all_staged`]);
//! - every output gets the same mode (0644 before the umask);
//! - a symbolic link is followed: its target is replaced (the link kept); a FIFO, device or socket
//!   is refused (renaming over it would replace it with a file, and its reader would get nothing);
//! - one writer per target: the temporary file (`.NAME.dvrk.tmp`, one per target) is locked
//!   (`flock`) while it is written, and a second process writing the same target is refused with
//!   one line. A temporary file left by a killed process is not locked and is taken over (emptied)
//!   by the next run writing that target.

use crate::error::{KinError, Result};
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// A temporary file of this process not yet committed or removed (for signal handlers), with
/// its locked handle while it is only reserved ([`reserve`]).
#[derive(Debug)]
struct Entry {
    tmp: PathBuf,
    target: PathBuf,
    reserved: Option<File>,
}

static STAGED: Mutex<Vec<Entry>> = Mutex::new(Vec::new());

fn registry() -> std::sync::MutexGuard<'static, Vec<Entry>> {
    STAGED.lock().unwrap_or_else(|e| e.into_inner())
}

/// Remove every staged or reserved file of this process (from a SIGINT/SIGTERM handler, or at
/// exit: nothing half-written is left behind). Returns how many were removed.
pub fn remove_all_staged() -> usize {
    let mut list = registry();
    let n = list.iter().filter(|e| std::fs::remove_file(&e.tmp).is_ok()).count();
    list.clear();
    n
}

fn file_error(path: &Path, what: &str, e: std::io::Error) -> KinError {
    KinError::File { path: path.into(), message: format!("cannot {what}: {e}") }
}

/// The file an output `path` replaces: symbolic links followed (a link's target is replaced, the
/// link kept); the path itself when nothing is there. An existing target that is not a regular
/// file (FIFO, device, socket, directory) is refused.
pub fn output_target(path: &Path) -> Result<PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let to = std::fs::read_link(&p).map_err(|e| file_error(path, "read the link", e))?;
                p = match p.parent() {
                    Some(d) if to.is_relative() => d.join(to),
                    _ => to,
                };
            }
            Ok(m) if !m.is_file() => {
                let via = if p != path { format!(" (the link's target {})", p.display()) } else { String::new() };
                return Err(KinError::File {
                    path: path.into(),
                    message: format!("is {}{via}, not a regular file: an output is written whole and renamed over its target; give a file name", crate::text_file::kind(&m)),
                });
            }
            _ => return Ok(p),
        }
    }
    Err(KinError::File { path: path.into(), message: "too many levels of symbolic links".into() })
}

/// The (device, inode) of an open file and of a path, equal when the path still names the file.
#[cfg(unix)]
fn same_inode(f: &File, p: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (f.metadata(), std::fs::symlink_metadata(p)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}
#[cfg(not(unix))]
fn same_inode(_: &File, _: &Path) -> bool {
    true
}

fn busy_message(tmp: &Path) -> String {
    format!("another process is writing it now (its temporary file {} is locked); wait for it to finish or give another name", tmp.display())
}

fn busy(target: &Path, tmp: &Path) -> KinError {
    KinError::File { path: target.into(), message: busy_message(tmp) }
}

/// Open and lock the temporary file of the resolved target `real` (created 0644 before the
/// umask, emptied): refused when another process holds it.
fn lock_temp(shown: &Path, real: &Path) -> Result<(PathBuf, File)> {
    let tmp = Staged::temp_path(real);
    for _ in 0..10 {
        if std::fs::symlink_metadata(&tmp).is_ok_and(|m| !m.is_file()) {
            return Err(KinError::File { path: shown.into(), message: format!("its temporary file {} exists and is not a regular file; remove it", tmp.display()) });
        }
        let mut options = std::fs::OpenOptions::new();
        options.read(true).write(true).create(true).truncate(false);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o644);
        let file = options.open(&tmp).map_err(|e| file_error(shown, "write", e))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => return Err(busy(shown, &tmp)),
            Err(std::fs::TryLockError::Error(e)) => return Err(file_error(shown, "lock its temporary file", e)),
        }
        // The writer before may have renamed it over its target between our open and lock.
        if same_inode(&file, &tmp) {
            file.set_len(0).map_err(|e| file_error(shown, "write", e))?;
            return Ok((tmp, file));
        }
    }
    Err(busy(shown, &tmp))
}

/// Reserve `path` as an output of this process before any work: its temporary file is created
/// and locked now, so a second process writing the same target is refused at its start, not
/// after its work. [`Staged::create`] takes the reservation; [`remove_all_staged`] ends it.
pub fn reserve(path: &Path) -> Result<()> {
    let real = output_target(path)?;
    if registry().iter().any(|e| e.target == real) {
        return Ok(());
    }
    let (tmp, file) = lock_temp(path, &real)?;
    registry().push(Entry { tmp, target: real, reserved: Some(file) });
    Ok(())
}

/// A file written beside its target, waiting to be renamed over it. Dropped uncommitted, it is
/// removed.
#[derive(Debug)]
pub struct Staged {
    tmp: PathBuf,
    /// The file replaced (symlinks followed).
    real: PathBuf,
    /// The output as given.
    target: PathBuf,
    /// The temporary file's lock, held until the rename.
    lock: Option<File>,
    live: bool,
}

impl Staged {
    /// The temporary path for `target` (hidden, in the same directory, one per target).
    pub fn temp_path(target: &Path) -> PathBuf {
        let file = target.file_name().map_or("out".into(), |n| n.to_string_lossy().into_owned());
        target.with_file_name(format!(".{file}.dvrk.tmp"))
    }

    /// Create the temporary file for `target` (mode 0644 before the umask), locked, and register
    /// it; a symlink's target is the one replaced, and a reservation ([`reserve`]) is taken.
    pub fn create(target: &Path) -> Result<(Staged, std::fs::File)> {
        let real = output_target(target)?;
        let reserved = registry().iter_mut().find(|e| e.target == real).and_then(|e| e.reserved.take().map(|f| (e.tmp.clone(), f)));
        let (tmp, file) = match reserved {
            Some(r) => r,
            None => {
                let (tmp, file) = lock_temp(target, &real)?;
                registry().push(Entry { tmp: tmp.clone(), target: real.clone(), reserved: None });
                (tmp, file)
            }
        };
        let lock = file.try_clone().map_err(|e| file_error(target, "write", e))?;
        Ok((Staged { tmp, real, target: target.to_path_buf(), lock: Some(lock), live: true }, file))
    }

    /// Stage `bytes` for `target`: written and synced, not yet visible.
    pub fn write(target: &Path, bytes: &[u8]) -> Result<Staged> {
        use std::io::Write;
        let (staged, mut f) = Self::create(target)?;
        f.write_all(bytes).and_then(|_| f.sync_all()).map_err(|e| file_error(target, "write", e))?;
        Ok(staged)
    }

    /// The destination (as given; a symlink's target is what is replaced).
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// The temporary file.
    pub fn temp(&self) -> &Path {
        &self.tmp
    }

    /// Rename the file over its target (a symlink's target: the link is kept).
    pub fn commit(mut self) -> Result<()> {
        let r = std::fs::rename(&self.tmp, &self.real).map_err(|e| file_error(&self.target, "replace", e));
        if r.is_err() {
            let _ = std::fs::remove_file(&self.tmp);
        }
        self.forget();
        r
    }

    fn forget(&mut self) {
        self.live = false;
        registry().retain(|e| e.tmp != self.tmp);
        self.lock = None;
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if self.live {
            let _ = std::fs::remove_file(&self.tmp);
            self.forget();
        }
    }
}

/// Commit staged files together: nothing is renamed unless every one was staged (the caller
/// stages all first); then each is renamed in turn.
pub fn commit_all(staged: Vec<Staged>) -> Result<()> {
    staged.into_iter().try_for_each(Staged::commit)
}

/// Write `bytes` to `path` atomically: a temporary file in the same directory, then a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    Staged::write(path, bytes)?.commit()
}

/// The file's identity: its canonical path (the directory resolved, the name kept), and
/// (device, inode) where it exists, so hard links and `./x` vs `x` are the same file.
fn identity(path: &Path) -> (Option<PathBuf>, Option<(u64, u64)>) {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let canon = std::fs::canonicalize(dir).ok().zip(path.file_name()).map(|(d, n)| d.join(n));
    #[cfg(unix)]
    let inode = {
        use std::os::unix::fs::MetadataExt;
        std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
    };
    #[cfg(not(unix))]
    let inode = None;
    (canon, inode)
}

fn same_file(a: &Path, b: &Path) -> bool {
    let (ca, ia) = identity(a);
    let (cb, ib) = identity(b);
    (ia.is_some() && ia == ib) || (ca.is_some() && ca == cb)
}

/// Check a command's outputs before it does any work: each `(flag, path)` of `outputs` must be
/// in an existing directory, must not be a directory, and must be neither one of `inputs` nor an
/// earlier output. Errors name the flag, the path and the clash.
pub fn check_outputs(inputs: &[(&str, &Path)], outputs: &[(&str, &Path)]) -> Result<()> {
    let field = |flag: &str, path: &Path, message: String| KinError::File { path: path.into(), message: format!("{flag}: {message}") };
    for (i, (flag, path)) in outputs.iter().enumerate() {
        if path.as_os_str().is_empty() || path.file_name().is_none() {
            return Err(field(flag, path, "not a file name".into()));
        }
        if path.is_dir() {
            return Err(field(flag, path, "is a directory; give a file name".into()));
        }
        let real = output_target(path).map_err(|e| match e {
            KinError::File { message, .. } => field(flag, path, message),
            e => e,
        })?;
        let tmp = Staged::temp_path(&real);
        let ours = registry().iter().any(|e| e.target == real);
        if !ours && std::fs::File::open(&tmp).is_ok_and(|f| matches!(f.try_lock(), Err(std::fs::TryLockError::WouldBlock))) {
            return Err(field(flag, path, busy_message(&tmp)));
        }
        let dir = match real.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if !dir.is_dir() {
            return Err(field(flag, path, format!("directory {} does not exist (outputs never create directories)", dir.display())));
        }
        if let Some((f, p)) = inputs.iter().find(|(_, p)| same_file(path, p)) {
            return Err(field(flag, path, format!("is the input {f} {}; an output never overwrites an input", p.display())));
        }
        if let Some((f, _)) = outputs[..i].iter().find(|(_, p)| same_file(path, p)) {
            return Err(field(flag, path, format!("is also the output {f}; give each output its own file")));
        }
    }
    Ok(())
}
