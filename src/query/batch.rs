//! The batch's rays and answers, and the tracing of a slice of rays in input order: each ray
//! alone ([`trace_one`]) or handed to the scene together ([`trace_many_for`]).

use super::order::{trace_batch_in, RayOrder};
use crate::scene::Scene;
use zeroset_primitives::root::uncertain_while;
use zeroset_primitives::{HitRequest, Interval, RawHit, Ray, SurfaceHit};

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
pub(super) fn completed(
    scene: &Scene,
    ray: &Ray,
    (object, raw): (u32, RawHit),
    request: HitRequest,
) -> (u32, SurfaceHit) {
    let primitive = &*scene.objects[object as usize].primitive;
    (object, SurfaceHit::complete(primitive, ray, &raw, request))
}

/// Room reused from batch to batch by [`trace_many_for`]: the rays of a batch, pushed one by one
/// (`TraceWork::push`), then traced together (`TraceWork::trace`).
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
