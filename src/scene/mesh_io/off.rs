//! OFF (Object File Format), ASCII, read directly and streamed line by line.
//!
//! A header line `OFF` (also `COFF`, `NOFF`, `CNOFF`, `STOFF`…: colours, normals and texture
//! coordinates after each vertex's `x y z` are ignored), the counts `vertices faces edges` (on
//! the header line or the next), one vertex per line (`x y z …`), then one face per line
//! (`n i₀ … iₙ₋₁`, optionally followed by a colour). `#` starts a comment; blank lines are
//! skipped. Faces of `n > 3` vertices are fanned `(0, i, i + 1)` like PLY polygons. The counts
//! are checked against the file's length before anything is reserved; binary OFF and
//! `nOFF`/`4OFF` (other dimensions) are refused.

use super::shared::{coordinate, file_len, reserve, Lines};
use super::MeshData;
use std::io::BufReader;
use std::path::Path;

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
