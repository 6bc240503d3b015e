//! A ray's query against a mesh, before and after the walk: the set-up (the f64 ray turned into
//! the f32 ray the tests use, [`MeshEntry`] and [`MeshQuery`]), the tests that turn a ray away
//! before any walk (the bounding ball, [`Mesh::misses_ball`], and the root's children), the rule
//! that picks the closest candidate ([`Candidate`], [`Mesh::beats`]: the smallest `(t, leaf
//! position)`) and the finish (the hit's `t` recomputed in f64 on its triangle's plane).
//!
//! The f32 ray: the origin rounded to f32, the direction multiplied by a power of two `s`
//! ([`direction_scale`], exact) so that its largest component lies in `[1, 2)`; its range is
//! `[t_min, t_max] / s` rounded outward. A candidate within the band `t_min + 10⁻⁵·(radius +
//! |o − c|)/|s·d|` is re-decided with its f64 `t` ([`Mesh::counts`]), so that rays leaving the
//! surface do not re-hit it.

use super::storage::{plane_t, Mesh};
use super::watertight::MeshRay;
use crate::bvh::prefetching::prefetch;
use crate::bvh::rounding::{round_down, round_up};
use crate::bvh::slab::SlabRay;
use crate::hit::RawHit;
use crate::ray::{Interval, Ray};
use glam::{DVec2, DVec3, Vec3A};

/// One ray's set-up for the mesh tests: the f32 ray (its direction scaled by a power of two, see
/// [`direction_scale`]), its range in that ray's `t`, and the band near `t_min` where hits are
/// re-decided in f64 (see the module docs), worked out at the first candidate hit (most rays have
/// none).
pub(super) struct MeshQuery {
    pub(super) ray: MeshRay,
    /// The power of two `s` the f64 direction was multiplied by: `t` along the f32 ray is the
    /// ray's `t` divided by `s`.
    pub(super) scale: f64,
    pub(super) t_min: f32,
    pub(super) t_max: f32,
    /// `t_min + 10⁻⁵·(radius + |origin − centre|) / |s·dir|`, once asked for ([`Mesh::counts`]).
    pub(super) band: std::cell::OnceCell<f32>,
}

/// The part of a [`MeshQuery`] made before the root test ([`Mesh::entry`]): the f32 ray (origin
/// and scaled direction), its slab test, the scale and the range in the f32 ray's `t`.
pub(super) struct MeshEntry {
    pub(super) slab: SlabRay,
    pub(super) origin: Vec3A,
    pub(super) dir: Vec3A,
    pub(super) scale: f64,
    pub(super) t_min: f32,
    pub(super) t_max: f32,
}

impl MeshEntry {
    /// The whole set-up: the watertight test's axes and shear added.
    #[inline(always)]
    pub(super) fn query(self) -> MeshQuery {
        MeshQuery {
            ray: MeshRay::with_slab(self.slab, self.origin, self.dir),
            scale: self.scale,
            t_min: self.t_min,
            t_max: self.t_max,
            band: std::cell::OnceCell::new(),
        }
    }
}

/// The closest candidate so far.
#[derive(Clone, Copy, Debug)]
pub(super) struct Candidate {
    /// `t` along the f32 ray's scaled direction.
    pub(super) t: f32,
    /// Barycentrics of the hit.
    pub(super) u: f32,
    pub(super) v: f32,
    /// The leaf holding the triangle, its first leaf position and its number of triangles
    /// (whose rows, [`Mesh::leaf`], just read by the test, give the triangle's plane without the
    /// index and vertex loads of [`Mesh::plane`]: two cache misses in a row on a large mesh),
    /// and the triangle's place in it. 20 bytes in all, as small as the tuple it replaced.
    pub(super) first: u32,
    pub(super) count: u16,
    pub(super) i: u16,
}

impl Candidate {
    /// The hit `(t, u, v)` on the `i`-th triangle of the leaf of `count` from `first`.
    #[inline(always)]
    pub(super) fn new((t, u, v): (f32, f32, f32), first: u32, count: u32, i: usize) -> Self {
        Self {
            t,
            u,
            v,
            first,
            count: count as u16,
            i: i as u16,
        }
    }

    /// The triangle's leaf position.
    #[inline(always)]
    pub(super) fn k(&self) -> usize {
        self.first as usize + usize::from(self.i)
    }
}

/// For a direction whose largest component magnitude is `m` (finite, > 0): the power of two `s`
/// that brings `s·m` into `[1, 2)` (into `[2⁻⁵³, 8)` at the ends of the f64 range, where `s`
/// is clamped to `[2⁻¹⁰²¹, 2¹⁰²¹]`), and `1/s`. Scaling by `s` is exact, so it costs no accuracy
/// and, unlike normalising, no square root or division.
#[inline(always)]
pub(super) fn direction_scale(m: f64) -> (f64, f64) {
    let exponent = (((m.to_bits() >> 52) & 0x7ff) as i64 - 1023).clamp(-1021, 1021);
    let power_of_two = |e: i64| f64::from_bits(((1023 + e) as u64) << 52);
    (power_of_two(-exponent), power_of_two(exponent))
}

/// `range.min · unscale` rounded down to f32 and clamped to `[0, f32::MAX]`: the f32 ray's
/// `t_min`. A subnormal `min` (a range opened at 0 starts at `0.next_up()`) times an `unscale`
/// below `2⁸⁷³` is below `2⁻¹⁵⁰`, so 0, answered without the multiplication: on x86 a subnormal
/// operand takes a microcode assist of some hundred cycles, which was half the cost of a ray
/// passing the mesh by.
#[inline(always)]
pub(super) fn scaled_t_min(min: f64, unscale: f64) -> f32 {
    if min > 0.0 && min < f64::MIN_POSITIVE && unscale < f64::from_bits((1023 + 873) << 52) {
        return 0.0;
    }
    round_down(min * unscale).clamp(0.0, f32::MAX)
}

impl Mesh {
    /// The set-up of `ray` over `range`, or `None` where nothing can be hit (a zero, infinite or
    /// NaN direction, a non-finite origin, an empty range).
    #[inline(always)]
    pub(super) fn query(&self, ray: &Ray, range: Interval) -> Option<MeshQuery> {
        Some(self.entry(ray, range)?.query())
    }

    /// The first half of [`Mesh::query`]: the f32 ray and its slab test, all that the root test
    /// needs, so that a ray passing the mesh by (most of a random batch) costs this, the test of
    /// the root ([`Mesh::enters_root`]) and nothing more.
    #[inline(always)]
    pub(super) fn entry(&self, ray: &Ray, range: Interval) -> Option<MeshEntry> {
        let largest = ray.dir.abs().max_element();
        if !(largest > 0.0 && largest.is_finite() && ray.origin.is_finite()) || range.is_empty() {
            return None;
        }
        let (scale, unscale) = direction_scale(largest);
        let (origin, dir) = (ray.origin.as_vec3a(), (ray.dir * scale).as_vec3a());
        Some(MeshEntry {
            slab: SlabRay::new(origin, dir),
            origin,
            dir,
            scale,
            t_min: scaled_t_min(range.min, unscale),
            t_max: round_up(range.max * unscale),
        })
    }

    /// Whether `ray` surely passes the mesh by, decided in f64 without a division: its line
    /// stays farther than `R` from the ball's centre `c` (`|(o − c) × d|² > R²·|d|²`), or, for a
    /// range starting at `t ≥ 0`, it starts outside that distance and moves away
    /// (`(o − c)·d ≥ 0`). `R` is the ball's radius enlarged by `10⁻⁶·(radius + |o|∞ + |o − c|₁)`,
    /// far more than the f32 ray the test traces is off the f64 one (`2⁻²⁴` of those sizes), and
    /// the products' rounding (`< 10⁻¹⁴·|o − c|²·|d|²`) is allowed for. So `true` never hides
    /// a hit, and most of a random batch (which misses the mesh by far) is answered here, in a
    /// few multiplications, rather than by the f32 set-up and the root's slab test (a third of
    /// the time of a random batch on a small mesh). Any NaN or overflow answers `false`.
    #[inline(always)]
    pub(super) fn misses_ball(&self, ray: &Ray, range: Interval) -> bool {
        let oc = ray.origin - self.center;
        let d = ray.dir;
        let (oc2, d2) = (oc.length_squared(), d.length_squared());
        let reach =
            self.ball_radius + 1e-6 * (self.ball_radius + ray.origin.abs().max_element() + oc.abs().element_sum());
        let reach2 = reach * reach;
        let beside = oc.cross(d).length_squared() > reach2 * d2 + 1e-14 * oc2 * d2;
        // no short cuts: without branches, four rays' tests run four wide ([`Mesh::misses_ball4`])
        let leaving = (range.min >= 0.0) & (oc2 > reach2) & (oc.dot(d) >= 0.0);
        beside | leaving
    }

    /// [`Mesh::misses_ball`] of four rays (`rays` and `ranges` hold four each): the same test
    /// ray by ray, which the AVX2 copy of a batch's test ([`Intersect::intersect_each`])
    /// computes four wide; one ray at a time, the test took as long as building the ray (most
    /// of a random batch ends there).
    #[inline(always)]
    pub(super) fn misses_ball4(&self, rays: &[Ray], ranges: &[Interval]) -> [bool; 4] {
        let mut miss = [false; 4];
        for l in 0..4 {
            miss[l] = self.misses_ball(&rays[l], ranges[l]);
        }
        miss
    }

    /// The slab test of the ray of `entry` against the root's children (the 8-wide walk's first
    /// step, see [`Octs::root_entry`]), or `None` if it enters none: made before the rest of the
    /// set-up and the choice of walk, which a ray passing the mesh by never needs.
    #[inline(always)]
    pub(super) fn enters_root(&self, entry: &MeshEntry) -> Option<(u32, [f32; 8])> {
        let root = self.octs().root_entry(&entry.slab, entry.t_min, entry.t_max)?;
        (root.0 != 0).then_some(root)
    }

    /// What every walk starts from: the ray's set-up ([`Mesh::entry`]) and the root's children it
    /// enters ([`Mesh::enters_root`]), or `None` where it cannot hit the mesh (it passes the
    /// bounding ball by, [`Mesh::misses_ball`], or enters none of those children).
    #[inline(always)]
    pub(super) fn walk_start(&self, ray: &Ray, range: Interval) -> Option<(MeshEntry, (u32, [f32; 8]))> {
        if self.misses_ball(ray, range) {
            return None;
        }
        self.walk_start_in_ball(ray, range)
    }

    /// [`Mesh::walk_start`] of a ray that the ball test kept already (a batch's rays are judged
    /// by it four at a time first, `mesh/stream.rs`): the set-up and the root's test.
    #[inline(always)]
    pub(super) fn walk_start_in_ball(&self, ray: &Ray, range: Interval) -> Option<(MeshEntry, (u32, [f32; 8]))> {
        let entry = self.entry(ray, range)?;
        let root = self.enters_root(&entry)?;
        Some((entry, root))
    }

    /// Whether a hit at f32 `t` on the triangle at leaf position `k` counts: outside the band
    /// near `t_min` always, inside it only if the f64 `t` on the triangle's plane is in `range`.
    #[inline(always)]
    pub(super) fn counts(&self, ray: &Ray, range: Interval, query: &MeshQuery, k: usize, t: f32) -> bool {
        self.surely_beyond_band(ray, query, t)
            || t > self.band(ray, query)
            || self.plane_t(ray, k).is_some_and(|t| range.contains(t))
    }

    /// The f32 end of the band near `t_min` where hits are re-decided in f64:
    /// `t_min + 10⁻⁵·(radius + |o − c|)/|s·d|`, worked out once per ray.
    #[inline(always)]
    pub(super) fn band(&self, ray: &Ray, query: &MeshQuery) -> f32 {
        *query.band.get_or_init(|| {
            let band = 1e-5 * (self.radius + (ray.origin - self.center).length());
            query.t_min + (band / (ray.dir * query.scale).length()) as f32
        })
    }

    /// A bound that decides most candidates (those far beyond the band) without the band's
    /// square roots and division: `true` only where `t > ` [`Mesh::band`]. With
    /// `B = 10⁻⁵·(radius + |o − c|)`, `|o − c| ≤ |o − c|₁` and `|s·d| ≥ m = max |s·dᵢ|`, the band's
    /// f32 end is at most `(t_min + 10⁻⁵·(radius + |o − c|₁)/m)·(1 + 2⁻²³)` (two f32 roundings
    /// up, `t_min ≥ 0`), so a `t` beyond `1 + 10⁻⁶` times that, compared multiplied through by
    /// `m`, is beyond the band.
    #[inline(always)]
    pub(super) fn surely_beyond_band(&self, ray: &Ray, query: &MeshQuery, t: f32) -> bool {
        let m = (ray.dir * query.scale).abs().max_element();
        let bound = f64::from(query.t_min) * m + 1e-5 * (self.radius + (ray.origin - self.center).abs().element_sum());
        f64::from(t) * m > bound * (1.0 + 1e-6)
    }

    /// Whether a candidate at `(k, t)` replaces `best`, whose `t` is `t_far`: a nearer `t`, or the
    /// same `t` on a triangle earlier in leaf order. The closest hit is thus the smallest
    /// `(t, k)`, whatever order the leaves are visited in (single rays and packets agree).
    #[inline(always)]
    pub(super) fn beats(best: Option<&Candidate>, k: usize, t: f32, t_far: f32) -> bool {
        t < t_far || best.is_none_or(|b| k < b.k())
    }

    /// The raw hit of the closest candidate: `t` recomputed in f64 on the triangle's plane.
    #[inline(always)]
    pub(super) fn finish(
        &self,
        ray: &Ray,
        range: Interval,
        query: &MeshQuery,
        best: Option<Candidate>,
    ) -> Option<RawHit> {
        let best = best?;
        let (hit, _) = self.finish_on_plane(ray, range, query, best)?;
        // what finishing the hit reads next ([`Mesh::hit_plane`]): asked for now, it arrives
        // while other rays are traced (on a large mesh, a cache miss each)
        prefetch(self.file_to_leaf.as_ptr().wrapping_add(hit.feature as usize));
        prefetch(self.leaf_places.as_ptr().wrapping_add(best.k()));
        Some(hit)
    }

    /// [`Mesh::finish`] and the hit's normal as [`Intersect::normal_at_f32`] gives it: from the
    /// normals' table where the mesh keeps one, else normalised from the plane `t` was found on
    /// (the triangle's rows, read for it, still in cache), as `normal_at` does, without its two
    /// lookups of the triangle's place (a cache miss each on a large mesh).
    #[inline(always)]
    pub(super) fn finish_with_normal(
        &self,
        ray: &Ray,
        range: Interval,
        query: &MeshQuery,
        best: Option<Candidate>,
    ) -> Option<(RawHit, glam::Vec3)> {
        let (hit, n) = self.finish_on_plane(ray, range, query, best?)?;
        Some((hit, self.unit_normal_f32(hit.feature, || Some(n))))
    }

    /// The raw hit of the candidate `best` (`t` recomputed in f64 on the triangle's plane) and
    /// that plane's unnormalised normal; `None` where `t` lies beyond the range. Every hit and
    /// every listed crossing is finished here.
    #[inline(always)]
    pub(super) fn finish_on_plane(
        &self,
        ray: &Ray,
        range: Interval,
        query: &MeshQuery,
        best: Candidate,
    ) -> Option<(RawHit, DVec3)> {
        let (n, a) = self.leaf(best.first, u32::from(best.count)).plane(usize::from(best.i));
        let t = plane_t(n, a, ray)
            .unwrap_or(f64::from(best.t) * query.scale)
            .max(range.min);
        if t > range.max {
            return None;
        }
        let hit = RawHit {
            t,
            feature: self.leaf_to_file[best.k()],
            local: DVec2::new(f64::from(best.u), f64::from(best.v)),
        };
        Some((hit, n))
    }
}
