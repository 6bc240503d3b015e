//! Temporary outputs that an interrupt cleans up, and those a killed run left behind.
//!
//! Every temporary file of [`super::atomic`] is created through [`create_temporary`], which
//! records its path in a process-wide registry for as long as it lives. [`install_handlers`]
//! (called by the CLI, never by a library user such as the Python bindings) starts a thread
//! that waits for SIGINT, SIGTERM or SIGHUP; on one it removes every registered file and ends
//! the process with the shell's code for that signal (130, 143, 129). The destinations are never
//! touched, so an interrupted run leaves the previous outputs as they were and nothing else.
//!
//! Creation and cleanup share one lock, and a file is created while that lock is held, so no
//! temporary file can appear unseen between the cleanup and the exit.
//!
//! A SIGKILL cannot be caught: its temporary files stay. Each live temporary file therefore holds
//! an advisory lock (`flock`) for its whole life, which the kernel drops when its process ends
//! however it ends; [`remove_stale`] deletes the temporary files of one destination whose lock is
//! free — files of dead runs — and leaves those of runs still writing.

use std::fs::File;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

/// The live temporary files, and whether an interrupt has begun cleaning up.
struct Registry {
    next_id: u64,
    live: Vec<(u64, PathBuf)>,
    interrupted: bool,
}

static REGISTRY: Mutex<Registry> = Mutex::new(Registry {
    next_id: 0,
    live: Vec::new(),
    interrupted: false,
});

fn registry() -> MutexGuard<'static, Registry> {
    REGISTRY.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A registered temporary file: dropping it takes the path off the registry (the file itself
/// belongs to its `NamedTempFile`).
#[derive(Debug)]
pub struct Registered(u64);

impl Drop for Registered {
    fn drop(&mut self) {
        registry().live.retain(|(id, _)| *id != self.0);
    }
}

/// Creates `path` (which must not exist) as a new private file and registers it, under the
/// registry's lock. After an interrupt began, nothing more is created.
///
/// # Errors
/// The file exists or cannot be created, or the process is being interrupted.
pub fn create_temporary(path: &Path) -> io::Result<(File, Registered)> {
    let mut registry = registry();
    if registry.interrupted {
        return Err(io::Error::new(io::ErrorKind::Interrupted, "interrupted"));
    }
    let mut options = std::fs::OpenOptions::new();
    options.read(true).write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let file = options.open(path)?;
    let id = registry.next_id;
    registry.next_id += 1;
    registry.live.push((id, path.to_path_buf()));
    Ok((file, Registered(id)))
}

/// Paths of the temporary files alive now.
#[must_use]
pub fn live_temporaries() -> Vec<PathBuf> {
    registry().live.iter().map(|(_, p)| p.clone()).collect()
}

/// Removes every registered temporary file and stops any more from being created; the registry's
/// lock is held until the process ends, so call it only right before exiting.
fn remove_all_and_exit(code: i32) -> ! {
    let mut registry = registry();
    registry.interrupted = true;
    for (_, path) in &registry.live {
        let _ = std::fs::remove_file(path);
    }
    std::process::exit(code)
}

/// Starts the thread that turns SIGINT, SIGTERM and SIGHUP into a cleanup and an exit with
/// 128 + the signal's number. Without it (a library user), signals keep their usual effect.
///
/// # Errors
/// The handlers cannot be registered.
#[cfg(unix)]
pub fn install_handlers() -> io::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])?;
    std::thread::Builder::new()
        .name("zeroset-signals".into())
        .spawn(move || {
            if let Some(signal) = signals.forever().next() {
                let name = match signal {
                    SIGINT => "SIGINT",
                    SIGTERM => "SIGTERM",
                    _ => "SIGHUP",
                };
                let removed = live_temporaries().len();
                eprintln!(
                    "\nzeroset: interrupted ({name}); {removed} unfinished output file(s) removed, \
                     the previous outputs are unchanged"
                );
                remove_all_and_exit(128 + signal);
            }
        })?;
    Ok(())
}

/// Signals keep their usual effect where they cannot be caught this way.
///
/// # Errors
/// Never.
#[cfg(not(unix))]
pub fn install_handlers() -> io::Result<()> {
    Ok(())
}

/// Whether `file_name` is one of our temporary names for the destination named `name`:
/// `.NAME.XXXXXX.tmp`, six ASCII letters or digits in the middle.
#[must_use]
pub fn is_temporary_of(file_name: &str, name: &str) -> bool {
    file_name
        .strip_prefix('.')
        .and_then(|rest| rest.strip_prefix(name))
        .and_then(|rest| rest.strip_prefix('.'))
        .and_then(|rest| rest.strip_suffix(".tmp"))
        .is_some_and(|middle| middle.len() == 6 && middle.bytes().all(|b| b.is_ascii_alphanumeric()))
}

/// Deletes the temporary files of the destination named `name` in `dir` that no live process
/// holds (their lock is free: the run that wrote them was killed); returns how many. A file is
/// deleted only while this process holds its lock and the name still refers to it, so a run
/// that has just created its file (and not yet locked it) finds it gone and makes another.
#[cfg(unix)]
pub fn remove_stale(dir: &Path, name: &str) -> usize {
    use fs4::fs_std::FileExt;
    use std::os::unix::fs::MetadataExt;
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mut removed = 0;
    for entry in entries.flatten() {
        let file_name = entry.file_name();
        if !is_temporary_of(&file_name.to_string_lossy(), name) {
            continue;
        }
        let path = entry.path();
        let Ok(file) = File::open(&path) else { continue };
        // a file system without locks (Err) keeps every temporary file: safe, only untidy
        if !matches!(file.try_lock_exclusive(), Ok(true)) {
            continue;
        }
        let same = match (file.metadata(), std::fs::symlink_metadata(&path)) {
            (Ok(open), Ok(named)) => open.dev() == named.dev() && open.ino() == named.ino() && named.is_file(),
            _ => false,
        };
        if same && std::fs::remove_file(&path).is_ok() {
            removed += 1;
        }
        // closing `file` releases the lock
    }
    removed
}

/// Stale temporary files are left where locks cannot tell them from live ones.
#[cfg(not(unix))]
pub fn remove_stale(_dir: &Path, _name: &str) -> usize {
    0
}

/// Takes the lock that marks `file` (just created at `path`) as alive, and checks that `path`
/// still names it (a [`remove_stale`] of another run may have deleted it between the creation
/// and the lock); `false` means it was deleted and another must be made.
///
/// # Errors
/// Reading the file's metadata fails.
#[cfg(unix)]
pub fn lock_as_alive(file: &File, path: &Path) -> io::Result<bool> {
    use fs4::fs_std::FileExt;
    use std::os::unix::fs::MetadataExt;
    if file.lock_exclusive().is_err() {
        // no locks on this file system: nothing can delete it either
        return Ok(true);
    }
    let open = file.metadata()?;
    Ok(std::fs::symlink_metadata(path).is_ok_and(|named| named.dev() == open.dev() && named.ino() == open.ino()))
}

/// Without locks, a file is always taken as alive.
///
/// # Errors
/// Never.
#[cfg(not(unix))]
pub fn lock_as_alive(_file: &File, _path: &Path) -> io::Result<bool> {
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporary_names_are_recognised_exactly() {
        assert!(is_temporary_of(".scene.exr.a1B2c3.tmp", "scene.exr"));
        assert!(!is_temporary_of(".scene.exr.a1B2c.tmp", "scene.exr"));
        assert!(!is_temporary_of(".scene.exr.a1-2c3.tmp", "scene.exr"));
        assert!(!is_temporary_of(".other.exr.a1B2c3.tmp", "scene.exr"));
        assert!(!is_temporary_of("scene.exr", "scene.exr"));
        assert!(!is_temporary_of(".scene.exr.a1B2c3.tmp.keep", "scene.exr"));
    }

    #[cfg(unix)]
    #[test]
    fn stale_files_go_and_live_ones_stay() {
        use fs4::fs_std::FileExt;
        let dir = tempfile::tempdir().unwrap();
        let stale = dir.path().join(".a.exr.AAAAAA.tmp");
        let live = dir.path().join(".a.exr.BBBBBB.tmp");
        let other = dir.path().join(".b.exr.CCCCCC.tmp");
        let output = dir.path().join("a.exr");
        for p in [&stale, &live, &other, &output] {
            std::fs::write(p, "x").unwrap();
        }
        // a live writer holds its lock (another open file description, as another process would)
        let holder = File::open(&live).unwrap();
        assert!(holder.try_lock_exclusive().unwrap());
        assert_eq!(remove_stale(dir.path(), "a.exr"), 1);
        assert!(!stale.exists());
        assert!(live.exists() && other.exists() && output.exists());
        drop(holder);
        assert_eq!(remove_stale(dir.path(), "a.exr"), 1);
        assert!(!live.exists());
    }

    #[test]
    fn registered_files_are_listed_while_alive() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.tmp");
        let (file, registered) = create_temporary(&path).unwrap();
        assert!(live_temporaries().contains(&path));
        assert!(lock_as_alive(&file, &path).unwrap());
        assert!(create_temporary(&path).is_err(), "an existing file is never reused");
        drop(registered);
        assert!(!live_temporaries().contains(&path));
    }
}
