//! Which pieces of a scene each pixel can see, worked out before any ray is traced: the
//! render hands a pixel's ray only its pieces (a lone mesh's leaves through
//! [`Pieces::intersect_pieces`], or the objects of a scene of several) instead of walking a
//! hierarchy, and a pixel with none sees nothing.
//!
//! For a pinhole camera and a scene of one static object that has [`Pieces`] (a mesh: its
//! hierarchy's leaves, a few triangles each), every piece's box is projected
//! ([`crate::render::cull::footprint::BoxProjector`]: the box enlarged by `10⁻⁴` of its size and
//! distance and a hundred times the origin's rounding, a hundred times or more the margin the
//! trait asks for, the rectangle widened by [`TIGHT_WIDENING`]). A pixel whose centre lies
//! outside a piece's rectangle has an exact ray that passes the box by more than that margin,
//! so the pieces whose rectangles hold the centre are all the trait needs: the answer is
//! [`Scene::intersect`]'s, bit for bit.
//!
//! A scene of several objects has its objects as pieces, each object's world box projected the
//! same way ([`crate::render::cull::footprint::BoxProjector::footprint_clipped`]: a box reaching behind
//! the eye plane, a ground polygon, is cut there first), or, for an object that knows a ball
//! around it in front of the eye (a sphere, [`zeroset_primitives::Intersect::bounding_ball`]),
//! that ball's exact image rectangle
//! ([`crate::render::cull::footprint::BoxProjector::ball_footprint`], about half a sphere's box's).
//! A lone mesh's leaves are projected four at a time
//! ([`crate::render::cull::footprint::BoxProjector::pinhole_footprints`]); for a crop of the image (a
//! Dask tile, a band of the Python render) only those under the hierarchy's nodes whose grown
//! footprints reach the crop ([`Pieces::piece_numbers_kept`], [`wanted_in`]): the same bins,
//! the others' footprints holding none of its pixels. The level-8 bench mesh at 3840×2160 in
//! one process, one thread: 40 tiles of 512×512 0.944 → 0.608 s, 16 of 540×960 0.799 → 0.620
//! s, the whole frame (bands of a million pixels) 0.731 → 0.636 s. A pixel tests the
//! unbounded objects, those without a footprint and its candidates, nearest box first, until
//! the next box lies beyond the closest hit ([`Scene::intersect_candidates`]): again
//! [`Scene::intersect`]'s answer, the scene's hierarchy not walked.
//!
//! Layout. Per bucket of 16 image rows, the pieces seen on any of its rows, nearest box first
//! ([`PieceBins::new`], made once per view, in parallel over the pieces and the buckets; a
//! piece is listed once per bucket it reaches, most reach one); per pixel of a row, the pieces
//! covering it in the same order ([`RowBins`], made when the row is rendered). Nearer pieces
//! first let the test dismiss the farther ones by their boxes once a hit is found. Memory is a
//! few tens of bytes per piece: on a machine where first touching a page costs microseconds,
//! per-row lists of a million-triangle mesh's pieces would take longer to write than to use.

use glam::DVec3;
use rayon::prelude::*;
use zeroset_primitives::{Aabb, Interval, Pieces, RawHit, Ray, Wanted};

use crate::camera::{Camera, Model};
use crate::render::cull::footprint::{BoxProjector, ImageRect, TIGHT_WIDENING};
use crate::render::Window;
use crate::scene::Scene;

/// Rows per bucket of [`PieceBins`].
const BUCKET_ROWS: u32 = 16;

/// The fewest window pixels per piece for which bins are made. Callgrind, the level-8 bench
/// mesh (182,000 leaves) at 1280 × 720: listing the leaves costs about 970 instructions a leaf,
/// and saves about 825 a traced pixel (46 % of the frame's pixels are under a leaf): the
/// listing pays for itself from about one traced pixel per leaf, two window pixels.
const PIXELS_PER_PIECE: u64 = 2;

/// A piece seen in the window: its number, a lower bound on the distance from the eye to any
/// hit on it, and the pixels (columns and rows, inclusive) whose centres its footprint holds.
#[derive(Clone, Copy, Debug)]
struct Seen {
    number: u32,
    /// The distance from the eye to the piece's box (or ball, see the module docs) less the
    /// box's enlargement ([`BoxProjector::enlargement`], at least the margin [`Pieces`] asks
    /// for), rounded down to f32: the pieces are listed by it, nearest first, and a pixel's test
    /// ends at the first piece beyond its closest hit so far.
    near: f32,
    columns: [u32; 2],
    rows: [u32; 2],
}

/// What the pieces of [`PieceBins`] are.
enum Source<'a> {
    /// The pieces of the scene's lone object.
    Lone { object: u32, pieces: &'a dyn Pieces },
    /// The scene's bounded objects, piece `i` being object `i` (its world box); every pixel
    /// also tests the unbounded objects and `always`, the bounded ones with no footprint (a box
    /// reaching behind the eye plane).
    Objects { always: Vec<u32> },
}

/// The pieces each row of a view's window can see (module docs).
pub(crate) struct PieceBins<'a> {
    source: Source<'a>,
    /// Whether a pixel with no pieces is traced all the same: some object is tested by every
    /// pixel (one unbounded, or with no footprint).
    every_pixel: bool,
    /// First row of the window.
    y0: u32,
    seen: Vec<Seen>,
    /// Under bucket `b` (the window's rows `y0 + 16·b ..`, sixteen of them): the pieces seen on
    /// any of its rows, nearest first: the distance's bits above, the index into `seen` below
    /// (ties go by the pieces' order, whatever the threads do).
    buckets: RangeLists<u64>,
}

impl<'a> PieceBins<'a> {
    /// The bins of `window` of `camera`'s view of `scene`, seen through a pinhole with nothing
    /// moving: the pieces of a lone object that has them, every one wholly in front of the eye
    /// ([`Source::Lone`]), or the objects of a scene of several ([`objects_as_pieces`]); else
    /// `None`.
    pub(crate) fn new(scene: &'a Scene, camera: &Camera, window: &Window) -> Option<Self> {
        if !matches!(camera.model, Model::Perspective(_)) || scene.has_motion() || window.height() == 0 {
            return None;
        }
        let pixels = u64::from(window.width()) * u64::from(window.height());
        // a window of fewer pixels than twice the pieces (a small crop of a dense mesh) would
        // spend more on the footprints than the walks they save
        let worth = |pieces: usize| (pieces as u64).saturating_mul(PIXELS_PER_PIECE) <= pixels;
        let (source, numbers, projector) = match scene.lone_object() {
            Some(object) => {
                let primitive = &*scene.objects[object as usize].primitive;
                let pieces = primitive.pieces()?;
                let projector = camera.box_projector(primitive.origin_rounding(camera.eye));
                let whole = window.x0 == 0 && window.y0 == 0 && window.x1 == camera.width && window.y1 == camera.height;
                // a crop (a Dask tile) projects only the pieces under the hierarchy's nodes it
                // may see; the whole image sees all of them, and an object reaching behind the
                // eye most likely has pieces there, which have no footprint and leave it without
                // bins: not worth asking about its nodes (a crop of the level-8 mesh seen from
                // inside its box took 0.0201 s before the nodes were asked about, 0.0218 s with)
                let numbers = if whole || projector.footprint(&primitive.bounds(), TIGHT_WIDENING).is_none() {
                    pieces.piece_numbers()
                } else {
                    pieces.piece_numbers_kept(&|bounds: &Aabb| wanted_in(&projector, bounds, window))
                };
                if !worth(numbers.len()) {
                    return None;
                }
                (Source::Lone { object, pieces }, numbers, projector)
            }
            None => {
                let numbers = objects_as_pieces(scene)?;
                if !worth(numbers.len()) {
                    return None;
                }
                let projector = camera.box_projector(scene.origin_rounding(camera.eye));
                (Source::Objects { always: Vec::new() }, numbers, projector)
            }
        };
        // every piece's footprint (a lone object's piece without one: no bins; an object
        // without one, even cut at the eye plane: tested by every pixel), kept where it holds
        // a pixel; in runs of pieces, each run's pieces in order into vectors of its own (no
        // lock, no per-piece item through rayon's collect), joined in the pieces' order
        let runs: Vec<(Vec<Seen>, Vec<u32>)> = numbers
            .par_chunks(FOOTPRINT_RUN)
            .map(|run| {
                let mut found = (Vec::with_capacity(run.len()), Vec::new());
                zeroset_primitives::with_fma!(footprints(
                    run: &[u32] = run,
                    scene: &Scene = scene,
                    source: &Source<'_> = &source,
                    projector: &BoxProjector<'_> = &projector,
                    window: &Window = window,
                    found: &mut (Vec<Seen>, Vec<u32>) = &mut found,
                ) -> ());
                found
            })
            .collect();
        let mut seen = Vec::with_capacity(runs.iter().map(|r| r.0.len()).sum());
        let mut no_footprint = Vec::new();
        for (run_seen, run_without) in runs {
            seen.extend(run_seen);
            no_footprint.extend(run_without);
        }
        let source = match source {
            Source::Lone { .. } if !no_footprint.is_empty() => return None,
            Source::Objects { .. } => {
                no_footprint.sort_unstable();
                Source::Objects { always: no_footprint }
            }
            lone => lone,
        };
        let bucket = |row: u32| ((row - window.y0) / BUCKET_ROWS) as usize;
        let mut buckets = RangeLists::default();
        buckets.fill(bucket(window.y1 - 1) + 1, || {
            // the distance's bits (≥ 0: they order like the values), then the index
            seen.iter().enumerate().map(|(i, piece)| {
                let key = (u64::from(piece.near.to_bits()) << 32) | i as u64;
                (key, bucket(piece.rows[0]), bucket(piece.rows[1]))
            })
        });
        // each bucket nearest first
        buckets
            .lists_mut()
            .into_par_iter()
            .for_each(|list| list.sort_unstable());
        let every_pixel = match &source {
            Source::Lone { .. } => false,
            Source::Objects { always, .. } => !always.is_empty() || scene.has_unbounded_objects(),
        };
        Some(Self {
            source,
            every_pixel,
            y0: window.y0,
            seen,
            buckets,
        })
    }

    /// Whether a pixel with no pieces is traced all the same (see the field).
    pub(crate) fn tests_every_pixel(&self) -> bool {
        self.every_pixel
    }

    /// The pieces of the rows `y0..y0 + rows`, columns `x0..x0 + columns`, into `band`: each
    /// bucket reaching them is read once.
    pub(crate) fn band(&self, y0: u32, rows: usize, x0: u32, columns: usize, band: &mut BandBins) {
        band.rows.resize_with(rows, Vec::new);
        band.rows.iter_mut().for_each(Vec::clear);
        if columns == 0 || rows == 0 {
            return;
        }
        let (end, y1) = (x0 + columns as u32 - 1, y0 + rows as u32 - 1);
        let bucket = |y: u32| (y.saturating_sub(self.y0) / BUCKET_ROWS) as usize;
        let last_bucket = bucket(y1).min(self.buckets.slots() - 1);
        for b in bucket(y0)..=last_bucket {
            // the rows of this band in bucket `b`: a piece reaching several buckets is taken
            // from each for its rows there only
            let (lo, hi) = (
                y0.max(self.y0 + b as u32 * BUCKET_ROWS),
                y1.min(self.y0 + (b as u32 + 1) * BUCKET_ROWS - 1),
            );
            for &key in self.buckets.get(b) {
                let piece = &self.seen[key as u32 as usize];
                let (first, last) = (piece.columns[0].max(x0), piece.columns[1].min(end));
                let (top, bottom) = (piece.rows[0].max(lo), piece.rows[1].min(hi));
                if first > last {
                    continue;
                }
                for y in top..=bottom {
                    band.rows[(y - y0) as usize].push((
                        (piece.number, piece.near),
                        (first - x0) as usize,
                        (last - x0) as usize,
                    ));
                }
            }
        }
    }

    /// [`Scene::intersect`]`(ray, range)` for the ray of a pixel whose pieces are `candidates`
    /// (nearest first, each with its [`Seen::near`]).
    #[inline]
    pub(crate) fn intersect(
        &self,
        scene: &Scene,
        ray: &Ray,
        range: Interval,
        candidates: &[Listed],
    ) -> Option<(u32, RawHit)> {
        match &self.source {
            Source::Lone { object, pieces } => scene
                .intersect_lone_pieces::<false>(*object, *pieces, ray, range, candidates)
                .map(|(object, raw, _)| (object, raw)),
            Source::Objects { always } => scene.intersect_candidates(ray, range, always, candidates),
        }
    }

    /// The lone object and its pieces, where the bins list a lone object's pieces: the caller
    /// may then ask them for the hit's normal with the hit ([`Scene::intersect_lone_pieces`]).
    pub(crate) fn lone(&self) -> Option<(u32, &'a dyn Pieces)> {
        match self.source {
            Source::Lone { object, pieces } => Some((object, pieces)),
            Source::Objects { .. } => None,
        }
    }
}

/// Pieces a task of [`PieceBins::new`] projects ([`footprints`]).
const FOOTPRINT_RUN: usize = 1024;

/// The footprints of the pieces `numbers` of `source` through `projector` (module docs): into
/// `found.0` each piece whose footprint holds a pixel centre of `window`, with its rows, columns
/// and distance, in the order of `numbers`; into `found.1` each piece without a footprint. A
/// lone object's pieces are projected four at a time
/// ([`BoxProjector::pinhole_footprints`]).
#[inline(always)]
fn footprints(
    numbers: &[u32],
    scene: &Scene,
    source: &Source<'_>,
    projector: &BoxProjector<'_>,
    window: &Window,
    found: &mut (Vec<Seen>, Vec<u32>),
) {
    match source {
        Source::Lone { pieces, .. } => {
            let mut boxes = vec![Aabb::EMPTY; numbers.len()];
            pieces.piece_boxes(numbers, &mut boxes);
            for (group, boxes) in numbers.chunks(4).zip(boxes.chunks(4)) {
                let mut four = [Aabb::EMPTY; 4];
                four[..boxes.len()].copy_from_slice(boxes);
                let rects = projector.pinhole_footprints(&four, TIGHT_WIDENING);
                for (l, &number) in group.iter().enumerate() {
                    match rects[l] {
                        _ if four[l].is_empty() => {}
                        Some((rect, near)) => found.0.extend(seen(number, &rect, near, window)),
                        None => found.1.push(number),
                    }
                }
            }
        }
        Source::Objects { .. } => {
            let eye = projector.eye();
            for &number in numbers {
                let primitive = &*scene.objects[number as usize].primitive;
                let bounds = primitive.bounds();
                // a ball tighter than the box, where the object has one and it is in front
                let ball = primitive
                    .bounding_ball()
                    .and_then(|(centre, radius)| projector.ball_footprint(centre, radius, &bounds, TIGHT_WIDENING));
                if let Some((rect, near)) = ball {
                    found.0.extend(seen(number, &rect, near, window));
                    continue;
                }
                match projector.footprint_clipped(&bounds, TIGHT_WIDENING) {
                    Some(rect) => {
                        let distance = (eye.clamp(bounds.min, bounds.max) - eye).length();
                        let near = distance - projector.enlargement(&bounds);
                        found.0.extend(seen(number, &rect, near, window));
                    }
                    None => found.1.push(number),
                }
            }
        }
    }
}

/// Which of the pieces lying in `bounds` may hold in their footprints ([`footprints`]) a pixel
/// centre of `window`: [`Wanted::Nothing`] only where none can, [`Wanted::Everything`] where the
/// box's rectangle lies inside the window's (no use asking about its inner boxes).
///
/// The box is grown by a hundredth of its diagonal on every side and its rectangle widened by a
/// pixel more than a piece's. That covers every box `b` inside it as [`footprints`] enlarges `b`:
/// `b`'s half edges `h_b` and centre `c_b` stay within the box's (`|c_b − c| + h_b ≤ h` on each
/// axis), so `b`'s enlargement `10⁻⁴·(2|h_b| + |c_b − eye|) + r` exceeds the box's
/// `10⁻⁴·(2|h| + |c − eye|) + r` by at most `10⁻⁴·|h|`, two hundred times less than the growth;
/// a pinhole images the enlarged `b`, being inside the grown box and that wholly in front of the
/// eye, inside the grown box's rectangle. A box reaching behind the eye (no footprint) is
/// [`Wanted::Partly`].
fn wanted_in(projector: &BoxProjector<'_>, bounds: &Aabb, window: &Window) -> Wanted {
    let grow = DVec3::splat(0.01 * bounds.diagonal_length());
    let Some(rect) = projector.footprint(&Aabb::new(bounds.min - grow, bounds.max + grow), TIGHT_WIDENING + 1.0) else {
        return Wanted::Partly;
    };
    let inside = rect.x0 >= f64::from(window.x0)
        && rect.x1 <= f64::from(window.x1)
        && rect.y0 >= f64::from(window.y0)
        && rect.y1 <= f64::from(window.y1);
    if inside {
        Wanted::Everything
    } else if seen(0, &rect, 0.0, window).is_some() {
        Wanted::Partly
    } else {
        Wanted::Nothing
    }
}

/// Piece `number` as the bins list it, if its footprint `rect` holds a pixel centre of
/// `window`: the pixels it holds, and `near`, the distance from the eye to its box or ball less
/// the enlargement, rounded down to f32 (0 if negative).
#[inline(always)]
fn seen(number: u32, rect: &ImageRect, near: f64, window: &Window) -> Option<Seen> {
    // the pixels whose centres `k + 0.5` lie in the rectangle, within the window
    let first = |lo: f64, start: u32| (lo - 0.5).ceil().max(f64::from(start));
    let last = |hi: f64, end: u32| (hi - 0.5).floor().min(f64::from(end) - 1.0);
    let (c0, c1) = (first(rect.x0, window.x0), last(rect.x1, window.x1));
    let (r0, r1) = (first(rect.y0, window.y0), last(rect.y1, window.y1));
    if !(c0 <= c1 && r0 <= r1) {
        return None;
    }
    Some(Seen {
        number,
        near: f32_below(near.max(0.0)),
        columns: [c0 as u32, c1 as u32],
        rows: [r0 as u32, r1 as u32],
    })
}

/// The objects of `scene` as the pieces of [`PieceBins`] (their indices; the unbounded ones are
/// tested by every pixel anyway), where the scene has a hierarchy over several objects. A mesh
/// among them is tested by each pixel's ray alone, which is faster than its packets (alternating
/// runs, a bench mesh on a ground polygon beside a sphere: level 4 0.074 -> 0.066 s, level 6
/// 0.083 -> 0.077, level 8 0.111 -> 0.108).
fn objects_as_pieces(scene: &Scene) -> Option<Vec<u32>> {
    let numbers: Vec<u32> = (0..scene.objects.len() as u32)
        .filter(|&i| scene.objects[i as usize].primitive.bounds().is_finite())
        .collect();
    (numbers.len() >= 2).then_some(numbers)
}

/// The largest f32 at most `x` (finite, ≥ 0).
fn f32_below(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) > x {
        y.next_down()
    } else {
        y
    }
}

/// The pieces of each row of a band, nearest first, with the columns they cover (relative to
/// the band's first column) ([`PieceBins::band`]).
#[derive(Default)]
pub(crate) struct BandBins {
    rows: Vec<Vec<(Listed, usize, usize)>>,
}

/// A piece as a pixel's list holds it: its number and its [`Seen::near`].
pub(crate) type Listed = (u32, f32);

impl BandBins {
    /// The pieces of each pixel of the band's row `r` (of `columns` pixels), into `bins`; the
    /// columns from the first to the last that has any (empty if none).
    pub(crate) fn row(&self, r: usize, columns: usize, bins: &mut RowBins) -> std::ops::Range<usize> {
        bins.fill(columns, || self.rows[r].iter().copied());
        let first = self.rows[r].iter().map(|&(_, first, _)| first).min();
        let last = self.rows[r].iter().map(|&(_, _, last)| last).max();
        first.zip(last).map_or(0..0, |(first, last)| first..last + 1)
    }
}

/// The pieces of each pixel of one row, nearest first ([`BandBins::row`]), listed under the
/// row's columns, each with its [`Seen::near`].
pub(crate) type RowBins = RangeLists<Listed>;

/// Values listed under numbered slots: `values[starts[s]..starts[s + 1]]` are those under slot
/// `s`, in the order they were given.
#[derive(Default)]
pub(crate) struct RangeLists<T> {
    starts: Vec<usize>,
    values: Vec<T>,
    /// Where each slot's next value goes while the lists are filled.
    next: Vec<usize>,
}

impl<T: Copy + Default> RangeLists<T> {
    /// Lists each `(value, first, last)` of `items()` under the slots `first..=last` of `slots`
    /// (all below `slots`), replacing what was listed: the items are walked twice, counted,
    /// then placed. The counting pass marks only each item's ends (`+1` at `first`, `−1` after
    /// `last`, in wrapping arithmetic: every running sum is a count, never negative), and one
    /// pass over the slots turns the marks into counts and the counts into starts.
    pub(crate) fn fill<I: Iterator<Item = (T, usize, usize)>>(&mut self, slots: usize, items: impl Fn() -> I) {
        self.starts.clear();
        self.starts.resize(slots + 2, 0);
        for (_, first, last) in items() {
            self.starts[first + 1] = self.starts[first + 1].wrapping_add(1);
            self.starts[last + 2] = self.starts[last + 2].wrapping_sub(1);
        }
        self.starts.truncate(slots + 1);
        // `starts[s + 1]` holds the change of slot `s`'s count from slot `s − 1`'s; the running
        // count and start stay in registers (read back from the array, each slot waited on the
        // store of the one before: a sixteenth of a quadrics Depth render)
        let (mut count, mut start) = (0usize, 0usize);
        for change in &mut self.starts[1..=slots] {
            count = count.wrapping_add(*change);
            start += count;
            *change = start;
        }
        self.values.clear();
        self.values.resize(self.starts[slots], T::default());
        self.next.clear();
        self.next.extend_from_slice(&self.starts[..slots]);
        for (value, first, last) in items() {
            for at in &mut self.next[first..=last] {
                self.values[*at] = value;
                *at += 1;
            }
        }
    }

    /// How many slots there are.
    pub(crate) fn slots(&self) -> usize {
        self.starts.len().saturating_sub(1)
    }

    /// The values under slot `s`.
    #[inline]
    pub(crate) fn get(&self, s: usize) -> &[T] {
        &self.values[self.starts[s]..self.starts[s + 1]]
    }

    /// Every slot's values, to work on each list apart.
    pub(crate) fn lists_mut(&mut self) -> Vec<&mut [T]> {
        let mut rest = &mut self.values[..];
        let mut lists = Vec::with_capacity(self.starts.len());
        for bounds in self.starts.windows(2) {
            let (list, after) = rest.split_at_mut(bounds[1] - bounds[0]);
            lists.push(list);
            rest = after;
        }
        lists
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Every slot lists exactly the items covering it, in the items' order, whatever was listed
    /// before (the lists are refilled, not appended to), with slots that no item covers empty.
    #[test]
    fn range_lists_hold_each_slot_s_items_in_order() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(4);
        let mut lists = RangeLists::<u32>::default();
        for round in 0..200 {
            let slots = rng.random_range(1..300);
            let items: Vec<(u32, usize, usize)> = (0..rng.random_range(0..60))
                .map(|k| {
                    let first = rng.random_range(0..slots);
                    (k, first, rng.random_range(first..slots))
                })
                .collect();
            lists.fill(slots, || items.iter().copied());
            assert_eq!(lists.slots(), slots, "round {round}");
            for s in 0..slots {
                let expected: Vec<u32> = items
                    .iter()
                    .filter(|&&(_, first, last)| first <= s && s <= last)
                    .map(|&(value, _, _)| value)
                    .collect();
                assert_eq!(lists.get(s), &expected[..], "round {round}, slot {s}");
            }
        }
    }
}
