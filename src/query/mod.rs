//! Batch first-hit queries: `zeroset query SCENE --rays RAYS.{csv,npy} -o HITS.{csv,npy}`.
//!
//! The batch path is three independent parts, run chunk after chunk of [`CHUNK_RAYS`] rays so
//! memory stays bounded whatever the number of rays, and output rows stay in input order:
//! 1. a [`RaySource`] parses rays ([`CsvRays`], [`NpyRays`]);
//! 2. [`trace_batch`] traces a slice of rays in parallel;
//! 3. a [`HitSink`] formats and writes the hits ([`CsvHits`], [`NpyHits`]).
//!
//! **CSV input**: one ray per line, `ox,oy,oz,dx,dy,dz[,tmin,tmax][,nx,ny,nz]` (default
//! `tmin = 0`, `tmax = +∞`; the range is open at `tmin` unless `--closed-range`, and the normal
//! columns spawn the origin off a surface with `--origin-precision`: see [`crate::query::rays`]),
//! fields separated by commas, spaces around them allowed. A UTF-8 byte-order mark
//! is skipped; blank lines and lines starting with `#` are skipped. The first other line is a
//! header only if its fields are exactly one of [`CSV_RAY_HEADERS`];
//! every other line must be a ray, and anything else — a word, a semicolon, fields separated by
//! spaces only, a trailing comma, a wrong count — is an error naming the file and line. No line
//! is ever skipped silently.
//!
//! **NPY input**: a NumPy `.npy` array of shape `(N, 6)`, `(N, 8)`, `(N, 9)` or `(N, 11)`,
//! little-endian `f8` or `f4`,
//! C order, with the same columns; errors name the row (0-based, as NumPy indexes it).
//!
//! The direction is used as given: `t` is in units of `|d|`, so normalise directions to get
//! distances. Origins and directions must be finite, directions non-zero with a largest
//! component of at least `2⁻⁵¹¹` ([`rays::MIN_DIRECTION`]: shorter ones would overflow `t`), `tmin ≤ tmax`.
//!
//! **CSV output**: a header line, then one line per input ray, in input order:
//! `hit,t,px,py,pz,nx,ny,nz,id,name,u,v` — `hit` is 1 or 0; on a miss every other field is
//! empty. The normal is the outward unit ∇Φ (not flipped); `id` is the object index, `name` its
//! name from the scene (empty if unnamed; commas and line breaks replaced by spaces); `u,v` are
//! empty where the primitive has none.
//!
//! With `--uncertain`, a last column `uncertain` is 1 where the root finder ran out of its
//! evaluation budget on the ray (the answer may be wrong), else 0; the count of such rays is
//! reported on stderr in any case.
//!
//! **NPY output**: an `f8` array of shape `(N, 11)` (`(N, 12)` with `--uncertain`), columns
//! `hit,t,px,py,pz,nx,ny,nz,id,u,v[,uncertain]` (no name), NaN where the CSV has an empty field. Writing `.npy` to stdout needs `.npy` input
//! (the row count goes in the header, before the rows).

pub mod all_hits;
pub mod batch;
pub mod csv;
pub mod npy;
pub mod order;
pub mod pixels;
pub mod point_table;
pub mod points;
pub mod rays;
#[cfg(test)]
mod tests;

pub use batch::{
    trace_batch, trace_many_for, trace_one, trace_one_for, QueryError, QueryHit, QueryRay, TraceWork, ANSWER, MISS,
};
pub use csv::{format_hits, parse_rays, parse_rays_with, CsvHits, CsvRays, CSV_HIT_HEADER, CSV_RAY_HEADERS};
pub use npy::{npy_preamble, NpyHits, NpyRays, NpyStream, NPY_HIT_COLUMNS};
pub use order::{coherent_order, trace_batch_in, RayOrder};

use crate::scene::Scene;

/// Rays read, traced and written per step of the batch loop.
pub const CHUNK_RAYS: usize = 1 << 16;

/// Where rays come from, a chunk at a time.
pub trait RaySource {
    /// Appends up to `max` rays to `out` (cleared first); returns `false` once the input is
    /// exhausted.
    ///
    /// # Errors
    /// A malformed ray or a read error, located.
    fn read_chunk(&mut self, max: usize, out: &mut Vec<QueryRay>) -> Result<bool, QueryError>;

    /// The total number of rays, when the format states it up front.
    fn len_hint(&self) -> Option<u64> {
        None
    }
}

/// Rays already in memory (pixel rays of a camera, rays built by a program) as a source.
pub struct VecRays {
    rays: std::vec::IntoIter<QueryRay>,
    total: u64,
}

impl VecRays {
    /// A source yielding `rays` in order.
    #[must_use]
    pub fn new(rays: Vec<QueryRay>) -> Self {
        Self {
            total: rays.len() as u64,
            rays: rays.into_iter(),
        }
    }
}

impl RaySource for VecRays {
    fn read_chunk(&mut self, max: usize, out: &mut Vec<QueryRay>) -> Result<bool, QueryError> {
        out.clear();
        out.extend(self.rays.by_ref().take(max));
        Ok(self.rays.len() > 0)
    }

    fn len_hint(&self) -> Option<u64> {
        Some(self.total)
    }
}

/// Where hits go, a chunk at a time, in input order.
pub trait HitSink {
    /// Writes the hits of one chunk.
    ///
    /// # Errors
    /// A write error.
    fn write_chunk(&mut self, scene: &Scene, hits: &[QueryHit]) -> std::io::Result<()>;

    /// Completes the output (e.g. the row count of an `.npy` header).
    ///
    /// # Errors
    /// A write error.
    fn finish(&mut self) -> std::io::Result<()>;
}

/// Counts of one batch run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BatchCounts {
    /// Rays read and traced.
    pub rays: u64,
    /// Rays that hit.
    pub hits: u64,
    /// Rays whose root finder ran out of its evaluation budget (see [`QueryHit::uncertain`]).
    pub uncertain: u64,
}

/// The batch loop: reads, traces and writes chunk by chunk, in order.
///
/// # Errors
/// A malformed ray (located) or an I/O error; the rows of earlier chunks may have been written.
pub fn run_batch(
    scene: &Scene,
    source: &mut (dyn RaySource + Send),
    sink: &mut (dyn HitSink + Send),
) -> anyhow::Result<BatchCounts> {
    run_batch_in(scene, source, sink, RayOrder::Input)
}

/// [`run_batch`] with each chunk traced in `order`.
///
/// While a chunk is traced, the next one is read and the one before written
/// ([`rayon::join`]: on the thread pool, whose other threads take part in the tracing as they
/// come free; on one thread, one after the other as before), so that reading and writing, which
/// run on one thread, no longer leave the others idle: on 10⁶ random rays of the level-4 bench
/// mesh, 2 threads, the three took 40, 65 and 46 ms one after the other. What is written and
/// what is reported are as if the chunks were taken one after the other: a chunk's rows are
/// written before the error of reading the next is returned, and the error of writing a chunk
/// comes before that of reading a later one.
///
/// # Errors
/// As [`run_batch`].
pub fn run_batch_in(
    scene: &Scene,
    source: &mut (dyn RaySource + Send),
    sink: &mut (dyn HitSink + Send),
    order: RayOrder,
) -> anyhow::Result<BatchCounts> {
    let mut counts = BatchCounts::default();
    let mut rays = Vec::with_capacity(CHUNK_RAYS);
    let mut next_rays = Vec::with_capacity(CHUNK_RAYS);
    let mut more = source.read_chunk(CHUNK_RAYS, &mut rays)?;
    // traced, not written yet
    let mut unwritten: Option<Vec<QueryHit>> = None;
    loop {
        let (hits, (read, written)) = rayon::join(
            || trace_batch_in(scene, &rays, order),
            || {
                let written = unwritten.as_ref().map_or(Ok(()), |hits| sink.write_chunk(scene, hits));
                let read = more.then(|| source.read_chunk(CHUNK_RAYS, &mut next_rays));
                (read, written)
            },
        );
        written?;
        counts.rays += rays.len() as u64;
        counts.hits += hits.iter().filter(|h| h.hit.is_some()).count() as u64;
        counts.uncertain += hits.iter().filter(|h| h.uncertain).count() as u64;
        match read {
            Some(Ok(still_more)) => {
                more = still_more;
                std::mem::swap(&mut rays, &mut next_rays);
                unwritten = Some(hits);
            }
            // the last chunk, or the one before an unreadable one: written, then the read's error
            last => {
                sink.write_chunk(scene, &hits)?;
                if let Some(Err(error)) = last {
                    return Err(error.into());
                }
                break;
            }
        }
    }
    sink.finish()?;
    Ok(counts)
}
