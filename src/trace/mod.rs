//! Tracing rays through a loaded [`Scene`]: the hierarchy over its objects and the closest-hit
//! and occlusion queries that walk it. The render loop, `query` and Python all come here.

use glam::Vec3;
use zeroset_primitives::root::{traced_again, uncertain_while};
use zeroset_primitives::{Aabb, Interval, RawHit, Ray};

use crate::scene::Scene;

pub mod packet;

use packet::{coherent, PACKET_COS};

/// `primitive`'s first hits of `rays` (none needing rescaling) over `ranges`, into `hits` and
/// `uncertain`, as [`zeroset_primitives::Intersect::intersect_each`] gives them: each run of
/// [`zeroset_primitives::PACKET`] consecutive rays that passes the packet test
/// ([`coherent`] with [`PACKET_COS`]) walks as one packet
/// ([`zeroset_primitives::Intersect::intersect_packet`], the same answers lane by lane), and the
/// other runs go to `intersect_each` together. A packet during which a root finder ran out of
/// budget is traced again ray by ray, so that the flag names the rays it belongs to (counted
/// once: [`traced_again`]). Random rays cost the test only: their runs fail it at the first
/// pair.
fn lone_packets_or_each(
    primitive: &dyn zeroset_primitives::Primitive,
    rays: &[Ray],
    ranges: &[Interval],
    hits: &mut [Option<RawHit>],
    uncertain: &mut [bool],
) {
    const N: usize = zeroset_primitives::PACKET;
    // runs of rays alike in kind (packets, or not) go to the primitive together
    let mut start = 0;
    while start < rays.len() {
        let packet = |at: usize| coherent(&rays[at..(at + N).min(rays.len())], PACKET_COS);
        let kind = packet(start);
        let mut end = (start + N).min(rays.len());
        while end < rays.len() && packet(end) == kind {
            end = (end + N).min(rays.len());
        }
        let (rays, ranges) = (&rays[start..end], &ranges[start..end]);
        let (hits, uncertain) = (&mut hits[start..end], &mut uncertain[start..end]);
        if kind {
            for (((rays, ranges), hits), uncertain) in rays
                .chunks(N)
                .zip(ranges.chunks(N))
                .zip(hits.chunks_mut(N))
                .zip(uncertain.chunks_mut(N))
            {
                let mut narrowed = [Interval::POSITIVE; N];
                narrowed[..rays.len()].copy_from_slice(ranges);
                // the packet sets the lanes that hit and leaves the others as they were
                hits.fill(None);
                let ((), flagged) =
                    uncertain_while(|| primitive.intersect_packet(rays, &mut narrowed[..rays.len()], hits));
                if flagged {
                    traced_again(|| primitive.intersect_each(rays, ranges, hits, uncertain));
                } else {
                    uncertain.fill(false);
                }
            }
        } else {
            primitive.intersect_each(rays, ranges, hits, uncertain);
        }
        start = end;
    }
}

/// Direction magnitudes (largest component) traced as given; beyond, [`Scene::intersect`] scales
/// the direction by a power of two first.
const DIR_SCALE_MIN: f64 = 1.0 / (1u64 << 60) as f64;
const DIR_SCALE_MAX: f64 = (1u64 << 60) as f64;

impl Scene {
    /// A box around every object (a moving one's over its motion): infinite if an object is
    /// unbounded (a plane), empty for a scene of no objects. No ray that misses it hits anything.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        self.bounds_parts().into_iter().fold(Aabb::EMPTY, Aabb::union)
    }

    /// Boxes whose union holds every object ([`zeroset_primitives::Implicit::bounds_parts`] of
    /// each; a moving object's box over its motion): tighter than [`Scene::bounds`] around a
    /// mesh. Some box is infinite where an object is unbounded.
    #[must_use]
    pub fn bounds_parts(&self) -> Vec<Aabb> {
        let mut parts = Vec::new();
        for object in &self.objects {
            match &object.motion {
                Some(motion) => parts.push(motion.bounds()),
                None => object.primitive.bounds_parts(&mut parts),
            }
        }
        parts
    }

    /// The closest hit along `ray` at frame time `time` with `t` in `range`: like
    /// [`Scene::intersect`], with moving objects placed at `time`. A scene without moving objects
    /// gives exactly [`Scene::intersect`]'s answer.
    #[inline]
    pub fn intersect_at(&self, ray: &Ray, range: Interval, time: f64) -> Option<(u32, RawHit)> {
        self.closest(
            range,
            |id, ray, r| self.with_primitive_at(id, time, |p| p.intersect(ray, r)),
            ray,
        )
    }

    /// Whether anything blocks `ray` within `range` at frame time `time`.
    #[must_use]
    pub fn occluded_at(&self, ray: &Ray, range: Interval, time: f64) -> bool {
        self.intersect_at(ray, range, time).is_some()
    }

    /// The closest hit along `ray` with `t` in `range`: the object index and its raw hit.
    #[inline]
    pub fn intersect(&self, ray: &Ray, range: Interval) -> Option<(u32, RawHit)> {
        self.closest(
            range,
            |id, ray, r| self.objects[id as usize].primitive.intersect(ray, r),
            ray,
        )
    }

    /// [`Scene::intersect`] of every ray of `rays` over its range in `ranges`, into `hits` (the
    /// raw hit) and `objects` (the object hit, where `hits` holds a hit), and into `uncertain`
    /// whether a root finder ran out of budget on that ray (this thread's
    /// [`zeroset_primitives::root::thread_uncertain_events`] moved meanwhile); the four slices
    /// have the same length. The same answers: a scene of one object (a lone mesh, the common
    /// query) hands the rays to it 256 at a time where no direction needs rescaling (see
    /// [`Scene::intersect`]) — what a call costs around the test is paid once, and a large mesh
    /// interleaves the rays' walks, which pays more the more rays a call has — and each run of
    /// [`zeroset_primitives::PACKET`] consecutive rays that point alike (a camera's rays in pixel
    /// order) as one packet ([`lone_packets_or_each`]); other scenes trace ray after ray.
    pub fn intersect_each(
        &self,
        rays: &[Ray],
        ranges: &[Interval],
        hits: &mut [Option<RawHit>],
        objects: &mut [u32],
        uncertain: &mut [bool],
    ) {
        const BATCH: usize = 256;
        let lone = self.lone_object();
        let batches = rays.chunks(BATCH).zip(ranges.chunks(BATCH));
        let outputs = hits
            .chunks_mut(BATCH)
            .zip(objects.chunks_mut(BATCH))
            .zip(uncertain.chunks_mut(BATCH));
        for ((rays, ranges), ((hits, objects), uncertain)) in batches.zip(outputs) {
            match lone {
                Some(object) if rays.iter().all(|ray| scaled_direction_size(ray).is_none()) => {
                    lone_packets_or_each(&*self.objects[object as usize].primitive, rays, ranges, hits, uncertain);
                    objects.fill(object);
                }
                _ => {
                    let outputs = hits.iter_mut().zip(objects.iter_mut()).zip(uncertain.iter_mut());
                    for ((ray, range), ((hit, object), uncertain)) in rays.iter().zip(ranges).zip(outputs) {
                        let (found, flagged) = uncertain_while(|| self.intersect(ray, *range));
                        (*hit, *object, *uncertain) = (found.map(|(_, raw)| raw), found.map_or(0, |(o, _)| o), flagged);
                    }
                }
            }
        }
    }

    /// How far off the exact ray from `origin` a hit may lie for the way the objects store its
    /// origin: the largest of their [`zeroset_primitives::Intersect::origin_rounding`] (moving
    /// objects placed at time 0).
    #[must_use]
    pub fn origin_rounding(&self, origin: glam::DVec3) -> f64 {
        self.objects
            .iter()
            .map(|o| o.primitive.origin_rounding(origin))
            .fold(0.0, f64::max)
    }

    /// The scene's one object, if it has exactly one (what every ray is tested against).
    pub(crate) fn lone_object(&self) -> Option<u32> {
        match self.hierarchy.unbounded[..] {
            [only] if self.hierarchy.bvh.is_empty() => Some(only),
            _ => None,
        }
    }

    /// [`Scene::intersect`] in a scene whose lone object `object` has the `pieces`, for a ray
    /// that can only meet the pieces `candidates` (see [`zeroset_primitives::Pieces`]), with,
    /// where `NORMAL` asks for it and the pieces work it out along the way, the hit's
    /// `normal_at_f32` ([`zeroset_primitives::Pieces::intersect_pieces_nearest_first_with_normal`]).
    /// A direction that needs rescaling takes [`Scene::intersect`] itself.
    #[inline]
    pub(crate) fn intersect_lone_pieces<const NORMAL: bool>(
        &self,
        object: u32,
        pieces: &dyn zeroset_primitives::Pieces,
        ray: &Ray,
        range: Interval,
        candidates: &[(u32, f32)],
    ) -> Option<(u32, RawHit, Option<Vec3>)> {
        debug_assert_eq!(self.lone_object(), Some(object));
        if scaled_direction_size(ray).is_some() {
            return self.intersect(ray, range).map(|(object, raw)| (object, raw, None));
        }
        if NORMAL {
            pieces
                .intersect_pieces_nearest_first_with_normal(ray, range, candidates)
                .map(|(raw, normal)| (object, raw, normal))
        } else {
            pieces
                .intersect_pieces_nearest_first(ray, range, candidates)
                .map(|raw| (object, raw, None))
        }
    }

    /// Whether some object has infinite bounds (a plane): tested by every ray.
    pub(crate) fn has_unbounded_objects(&self) -> bool {
        self.hierarchy
            .unbounded
            .iter()
            .any(|&i| !self.objects[i as usize].primitive.bounds().is_finite())
    }

    /// [`Scene::intersect`] for a ray from the eye of a scene with a hierarchy, whose hits among
    /// the hierarchy's objects can only lie on `always` and `candidates`, these `(object, near)`
    /// nearest first: `near` is at most the distance from the ray's origin to any hit on the
    /// object.
    /// The unbounded objects are tested first and the others settled by the hierarchy's rules
    /// ([`settles_tie`]), so the answer is the hierarchy's: a candidate whose `near` lies beyond
    /// the closest hit so far, and all after it, cannot hold a hit in range.
    pub(crate) fn intersect_candidates(
        &self,
        ray: &Ray,
        range: Interval,
        always: &[u32],
        candidates: &[(u32, f32)],
    ) -> Option<(u32, RawHit)> {
        if scaled_direction_size(ray).is_some() {
            return self.intersect(ray, range);
        }
        let (mut range, best) =
            self.closest_unbounded(range, |id, r| self.objects[id as usize].primitive.intersect(ray, r));
        // the closest hit so far, field by field (see `ClosestSoFar`)
        let mut closest = ClosestSoFar::default();
        let mut test = |id: u32, range: &mut Interval| {
            let result = self.objects[id as usize].primitive.intersect(ray, *range);
            if let Some(hit) = &result {
                let t = scalar(&hit.t);
                if closest.settles_tie(id, t, *range) {
                    range.max = t;
                    closest.keep(id, hit);
                }
            }
        };
        for &id in always {
            test(id, &mut range);
        }
        // a candidate whose `near` lies beyond the reach of the closest hit so far (`t` times
        // the direction's length) ends the list: compared squared, `near² > t²·|d|²`, with
        // `10⁻⁹` of room for the rounding of the products (a few ulps), so no square root waits
        // on the direction. Neither side can underflow to a wrong answer: `near > 0` is at least
        // 2⁻¹⁴⁹ in f32, and a `t` whose square underflows reaches less than that along a
        // direction of at most `√3·2⁶⁰` (`DIR_SCALE_MAX`).
        let mut length_squared = None;
        for &(id, near) in candidates {
            if range.max.is_finite() {
                let length_squared = *length_squared.get_or_insert_with(|| ray.dir.length_squared() * (1.0 + 1e-9));
                let near = f64::from(near);
                if near > 0.0 && near * near > range.max * range.max * length_squared {
                    break;
                }
            }
            test(id, &mut range);
        }
        closest.hit().or(best)
    }

    /// The closest hit of `test(object, range)` over the objects tested by every ray (those
    /// outside the hierarchy), in order, each shrinking `range.max` to its hit: that range and
    /// the last hit found.
    #[inline(always)]
    fn closest_unbounded(
        &self,
        mut range: Interval,
        test: impl Fn(u32, Interval) -> Option<RawHit>,
    ) -> (Interval, Option<(u32, RawHit)>) {
        let mut best = None;
        for &i in &self.hierarchy.unbounded {
            if let Some(hit) = test(i, range) {
                range.max = hit.t;
                best = Some((i, hit));
            }
        }
        (range, best)
    }

    /// The closest hit of `test(object, ray, range)` over the always-tested objects and the BVH,
    /// shrinking `range.max` as hits are found.
    ///
    /// A direction whose length is far from 1 (a query's `10⁻³⁰` or `10¹⁵⁵`) is first scaled by a
    /// power of two `k` near its largest component (exact): the ray `o + t'·(d/k)` is the same
    /// line with `t' = t·k`, so the range is scaled by `k` and the hit's `t'` mapped back by
    /// `1/k`. Without it, squares of the direction and the hierarchy's f32 reciprocals overflow or
    /// underflow and every ray misses.
    #[inline(always)]
    fn closest(
        &self,
        range: Interval,
        test: impl Fn(u32, &Ray, Interval) -> Option<RawHit>,
        ray: &Ray,
    ) -> Option<(u32, RawHit)> {
        let Some(size) = scaled_direction_size(ray) else {
            return self.closest_unscaled(range, |id, r| test(id, ray, r), ray);
        };
        let k = zeroset_primitives::math::power_of_two_scale(size);
        let scaled = Ray::new(ray.origin, ray.dir / k);
        let (object, hit) = self.closest_unscaled(
            Interval::new(range.min * k, range.max * k),
            |id, r| test(id, &scaled, r),
            &scaled,
        )?;
        let t = hit.t / k;
        range.contains(t).then_some((object, RawHit { t, ..hit }))
    }

    #[inline(always)]
    fn closest_unscaled(
        &self,
        range: Interval,
        test: impl Fn(u32, Interval) -> Option<RawHit>,
        ray: &Ray,
    ) -> Option<(u32, RawHit)> {
        let (range, best) = self.closest_unbounded(range, &test);
        // a scene of one bounded object has no hierarchy: no call
        if self.hierarchy.bvh.is_empty() {
            return best;
        }
        let mut raw: Option<(u32, RawHit)> = None;
        let object = self.hierarchy.bvh.closest(ray, range, |id, r| {
            let hit = test(id, r)?;
            if !settles_tie(raw.map(|(holder, _)| holder), id, hit.t, r) {
                return None;
            }
            raw = Some((id, hit));
            Some(hit.t)
        });
        // `raw` holds the last hit reported, which is the closest one
        match (object, raw) {
            (Some(_), Some(raw)) => Some(raw),
            _ => best,
        }
    }

    /// The closest hits of several rays (coherent ones, such as neighbouring pixels) with `t`
    /// in their `ranges`: `out[i]` is exactly [`Scene::intersect`]`(&rays[i], ranges[i])`. They
    /// walk the scene's hierarchy together, and objects that trace packets faster
    /// ([`zeroset_primitives::Intersect::intersect_packet`], meshes) take up to
    /// [`zeroset_primitives::PACKET`] rays at a time. The three slices have the same length.
    pub fn intersect_packet(&self, rays: &[Ray], ranges: &[Interval], out: &mut [Option<(u32, RawHit)>]) {
        const N: usize = zeroset_primitives::PACKET;
        for ((rays, given), out) in rays.chunks(N).zip(ranges.chunks(N)).zip(out.chunks_mut(N)) {
            let plain = rays.iter().all(|ray| scaled_direction_size(ray).is_none());
            if !plain || !coherent(rays, PACKET_COS) {
                for ((ray, range), out) in rays.iter().zip(given).zip(out.iter_mut()) {
                    *out = self.intersect(ray, *range);
                }
                continue;
            }
            let n = rays.len();
            let mut ranges = [Interval::POSITIVE; N];
            ranges[..n].copy_from_slice(given);
            out.fill(None);
            for &object in &self.hierarchy.unbounded {
                let mut raw = [None; N];
                self.objects[object as usize]
                    .primitive
                    .intersect_packet(rays, &mut ranges[..n], &mut raw[..n]);
                for (out, raw) in out.iter_mut().zip(raw) {
                    if let Some(hit) = raw {
                        *out = Some((object, hit));
                    }
                }
            }
            if self.hierarchy.bvh.node_count() == 0 {
                continue;
            }
            let mut raw: [Option<(u32, RawHit)>; N] = [None; N];
            let objects = self.hierarchy.bvh.closest_packet(rays, &ranges[..n], |lane, id, r| {
                let hit = self.objects[id as usize].primitive.intersect(&rays[lane], r)?;
                if !settles_tie(raw[lane].map(|(holder, _)| holder), id, hit.t, r) {
                    return None;
                }
                raw[lane] = Some((id, hit));
                Some(hit.t)
            });
            for ((out, object), raw) in out.iter_mut().zip(objects).zip(raw) {
                if let (Some(_), Some(raw)) = (object, raw) {
                    *out = Some(raw);
                }
            }
        }
    }

    /// Whether anything blocks `ray` within `range` (shadow rays).
    #[must_use]
    pub fn occluded(&self, ray: &Ray, range: Interval) -> bool {
        self.intersect(ray, range).is_some()
    }
}

/// The closest hit of [`Scene::intersect_candidates`] so far, kept as separate fields (which
/// the compiler holds in registers) and read from each hit one scalar at a time. A hit comes back
/// from its primitive's call through memory, written field by field; a 16-byte copy of it spans
/// two of those writes, cannot take its data from the store buffer and waits until both reach the
/// cache (a store-forwarding stall, some 15 cycles a hit), whereas each scalar load lies within
/// one write.
#[derive(Clone, Copy, Default)]
struct ClosestSoFar {
    found: bool,
    object: u32,
    t: f64,
    feature: u32,
    u: f64,
    v: f64,
}

/// `*x`, loaded on its own: never merged with its neighbours into a wider load (see
/// [`ClosestSoFar`]).
#[inline(always)]
pub(crate) fn scalar(x: &f64) -> f64 {
    // SAFETY: a read of a valid, aligned `f64` through a reference
    unsafe { std::ptr::read_volatile(x) }
}

impl ClosestSoFar {
    /// [`settles_tie`] against the hit kept so far.
    #[inline(always)]
    fn settles_tie(&self, id: u32, t: f64, range: Interval) -> bool {
        settles_tie(self.found.then_some(self.object), id, t, range)
    }

    /// Keeps object `object`'s `hit`.
    #[inline(always)]
    fn keep(&mut self, object: u32, hit: &RawHit) {
        *self = Self {
            found: true,
            object,
            t: scalar(&hit.t),
            feature: hit.feature,
            u: scalar(&hit.local.x),
            v: scalar(&hit.local.y),
        };
    }

    /// The hit kept, if any.
    #[inline(always)]
    fn hit(&self) -> Option<(u32, RawHit)> {
        self.found.then(|| {
            (
                self.object,
                RawHit {
                    t: self.t,
                    feature: self.feature,
                    local: glam::DVec2::new(self.u, self.v),
                },
            )
        })
    }
}

/// The largest component magnitude of `ray`'s direction where [`Scene::intersect`] scales the
/// direction first (finite and non-zero, but outside `[DIR_SCALE_MIN, DIR_SCALE_MAX]`); `None`
/// where the ray is traced as given. For the non-negative size (or NaN) the bit patterns order as
/// the values, so two integer comparisons decide.
#[inline(always)]
fn scaled_direction_size(ray: &Ray) -> Option<f64> {
    let size = ray.dir.abs().max_element().to_bits();
    let scaled = size.wrapping_sub(1) < DIR_SCALE_MIN.to_bits() - 1
        || (size > DIR_SCALE_MAX.to_bits() && size < f64::INFINITY.to_bits());
    scaled.then(|| f64::from_bits(size))
}

/// Whether object `id`'s hit at `t` (within `range`, whose `max` is the closest hit so far)
/// replaces the closest hit, held by object `holder` (`None`: none yet): a nearer hit does; one
/// at exactly `range.max` only if `id` is smaller than `holder`. The hierarchy's closest hit is
/// thus the smallest `(t, id)`, whatever order its leaves are visited in (single rays and packets
/// agree).
#[inline(always)]
fn settles_tie(holder: Option<u32>, id: u32, t: f64, range: Interval) -> bool {
    t < range.max || holder.is_none_or(|holder| id < holder)
}
