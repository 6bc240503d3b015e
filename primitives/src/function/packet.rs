//! Packets of rays through an expression's octree ([`Function::intersect_packet`]): the rays
//! walk it together ([`crate::expr::cells::CellTree::walk_packet`]) and the ones a leaf proves monotone are refined
//! together, their points evaluated in one pass of the tape ([`Tape::eval_points`]). Each ray
//! gets exactly what [`Function::intersect`] gives it alone (see `docs/numerics.md`).

use super::{defined_or_outside, monotone_along, with_scratch, Compiled, Function, Phi, RayState, Scratch};
use crate::bounds::Aabb;
use crate::expr::cells::{Leaf, LANES};
use crate::expr::tape::Tape;
use crate::hit::RawHit;
use crate::isolation::{monotone_ends, Ends};
use crate::ray::{Interval, Ray};
use crate::root::{RootOptions, RootReport};
use glam::DVec3;

pub(super) fn intersect_packet(
    function: &Function,
    rays: &[Ray],
    ranges: &mut [Interval],
    hits: &mut [Option<RawHit>],
) {
    let Phi::Expression(compiled) = &function.phi else {
        return crate::traits::packet_lane_by_lane(function, rays, ranges, hits);
    };
    for ((rays, ranges), hits) in rays
        .chunks(LANES)
        .zip(ranges.chunks_mut(LANES))
        .zip(hits.chunks_mut(LANES))
    {
        let mut together = [Ray::new(DVec3::ZERO, DVec3::Z); LANES];
        let mut segments = [Interval::POSITIVE; LANES];
        let mut lane_of = [0usize; LANES];
        let mut n = 0;
        for (i, (ray, range)) in rays.iter().zip(ranges.iter_mut()).enumerate() {
            let Some(segment) = function.clipped(ray, *range) else {
                continue;
            };
            if compiled.walks(ray, segment) {
                (together[n], segments[n], lane_of[n]) = (*ray, segment, i);
                n += 1;
            } else if let Some(found) = crate::root::first_root(function, ray, *range, &function.options).hit {
                range.max = found.t;
                hits[i] = Some(found);
            }
        }
        let reports = compiled.first_roots(&together[..n], &segments[..n], &function.bounds, &function.options);
        for (report, &i) in reports.iter().zip(&lane_of[..n]) {
            if let Some(found) = report.as_ref().and_then(|r| r.hit) {
                ranges[i].max = found.t;
                hits[i] = Some(found);
            }
        }
    }
}

/// Points along the rays of a packet inside one leaf, evaluated together: those in the leaf's
/// grown cell with its pruned tape ([`Tape::eval_points`]), any other with the full tape, as
/// [`LeafAlong::point`] chooses (the same values).
struct PointBatch<'a> {
    leaf: &'a Leaf,
    full: &'a Tape,
    /// Slot `i` (`2·LANES` of them): the point asked for, if any.
    asked: [Option<DVec3>; 2 * LANES],
    values: [f64; 2 * LANES],
}

impl<'a> PointBatch<'a> {
    fn new(leaf: &'a Leaf, full: &'a Tape) -> Self {
        Self {
            leaf,
            full,
            asked: [None; 2 * LANES],
            values: [f64::NAN; 2 * LANES],
        }
    }

    fn clear(&mut self) {
        self.asked = [None; 2 * LANES];
    }

    /// Asks for `g(t)` along `ray` in slot `slot`.
    fn ask(&mut self, ray: &Ray, slot: usize, t: f64) {
        self.asked[slot] = Some(ray.at(t));
    }

    /// `g` at the asked points ([`defined_or_outside`] of Φ).
    fn evaluate(&mut self, scratch: &mut Scratch) {
        let (lo, hi) = self.leaf.grown();
        let mut inside = [[0.0; 3]; 2 * LANES];
        let mut slots = [0usize; 2 * LANES];
        let mut n = 0;
        for (slot, asked) in self.asked.iter().enumerate() {
            let Some(p) = *asked else { continue };
            if (p.cmpge(lo) & p.cmple(hi)).all() {
                (inside[n], slots[n]) = (p.to_array(), slot);
                n += 1;
            } else {
                self.values[slot] = defined_or_outside(self.full.eval_f64(p.to_array(), &mut scratch.points));
            }
        }
        let mut values = [0.0; 2 * LANES];
        self.leaf
            .tape()
            .eval_points(&inside[..n], &mut values[..n], &mut scratch.lanes);
        for (&slot, &v) in slots[..n].iter().zip(&values[..n]) {
            self.values[slot] = defined_or_outside(v);
        }
    }

    /// The value evaluated in `slot`, if a point was asked for there.
    fn value(&self, slot: usize) -> Option<f64> {
        self.asked[slot].map(|_| self.values[slot])
    }
}

impl Compiled {
    /// [`Compiled::first_root`] of up to [`LANES`] rays whose segments the octree serves
    /// ([`Compiled::walks`]), walked together ([`crate::expr::cells::CellTree::walk_packet`]: each ray visits the
    /// same leaves with the same pieces as alone, so the reports are the same).
    fn first_roots(
        &self,
        rays: &[Ray],
        segments: &[Interval],
        bounds: &Aabb,
        options: &RootOptions,
    ) -> [Option<RootReport>; LANES] {
        let n = rays.len();
        let mut origin = [DVec3::ZERO; LANES];
        let mut dir = [DVec3::ZERO; LANES];
        let (mut t0, mut t1) = ([0.0; LANES], [0.0; LANES]);
        for (lane, (ray, segment)) in rays.iter().zip(segments).enumerate() {
            (origin[lane], dir[lane]) = (ray.origin, ray.dir);
            (t0[lane], t1[lane]) = (segment.min, segment.max);
        }
        let mut states = [RayState::default(); LANES];
        with_scratch(|scratch| {
            self.cells().walk_packet(
                &origin[..n],
                &dir[..n],
                &t0[..n],
                &t1[..n],
                &mut |leaf, lanes, ta, tb| {
                    self.visit_leaf_lanes(rays, bounds, options, scratch, &mut states, leaf, lanes, (ta, tb))
                },
            );
        });
        std::array::from_fn(|lane| (lane < n).then(|| states[lane].report()))
    }

    /// [`Compiled::visit_leaf`] for the `lanes` of a packet crossing one leaf, each on its piece
    /// `[ta[i], tb[i]]`; returns the lanes whose search ends here. Lanes the leaf's gradient
    /// proves monotone are refined together: their end values, then each step of their
    /// refinements ([`crate::finder::Refinement`]), evaluated at once ([`Tape::eval_points`]): each lane takes
    /// the same points, counts and result as [`crate::isolation::monotone_root`] alone. Other lanes are isolated
    /// one by one.
    #[allow(clippy::too_many_arguments)]
    fn visit_leaf_lanes(
        &self,
        rays: &[Ray],
        bounds: &Aabb,
        options: &RootOptions,
        scratch: &mut Scratch,
        states: &mut [RayState; LANES],
        leaf: &Leaf,
        lanes: u32,
        (ta, tb): (&[f64; LANES], &[f64; LANES]),
    ) -> u32 {
        let mut ended = 0;
        let mut monotone = 0u32;
        for lane in (0..LANES).filter(|&lane| lanes & 1 << lane != 0) {
            if monotone_along(leaf.gradient(), rays[lane].dir) {
                monotone |= 1 << lane;
            } else if self.visit_leaf(
                &rays[lane],
                bounds,
                options,
                scratch,
                &mut states[lane],
                leaf,
                (ta[lane], tb[lane]),
                false,
            ) {
                ended |= 1 << lane;
            }
        }
        if monotone == 0 {
            return ended;
        }
        let mut points = PointBatch::new(leaf, &self.tape);
        let count = |state: &mut RayState| state.evaluations = state.evaluations.saturating_add(1);
        // the end values, as `monotone_root` asks for them: g(a), then g(b)
        let mut ends = [(0.0, 0.0); LANES];
        for lane in (0..LANES).filter(|&lane| monotone & 1 << lane != 0) {
            let state = &mut states[lane];
            count(state);
            if ta[lane] == state.last.0 {
                ends[lane].0 = state.last.1;
            } else {
                points.ask(&rays[lane], lane, ta[lane]);
            }
            count(state);
            points.ask(&rays[lane], LANES + lane, tb[lane]);
        }
        points.evaluate(scratch);
        let mut refinements = [None; LANES];
        for lane in (0..LANES).filter(|&lane| monotone & 1 << lane != 0) {
            if let Some(ga) = points.value(lane) {
                ends[lane].0 = ga;
            }
            let (ga, gb) = (ends[lane].0, points.value(LANES + lane).unwrap_or(f64::NAN));
            let state = &mut states[lane];
            state.last = (tb[lane], gb);
            let hit = match monotone_ends((ta[lane], ga), (tb[lane], gb), options.tolerance) {
                Ends::NoRoot => None,
                Ends::Root(t) => Some(t),
                Ends::Bracket(refinement) => {
                    refinements[lane] = Some(refinement);
                    continue;
                }
            };
            state.outcome.hit = hit.map(|t| (t, false));
            ended |= u32::from(hit.is_some()) << lane;
        }
        // the refinements, one step of each at a time
        loop {
            points.clear();
            let mut asked = false;
            for lane in 0..LANES {
                let Some(refinement) = &refinements[lane] else { continue };
                let state = &mut states[lane];
                match refinement.next_point() {
                    None => {
                        state.outcome.hit = Some((refinement.root(), false));
                        ended |= 1 << lane;
                        refinements[lane] = None;
                    }
                    Some(t) => {
                        count(state);
                        if t != state.last.0 {
                            points.ask(&rays[lane], lane, t);
                            asked = true;
                        }
                    }
                }
            }
            if refinements.iter().all(Option::is_none) {
                return ended;
            }
            if asked {
                points.evaluate(scratch);
            }
            for lane in 0..LANES {
                let Some(refinement) = &mut refinements[lane] else {
                    continue;
                };
                let t = refinement.next_point().unwrap_or(f64::NAN);
                let state = &mut states[lane];
                let g = match points.value(lane) {
                    Some(g) => {
                        state.last = (t, g);
                        g
                    }
                    None => state.last.1,
                };
                refinement.take(g);
            }
        }
    }
}
