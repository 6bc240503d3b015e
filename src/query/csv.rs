//! The CSV formats of `zeroset query`: rays in ([`CsvRays`], [`parse_rays`]), hits out
//! ([`CsvHits`]). The formats are documented in [`crate::query`].

use super::batch::{QueryError, QueryHit, QueryRay};
use super::rays::{query_ray_from_fields, RaySetup};
use super::{HitSink, RaySource, CHUNK_RAYS};
use crate::scene::Scene;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::io::{BufRead, Read, Write};

/// The documented CSV headers (without and with the `t` range).
pub const CSV_RAY_HEADERS: [&str; 4] = [
    "ox,oy,oz,dx,dy,dz",
    "ox,oy,oz,dx,dy,dz,tmin,tmax",
    "ox,oy,oz,dx,dy,dz,nx,ny,nz",
    "ox,oy,oz,dx,dy,dz,tmin,tmax,nx,ny,nz",
];

/// The CSV output header.
pub const CSV_HIT_HEADER: &str = "hit,t,px,py,pz,nx,ny,nz,id,name,u,v";

/// What one CSV line holds.
enum CsvLine {
    Skip,
    Header,
    Ray(QueryRay),
}

/// Parses one CSV line (see the module docs).
fn parse_csv_line(line: &str, setup: &RaySetup) -> Result<CsvLine, String> {
    let trimmed = line.trim();
    if trimmed.is_empty() || trimmed.starts_with('#') {
        return Ok(CsvLine::Skip);
    }
    let fields: Vec<&str> = trimmed.split(',').map(str::trim).collect();
    let joined = fields.join(",");
    if CSV_RAY_HEADERS.contains(&joined.as_str()) {
        return Ok(CsvLine::Header);
    }
    if trimmed.contains(';') {
        return Err(format!("fields are separated by commas, found `;` in `{trimmed}`"));
    }
    let mut v = Vec::with_capacity(8);
    for (k, field) in fields.iter().enumerate() {
        if field.is_empty() {
            let hint = if k + 1 == fields.len() {
                " (a trailing comma?)"
            } else {
                ""
            };
            return Err(format!("field {} is empty{hint} in `{trimmed}`", k + 1));
        }
        match field.parse::<f64>() {
            Ok(x) => v.push(x),
            Err(_) => {
                return Err(format!(
                    "field {} `{field}` is not a number; expected `ox,oy,oz,dx,dy,dz[,tmin,tmax][,nx,ny,nz]`",
                    k + 1
                ))
            }
        }
    }
    query_ray_from_fields(&v, setup).map(CsvLine::Ray)
}

/// CSV rays from any buffered reader, parsed in parallel a chunk at a time.
pub struct CsvRays<R> {
    reader: R,
    path: String,
    setup: RaySetup,
    /// Lines read so far.
    line_no: usize,
    /// Whether a ray (or the header) has been seen: a header is accepted only before.
    seen_content: bool,
    lines: Vec<String>,
    done: bool,
}

impl<R: BufRead> CsvRays<R> {
    /// A reader of `reader`, named `path` in errors, building rays with the default
    /// [`RaySetup`] (range open at `tmin`, origins as given).
    pub fn new(reader: R, path: &str) -> Self {
        Self::with_setup(reader, path, RaySetup::default())
    }

    /// A reader building each ray as `setup` says.
    pub fn with_setup(reader: R, path: &str, setup: RaySetup) -> Self {
        Self {
            reader,
            path: path.to_string(),
            setup,
            line_no: 0,
            seen_content: false,
            lines: Vec::new(),
            done: false,
        }
    }
}

/// The longest line of a CSV ray file: 64 KiB (eleven numbers in full take under 300 bytes). A
/// longer line is refused after that much is read, so an input without line ends (`/dev/zero`,
/// a binary file) is never read whole.
pub const MAX_RAY_LINE_BYTES: usize = 64 << 10;

impl<R: BufRead> RaySource for CsvRays<R> {
    fn read_chunk(&mut self, max: usize, out: &mut Vec<QueryRay>) -> Result<bool, QueryError> {
        out.clear();
        let first_line = self.line_no + 1;
        let mut count = 0;
        // reuse the line buffers of the previous chunk
        while count < max && !self.done {
            if self.lines.len() <= count {
                self.lines.push(String::new());
            }
            let buffer = &mut self.lines[count];
            buffer.clear();
            // at most one byte more than a line may have: a longer one is refused, not read on
            let read = (&mut self.reader)
                .take(MAX_RAY_LINE_BYTES as u64 + 1)
                .read_line(buffer)
                .map_err(|e| QueryError {
                    path: self.path.clone(),
                    location: (self.line_no + 1).to_string(),
                    message: format!("reading: {e}"),
                })?;
            if buffer.len() > MAX_RAY_LINE_BYTES {
                return Err(QueryError {
                    path: self.path.clone(),
                    location: (self.line_no + 1).to_string(),
                    message: format!(
                        "line longer than {} KiB (a ray line has at most 11 numbers): not a CSV ray file?",
                        MAX_RAY_LINE_BYTES >> 10
                    ),
                });
            }
            if read == 0 {
                self.done = true;
                break;
            }
            self.line_no += 1;
            if self.line_no == 1 {
                if let Some(rest) = buffer.strip_prefix('\u{feff}') {
                    *buffer = rest.to_string();
                }
            }
            count += 1;
        }
        let parsed: Vec<Result<CsvLine, String>> = self.lines[..count]
            .par_iter()
            .map(|l| parse_csv_line(l, &self.setup))
            .collect();
        for (k, line) in parsed.into_iter().enumerate() {
            let located = |message: String| QueryError {
                path: self.path.clone(),
                location: (first_line + k).to_string(),
                message,
            };
            match line.map_err(located)? {
                CsvLine::Skip => {}
                CsvLine::Header if !self.seen_content => self.seen_content = true,
                CsvLine::Header => {
                    return Err(located(
                        "a header line is allowed only before the first ray".to_string(),
                    ))
                }
                CsvLine::Ray(ray) => {
                    self.seen_content = true;
                    out.push(ray);
                }
            }
        }
        Ok(!self.done)
    }
}

/// One CSV output row (without the line break).
fn csv_row(scene: &Scene, answer: &QueryHit, uncertain_column: bool, out: &mut String) {
    match &answer.hit {
        None => out.push_str("0,,,,,,,,,,,"),
        Some((object, h)) => {
            let n = h.normal.unwrap_or_default();
            let name = scene.objects[*object as usize]
                .name
                .as_deref()
                .unwrap_or("")
                .replace([',', '\n', '\r'], " ");
            let _ = write!(
                out,
                "1,{:e},{:e},{:e},{:e},{:e},{:e},{:e},{object},{name},",
                h.t, h.point.x, h.point.y, h.point.z, n.x, n.y, n.z
            );
            if let Some(uv) = h.uv {
                let _ = write!(out, "{:e},{:e}", uv.x, uv.y);
            } else {
                out.push(',');
            }
        }
    }
    if uncertain_column {
        out.push_str(if answer.uncertain { ",1" } else { ",0" });
    }
}

/// Formats hits as CSV text (header included), for callers that hold all hits.
#[must_use]
pub fn format_hits(scene: &Scene, hits: &[QueryHit]) -> String {
    let mut out = format!("{CSV_HIT_HEADER}\n");
    for hit in hits {
        csv_row(scene, hit, false, &mut out);
        out.push('\n');
    }
    out
}

/// CSV hits (see the module docs); rows are formatted in parallel.
pub struct CsvHits<W> {
    writer: W,
    header_written: bool,
    uncertain_column: bool,
}

impl<W: Write> CsvHits<W> {
    /// A CSV sink on `writer`, with the `uncertain` column last if `uncertain_column`.
    pub fn new(writer: W, uncertain_column: bool) -> Self {
        Self {
            writer,
            header_written: false,
            uncertain_column,
        }
    }

    fn header(&mut self) -> std::io::Result<()> {
        if !self.header_written {
            self.header_written = true;
            let extra = if self.uncertain_column { ",uncertain" } else { "" };
            writeln!(self.writer, "{CSV_HIT_HEADER}{extra}")?;
        }
        Ok(())
    }
}

impl<W: Write> HitSink for CsvHits<W> {
    fn write_chunk(&mut self, scene: &Scene, hits: &[QueryHit]) -> std::io::Result<()> {
        self.header()?;
        let uncertain_column = self.uncertain_column;
        let pieces: Vec<String> = hits
            .par_chunks(1024)
            .map(|part| {
                let mut text = String::with_capacity(part.len() * 160);
                for hit in part {
                    csv_row(scene, hit, uncertain_column, &mut text);
                    text.push('\n');
                }
                text
            })
            .collect();
        for piece in pieces {
            self.writer.write_all(piece.as_bytes())?;
        }
        Ok(())
    }

    fn finish(&mut self) -> std::io::Result<()> {
        self.header()?;
        self.writer.flush()
    }
}

/// Parses a whole CSV text at once (for tests and small batches) with the default [`RaySetup`].
///
/// # Errors
/// The first malformed line.
pub fn parse_rays(text: &str, path: &str) -> Result<Vec<QueryRay>, QueryError> {
    parse_rays_with(text, path, &RaySetup::default())
}

/// Parses a whole CSV text at once, building each ray as `setup` says.
///
/// # Errors
/// The first malformed line.
pub fn parse_rays_with(text: &str, path: &str, setup: &RaySetup) -> Result<Vec<QueryRay>, QueryError> {
    let mut source = CsvRays::with_setup(text.as_bytes(), path, *setup);
    let (mut all, mut chunk) = (Vec::new(), Vec::new());
    while source.read_chunk(CHUNK_RAYS, &mut chunk)? {
        all.append(&mut chunk);
    }
    all.append(&mut chunk);
    Ok(all)
}
