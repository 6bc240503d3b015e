//! Input files read within a limit (see [`crate::resources`], "Input files"): [`open_input`],
//! [`read_input_to_string`], [`check_input_path`] for readers that open files themselves, and
//! [`BoundedReader`] for streams.

use super::{ensure_memory, human_bytes, NotEnoughMemory, DEFAULT_INPUT_LIMIT, INPUT_LIMIT_VAR};
use std::io::{self, Read};
use std::path::Path;

/// The largest input file read: [`INPUT_LIMIT_VAR`] (a number of bytes) where set, else
/// [`DEFAULT_INPUT_LIMIT`].
///
/// # Errors
/// The variable is set but not a number of bytes.
pub fn input_limit() -> io::Result<u64> {
    match std::env::var(INPUT_LIMIT_VAR) {
        Err(_) => Ok(DEFAULT_INPUT_LIMIT),
        Ok(text) => text.trim().parse().map_err(|_| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("{INPUT_LIMIT_VAR}={text:?} is not a number of bytes"),
            )
        }),
    }
}

/// An input file opened for a bounded read ([`open_input`]).
#[derive(Debug)]
pub struct InputFile {
    file: std::fs::File,
    len: u64,
    limit: u64,
    what: String,
}

/// Opens `path`, a `what` ("scene file", "pose file"), for a bounded read: a regular file of at
/// most [`input_limit`] bytes. Nothing waits on a FIFO (it is opened without blocking, then
/// refused like a device, a socket or a directory).
///
/// # Errors
/// The file cannot be opened, is not a regular file, or is over the limit (the message gives
/// its size, the limit and how to raise it); the path is the caller's to add.
pub fn open_input(path: &Path, what: &str) -> io::Result<InputFile> {
    let limit = input_limit()?;
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::fs::OpenOptionsExt;
        // a FIFO without a writer would block `open` for ever; regular files ignore the flag
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path)?;
    let kind = file.metadata()?.file_type();
    if !kind.is_file() {
        return Err(not_regular(what, &kind));
    }
    let len = file.metadata()?.len();
    let input = InputFile {
        file,
        len,
        limit,
        what: what.to_string(),
    };
    if len > limit {
        return Err(input.too_large(&format!("is {} ({len} bytes)", human_bytes(len))));
    }
    Ok(input)
}

/// Checks, without opening it (which could wait on a FIFO), that `path`, a `what`, is a regular
/// file of at most `limit` bytes (`limit_name` names the limit in the message: "input files",
/// "mesh files"); returns its length. For readers that open the file themselves.
///
/// # Errors
/// As [`open_input`]: not a regular file, or over the limit (with how to raise it).
pub fn check_input_path(path: &Path, what: &str, limit: u64, limit_name: &str) -> io::Result<u64> {
    let metadata = std::fs::metadata(path)?;
    let kind = metadata.file_type();
    if !kind.is_file() {
        return Err(not_regular(what, &kind));
    }
    let len = metadata.len();
    if len > limit {
        return Err(over_limit(
            what,
            &format!("is {} ({len} bytes)", human_bytes(len)),
            limit,
            limit_name,
        ));
    }
    Ok(len)
}

/// The input limit where [`INPUT_LIMIT_VAR`] is set, else `default` (a reader whose files are
/// commonly larger than [`DEFAULT_INPUT_LIMIT`], such as meshes, has its own default).
///
/// # Errors
/// The variable is set but not a number of bytes.
pub fn input_limit_or(default: u64) -> io::Result<u64> {
    if std::env::var_os(INPUT_LIMIT_VAR).is_some() {
        input_limit()
    } else {
        Ok(default)
    }
}

fn not_regular(what: &str, kind: &std::fs::FileType) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidInput,
        format!(
            "not a regular file but {}: a {what} must be a regular file (a device or FIFO may never \
             end, or wait for ever)",
            file_kind(kind)
        ),
    )
}

fn over_limit(what: &str, state: &str, limit: u64, limit_name: &str) -> io::Error {
    io::Error::new(
        io::ErrorKind::FileTooLarge,
        format!(
            "the {what} {state}, over the limit of {} ({limit} bytes) for {limit_name}; set \
             {INPUT_LIMIT_VAR} to a larger number of bytes to read it",
            human_bytes(limit),
        ),
    )
}

/// A reader of an input that ends with an error once more than its limit was read (a file that
/// grew since it was checked, an endless stream): see [`InputFile::into_reader`].
#[derive(Debug)]
pub struct BoundedReader<R> {
    inner: R,
    read: u64,
    limit: u64,
    what: String,
}

impl<R: Read> BoundedReader<R> {
    /// `inner`, a `what` ("ray file", "standard input"), read up to `limit` bytes.
    pub fn new(inner: R, what: &str, limit: u64) -> Self {
        Self {
            inner,
            read: 0,
            limit,
            what: what.to_string(),
        }
    }
}

impl<R: Read> Read for BoundedReader<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        // one byte past the limit may be read: it tells a file of exactly the limit from a longer one
        let room = self.limit.saturating_add(1).saturating_sub(self.read);
        let want = buf.len().min(usize::try_from(room).unwrap_or(usize::MAX));
        let n = self.inner.read(&mut buf[..want])?;
        self.read += n as u64;
        if self.read > self.limit {
            let state = format!("went on past {} read", human_bytes(self.limit));
            return Err(over_limit(&self.what, &state, self.limit, "input files"));
        }
        Ok(n)
    }
}

/// "a directory", "a FIFO", … for a message.
pub fn file_kind(kind: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if kind.is_char_device() {
            return "a character device";
        }
        if kind.is_block_device() {
            return "a block device";
        }
        if kind.is_socket() {
            return "a socket";
        }
    }
    if kind.is_dir() {
        "a directory"
    } else {
        "not a file"
    }
}

impl InputFile {
    /// The file's length when it was opened.
    #[must_use]
    pub fn len(&self) -> u64 {
        self.len
    }

    /// Whether the file was empty when it was opened.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The file as a reader that ends one byte past the limit (a file that grew past it since it
    /// was opened then reads too long, which [`InputFile::read_to_string`] refuses).
    pub fn reader(&mut self) -> impl Read + '_ {
        (&mut self.file).take(self.limit.saturating_add(1))
    }

    /// The whole file as text, at most the limit, its buffer checked against the memory room and
    /// reserved fallibly.
    ///
    /// # Errors
    /// A read error, text that is not UTF-8, more than the limit read, or no memory for it.
    pub fn read_to_string(mut self) -> io::Result<String> {
        let what = format!("reading the {} ({})", self.what, human_bytes(self.len));
        let len = usize::try_from(self.len).unwrap_or(usize::MAX);
        let mut bytes = Vec::new();
        ensure_memory(&what, self.len)
            .and_then(|()| {
                bytes.try_reserve_exact(len).map_err(|_| NotEnoughMemory {
                    what: what.clone(),
                    needed: self.len,
                    room: None,
                })
            })
            .map_err(|e| io::Error::new(io::ErrorKind::OutOfMemory, e.to_string()))?;
        self.reader().read_to_end(&mut bytes)?;
        if bytes.len() as u64 > self.limit {
            return Err(self.too_large("grew while it was read"));
        }
        String::from_utf8(bytes).map_err(|e| {
            io::Error::new(
                io::ErrorKind::InvalidData,
                format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
            )
        })
    }

    fn too_large(&self, state: &str) -> io::Error {
        over_limit(&self.what, state, self.limit, "input files")
    }

    /// The file as an owned reader that fails once more than the limit was read (a file that
    /// grew since it was opened), for a reader that streams it.
    #[must_use]
    pub fn into_reader(self) -> BoundedReader<std::fs::File> {
        BoundedReader::new(self.file, &self.what, self.limit)
    }
}

/// The whole of `path`, a `what`, as text: [`open_input`] then [`InputFile::read_to_string`].
///
/// # Errors
/// As those two.
pub fn read_input_to_string(path: &Path, what: &str) -> io::Result<String> {
    open_input(path, what)?.read_to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(target_os = "linux")]
    #[test]
    fn devices_fifos_and_directories_are_refused_without_waiting() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("fifo");
        let c_path = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid C string; mkfifo only creates the node
        assert_eq!(unsafe { libc::mkfifo(c_path.as_ptr(), 0o600) }, 0);
        for (path, kind) in [
            (Path::new("/dev/zero"), "a character device"),
            (fifo.as_path(), "a FIFO"),
            (dir.path(), "a directory"),
        ] {
            let err = read_input_to_string(path, "scene file").unwrap_err().to_string();
            assert!(
                err.contains(kind) && err.contains("a scene file must be a regular file"),
                "{err}"
            );
        }
    }

    #[test]
    fn regular_files_are_read_within_the_limit() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scene.ron");
        std::fs::write(&path, "Scene()").unwrap();
        assert_eq!(read_input_to_string(&path, "scene file").unwrap(), "Scene()");
        let input = open_input(&path, "scene file").unwrap();
        assert_eq!((input.len(), input.is_empty()), (7, false));
        // over a limit of 4 bytes (the file as opened, then one that grew since)
        let small = InputFile { limit: 4, ..input };
        let err = small.too_large("is 7 B (7 bytes)").to_string();
        assert!(
            err.contains("the scene file is 7 B")
                && err.contains("limit of 4 B (4 bytes)")
                && err.contains(INPUT_LIMIT_VAR),
            "{err}"
        );
        let err = small.read_to_string().unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::FileTooLarge, "{err}");
    }

    /// A stream read through the bound fails once it goes past the limit, naming the input, the
    /// limit and the variable; one of exactly the limit reads whole.
    #[test]
    fn streams_end_with_an_error_past_the_limit() {
        let mut exact = String::new();
        BoundedReader::new(&b"0123456789"[..], "ray file", 10)
            .read_to_string(&mut exact)
            .unwrap();
        assert_eq!(exact, "0123456789");
        let mut sink = Vec::new();
        let err = BoundedReader::new(std::io::repeat(b'0'), "ray file", 1000)
            .read_to_end(&mut sink)
            .unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::FileTooLarge);
        let message = err.to_string();
        assert!(
            message.starts_with("the ray file went on past 1.0 kB read, over the limit of 1.0 kB (1000 bytes)")
                && message.contains(INPUT_LIMIT_VAR),
            "{message}"
        );
        assert!(sink.len() <= 1001, "{} bytes kept", sink.len());
    }

    /// Paths are checked without being opened: a regular file's length, refusals for a
    /// directory and a file over the limit.
    #[test]
    fn paths_are_checked_without_opening() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mesh.obj");
        std::fs::write(&path, "v 0 0 0\n").unwrap();
        assert_eq!(check_input_path(&path, "mesh file", 8, "mesh files").unwrap(), 8);
        let err = check_input_path(&path, "mesh file", 7, "mesh files")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("the mesh file is 8 B (8 bytes), over the limit of 7 B (7 bytes) for mesh files"),
            "{err}"
        );
        let err = check_input_path(dir.path(), "mesh file", 7, "mesh files")
            .unwrap_err()
            .to_string();
        assert!(err.contains("not a regular file but a directory"), "{err}");
    }
}
