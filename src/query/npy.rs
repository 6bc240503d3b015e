//! The NumPy `.npy` formats of `zeroset query`: rays in ([`NpyRays`]), hits out ([`NpyHits`],
//! [`NpyStream`]). The formats are documented in [`crate::query`].

use super::batch::{QueryError, QueryHit, QueryRay};
use super::rays::{query_ray_from_fields, RaySetup};
use super::{HitSink, RaySource};
use crate::scene::Scene;
use rayon::prelude::*;
use std::io::{Read, Seek, SeekFrom, Write};

/// The parts of an `.npy` header zeroset reads.
#[derive(Debug)]
pub(crate) struct NpyHeader {
    pub(crate) rows: u64,
    pub(crate) columns: usize,
    /// `true` for `f8`, `false` for `f4`.
    pub(crate) double: bool,
}

/// Parses the `.npy` preamble (magic, version, header dictionary) of a ray array from `reader`.
pub(super) fn read_npy_header(reader: &mut impl Read, path: &str) -> Result<NpyHeader, QueryError> {
    read_npy_table_header(
        reader,
        path,
        &[6, 8, 9, MAX_COLUMNS as u64],
        "(N, 6) or (N, 8), or with normals (N, 9) or (N, 11)",
    )
}

/// Parses the `.npy` preamble of a two-dimensional `f8` or `f4` array whose column count is one
/// of `columns` (`expected` says them in words, for errors).
pub(crate) fn read_npy_table_header(
    reader: &mut impl Read,
    path: &str,
    columns: &[u64],
    expected: &str,
) -> Result<NpyHeader, QueryError> {
    let err = |message: String| QueryError {
        path: path.to_string(),
        location: "header".into(),
        message,
    };
    let mut preamble = [0u8; 8];
    reader
        .read_exact(&mut preamble)
        .map_err(|e| err(format!("reading the .npy preamble: {e}")))?;
    if &preamble[..6] != b"\x93NUMPY" {
        return Err(err("not a NumPy .npy file (no \\x93NUMPY magic)".into()));
    }
    let header_len = match preamble[6] {
        1 => {
            let mut b = [0u8; 2];
            reader.read_exact(&mut b).map_err(|e| err(format!("reading: {e}")))?;
            usize::from(u16::from_le_bytes(b))
        }
        2 | 3 => {
            let mut b = [0u8; 4];
            reader.read_exact(&mut b).map_err(|e| err(format!("reading: {e}")))?;
            u32::from_le_bytes(b) as usize
        }
        v => return Err(err(format!(".npy format version {v} is not supported"))),
    };
    if header_len > 1 << 20 {
        return Err(err(format!("header of {header_len} bytes is not plausible")));
    }
    let mut text = vec![0u8; header_len];
    reader
        .read_exact(&mut text)
        .map_err(|e| err(format!("reading the header: {e}")))?;
    let text = String::from_utf8_lossy(&text);
    let dict = parse_header_dict(&text).map_err(|m| err(format!("header dictionary `{}`: {m}", text.trim_end())))?;
    let double = match dict.descr.as_str() {
        "<f8" => true,
        "<f4" => false,
        other => {
            return Err(err(format!(
                "dtype '{other}' is not supported; use little-endian float64 ('<f8') or float32 ('<f4')"
            )))
        }
    };
    if dict.fortran_order {
        return Err(err(
            "Fortran-order arrays are not supported; save a C-order array".into()
        ));
    }
    let shape = dict.shape.iter().map(u64::to_string).collect::<Vec<_>>().join(", ");
    let &[rows, width] = dict.shape.as_slice() else {
        return Err(err(format!("shape ({shape}): expected {expected}")));
    };
    if !columns.contains(&width) {
        return Err(err(format!("shape ({shape}): expected {expected}")));
    }
    Ok(NpyHeader {
        rows,
        columns: width as usize,
        double,
    })
}

/// The three entries of an `.npy` header dictionary.
#[derive(Debug, PartialEq)]
pub(super) struct HeaderDict {
    pub(super) descr: String,
    pub(super) fortran_order: bool,
    pub(super) shape: Vec<u64>,
}

/// Parses the header dictionary, a Python literal such as
/// `{'descr': '<f8', 'fortran_order': False, 'shape': (3, 6), }` followed by padding: exactly the
/// keys `descr` (a string), `fortran_order` (`True` or `False`) and `shape` (a tuple of
/// non-negative integers), each once, in any order, strings in single or double quotes, a
/// trailing comma allowed (in the tuple too: `(3,)`), whitespace anywhere between tokens.
///
/// # Errors
/// Anything else, said in words (what was expected where).
pub(super) fn parse_header_dict(text: &str) -> Result<HeaderDict, String> {
    let mut p = Tokens { rest: text };
    p.expect('{')?;
    let (mut descr, mut fortran, mut shape) = (None, None, None);
    loop {
        if p.eat('}') {
            break;
        }
        let key = p.string()?;
        p.expect(':')?;
        match key.as_str() {
            "descr" if descr.is_none() => descr = Some(p.string()?),
            "fortran_order" if fortran.is_none() => fortran = Some(p.boolean()?),
            "shape" if shape.is_none() => shape = Some(p.tuple()?),
            "descr" | "fortran_order" | "shape" => return Err(format!("key '{key}' given twice")),
            _ => {
                return Err(format!(
                    "unexpected key '{key}' (an .npy header has descr, fortran_order and shape)"
                ))
            }
        }
        if !p.eat(',') {
            p.expect('}')?;
            break;
        }
    }
    if !p.rest.trim().is_empty() {
        return Err(format!("unexpected `{}` after the dictionary", p.rest.trim()));
    }
    Ok(HeaderDict {
        descr: descr.ok_or("no 'descr'")?,
        fortran_order: fortran.ok_or("no 'fortran_order'")?,
        shape: shape.ok_or("no 'shape'")?,
    })
}

/// The tokens of a header dictionary, read from the front.
struct Tokens<'a> {
    rest: &'a str,
}

impl Tokens<'_> {
    fn skip_space(&mut self) {
        self.rest = self.rest.trim_start();
    }

    /// Takes `c` if it comes next.
    fn eat(&mut self, c: char) -> bool {
        self.skip_space();
        match self.rest.strip_prefix(c) {
            Some(rest) => {
                self.rest = rest;
                true
            }
            None => false,
        }
    }

    fn expect(&mut self, c: char) -> Result<(), String> {
        if self.eat(c) {
            Ok(())
        } else {
            Err(format!("expected `{c}` at `{}`", self.excerpt()))
        }
    }

    fn excerpt(&self) -> String {
        let end = self.rest.char_indices().nth(20).map_or(self.rest.len(), |(i, _)| i);
        self.rest[..end].to_string()
    }

    /// A string in single or double quotes (no escapes: none appear in an .npy header).
    fn string(&mut self) -> Result<String, String> {
        self.skip_space();
        let quote = self.rest.chars().next().filter(|c| *c == '\'' || *c == '"');
        let Some(quote) = quote else {
            return Err(format!("expected a quoted string at `{}`", self.excerpt()));
        };
        let body = &self.rest[1..];
        let end = body
            .find(quote)
            .ok_or_else(|| format!("unterminated string at `{}`", self.excerpt()))?;
        let value = body[..end].to_string();
        self.rest = &body[end + 1..];
        Ok(value)
    }

    fn boolean(&mut self) -> Result<bool, String> {
        self.skip_space();
        for (word, value) in [("True", true), ("False", false)] {
            if let Some(rest) = self.rest.strip_prefix(word) {
                if !rest.starts_with(|c: char| c.is_alphanumeric() || c == '_') {
                    self.rest = rest;
                    return Ok(value);
                }
            }
        }
        Err(format!("expected True or False at `{}`", self.excerpt()))
    }

    /// `(a, b, …)` of non-negative integers, a trailing comma allowed.
    fn tuple(&mut self) -> Result<Vec<u64>, String> {
        self.expect('(')?;
        let mut values = Vec::new();
        loop {
            if self.eat(')') {
                return Ok(values);
            }
            self.skip_space();
            let digits = self.rest.find(|c: char| !c.is_ascii_digit()).unwrap_or(self.rest.len());
            let value = self.rest[..digits]
                .parse::<u64>()
                .map_err(|_| format!("expected a non-negative integer at `{}`", self.excerpt()))?;
            self.rest = &self.rest[digits..];
            values.push(value);
            if !self.eat(',') {
                self.expect(')')?;
                return Ok(values);
            }
        }
    }
}

/// Rays from a NumPy `.npy` array (see the module docs).
pub struct NpyRays<R> {
    reader: R,
    path: String,
    setup: RaySetup,
    header: NpyHeader,
    next_row: u64,
    bytes: Vec<u8>,
}

impl<R: Read> NpyRays<R> {
    /// Reads the header of `reader`, named `path` in errors.
    ///
    /// # Errors
    /// Not an `.npy` file of a supported dtype and shape.
    pub fn new(reader: R, path: &str) -> Result<Self, QueryError> {
        Self::with_setup(reader, path, RaySetup::default())
    }

    /// Reads the header; each ray is built as `setup` says.
    ///
    /// # Errors
    /// Not an `.npy` file of a supported dtype and shape.
    pub fn with_setup(mut reader: R, path: &str, setup: RaySetup) -> Result<Self, QueryError> {
        let header = read_npy_header(&mut reader, path)?;
        Ok(Self {
            reader,
            path: path.to_string(),
            setup,
            header,
            next_row: 0,
            bytes: Vec::new(),
        })
    }
}

/// The widest ray rows a `.npy` file may have: origin, direction, range and surface normal.
const MAX_COLUMNS: usize = 11;

impl<R: Read> RaySource for NpyRays<R> {
    fn read_chunk(&mut self, max: usize, out: &mut Vec<QueryRay>) -> Result<bool, QueryError> {
        out.clear();
        let rows = (self.header.rows - self.next_row).min(max as u64) as usize;
        let width = if self.header.double { 8 } else { 4 };
        let columns = self.header.columns;
        self.bytes.resize(rows * columns * width, 0);
        self.reader.read_exact(&mut self.bytes).map_err(|e| QueryError {
            path: self.path.clone(),
            location: format!("row {}", self.next_row),
            message: format!("reading {rows} rows: {e} (the file is shorter than its shape says)"),
        })?;
        let double = self.header.double;
        let setup = self.setup;
        let parsed: Vec<Result<QueryRay, String>> = self
            .bytes
            .par_chunks_exact(columns * width)
            .map(|row| {
                // the row's fields on the stack (at most 11 columns, checked with the header)
                let mut v = [0.0f64; MAX_COLUMNS];
                for (field, b) in v.iter_mut().zip(row.chunks_exact(width)) {
                    *field = if double {
                        f64::from_le_bytes(b.try_into().expect("8 bytes"))
                    } else {
                        f64::from(f32::from_le_bytes(b.try_into().expect("4 bytes")))
                    };
                }
                query_ray_from_fields(&v[..columns], &setup)
            })
            .collect();
        for (k, ray) in parsed.into_iter().enumerate() {
            out.push(ray.map_err(|message| QueryError {
                path: self.path.clone(),
                location: format!("row {}", self.next_row + k as u64),
                message,
            })?);
        }
        self.next_row += rows as u64;
        if self.next_row == self.header.rows {
            // nothing may follow the array
            let mut extra = [0u8; 1];
            if self.reader.read(&mut extra).is_ok_and(|n| n > 0) {
                return Err(QueryError {
                    path: self.path.clone(),
                    location: format!("row {}", self.next_row),
                    message: format!("data beyond the {} rows of the shape", self.header.rows),
                });
            }
            return Ok(false);
        }
        Ok(true)
    }

    fn len_hint(&self) -> Option<u64> {
        Some(self.header.rows)
    }
}

/// Columns of the `.npy` output (without the optional `uncertain` column).
pub const NPY_HIT_COLUMNS: usize = 11;

/// Length of the `.npy` output preamble: fixed, so the row count can be patched in at the end.
pub(super) const NPY_PREAMBLE_LEN: usize = 128;

/// The `.npy` (version 1.0) preamble of an `f8` array of shape `(rows, columns)`, padded with
/// spaces to `NPY_PREAMBLE_LEN` bytes.
#[must_use]
pub fn npy_preamble(rows: u64, columns: usize) -> Vec<u8> {
    let dict = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({rows}, {columns}), }}");
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    let header_len = NPY_PREAMBLE_LEN - 10;
    bytes.extend_from_slice(&(header_len as u16).to_le_bytes());
    bytes.extend_from_slice(dict.as_bytes());
    bytes.resize(NPY_PREAMBLE_LEN - 1, b' ');
    bytes.push(b'\n');
    bytes
}

/// `.npy` hits: rows counted as they are written; the header is written first with the known
/// count, or patched at the end when the writer can seek.
pub struct NpyHits<W> {
    writer: W,
    /// 11, or 12 with the `uncertain` column.
    columns: usize,
    rows: u64,
    /// The count written in the header up front, if it was known.
    declared: Option<u64>,
    started: bool,
}

impl<W: Write + Seek> NpyHits<W> {
    /// A sink on a seekable `writer` (a file): the row count is patched in at the end.
    pub fn seekable(writer: W, uncertain_column: bool) -> Self {
        Self {
            writer,
            columns: NPY_HIT_COLUMNS + usize::from(uncertain_column),
            rows: 0,
            declared: None,
            started: false,
        }
    }
}

impl<W: Write> NpyHits<W> {
    /// A sink on any writer for exactly `rows` rows, declared up front.
    pub fn with_rows(writer: W, rows: u64, uncertain_column: bool) -> Self {
        Self {
            writer,
            columns: NPY_HIT_COLUMNS + usize::from(uncertain_column),
            rows: 0,
            declared: Some(rows),
            started: false,
        }
    }

    fn start(&mut self) -> std::io::Result<()> {
        if !self.started {
            self.started = true;
            self.writer
                .write_all(&npy_preamble(self.declared.unwrap_or(0), self.columns))?;
        }
        Ok(())
    }

    fn write_rows(&mut self, hits: &[QueryHit]) -> std::io::Result<()> {
        self.start()?;
        let columns = self.columns;
        // each row's bytes written in place, in parallel (a collected byte iterator costs a third
        // of a whole `query` run)
        let mut bytes = vec![0u8; hits.len() * columns * 8];
        bytes
            .par_chunks_mut(columns * 8)
            .zip(hits.par_iter())
            .with_min_len(1024)
            .for_each(|(row, hit)| {
                let flag = f64::from(u8::from(hit.uncertain));
                let values = npy_row(hit).into_iter().chain(std::iter::once(flag));
                for (field, value) in row.chunks_exact_mut(8).zip(values) {
                    field.copy_from_slice(&value.to_le_bytes());
                }
            });
        self.writer.write_all(&bytes)?;
        self.rows += hits.len() as u64;
        Ok(())
    }
}

/// One `.npy` output row.
fn npy_row(answer: &QueryHit) -> [f64; NPY_HIT_COLUMNS] {
    let nan = f64::NAN;
    match &answer.hit {
        None => [0.0, nan, nan, nan, nan, nan, nan, nan, nan, nan, nan],
        Some((object, h)) => {
            let n = h.normal.map_or([nan; 3], |n| n.to_array());
            let uv = h.uv.map_or([nan; 2], |uv| uv.to_array());
            [
                1.0,
                h.t,
                h.point.x,
                h.point.y,
                h.point.z,
                n[0],
                n[1],
                n[2],
                f64::from(*object),
                uv[0],
                uv[1],
            ]
        }
    }
}

/// `.npy` sink on a seekable writer.
impl<W: Write + Seek> HitSink for NpyHits<W> {
    fn write_chunk(&mut self, _scene: &Scene, hits: &[QueryHit]) -> std::io::Result<()> {
        self.write_rows(hits)
    }

    fn finish(&mut self) -> std::io::Result<()> {
        self.start()?;
        if self.declared != Some(self.rows) {
            self.writer.seek(SeekFrom::Start(0))?;
            self.writer.write_all(&npy_preamble(self.rows, self.columns))?;
            self.writer.seek(SeekFrom::End(0))?;
        }
        self.writer.flush()
    }
}

/// `.npy` sink on a stream (stdout) with the row count declared up front.
pub struct NpyStream<W: Write>(pub NpyHits<W>);

impl<W: Write> HitSink for NpyStream<W> {
    fn write_chunk(&mut self, _scene: &Scene, hits: &[QueryHit]) -> std::io::Result<()> {
        self.0.write_rows(hits)
    }

    fn finish(&mut self) -> std::io::Result<()> {
        self.0.start()?;
        if self.0.declared != Some(self.0.rows) {
            return Err(std::io::Error::other(format!(
                "wrote {} rows after declaring {:?}",
                self.0.rows, self.0.declared
            )));
        }
        self.0.writer.flush()
    }
}
