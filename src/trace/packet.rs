//! When rays walk together: the one coherence test of packets.
//!
//! A packet of rays is traced together ([`crate::scene::Scene::intersect_packet`], each lane
//! still getting exactly its single ray's answer) only where its directions lie within a small
//! angle of the first ray's: beyond, the rays part after a few nodes and each walks alone faster.
//! [`coherent`] is that test, for a cosine chosen by the caller. Two callers use it with two
//! thresholds, and they serve different purposes:
//!
//! - [`PACKET_COS`] (`cos` of about 3.6°) decides whether a packet walks the hierarchies
//!   together: the render's pixel blocks, every packet a sorted query hands over, and each run
//!   of consecutive rays a batch hands to a lone object
//!   ([`crate::scene::Scene::intersect_each`]: a camera's rays in pixel order);
//! - the query's sort ([`crate::query::order`]) uses a wider cosine (about 8°, twice the width
//!   of its direction cells) to judge whether sorting a batch into packets pays at all; a packet
//!   it passes is still walked together only if it passes [`PACKET_COS`].
//!
//! The threshold only chooses between two ways of computing the same answers, never the answers.

use zeroset_primitives::Ray;

/// Largest angle between a packet's directions for tracing it together: `cos` of about 3.6°.
/// Beyond, the rays part after a few nodes and each walks alone faster (random query rays,
/// even sorted; a camera's neighbouring pixels are a small fraction of a degree apart).
pub const PACKET_COS: f64 = 0.998;

/// Whether every ray of `rays` points within the angle whose cosine is `cosine` (in `(0, 1]`)
/// of the first ray's direction: `d·d₀ ≥ 0` and `(d·d₀)² ≥ cosine²·|d|²·|d₀|²`, no square root
/// (the plain scale of the directions keeps the squares finite). An empty slice is not
/// coherent; a single ray is.
#[inline]
pub fn coherent(rays: &[Ray], cosine: f64) -> bool {
    let Some(first) = rays.first() else { return false };
    let (d0, len0) = (first.dir, first.dir.length_squared());
    let c2 = cosine * cosine;
    rays[1..].iter().all(|r| {
        let dot = r.dir.dot(d0);
        dot >= 0.0 && dot * dot >= c2 * r.dir.length_squared() * len0
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn ray(dir: DVec3) -> Ray {
        Ray::new(DVec3::ZERO, dir)
    }

    #[test]
    fn rays_within_the_angle_are_coherent_and_wider_ones_are_not() {
        let first = ray(DVec3::Z);
        // 3° and 4° off the first ray, lengths differing (only the angle counts)
        let three = ray(5.0 * DVec3::new(3f64.to_radians().sin(), 0.0, 3f64.to_radians().cos()));
        let four = ray(0.5 * DVec3::new(0.0, 4f64.to_radians().sin(), 4f64.to_radians().cos()));
        assert!(coherent(&[first, three], PACKET_COS));
        assert!(!coherent(&[first, three, four], PACKET_COS));
        assert!(coherent(&[first, three, four], 0.99));
        assert!(!coherent(&[first, ray(-DVec3::Z)], 0.5));
        assert!(coherent(&[first], PACKET_COS));
        assert!(!coherent(&[], PACKET_COS));
    }
}
