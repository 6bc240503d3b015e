//! The scene's hierarchy over its bounded objects ([`Bvh`]): built by the one builder with leaves
//! of at most two objects, walked by single rays ([`Bvh::closest`]) and by packets
//! ([`Bvh::closest_packet`]).
//!
//! Its slab tests are conservative against the f64 ray (the objects are then tested in f64, so
//! the f32 traversal never changes a hit): boxes are rounded outward from the objects' f64 boxes,
//! each slab's entry is lowered and its exit raised by the f32 origin's error and one more f32
//! ulp of the origin (`pad`, scaled by the reciprocal direction), and exits are enlarged by
//! `1 + 2γ₅`. A ray the f32 arithmetic cannot represent (an origin past `10³⁷`, a tiny non-zero
//! direction component) tests every object instead.

use super::build::{Bb, BuildItem, Leaves};
use super::lanes::{lane_mask, lanes_of, max_f32, min_f32};
use super::packet::{walk_packet, PacketVisitor};
use super::quad::Quad;
use super::quad_bvh::QuadBvh;
use super::rounding::{round_down, round_up};
use super::walk::{traverse_quads, traverse_quads_from, NodeTest, SlabsFrom};
use crate::PACKET;
use crate::{Aabb, Interval, Ray};
use glam::{Vec3A, Vec4};

/// A BVH over items identified by `u32` ids.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    /// The 4-wide nodes; leaves index `items`.
    tree: QuadBvh,
    /// Item ids in leaf order.
    items: Vec<u32>,
}

/// Largest leaf of the scene's hierarchy.
const MAX_LEAF: usize = 2;

/// A ray's data for the conservative slab tests: the f32 origin, the reciprocal direction (a
/// zero component as `±10³⁰`) and the per-axis pad `(|o − o₃₂| + ulp(o₃₂))·|1/d|`.
pub(super) struct SlabRay {
    origin: Vec3A,
    inv: Vec3A,
    pad: Vec3A,
}

const EXIT_PAD: f32 = 1.0 + 2.0 * (5.0 * f32::EPSILON * 0.5) / (1.0 - 5.0 * f32::EPSILON * 0.5);

impl SlabRay {
    #[inline]
    pub(super) fn new(ray: &Ray) -> Self {
        let origin = ray.origin.as_vec3a();
        let error = (ray.origin - origin.as_dvec3()).abs().as_vec3a();
        let inv = Vec3A::from_array(ray.dir.to_array().map(|d| {
            if d == 0.0 {
                1e30f32.copysign(d as f32)
            } else {
                (1.0 / d) as f32
            }
        }));
        // one more f32 ulp of the origin keeps the pad itself conservative
        let pad = (error + origin.abs() * f32::EPSILON) * inv.abs();
        Self { origin, inv, pad }
    }

    /// Whether the f32 slab arithmetic is meaningful for this ray: origin, reciprocals and pads
    /// finite, and the origin well inside f32 range (so that `box − origin` cannot overflow).
    #[inline]
    fn is_representable(&self) -> bool {
        self.origin.abs().max_element() <= 1e37 && self.inv.is_finite() && self.pad.is_finite()
    }

    /// Entry distances into the four boxes of `quad` within `[t0, t1]`: [`SlabRay::entry`]'s
    /// arithmetic, four boxes per SSE operation.
    #[inline(always)]
    pub(super) fn entry4(&self, quad: &Quad, t0: f32, t1: f32) -> (u32, [f32; 4]) {
        let mut near = Vec4::splat(t0);
        let mut far = Vec4::splat(t1);
        for axis in 0..3 {
            let o = Vec4::splat(self.origin[axis]);
            let inv = Vec4::splat(self.inv[axis]);
            let pad = Vec4::splat(self.pad[axis]);
            let a = (Vec4::from_array(quad.lo[axis]) - o) * inv;
            let b = (Vec4::from_array(quad.hi[axis]) - o) * inv;
            near = near.max(a.min(b) - pad);
            far = far.min(a.max(b) * EXIT_PAD + pad);
        }
        (near.cmple(far).bitmask(), near.to_array())
    }

    /// Entry distance into the node within `[t0, t1]`, or `None`.
    #[inline(always)]
    #[cfg(test)]
    pub(super) fn entry(&self, bounds: &[[f32; 3]; 2], t0: f32, t1: f32) -> Option<f32> {
        let lo = (Vec3A::from_array(bounds[0]) - self.origin) * self.inv;
        let hi = (Vec3A::from_array(bounds[1]) - self.origin) * self.inv;
        let near = lo.min(hi) - self.pad;
        let far = lo.max(hi) * EXIT_PAD + self.pad;
        let near = near.max_element().max(t0);
        let far = far.min_element().min(t1);
        (near <= far).then_some(near)
    }
}

impl NodeTest for SlabsFrom<'_, SlabRay> {
    #[inline(always)]
    fn entry4(&self, quad: &Quad, t_max: f32) -> (u32, [f32; 4]) {
        self.ray.entry4(quad, self.t_min, t_max)
    }
}

impl Bvh {
    /// Whether the hierarchy holds no items (then every walk finds nothing).
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Builds over items `(bounds, id)` (all bounds finite), in parallel; traversal reports
    /// the ids. The tree does not depend on the thread count.
    #[must_use]
    pub fn build(items: &[(Aabb, u32)]) -> Self {
        Self::build_from(items.iter().copied())
    }

    /// [`Bvh::build`] over boxes given one at a time, so that the caller need not hold a list of
    /// them (48 B each) during the build.
    #[must_use]
    pub fn build_from(items: impl IntoIterator<Item = (Aabb, u32)>) -> Self {
        let work: Vec<BuildItem> = items
            .into_iter()
            .map(|(b, id)| {
                let bounds = Bb {
                    lo: Vec3A::new(round_down(b.min.x), round_down(b.min.y), round_down(b.min.z)),
                    hi: Vec3A::new(round_up(b.max.x), round_up(b.max.y), round_up(b.max.z)),
                };
                BuildItem::new(bounds, id)
            })
            .collect();
        if work.is_empty() {
            return Self::default();
        }
        let (tree, items) = QuadBvh::build_ids(work, Leaves::per_item(MAX_LEAF));
        Self { tree, items }
    }

    /// Nearest-item search from the point `p`: visits leaves nearest box first, calling
    /// `test(id, bound)` for their items with `bound` a lower bound of the distance from `p` to
    /// the item (the distance to its leaf's stored f32 box, which is rounded outward from the
    /// items' boxes); `test` returns a distance beyond which nothing need be visited (its best
    /// upper bound so far, `+∞` while it has none). Nodes farther than the smallest value
    /// returned so far are skipped.
    pub fn nearest(&self, p: glam::DVec3, mut test: impl FnMut(u32, f64) -> f64) {
        if self.items.is_empty() {
            return;
        }
        let best = std::cell::Cell::new(f64::INFINITY);
        // the walk asks for a node's bound right before visiting it as a leaf
        let last_bound = std::cell::Cell::new(0.0);
        self.tree.nearest(
            |node| {
                let lo = glam::DVec3::from_array(node.lo.map(f64::from));
                let hi = glam::DVec3::from_array(node.hi.map(f64::from));
                let d = (lo - p).max(p - hi).max(glam::DVec3::ZERO).length();
                last_bound.set(d);
                (d <= best.get()).then_some(d)
            },
            |first, count| {
                let bound = last_bound.get();
                for &id in &self.items[first as usize..(first + count) as usize] {
                    if bound <= best.get() {
                        best.set(best.get().min(test(id, bound)));
                    }
                }
            },
        );
    }

    /// Number of 4-wide nodes.
    #[must_use]
    pub fn node_count(&self) -> usize {
        self.tree.quad_count()
    }

    /// Closest-hit traversal: calls `test(id, range)` for items whose node the ray enters
    /// within `range`; `test` returns the hit parameter if it found one inside the range, which
    /// then becomes the new `range.max`. Returns the id of the item that set the final
    /// `range.max`. Walks the 4-wide nodes, entered children pushed farthest first.
    ///
    /// The f32 slab tests need the origin within f32 range and finite reciprocals of the
    /// direction; a ray beyond that (an origin past `10³⁷`, a direction component below
    /// `10⁻³⁸` but not zero) tests every item instead (slow, exact). Boxes beyond f32 range are
    /// stored as infinite and need nothing special.
    #[inline]
    pub fn closest(
        &self,
        ray: &Ray,
        mut range: Interval,
        mut test: impl FnMut(u32, Interval) -> Option<f64>,
    ) -> Option<u32> {
        // an empty hierarchy (a scene whose one bounded object is tested directly) costs nothing,
        // not even the slab set-up's divisions
        if self.items.is_empty() {
            return None;
        }
        let slab = SlabRay::new(ray);
        let mut best = None;
        if !slab.is_representable() {
            for &id in &self.items {
                if let Some(t) = test(id, range) {
                    range.max = t;
                    best = Some(id);
                }
            }
            return best;
        }
        let t0 = round_down(range.min);
        traverse_quads(
            self.tree.quads(),
            round_up(range.max),
            SlabsFrom { ray: &slab, t_min: t0 },
            |first, count, _| {
                let mut found = None;
                for &id in &self.items[first as usize..(first + count) as usize] {
                    if let Some(t) = test(id, range) {
                        range.max = t;
                        best = Some(id);
                        found = Some(round_up(t));
                    }
                }
                found
            },
        );
        best
    }
}

/// A packet's rays for the scene hierarchy's slab tests, in SoA layout (see [`SlabRay`]).
struct SlabPacket {
    origin: [[f32; PACKET]; 3],
    inv: [[f32; PACKET]; 3],
    pad: [[f32; PACKET]; 3],
    t_min: [f32; PACKET],
}

impl SlabPacket {
    /// Entry distances of every lane into child `slot` of `quad` and the lanes entering it
    /// before their `t1`: [`SlabRay::entry4`]'s arithmetic, lane by lane.
    #[inline(always)]
    fn entry(&self, quad: &Quad, slot: usize, t1: &[f32; PACKET]) -> (u32, [f32; PACKET]) {
        let mut near = [0.0; PACKET];
        let mut inside = [0i32; PACKET];
        for l in 0..PACKET {
            let mut n = self.t_min[l];
            let mut f = t1[l];
            for axis in 0..3 {
                let o = self.origin[axis][l];
                let inv = self.inv[axis][l];
                let pad = self.pad[axis][l];
                let a = (quad.lo[axis][slot] - o) * inv;
                let b = (quad.hi[axis][slot] - o) * inv;
                n = max_f32(n, min_f32(a, b) - pad);
                f = min_f32(f, max_f32(a, b) * EXIT_PAD + pad);
            }
            near[l] = n;
            inside[l] = -i32::from(n <= f);
        }
        (lane_mask(&inside), near)
    }
}

/// A node of the scene's hierarchy entered by at most this many lanes is walked by each alone.
const SCENE_ALONE_LANES: u32 = 1;

/// The scene hierarchy's packet walk: lanes' slab rays, ranges and closest ids so far.
struct ScenePacket<'a, T> {
    bvh: &'a Bvh,
    slabs: &'a [Option<SlabRay>; PACKET],
    packet: SlabPacket,
    ranges: [Interval; PACKET],
    best: [Option<u32>; PACKET],
    test: T,
}

impl<T: FnMut(usize, u32, Interval) -> Option<f64>> ScenePacket<'_, T> {
    /// Lane `l`'s items `first..first + count`: [`Bvh::closest`]'s leaf test. Returns the new
    /// `t_max` if one was hit.
    #[inline(always)]
    fn leaf_lane(&mut self, l: usize, first: u32, count: u32) -> Option<f32> {
        let mut found = None;
        for &id in &self.bvh.items[first as usize..(first + count) as usize] {
            if let Some(t) = (self.test)(l, id, self.ranges[l]) {
                self.ranges[l].max = t;
                self.best[l] = Some(id);
                found = Some(round_up(t));
            }
        }
        found
    }
}

impl<T: FnMut(usize, u32, Interval) -> Option<f64>> PacketVisitor for ScenePacket<'_, T> {
    #[inline(always)]
    fn entry(&self, quad: &Quad, slot: usize, t1: &[f32; PACKET]) -> (u32, [f32; PACKET]) {
        self.packet.entry(quad, slot, t1)
    }

    #[inline(always)]
    fn leaf(&mut self, first: u32, count: u32, lanes: u32, t_max: &mut [f32; PACKET]) {
        for l in lanes_of(lanes) {
            if let Some(t) = self.leaf_lane(l, first, count) {
                t_max[l] = t;
            }
        }
    }

    #[inline(always)]
    fn alone(&mut self, root: usize, lanes: u32, t_max: &mut [f32; PACKET]) {
        for l in lanes_of(lanes) {
            let Some(slab) = &self.slabs[l] else { continue };
            let t0 = self.packet.t_min[l];
            let mut lane_max = t_max[l];
            let quads = self.bvh.tree.quads();
            traverse_quads_from(
                quads,
                root,
                lane_max,
                SlabsFrom { ray: slab, t_min: t0 },
                |first, count, _| {
                    let t = self.leaf_lane(l, first, count)?;
                    lane_max = t;
                    Some(t)
                },
            );
            t_max[l] = lane_max;
        }
    }
}

impl Bvh {
    /// [`Bvh::closest`] for a packet of at most [`PACKET`] rays at once: `test(lane, id, range)`
    /// as there, per lane; returns each lane's id that set its final `range.max`. The rays walk
    /// the 4-wide nodes together (see [`walk_packet`]). Where `test` settles exact ties of `t`
    /// by id (rejects a hit at exactly `range.max` from an id above the one holding it), every
    /// lane gets [`Bvh::closest`]'s answer whatever order the leaves are visited in.
    pub fn closest_packet(
        &self,
        rays: &[Ray],
        ranges: &[Interval],
        mut test: impl FnMut(usize, u32, Interval) -> Option<f64>,
    ) -> [Option<u32>; PACKET] {
        let n = rays.len().min(PACKET);
        if n == 0 {
            return [None; PACKET];
        }
        let slabs: [Option<SlabRay>; PACKET] = std::array::from_fn(|l| (l < n).then(|| SlabRay::new(&rays[l])));
        if slabs[..n].iter().flatten().any(|s| !s.is_representable()) || self.tree.quads().is_empty() {
            let mut best = [None; PACKET];
            for l in 0..n {
                best[l] = self.closest(&rays[l], ranges[l], |id, r| test(l, id, r));
            }
            return best;
        }
        let mut packet = SlabPacket {
            origin: [[0.0; PACKET]; 3],
            inv: [[0.0; PACKET]; 3],
            pad: [[0.0; PACKET]; 3],
            t_min: [0.0; PACKET],
        };
        let mut t_max = [f32::NEG_INFINITY; PACKET];
        let mut lane_ranges = [Interval::POSITIVE; PACKET];
        let mut active = 0;
        for l in 0..PACKET {
            // a lane without a ray repeats the first with an empty range
            let (slab, range) = match &slabs[l] {
                Some(slab) => (slab, ranges[l]),
                None => (
                    slabs[0].as_ref().expect("a packet has a first ray"),
                    Interval::new(1.0, 0.0),
                ),
            };
            for axis in 0..3 {
                packet.origin[axis][l] = slab.origin[axis];
                packet.inv[axis][l] = slab.inv[axis];
                packet.pad[axis][l] = slab.pad[axis];
            }
            packet.t_min[l] = round_down(range.min);
            lane_ranges[l] = range;
            if l < n && !range.is_empty() {
                t_max[l] = round_up(range.max);
                active |= 1 << l;
            }
        }
        // the walk runs in the AVX2 copy where the CPU has it (eight lanes per slab operation);
        // `test` is called through a pointer, as a type without a name cannot cross into it
        #[inline(always)]
        fn walk(
            bvh: &Bvh,
            slabs: &[Option<SlabRay>; PACKET],
            packet: SlabPacket,
            ranges: [Interval; PACKET],
            active: u32,
            t_max: &mut [f32; PACKET],
            test: &mut dyn FnMut(usize, u32, Interval) -> Option<f64>,
        ) -> [Option<u32>; PACKET] {
            let t_min = packet.t_min;
            let mut visitor = ScenePacket {
                bvh,
                slabs,
                packet,
                ranges,
                best: [None; PACKET],
                test,
            };
            walk_packet(bvh.tree.quads(), active, t_min, t_max, SCENE_ALONE_LANES, &mut visitor);
            visitor.best
        }
        crate::with_fma!(walk(
            bvh: &Bvh = self,
            slabs: &[Option<SlabRay>; PACKET] = &slabs,
            packet: SlabPacket = packet,
            ranges: [Interval; PACKET] = lane_ranges,
            active: u32 = active,
            t_max: &mut [f32; PACKET] = &mut t_max,
            test: &mut dyn FnMut(usize, u32, Interval) -> Option<f64> = &mut test,
        ) -> [Option<u32>; PACKET])
    }
}
