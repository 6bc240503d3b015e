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
//! columns spawn the origin off a surface with `--origin-precision`: see [`crate::query_rays`]),
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
//! distances. Origins and directions must be finite, directions non-zero, `tmin ≤ tmax`.
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

use crate::query_rays::RaySetup;
use crate::scene::Scene;
use glam::DVec3;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::io::{BufRead, Read, Seek, SeekFrom, Write};
use zeroset_primitives::root::{thread_uncertain_events, uncertain_while};
use zeroset_primitives::{HitRequest, Interval, RawHit, Ray, SurfaceHit, PACKET};

/// Rays read, traced and written per step of the batch loop.
pub const CHUNK_RAYS: usize = 1 << 16;

/// The documented CSV headers (without and with the `t` range).
pub const CSV_RAY_HEADERS: [&str; 4] = [
    "ox,oy,oz,dx,dy,dz",
    "ox,oy,oz,dx,dy,dz,tmin,tmax",
    "ox,oy,oz,dx,dy,dz,nx,ny,nz",
    "ox,oy,oz,dx,dy,dz,tmin,tmax,nx,ny,nz",
];

/// The CSV output header.
pub const CSV_HIT_HEADER: &str = "hit,t,px,py,pz,nx,ny,nz,id,name,u,v";

/// One query ray with its parameter range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QueryRay {
    /// The ray.
    pub ray: Ray,
    /// Accepted `t`.
    pub range: Interval,
}

/// What a query answers about a hit: normal and uv (the point comes with every hit); not the
/// point's error bound, which nothing downstream of a query uses.
pub const ANSWER: HitRequest = HitRequest {
    normal: true,
    uv: true,
    error: false,
};

/// A miss, certain: the answer before a ray is traced.
pub const MISS: QueryHit = QueryHit {
    hit: None,
    uncertain: false,
};

/// The answer for one query ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QueryHit {
    /// The first hit: the object index and its completed hit record (normal and uv; its
    /// `error` is not computed, `+∞`).
    pub hit: Option<(u32, SurfaceHit)>,
    /// Whether the root finder ran out of its evaluation budget on this ray: the answer (a miss,
    /// or a hit beyond a surface it could not resolve) may be wrong.
    pub uncertain: bool,
}

/// A malformed ray or an unreadable input.
#[derive(Debug, thiserror::Error)]
#[error("{path}:{location}: {message}")]
pub struct QueryError {
    /// The ray file.
    pub path: String,
    /// 1-based line number (CSV), `row N` (NPY) or `header`.
    pub location: String,
    /// What is wrong.
    pub message: String,
}

/// First hits of `rays` in `scene` (in input order, traced in parallel), with normal and uv.
#[must_use]
pub fn trace_batch(scene: &Scene, rays: &[QueryRay]) -> Vec<QueryHit> {
    trace_batch_in(scene, rays, RayOrder::Input)
}

/// The order in which a batch's rays are traced. The answers are the same whatever the order;
/// only the speed differs. `Input` traces each ray alone, as given; `Sorted` sorts the batch
/// for coherence and traces it in packets of [`PACKET`] neighbouring rays
/// ([`Scene::intersect_packet`]). On every batch measured (random rays, camera rays in pixel
/// order or shuffled, many cameras' rays shuffled together) `Input` is the faster: the single-ray
/// walks lose little to a lack of order, less than sorting costs (see the README's "Command
/// line", `zeroset query`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum RayOrder {
    /// As given.
    Input,
    /// Sorted for coherence ([`coherent_order`]) and traced in packets where the sorted
    /// neighbours point alike (within ~8°), so they walk the same nodes together; a batch with no
    /// such coherence to recover (random rays) is traced as given.
    Sorted,
}

/// First hits of `rays` in `scene`, traced in `order`, returned in input order.
#[must_use]
pub fn trace_batch_in(scene: &Scene, rays: &[QueryRay], order: RayOrder) -> Vec<QueryHit> {
    let sort = match order {
        RayOrder::Input => false,
        RayOrder::Sorted => rays.len() > 1,
    };
    // each ray on its own, handed to the scene 256 at a time
    let one_by_one = || {
        let mut answers = vec![MISS; rays.len()];
        answers.par_chunks_mut(256).zip(rays.par_chunks(256)).for_each_init(
            TraceWork::default,
            |work, (answers, rays)| {
                trace_many_for(scene, rays, ANSWER, work, answers);
            },
        );
        answers
    };
    if !sort || !sample_may_pay(rays) {
        return one_by_one();
    }
    let permutation = coherent_order(rays);
    if !packets_pay(rays, &permutation) {
        return one_by_one();
    }
    // one array per packet: an indexed collect, straight into place (a flattened one would
    // gather pieces and copy them together)
    let traced: Vec<[QueryHit; PACKET]> = permutation
        .par_chunks(PACKET)
        .with_min_len(32)
        .map(|packet| trace_packet(scene, rays, packet))
        .collect();
    // position in the traced order of each input ray
    let mut rank = vec![0u32; rays.len()];
    for (k, &i) in permutation.iter().enumerate() {
        rank[i as usize] = k as u32;
    }
    rank.par_iter()
        .map(|&k| traced[k as usize / PACKET][k as usize % PACKET])
        .collect()
}

/// Rays whose directions are all within this cosine of the first ray's (about 8°: twice the
/// width of [`coherent_order`]'s direction cells) are traced as a packet; a packet of rays spread
/// wider (random rays, sorted: neighbours in the order start near each other but point anywhere in
/// their octant) would walk the hierarchy lane by lane anyway, paying the packet's bookkeeping on
/// top, so its rays are traced one by one.
const PACKET_COSINE: f64 = 0.99;

/// Whether tracing `rays` in packets of [`PACKET`] along `permutation` pays: at least a quarter
/// of up to 256 packets spread evenly over it are [`coherent`]. Where they are not (random rays:
/// sorted neighbours start near each other but point anywhere in their octant), the packets would
/// be traced ray by ray anyway, and putting the answers back into input order would cost more than
/// the order saves, so the batch is traced as given.
fn packets_pay(rays: &[QueryRay], permutation: &[u32]) -> bool {
    let packets = permutation.len() / PACKET;
    if packets == 0 {
        return false;
    }
    let sampled = packets.min(256);
    let coherent_count = (0..sampled)
        .filter(|&s| {
            let first = s * packets / sampled * PACKET;
            let lanes: [Ray; PACKET] = std::array::from_fn(|l| rays[permutation[first + l] as usize].ray);
            coherent(&lanes)
        })
        .count();
    4 * coherent_count >= sampled
}

/// Rays in the sample [`sample_may_pay`] sorts (about one in `len / COHERENCE_SAMPLE`).
const COHERENCE_SAMPLE: usize = 4096;

/// Whether sorting a batch may pay, judged on an evenly spread sample of it before the batch
/// itself is sorted: a batch of at least four samples' size whose sorted sample has no coherent
/// packets ([`packets_pay`]) has none to recover (random rays: sorted neighbours point anywhere),
/// so its sort (as long as tracing it, on a small mesh) is skipped. The sample is sparser than
/// the batch, so it finds fewer coherent neighbours than the batch would: a batch it turns down
/// is traced as given (the same answers); one it passes is sorted and judged again in full.
fn sample_may_pay(rays: &[QueryRay]) -> bool {
    if rays.len() < 4 * COHERENCE_SAMPLE {
        return true;
    }
    let sample: Vec<QueryRay> = rays.iter().step_by(rays.len() / COHERENCE_SAMPLE).copied().collect();
    packets_pay(&sample, &coherent_order(&sample))
}

/// Whether the rays point alike enough to be traced as a packet (see [`PACKET_COSINE`]).
fn coherent(lanes: &[Ray]) -> bool {
    let Some(first) = lanes.first() else {
        return true;
    };
    let first_len2 = first.dir.length_squared();
    lanes[1..].iter().all(|ray| {
        let dot = first.dir.dot(ray.dir);
        // `dot ≥ c·|a|·|b|`, squared (both sides are then non-negative)
        dot > 0.0 && dot * dot >= PACKET_COSINE * PACKET_COSINE * first_len2 * ray.dir.length_squared()
    })
}

/// The first hits of `rays[i]` for the (at most [`PACKET`]) indices `packet`, in `packet`'s
/// order (the lanes past `packet.len()` are misses): traced together
/// ([`Scene::intersect_packet`]) where they point alike ([`coherent`]), else one by one
/// ([`trace_one`]). If a root finder ran out of budget while a packet was traced, its rays are
/// traced again one by one to tell which.
fn trace_packet(scene: &Scene, rays: &[QueryRay], packet: &[u32]) -> [QueryHit; PACKET] {
    let n = packet.len().min(PACKET);
    let mut lanes = [Ray::new(DVec3::ZERO, DVec3::Z); PACKET];
    let mut ranges = [Interval::POSITIVE; PACKET];
    for (l, &i) in packet[..n].iter().enumerate() {
        lanes[l] = rays[i as usize].ray;
        ranges[l] = rays[i as usize].range;
    }
    let mut out = [QueryHit {
        hit: None,
        uncertain: false,
    }; PACKET];
    let exhausted_before = thread_uncertain_events();
    let mut found = [None; PACKET];
    // together where the rays point alike and no root finder ran out of budget meanwhile
    let together = coherent(&lanes[..n]) && {
        scene.intersect_packet(&lanes[..n], &ranges[..n], &mut found[..n]);
        thread_uncertain_events() == exhausted_before
    };
    if together {
        for l in 0..n {
            out[l].hit = found[l].map(|hit| completed(scene, &lanes[l], hit, ANSWER));
        }
    } else {
        for (l, &i) in packet[..n].iter().enumerate() {
            out[l] = trace_one(scene, &rays[i as usize]);
        }
    }
    out
}

/// One ray's first hit, with normal and uv, and whether its answer is uncertain: what
/// [`trace_batch`] gives for each of its rays.
#[inline]
#[must_use]
pub fn trace_one(scene: &Scene, q: &QueryRay) -> QueryHit {
    trace_one_for(scene, q, ANSWER)
}

/// [`trace_one`] with the hit completed as far as `request` asks: a normal or uv not asked for
/// is left `None` (not computed); everything else is as [`trace_one`] gives it.
#[inline]
#[must_use]
pub fn trace_one_for(scene: &Scene, q: &QueryRay, request: HitRequest) -> QueryHit {
    let (hit, uncertain) = uncertain_while(|| {
        let hit = scene.intersect(&q.ray, q.range)?;
        Some(completed(scene, &q.ray, hit, request))
    });
    QueryHit { hit, uncertain }
}

/// The hit `(object, raw)` of `ray`, completed as far as `request` asks.
#[inline]
fn completed(scene: &Scene, ray: &Ray, (object, raw): (u32, RawHit), request: HitRequest) -> (u32, SurfaceHit) {
    let primitive = &*scene.objects[object as usize].primitive;
    (object, SurfaceHit::complete(primitive, ray, &raw, request))
}

/// Room reused from batch to batch by [`trace_many_for`]: the rays of a batch, pushed one by one
/// ([`TraceWork::push`]), then traced together ([`TraceWork::trace`]).
#[derive(Debug, Default)]
pub struct TraceWork {
    rays: Vec<Ray>,
    ranges: Vec<Interval>,
    hits: Vec<Option<RawHit>>,
    objects: Vec<u32>,
    uncertain: Vec<bool>,
}

impl TraceWork {
    /// Forgets the rays of the last batch.
    #[inline]
    pub(crate) fn clear(&mut self) {
        self.rays.clear();
        self.ranges.clear();
    }

    /// Adds a ray and its accepted range to the batch.
    #[inline(always)]
    pub(crate) fn push(&mut self, ray: Ray, range: Interval) {
        self.rays.push(ray);
        self.ranges.push(range);
    }

    /// Adds rays that share one accepted range to the batch.
    #[inline(always)]
    pub(crate) fn push_sharing(&mut self, rays: impl ExactSizeIterator<Item = Ray>, range: Interval) {
        let n = rays.len();
        self.rays.extend(rays);
        self.ranges.extend(std::iter::repeat_n(range, n));
    }

    /// The rays pushed since the last [`TraceWork::clear`].
    #[cfg(test)]
    pub(crate) fn pushed(&self) -> Vec<QueryRay> {
        self.rays
            .iter()
            .zip(&self.ranges)
            .map(|(&ray, &range)| QueryRay { ray, range })
            .collect()
    }

    /// [`trace_one_for`] of every ray pushed, handed to `answer(i, hit, uncertain)` in the order
    /// pushed: the rays go to the scene together ([`Scene::intersect_each`]), then each hit is
    /// completed as far as `request` asks (a hit whose completion ran out of budget is
    /// uncertain too, as in [`trace_one_for`]).
    #[inline]
    pub(crate) fn trace(
        &mut self,
        scene: &Scene,
        request: HitRequest,
        mut answer: impl FnMut(usize, Option<&(u32, SurfaceHit)>, bool),
    ) {
        let n = self.rays.len();
        // sized, not cleared: `intersect_each` writes every entry (what the last batch left in
        // them is never read)
        self.hits.resize(n, None);
        self.objects.resize(n, 0);
        self.uncertain.resize(n, false);
        scene.intersect_each(
            &self.rays,
            &self.ranges,
            &mut self.hits,
            &mut self.objects,
            &mut self.uncertain,
        );
        let traced = self.hits.iter().zip(&self.objects).zip(&self.uncertain);
        for (i, (ray, ((&hit, &object), &traced_uncertain))) in self.rays.iter().zip(traced).enumerate() {
            match hit {
                None => answer(i, None, traced_uncertain),
                Some(raw) => {
                    let (hit, completed_uncertain) = uncertain_while(|| completed(scene, ray, (object, raw), request));
                    answer(i, Some(&hit), traced_uncertain || completed_uncertain);
                }
            }
        }
    }
}

/// [`trace_one_for`] of every ray of `rays`, into `answers` (of the same length): the same
/// answers, `uncertain` flags included, the rays handed to the scene together
/// ([`Scene::intersect_each`]) and the hits completed after.
pub fn trace_many_for(
    scene: &Scene,
    rays: &[QueryRay],
    request: HitRequest,
    work: &mut TraceWork,
    answers: &mut [QueryHit],
) {
    work.clear();
    for q in rays {
        work.push(q.ray, q.range);
    }
    work.trace(scene, request, |i, hit, uncertain| {
        answers[i] = QueryHit {
            hit: hit.copied(),
            uncertain,
        };
    });
}

/// A permutation of `rays` that puts coherent rays together: sorted by direction octant, then
/// by the Morton code of the origin (10 bits per axis over the batch's origin bounds), then by
/// the direction quantised to 5 bits per component. Ties keep the input order.
#[must_use]
pub fn coherent_order(rays: &[QueryRay]) -> Vec<u32> {
    let (lo, hi) = rays.par_iter().map(|q| (q.ray.origin, q.ray.origin)).reduce(
        || (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |a, b| (a.0.min(b.0), a.1.max(b.1)),
    );
    let extent = hi - lo;
    let scale = DVec3::select(extent.cmpgt(DVec3::ZERO), 1023.0 / extent, DVec3::ZERO);
    let spread = |v: u64| -> u64 {
        // the 10 low bits of `v` moved to every third bit
        let mut x = v & 0x3ff;
        x = (x | (x << 16)) & 0x0300_00ff;
        x = (x | (x << 8)) & 0x0300_f00f;
        x = (x | (x << 4)) & 0x030c_30c3;
        (x | (x << 2)) & 0x0924_9249
    };
    let mut keyed: Vec<(u64, u32)> = rays
        .par_iter()
        .enumerate()
        .map(|(i, q)| {
            let d = q.ray.dir;
            let octant = u64::from(d.x < 0.0) | u64::from(d.y < 0.0) << 1 | u64::from(d.z < 0.0) << 2;
            let cell = ((q.ray.origin - lo) * scale).clamp(DVec3::ZERO, DVec3::splat(1023.0));
            let morton = spread(cell.x as u64) | spread(cell.y as u64) << 1 | spread(cell.z as u64) << 2;
            let unit = d / d.abs().max_element();
            let quantised = ((unit + 1.0) * 15.5).clamp(DVec3::ZERO, DVec3::splat(31.0));
            let direction = (quantised.x as u64) << 10 | (quantised.y as u64) << 5 | quantised.z as u64;
            (octant << 45 | morton << 15 | direction, i as u32)
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// The checks every ray passes, whatever its format, and its construction as `setup` says
/// ([`crate::query_rays::ray_from_fields`]: range convention, spawned origins).
fn ray_from_fields(v: &[f64], setup: &RaySetup) -> Result<QueryRay, String> {
    let (ray, range) = crate::query_rays::ray_from_fields(v, setup)?;
    Ok(QueryRay { ray, range })
}

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
    ray_from_fields(&v, setup).map(CsvLine::Ray)
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
            let read = self.reader.read_line(buffer).map_err(|e| QueryError {
                path: self.path.clone(),
                location: (self.line_no + 1).to_string(),
                message: format!("reading: {e}"),
            })?;
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

/// The parts of an `.npy` header zeroset reads.
#[derive(Debug)]
struct NpyHeader {
    rows: u64,
    columns: usize,
    /// `true` for `f8`, `false` for `f4`.
    double: bool,
}

/// Parses the `.npy` preamble (magic, version, header dictionary) from `reader`.
fn read_npy_header(reader: &mut impl Read, path: &str) -> Result<NpyHeader, QueryError> {
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
    let text = String::from_utf8_lossy(&text).replace(' ', "");
    let value_of = |key: &str| -> Option<&str> {
        let start = text.find(&format!("'{key}':"))? + key.len() + 3;
        Some(&text[start..])
    };
    let descr = value_of("descr").ok_or_else(|| err(format!("no 'descr' in `{text}`")))?;
    let double = if descr.starts_with("'<f8'") {
        true
    } else if descr.starts_with("'<f4'") {
        false
    } else {
        return Err(err(format!(
            "dtype {} is not supported; use little-endian float64 ('<f8') or float32 ('<f4')",
            descr.split(',').next().unwrap_or(descr)
        )));
    };
    if !value_of("fortran_order").is_some_and(|v| v.starts_with("False")) {
        return Err(err(
            "Fortran-order arrays are not supported; save a C-order array".into()
        ));
    }
    let shape = value_of("shape")
        .and_then(|v| v.strip_prefix('('))
        .and_then(|v| v.split(')').next())
        .ok_or_else(|| err(format!("no 'shape' in `{text}`")))?;
    let dims: Vec<&str> = shape.split(',').filter(|s| !s.is_empty()).collect();
    let parse = |s: &str| {
        s.parse::<u64>()
            .map_err(|_| err(format!("shape ({shape}) is not an integer tuple")))
    };
    if dims.len() != 2 {
        return Err(err(format!("shape ({shape}): expected (N, 6) or (N, 8)")));
    }
    let (rows, columns) = (parse(dims[0])?, parse(dims[1])?);
    if ![6, 8, 9, MAX_COLUMNS as u64].contains(&columns) {
        return Err(err(format!("shape ({shape}): expected (N, 6) or (N, 8)")));
    }
    Ok(NpyHeader {
        rows,
        columns: columns as usize,
        double,
    })
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
                ray_from_fields(&v[..columns], &setup)
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

/// Columns of the `.npy` output (without the optional `uncertain` column).
pub const NPY_HIT_COLUMNS: usize = 11;

/// Length of the `.npy` output preamble: fixed, so the row count can be patched in at the end.
const NPY_PREAMBLE_LEN: usize = 128;

/// The `.npy` (version 1.0) preamble of an `f8` array of shape `(rows, columns)`, padded with
/// spaces to [`NPY_PREAMBLE_LEN`] bytes.
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A source of in-memory rays that fails when asked for chunk `fail_at`.
    struct FailingRays {
        rays: Vec<QueryRay>,
        taken: usize,
        chunk: usize,
        fail_at: Option<usize>,
    }

    impl RaySource for FailingRays {
        fn read_chunk(&mut self, max: usize, out: &mut Vec<QueryRay>) -> Result<bool, QueryError> {
            out.clear();
            if self.fail_at == Some(self.chunk) {
                return Err(QueryError {
                    path: "rays".into(),
                    location: format!("chunk {}", self.chunk),
                    message: "unreadable".into(),
                });
            }
            self.chunk += 1;
            let end = (self.taken + max).min(self.rays.len());
            out.extend_from_slice(&self.rays[self.taken..end]);
            self.taken = end;
            Ok(end < self.rays.len())
        }
    }

    /// A sink keeping the rows it is given, that fails when given chunk `fail_at`.
    #[derive(Default)]
    struct KeptRows {
        rows: Vec<QueryHit>,
        chunks: usize,
        fail_at: Option<usize>,
        finished: bool,
    }

    impl HitSink for KeptRows {
        fn write_chunk(&mut self, _scene: &Scene, hits: &[QueryHit]) -> std::io::Result<()> {
            if self.fail_at == Some(self.chunks) {
                return Err(std::io::Error::other("disk full"));
            }
            self.chunks += 1;
            self.rows.extend_from_slice(hits);
            Ok(())
        }

        fn finish(&mut self) -> std::io::Result<()> {
            self.finished = true;
            Ok(())
        }
    }

    /// The batch loop, which reads the next chunk and writes the last one while it traces one,
    /// writes and reports as if it took the chunks one after the other: every row in order (on
    /// one thread and on three), the rows of the chunks before an unreadable one written and its
    /// error returned, and a write error returned before the read error of a later chunk.
    #[test]
    fn the_batch_loop_writes_and_fails_in_chunk_order() {
        let scene = Scene::from_ron(
            "Scene(camera: (), objects: [(shape: Sphere(center: (0, 0, 0), radius: 1))])",
            "t.ron",
        )
        .unwrap();
        let n = 2 * CHUNK_RAYS + 1000;
        let rays: Vec<QueryRay> = (0..n)
            .map(|i| {
                let a = i as f64 * 0.618_033_988_749_895;
                QueryRay {
                    ray: Ray::new(DVec3::new(a.sin() * 1.5, a.cos() * 1.5, -3.0), DVec3::Z),
                    range: Interval::POSITIVE,
                }
            })
            .collect();
        let expected = trace_batch(&scene, &rays);
        let source = |fail_at| FailingRays {
            rays: rays.clone(),
            taken: 0,
            chunk: 0,
            fail_at,
        };
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut sink = KeptRows::default();
            let counts = pool
                .install(|| run_batch(&scene, &mut source(None), &mut sink))
                .unwrap();
            assert_eq!(counts.rays, n as u64);
            assert_eq!(counts.hits, expected.iter().filter(|h| h.hit.is_some()).count() as u64);
            assert!(sink.finished && sink.chunks == 3);
            assert!(sink.rows == expected, "{threads} threads: rows in order");
            // the third chunk unreadable: the first two written, not finished
            let mut sink = KeptRows::default();
            let error = pool
                .install(|| run_batch(&scene, &mut source(Some(2)), &mut sink))
                .unwrap_err();
            assert_eq!(error.to_string(), "rays:chunk 2: unreadable");
            assert!(!sink.finished && sink.rows[..] == expected[..2 * CHUNK_RAYS]);
            // the second chunk's write fails before the third is found unreadable
            let mut sink = KeptRows {
                fail_at: Some(1),
                ..KeptRows::default()
            };
            let error = pool
                .install(|| run_batch(&scene, &mut source(Some(2)), &mut sink))
                .unwrap_err();
            assert_eq!(error.to_string(), "disk full");
            assert!(!sink.finished && sink.rows[..] == expected[..CHUNK_RAYS]);
        }
    }

    /// Rays handed to the scene together ([`trace_many_for`]) get exactly the answers they get
    /// one by one, `uncertain` flags included: a lone object (the batch handed to it in one
    /// call), a lone `Function` whose budget of 4 evaluations runs out on the rays through its
    /// sphere (flagged ray by ray), and three objects; in each, some directions 10⁻³⁰⁰ or 10³⁰⁰
    /// long (rescaled, so not handed over together).
    #[test]
    fn rays_traced_together_equal_rays_traced_one_by_one() {
        use rand::{Rng, SeedableRng};
        let scenes = [
            "Scene(camera: (), objects: [(shape: Sphere(center: (0, 0, 0), radius: 1))])",
            "Scene(camera: (), objects: [(shape: Function(phi: \"sqrt(x^2 + y^2 + z^2) - 1\", \
             min: (-2, -2, -2), max: (2, 2, 2), budget: 4))])",
            "Scene(camera: (), objects: [(shape: Sphere(center: (0, 0, 0), radius: 1)), \
             (shape: Box(min: (2, -1, -1), max: (3, 1, 1))), (shape: Plane(normal: (0, 1, 0), point: (0, -2, 0)))])",
        ];
        let mut rng = rand::rngs::StdRng::seed_from_u64(14);
        for (which, text) in scenes.iter().enumerate() {
            let scene = Scene::from_ron(text, "t.ron").unwrap();
            let rays: Vec<QueryRay> = (0..3000)
                .map(|i| {
                    let o = DVec3::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0), -4.0);
                    let aim = DVec3::new(rng.random_range(-1.5..1.5), rng.random_range(-1.5..1.5), 0.0);
                    let scale = match i % 97 {
                        0 => 1e-300,
                        1 => 1e300,
                        _ => 1.0,
                    };
                    QueryRay {
                        ray: Ray::new(o, (aim - o) * scale),
                        range: Interval::POSITIVE,
                    }
                })
                .collect();
            let one_by_one: Vec<QueryHit> = rays.iter().map(|q| trace_one(&scene, q)).collect();
            let mut work = TraceWork::default();
            let mut together = vec![MISS; rays.len()];
            for (rays, answers) in rays.chunks(256).zip(together.chunks_mut(256)) {
                trace_many_for(&scene, rays, ANSWER, &mut work, answers);
            }
            assert_eq!(together, one_by_one, "scene {which}");
            assert_eq!(trace_batch(&scene, &rays), one_by_one, "scene {which}");
            let hits = one_by_one.iter().filter(|a| a.hit.is_some()).count();
            let uncertain = one_by_one.iter().filter(|a| a.uncertain).count();
            assert!(hits > 300, "scene {which}: {hits} hits");
            assert_eq!(uncertain > 100, which == 1, "scene {which}: {uncertain} uncertain");
        }
    }

    /// Tracing in the coherent order gives every ray the same answer as the input order, in
    /// input order, and the order is a permutation.
    #[test]
    fn sorted_order_gives_the_same_answers() {
        use rand::{Rng, SeedableRng};
        let scene = Scene::from_ron(
            "Scene(camera: (), objects: [(shape: Sphere(center: (0, 0, 0), radius: 1)), \
             (shape: Box(min: (2, -1, -1), max: (3, 1, 1))), (shape: Plane(normal: (0, 1, 0), point: (0, -2, 0)))])",
            "t.ron",
        )
        .unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let rays: Vec<QueryRay> = (0..5000)
            .map(|_| {
                let o = DVec3::new(
                    rng.random_range(-4.0..4.0),
                    rng.random_range(-1.5..4.0),
                    rng.random_range(-4.0..4.0),
                );
                let d = DVec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                QueryRay {
                    ray: Ray::new(o, d),
                    range: Interval::new(0.0, f64::INFINITY),
                }
            })
            .collect();
        let mut order = coherent_order(&rays);
        assert_ne!(order, (0..5000).collect::<Vec<u32>>(), "random rays get reordered");
        order.sort_unstable();
        assert_eq!(order, (0..5000).collect::<Vec<u32>>());
        // random rays: sorted neighbours point anywhere, so the batch is traced as given
        assert!(!packets_pay(&rays, &coherent_order(&rays)));
        let input = trace_batch_in(&scene, &rays, RayOrder::Input);
        let sorted = trace_batch_in(&scene, &rays, RayOrder::Sorted);
        assert!(input.iter().filter(|h| h.hit.is_some()).count() > 1000);
        assert_eq!(input, sorted);
        // four cameras' rays, shuffled: sorting gathers each camera's neighbouring rays into
        // packets, which are traced together and give the same answers
        let mut views: Vec<QueryRay> = (0..4000)
            .map(|i| {
                let eye = DVec3::new(f64::from(i % 4) - 1.5, 0.5, -6.0);
                let (u, v) = (f64::from(i / 4 % 40) / 40.0 - 0.5, f64::from(i / 160) / 25.0 - 0.5);
                QueryRay {
                    ray: Ray::new(eye, DVec3::new(u * 0.8, v * 0.8, 1.0)),
                    range: Interval::new(0.0, f64::INFINITY),
                }
            })
            .collect();
        for k in (1..views.len()).rev() {
            views.swap(k, rng.random_range(0..=k));
        }
        assert!(packets_pay(&views, &coherent_order(&views)));
        // judged on a sample first: many random rays are turned down before any sort, many
        // cameras' shuffled rays (a sample of one in ten) are still found coherent
        let many_random: Vec<QueryRay> = rays.iter().cycle().take(40_000).copied().collect();
        assert!(!sample_may_pay(&many_random));
        let mut many_views: Vec<QueryRay> = (0..40_000)
            .map(|i| {
                let eye = DVec3::new(f64::from(i % 4) - 1.5, 0.5, -6.0);
                let (u, v) = (f64::from(i / 4 % 100) / 100.0 - 0.5, f64::from(i / 400) / 100.0 - 0.5);
                QueryRay {
                    ray: Ray::new(eye, DVec3::new(u * 0.8, v * 0.8, 1.0)),
                    range: Interval::new(0.0, f64::INFINITY),
                }
            })
            .collect();
        for k in (1..many_views.len()).rev() {
            many_views.swap(k, rng.random_range(0..=k));
        }
        assert!(sample_may_pay(&many_views) && sample_may_pay(&views));
        let input = trace_batch_in(&scene, &views, RayOrder::Input);
        let sorted = trace_batch_in(&scene, &views, RayOrder::Sorted);
        assert!(input.iter().filter(|h| h.hit.is_some()).count() > 1000);
        assert_eq!(input, sorted);
    }

    fn origins(rays: &[QueryRay]) -> Vec<f64> {
        rays.iter().map(|r| r.ray.origin.x).collect()
    }

    #[test]
    fn first_line_is_a_ray_unless_it_is_the_documented_header() {
        let bom = "\u{feff}1,0,-5,0,0,1\n2,0,-5,0,0,1\n";
        assert_eq!(origins(&parse_rays(bom, "r").unwrap()), [1.0, 2.0]);
        let spaced = " 1 , 0, -5, 0, 0, 1 \n2,0,-5,0,0,1\n";
        assert_eq!(origins(&parse_rays(spaced, "r").unwrap()), [1.0, 2.0]);
        let header = "\u{feff}ox, oy, oz, dx, dy, dz, tmin, tmax\n1,0,-5,0,0,1,0,9\n";
        assert_eq!(origins(&parse_rays(header, "r").unwrap()), [1.0]);
        for (text, needle) in [
            ("1;0;-5;0;0;1\n", "r:1: fields are separated by commas"),
            ("1,0,-5,0,0,1,\n", "r:1: field 7 is empty (a trailing comma?)"),
            ("1 0 -5 0 0 1\n", "r:1: field 1 `1 0 -5 0 0 1` is not a number"),
            ("x,y,z,dx,dy,dz\n1,0,-5,0,0,1\n", "r:1: field 1 `x`"),
            (
                "1,0,-5,0,0,1\nox,oy,oz,dx,dy,dz\n",
                "r:2: a header line is allowed only before",
            ),
        ] {
            let err = parse_rays(text, "r").unwrap_err().to_string();
            assert!(err.starts_with(needle), "{text:?}: {err}");
        }
    }

    #[test]
    fn chunks_keep_line_numbers_and_order() {
        let mut text = String::from("# comment\n");
        for i in 0..10 {
            let _ = writeln!(text, "{i},0,0,0,0,1");
        }
        text.push_str("bad\n");
        let mut source = CsvRays::new(text.as_bytes(), "r");
        let mut chunk = Vec::new();
        let mut seen = Vec::new();
        let err = loop {
            match source.read_chunk(3, &mut chunk) {
                Ok(_) => seen.extend(origins(&chunk)),
                Err(e) => break e,
            }
        };
        // chunks of three lines: the fourth (lines 10–12) holds the error and is not returned
        assert_eq!(seen, (0..8).map(f64::from).collect::<Vec<_>>());
        assert_eq!(err.location, "12");
    }

    #[test]
    fn npy_preamble_is_aligned_and_round_trips() {
        let p = npy_preamble(12_345_678_901, NPY_HIT_COLUMNS + 1);
        assert_eq!(p.len(), NPY_PREAMBLE_LEN);
        assert_eq!(p.len() % 64, 0, "NumPy aligns the data to 64 bytes");
        let header = read_npy_header(&mut p.as_slice(), "h").unwrap_err();
        // 12 columns are not a ray array: the header parses, the shape is refused
        assert!(header.message.contains("(12345678901,12)"), "{header}");
        let rays = npy_preamble(7, 8);
        let h = read_npy_header(&mut rays.as_slice(), "h").unwrap();
        assert_eq!((h.rows, h.columns, h.double), (7, 8, true));
    }
}
