//! OFF (Object File Format), ASCII, read directly and streamed in blocks of lines.
//!
//! A header line `OFF` (also `COFF`, `NOFF`, `CNOFF`, `STOFF`…: colours, normals and texture
//! coordinates after each vertex's `x y z` are ignored), the counts `vertices faces edges` (on
//! the header line or the next), one vertex per line (`x y z …`), then one face per line
//! (`n i₀ … iₙ₋₁`, optionally followed by a colour). `#` starts a comment; blank lines are
//! skipped. Faces of `n > 3` vertices are fanned `(0, i, i + 1)` like PLY polygons. The counts
//! are checked against the file's length before anything is reserved; binary OFF and
//! `nOFF`/`4OFF` (other dimensions) are refused. Reading stops after the last face.
//!
//! The file is read in blocks of whole lines (`text::for_each_block`). A block is parsed in
//! parallel pieces: the pieces' line ends are counted first, so each piece knows its first line's
//! number and, where no line before it in the block is blank or a comment, whether each of its
//! lines is a vertex or a face; then the pieces are parsed, and the first error in the file's
//! order is the one reported. A block where a blank or comment line upsets that count is parsed
//! again in one piece.

use super::shared::{file_len, reserve};
use super::text::{
    coordinate, for_each_block, parse_i64, parse_u64, piece_count, piece_starts, show, Cuts, Fast, TextLines, Tokens,
    CUTS,
};
use super::MeshData;
use rayon::prelude::*;
use std::path::Path;

/// The header read so far.
#[derive(Default)]
struct Header {
    seen_keyword: bool,
    counts: Vec<String>,
    /// Lines read.
    lines: u64,
}

/// The vertices and faces: the counts, what is read, the lines and lines with content before.
struct Body {
    nv: u64,
    nf: u64,
    data: MeshData,
    lines: u64,
    content: u64,
}

/// What a piece of a block holds: its vertices and triangles, or the first error in it.
#[derive(Default)]
struct Piece {
    vertices: Vec<[f32; 3]>,
    indices: Vec<[u32; 3]>,
    error: Option<String>,
    /// The lines, and lines with content, read.
    read: (u64, u64),
}

/// Reads an OFF file.
pub(super) fn read_off(path: &Path) -> Result<MeshData, String> {
    read_off_cut(path, CUTS)
}

/// Reads an OFF file, cut as `cuts` says.
pub(super) fn read_off_cut(path: &Path, cuts: Cuts) -> Result<MeshData, String> {
    let len = file_len(path)?;
    let mut header = Header::default();
    let mut body: Option<Body> = None;
    let mut pieces: Vec<Piece> = Vec::new();
    for_each_block(path, cuts.block, |block, offset| {
        let body = match &mut body {
            Some(body) => body,
            None => {
                let mut lines = TextLines::new(block, offset, header.lines);
                let Some(read) = read_header(&mut header, &mut lines, len)? else {
                    header.lines = lines.line - 1;
                    return Ok(true);
                };
                let start = lines.consumed();
                let body = body.insert(read);
                read_body(body, &block[start..], offset + start as u64, cuts.piece, &mut pieces)?;
                return Ok(body.content < body.nv + body.nf);
            }
        };
        read_body(body, block, offset, cuts.piece, &mut pieces)?;
        Ok(body.content < body.nv + body.nf)
    })?;
    let Some(body) = body else {
        return Err(format!(
            "OFF: line {}: unexpected end of file in the header (expected {})",
            header.lines + 1,
            if header.seen_keyword {
                "the counts `vertices faces edges`"
            } else {
                "`OFF`"
            }
        ));
    };
    let (nv, nf) = (body.nv, body.nf);
    if body.content < nv + nf {
        let at = if body.content < nv {
            format!("vertex {}", body.content)
        } else {
            format!("face {}", body.content - nv)
        };
        return Err(format!(
            "OFF: line {}: unexpected end of file at {at} (the header claims {nv} vertices, {nf} faces; truncated?)",
            body.lines + 1
        ));
    }
    Ok(body.data)
}

/// Reads header lines until the counts are complete (then the body, its arrays reserved), or
/// the lines end (`None`).
fn read_header(header: &mut Header, lines: &mut TextLines, len: u64) -> Result<Option<Body>, String> {
    // a keyword ending in OFF, counts on the same line or the next
    while header.counts.len() < 3 {
        let Some(line) = lines.next_line().map_err(|e| format!("OFF: {e}"))? else {
            return Ok(None);
        };
        let body = line.split('#').next().unwrap_or("");
        let mut tokens = body.split_ascii_whitespace().peekable();
        if tokens.peek().is_none() {
            continue;
        }
        if !header.seen_keyword {
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
            header.seen_keyword = true;
        }
        header.counts.extend(tokens.map(str::to_string));
    }
    let counts = &header.counts;
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
    let mut data = MeshData::default();
    reserve(&mut data.vertices, nv, "OFF vertices")?;
    reserve(&mut data.indices, nf, "OFF faces")?;
    Ok(Some(Body {
        nv,
        nf,
        data,
        lines: lines.line,
        content: 0,
    }))
}

/// The lines of `text` (whole lines, the last perhaps without its line end).
fn count_lines(text: &[u8]) -> u64 {
    let ends = memchr::memchr_iter(b'\n', text).count() as u64;
    ends + u64::from(text.last().is_some_and(|&c| c != b'\n'))
}

/// Reads the vertex and face lines of a block (at byte `offset`) into `body`, in pieces of about
/// `piece` bytes.
///
/// The pieces are parsed in parallel, each assuming that every line before it in the block has
/// content (lines are counted fast; OFF bodies rarely hold blank or comment lines). That holds
/// where no piece before has a line without content among those it read; where it fails, the
/// block is parsed again in one piece.
fn read_body(body: &mut Body, block: &[u8], offset: u64, piece: usize, pieces: &mut Vec<Piece>) -> Result<(), String> {
    let starts = piece_starts(block, piece_count(block.len(), piece), |_| true);
    let mut ranges: Vec<(usize, usize)> = starts.windows(2).map(|w| (w[0], w[1])).collect();
    let total = body.nv + body.nf;
    loop {
        let counts: Vec<u64> = if ranges.len() > 1 {
            ranges.par_iter().map(|&(a, b)| count_lines(&block[a..b])).collect()
        } else {
            vec![0]
        };
        // each piece's first line number and (assumed) first content line
        let firsts: Vec<(u64, u64)> = counts
            .iter()
            .scan((body.lines, body.content), |at, &n| {
                let first = *at;
                *at = (at.0 + n, at.1 + n);
                Some(first)
            })
            .collect();
        pieces.resize_with(ranges.len(), Piece::default);
        let nv = body.nv;
        pieces
            .par_iter_mut()
            .zip(ranges.par_iter().zip(&firsts))
            .for_each(|(piece, (&(a, b), &(lines, content)))| {
                piece.vertices.clear();
                piece.indices.clear();
                piece.error = None;
                piece.read = (0, 0);
                if content < total {
                    let mut lines = TextLines::new(&block[a..b], offset + a as u64, lines);
                    if let Err(e) = read_lines(&mut lines, content, nv, total, piece) {
                        piece.error = Some(e);
                    }
                }
            });
        let last = pieces.len() - 1;
        let assumed = pieces.iter().enumerate().all(|(k, piece)| {
            let done = firsts[k].1 >= total || piece.error.is_some() || firsts[k].1 + piece.read.1 >= total;
            k == last || done || piece.read.0 == piece.read.1
        });
        if !assumed && ranges.len() > 1 {
            ranges = vec![(0, block.len())];
            continue;
        }
        for (piece, &(_, content)) in pieces.iter().zip(&firsts) {
            if content >= total {
                break;
            }
            if let Some(e) = &piece.error {
                return Err(e.clone());
            }
            reserve(&mut body.data.vertices, piece.vertices.len() as u64, "OFF vertices")?;
            body.data.vertices.extend_from_slice(&piece.vertices);
            reserve(&mut body.data.indices, piece.indices.len() as u64, "OFF triangles")?;
            body.data.indices.extend_from_slice(&piece.indices);
            body.lines += piece.read.0;
            body.content += piece.read.1;
        }
        return Ok(());
    }
}

/// Reads the lines of a piece whose first content line is `content` (vertices below `nv`, faces
/// up to `total`) into `piece`, counting the lines and content lines read in `piece.read`.
fn read_lines(lines: &mut TextLines, mut content: u64, nv: u64, total: u64, piece: &mut Piece) -> Result<(), String> {
    let mut face: Vec<u32> = Vec::new();
    while content < total {
        if let Some(taken) = lines.unread().and_then(|rest| fast_line(rest, content, nv, piece)) {
            lines.skip_line(taken);
            piece.read.0 += 1;
            piece.read.1 += 1;
            content += 1;
            continue;
        }
        let Some(line) = lines.next_line().map_err(|e| format!("OFF: {e}"))? else {
            break;
        };
        piece.read.0 += 1;
        let mut tokens = Tokens::before_comment(line);
        let Some(first) = tokens.next_token() else { continue };
        if content < nv {
            let v = content;
            let mut p = [0f32; 3];
            for (k, x) in p.iter_mut().enumerate() {
                let token = if k == 0 { Some(first) } else { tokens.next_token() };
                *x = coordinate(token, || ["x", "y", "z"][k])
                    .map_err(|e| format!("OFF: {}, vertex {v}: {e}", lines.at()))?;
            }
            piece.vertices.push(p);
        } else {
            read_face(lines, content - nv, nv, first, tokens, &mut face, &mut piece.indices)?;
        }
        content += 1;
        piece.read.1 += 1;
    }
    Ok(())
}

/// Reads content line `content` in the common layout (`x y z` or `3 i j k`, single spaces or
/// tabs, nothing after) from the start of `rest` into `piece`: the bytes taken. `None` where the
/// general reader must read the line (other layouts, comments, errors).
#[inline]
fn fast_line(rest: &[u8], content: u64, nv: u64, piece: &mut Piece) -> Option<usize> {
    let mut f = Fast::new(rest);
    if content < nv {
        let p = [f.f32()?, f.f32()?, f.f32()?];
        let taken = f.end()?;
        piece.vertices.push(p);
        return Some(taken);
    }
    if f.u32()? != 3 {
        return None;
    }
    let t = [f.u32()?, f.u32()?, f.u32()?];
    if t.iter().any(|&i| u64::from(i) >= nv) {
        return None;
    }
    let taken = f.end()?;
    piece.indices.push(t);
    Some(taken)
}

/// Reads face `f` (its vertex count `first`, then `tokens`), fanned into `indices`.
fn read_face(
    lines: &TextLines,
    f: u64,
    nv: u64,
    first: &[u8],
    mut tokens: Tokens,
    face: &mut Vec<u32>,
    indices: &mut Vec<[u32; 3]>,
) -> Result<(), String> {
    let at = || format!("OFF: {}, face {f}", lines.at());
    let n = parse_u64(first)
        .and_then(|n| usize::try_from(n).ok())
        .ok_or_else(|| format!("{}: the vertex count `{}` is not a count", at(), show(first)))?;
    if n < 3 {
        return Err(format!("{}: {n} vertex indices (at least 3 needed)", at()));
    }
    face.clear();
    for k in 0..n {
        let Some(token) = tokens.next_token() else {
            return Err(format!("{}: {n} vertices announced, {k} given", at()));
        };
        let i =
            parse_i64(token).ok_or_else(|| format!("{}: vertex index `{}` is not an integer", at(), show(token)))?;
        if i < 0 || i as u64 >= nv {
            return Err(format!("{}: vertex index {i} out of range ({nv} vertices)", at()));
        }
        face.push(i as u32);
    }
    if indices.capacity() - indices.len() < n - 2 {
        reserve(indices, (n - 2).max(indices.len()) as u64, "OFF triangles")?;
    }
    indices.extend((1..n - 1).map(|k| [face[0], face[k], face[k + 1]]));
    Ok(())
}
