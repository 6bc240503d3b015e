//! Packets of rays through an expression's octree ([`Intersect::intersect_packet`] of
//! [`Function`]: a shared walk and refinements evaluated together) give each ray exactly what
//! it gets alone ([`Intersect::intersect`]): the same hits, bit for bit, the same features and
//! the same narrowed ranges, on smooth, kinked, thin and partly undefined surfaces, for
//! orthographic and perspective packets, narrow packets on the octree's mid-planes, packets whose directions disagree in sign, rays along
//! the axes, from inside the box and with short ranges.

use glam::DVec3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use zeroset_primitives::testing::random_unit;
use zeroset_primitives::*;

const SHAPES: [&str; 6] = [
    "sqrt(x^2 + y^2 + z^2) - 1",
    "(x^4 - 5*x^2 + y^4 - 5*y^2 + z^4 - 5*z^2 + 11.8) / 8",
    "max(abs(sqrt(x^2 + y^2 + z^2) - 0.9) - 0.02, 0.35 - abs(sin(6*x)*cos(6*y) + sin(6*y)*cos(6*z)))",
    "min(min(sqrt((x-0.5)^2 + y^2 + z^2) - 0.45, sqrt((x+0.5)^2 + y^2 + z^2) - 0.45), sqrt(x^2 + (y-0.6)^2 + z^2) - 0.3)",
    "abs(sqrt(x^2 + y^2 + z^2) - 1) - 0.0005",
    "x^2 + y^2 - 0.3*z^2 - 0.1",
];

fn function(text: &str) -> Function {
    let bounds = Aabb::new(DVec3::splat(-1.5), DVec3::splat(1.5));
    Function::from_expr(expr::Expr::parse(text).unwrap(), bounds, RootOptions::default()).unwrap()
}

/// Packets of eight rays, each built by `aim(lane)`, with their ranges.
fn packets(
    seed: u64,
    count: usize,
    mut aim: impl FnMut(&mut StdRng, usize, usize) -> (Ray, Interval),
) -> Vec<Vec<(Ray, Interval)>> {
    let mut rng = StdRng::seed_from_u64(seed);
    (0..count)
        .map(|packet| (0..PACKET).map(|lane| aim(&mut rng, packet, lane)).collect())
        .collect()
}

fn key(hit: &Option<RawHit>) -> Option<(u64, u32)> {
    hit.map(|h| (h.t.to_bits(), h.feature))
}

/// Every packet against its rays one by one (on a second copy of the surface, so that neither
/// path finds the octree cells the other made).
fn check(name: &str, text: &str, packets: &[Vec<(Ray, Interval)>]) -> usize {
    let (alone, together) = (function(text), function(text));
    let mut hits = 0;
    for packet in packets {
        let rays: Vec<Ray> = packet.iter().map(|(r, _)| *r).collect();
        let mut ranges: Vec<Interval> = packet.iter().map(|(_, i)| *i).collect();
        let mut found = vec![None; rays.len()];
        together.intersect_packet(&rays, &mut ranges, &mut found);
        for (lane, (ray, range)) in packet.iter().enumerate() {
            let expected = alone.intersect(ray, *range);
            assert_eq!(
                key(&found[lane]),
                key(&expected),
                "{name}, {text}: lane {lane} of {packet:?}"
            );
            let narrowed = expected.map_or(range.max, |h| h.t);
            assert_eq!(
                ranges[lane].max.to_bits(),
                narrowed.to_bits(),
                "{name}, {text}: range of lane {lane}"
            );
            hits += usize::from(expected.is_some());
        }
    }
    hits
}

#[test]
fn packets_hit_what_their_rays_hit_alone() {
    for text in SHAPES {
        // an orthographic camera looking down -z: 4 x 2 pixel packets, directions with zeros
        let ortho = packets(1, 3000, |rng, _, lane| {
            let (x, y) = (rng.random_range(-1.5..1.5), rng.random_range(-1.5..1.5));
            let step = 3.0 / 256.0;
            let origin = DVec3::new(x + step * (lane % 4) as f64, y + step * (lane / 4) as f64, 3.0);
            (Ray::new(origin, DVec3::NEG_Z), Interval::POSITIVE)
        });
        // a pinhole camera: neighbouring directions from one eye
        let eye = DVec3::new(0.7, 0.4, 3.5);
        let pinhole = packets(2, 3000, |rng, _, lane| {
            let target = DVec3::new(rng.random_range(-1.2..1.2), rng.random_range(-1.2..1.2), 0.0);
            let offset = DVec3::new(0.004 * (lane % 4) as f64, 0.004 * (lane / 4) as f64, 0.0);
            (Ray::new(eye, target + offset - eye), Interval::POSITIVE)
        });
        // unrelated rays: random origins in and around the box, random directions (signs
        // disagree within a packet), short and long ranges
        let random = packets(3, 3000, |rng, _, _| {
            let origin = DVec3::new(
                rng.random_range(-2.5..2.5),
                rng.random_range(-2.5..2.5),
                rng.random_range(-2.5..2.5),
            );
            let range = if rng.random_bool(0.3) {
                Interval::new(rng.random_range(0.0..0.5), rng.random_range(0.5..2.0))
            } else {
                Interval::POSITIVE
            };
            (Ray::new(origin, random_unit(rng) * rng.random_range(0.5..2.0)), range)
        });
        // axis-aligned rays of one octant, some starting on the octree's mid-planes
        let axes = packets(4, 1500, |rng, _, lane| {
            let axis = [DVec3::X, DVec3::Y, DVec3::Z][lane % 3];
            let on_plane = |rng: &mut StdRng| {
                if rng.random_bool(0.3) {
                    0.0
                } else {
                    rng.random_range(-1.4..1.4)
                }
            };
            let origin = DVec3::new(on_plane(rng), on_plane(rng), on_plane(rng)) - 2.0 * axis;
            (Ray::new(origin, axis), Interval::POSITIVE)
        });
        // narrow packets on the octree's mid-planes (the box [-1.5, 1.5] halved up to 9 times):
        // lanes exactly on a plane, lanes a pixel off it, and the packet's first lane (the
        // beam's central ray) moving on no axis but z while the others lean away from it
        let planes = packets(5, 3000, |_, packet, lane| {
            // the same planes for every lane of a packet
            let rng = &mut StdRng::seed_from_u64(packet as u64);
            let plane = |rng: &mut StdRng| {
                let depth = rng.random_range(1..=9);
                let cells = 1u32 << depth;
                -1.5 + 3.0 * f64::from(rng.random_range(1..cells)) / f64::from(cells)
            };
            let (x, y) = (plane(rng), plane(rng));
            let step = 3.0 / 1024.0;
            let (dx, dy) = ((lane % 4) as f64 * step, (lane / 4) as f64 * step);
            if packet % 2 == 0 {
                let origin = DVec3::new(x + dx, y + dy, 3.0);
                (Ray::new(origin, DVec3::NEG_Z), Interval::POSITIVE)
            } else {
                let eye = DVec3::new(x, y, 2.5);
                (Ray::new(eye, DVec3::new(0.3 * dx, 0.3 * dy, -1.0)), Interval::POSITIVE)
            }
        });
        let mut total = 0;
        for (name, batch) in [
            ("orthographic", &ortho),
            ("pinhole", &pinhole),
            ("random", &random),
            ("axes", &axes),
            ("mid-planes", &planes),
        ] {
            total += check(name, text, batch);
        }
        assert!(total > 1000, "{text}: only {total} hits, the packets test too little");
    }
}
