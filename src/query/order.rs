//! The order a batch is traced in: as given, or sorted for coherence and traced in packets
//! where the sorted neighbours point alike ([`crate::trace::packet`]).

use super::batch::{completed, trace_many_for, trace_one, QueryHit, QueryRay, TraceWork, ANSWER, MISS};
use crate::scene::Scene;
use crate::trace::packet::coherent;
use glam::DVec3;
use rayon::prelude::*;
use zeroset_primitives::root::{thread_uncertain_events, traced_again};
use zeroset_primitives::{Interval, Ray, PACKET};

/// The order in which a batch's rays are traced. The answers are the same whatever the order;
/// only the speed differs. `Input` traces the rays as given (runs of [`PACKET`] consecutive rays
/// that point alike, such as a camera's rays in pixel order, walk a lone object as packets:
/// [`Scene::intersect_each`]); `Sorted` sorts the batch for coherence and traces it in packets
/// of [`PACKET`] neighbouring rays ([`Scene::intersect_packet`]). On every batch measured
/// `Input` is the faster: sorting costs more than it recovers (`docs/performance.md`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum RayOrder {
    /// As given.
    Input,
    /// Sorted for coherence ([`coherent_order`]) and traced in packets where the sorted
    /// neighbours point alike (within ~8°), so they walk the same nodes together; a batch with no
    /// such coherence to recover (random rays) is traced as given.
    Sorted,
}

/// First hits of `rays` in `scene`, traced in `order`, returned in input order.
#[must_use]
pub fn trace_batch_in(scene: &Scene, rays: &[QueryRay], order: RayOrder) -> Vec<QueryHit> {
    let sort = match order {
        RayOrder::Input => false,
        RayOrder::Sorted => rays.len() > 1,
    };
    // each ray on its own, handed to the scene 256 at a time
    let one_by_one = || {
        let mut answers = vec![MISS; rays.len()];
        answers.par_chunks_mut(256).zip(rays.par_chunks(256)).for_each_init(
            TraceWork::default,
            |work, (answers, rays)| {
                trace_many_for(scene, rays, ANSWER, work, answers);
            },
        );
        answers
    };
    if !sort || !sample_may_pay(rays) {
        return one_by_one();
    }
    let permutation = coherent_order(rays);
    if !packets_pay(rays, &permutation) {
        return one_by_one();
    }
    // one array per packet: an indexed collect, straight into place (a flattened one would
    // gather pieces and copy them together)
    let traced: Vec<[QueryHit; PACKET]> = permutation
        .par_chunks(PACKET)
        .with_min_len(32)
        .map(|packet| trace_packet(scene, rays, packet))
        .collect();
    // position in the traced order of each input ray
    let mut rank = vec![0u32; rays.len()];
    for (k, &i) in permutation.iter().enumerate() {
        rank[i as usize] = k as u32;
    }
    rank.par_iter()
        .map(|&k| traced[k as usize / PACKET][k as usize % PACKET])
        .collect()
}

/// Rays whose directions are all within this cosine of the first ray's (about 8°: twice the
/// width of [`coherent_order`]'s direction cells; [`coherent`]) are handed over as a packet
/// (which [`Scene::intersect_packet`] then walks together only within
/// [`crate::trace::packet::PACKET_COS`]); a packet of rays spread
/// wider (random rays, sorted: neighbours in the order start near each other but point anywhere in
/// their octant) would walk the hierarchy lane by lane anyway, paying the packet's bookkeeping on
/// top, so its rays are traced one by one.
const PACKET_COSINE: f64 = 0.99;

/// Whether tracing `rays` in packets of [`PACKET`] along `permutation` pays: at least a quarter
/// of up to 256 packets spread evenly over it are [`coherent`]. Where they are not (random rays:
/// sorted neighbours start near each other but point anywhere in their octant), the packets would
/// be traced ray by ray anyway, and putting the answers back into input order would cost more than
/// the order saves, so the batch is traced as given.
pub(super) fn packets_pay(rays: &[QueryRay], permutation: &[u32]) -> bool {
    let packets = permutation.len() / PACKET;
    if packets == 0 {
        return false;
    }
    let sampled = packets.min(256);
    let coherent_count = (0..sampled)
        .filter(|&s| {
            let first = s * packets / sampled * PACKET;
            let lanes: [Ray; PACKET] = std::array::from_fn(|l| rays[permutation[first + l] as usize].ray);
            coherent(&lanes, PACKET_COSINE)
        })
        .count();
    4 * coherent_count >= sampled
}

/// Rays in the sample [`sample_may_pay`] sorts (about one in `len / COHERENCE_SAMPLE`).
const COHERENCE_SAMPLE: usize = 4096;

/// Whether sorting a batch may pay, judged on an evenly spread sample of it before the batch
/// itself is sorted: a batch of at least four samples' size whose sorted sample has no coherent
/// packets ([`packets_pay`]) has none to recover (random rays: sorted neighbours point anywhere),
/// so its sort (as long as tracing it, on a small mesh) is skipped. The sample is sparser than
/// the batch, so it finds fewer coherent neighbours than the batch would: a batch it turns down
/// is traced as given (the same answers); one it passes is sorted and judged again in full.
pub(super) fn sample_may_pay(rays: &[QueryRay]) -> bool {
    if rays.len() < 4 * COHERENCE_SAMPLE {
        return true;
    }
    let sample: Vec<QueryRay> = rays.iter().step_by(rays.len() / COHERENCE_SAMPLE).copied().collect();
    packets_pay(&sample, &coherent_order(&sample))
}

/// The first hits of `rays[i]` for the (at most [`PACKET`]) indices `packet`, in `packet`'s
/// order (the lanes past `packet.len()` are misses): traced together
/// ([`Scene::intersect_packet`]) where they point alike ([`coherent`]), else one by one
/// ([`trace_one`]). If a root finder ran out of budget while a packet was traced, its rays are
/// traced again one by one to tell which (counted once: [`traced_again`]).
fn trace_packet(scene: &Scene, rays: &[QueryRay], packet: &[u32]) -> [QueryHit; PACKET] {
    let n = packet.len().min(PACKET);
    let mut lanes = [Ray::new(DVec3::ZERO, DVec3::Z); PACKET];
    let mut ranges = [Interval::POSITIVE; PACKET];
    for (l, &i) in packet[..n].iter().enumerate() {
        lanes[l] = rays[i as usize].ray;
        ranges[l] = rays[i as usize].range;
    }
    let mut out = [QueryHit {
        hit: None,
        uncertain: false,
    }; PACKET];
    let exhausted_before = thread_uncertain_events();
    let mut found = [None; PACKET];
    // together where the rays point alike and no root finder ran out of budget meanwhile
    let packed = coherent(&lanes[..n], PACKET_COSINE);
    let together = packed && {
        scene.intersect_packet(&lanes[..n], &ranges[..n], &mut found[..n]);
        thread_uncertain_events() == exhausted_before
    };
    if together {
        for l in 0..n {
            out[l].hit = found[l].map(|hit| completed(scene, &lanes[l], hit, ANSWER));
        }
    } else {
        for (l, &i) in packet[..n].iter().enumerate() {
            let one = || trace_one(scene, &rays[i as usize]);
            // a packet traced together, then again, counts its rays' outcomes once
            out[l] = if packed { traced_again(one) } else { one() };
        }
    }
    out
}

/// A permutation of `rays` that puts coherent rays together: sorted by direction octant, then
/// by the Morton code of the origin (10 bits per axis over the batch's origin bounds), then by
/// the direction quantised to 5 bits per component. Ties keep the input order.
#[must_use]
pub fn coherent_order(rays: &[QueryRay]) -> Vec<u32> {
    let (lo, hi) = rays.par_iter().map(|q| (q.ray.origin, q.ray.origin)).reduce(
        || (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |a, b| (a.0.min(b.0), a.1.max(b.1)),
    );
    let extent = hi - lo;
    let scale = DVec3::select(extent.cmpgt(DVec3::ZERO), 1023.0 / extent, DVec3::ZERO);
    let spread = |v: u64| -> u64 {
        // the 10 low bits of `v` moved to every third bit
        let mut x = v & 0x3ff;
        x = (x | (x << 16)) & 0x0300_00ff;
        x = (x | (x << 8)) & 0x0300_f00f;
        x = (x | (x << 4)) & 0x030c_30c3;
        (x | (x << 2)) & 0x0924_9249
    };
    let mut keyed: Vec<(u64, u32)> = rays
        .par_iter()
        .enumerate()
        .map(|(i, q)| {
            let d = q.ray.dir;
            let octant = u64::from(d.x < 0.0) | u64::from(d.y < 0.0) << 1 | u64::from(d.z < 0.0) << 2;
            let cell = ((q.ray.origin - lo) * scale).clamp(DVec3::ZERO, DVec3::splat(1023.0));
            let morton = spread(cell.x as u64) | spread(cell.y as u64) << 1 | spread(cell.z as u64) << 2;
            let unit = d / d.abs().max_element();
            let quantised = ((unit + 1.0) * 15.5).clamp(DVec3::ZERO, DVec3::splat(31.0));
            let direction = (quantised.x as u64) << 10 | (quantised.y as u64) << 5 | quantised.z as u64;
            (octant << 45 | morton << 15 | direction, i as u32)
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}
