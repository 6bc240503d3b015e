//! What the STL, OFF and glTF readers share: the size limit, bounded line reading with line
//! numbers and byte offsets, fallible reservation, and exact vertex welding.

use std::io::{BufRead, Read};
use std::path::Path;

/// The largest mesh file (or glTF buffer total) read: 16 GiB. A larger file is refused with a
/// message before anything is allocated.
pub const MAX_MESH_FILE_BYTES: u64 = 16 << 30;

/// The longest line of a text mesh file (ASCII STL, OFF): 1 MiB. A longer line is refused
/// (a binary file read as text, or a hostile one), so a line is never read unbounded.
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// The length of `path`, checked against [`MAX_MESH_FILE_BYTES`]; the error is the message.
pub(super) fn file_len(path: &Path) -> Result<u64, String> {
    let len = std::fs::metadata(path).map_err(|e| e.to_string())?.len();
    check_size(len)?;
    Ok(len)
}

/// Refuses a size over [`MAX_MESH_FILE_BYTES`].
pub(super) fn check_size(len: u64) -> Result<(), String> {
    if len > MAX_MESH_FILE_BYTES {
        return Err(format!(
            "{len} bytes: larger than the {} GiB limit of mesh files",
            MAX_MESH_FILE_BYTES >> 30
        ));
    }
    Ok(())
}

/// Reads all of `path` (at most [`MAX_MESH_FILE_BYTES`]), reserving the buffer fallibly.
pub(super) fn read_all(path: &Path) -> Result<Vec<u8>, String> {
    let len = file_len(path)?;
    let mut file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut bytes = Vec::new();
    reserve(&mut bytes, len, "the file")?;
    file.by_ref()
        .take(MAX_MESH_FILE_BYTES + 1)
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

/// A text file read line by line, each line bounded by [`MAX_LINE_BYTES`], with the current
/// line's number (from 1) and byte offset.
pub(super) struct Lines<R> {
    reader: R,
    /// The number of the line last read (1 for the first).
    pub line: u64,
    /// The byte offset where the line last read starts.
    pub offset: u64,
    next_offset: u64,
}

impl<R: BufRead> Lines<R> {
    pub fn new(reader: R) -> Self {
        Self {
            reader,
            line: 0,
            offset: 0,
            next_offset: 0,
        }
    }

    /// Where the last line is: `line N (byte B)`.
    pub fn at(&self) -> String {
        format!("line {} (byte {})", self.line, self.offset)
    }

    /// The next line without its line ending (`None` at the end of the file). A line that is not
    /// UTF-8 or longer than [`MAX_LINE_BYTES`] is an error naming it.
    pub fn next_line<'b>(&mut self, buf: &'b mut Vec<u8>) -> Result<Option<&'b str>, String> {
        buf.clear();
        self.line += 1;
        self.offset = self.next_offset;
        let n = (&mut self.reader)
            .take(MAX_LINE_BYTES as u64 + 1)
            .read_until(b'\n', buf)
            .map_err(|e| format!("{}: {e}", self.at()))?;
        if n == 0 {
            return Ok(None);
        }
        self.next_offset += n as u64;
        if n > MAX_LINE_BYTES && buf.last() != Some(&b'\n') {
            return Err(format!(
                "{}: longer than {MAX_LINE_BYTES} bytes (a binary file, or not this format?)",
                self.at()
            ));
        }
        while matches!(buf.last(), Some(b'\n' | b'\r')) {
            buf.pop();
        }
        std::str::from_utf8(buf)
            .map(Some)
            .map_err(|_| format!("{}: not text (invalid UTF-8)", self.at()))
    }
}

/// Parses a finite `f32` coordinate token; the error names `what`.
pub(super) fn coordinate(token: Option<&str>, what: &str) -> Result<f32, String> {
    let token = token.ok_or_else(|| format!("{what}: missing"))?;
    let x: f32 = token
        .parse()
        .map_err(|_| format!("{what}: `{token}` is not a number"))?;
    if !x.is_finite() {
        return Err(format!("{what}: `{token}` is not finite"));
    }
    Ok(x)
}

/// Exact vertex welding: positions whose coordinates compare equal become one vertex.
///
/// Equality is `f32` equality of each coordinate: bit-equal positions, and also `-0.0` against
/// `0.0` (the same point; keeping them apart would open a crack along every edge through it).
/// The welded vertex keeps the first occurrence's bits. Positions must be finite (the readers
/// refuse NaN before welding). An open-addressing table of vertex indices, grown at half full.
pub(super) struct Welder {
    /// The welded vertices, in order of first occurrence.
    pub vertices: Vec<[f32; 3]>,
    slots: Vec<u32>,
    mask: usize,
    /// Corners seen.
    pub corners: u64,
}

const EMPTY: u32 = u32::MAX;

/// The key of a position: its bits with `-0.0` made `+0.0`.
#[inline(always)]
fn key(p: [f32; 3]) -> [u32; 3] {
    p.map(|x| (x + 0.0).to_bits())
}

#[inline(always)]
fn hash(k: [u32; 3]) -> usize {
    let a = u64::from(k[0]) | (u64::from(k[1]) << 32);
    let h = (a ^ (a >> 29)).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ u64::from(k[2]);
    let h = h.wrapping_mul(0xD6E8_FEB8_6659_FD93);
    (h ^ (h >> 32)) as usize
}

impl Welder {
    /// A welder expecting about `vertices` distinct positions.
    pub fn with_capacity(vertices: u64) -> Result<Self, String> {
        let want = vertices.clamp(16, 1 << 31).next_power_of_two() * 2;
        let mut slots = Vec::new();
        reserve(&mut slots, want, "vertex table")?;
        slots.resize(want as usize, EMPTY);
        let mut out = Vec::new();
        reserve(&mut out, vertices.min(1 << 28), "vertices")?;
        Ok(Self {
            vertices: out,
            slots,
            mask: want as usize - 1,
            corners: 0,
        })
    }

    /// The index of `p`, added if new. Errors past 2³² − 1 vertices or when memory runs out.
    #[inline]
    pub fn index(&mut self, p: [f32; 3]) -> Result<u32, String> {
        self.corners += 1;
        let k = key(p);
        let mut i = hash(k) & self.mask;
        loop {
            let s = self.slots[i];
            if s == EMPTY {
                break;
            }
            if key(self.vertices[s as usize]) == k {
                return Ok(s);
            }
            i = (i + 1) & self.mask;
        }
        let n = self.vertices.len();
        if n >= EMPTY as usize - 1 {
            return Err("more than 2³² − 2 distinct vertices".into());
        }
        if self.vertices.len() == self.vertices.capacity() {
            reserve(&mut self.vertices, n.max(16) as u64, "vertices")?;
        }
        self.vertices.push(p);
        self.slots[i] = n as u32;
        if 2 * (n + 1) > self.slots.len() {
            self.grow()?;
        }
        Ok(n as u32)
    }

    fn grow(&mut self) -> Result<(), String> {
        let size = self.slots.len() * 2;
        let mut slots = Vec::new();
        reserve(&mut slots, size as u64, "vertex table")?;
        slots.resize(size, EMPTY);
        let mask = size - 1;
        for (n, v) in self.vertices.iter().enumerate() {
            let mut i = hash(key(*v)) & mask;
            while slots[i] != EMPTY {
                i = (i + 1) & mask;
            }
            slots[i] = n as u32;
        }
        self.slots = slots;
        self.mask = mask;
        Ok(())
    }

    /// Corners merged into an earlier vertex (corners − distinct vertices).
    pub fn merged(&self) -> u64 {
        self.corners - self.vertices.len() as u64
    }
}
