//! How a line of `zeroset query` input becomes a ray: its parameter range and, for rays that
//! start on a surface, a spawned origin.
//!
//! **Columns.** `ox,oy,oz,dx,dy,dz`, optionally `,tmin,tmax`, optionally followed by the surface
//! normal at the origin `,nx,ny,nz` (6, 8, 9 or 11 numbers).
//!
//! **Range.** By default the range is open at its start, `tmin < t ≤ tmax` (`tmin = 0`,
//! `tmax = +∞` when not given): the first hit with `t > 0`, the classic definition, so an origin
//! lying exactly on a face, cap or plane does not report that surface at `t = 0`. With
//! [`RangeConvention::Closed`] (`--closed-range`) it is `tmin ≤ t ≤ tmax`.
//!
//! **Spawned origins.** With a [`PointPrecision`] (`--origin-precision f32|f64|E`) every line must
//! carry the normal, and the origin is replaced by
//! `zeroset_primitives::offset::spawn_origin(origin, normal, dir, precision, magnitude)`, with
//! `magnitude` the largest coordinate magnitude of the scene's bounded objects: a ray cast from a
//! stored (e.g. float32) hit point cannot re-hit the surface it starts on through rounding, and
//! loses no hit farther than `spawn_distance` from the point (see `docs/numerics.md`).
//!
//! **Columns.** Rays already in memory as arrays (the Python package's numpy arrays) are a
//! [`RayColumns`]: each ray is built by the same [`ray_from_fields`] as a line of input, and
//! [`trace_columns`] builds a chunk of [`COLUMN_CHUNK`] rays at a time, in parallel, then traces
//! them ([`crate::query::trace_one`]) and hands the chunk's hits over together, so rays and hit
//! records only ever exist for the chunks in flight (cache-sized), and the caller writes the
//! answers straight into its own output buffers.

use super::batch::{QueryRay, TraceWork};
use crate::scene::Scene;
use glam::DVec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use zeroset_primitives::offset::{spawn_origin, PointPrecision};
use zeroset_primitives::{HitRequest, Interval, Ray, SurfaceHit};

/// Whether the query range includes its start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RangeConvention {
    /// `tmin < t ≤ tmax` (the default).
    #[default]
    OpenStart,
    /// `tmin ≤ t ≤ tmax`.
    Closed,
}

impl RangeConvention {
    /// `Closed` when `closed`, else the default `OpenStart` (the `--closed-range` flag).
    #[must_use]
    pub fn closed_if(closed: bool) -> Self {
        if closed {
            Self::Closed
        } else {
            Self::OpenStart
        }
    }

    /// The accepted range of `tmin ≤ tmax` (checked by the caller) under this convention: from
    /// the next f64 above `tmin` (`OpenStart`) or from `tmin` itself (`Closed`), to `tmax`.
    #[inline]
    #[must_use]
    pub fn range(self, tmin: f64, tmax: f64) -> Interval {
        let min = match self {
            Self::OpenStart => tmin.next_up(),
            Self::Closed => tmin,
        };
        Interval::new(min, tmax)
    }
}

/// Element `i` of a column holding one value for every ray (`tmin`, `tmax`) or one per ray.
#[inline(always)]
fn per_ray(column: &[f64], i: usize) -> f64 {
    column[if column.len() == 1 { 0 } else { i }]
}

/// How input lines become rays.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RaySetup {
    /// The range convention.
    pub range: RangeConvention,
    /// The precision of the origins, when they are points on surfaces to spawn from.
    pub origin_precision: Option<PointPrecision>,
    /// Largest coordinate magnitude the scene's closed forms compute with (for spawning).
    pub magnitude: f64,
}

/// The largest coordinate magnitude over the scene's bounded objects (`offset::magnitude` of
/// their world bounds; unbounded ones, planes, contribute 0).
#[must_use]
pub fn scene_magnitude(scene: &Scene) -> f64 {
    scene
        .objects
        .iter()
        .map(|o| zeroset_primitives::offset::magnitude(&o.primitive.bounds()))
        .fold(0.0, f64::max)
}

/// A ray with its accepted `t` range, from one line's numbers (see the module docs); the error
/// says what is wrong with the line.
pub fn ray_from_fields(v: &[f64], setup: &RaySetup) -> Result<(Ray, Interval), String> {
    if ![6, 8, 9, 11].contains(&v.len()) {
        return Err(format!(
            "expected 6, 8, 9 or 11 fields `ox,oy,oz,dx,dy,dz[,tmin,tmax][,nx,ny,nz]`, got {}",
            v.len()
        ));
    }
    let origin = DVec3::new(v[0], v[1], v[2]);
    let dir = DVec3::new(v[3], v[4], v[5]);
    let (tmin, tmax) = if v.len() == 8 || v.len() == 11 {
        (v[6], v[7])
    } else {
        (0.0, f64::INFINITY)
    };
    let normal = (v.len() == 9 || v.len() == 11).then(|| DVec3::new(v[v.len() - 3], v[v.len() - 2], v[v.len() - 1]));
    checked_ray(origin, dir, tmin, tmax, normal, setup)
}

/// The smallest accepted largest component of a ray direction, `2⁻⁵¹¹ ≈ 1.5·10⁻¹⁵⁴`. `t` is in
/// units of `|d|`, so a hit at distance `D` has `t = D/|d|`, which overflows to `+∞` (and could
/// only be reported as a miss) once `D > |d|·1.8·10³⁰⁸`; from this length on that needs
/// `D > 2⁵¹²`, beyond any coordinate whose square is finite. Shorter directions are refused.
pub const MIN_DIRECTION: f64 = f64::from_bits((1023 - 511) << 52);

/// The ray of one line's values, already split into their columns (`normal` where the line has
/// one): every check of the module docs, the spawned origin and the range convention.
#[inline(always)]
fn checked_ray(
    origin: DVec3,
    dir: DVec3,
    tmin: f64,
    tmax: f64,
    normal: Option<DVec3>,
    setup: &RaySetup,
) -> Result<(Ray, Interval), String> {
    if !origin.is_finite() || !dir.is_finite() {
        return Err("origin and direction must be finite".into());
    }
    if dir == DVec3::ZERO {
        return Err("direction must be non-zero".into());
    }
    if dir.abs().max_element() < MIN_DIRECTION {
        return Err(format!(
            "direction ({:e}, {:e}, {:e}) is too short: its largest component is below 2^-511 \
             ≈ 1.5e-154, where t (in units of |d|) overflows for hits farther than |d|·1.8e308; \
             scale or normalise the direction",
            dir.x, dir.y, dir.z
        ));
    }
    if tmin.is_nan() || tmax.is_nan() || tmin > tmax {
        return Err(format!("invalid t range [{tmin}, {tmax}]"));
    }
    let origin = match (setup.origin_precision, normal) {
        (None, None) => origin,
        (None, Some(_)) => {
            return Err("normal columns nx,ny,nz are only used with --origin-precision f32|f64|E".into());
        }
        (Some(_), None) => {
            return Err("--origin-precision needs the surface normal: add columns nx,ny,nz".into());
        }
        (Some(precision), Some(n)) => {
            if !n.is_finite() || n == DVec3::ZERO {
                return Err(format!("normal must be finite and non-zero, got {n}"));
            }
            spawn_origin(origin, n, dir, precision, setup.magnitude)
        }
    };
    Ok((Ray::new(origin, dir), setup.range.range(tmin, tmax)))
}

/// Rays per step of [`trace_columns`]: the rays of one chunk (about 64 bytes a ray) stay in a
/// core's cache between building and tracing, and one thread does all of a chunk.
pub const COLUMN_CHUNK: usize = 256;

/// Rays as columns: `origins` and `directions` flat `[x₀, y₀, z₀, x₁, …]`, `tmin` and `tmax` one
/// value for every ray or one per ray, and optionally the surface normals at the origins (flat like
/// the origins) for spawned origins.
#[derive(Clone, Copy, Debug)]
pub struct RayColumns<'a> {
    origins: &'a [f64],
    directions: &'a [f64],
    tmin: &'a [f64],
    tmax: &'a [f64],
    normals: Option<&'a [f64]>,
}

impl<'a> RayColumns<'a> {
    /// Checks that the columns agree in length; the error names the column that does not.
    ///
    /// # Errors
    /// A length that is not a multiple of 3, columns of different ray counts, or a `tmin`/`tmax`
    /// that is neither one value nor one per ray.
    pub fn new(
        origins: &'a [f64],
        directions: &'a [f64],
        tmin: &'a [f64],
        tmax: &'a [f64],
        normals: Option<&'a [f64]>,
    ) -> Result<Self, String> {
        if origins.len() % 3 != 0 {
            return Err(format!("origins: {} values are not rows of 3", origins.len()));
        }
        let n = origins.len() / 3;
        if directions.len() != origins.len() {
            return Err(format!(
                "origins and directions differ in length: {n} and {}",
                directions.len() / 3
            ));
        }
        if let Some(normals) = normals {
            if normals.len() != origins.len() {
                return Err(format!("normals: expected {n} rows, got {}", normals.len() / 3));
            }
        }
        for (name, column) in [("tmin", tmin), ("tmax", tmax)] {
            if column.len() != 1 && column.len() != n {
                return Err(format!("{name}: expected a scalar or {n} values, got {}", column.len()));
            }
        }
        Ok(Self {
            origins,
            directions,
            tmin,
            tmax,
            normals,
        })
    }

    /// Number of rays.
    #[must_use]
    pub fn len(&self) -> usize {
        self.origins.len() / 3
    }

    /// Whether there are no rays.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.origins.is_empty()
    }

    /// Ray `i`, exactly as [`ray_from_fields`] builds it from the same numbers on one line.
    ///
    /// # Errors
    /// What is wrong with the ray (see [`ray_from_fields`]).
    ///
    /// # Panics
    /// If `i ≥ self.len()`.
    #[inline]
    pub fn ray(&self, i: usize, setup: &RaySetup) -> Result<QueryRay, String> {
        let row = |values: &[f64]| DVec3::from_slice(&values[3 * i..3 * i + 3]);
        let (ray, range) = checked_ray(
            row(self.origins),
            row(self.directions),
            per_ray(self.tmin, i),
            per_ray(self.tmax, i),
            self.normals.map(row),
            setup,
        )?;
        Ok(QueryRay { ray, range })
    }

    /// Asks memory for the origins and directions of the rays of `chunk` (clamped to the
    /// columns): [`trace_columns`] requests the next chunk's while it traces one, so that
    /// building the next does not wait on memory (`cast_rays`, 10⁶ random rays: 2–3 % faster on
    /// the level-4 and level-6 meshes; the same requests spread over the chunk's answers, a line
    /// a ray, measured alike).
    fn request(&self, chunk: std::ops::Range<usize>) {
        let values = 3 * chunk.start.min(self.len())..3 * chunk.end.min(self.len());
        for column in [&self.origins[values.clone()], &self.directions[values]] {
            for line in column.chunks(8) {
                zeroset_primitives::bvh::prefetch(line.as_ptr());
            }
        }
    }

    /// Rays `chunk` (indices) pushed to `out` as [`RayColumns::ray`] builds them, when every
    /// one is plain: no normals and no spawned origin, origin and direction finite, direction
    /// non-zero, `tmin ≤ tmax` (neither NaN). The checks run over the whole chunk at once, in
    /// loops without early exits (which the compiler vectorises), so a batch of good rays skips
    /// the per-ray error paths. `false`, with `out` untouched, where any ray is not plain: build
    /// that chunk ray by ray, which says what is wrong.
    #[inline]
    fn plain_rays(&self, chunk: std::ops::Range<usize>, setup: &RaySetup, out: &mut TraceWork) -> bool {
        if self.normals.is_some() || setup.origin_precision.is_some() {
            return false;
        }
        let values = 3 * chunk.start..3 * chunk.end;
        let (origins, directions) = (&self.origins[values.clone()], &self.directions[values]);
        // `|v| ≤ MAX` is false for ±∞ and NaN
        let finite = |column: &[f64]| column.iter().fold(true, |ok, v| ok & (v.abs() <= f64::MAX));
        let nonzero = directions.chunks_exact(3).fold(true, |ok, d| {
            ok & (d[0].abs().max(d[1].abs()).max(d[2].abs()) >= MIN_DIRECTION)
        });
        let at = |column: &'a [f64]| -> &'a [f64] {
            if column.len() == 1 {
                column
            } else {
                &column[chunk.clone()]
            }
        };
        let (tmin, tmax) = (at(self.tmin), at(self.tmax));
        // `a ≤ b` is false where either is NaN
        let ordered = if tmin.len() == tmax.len() {
            tmin.iter().zip(tmax).fold(true, |ok, (a, b)| ok & (a <= b))
        } else if tmin.len() == 1 {
            tmax.iter().fold(true, |ok, b| ok & (tmin[0] <= *b))
        } else {
            tmin.iter().fold(true, |ok, a| ok & (*a <= tmax[0]))
        };
        if !(finite(origins) & finite(directions) & nonzero & ordered) {
            return false;
        }
        let rays = origins
            .chunks_exact(3)
            .zip(directions.chunks_exact(3))
            .map(|(o, d)| Ray::new(DVec3::new(o[0], o[1], o[2]), DVec3::new(d[0], d[1], d[2])));
        if let ([tmin], [tmax]) = (tmin, tmax) {
            // one range for every ray (the common call): made once
            out.push_sharing(rays, setup.range.range(*tmin, *tmax));
        } else {
            for (k, ray) in rays.enumerate() {
                out.push(ray, setup.range.range(per_ray(tmin, k), per_ray(tmax, k)));
            }
        }
        true
    }

    /// Every ray, built in parallel.
    ///
    /// # Errors
    /// The first bad ray by index: `(index, what is wrong)`.
    pub fn rays(&self, setup: &RaySetup) -> Result<Vec<QueryRay>, (usize, String)> {
        let rays: Result<Vec<QueryRay>, ()> = (0..self.len())
            .into_par_iter()
            .map(|i| self.ray(i, setup).map_err(|_| ()))
            .collect();
        // a parallel collect stops at whichever bad ray a thread met first, not at the first by
        // index: look for that one
        rays.map_err(|()| {
            (0..self.len())
                .into_par_iter()
                .find_map_first(|i| self.ray(i, setup).err().map(|message| (i, message)))
                .expect("a ray failed to build")
        })
    }
}

/// Where [`trace_columns`] writes the answers of one chunk of rays (rows `0..len`, `len` at
/// most [`COLUMN_CHUNK`]).
pub trait ChunkAnswers: Send {
    /// Writes every row as a miss that is not uncertain: called once, before the chunk's rays are
    /// traced. Filling whole columns at once costs a fraction of writing the rows one by one, and
    /// most random rays miss.
    fn misses(&mut self, len: usize);

    /// Writes row `i`: a hit, or a miss flagged uncertain (`hit` is `None`). Called in ray order,
    /// once for each row that is not a certain miss ([`ChunkAnswers::misses`] wrote those).
    fn put(&mut self, i: usize, hit: Option<&(u32, SurfaceHit)>, uncertain: bool);
}

/// First hits of every ray of `columns` (built as [`RayColumns::ray`] does, traced as
/// [`crate::query::trace_one_for`] traces each, completed as far as `request` asks), written
/// into `outputs[k]` for the rays `k·COLUMN_CHUNK + i` (`i` below [`COLUMN_CHUNK`]): first every
/// row as a miss ([`ChunkAnswers::misses`]), then the rows of the hits and uncertain misses in
/// ray order ([`ChunkAnswers::put`]), so that the caller writes each answer straight into its
/// own buffers. Chunks run in parallel on rayon's pool, each built, traced (handed to the scene
/// together, [`crate::scene::Scene::intersect_each`]) and written while in cache: no ray or hit
/// record outlives its chunk. With the full request ([`crate::query::ANSWER`]) the answers equal
/// [`crate::query::trace_batch`] on all the rays at once (every ray is traced on its own).
///
/// # Errors
/// The first bad ray by index, `(index, what is wrong)`; every ray is still checked (so the
/// reported one is the first), but no chunk is traced once one is found, and the outputs are then
/// partly filled.
///
/// # Panics
/// If `outputs` does not hold one entry per chunk (`len.div_ceil(COLUMN_CHUNK)`).
pub fn trace_columns<O: ChunkAnswers>(
    scene: &Scene,
    columns: &RayColumns<'_>,
    setup: &RaySetup,
    request: HitRequest,
    outputs: Vec<O>,
) -> Result<(), (usize, String)> {
    let n = columns.len();
    assert_eq!(outputs.len(), n.div_ceil(COLUMN_CHUNK), "one output per chunk of rays");
    let failed = AtomicBool::new(false);
    let first_error: Mutex<Option<(usize, String)>> = Mutex::new(None);
    outputs
        .into_par_iter()
        .enumerate()
        .for_each_init(TraceWork::default, |work, (k, mut out)| {
            let chunk = k * COLUMN_CHUNK..((k + 1) * COLUMN_CHUNK).min(n);
            work.clear();
            // the chunk's rays at once where all are plain, else one by one (which finds the bad one)
            if !columns.plain_rays(chunk.clone(), setup, work) {
                for i in chunk.clone() {
                    match columns.ray(i, setup) {
                        Ok(q) => work.push(q.ray, q.range),
                        Err(message) => {
                            failed.store(true, Ordering::Relaxed);
                            let mut first = first_error.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                            if first.as_ref().is_none_or(|(j, _)| i < *j) {
                                *first = Some((i, message));
                            }
                            return;
                        }
                    }
                }
            }
            if !failed.load(Ordering::Relaxed) {
                out.misses(chunk.len());
                // the next chunk's rays (most often this thread's next) arrive while this one is traced
                columns.request((k + 1) * COLUMN_CHUNK..(k + 2) * COLUMN_CHUNK);
                work.trace(scene, request, |i, hit, uncertain| {
                    if hit.is_some() || uncertain {
                        out.put(i, hit, uncertain);
                    }
                });
            }
        });
    match first_error
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
    {
        Some(error) => Err(error),
        None => Ok(()),
    }
}

/// The checks every ray passes, whatever its format, and its construction as `setup` says
/// ([`crate::query::rays::ray_from_fields`]: range convention, spawned origins).
pub(crate) fn query_ray_from_fields(v: &[f64], setup: &RaySetup) -> Result<QueryRay, String> {
    let (ray, range) = ray_from_fields(v, setup)?;
    Ok(QueryRay { ray, range })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::query::{trace_batch, QueryHit, ANSWER};

    /// Rays built from columns equal the rays (or the errors) `ray_from_fields` makes of the same
    /// numbers on one line, under both range conventions, good rays and bad ones alike (the two
    /// take their values apart differently, then share `checked_ray`).
    #[test]
    fn column_rays_equal_line_rays() {
        let values = [0.0, -0.0, 1.5, -2.0, 1e300, f64::INFINITY, f64::NEG_INFINITY, f64::NAN];
        let mut state = 12345u64;
        let mut pick = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            // mostly ordinary numbers, sometimes one of the special values
            let r = (state >> 33) as usize;
            if r % 5 == 0 {
                values[r / 5 % values.len()]
            } else {
                (r % 2001) as f64 / 100.0 - 10.0
            }
        };
        let n = 4000;
        let origins: Vec<f64> = (0..3 * n).map(|_| pick()).collect();
        let directions: Vec<f64> = (0..3 * n).map(|k| if k % 7 == 0 { 0.0 } else { pick() }).collect();
        let tmin: Vec<f64> = (0..n).map(|_| pick()).collect();
        let tmax: Vec<f64> = (0..n).map(|_| pick()).collect();
        let normals: Vec<f64> = (0..3 * n).map(|_| pick()).collect();
        let (mut good, mut bad) = (0, 0);
        // without normals, and with them (spawned origins, and the error without a precision)
        let cases = [
            (RangeConvention::OpenStart, None, None),
            (RangeConvention::Closed, None, None),
            (
                RangeConvention::OpenStart,
                Some(&normals[..]),
                Some(PointPrecision::F32),
            ),
            (RangeConvention::Closed, Some(&normals[..]), None),
        ];
        for (range, normals, origin_precision) in cases {
            let columns = RayColumns::new(&origins, &directions, &tmin, &tmax, normals).unwrap();
            let setup = RaySetup {
                range,
                origin_precision,
                magnitude: 10.0,
            };
            for i in 0..n {
                let mut fields = origins[3 * i..3 * i + 3].to_vec();
                fields.extend_from_slice(&directions[3 * i..3 * i + 3]);
                fields.extend_from_slice(&[tmin[i], tmax[i]]);
                if let Some(normals) = normals {
                    fields.extend_from_slice(&normals[3 * i..3 * i + 3]);
                }
                let line = ray_from_fields(&fields, &setup).map(|(ray, range)| QueryRay { ray, range });
                let column = columns.ray(i, &setup);
                match (&column, &line) {
                    (Ok(c), Ok(l)) => {
                        good += 1;
                        // bit for bit (NaN-free: good rays are finite)
                        assert_eq!(format!("{c:?}"), format!("{l:?}"), "ray {i}");
                    }
                    (Err(c), Err(l)) => {
                        bad += 1;
                        assert_eq!(c, l, "ray {i}");
                    }
                    _ => panic!("ray {i}: columns {column:?}, line {line:?}"),
                }
            }
        }
        assert!(good > 2000 && bad > 2000, "{good} good, {bad} bad");
    }

    /// A chunk built at once ([`RayColumns::plain_rays`]) holds exactly the rays
    /// [`RayColumns::ray`] builds one by one, and a chunk is refused exactly where one of its rays
    /// is bad or the rays spawn from normals: per-ray and scalar `tmin`/`tmax`, both range
    /// conventions, chunks of 1 to 40 rays with a bad value now and then.
    #[test]
    fn plain_chunks_equal_rays_built_one_by_one() {
        let mut state = 99u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as usize
        };
        let n = 3000;
        let special = [f64::NAN, f64::INFINITY, 0.0, -0.0, 1e300];
        let mut value = |bad_one_in: usize| {
            let r = next();
            if r % bad_one_in == 0 {
                special[r / bad_one_in % special.len()]
            } else {
                (r % 2001) as f64 / 100.0 - 10.0
            }
        };
        let origins: Vec<f64> = (0..3 * n).map(|_| value(2500)).collect();
        let mut directions: Vec<f64> = (0..3 * n).map(|_| value(400)).collect();
        // a zero direction now and then (one component zero is fine)
        for ray in (0..n).step_by(97) {
            directions[3 * ray..3 * ray + 3].fill(if ray % 2 == 0 { 0.0 } else { -0.0 });
        }
        let tmin: Vec<f64> = (0..n).map(|_| value(300)).map(|t| t.abs() * 0.01).collect();
        let tmax: Vec<f64> = (0..n).map(|_| value(300)).map(|t| t.abs()).collect();
        let normals = [0.0, 0.0, 1.0].repeat(n);
        let (mut built, mut refused) = (0, 0);
        for (tmin, tmax) in [
            (&tmin[..], &tmax[..]),
            (&[0.0][..], &tmax[..]),
            (&tmin[..], &[f64::INFINITY][..]),
        ] {
            for (range, with_normals) in [
                (RangeConvention::OpenStart, false),
                (RangeConvention::Closed, false),
                (RangeConvention::OpenStart, true),
            ] {
                let columns =
                    RayColumns::new(&origins, &directions, tmin, tmax, with_normals.then_some(&normals[..])).unwrap();
                let setup = RaySetup {
                    range,
                    origin_precision: with_normals.then_some(PointPrecision::F32),
                    magnitude: 10.0,
                };
                let mut start = 0;
                while start < n {
                    let chunk = start..(start + 1 + next() % 40).min(n);
                    start = chunk.end;
                    let one_by_one: Vec<Result<QueryRay, String>> =
                        chunk.clone().map(|i| columns.ray(i, &setup)).collect();
                    let mut work = TraceWork::default();
                    let plain = columns.plain_rays(chunk.clone(), &setup, &mut work);
                    let out = work.pushed();
                    if plain {
                        built += 1;
                        let expected: Vec<QueryRay> = one_by_one.into_iter().map(Result::unwrap).collect();
                        // bit for bit (the rays are finite)
                        assert_eq!(format!("{out:?}"), format!("{expected:?}"), "chunk {chunk:?}");
                    } else {
                        refused += 1;
                        assert!(out.is_empty());
                        assert!(
                            with_normals || one_by_one.iter().any(Result::is_err),
                            "chunk {chunk:?} refused"
                        );
                    }
                }
            }
        }
        assert!(built > 100 && refused > 100, "{built} built, {refused} refused");
    }

    /// With bad rays on either side of the middle (the second is where a second thread starts),
    /// the error names the first by index, whichever thread meets which first.
    #[test]
    fn the_first_bad_ray_by_index_is_reported() {
        let n = 40_000;
        let mut origins = vec![0.0; 3 * n];
        let mut directions: Vec<f64> = (0..3 * n).map(|k| if k % 3 == 2 { 1.0 } else { 0.0 }).collect();
        origins[3 * 19_999 + 1] = f64::INFINITY;
        directions[3 * 20_001..3 * 20_001 + 3].fill(0.0);
        let columns = RayColumns::new(&origins, &directions, &[0.0], &[f64::INFINITY], None).unwrap();
        for _ in 0..20 {
            let (index, message) = columns.rays(&RaySetup::default()).unwrap_err();
            assert_eq!(
                (index, message.as_str()),
                (19_999, "origin and direction must be finite")
            );
        }
        origins[3 * 19_999 + 1] = 0.0;
        let columns = RayColumns::new(&origins, &directions, &[0.0], &[f64::INFINITY], None).unwrap();
        assert_eq!(columns.rays(&RaySetup::default()).unwrap_err().0, 20_001);
    }

    #[test]
    fn open_range_excludes_the_start_and_closed_keeps_it() {
        let (_, open) = ray_from_fields(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0], &RaySetup::default()).unwrap();
        assert!(!open.contains(0.0) && open.contains(f64::from_bits(1)) && open.contains(1e300));
        let closed = RaySetup {
            range: RangeConvention::Closed,
            ..RaySetup::default()
        };
        let (_, r) = ray_from_fields(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 3.0], &closed).unwrap();
        assert!(r.contains(2.0) && r.contains(3.0) && !r.contains(3.0f64.next_up()));
    }

    #[test]
    fn spawned_origin_needs_normals_and_moves_along_them() {
        let f32_setup = RaySetup {
            origin_precision: Some(PointPrecision::F32),
            ..RaySetup::default()
        };
        assert!(ray_from_fields(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], &f32_setup)
            .unwrap_err()
            .contains("needs the surface normal"));
        assert!(
            ray_from_fields(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0], &RaySetup::default())
                .unwrap_err()
                .contains("only used with --origin-precision")
        );
        let (ray, _) = ray_from_fields(&[0.0, 0.0, 1.0, 0.0, 1.0, -0.5, 0.0, 0.0, 1.0], &f32_setup).unwrap();
        // leaving downwards (d·n < 0): moved below z = 1 by the spawn distance
        assert!(
            ray.origin.z < 1.0 - 2.0 * 2f64.powi(-24) && ray.origin.z > 1.0 - 1e-6,
            "{}",
            ray.origin
        );
        assert!(ray_from_fields(&[0.0; 7], &RaySetup::default()).is_err());
    }

    /// A chunk's rows as [`trace_columns`] writes them, and the last row handed over.
    #[derive(Default)]
    struct Answers {
        rows: Vec<QueryHit>,
        last: Option<usize>,
    }

    impl ChunkAnswers for &Mutex<Answers> {
        fn misses(&mut self, len: usize) {
            let mut answers = self.lock().unwrap();
            assert!(
                answers.rows.is_empty() && answers.last.is_none(),
                "misses written first, once"
            );
            answers.rows = vec![
                QueryHit {
                    hit: None,
                    uncertain: false
                };
                len
            ];
        }

        fn put(&mut self, i: usize, hit: Option<&(u32, SurfaceHit)>, uncertain: bool) {
            let mut answers = self.lock().unwrap();
            assert!(
                answers.last.is_none_or(|last| last < i),
                "rows handed over once, in order"
            );
            assert!(hit.is_some() || uncertain, "certain misses are not handed over");
            answers.last = Some(i);
            answers.rows[i] = QueryHit {
                hit: hit.copied(),
                uncertain,
            };
        }
    }

    /// Counts the rows written.
    struct Counted<'a>(&'a std::sync::atomic::AtomicUsize);

    impl ChunkAnswers for Counted<'_> {
        fn misses(&mut self, len: usize) {
            self.0.fetch_add(len, Ordering::Relaxed);
        }

        fn put(&mut self, _: usize, _: Option<&(u32, SurfaceHit)>, _: bool) {}
    }

    /// Two spheres and a box; rays from a grid of origins in many directions, about a third
    /// missing, over more than two chunks (the last one partial).
    fn scene_and_columns() -> (Scene, Vec<f64>, Vec<f64>, Vec<f64>) {
        let scene = Scene::from_ron(
            "Scene(camera: (eye: (0, 0, 5)), objects: [\
             (shape: Sphere(center: (0, 0, 0), radius: 1)),\
             (shape: Sphere(center: (2, 0.5, 0), radius: 0.5)),\
             (shape: Box(min: (-2, -2, -0.2), max: (-1, -1, 0.2)))])",
            "<test>",
        )
        .unwrap();
        let n = 2 * COLUMN_CHUNK + 77;
        let (mut origins, mut directions, mut tmax) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..n {
            let a = i as f64 * 0.618_033_988_749_895;
            origins.extend_from_slice(&[(a * 7.0).sin() * 0.5, (a * 3.0).cos() * 0.5, 4.0]);
            directions.extend_from_slice(&[a.cos() * 0.3, a.sin() * 0.3, -1.0]);
            tmax.push(if i % 5 == 0 { 3.5 } else { f64::INFINITY });
        }
        (scene, origins, directions, tmax)
    }

    #[test]
    fn traced_columns_equal_trace_batch_on_the_same_rays() {
        let (scene, origins, directions, tmax) = scene_and_columns();
        let setup = RaySetup::default();
        let columns = RayColumns::new(&origins, &directions, &[0.0], &tmax, None).unwrap();
        let rays = columns.rays(&setup).unwrap();
        // the rays are those of the text path, field for field
        let line = [
            origins[30],
            origins[31],
            origins[32],
            directions[30],
            directions[31],
            directions[32],
            0.0,
            3.5,
        ];
        assert_eq!(rays[10], {
            let (ray, range) = ray_from_fields(&line, &setup).unwrap();
            QueryRay { ray, range }
        });
        let expected = trace_batch(&scene, &rays);
        let chunks = columns.len().div_ceil(COLUMN_CHUNK);
        let slots: Vec<Mutex<Answers>> = (0..chunks).map(|_| Mutex::new(Answers::default())).collect();
        trace_columns(&scene, &columns, &setup, ANSWER, slots.iter().collect()).unwrap();
        let got: Vec<QueryHit> = slots.into_iter().flat_map(|s| s.into_inner().unwrap().rows).collect();
        let hits = got.iter().filter(|h| h.hit.is_some()).count();
        assert!(hits > columns.len() / 3 && hits < columns.len(), "{hits} hits");
        assert_eq!(got, expected);
    }

    #[test]
    fn the_first_bad_ray_by_index_is_reported_and_nothing_traced() {
        let (scene, origins, mut directions, tmax) = scene_and_columns();
        // bad rays in the last chunk and, later-found or not, an earlier one in the second
        directions[3 * (2 * COLUMN_CHUNK + 5)..][..3].copy_from_slice(&[0.0; 3]);
        directions[3 * (COLUMN_CHUNK + 9) + 1] = f64::NAN;
        let columns = RayColumns::new(&origins, &directions, &[0.0], &tmax, None).unwrap();
        let setup = RaySetup::default();
        let traced = std::sync::atomic::AtomicUsize::new(0);
        let counters = (0..3).map(|_| Counted(&traced)).collect();
        let error = trace_columns(&scene, &columns, &setup, ANSWER, counters).unwrap_err();
        assert_eq!(
            error,
            (COLUMN_CHUNK + 9, "origin and direction must be finite".to_string())
        );
        assert_eq!(columns.rays(&setup).unwrap_err().0, COLUMN_CHUNK + 9);
        // the chunks holding bad rays are never traced; the first may have been before the error
        assert!(traced.into_inner() <= COLUMN_CHUNK);
    }

    #[test]
    fn columns_of_different_lengths_are_named() {
        let six = [0.0; 6];
        assert!(RayColumns::new(&six, &six[..3], &[0.0], &[1.0], None)
            .unwrap_err()
            .contains("origins and directions differ in length: 2 and 1"));
        assert!(RayColumns::new(&six, &six, &[0.0; 3], &[1.0], None)
            .unwrap_err()
            .starts_with("tmin: expected a scalar or 2 values, got 3"));
        assert!(RayColumns::new(&six, &six, &[0.0], &[1.0], Some(&six[..3]))
            .unwrap_err()
            .starts_with("normals: expected 2 rows, got 1"));
        assert!(RayColumns::new(&six[..4], &six[..4], &[0.0], &[1.0], None)
            .unwrap_err()
            .contains("not rows of 3"));
    }
}
