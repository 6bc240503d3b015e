//! What the STL, OFF and glTF readers share: the size limits, bounded whole-file reading and
//! fallible reservation.

use std::io::Read;
use std::path::Path;

/// The largest mesh file (or glTF buffer total) read: 16 GiB. A larger file is refused with a
/// message before anything is allocated.
pub const MAX_MESH_FILE_BYTES: u64 = 16 << 30;

/// The longest line of a text mesh file (ASCII STL, OFF): 1 MiB. A longer line is refused
/// (a binary file read as text, or a hostile one), so a line is never read unbounded.
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// The largest mesh file read: [`crate::resources::INPUT_LIMIT_VAR`] where set (the limit of
/// every input file), else [`MAX_MESH_FILE_BYTES`].
pub(super) fn mesh_limit() -> Result<u64, String> {
    crate::resources::input_limit_or(MAX_MESH_FILE_BYTES).map_err(|e| e.to_string())
}

/// The length of `path`, checked without opening it (a FIFO is never waited on) to be a regular
/// file within [`mesh_limit`]; the error is the message (with how to raise the limit).
pub(super) fn file_len(path: &Path) -> Result<u64, String> {
    let limit = mesh_limit()?;
    crate::resources::check_input_path(path, "mesh file", limit, "mesh files").map_err(|e| e.to_string())
}

/// Refuses a size over [`mesh_limit`].
pub(super) fn check_size(len: u64) -> Result<(), String> {
    let limit = mesh_limit()?;
    if len > limit {
        return Err(format!(
            "{len} bytes: larger than the limit of {} ({limit} bytes) for mesh files; set {} to a larger \
             number of bytes to read it",
            crate::resources::human_bytes(limit),
            crate::resources::INPUT_LIMIT_VAR
        ));
    }
    Ok(())
}

/// Reads all of `path` (at most [`mesh_limit`]), reserving the buffer fallibly.
pub(super) fn read_all(path: &Path) -> Result<Vec<u8>, String> {
    let len = file_len(path)?;
    let mut file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut bytes = Vec::new();
    reserve(&mut bytes, len, "the file")?;
    file.by_ref()
        .take(mesh_limit()?.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| e.to_string())?;
    check_size(bytes.len() as u64)?;
    Ok(bytes)
}

/// Reserves room for `n` more items of `v`, or says which `what` did not fit.
pub(super) fn reserve<T>(v: &mut Vec<T>, n: u64, what: &str) -> Result<(), String> {
    let n = usize::try_from(n).map_err(|_| format!("{what}: {n} items do not fit in memory"))?;
    v.try_reserve(n)
        .map_err(|_| format!("{what}: {n} items do not fit in memory"))
}
