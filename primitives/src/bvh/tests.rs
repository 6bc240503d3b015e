//! Tests of the scene's hierarchy and the walks it shares (rounding, slab tests, child order,
//! single rays and packets against brute force).

use super::quad::Quad;
use super::rounding::{round_down, round_up};
use super::scene::SlabRay;
use super::walk::farthest_first;
use super::*;
use crate::{Aabb, Interval, Ray, PACKET};
use glam::DVec3;
use rand::{Rng, SeedableRng};

/// `round_down(x)` is the largest f32 not above `x` and `round_up(x)` the smallest not below,
/// checked by their definition in f64 (exact for every f32) on zeros of both signs, subnormal
/// f64s (a range opened at 0 starts at `0.next_up()`), f32 subnormals, normal values and the
/// ends of the ranges.
#[test]
fn rounding_brackets_every_value() {
    let values = [
        0.0,
        -0.0,
        0.0f64.next_up(),
        -(0.0f64.next_up()),
        f64::MIN_POSITIVE.next_down(),
        -f64::MIN_POSITIVE.next_down(),
        f64::MIN_POSITIVE,
        1e-310,
        -1e-310,
        1e-45,
        7e-46,
        -7e-46,
        1.5e-39,
        0.1,
        -0.1,
        1.0,
        3.4e38,
        1e300,
        -1e300,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for x in values {
        let down = round_down(x);
        let exact = |r: f32| f64::from(r) == x;
        assert!(
            f64::from(down) <= x && (exact(down) || f64::from(down.next_up()) > x),
            "round_down({x:e}) = {down:e}"
        );
        let up = round_up(x);
        assert!(
            f64::from(up) >= x && (exact(up) || f64::from(up.next_down()) < x),
            "round_up({x:e}) = {up:e}"
        );
    }
}

/// The sorting network puts the entered slots first, farthest entry first (entries within 3
/// ulps, which share a key, in slot order), and among equal entries the earlier slot first,
/// for every set of entered slots (entries drawn from a few values, so that ties, near-ties,
/// zeros of both signs, negatives and infinities all occur).
#[test]
fn farthest_first_sorts_the_entered_slots() {
    let values = [
        -2.5f32,
        -0.0,
        0.0,
        1e-30,
        1.0,
        1.0 + f32::EPSILON,
        1.5,
        3.0,
        f32::INFINITY,
    ];
    let close = |a: f32, b: f32| a == b || (a.signum() == b.signum() && a.to_bits().abs_diff(b.to_bits()) <= 3);
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    for _ in 0..2000 {
        let near: [f32; 4] = std::array::from_fn(|_| values[rng.random_range(0..values.len())]);
        for entered in 1u32..16 {
            let got = farthest_first(entered, near);
            let n = entered.count_ones() as usize;
            let mut slots = got[..n].to_vec();
            slots.sort_unstable();
            let want: Vec<usize> = (0..4).filter(|&s| entered & (1 << s) != 0).collect();
            assert_eq!(slots, want, "the entered slots first: {near:?} {entered:04b}");
            for pair in got[..n].windows(2) {
                let (a, b) = (near[pair[0]], near[pair[1]]);
                assert!(a > b || close(a, b), "farthest first: {near:?} {entered:04b} {got:?}");
                if a.to_bits() == b.to_bits() {
                    assert!(pair[0] < pair[1], "ties in slot order: {near:?} {entered:04b} {got:?}");
                }
            }
        }
    }
}

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

/// Packets of rays (coherent, scattered, partial, with limited ranges) get exactly the
/// single-ray walk's answers, exact ties of `t` settled by id in both (boxes sharing faces).
#[test]
fn packets_equal_single_rays() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(12);
    // a grid of unit boxes (shared faces give exact ties) plus random ones
    let mut boxes: Vec<Aabb> = Vec::new();
    for i in 0..6 {
        for j in 0..6 {
            let c = DVec3::new(f64::from(i) - 3.0, f64::from(j) - 3.0, 0.0);
            boxes.push(Aabb::new(c, c + DVec3::ONE));
        }
    }
    for _ in 0..3000 {
        let c = DVec3::new(
            rng.random_range(-10.0..10.0),
            rng.random_range(-10.0..10.0),
            rng.random_range(-10.0..10.0),
        );
        let h = DVec3::new(
            rng.random_range(0.01..0.5),
            rng.random_range(0.01..0.5),
            rng.random_range(0.01..0.5),
        );
        boxes.push(Aabb::new(c - h, c + h));
    }
    let items: Vec<(Aabb, u32)> = boxes.iter().enumerate().map(|(i, b)| (*b, i as u32)).collect();
    let bvh = Bvh::build(&items);
    let entry = |b: &Aabb, ray: &Ray, range: Interval| b.clip(ray, range).map(|r| r.min);
    // the closest box, exact ties going to the smaller id
    let settle = |best: Option<u32>, id: u32, t: f64, range: Interval| t < range.max || best.is_none_or(|b| id < b);
    for round in 0..3000 {
        let n = if round % 5 == 0 {
            rng.random_range(1..=PACKET)
        } else {
            PACKET
        };
        let eye = DVec3::new(rng.random_range(-12.0..12.0), rng.random_range(-12.0..12.0), -15.0);
        let spread = if round % 2 == 0 { 0.01 } else { 1.0 };
        let rays: Vec<Ray> = (0..n)
            .map(|_| {
                let d = DVec3::new(
                    rng.random_range(-spread..spread),
                    rng.random_range(-spread..spread),
                    1.0,
                );
                Ray::new(eye, d)
            })
            .collect();
        let ranges: Vec<Interval> = (0..n)
            .map(|_| {
                if rng.random_bool(0.2) {
                    Interval::new(10.0, 16.0)
                } else {
                    Interval::POSITIVE
                }
            })
            .collect();
        let single: Vec<Option<u32>> = (0..n)
            .map(|l| {
                let mut best = None;
                bvh.closest(&rays[l], ranges[l], |id, r| {
                    let t = entry(&boxes[id as usize], &rays[l], r)?;
                    settle(best, id, t, r).then(|| {
                        best = Some(id);
                        t
                    })
                })
            })
            .collect();
        let mut best = [None; PACKET];
        let packet = bvh.closest_packet(&rays, &ranges, |l, id, r| {
            let t = entry(&boxes[id as usize], &rays[l], r)?;
            settle(best[l], id, t, r).then(|| {
                best[l] = Some(id);
                t
            })
        });
        assert_eq!(&packet[..n], &single[..], "rays {rays:?}");
        assert!(packet[n..].iter().all(Option::is_none));
    }
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
