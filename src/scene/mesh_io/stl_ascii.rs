//! ASCII STL: `solid name`, facets of `facet normal …` / `outer loop` / three `vertex x y z` /
//! `endloop` / `endfacet`, then `endsolid` (several solids in one file are read as one mesh).
//! Words are matched in any case; what follows the words a line needs is ignored.
//!
//! The file is read in blocks of whole lines (`text::for_each_block`); the reader's state (what
//! it expects next, the line and facet counts) is carried from block to block. A block is parsed
//! in parallel pieces that start at `facet` lines, each but the first assuming it starts between
//! facets; the pieces are kept only when each ends between facets, so they give what one pass
//! over the block gives. Otherwise, and on any error, the block is parsed again in one pass from
//! the carried state, so messages and results are exactly those of a single pass over the file.
//! A block's corners are welded while the next block is parsed.

use super::shared::{file_len, reserve};
use super::stl::{finish, Stl};
use super::text::{coordinate, for_each_block, piece_count, piece_starts, Cuts, Fast, TextLines, Tokens, CUTS};
use super::weld::{Corner, Welder};
use rayon::prelude::*;
use std::path::Path;

/// What the ASCII reader expects next.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Expect {
    Solid,
    FacetOrEnd,
    OuterLoop,
    Vertex(usize),
    EndLoop,
    EndFacet,
}

/// Where a pass stands: what it expects next, and the lines, facets and solids before.
#[derive(Clone, Copy, Debug)]
struct State {
    expect: Expect,
    lines: u64,
    facets: u64,
    solids: u64,
}

/// Reads an ASCII STL (see the module documentation).
pub(super) fn read_ascii(path: &Path) -> Result<Stl, String> {
    read_ascii_cut(path, CUTS)
}

/// Reads an ASCII STL, cut as `cuts` says.
pub(super) fn read_ascii_cut(path: &Path, cuts: Cuts) -> Result<Stl, String> {
    let len = file_len(path)?;
    // a facet takes some 200 bytes, a closed mesh has half as many vertices as triangles;
    // reserved room not written to costs no memory
    let mut indices: Vec<[u32; 3]> = Vec::new();
    reserve(&mut indices, len / 150, "ASCII STL triangles")?;
    let mut welder = Welder::with_capacity(len / 300 + 3)?;
    let mut state = State {
        expect: Expect::Solid,
        lines: 0,
        facets: 0,
        solids: 0,
    };
    // the corners of the pieces of the block being parsed, and of the block before (to weld)
    let mut parsing: Vec<Vec<Corner>> = Vec::new();
    let mut parsed: Vec<Vec<Corner>> = Vec::new();
    for_each_block(path, cuts.block, |block, offset| {
        let (welded, read) = rayon::join(
            || weld_all(&mut welder, &parsed, &mut indices),
            || parse_block(block, offset, state, cuts.piece, &mut parsing),
        );
        welded?;
        state = read?;
        std::mem::swap(&mut parsing, &mut parsed);
        Ok(true)
    })?;
    weld_all(&mut welder, &parsed, &mut indices)?;
    if state.expect != Expect::Solid {
        return Err(format!(
            "ASCII STL: line {}: unexpected end of file inside {} (truncated?)",
            state.lines + 1,
            if state.solids == 0 {
                "the file".to_string()
            } else {
                format!("facet {}", state.facets)
            }
        ));
    }
    if indices.is_empty() {
        return Err("ASCII STL: no facets".into());
    }
    Ok(finish(welder, indices, true))
}

fn weld_all(welder: &mut Welder, pieces: &[Vec<Corner>], indices: &mut Vec<[u32; 3]>) -> Result<(), String> {
    for corners in pieces {
        welder.add(corners, indices).map_err(|e| format!("ASCII STL: {e}"))?;
    }
    Ok(())
}

/// Whether a line starts with the word `facet` (any case).
fn is_facet_line(line: &[u8]) -> bool {
    let at = line
        .iter()
        .position(|c| !matches!(c, b' ' | b'\t' | b'\r' | b'\x0C'))
        .unwrap_or(line.len());
    let word = &line[at..];
    word.len() >= 5 && word[..5].eq_ignore_ascii_case(b"facet") && word.get(5).is_none_or(u8::is_ascii_whitespace)
}

/// Parses a block (at byte `offset`, from `state`) in pieces of about `piece` bytes into
/// `pieces` (their corners, in order); returns the state at its end.
fn parse_block(
    block: &[u8],
    offset: u64,
    state: State,
    piece: usize,
    pieces: &mut Vec<Vec<Corner>>,
) -> Result<State, String> {
    let starts = piece_starts(block, piece_count(block.len(), piece), is_facet_line);
    let count = starts.len() - 1;
    pieces.resize_with(count.max(1), Vec::new);
    if count > 1 {
        let ends: Vec<Result<State, String>> = pieces
            .par_iter_mut()
            .zip(starts.par_windows(2))
            .enumerate()
            .map(|(k, (corners, w))| {
                let from = if k == 0 {
                    state
                } else {
                    // a guess, checked against the piece before
                    State {
                        expect: Expect::FacetOrEnd,
                        lines: 0,
                        facets: 0,
                        solids: 0,
                    }
                };
                parse_piece(&block[w[0]..w[1]], offset + w[0] as u64, from, corners)
            })
            .collect();
        let mut end = state;
        let fits = ends.iter().enumerate().all(|(k, piece)| match piece {
            Ok(piece) if k == 0 || end.expect == Expect::FacetOrEnd => {
                end = State {
                    expect: piece.expect,
                    lines: if k == 0 { piece.lines } else { end.lines + piece.lines },
                    facets: if k == 0 {
                        piece.facets
                    } else {
                        end.facets + piece.facets
                    },
                    solids: if k == 0 {
                        piece.solids
                    } else {
                        end.solids + piece.solids
                    },
                };
                true
            }
            _ => false,
        });
        if fits {
            return Ok(end);
        }
    }
    // one pass over the block
    pieces.truncate(1);
    parse_piece(block, offset, state, &mut pieces[0])
}

/// Parses `text` (at byte `offset` of the file, on a line start) from `state`, its corners into
/// `corners`; returns the state at its end.
fn parse_piece(text: &[u8], offset: u64, state: State, corners: &mut Vec<Corner>) -> Result<State, String> {
    corners.clear();
    reserve(corners, text.len() as u64 / 64, "ASCII STL corners")?;
    let mut lines = TextLines::new(text, offset, state.lines);
    let State {
        mut expect,
        mut facets,
        mut solids,
        ..
    } = state;
    loop {
        if let Some(rest) = lines.unread() {
            if let Some((taken, next)) = fast_line(rest, expect, corners) {
                lines.skip_line(taken);
                facets += u64::from(expect == Expect::EndFacet);
                expect = next;
                continue;
            }
        }
        let line = match lines.next_line() {
            Ok(Some(line)) => line,
            Ok(None) => break,
            Err(e) => return Err(format!("ASCII STL: {e}")),
        };
        let mut tokens = Tokens::new(line);
        let Some(word) = tokens.next_token() else { continue };
        let word_is = |w: &str| word.eq_ignore_ascii_case(w.as_bytes());
        let ok = match expect {
            Expect::Solid => word_is("solid"),
            Expect::FacetOrEnd => word_is("facet") || word_is("endsolid"),
            Expect::OuterLoop => {
                word_is("outer") && tokens.next_token().is_some_and(|w| w.eq_ignore_ascii_case(b"loop"))
            }
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
                "ASCII STL: {}, facet {facets}: expected {wanted}, found `{}`",
                lines.at(),
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
                    *x = coordinate(tokens.next_token(), || format!("coordinate {}", ["x", "y", "z"][k]))
                        .map_err(|e| format!("ASCII STL: {}, facet {facets}, vertex {c}: {e}", lines.at()))?;
                }
                if corners.len() == corners.capacity() {
                    let more = corners.len().max(1024) as u64;
                    reserve(corners, more, "ASCII STL corners")?;
                }
                corners.push(Corner::new(p));
                if c == 2 {
                    Expect::EndLoop
                } else {
                    Expect::Vertex(c + 1)
                }
            }
            Expect::EndLoop => Expect::EndFacet,
            Expect::EndFacet => {
                facets += 1;
                Expect::FacetOrEnd
            }
        };
    }
    Ok(State {
        expect,
        lines: lines.line - 1,
        facets,
        solids,
    })
}

/// Reads a line in the common layout (lower-case words, single numbers, nothing after what is
/// needed but on a `facet` line) from the start of `rest`, its corner into `corners`: the bytes
/// taken and what is expected next. `None` where the general reader must read the line.
#[inline]
fn fast_line(rest: &[u8], expect: Expect, corners: &mut Vec<Corner>) -> Option<(usize, Expect)> {
    let mut f = Fast::new(rest);
    let next = match expect {
        Expect::Vertex(c) => {
            f.word(b"vertex")?;
            let p = [f.f32()?, f.f32()?, f.f32()?];
            let taken = f.end()?;
            if corners.len() == corners.capacity() {
                return None;
            }
            corners.push(Corner::new(p));
            let next = if c == 2 { Expect::EndLoop } else { Expect::Vertex(c + 1) };
            return Some((taken, next));
        }
        Expect::FacetOrEnd => {
            f.word(b"facet")?;
            return Some((f.rest_of_line()?, Expect::OuterLoop));
        }
        Expect::OuterLoop => {
            f.word(b"outer")?;
            f.word(b"loop")?;
            Expect::Vertex(0)
        }
        Expect::EndLoop => {
            f.word(b"endloop")?;
            Expect::EndFacet
        }
        Expect::EndFacet => {
            f.word(b"endfacet")?;
            Expect::FacetOrEnd
        }
        Expect::Solid => return None,
    };
    Some((f.end()?, next))
}

/// The first 40 characters of a line, for messages.
fn clip(line: &str) -> String {
    let mut out: String = line.trim().chars().take(40).collect();
    if line.trim().chars().count() > 40 {
        out.push('…');
    }
    out
}
