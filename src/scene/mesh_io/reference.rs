//! The text readers as they were before they were cut into blocks and parallel pieces (line by
//! line through a `BufRead`, one hash-table lookup per corner), kept for the tests as the
//! reference the faster readers must agree with, result for result and message for message.

use super::shared::{file_len, reserve, MAX_LINE_BYTES};
use super::MeshData;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

/// An STL file read and welded.
pub(super) struct Stl {
    pub data: MeshData,
    pub corners: u64,
    pub merged: u64,
    pub ascii: bool,
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

/// Reads a binary STL of `len` bytes.
pub(super) fn read_binary(path: &Path, len: u64) -> Result<Stl, String> {
    if len < 84 {
        return Err(format!(
            "binary STL: {len} bytes, shorter than the 84-byte header and count (truncated, or not an STL file?)"
        ));
    }
    let mut reader = BufReader::with_capacity(1 << 20, std::fs::File::open(path).map_err(|e| e.to_string())?);
    let mut head = [0u8; 84];
    reader.read_exact(&mut head).map_err(|e| e.to_string())?;
    let n = u32::from_le_bytes([head[80], head[81], head[82], head[83]]);
    let want = 84 + 50 * u64::from(n);
    if want != len {
        let held = (len - 84) / 50;
        let place = if want > len {
            format!(
                "triangle {held} at byte {} is cut off (truncated, or a wrong count)",
                84 + 50 * held
            )
        } else {
            format!("{} bytes follow the last triangle", len - want)
        };
        return Err(format!(
            "binary STL: the count at byte 80 says {n} triangles ({want} bytes), the file has {len} bytes: {place}"
        ));
    }
    if n == 0 {
        return Err("binary STL: the count at byte 80 is 0 triangles".into());
    }
    let mut indices = Vec::new();
    reserve(&mut indices, u64::from(n), "binary STL triangles")?;
    // a closed mesh has about n / 2 vertices
    let mut welder = Welder::with_capacity(u64::from(n) / 2 + 3)?;
    let mut record = [0u8; 50];
    for t in 0..u64::from(n) {
        reader
            .read_exact(&mut record)
            .map_err(|e| format!("binary STL: triangle {t} at byte {}: {e}", 84 + 50 * t))?;
        let mut tri = [0u32; 3];
        for (c, slot) in tri.iter_mut().enumerate() {
            let at = 12 + 12 * c;
            let p: [f32; 3] = std::array::from_fn(|k| {
                let b = at + 4 * k;
                f32::from_le_bytes([record[b], record[b + 1], record[b + 2], record[b + 3]])
            });
            if !p.iter().all(|x| x.is_finite()) {
                return Err(format!(
                    "binary STL: triangle {t} at byte {}: corner {c} {p:?} is not finite",
                    84 + 50 * t
                ));
            }
            *slot = welder.index(p).map_err(|e| format!("binary STL: triangle {t}: {e}"))?;
        }
        indices.push(tri);
    }
    Ok(finish(welder, indices, false))
}

fn finish(welder: Welder, indices: Vec<[u32; 3]>, ascii: bool) -> Stl {
    let (corners, merged) = (welder.corners, welder.merged());
    Stl {
        data: MeshData {
            vertices: welder.vertices,
            indices,
            normals: None,
        },
        corners,
        merged,
        ascii,
    }
}

/// What the ASCII reader expects next.
#[derive(Clone, Copy, PartialEq)]
enum Expect {
    Solid,
    FacetOrEnd,
    OuterLoop,
    Vertex(usize),
    EndLoop,
    EndFacet,
}

/// Reads an ASCII STL, streamed line by line.
pub(super) fn read_ascii(path: &Path) -> Result<Stl, String> {
    let len = file_len(path)?;
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut lines = Lines::new(BufReader::with_capacity(1 << 20, file));
    let mut buf = Vec::with_capacity(256);
    // a facet takes at least 7 lines of ~100 bytes; reserve for what the size allows
    let guess = len / 200;
    let mut indices: Vec<[u32; 3]> = Vec::new();
    reserve(&mut indices, guess, "ASCII STL triangles")?;
    let mut welder = Welder::with_capacity(guess / 2 + 3)?;
    let mut expect = Expect::Solid;
    let mut tri = [0u32; 3];
    let mut solids = 0usize;
    loop {
        let line = match lines.next_line(&mut buf) {
            Ok(Some(line)) => line,
            Ok(None) => break,
            Err(e) => return Err(format!("ASCII STL: {e}")),
        };
        let mut tokens = line.split_ascii_whitespace();
        let Some(word) = tokens.next() else { continue };
        let word_is = |w: &str| word.eq_ignore_ascii_case(w);
        let ok = match expect {
            Expect::Solid => word_is("solid"),
            Expect::FacetOrEnd => word_is("facet") || word_is("endsolid"),
            Expect::OuterLoop => word_is("outer") && tokens.next().is_some_and(|w| w.eq_ignore_ascii_case("loop")),
            Expect::Vertex(_) => word_is("vertex"),
            Expect::EndLoop => word_is("endloop"),
            Expect::EndFacet => word_is("endfacet"),
        };
        if !ok {
            let wanted = match expect {
                Expect::Solid => "`solid`",
                Expect::FacetOrEnd => "`facet normal` or `endsolid`",
                Expect::OuterLoop => "`outer loop`",
                Expect::Vertex(_) => "`vertex x y z`",
                Expect::EndLoop => "`endloop` (a facet has 3 vertices)",
                Expect::EndFacet => "`endfacet`",
            };
            return Err(format!(
                "ASCII STL: {}, facet {}: expected {wanted}, found `{}`",
                lines.at(),
                indices.len(),
                clip(line)
            ));
        }
        expect = match expect {
            Expect::Solid => {
                solids += 1;
                Expect::FacetOrEnd
            }
            Expect::FacetOrEnd if word_is("endsolid") => Expect::Solid,
            Expect::FacetOrEnd => Expect::OuterLoop,
            Expect::OuterLoop => Expect::Vertex(0),
            Expect::Vertex(c) => {
                let mut p = [0f32; 3];
                for (k, x) in p.iter_mut().enumerate() {
                    *x = coordinate(tokens.next(), &format!("coordinate {}", ["x", "y", "z"][k]))
                        .map_err(|e| format!("ASCII STL: {}, facet {}, vertex {c}: {e}", lines.at(), indices.len()))?;
                }
                tri[c] = welder.index(p).map_err(|e| format!("ASCII STL: {}: {e}", lines.at()))?;
                if c == 2 {
                    Expect::EndLoop
                } else {
                    Expect::Vertex(c + 1)
                }
            }
            Expect::EndLoop => Expect::EndFacet,
            Expect::EndFacet => {
                if indices.len() == indices.capacity() {
                    let more = indices.len().max(1024) as u64;
                    reserve(&mut indices, more, "ASCII STL triangles")?;
                }
                indices.push(tri);
                Expect::FacetOrEnd
            }
        };
    }
    if expect != Expect::Solid {
        return Err(format!(
            "ASCII STL: line {}: unexpected end of file inside {} (truncated?)",
            lines.line,
            if solids == 0 {
                "the file".to_string()
            } else {
                format!("facet {}", indices.len())
            }
        ));
    }
    if indices.is_empty() {
        return Err("ASCII STL: no facets".into());
    }
    Ok(finish(welder, indices, true))
}

/// The first 40 characters of a line, for messages.
fn clip(line: &str) -> String {
    let mut out: String = line.trim().chars().take(40).collect();
    if line.trim().chars().count() > 40 {
        out.push('…');
    }
    out
}

/// Reads an OFF file.
pub(super) fn read_off(path: &Path) -> Result<MeshData, String> {
    let len = file_len(path)?;
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut lines = Lines::new(BufReader::with_capacity(1 << 20, file));
    let mut buf = Vec::with_capacity(256);
    // the header: a keyword ending in OFF, counts on the same line or the next
    let mut counts: Vec<String> = Vec::new();
    let mut seen_keyword = false;
    while counts.len() < 3 {
        let Some(line) = lines.next_line(&mut buf).map_err(|e| format!("OFF: {e}"))? else {
            return Err(format!(
                "OFF: line {}: unexpected end of file in the header (expected {})",
                lines.line,
                if seen_keyword {
                    "the counts `vertices faces edges`"
                } else {
                    "`OFF`"
                }
            ));
        };
        let body = line.split('#').next().unwrap_or("");
        let mut tokens = body.split_ascii_whitespace().peekable();
        if tokens.peek().is_none() {
            continue;
        }
        if !seen_keyword {
            let word = tokens.next().unwrap_or("");
            let Some(prefix) = word.strip_suffix("OFF") else {
                return Err(format!(
                    "OFF: {}: expected the keyword `OFF`, found `{}` (not an OFF file?)",
                    lines.at(),
                    word.chars().take(20).collect::<String>()
                ));
            };
            if prefix.contains('n') || prefix.contains('4') {
                return Err(format!(
                    "OFF: {}: `{word}` (a dimension other than 3) is not supported",
                    lines.at()
                ));
            }
            if tokens.peek() == Some(&"BINARY") {
                return Err(format!("OFF: {}: binary OFF is not supported", lines.at()));
            }
            seen_keyword = true;
        }
        counts.extend(tokens.map(str::to_string));
    }
    let count = |k: usize, what: &str| -> Result<u64, String> {
        counts[k]
            .parse::<u64>()
            .map_err(|_| format!("OFF: {}: the {what} count `{}` is not a count", lines.at(), counts[k]))
    };
    let (nv, nf) = (count(0, "vertex")?, count(1, "face")?);
    // each vertex line takes at least 6 bytes (`0 0 0\n`), each face line 8 (`3 0 1 2\n`)
    let least = nv.saturating_mul(6).saturating_add(nf.saturating_mul(8));
    if least > len {
        return Err(format!(
            "OFF: {}: the header claims {nv} vertices and {nf} faces, at least {least} bytes, \
             but the file has {len} bytes (a lying count, or truncated)",
            lines.at()
        ));
    }
    if nv > u64::from(u32::MAX) {
        return Err(format!("OFF: {}: {nv} vertices (at most 2³² − 1)", lines.at()));
    }
    if nf == 0 {
        return Err(format!("OFF: {}: the header claims 0 faces", lines.at()));
    }
    let mut vertices: Vec<[f32; 3]> = Vec::new();
    reserve(&mut vertices, nv, "OFF vertices")?;
    let mut indices: Vec<[u32; 3]> = Vec::new();
    reserve(&mut indices, nf, "OFF faces")?;
    let end = |lines: &Lines<_>, what: String| {
        format!(
            "OFF: line {}: unexpected end of file at {what} (the header claims {nv} vertices, {nf} faces; truncated?)",
            lines.line
        )
    };
    let mut v = 0u64;
    while v < nv {
        let Some(line) = lines.next_line(&mut buf).map_err(|e| format!("OFF: {e}"))? else {
            return Err(end(&lines, format!("vertex {v}")));
        };
        let body = line.split('#').next().unwrap_or("");
        let mut tokens = body.split_ascii_whitespace().peekable();
        if tokens.peek().is_none() {
            continue;
        }
        let mut p = [0f32; 3];
        for (k, x) in p.iter_mut().enumerate() {
            *x = coordinate(tokens.next(), ["x", "y", "z"][k])
                .map_err(|e| format!("OFF: {}, vertex {v}: {e}", lines.at()))?;
        }
        vertices.push(p);
        v += 1;
    }
    let mut f = 0u64;
    let mut face: Vec<u32> = Vec::new();
    while f < nf {
        let Some(line) = lines.next_line(&mut buf).map_err(|e| format!("OFF: {e}"))? else {
            return Err(end(&lines, format!("face {f}")));
        };
        let body = line.split('#').next().unwrap_or("");
        let mut tokens = body.split_ascii_whitespace().peekable();
        let Some(first) = tokens.next() else { continue };
        let at = |lines: &Lines<_>| format!("OFF: {}, face {f}", lines.at());
        let n: usize = first
            .parse()
            .map_err(|_| format!("{}: the vertex count `{first}` is not a count", at(&lines)))?;
        if n < 3 {
            return Err(format!("{}: {n} vertex indices (at least 3 needed)", at(&lines)));
        }
        face.clear();
        for k in 0..n {
            let Some(token) = tokens.next() else {
                return Err(format!("{}: {n} vertices announced, {k} given", at(&lines)));
            };
            let i: i64 = token
                .parse()
                .map_err(|_| format!("{}: vertex index `{token}` is not an integer", at(&lines)))?;
            if i < 0 || i as u64 >= nv {
                return Err(format!("{}: vertex index {i} out of range ({nv} vertices)", at(&lines)));
            }
            face.push(i as u32);
        }
        for k in 1..n - 1 {
            if indices.len() == indices.capacity() {
                let more = indices.len() as u64;
                reserve(&mut indices, more, "OFF triangles")?;
            }
            indices.push([face[0], face[k], face[k + 1]]);
        }
        f += 1;
    }
    Ok(MeshData {
        vertices,
        indices,
        normals: None,
    })
}

#[cfg(test)]
mod tests;
