//! The mesh's trait implementations: [`Implicit`] (Φ, its gradient and the boxes of the
//! hierarchy's parts) and [`Intersect`] (single rays, batches, packets and the hit's normals, as
//! the module docs of [`crate::mesh`] state them). The work is done in the files next to this one:
//! `walk.rs` (single rays), `stream.rs` (batches), `packet.rs` (packets), `phi.rs` (Φ).

use super::packet;
use super::storage::{v64, Mesh};
use super::walk::single_ray;
use crate::bounds::Aabb;
use crate::crossings::Crossings;
use crate::hit::RawHit;
use crate::proximity::{Closest, SignMethod};
use crate::ray::{Interval, Ray};
use crate::traits::{Implicit, Intersect};
use glam::{DVec2, DVec3};

/// How many levels below the root [`Implicit::bounds_parts`] takes the boxes from.
pub(super) const PART_LEVELS: u32 = 4;

impl Implicit for Mesh {
    /// Distance to the nearest triangle, signed by its face normal (see the module docs);
    /// unsigned for a mesh without a surface ([`Mesh::has_surface`]).
    fn phi(&self, p: DVec3) -> f64 {
        let (q, k) = self.nearest(p);
        let d = (p - q).length();
        let (n, _) = self.plane(k);
        if n.dot(p - q) < 0.0 {
            -d
        } else {
            d
        }
    }

    fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The nearest point of the nearest triangle, in f64 (see `phi.rs`); its triangle is the
    /// feature, numbered as the mesh's input triangles. `None` for a mesh without triangles.
    fn closest(&self, p: DVec3) -> Option<Closest> {
        if self.tris.is_empty() {
            return None;
        }
        let (q, k) = self.nearest(p);
        Some(Closest::exact(p, q, self.leaf_to_file[k]))
    }

    /// The boxes [`PART_LEVELS`] levels below the hierarchy's root (at most `4^PART_LEVELS`; a
    /// leaf met on the way gives its own box): together they hold every triangle.
    fn bounds_parts(&self, parts: &mut Vec<Aabb>) {
        if self.bvh.quads().is_empty() {
            parts.push(self.bounds);
            return;
        }
        let boxes = self.bvh.boxes_below(PART_LEVELS);
        parts.extend(boxes.into_iter().map(|(lo, hi)| Aabb::new(v64(lo), v64(hi))));
    }

    /// Inside by `method` (see [`SignMethod`]'s table and `mesh/inside.rs`): the exact or the
    /// fast generalized winding number (`|w| > ½`), the nearest feature's angle-weighted
    /// pseudo-normal, or the parity of a ray's crossings.
    fn contains(&self, p: DVec3, method: SignMethod) -> bool {
        self.contains_by(p, method)
    }

    /// `±(p − q)/|p − q|` towards `Φ > 0`, or the nearest triangle's normal on the surface.
    fn gradient(&self, p: DVec3) -> DVec3 {
        let (q, k) = self.nearest(p);
        let n = self.plane(k).0.normalize_or_zero();
        let d = p - q;
        let len = d.length();
        if len <= 1e-12 * self.radius.max(f64::MIN_POSITIVE) {
            n
        } else if n.dot(d) < 0.0 {
            -d / len
        } else {
            d / len
        }
    }
}

impl Intersect for Mesh {
    /// [`single_ray`] in its AVX2+FMA copy where the CPU has them.
    fn intersect(&self, ray: &Ray, range: Interval) -> Option<RawHit> {
        if !self.surface {
            return None;
        }
        crate::with_fma!(single_ray(mesh: &Mesh = self, ray: &Ray = ray, range: Interval = range) -> Option<RawHit>)
    }

    /// The rays inside one AVX2+FMA copy (the CPU's features checked once for the batch), their
    /// walks interleaved on a mesh larger than the L2 cache (`mesh/stream.rs`): the same answers
    /// as [`Mesh::intersect`] ray by ray. A mesh has no root finder, so no answer is uncertain.
    fn intersect_each(&self, rays: &[Ray], ranges: &[Interval], hits: &mut [Option<RawHit>], uncertain: &mut [bool]) {
        uncertain.fill(false);
        if !self.surface {
            hits.fill(None);
            return;
        }
        #[inline(always)]
        fn each(mesh: &Mesh, rays: &[Ray], ranges: &[Interval], hits: &mut [Option<RawHit>]) {
            mesh.intersect_stream(rays, ranges, hits);
        }
        crate::with_fma!(each(mesh: &Mesh = self, rays: &[Ray] = rays, ranges: &[Interval] = ranges, hits: &mut [Option<RawHit>] = hits) -> ())
    }

    /// Walks the hierarchy once for the whole packet (see `mesh/packet.rs`); the same answers
    /// as [`Mesh::intersect`] lane by lane.
    fn intersect_packet(&self, rays: &[Ray], ranges: &mut [Interval], hits: &mut [Option<RawHit>]) {
        if !self.surface {
            hits.fill(None);
            return;
        }
        for ((rays, ranges), hits) in rays
            .chunks(crate::PACKET)
            .zip(ranges.chunks_mut(crate::PACKET))
            .zip(hits.chunks_mut(crate::PACKET))
        {
            packet::intersect(self, rays, ranges, hits);
        }
    }

    /// The hit triangle's geometric normal, `(b − a) × (c − a)` normalised.
    fn normal_at(&self, _ray: &Ray, raw: &RawHit) -> DVec3 {
        self.hit_plane(raw).map_or(DVec3::ZERO, |(n, _)| n.normalize_or_zero())
    }

    /// The hit triangle's normal from the f32 table made with the mesh (the same rounded
    /// values as `normal_at(…).as_vec3()`); without one (a large mesh), `normal_at` rounded.
    fn normal_at_f32(&self, _ray: &Ray, raw: &RawHit) -> glam::Vec3 {
        self.unit_normal_f32(raw.feature, || self.hit_plane(raw).map(|(n, _)| n))
    }

    /// Every crossing in one walk of the hierarchy (`mesh/crossings.rs`); a crossing at an edge
    /// or vertex shared by triangles is reported once. Whether the ray starts inside is decided
    /// by the default sign method ([`SignMethod::FastWinding`], a lookup for most points of a
    /// closed mesh), not by Φ's nearest face.
    fn crossings<'a>(&'a self, ray: &Ray, range: Interval) -> Crossings<'a> {
        if !self.surface {
            return Crossings::constant(false);
        }
        #[inline(always)]
        fn collect(mesh: &Mesh, ray: &Ray, range: Interval) -> Vec<crate::crossings::Crossing> {
            super::crossings::all_crossings(mesh, ray, range)
        }
        let found = crate::with_fma!(collect(mesh: &Mesh = self, ray: &Ray = ray, range: Interval = range) -> Vec<crate::crossings::Crossing>);
        Crossings::listed(self, ray.at(range.min), found)
    }

    /// The default bound, raised to what the f32 copy of a ray started near the surface is off
    /// by: `8·2⁻²³·(max |pᵢ| + the bounds' magnitude)` at the hit point `p`. A secondary ray
    /// started closer than that could have its f32 origin (off by `2⁻²⁴` of each component)
    /// on the other side of the triangle's plane, or its f32 test (whose sheared coordinates
    /// round at the vertices' magnitude) decide the side wrongly: it would hit the surface it
    /// leaves, or miss the one it enters.
    fn hit_error(&self, ray: &Ray, raw: &RawHit) -> f64 {
        let magnitude = crate::offset::magnitude(&self.bounds());
        let f32_rounding = 8.0 * f64::from(f32::EPSILON) * (ray.at(raw.t).abs().max_element() + magnitude);
        crate::offset::point_error_bound(ray, raw.t, magnitude).max(f32_rounding)
    }

    /// The barycentrics `(u, v)` of the hit (see the module docs).
    fn uv_at(&self, _ray: &Ray, raw: &RawHit) -> Option<DVec2> {
        Some(raw.local)
    }

    fn shading_normal_at(&self, _ray: &Ray, raw: &RawHit) -> Option<DVec3> {
        self.shading_normal(raw)
    }

    /// The hierarchy's leaves (see `mesh/pieces.rs`); none for a mesh without a surface.
    fn pieces(&self) -> Option<&dyn crate::Pieces> {
        self.surface.then_some(self as &dyn crate::Pieces)
    }

    /// The f32 copy of the origin is off by up to `2⁻²⁴` of each component's size: at most
    /// `√3·2⁻²⁴·max |oᵢ| < 2⁻²³·max |oᵢ|` in all.
    fn origin_rounding(&self, origin: DVec3) -> f64 {
        f64::from(f32::EPSILON) * origin.abs().max_element()
    }
}

/// Whether a ray's crossings start inside the mesh: the default sign method
/// ([`SignMethod::FastWinding`]).
impl crate::crossings::InsideTest for Mesh {
    fn inside(&self, p: DVec3) -> bool {
        self.contains(p, SignMethod::FastWinding)
    }
}
