//! Tests of the hierarchy builder.
use super::*;

/// Items in surface order (neighbours fall in the same bins), one in 97 at the far end of
/// the f32 range.
fn binned_items(n: usize) -> Vec<BuildItem> {
    (0..n)
        .map(|i| {
            let x = i as f32 * 0.01;
            let lo = if i % 97 == 5 {
                Vec3A::new(-f32::MAX, 1.0, 2.0)
            } else {
                Vec3A::new(x, (x * 3.0).sin(), 0.5 * x)
            };
            BuildItem::new(
                Bb {
                    lo,
                    hi: lo + Vec3A::new(0.02, 0.03, 0.01),
                },
                i as u32,
            )
        })
        .collect()
}

/// The two sets of bins of a large node's binning, merged, are the bins of one set: the same
/// counts, the same boxes, bit for bit.
#[test]
fn paired_bins_equal_one_set() {
    for n in [3, 127, 128, 129, 1000, 4097] {
        let items = binned_items(n);
        let (_, centroids) = boxes_of(&items);
        let extent = centroids.hi - centroids.lo;
        let scale = Vec3A::select(extent.cmpgt(Vec3A::ZERO), Vec3A::splat(31.9) / extent, Vec3A::ZERO);
        let mut paired = Bins::<BINS>::empty();
        paired.add(&items, centroids.lo, scale);
        let mut single = Bins::<BINS>::empty();
        single.add_each(&items, centroids.lo, scale);
        assert_eq!(paired.counts, single.counts, "{n} items");
        let bits = |b: &Bins<BINS>| {
            b.bounds
                .iter()
                .flatten()
                .flat_map(|bb| [bb.lo.to_array(), bb.hi.to_array()])
                .flatten()
                .map(f32::to_bits)
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&paired), bits(&single), "{n} items");
    }
}

/// The SAH split moves its items word by word: afterwards the same items, each whole, those
/// whose bin is left of the split first, in the order in which they came.
#[test]
fn split_partitions_whole_items_stably_on_the_left() {
    let items = binned_items(3000);
    let mut split = items.clone();
    let (bounds, centroids) = boxes_of(&split);
    let Some(Split::At(children)) =
        sah_split_binned::<BINS>(&mut split, bounds, centroids, Leaves::tested_together(8, 3.0))
    else {
        panic!("3000 spread items are split");
    };
    let key = |t: &BuildItem| (t.id, t.lo.map(f32::to_bits), t.hi.map(f32::to_bits));
    let mut before: Vec<_> = items.iter().map(key).collect();
    let mut after: Vec<_> = split.iter().map(key).collect();
    // the left side keeps the items' order (each is swapped to the end of the left side)
    let left: Vec<u32> = split[..children.mid].iter().map(|t| t.id).collect();
    assert!(left.windows(2).all(|w| w[0] < w[1]), "left side in input order");
    let in_left = |t: &BuildItem| left.binary_search(&t.id).is_ok();
    let lc = split[..children.mid]
        .iter()
        .fold(Bb::EMPTY, |b, t| b.include(t.centroid()));
    assert_eq!(lc.lo.to_array(), children.centroids[0].lo.to_array());
    assert!(split[children.mid..].iter().all(|t| !in_left(t)));
    before.sort_unstable();
    after.sort_unstable();
    assert_eq!(before, after, "the same items, each whole");
}

#[test]
fn build_items_are_small_and_keep_box_and_centre() {
    assert_eq!(std::mem::size_of::<BuildItem>(), 28);
    assert_eq!(std::mem::size_of::<Quad>(), 128);
    let bounds = Bb {
        lo: Vec3A::new(-f32::MAX, 1.0, -3.5),
        hi: Vec3A::new(f32::MAX, f32::MAX, 0.25),
    };
    let item = BuildItem::new(bounds, 7);
    assert_eq!(item.id, 7);
    assert_eq!((item.bounds().lo, item.bounds().hi), (bounds.lo, bounds.hi));
    // lo/2 + hi/2 in f64 (exact here), where (lo + hi)/2 would overflow to infinity
    let expected = [0.0, 0.5 + f64::from(f32::MAX) / 2.0, -1.625];
    for (axis, expected) in expected.into_iter().enumerate() {
        assert_eq!(f64::from(item.centroid()[axis]), expected as f32 as f64, "axis {axis}");
        assert_eq!(item.centroid_on(axis).to_bits(), item.centroid()[axis].to_bits());
    }
}

/// Every node in use is reached exactly once from the root, children after their parent;
/// the parallel subtrees' unused room is zero nodes that no slot refers to; every item lies
/// in exactly one leaf, inside its box. For leaf roots and trees of every shape, small ones
/// packed and large ones built in parallel (more than `PARALLEL_MIN` items).
#[test]
fn node_arrays_hold_the_whole_tree() {
    let mut state = 12345u64;
    let mut random = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    // random boxes, then (from 10⁴ items on) boxes whose centres all coincide, which are split
    // at the median all the way down
    let sizes = [1, 2, 3, 7, 64, 65, 1000, 5000, 70_000, 10_000, 20_000];
    for (round, n) in sizes.into_iter().enumerate() {
        let coincide = round >= 9;
        let mut items: Vec<BuildItem> = (0..n)
            .map(|id| {
                let lo = Vec3A::new(random(), random(), random()) * 100.0;
                let size = Vec3A::new(random(), random(), random());
                let bounds = if coincide {
                    Bb {
                        lo: Vec3A::splat(-1.0) - size,
                        hi: Vec3A::splat(1.0) + size,
                    }
                } else {
                    Bb { lo, hi: lo + size }
                };
                BuildItem::new(bounds, id)
            })
            .collect();
        for leaves in [
            Leaves::per_item(2),
            Leaves::per_item(6),
            Leaves::tested_together(8, 3.0),
        ] {
            let bvh = QuadBvh::build(&mut items, leaves);
            assert!(!bvh.quads.is_empty());
            assert!(bvh.quads.len() <= node_bound(n));
            // every quad reached once, children after their parent (depth first), and
            // every item in exactly one leaf inside its leaf's box
            let mut reached = vec![0; bvh.quads.len()];
            let mut covered = vec![0; n as usize];
            reached[0] = 1;
            for (index, quad) in bvh.quads.iter().enumerate() {
                for s in 0..quad.len as usize {
                    let (first, count) = (quad.child[s] as usize, usize::from(quad.count[s]));
                    if count == 0 {
                        assert!(first > index, "{n} items: quad {index} slot {s}");
                        reached[first] += 1;
                        continue;
                    }
                    for item in &items[first..first + count] {
                        covered[item.id as usize] += 1;
                        for axis in 0..3 {
                            assert!(quad.lo[axis][s] <= item.lo[axis] && item.hi[axis] <= quad.hi[axis][s]);
                        }
                    }
                }
            }
            assert_eq!(reached.iter().filter(|&&r| r == 1).count(), bvh.quad_count());
            for (quad, &r) in bvh.quads.iter().zip(&reached) {
                assert!(r <= 1, "{n} items, {leaves:?}");
                if r == 0 {
                    assert!(quad.len == 0 && quad.child == [0; 4] && quad.count == [0; 4]);
                }
            }
            if n <= PARALLEL_MIN as u32 {
                assert_eq!(bvh.quads.len(), bvh.quad_count(), "packed: {n} items");
            }
            assert!(covered.iter().all(|&c| c == 1), "{n} items, {leaves:?}");
        }
    }
}
