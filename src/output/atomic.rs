//! Files that appear whole or not at all.
//!
//! Every output (EXR, PNG previews, `query` results) is written to a temporary file in the
//! destination's own directory, flushed and `fsync`ed, and only then renamed over the
//! destination. A rename within one file system is atomic (POSIX `rename(2)`), so a reader — or a
//! kill, a Ctrl-C, a full disk at any moment — sees either the previous file or the complete new
//! one, never a truncated mix. The temporary file (`.NAME.XXXXXX.tmp`) is removed on any error or
//! unwind, and on SIGINT, SIGTERM or SIGHUP once the CLI installed its handlers
//! ([`super::interrupt`]); only a SIGKILL can leave one behind, it never has the destination's
//! name, and the next run writing the same destination removes it.
//!
//! [`check_destination`] is the early check run before any tracing: the directory must exist or
//! be creatable and must accept a new file, and its file system must have room for the estimated
//! output.

use super::interrupt::{create_temporary, lock_as_alive, remove_stale, Registered};
use crate::resources::human_bytes;
use anyhow::{bail, Context, Result};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use tempfile::TempPath;

/// A file being written under a temporary name next to `destination`; [`AtomicFile::commit`]
/// renames it into place. Dropped without a commit, it is deleted.
///
/// A destination that is a symbolic link is resolved first (the link keeps pointing at the new
/// file); one that exists and is neither a regular file nor a directory — `/dev/null`, a named
/// pipe, a terminal — is written directly, since it holds nothing to protect and cannot be
/// renamed over.
pub struct AtomicFile {
    target: Target,
    destination: PathBuf,
}

/// Where the bytes go.
enum Target {
    /// A temporary file beside the destination, renamed over it on commit. Its path is deleted
    /// (on drop) before it leaves the registry of live temporary files, and both before the
    /// file is closed (which releases its lock). Fields drop in this order.
    Temporary {
        path: TempPath,
        registered: Registered,
        file: File,
    },
    /// The destination itself (a device or pipe).
    Direct(File),
}

impl AtomicFile {
    /// Creates the temporary file in `destination`'s directory.
    ///
    /// # Errors
    /// The directory cannot be written.
    pub fn create(destination: &Path) -> Result<Self> {
        let destination = &std::fs::canonicalize(destination)
            .ok()
            .filter(|_| destination.is_symlink())
            .unwrap_or_else(|| destination.to_path_buf());
        if let Ok(meta) = std::fs::metadata(destination) {
            if meta.is_dir() {
                bail!("{} is a directory, not a file", destination.display());
            }
            if !meta.is_file() {
                let file = std::fs::OpenOptions::new()
                    .write(true)
                    .open(destination)
                    .with_context(|| format!("opening {}", destination.display()))?;
                return Ok(Self {
                    target: Target::Direct(file),
                    destination: destination.clone(),
                });
            }
        }
        let dir = parent_dir(destination);
        let name = destination
            .file_name()
            .map_or_else(|| "output".to_string(), |n| n.to_string_lossy().into_owned());
        // the temporary files of earlier runs that were killed (their lock is free)
        remove_stale(&dir, &name);
        let (file, path, registered) = new_temporary(&dir, &name)?;
        // a temporary file is private (0600); the result gets the replaced file's permissions,
        // or the usual 0644 for a new file
        let permissions =
            std::fs::metadata(destination).map_or_else(|_| default_permissions(), |m| Some(m.permissions()));
        if let Some(permissions) = permissions {
            file.set_permissions(permissions)
                .with_context(|| format!("setting the permissions of a file in {}", dir.display()))?;
        }
        Ok(Self {
            target: Target::Temporary { file, path, registered },
            destination: destination.clone(),
        })
    }

    /// The open temporary file (or the device written directly).
    pub fn file(&mut self) -> &mut File {
        match &mut self.target {
            Target::Temporary { file, .. } | Target::Direct(file) => file,
        }
    }

    /// The destination path.
    #[must_use]
    pub fn destination(&self) -> &Path {
        &self.destination
    }

    /// Flushes the data to disk and renames the file over the destination.
    ///
    /// # Errors
    /// The `fsync` or the rename fails (the temporary file is then removed).
    pub fn commit(self) -> Result<()> {
        let Target::Temporary { file, path, registered } = self.target else {
            return Ok(());
        };
        file.sync_all()
            .with_context(|| format!("flushing {} to disk", self.destination.display()))?;
        let destination = self.destination;
        // the file stays open (its lock held) until after the rename
        path.persist(&destination)
            .map_err(|e| e.error)
            .with_context(|| format!("renaming the finished file to {}", destination.display()))?;
        drop((registered, file));
        // make the rename itself durable where the platform allows opening a directory
        if let Ok(dir) = File::open(parent_dir(&destination)) {
            let _ = dir.sync_all();
        }
        Ok(())
    }
}

/// A new registered temporary file `.NAME.XXXXXX.tmp` in `dir`, holding its lock.
fn new_temporary(dir: &Path, name: &str) -> Result<(File, TempPath, Registered)> {
    let context = || format!("creating a temporary file in {}", dir.display());
    // another run's stale-file cleanup can delete a file between its creation and its lock
    for _ in 0..16 {
        let temp = tempfile::Builder::new()
            .prefix(&format!(".{name}."))
            .suffix(".tmp")
            .make_in(dir, create_temporary)
            .with_context(context)?;
        let ((file, registered), path) = temp.into_parts();
        if lock_as_alive(&file, &path).with_context(context)? {
            return Ok((file, path, registered));
        }
        // the name was already deleted and may be another file's by now: never delete it again
        let _ = path.keep();
        drop(registered);
    }
    bail!("{}: the temporary file kept disappearing", context())
}

/// Asks the operating system to start writing `file`'s bytes `offset..offset + len` (already
/// handed to it) to disk, without waiting: Linux's `sync_file_range(SYNC_FILE_RANGE_WRITE)`.
/// A large file written this way as it grows finds little left to write at the `fsync` of
/// [`AtomicFile::commit`] (a 265 MB 4K EXR: that `fsync` took 0.47 s after the trace). Nothing
/// elsewhere, and a failure is ignored: the commit's `fsync` is what guarantees the data.
pub fn start_writeback(file: &File, offset: u64, len: u64) {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        if let (Ok(offset), Ok(len)) = (i64::try_from(offset), i64::try_from(len)) {
            // SAFETY: a plain system call on an open descriptor; it reads no memory of ours
            let _ = unsafe { libc::sync_file_range(file.as_raw_fd(), offset, len, libc::SYNC_FILE_RANGE_WRITE) };
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (file, offset, len);
}

/// Bytes between two [`start_writeback`] calls of a [`WritebackFile`].
const WRITEBACK_STEP: u64 = 8 << 20;

/// A file written through [`start_writeback`]: every `WRITEBACK_STEP` bytes written, the new
/// bytes are sent on their way to disk, so that the `fsync` of [`AtomicFile::commit`] finds
/// little left to do (`zeroset query` writing 88 MB of `.npy`: that `fsync` took 0.14 s after the
/// last chunk). Seeking (to patch a header) is passed through.
pub struct WritebackFile<'a> {
    file: &'a File,
    /// Current position in the file.
    position: u64,
    /// Position up to which writeback was started.
    started: u64,
}

impl<'a> WritebackFile<'a> {
    /// Writes to `file` from its current position, assumed to be its start.
    #[must_use]
    pub fn new(file: &'a File) -> Self {
        Self {
            file,
            position: 0,
            started: 0,
        }
    }
}

impl Write for WritebackFile<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let written = self.file.write(buf)?;
        self.position += written as u64;
        if self.position >= self.started + WRITEBACK_STEP {
            start_writeback(self.file, self.started, self.position - self.started);
            self.started = self.position;
        }
        Ok(written)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

impl std::io::Seek for WritebackFile<'_> {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        self.position = std::io::Seek::seek(&mut self.file, pos)?;
        Ok(self.position)
    }
}

/// Permissions of a new output file: `rw-r--r--` on Unix; elsewhere the temporary file's own.
fn default_permissions() -> Option<std::fs::Permissions> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        Some(std::fs::Permissions::from_mode(0o644))
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// Writes `destination` atomically with `write`, which gets a buffered writer on the temporary
/// file.
///
/// # Errors
/// Creating, writing, flushing or renaming fails; the destination is then untouched.
pub fn write_atomically(destination: &Path, write: impl FnOnce(&mut BufWriter<&mut File>) -> Result<()>) -> Result<()> {
    let mut file = AtomicFile::create(destination)?;
    {
        let mut writer = BufWriter::with_capacity(1 << 20, file.file());
        write(&mut writer)?;
        writer
            .flush()
            .with_context(|| format!("writing {}", destination.display()))?;
    }
    file.commit()
}

/// The directory a file path lives in (`.` for a bare name).
#[must_use]
pub fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Refuses, before anything is written, a destination that exists (following links) but is not
/// a regular file: a directory, or a device or FIFO (`-o link.exr` where the link points to
/// `/dev/null`). A render's files are written to a temporary file beside the destination and
/// renamed over it, so only a regular file (or none) can be replaced; such a destination used to
/// fail after the whole render.
///
/// # Errors
/// The destination is not a regular file; the message names it, its link target and its kind.
pub fn require_file_destination(path: &Path) -> Result<()> {
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(());
    };
    if meta.is_file() {
        return Ok(());
    }
    let target = match std::fs::canonicalize(path) {
        Ok(t) if path.is_symlink() => format!(" (a link to {})", t.display()),
        _ => String::new(),
    };
    bail!(
        "{}{target} is {}, not a regular file: outputs are written to a temporary file and renamed \
         over the destination; choose another file name",
        path.display(),
        crate::resources::file_kind(&meta.file_type())
    )
}

/// The early check before tracing: creates `dir` if needed, proves it accepts a new file (by
/// creating and deleting a temporary one), and compares `estimated_bytes` with the space
/// available to this user on its file system.
///
/// # Errors
/// The directory cannot be created or written, or the estimate exceeds the free space.
pub fn check_destination(dir: &Path, estimated_bytes: u64) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating the output directory {}", dir.display()))?;
    let probe = tempfile::Builder::new()
        .prefix(".zeroset-write-check.")
        .make_in(dir, create_temporary)
        .with_context(|| format!("the output directory {} is not writable", dir.display()))?;
    drop(probe);
    // file systems that cannot report free space (some network mounts) are not refused
    if let Ok(available) = fs4::available_space(dir) {
        if estimated_bytes > available {
            bail!(
                "the outputs need about {} but {} has only {} free",
                human_bytes(estimated_bytes),
                dir.display(),
                human_bytes(available)
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commit_replaces_and_drop_leaves_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        std::fs::write(&path, "old").unwrap();
        // an error inside the writer: the old file stays, no temporary file is left
        let failed = write_atomically(&path, |w| {
            w.write_all(b"partial")?;
            bail!("interrupted")
        });
        assert!(failed.is_err());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        write_atomically(&path, |w| Ok(w.write_all(b"new")?)).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[cfg(unix)]
    #[test]
    fn links_are_followed_and_devices_written_directly() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("target.txt");
        let link = dir.path().join("link.txt");
        std::fs::write(&target, "old").unwrap();
        std::os::unix::fs::symlink(&target, &link).unwrap();
        write_atomically(&link, |w| Ok(w.write_all(b"new")?)).unwrap();
        assert!(link.is_symlink(), "the link is kept");
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "new");
        write_atomically(Path::new("/dev/null"), |w| Ok(w.write_all(b"discarded")?)).unwrap();
        let null = std::fs::metadata("/dev/null").unwrap();
        assert!(null.file_type().is_char_device(), "/dev/null is still a device");
        assert!(
            write_atomically(dir.path(), |_| Ok(())).is_err(),
            "a directory is refused"
        );
    }

    #[test]
    fn check_refuses_more_than_the_free_space() {
        let dir = tempfile::tempdir().unwrap();
        check_destination(dir.path(), 1).unwrap();
        let err = check_destination(dir.path(), u64::MAX).unwrap_err().to_string();
        assert!(err.contains("free") && err.contains("TB"), "{err}");
    }
}
