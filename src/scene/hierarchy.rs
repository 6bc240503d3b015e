//! The scene's acceleration structure, built when the scene is loaded: a BVH over the bounded
//! objects and the objects every ray tests. The queries that walk it live in [`crate::trace`].

use super::Object;
use zeroset_primitives::Bvh;

/// The objects' acceleration structure: a BVH over the bounded ones, plus the objects tested on
/// every ray (those with infinite bounds, and a lone bounded object).
#[derive(Debug, Default)]
pub(crate) struct Hierarchy {
    pub(crate) unbounded: Vec<u32>,
    pub(crate) bvh: Bvh,
}

impl Hierarchy {
    /// Builds the hierarchy over `objects`' world bounds (a moving object's over its motion).
    pub(crate) fn build(objects: &[Object]) -> Self {
        let bounds = |o: &Object| match &o.motion {
            None => o.primitive.bounds(),
            Some(m) => m.bounds(),
        };
        let mut unbounded = Vec::new();
        let (mut bounded, mut last_bounded) = (0usize, 0u32);
        for (i, o) in objects.iter().enumerate() {
            if bounds(o).is_finite() {
                bounded += 1;
                last_bounded = i as u32;
            } else {
                unbounded.push(i as u32);
            }
        }
        // a lone bounded object is tested directly: a scene of one primitive pays nothing for the BVH
        if bounded == 1 {
            unbounded.push(last_bounded);
            return Self {
                unbounded,
                bvh: Bvh::default(),
            };
        }
        // the boxes are computed again as the builder takes them, not held in a list meanwhile
        let boxes = objects.iter().enumerate().filter_map(|(i, o)| {
            let b = bounds(o);
            b.is_finite().then_some((b, i as u32))
        });
        let bvh = Bvh::build_from(boxes);
        Self { unbounded, bvh }
    }
}
