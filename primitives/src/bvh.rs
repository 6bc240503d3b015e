//! The scene's bounding volume hierarchy over its bounded objects, and what every hierarchy
//! shares: the 4-wide node ([`Quad`]) and its ordered closest-hit walk ([`traverse_quads`]).
//! One builder (`build`: parallel binned SAH, collapsed into 4-wide nodes) makes both the
//! scene's hierarchy (leaves of at most two objects) and each mesh's (leaves of at most six
//! triangles).
//!
//! Traversal of the scene's hierarchy: quads hold their children's f32 bounds (rounded outward
//! from the objects' f64 bounds) in SoA layout, tested four at a time with SSE, conservative
//! against the f64 ray (see `SlabRay`); the nearest entered child is visited next, the others
//! pushed farthest first and skipped when popped if the closest hit is already nearer.
//! Primitives are then tested in f64, so the f32 traversal never changes a hit.

pub(crate) mod build;

use crate::{Aabb, Interval, Ray};
use build::{Bb, BuildItem, QuadBvh};
use glam::{Vec3A, Vec4};
use std::mem::MaybeUninit;

/// Rounds an f64 to the nearest f32 not above it (boxes and ray ranges rounded outward).
#[inline]
pub(crate) fn round_down(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) > x {
        y.next_down()
    } else {
        y
    }
}

/// Rounds an f64 to the nearest f32 not below it.
#[inline]
pub(crate) fn round_up(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) < x {
        y.next_up()
    } else {
        y
    }
}

/// A BVH over items identified by `u32` ids.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    /// The 4-wide nodes; leaves index `items`.
    tree: QuadBvh,
    /// Item ids in leaf order.
    items: Vec<u32>,
}

/// A 4-wide node, shared by the scene's and the meshes' hierarchies: up to four children's f32
/// boxes in SoA layout, tested in one SSE pass per axis. `count[i] = 0` marks an inner child
/// (its quad is `child[i]`), `count[i] > 0` a leaf of that many items (or triangles) from
/// `child[i]`; slots beyond `len` are empty.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
pub(crate) struct Quad {
    pub lo: [[f32; 4]; 3],
    pub hi: [[f32; 4]; 3],
    pub child: [u32; 4],
    pub count: [u32; 4],
    pub len: u32,
}

/// Traversal stack capacity: at most 3 entries left per level over at most 128 levels (both
/// hierarchies split at the median below a fixed depth, which bounds theirs under 128), plus 4.
const QUAD_STACK: usize = 3 * 128 + 4;

/// Ordered closest-hit walk over 4-wide nodes, starting at `quads[0]`: `entry4(quad, t_max)`
/// gives a bit per child slot the ray enters before `t_max` and the entry distances. The nearest
/// entered child is visited next and the others pushed farthest first (among equal entries the
/// later slot is visited first); one popped after the closest hit moved nearer than its entry
/// is skipped. `leaf(first, count, t_max)` tests a leaf and returns the new, smaller `t_max` if
/// it found a hit.
#[inline(always)]
pub(crate) fn traverse_quads(
    quads: &[Quad],
    mut t_max: f32,
    entry4: impl Fn(&Quad, f32) -> (u32, [f32; 4]),
    mut leaf: impl FnMut(u32, u32, f32) -> Option<f32>,
) {
    if quads.is_empty() {
        return;
    }
    // uninitialised: only entries below `top`, written before, are ever read
    let mut stack = [const { MaybeUninit::<(u32, u32, f32)>::uninit() }; QUAD_STACK];
    let mut top = 0usize;
    let mut quad = 0usize;
    'nodes: loop {
        let q = &quads[quad];
        let (hits, near) = entry4(q, t_max);
        let mut hits = hits & ((1u32 << q.len) - 1);
        let mut next = None;
        if hits != 0 {
            if hits & (hits - 1) == 0 {
                let slot = hits.trailing_zeros() as usize;
                next = Some((q.child[slot], q.count[slot], near[slot]));
            } else {
                // the entered children sorted farthest first (insertion into at most four)
                let mut order = [(0f32, 0usize); 4];
                let mut n = 0;
                while hits != 0 {
                    let slot = hits.trailing_zeros() as usize;
                    hits &= hits - 1;
                    let t = near[slot];
                    let mut k = n;
                    while k > 0 && order[k - 1].0 < t {
                        order[k] = order[k - 1];
                        k -= 1;
                    }
                    order[k] = (t, slot);
                    n += 1;
                }
                for &(t, slot) in &order[..n - 1] {
                    stack[top].write((q.child[slot], q.count[slot], t));
                    top += 1;
                }
                let (t, slot) = order[n - 1];
                next = Some((q.child[slot], q.count[slot], t));
            }
        }
        // visit `next`, else pop, until an inner node to open
        loop {
            let (child, count, entry) = match next.take() {
                Some(entry) => entry,
                None => {
                    if top == 0 {
                        return;
                    }
                    top -= 1;
                    // SAFETY: `stack[top]` was written by the push that raised `top` above it
                    unsafe { stack[top].assume_init() }
                }
            };
            if entry > t_max {
                continue;
            }
            if count == 0 {
                quad = child as usize;
                continue 'nodes;
            }
            if let Some(t) = leaf(child, count, t_max) {
                t_max = t;
            }
        }
    }
}

/// Largest leaf of the scene's hierarchy.
const MAX_LEAF: usize = 2;

struct SlabRay {
    origin: Vec3A,
    inv: Vec3A,
    pad: Vec3A,
}

const EXIT_PAD: f32 = 1.0 + 2.0 * (5.0 * f32::EPSILON * 0.5) / (1.0 - 5.0 * f32::EPSILON * 0.5);

impl SlabRay {
    #[inline]
    fn new(ray: &Ray) -> Self {
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
    fn entry4(&self, quad: &Quad, t0: f32, t1: f32) -> (u32, [f32; 4]) {
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
    fn entry(&self, bounds: &[[f32; 3]; 2], t0: f32, t1: f32) -> Option<f32> {
        let lo = (Vec3A::from_array(bounds[0]) - self.origin) * self.inv;
        let hi = (Vec3A::from_array(bounds[1]) - self.origin) * self.inv;
        let near = lo.min(hi) - self.pad;
        let far = lo.max(hi) * EXIT_PAD + self.pad;
        let near = near.max_element().max(t0);
        let far = far.min_element().min(t1);
        (near <= far).then_some(near)
    }
}

impl Bvh {
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
        let (tree, items) = QuadBvh::build_ids(work, MAX_LEAF);
        Self { tree, items }
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
            |q, t1| slab.entry4(q, t0, t1),
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

/// Splits `work` at its median centroid along the centroids' longest axis.
#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use rand::{Rng, SeedableRng};

    /// The 4-wide slab test gives exactly the single-box test's answer for each of its boxes.
    #[test]
    fn four_wide_entry_equals_single_entries() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        for _ in 0..20_000 {
            let mut quad = Quad {
                len: 4,
                ..Quad::default()
            };
            let mut nodes = Vec::new();
            for slot in 0..4 {
                let c = DVec3::new(
                    rng.random_range(-9.0..9.0),
                    rng.random_range(-9.0..9.0),
                    rng.random_range(-9.0..9.0),
                );
                let h = DVec3::new(
                    rng.random_range(0.0..2.0),
                    rng.random_range(0.0..2.0),
                    rng.random_range(0.0..2.0),
                );
                let (lo, hi) = (c - h, c + h);
                let node = [
                    [round_down(lo.x), round_down(lo.y), round_down(lo.z)],
                    [round_up(hi.x), round_up(hi.y), round_up(hi.z)],
                ];
                for (axis, (lo, hi)) in node[0].iter().zip(&node[1]).enumerate() {
                    quad.lo[axis][slot] = *lo;
                    quad.hi[axis][slot] = *hi;
                }
                nodes.push(node);
            }
            let mut d = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if rng.random_bool(0.2) {
                d.y = 0.0;
            }
            let o = DVec3::new(
                rng.random_range(-1e3..1e3),
                rng.random_range(-20.0..20.0),
                rng.random_range(-20.0..20.0),
            );
            let slab = SlabRay::new(&Ray::new(o, d));
            let (t0, t1) = (rng.random_range(0.0..1.0), rng.random_range(1.0..2e3));
            let single: Vec<_> = nodes.iter().map(|n| slab.entry(n, t0, t1)).collect();
            let (hits, near) = slab.entry4(&quad, t0, t1);
            let four: Vec<_> = (0..4).map(|i| (hits & (1 << i) != 0).then_some(near[i])).collect();
            assert_eq!(four, single);
        }
    }

    /// The BVH finds the same closest box as testing every box, on random boxes and rays.
    #[test]
    fn closest_hit_equals_brute_force() {
        closest_hit_equals_brute_force_with(500, 7, -20.0);
    }

    /// Above `build::PARALLEL_MIN` items the subtrees are built in parallel; origins beyond
    /// f32 range take the linear scan.
    #[test]
    fn parallel_build_and_far_origins_equal_brute_force() {
        closest_hit_equals_brute_force_with(5 * build::PARALLEL_MIN, 8, -20.0);
        closest_hit_equals_brute_force_with(600, 9, -1e39);
    }

    fn closest_hit_equals_brute_force_with(count: usize, seed: u64, origin_z: f64) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let boxes: Vec<Aabb> = (0..count)
            .map(|_| {
                let c = DVec3::new(
                    rng.random_range(-10.0..10.0),
                    rng.random_range(-10.0..10.0),
                    rng.random_range(-10.0..10.0),
                );
                let h = DVec3::new(
                    rng.random_range(0.01..1.0),
                    rng.random_range(0.01..1.0),
                    rng.random_range(0.01..1.0),
                );
                Aabb::new(c - h, c + h)
            })
            .collect();
        let items: Vec<(Aabb, u32)> = boxes.iter().enumerate().map(|(i, b)| (*b, i as u32)).collect();
        let bvh = Bvh::build(&items);
        let entry = |b: &Aabb, ray: &Ray, range: Interval| b.clip(ray, range).map(|r| r.min);
        for _ in 0..5000 {
            let o = DVec3::new(rng.random_range(-15.0..15.0), rng.random_range(-15.0..15.0), origin_z);
            let d = DVec3::new(rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5), 1.0).normalize();
            let ray = Ray::new(o, d);
            let brute = boxes
                .iter()
                .enumerate()
                .filter_map(|(i, b)| entry(b, &ray, Interval::POSITIVE).map(|t| (t, i as u32)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let found = bvh.closest(&ray, Interval::POSITIVE, |i, r| entry(&boxes[i as usize], &ray, r));
            assert_eq!(
                found.map(|i| entry(&boxes[i as usize], &ray, Interval::POSITIVE).unwrap()),
                brute.map(|b| b.0)
            );
        }
    }
}
