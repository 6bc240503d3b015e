//! STL, binary and ASCII, read directly (streamed), corners welded exactly into shared vertices.
//!
//! Binary: an 80-byte header, a little-endian `u32` triangle count `n`, then `n` records of
//! 50 bytes (normal, three corners as `f32` triples, a 2-byte attribute), so the file is exactly
//! `84 + 50·n` bytes. ASCII: `solid name`, facets of `facet normal …` / `outer loop` /
//! three `vertex x y z` / `endloop` / `endfacet`, then `endsolid` (several solids in one file are
//! read as one mesh). Facet normals are ignored (the geometric normal comes from the winding).
//!
//! Which of the two: a file not starting with `solid` is binary. One that does is binary when
//! its size is exactly `84 + 50·n` for the count at byte 80 and it parses as binary (an exporter
//! may write `solid` into a binary header); otherwise it is read as ASCII.
//!
//! Corners are welded with [`Welder`]: equal positions (bit-equal, and `-0.0` with `0.0`) become
//! one vertex, so a closed STL is as watertight as the indexed mesh it was written from.

use super::shared::{coordinate, file_len, reserve, Lines, Welder};
use super::MeshData;
use std::io::{BufReader, Read};
use std::path::Path;

/// An STL file read and welded; `merged` counts the corners merged into earlier vertices.
pub(super) struct Stl {
    pub data: MeshData,
    pub corners: u64,
    pub merged: u64,
    pub ascii: bool,
}

/// Reads an STL file, binary or ASCII by its content (see the module documentation).
pub(super) fn read_stl(path: &Path) -> Result<Stl, String> {
    let len = file_len(path)?;
    let mut file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut head = [0u8; 84];
    let got = read_up_to(&mut file, &mut head)?;
    let starts_solid = head[..got].trim_ascii_start().starts_with(b"solid");
    let count = (got == 84).then(|| u32::from_le_bytes([head[80], head[81], head[82], head[83]]));
    let size_fits = count.is_some_and(|n| 84 + 50 * u64::from(n) == len);
    if starts_solid && !size_fits {
        return read_ascii(path);
    }
    if starts_solid {
        // the size says binary; a parse failure falls back to ASCII (then the binary error is kept)
        return match read_binary(path, len) {
            Ok(stl) => Ok(stl),
            Err(binary) => read_ascii(path).map_err(|_| binary),
        };
    }
    read_binary(path, len)
}

fn read_up_to(file: &mut std::fs::File, buf: &mut [u8]) -> Result<usize, String> {
    let mut got = 0;
    while got < buf.len() {
        match file.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e.to_string()),
        }
    }
    Ok(got)
}

/// Reads a binary STL of `len` bytes.
fn read_binary(path: &Path, len: u64) -> Result<Stl, String> {
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
fn read_ascii(path: &Path) -> Result<Stl, String> {
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
