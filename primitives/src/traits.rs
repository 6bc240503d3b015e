//! The extension points: [`Implicit`], [`Parametric`], [`Intersect`] and the object-safe
//! [`Primitive`] a scene stores.
//!
//! The minimum a new primitive type writes is [`Implicit::phi`] and [`Implicit::bounds`] plus an
//! empty `impl Intersect for MyType {}`: the gradient (normals) comes from central differences and
//! the intersection from the generic root finder in [`crate::root`]. Built-ins override both with
//! closed forms. A type that can bound Φ by interval arithmetic along a ray segment
//! ([`Implicit::enclose_along`]) gets guaranteed first roots ([`crate::isolation`]) instead of the
//! sampling / Lipschitz march.

use crate::bounds::Aabb;
use crate::crossings::{step_past, Crossing, Crossings};
use crate::expr::Jet;
use crate::hit::RawHit;
use crate::hit::{HitRequest, SurfaceHit};
use crate::math::enclosure::Enclosure;
use crate::proximity::{Closest, SignMethod};
use crate::ray::{Interval, Ray};
use crate::root::{self, RootOptions};
use glam::{DVec2, DVec3, Vec3};

pub use crate::implicit::Implicit;

/// The rectangle `u ∈ [u.0, u.1]`, `v ∈ [v.0, v.1]` a parametric form is defined on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvDomain {
    /// Range of `u`.
    pub u: (f64, f64),
    /// Range of `v`.
    pub v: (f64, f64),
}

impl UvDomain {
    /// `[0, 1] × [0, 1]`.
    pub const UNIT: Self = Self {
        u: (0.0, 1.0),
        v: (0.0, 1.0),
    };
}

/// A surface given as a map from a parameter rectangle `(u, v)` to points.
pub trait Parametric {
    /// Where `(u, v)` may range. Planar primitives use plane coordinates, so their domain covers
    /// the shape's bounding rectangle and [`Implicit::within_boundary`] says which points count.
    fn domain(&self) -> UvDomain {
        UvDomain::UNIT
    }

    /// The surface point at `(u, v)`.
    fn point(&self, uv: DVec2) -> DVec3;

    /// `(∂p/∂u, ∂p/∂v)` at `(u, v)`. Their cross product points to the `Φ > 0` side. The default
    /// is a central difference; built-ins give the analytic form.
    fn partials(&self, uv: DVec2) -> (DVec3, DVec3) {
        let h = 1e-6;
        let du = DVec2::new(h, 0.0);
        let dv = DVec2::new(0.0, h);
        (
            (self.point(uv + du) - self.point(uv - du)) / (2.0 * h),
            (self.point(uv + dv) - self.point(uv - dv)) / (2.0 * h),
        )
    }

    /// The parameters of a point `p` on the surface (the inverse of [`Parametric::point`]).
    fn uv(&self, p: DVec3) -> DVec2;
}

/// First-hit ray intersection.
pub trait Intersect: Implicit {
    /// The hit with the smallest `t` in the closed `range`, or `None`.
    ///
    /// The default runs the generic root finder ([`root::first_root`]) on Φ with
    /// [`Intersect::root_options`]; closed-form primitives override it.
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        root::first_root(self, ray, range, &self.root_options()).hit
    }

    /// Closest hits of many unrelated rays (a query batch, in any order): `hits[i]` becomes
    /// exactly [`Intersect::intersect`]`(&rays[i], ranges[i])`, and `uncertain[i]` whether a
    /// root finder ran out of budget on that ray (this thread's
    /// [`crate::root::thread_uncertain_events`] moved while it was traced). The four slices have
    /// the same length.
    ///
    /// The default calls `intersect` ray after ray; a type whose test runs in a copy chosen at
    /// run time overrides it to choose once for the whole batch (a mesh), with the same answers.
    fn intersect_each(&self, rays: &[Ray], ranges: &[Interval], hits: &mut [Option<RawHit>], uncertain: &mut [bool]) {
        for (((ray, range), hit), uncertain) in rays.iter().zip(ranges).zip(hits).zip(uncertain) {
            (*hit, *uncertain) = crate::root::uncertain_while(|| self.intersect(ray, *range));
        }
    }

    /// Closest hits of several rays at once (a packet of at most [`crate::PACKET`] coherent
    /// rays, such as neighbouring pixels): for each lane `i`, exactly
    /// [`Intersect::intersect`]`(&rays[i], ranges[i])`; where that is a hit, `hits[i]` is set to
    /// it and `ranges[i].max` to its `t`, and other lanes are left as they were (so a scene calls
    /// it object after object). The three slices have the same length.
    ///
    /// The default traces lane after lane; a type with a faster way overrides it (a mesh walks
    /// its hierarchy once for the whole packet, with the rays in SIMD lanes), giving the same
    /// answers.
    fn intersect_packet(&self, rays: &[Ray], ranges: &mut [Interval], hits: &mut [Option<RawHit>]) {
        packet_lane_by_lane(self, rays, ranges, hits);
    }

    /// Tolerances of the generic root finder for this type.
    fn root_options(&self) -> RootOptions {
        RootOptions::default()
    }

    /// Unit outward normal (towards Φ > 0) at the hit `raw` found along `ray`. The default
    /// normalises [`Implicit::gradient`] at `ray.at(raw.t)` and returns zero where ∇Φ vanishes.
    fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 {
        self.gradient(ray.at(raw.t)).normalize_or_zero()
    }

    /// [`Intersect::normal_at`] rounded to f32, component by component: always exactly
    /// `normal_at(ray, raw).as_vec3()`. For outputs stored in f32 (the render's AOVs); a type
    /// that keeps its normals rounded (a mesh's per-triangle table) answers from them without
    /// the square root and division of the f64 normal. The default rounds `normal_at`.
    fn normal_at_f32(&self, ray: &Ray, raw: &RawHit) -> Vec3 {
        self.normal_at(ray, raw).as_vec3()
    }

    /// Surface parameters at the hit, where the type has them. The default has none; types that
    /// implement [`Parametric`] return `Some(Parametric::uv(point))`.
    fn uv_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        let _ = (ray, raw);
        None
    }

    /// A bound on the distance between the computed hit point `ray.at(raw.t)` and the exact
    /// surface, for starting secondary rays ([`crate::offset`]). The default,
    /// [`crate::offset::point_error_bound`] with the bounds' magnitude, covers the built-in
    /// closed forms and the root finder's points in the primitive's own space; [`crate::Transformed`]
    /// adds the rounding of its maps.
    fn hit_error(&self, ray: &Ray, raw: &RawHit) -> f64 {
        crate::offset::point_error_bound(ray, raw.t, crate::offset::magnitude(&self.bounds()))
    }

    /// Unit shading normal at the hit where the type has one distinct from the geometric normal
    /// (a mesh's interpolated per-vertex normals), on the same side as
    /// [`Intersect::normal_at`] up to interpolation. The default has none.
    fn shading_normal_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec3> {
        let _ = (ray, raw);
        None
    }

    /// Whether the ray starts inside at `range.min`, then every boundary crossing in `range`,
    /// lazily in increasing `t` (see [`crate::crossings`]). The default,
    /// [`repeated_intersection`], asks [`Intersect::intersect`] again a small step past
    /// each hit; combinators ([`crate::Csg`]) and wrappers ([`crate::Transformed`]) override it so
    /// nested trees are walked once per ray.
    fn crossings<'a>(&'a self, ray: &Ray, range: Interval) -> Crossings<'a> {
        repeated_intersection(self, ray, range)
    }

    /// How far from the exact ray `origin + t·dir` a hit this type reports may lie because of
    /// how it stores the ray's origin, beyond rounding proportional to the distance travelled:
    /// 0 for tests in f64 (the default); a mesh, which tests an f32 copy of the ray,
    /// `2⁻²³·max |origin component|`. What skips pixels by geometry (footprints of boxes) must
    /// allow for it.
    fn origin_rounding(&self, origin: DVec3) -> f64 {
        let _ = origin;
        0.0
    }

    /// A ball `(centre, radius)` holding every point of the surface, where the type knows one
    /// that is tighter than its box: what decides which pixels can see the object projects it
    /// instead of the box (a sphere's box seen at an angle covers about twice its disc). The
    /// default has none.
    fn bounding_ball(&self) -> Option<(DVec3, f64)> {
        None
    }

    /// The surface cut into boxed pieces that can be tested on their own ([`Pieces`]), where
    /// the type has such a cut (a mesh: its hierarchy's leaves). The default has none.
    fn pieces(&self) -> Option<&dyn Pieces> {
        None
    }
}

/// A surface cut into pieces, each inside a box, whose closest hit can be found among a few of
/// them: a renderer that knows beforehand which boxes a ray can meet (the boxes whose image
/// covers a pixel) hands those to [`Pieces::intersect_pieces`] and skips the hierarchy walk.
pub trait Pieces: Sync {
    /// The numbers of the pieces, each once (in an order that keeps neighbours in space mostly
    /// together). Other numbers name no piece.
    fn piece_numbers(&self) -> Vec<u32>;

    /// The box of the piece numbered `number` (finite), or `None` if no piece has that number.
    /// Every point of the surface lies in at least one piece's box.
    fn piece_box(&self, number: u32) -> Option<Aabb>;

    /// [`Pieces::piece_numbers`], in the same order, less pieces the caller has no need of: the
    /// caller is asked about boxes holding several pieces (a hierarchy's inner nodes), and
    /// [`Wanted::Nothing`] promises that no piece lying wholly inside the box is needed; those
    /// are then left out together, unread. A crop of a render needs only the pieces it may see.
    /// Pieces of boxes not asked about, or answered otherwise, are all returned. The default asks
    /// nothing and returns every piece.
    fn piece_numbers_kept(&self, wanted: &(dyn Fn(&Aabb) -> Wanted + Sync)) -> Vec<u32> {
        let _ = wanted;
        self.piece_numbers()
    }

    /// [`Pieces::piece_box`] of each of `numbers` into `boxes` (as long), [`Aabb::EMPTY`] where no
    /// piece has the number: one call for the many pieces a renderer projects (the default,
    /// compiled for each implementing type, calls its `piece_box` directly).
    fn piece_boxes(&self, numbers: &[u32], boxes: &mut [Aabb]) {
        for (&number, bounds) in numbers.iter().zip(boxes) {
            *bounds = self.piece_box(number).unwrap_or(Aabb::EMPTY);
        }
    }

    /// Exactly [`Intersect::intersect`]`(ray, range)`, given that `candidates` (piece numbers,
    /// in any order, repeats allowed, numbers of no piece ignored) holds every piece whose box
    /// the ray passes within `10⁻⁶·(|box diagonal| + |box centre − ray origin|)` plus four times
    /// [`Intersect::origin_rounding`] of inside `range`: no other piece can hold the closest hit.
    /// Nearer pieces first make it faster (farther ones are then dismissed by their box).
    fn intersect_pieces(&self, ray: &Ray, range: Interval, candidates: &[u32]) -> Option<RawHit>;

    /// [`Pieces::intersect_pieces`] for candidates listed nearest first, each `(number, near)`
    /// with `near` at most the distance from the ray's origin to the piece's box less
    /// `10⁻⁶·(|box diagonal| + |box centre − ray origin|)` plus four times
    /// [`Intersect::origin_rounding`] (the margin of [`Pieces::intersect_pieces`]), and `near`
    /// never decreasing along the list: once the closest hit so far lies nearer than a
    /// candidate's `near`, that candidate and all after it can be left untested. The default
    /// tests them all.
    fn intersect_pieces_nearest_first(&self, ray: &Ray, range: Interval, candidates: &[(u32, f32)]) -> Option<RawHit> {
        let numbers: Vec<u32> = candidates.iter().map(|&(number, _)| number).collect();
        self.intersect_pieces(ray, range, &numbers)
    }

    /// [`Pieces::intersect_pieces_nearest_first`], and with the hit the normal
    /// [`Intersect::normal_at_f32`] gives for it, bit for bit, where the type works it out along
    /// the way (a mesh: from the triangle's rows the hit was found in, before they leave the
    /// cache); `None` in its place where not (the default).
    fn intersect_pieces_nearest_first_with_normal(
        &self,
        ray: &Ray,
        range: Interval,
        candidates: &[(u32, f32)],
    ) -> Option<(RawHit, Option<Vec3>)> {
        self.intersect_pieces_nearest_first(ray, range, candidates)
            .map(|hit| (hit, None))
    }
}

/// What a caller of [`Pieces::piece_numbers_kept`] needs of the pieces lying inside a box.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wanted {
    /// None of them.
    Nothing,
    /// Maybe all of them: they are returned without asking about the boxes inside.
    Everything,
    /// Maybe some of them: ask about the boxes inside.
    Partly,
}

/// What a scene stores: anything that intersects, is printable and can be shared across threads.
/// Implemented for every such type; use it as `Arc<dyn Primitive>`.
pub trait Primitive: Intersect + std::fmt::Debug + Send + Sync {}

impl<T: Intersect + std::fmt::Debug + Send + Sync + ?Sized> Primitive for T {}

macro_rules! forward_through_pointer {
    ($($ptr:ident)::+) => {
        impl<P: Implicit + ?Sized> Implicit for $($ptr)::+<P> {
            fn phi(&self, p: DVec3) -> f64 { (**self).phi(p) }
            fn bounds(&self) -> Aabb { (**self).bounds() }
            fn bounds_parts(&self, parts: &mut Vec<Aabb>) { (**self).bounds_parts(parts) }
            fn gradient(&self, p: DVec3) -> DVec3 { (**self).gradient(p) }
            fn lipschitz(&self) -> Option<f64> { (**self).lipschitz() }
            fn within_boundary(&self, p: DVec3) -> bool { (**self).within_boundary(p) }
            fn closest(&self, p: DVec3) -> Option<Closest> { (**self).closest(p) }
            fn contains(&self, p: DVec3, method: SignMethod) -> bool { (**self).contains(p, method) }
            fn enclose_along(&self, ray: &Ray, segment: Interval) -> Option<Jet<Enclosure>> { (**self).enclose_along(ray, segment) }
            fn enclose_value_along(&self, ray: &Ray, segment: Interval) -> Option<Enclosure> { (**self).enclose_value_along(ray, segment) }
        }
        impl<P: Intersect + ?Sized> Intersect for $($ptr)::+<P> {
            fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> { (**self).intersect(ray, range) }
            fn intersect_packet(&self, rays: &[Ray], ranges: &mut [Interval], hits: &mut [Option<RawHit>]) { (**self).intersect_packet(rays, ranges, hits) }
            fn intersect_each(&self, rays: &[Ray], ranges: &[Interval], hits: &mut [Option<RawHit>], uncertain: &mut [bool]) { (**self).intersect_each(rays, ranges, hits, uncertain) }
            fn root_options(&self) -> RootOptions { (**self).root_options() }
            fn normal_at(&self, ray: &Ray, raw: &RawHit) -> DVec3 { (**self).normal_at(ray, raw) }
            fn normal_at_f32(&self, ray: &Ray, raw: &RawHit) -> Vec3 { (**self).normal_at_f32(ray, raw) }
            fn uv_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec2> { (**self).uv_at(ray, raw) }
            fn hit_error(&self, ray: &Ray, raw: &RawHit) -> f64 { (**self).hit_error(ray, raw) }
            fn shading_normal_at(&self, ray: &Ray, raw: &RawHit) -> Option<DVec3> { (**self).shading_normal_at(ray, raw) }
            fn crossings<'a>(&'a self, ray: &Ray, range: Interval) -> Crossings<'a> { (**self).crossings(ray, range) }
            fn bounding_ball(&self) -> Option<(DVec3, f64)> { (**self).bounding_ball() }
            fn pieces(&self) -> Option<&dyn Pieces> { (**self).pieces() }
            fn origin_rounding(&self, origin: DVec3) -> f64 { (**self).origin_rounding(origin) }
        }
    };
}

forward_through_pointer!(std::sync::Arc);
forward_through_pointer!(Box);

/// [`Intersect::intersect_packet`] lane after lane with [`Intersect::intersect`]: its default,
/// for overrides that take this way for some of their rays.
pub fn packet_lane_by_lane<P: Intersect + ?Sized>(
    primitive: &P,
    rays: &[Ray],
    ranges: &mut [Interval],
    hits: &mut [Option<RawHit>],
) {
    for ((ray, range), hit) in rays.iter().zip(ranges.iter_mut()).zip(hits.iter_mut()) {
        if let Some(found) = primitive.intersect(ray, *range) {
            range.max = found.t;
            *hit = Some(found);
        }
    }
}

/// The crossings of `primitive` found by repeated first-hit queries: the default of
/// [`Intersect::crossings`].
///
/// After a hit at `t` the next search starts at [`step_past`]`(t)`. Where the primitive keeps
/// reporting tangential contacts (`dir · n = 0`, e.g. a ray lying in a face plane, a contact
/// segment reported at every `t_min`), the step doubles, so the segment is left in at most
/// ~2,100 queries instead of one ulp at a time.
pub fn repeated_intersection<'a, P: Intersect + ?Sized>(primitive: &'a P, ray: &Ray, range: Interval) -> Crossings<'a> {
    let ray = *ray;
    let mut from = range.min;
    let mut step = 0.0f64;
    let mut done = false;
    let rest = std::iter::from_fn(move || loop {
        if done {
            return None;
        }
        let Some(hit) = primitive.intersect(&ray, Interval::new(from, range.max)) else {
            done = true;
            return None;
        };
        let facing = ray.dir.dot(primitive.normal_at(&ray, &hit));
        let mut after = step_past(hit.t);
        if facing == 0.0 {
            step = (2.0 * step).max(after - hit.t);
            after = hit.t + step;
        } else {
            step = 0.0;
        }
        if after.is_finite() && after > hit.t && after <= range.max {
            from = after;
        } else {
            done = true;
        }
        if facing != 0.0 {
            return Some(Crossing {
                hit,
                inside_after: facing < 0.0,
            });
        }
    });
    let start = ray.at(range.min);
    Crossings::with_lazy_start(move || primitive.phi(start) < 0.0, rest)
}

/// The second stage of a hit, written here beside [`Intersect`] (whose methods it calls).
impl SurfaceHit {
    /// Builds the record for `raw`, found on `surface` along `ray`, computing what `request` asks.
    #[must_use]
    pub fn complete<S: Intersect + ?Sized>(surface: &S, ray: &Ray, raw: &RawHit, request: HitRequest) -> Self {
        Self {
            t: raw.t,
            point: ray.at(raw.t),
            normal: request.normal.then(|| surface.normal_at(ray, raw)),
            uv: if request.uv { surface.uv_at(ray, raw) } else { None },
            feature: raw.feature,
            error: if request.error {
                surface.hit_error(ray, raw)
            } else {
                f64::INFINITY
            },
        }
    }
}
