//! `zeroset points`: point queries over a file of points, streamed ([`run_points`]).
//!
//! **Input**: CSV, one point `x,y,z` per line (blank lines and lines starting with `#` skipped,
//! an optional first line `x,y,z`), or a NumPy `.npy` array of shape `(N, 3)`, little-endian
//! `f8` or `f4`, C order. Coordinates must be finite; an error names the file and line (CSV) or
//! row (NPY, 0-based).
//!
//! **Output**: one row per point, in input order: CSV with a header line, or an `f8` `.npy` array
//! `(N, columns)`. The columns depend on the query ([`PointQuery::columns`]):
//!
//! | query | columns |
//! |---|---|
//! | `closest` | `x,y,z,distance,lower,upper,id,primitive` (the nearest surface point, object index, primitive part) |
//! | `distance` | `distance,lower,upper` |
//! | `signed` | `signed_distance,lower,upper` (negative inside) |
//! | `occupancy` | `occupancy` (1 inside, 0 outside) |
//! | `phi` | `phi,gx,gy,gz` (Φ of the scene and its gradient) |
//!
//! `distance` is exact where `lower == upper` (closed forms, meshes, similarity transforms); for
//! CSG, expressions and general affine maps `[lower, upper]` is a guaranteed interval and
//! `distance` its upper end (reached by the reported point). Points are read, answered (in
//! parallel) and written [`CHUNK_POINTS`] at a time, so memory stays bounded whatever their
//! number.

use super::batch::QueryError;
use super::npy::{npy_preamble, read_npy_table_header, NpyHeader};
use super::points::PointQueryError;
use crate::scene::Scene;
use glam::DVec3;
use rayon::prelude::*;
use std::io::{BufRead, Read, Seek, SeekFrom, Write};
use zeroset_primitives::SignMethod;

/// Points read, answered and written per step.
pub const CHUNK_POINTS: usize = 1 << 16;

/// What `zeroset points` computes at each point.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PointQuery {
    /// The nearest surface point.
    Closest,
    /// The distance to the nearest surface.
    Distance,
    /// The distance, negative inside.
    Signed,
    /// Inside (1) or outside (0).
    Occupancy,
    /// Φ and its gradient.
    Phi,
}

impl PointQuery {
    /// The output columns' names.
    #[must_use]
    pub fn columns(self) -> &'static [&'static str] {
        match self {
            Self::Closest => &["x", "y", "z", "distance", "lower", "upper", "id", "primitive"],
            Self::Distance => &["distance", "lower", "upper"],
            Self::Signed => &["signed_distance", "lower", "upper"],
            Self::Occupancy => &["occupancy"],
            Self::Phi => &["phi", "gx", "gy", "gz"],
        }
    }

    /// The answer's row at `p` (as long as [`PointQuery::columns`]), into `row`.
    ///
    /// # Errors
    /// Where the scene cannot answer (see [`PointQueryError`]).
    pub fn answer(self, scene: &Scene, p: DVec3, sign: SignMethod, row: &mut [f64]) -> Result<(), PointQueryError> {
        match self {
            Self::Closest => {
                let found = scene.closest_point(p)?;
                let c = found.closest;
                let q = c.point.map_or([f64::NAN; 3], |q| q.to_array());
                row.copy_from_slice(&[
                    q[0],
                    q[1],
                    q[2],
                    c.upper,
                    c.lower,
                    c.upper,
                    f64::from(found.object),
                    f64::from(c.feature),
                ]);
            }
            Self::Distance => {
                let c = scene.closest_point(p)?.closest;
                row.copy_from_slice(&[c.upper, c.lower, c.upper]);
            }
            Self::Signed => {
                let (lower, upper) = scene.signed_distance(p, sign)?;
                let value = if upper <= 0.0 { lower } else { upper };
                row.copy_from_slice(&[value, lower, upper]);
            }
            Self::Occupancy => {
                if !p.is_finite() {
                    return Err(PointQueryError::NotFinite(format!("({}, {}, {})", p.x, p.y, p.z)));
                }
                row[0] = f64::from(u8::from(scene.contains(p, sign)));
            }
            Self::Phi => {
                let g = scene.gradient(p);
                row.copy_from_slice(&[scene.phi(p), g.x, g.y, g.z]);
            }
        }
        Ok(())
    }
}

/// Where points come from, a chunk at a time.
pub trait PointSource {
    /// Appends up to `max` points to `out` (cleared first); returns `false` once the input is
    /// exhausted.
    ///
    /// # Errors
    /// A malformed point or a read error, located.
    fn read_chunk(&mut self, max: usize, out: &mut Vec<DVec3>) -> Result<bool, QueryError>;

    /// The number of points, when the format states it up front.
    fn len_hint(&self) -> Option<u64> {
        None
    }
}

/// CSV points (`x,y,z` per line).
pub struct CsvPoints<R> {
    reader: R,
    path: String,
    line_no: usize,
    seen_content: bool,
    line: String,
}

impl<R: BufRead> CsvPoints<R> {
    /// A reader of `reader`, named `path` in errors.
    pub fn new(reader: R, path: &str) -> Self {
        Self {
            reader,
            path: path.to_string(),
            line_no: 0,
            seen_content: false,
            line: String::new(),
        }
    }

    fn error(&self, message: String) -> QueryError {
        QueryError {
            path: self.path.clone(),
            location: self.line_no.to_string(),
            message,
        }
    }
}

/// The longest line of a CSV point file (three numbers take under 100 bytes).
const MAX_POINT_LINE_BYTES: usize = 4 << 10;

impl<R: BufRead> PointSource for CsvPoints<R> {
    fn read_chunk(&mut self, max: usize, out: &mut Vec<DVec3>) -> Result<bool, QueryError> {
        out.clear();
        while out.len() < max {
            self.line.clear();
            let read = (&mut self.reader)
                .take(MAX_POINT_LINE_BYTES as u64 + 1)
                .read_line(&mut self.line)
                .map_err(|e| self.error(format!("reading: {e}")))?;
            if read == 0 {
                return Ok(false);
            }
            self.line_no += 1;
            if self.line.len() > MAX_POINT_LINE_BYTES {
                return Err(self.error(format!(
                    "line longer than {} KiB (a point line has three numbers): not a CSV point file?",
                    MAX_POINT_LINE_BYTES >> 10
                )));
            }
            let text = self.line.trim_start_matches('\u{feff}').trim();
            if text.is_empty() || text.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = text.split(',').map(str::trim).collect();
            if !self.seen_content && fields == ["x", "y", "z"] {
                self.seen_content = true;
                continue;
            }
            self.seen_content = true;
            if fields.len() != 3 {
                return Err(self.error(format!(
                    "expected 3 comma-separated numbers x,y,z, found {} fields in `{text}`",
                    fields.len()
                )));
            }
            let mut v = [0.0; 3];
            for (value, field) in v.iter_mut().zip(&fields) {
                *value = field
                    .parse::<f64>()
                    .map_err(|_| self.error(format!("`{field}` is not a number")))?;
                if !value.is_finite() {
                    return Err(self.error(format!("`{field}`: coordinates must be finite")));
                }
            }
            out.push(DVec3::from_array(v));
        }
        Ok(true)
    }
}

/// `.npy` points: an `(N, 3)` array of `f8` or `f4`.
pub struct NpyPoints<R> {
    reader: R,
    path: String,
    header: NpyHeader,
    next_row: u64,
    bytes: Vec<u8>,
}

impl<R: Read> NpyPoints<R> {
    /// Reads the header of `reader`, named `path` in errors.
    ///
    /// # Errors
    /// Not an `.npy` file of a supported dtype and shape.
    pub fn new(mut reader: R, path: &str) -> Result<Self, QueryError> {
        let header = read_npy_table_header(&mut reader, path, &[3], "(N, 3): one point x, y, z per row")?;
        Ok(Self {
            reader,
            path: path.to_string(),
            header,
            next_row: 0,
            bytes: Vec::new(),
        })
    }
}

impl<R: Read> PointSource for NpyPoints<R> {
    fn read_chunk(&mut self, max: usize, out: &mut Vec<DVec3>) -> Result<bool, QueryError> {
        out.clear();
        let rows = (self.header.rows - self.next_row).min(max as u64) as usize;
        let width = if self.header.double { 8 } else { 4 };
        self.bytes.resize(rows * 3 * width, 0);
        self.reader.read_exact(&mut self.bytes).map_err(|e| QueryError {
            path: self.path.clone(),
            location: format!("row {}", self.next_row),
            message: format!("reading {rows} rows: {e} (the file is shorter than its shape says)"),
        })?;
        let value = |b: &[u8]| {
            if width == 8 {
                f64::from_le_bytes(b.try_into().expect("8 bytes"))
            } else {
                f64::from(f32::from_le_bytes(b.try_into().expect("4 bytes")))
            }
        };
        for (k, row) in self.bytes.chunks_exact(3 * width).enumerate() {
            let p = DVec3::new(
                value(&row[..width]),
                value(&row[width..2 * width]),
                value(&row[2 * width..]),
            );
            if !p.is_finite() {
                return Err(QueryError {
                    path: self.path.clone(),
                    location: format!("row {}", self.next_row + k as u64),
                    message: format!("point ({}, {}, {}): coordinates must be finite", p.x, p.y, p.z),
                });
            }
            out.push(p);
        }
        self.next_row += rows as u64;
        if self.next_row == self.header.rows {
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

/// Rows of f64 values out, a chunk at a time: CSV with a header, or `.npy`.
pub enum TableSink<W: Write> {
    /// CSV: the header, then one line per row; integers without a fraction, NaN as an empty field.
    Csv {
        /// Where the lines go.
        writer: W,
        /// Whether the header has been written.
        started: bool,
        /// Column names.
        columns: &'static [&'static str],
    },
    /// `.npy` `f8` `(N, columns)`: the row count declared up front, or patched in at the end
    /// ([`TableSink::finish_seekable`]).
    Npy {
        /// Where the bytes go.
        writer: W,
        /// Columns per row.
        columns: usize,
        /// Rows written.
        rows: u64,
        /// The count written in the header, if known up front.
        declared: Option<u64>,
        /// Whether the header has been written.
        started: bool,
    },
}

impl<W: Write> TableSink<W> {
    /// A CSV sink with these column names.
    pub fn csv(writer: W, columns: &'static [&'static str]) -> Self {
        Self::Csv {
            writer,
            started: false,
            columns,
        }
    }

    /// An `.npy` sink of `columns` columns; `declared` rows if known up front.
    pub fn npy(writer: W, columns: usize, declared: Option<u64>) -> Self {
        Self::Npy {
            writer,
            columns,
            rows: 0,
            declared,
            started: false,
        }
    }

    /// Writes rows given flat, `values.len()` a multiple of the column count.
    ///
    /// # Errors
    /// A write error.
    pub fn write(&mut self, values: &[f64]) -> std::io::Result<()> {
        match self {
            Self::Csv {
                writer,
                started,
                columns,
            } => {
                if !*started {
                    *started = true;
                    writeln!(writer, "{}", columns.join(","))?;
                }
                let text: String = values
                    .par_chunks(columns.len())
                    .with_min_len(1024)
                    .map(|row| {
                        let mut line = String::with_capacity(24 * row.len());
                        for (i, v) in row.iter().enumerate() {
                            if i > 0 {
                                line.push(',');
                            }
                            if v.is_finite() {
                                use std::fmt::Write as _;
                                let _ = write!(line, "{v}");
                            } else if !v.is_nan() {
                                line.push_str(if *v > 0.0 { "inf" } else { "-inf" });
                            }
                        }
                        line.push('\n');
                        line
                    })
                    .collect();
                writer.write_all(text.as_bytes())
            }
            Self::Npy {
                writer,
                columns,
                rows,
                declared,
                started,
            } => {
                if !*started {
                    *started = true;
                    writer.write_all(&npy_preamble(declared.unwrap_or(0), *columns))?;
                }
                let mut bytes = vec![0u8; values.len() * 8];
                bytes
                    .par_chunks_mut(8)
                    .zip(values.par_iter())
                    .with_min_len(4096)
                    .for_each(|(b, v)| b.copy_from_slice(&v.to_le_bytes()));
                writer.write_all(&bytes)?;
                *rows += (values.len() / *columns) as u64;
                Ok(())
            }
        }
    }

    /// Completes a stream: an `.npy` must have written the rows it declared.
    ///
    /// # Errors
    /// A write error, or an `.npy` row count other than declared.
    pub fn finish(&mut self) -> std::io::Result<()> {
        self.write(&[])?;
        match self {
            Self::Csv { writer, .. } => writer.flush(),
            Self::Npy {
                writer, rows, declared, ..
            } => {
                if *declared != Some(*rows) {
                    return Err(std::io::Error::other(format!(
                        "wrote {rows} rows after declaring {declared:?}"
                    )));
                }
                writer.flush()
            }
        }
    }
}

impl<W: Write + Seek> TableSink<W> {
    /// Completes a file: an `.npy` header gets the final row count.
    ///
    /// # Errors
    /// A write error.
    pub fn finish_seekable(&mut self) -> std::io::Result<()> {
        self.write(&[])?;
        match self {
            Self::Csv { writer, .. } => writer.flush(),
            Self::Npy {
                writer,
                columns,
                rows,
                declared,
                ..
            } => {
                if *declared != Some(*rows) {
                    writer.seek(SeekFrom::Start(0))?;
                    writer.write_all(&npy_preamble(*rows, *columns))?;
                    writer.seek(SeekFrom::End(0))?;
                }
                writer.flush()
            }
        }
    }
}

/// Why a point batch stopped.
#[derive(Debug, thiserror::Error)]
pub enum PointsError {
    /// Malformed input.
    #[error(transparent)]
    Input(#[from] QueryError),
    /// The scene cannot answer.
    #[error("{path}:{location}: {source}")]
    Scene {
        /// The point file.
        path: String,
        /// The row or line of the first point it could not answer.
        location: String,
        /// Why.
        source: PointQueryError,
    },
    /// Writing the answers.
    #[error("writing the answers: {0}")]
    Output(#[from] std::io::Error),
}

/// Answers `query` at every point of `source` and writes the rows to `sink` (chunk after chunk,
/// each in parallel); returns the number of points. `path` names the input in errors.
///
/// # Errors
/// Malformed input, a point the scene cannot answer, or a write error.
pub fn run_points<W: Write>(
    scene: &Scene,
    source: &mut dyn PointSource,
    path: &str,
    query: PointQuery,
    sign: SignMethod,
    sink: &mut TableSink<W>,
) -> Result<u64, PointsError> {
    let width = query.columns().len();
    let mut points = Vec::new();
    let mut values = Vec::new();
    let mut total = 0u64;
    loop {
        let more = source.read_chunk(CHUNK_POINTS, &mut points)?;
        values.clear();
        values.resize(points.len() * width, 0.0);
        let failed = values
            .par_chunks_mut(width)
            .zip(points.par_iter())
            .enumerate()
            .with_min_len(256)
            .find_map_first(|(i, (row, &p))| query.answer(scene, p, sign, row).err().map(|e| (i, e)));
        if let Some((i, source)) = failed {
            return Err(PointsError::Scene {
                path: path.to_string(),
                location: format!("point {}", total + i as u64),
                source,
            });
        }
        sink.write(&values)?;
        total += points.len() as u64;
        if !more {
            return Ok(total);
        }
    }
}
