//! Where on the image a box can be seen: the rectangle of image positions outside which the ray
//! through a position ([`Camera::ray_through`], the pinhole's ray) provably misses the box
//! ([`Camera::footprint`]), and the union of such rectangles for several boxes
//! ([`Camera::coverage`]). The renderer skips the pixels outside the coverage of the scene's
//! parts (their rays are never made): they see nothing, so they get the miss values untraced.
//!
//! Maths. The box is first enlarged by `δ = 10⁻⁴·(|diagonal| + |centre − eye|)` on every side,
//! plus a hundred times how far a hit may lie off the exact ray for the way the surface stores
//! the ray's origin (a mesh's f32 copy of it, [`zeroset_primitives::Intersect::origin_rounding`]).
//! A ray meets a point `p` exactly when `p` is seen at the ray's image position
//! ([`Camera::project`]). For the models whose projection maps segments to segments (the
//! pinhole, wholly in front of the eye plane, and the orthographic camera), the image of the
//! enlarged box is the convex hull of its eight corners' images, so a position outside their
//! bounding rectangle sees no point of the enlarged box: its exact ray passes the original box
//! at a distance of at least `δ`, a million times what rounding moves a ray in proportion to
//! its length (the f64 ray's set-up, a mesh's f32 copy of it) or puts a hit off its surface, a
//! hundred times what the origin's storage does. The rectangle is widened by one pixel more for
//! the rounding of the projection itself ([`TIGHT_WIDENING`] for the pixel bins of a mesh's
//! leaves, boxes only a few pixels wide).
//!
//! Other models (panoramas, fisheyes, distortion) get no rectangle: every pixel is traced. Nor
//! does a box reaching behind a pinhole's eye plane, except through
//! [`BoxProjector::footprint_clipped`] (the pixel bins of a scene of several objects), which
//! cuts it at a depth in front of which nothing is seen in the image.

use super::{Camera, Model};
use glam::DVec3;
use zeroset_primitives::Aabb;

/// A closed rectangle `[x0, x1] × [y0, y1]` of image positions (pixel units, `y` down).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageRect {
    pub x0: f64,
    pub x1: f64,
    pub y0: f64,
    pub y1: f64,
}

impl ImageRect {
    /// Whether the centre of pixel `(i, j)` lies in the rectangle.
    #[inline(always)]
    #[must_use]
    pub fn holds_pixel(&self, i: u32, j: u32) -> bool {
        let (x, y) = (f64::from(i) + 0.5, f64::from(j) + 0.5);
        x >= self.x0 && x <= self.x1 && y >= self.y0 && y <= self.y1
    }
}

/// Relative enlargement of the box (module docs).
const MARGIN: f64 = 1e-4;

/// How much a box is enlarged before its corners are projected: `10⁻⁴·(|diagonal| +
/// |centre − eye|) + 100·r`, `r` how far off the exact ray a hit may lie for the way the
/// surface stores the ray's origin (a mesh's f32 copy: `2⁻²³·max |eyeᵢ|`, however near the box).
#[inline(always)]
fn enlargement(bounds: &Aabb, eye: DVec3, origin_rounding: f64) -> f64 {
    MARGIN * (bounds.diagonal_length() + (bounds.center() - eye).length()) + 100.0 * origin_rounding
}

/// Pixels a footprint of the pixel bins is widened by: the projection's own rounding, below
/// `10⁻⁹` pixels on images up to `10⁶` pixels wide, with room to spare. The rounding of rays and
/// hits is covered by the box's enlargement.
pub const TIGHT_WIDENING: f64 = 1e-3;

/// The most boxes [`Camera::coverage`] projects one by one (about 3 ms for a 2160-row image);
/// beyond, it projects the box around them.
const MOST_PARTS: usize = 1024;

/// The pixel centres that can see any of several boxes: per image row, the column spans
/// `[x0, x1]` (image positions, merged, in increasing order) of the boxes' footprints that
/// cover the row's centre line.
#[derive(Clone, Debug, PartialEq)]
pub struct Coverage {
    /// Spans of row `j`: `spans[starts[j]..starts[j + 1]]`.
    starts: Vec<u32>,
    spans: Vec<(f64, f64)>,
}

impl Coverage {
    /// Whether the centre of pixel `(i, j)` lies in a footprint (rows beyond the image: yes).
    #[inline]
    #[must_use]
    pub fn holds_pixel(&self, i: u32, j: u32) -> bool {
        let j = j as usize;
        if j + 1 >= self.starts.len() {
            return true;
        }
        let x = f64::from(i) + 0.5;
        self.spans[self.starts[j] as usize..self.starts[j + 1] as usize]
            .iter()
            .any(|&(x0, x1)| x >= x0 && x <= x1)
    }
}

impl Camera {
    /// The pixels whose rays can meet any of `parts` (the [`Camera::footprint`] of each, a
    /// hit allowed `origin_rounding` off the exact ray besides: see [`BoxProjector`]), or `None`
    /// where this camera cannot say for one of them (every pixel may).
    #[must_use]
    pub fn coverage(&self, parts: &[Aabb], origin_rounding: f64) -> Option<Coverage> {
        if parts.len() > MOST_PARTS {
            // one box around them all: the spans are made row by row over every box
            let all = parts.iter().fold(Aabb::EMPTY, |all, part| all.union(*part));
            return self.coverage(&[all], origin_rounding);
        }
        let projector = self.box_projector(origin_rounding);
        let mut rects = Vec::with_capacity(parts.len());
        for part in parts {
            if part.is_empty() {
                continue;
            }
            rects.push(projector.footprint(part, 1.0)?);
        }
        let mut starts = Vec::with_capacity(self.height as usize + 1);
        let mut spans: Vec<(f64, f64)> = Vec::new();
        let mut row: Vec<(f64, f64)> = Vec::new();
        for j in 0..self.height {
            let first = spans.len();
            starts.push(first as u32);
            let y = f64::from(j) + 0.5;
            row.clear();
            row.extend(rects.iter().filter(|r| y >= r.y0 && y <= r.y1).map(|r| (r.x0, r.x1)));
            row.sort_by(|a, b| a.0.total_cmp(&b.0));
            // merged: each span starts after the one before ends
            for &(x0, x1) in &row {
                match spans[first..].last_mut() {
                    Some(last) if x0 <= last.1 => last.1 = last.1.max(x1),
                    _ => spans.push((x0, x1)),
                }
            }
        }
        starts.push(spans.len() as u32);
        Some(Coverage { starts, spans })
    }

    /// The image positions whose rays can meet `bounds` (module docs) on a surface tested in
    /// f64 arithmetic (else see [`Camera::box_projector`]), or `None` where this camera cannot
    /// say (every position may).
    #[must_use]
    pub fn footprint(&self, bounds: &Aabb) -> Option<ImageRect> {
        self.box_projector(0.0).footprint(bounds, 1.0)
    }

    /// What projecting many boxes through this camera shares ([`BoxProjector`]), for surfaces
    /// whose hits may lie up to `origin_rounding` off the exact ray besides the rounding
    /// proportional to distance ([`zeroset_primitives::Intersect::origin_rounding`] at the eye).
    #[must_use]
    pub fn box_projector(&self, origin_rounding: f64) -> BoxProjector<'_> {
        let pinhole = match &self.model {
            Model::Perspective(m) => {
                let (w, h) = (f64::from(self.width), f64::from(self.height));
                Some(PinholeScales {
                    ax: 0.5 * w / self.tan_half_hfov(),
                    ay: 0.5 * h / self.tan_half_vfov,
                    cx: 0.5 * w + m.principal_offset.x,
                    cy: 0.5 * h + m.principal_offset.y,
                })
            }
            _ => None,
        };
        BoxProjector {
            camera: self,
            pinhole,
            origin_rounding,
        }
    }
}

/// The pinhole's projection `x = cx + ax·a/c`, `y = cy − ay·b/c` of camera-local `(a, b, c)`:
/// [`crate::camera::Perspective::project`]'s formula with its constants worked out once.
#[derive(Clone, Copy, Debug)]
struct PinholeScales {
    ax: f64,
    ay: f64,
    cx: f64,
    cy: f64,
}

/// Projects boxes through one camera ([`Camera::box_projector`]): the footprints of
/// [`Camera::footprint`], [`Camera::coverage`] and the pixel bins (widened by
/// [`TIGHT_WIDENING`]), with the camera's constants worked out once for all of them.
#[derive(Clone, Copy, Debug)]
pub struct BoxProjector<'a> {
    camera: &'a Camera,
    pinhole: Option<PinholeScales>,
    /// How far off the exact ray a hit may lie for the way its origin is stored.
    origin_rounding: f64,
}

impl BoxProjector<'_> {
    /// The eye the boxes are projected from.
    #[inline(always)]
    #[must_use]
    pub fn eye(&self) -> DVec3 {
        self.camera.eye
    }

    /// How much [`BoxProjector::footprint`] enlarges `bounds` before projecting it: a hit
    /// farther than this from the box would not be found by a footprint's pixels.
    #[inline(always)]
    #[must_use]
    pub fn enlargement(&self, bounds: &Aabb) -> f64 {
        enlargement(bounds, self.camera.eye, self.origin_rounding)
    }

    /// The bounding rectangle of the images of the enlarged box's corners (module docs),
    /// widened by `widening` pixels on every side.
    #[inline(always)]
    #[must_use]
    pub fn footprint(&self, bounds: &Aabb, widening: f64) -> Option<ImageRect> {
        let (delta, corners) = self.local_corners(bounds)?;
        match (&self.camera.model, self.pinhole) {
            // strictly in front, by more than rounding could move a corner across the plane
            (Model::Perspective(_), Some(p)) if corners[2].iter().all(|&z| z > delta) => {
                p.corners_rect(&corners, widening)
            }
            (Model::Orthographic(m), _) => {
                let [lx, ly, lz] = corners;
                let (mut xs, mut ys) = ([0.0; 8], [0.0; 8]);
                for c in 0..8 {
                    let seen = m.project(self.camera, DVec3::new(lx[c], ly[c], lz[c]));
                    (xs[c], ys[c]) = (seen.x, seen.y);
                }
                bounding_rect(&xs, &ys, widening)
            }
            _ => None,
        }
    }

    /// [`BoxProjector::footprint`] of a pinhole for four boxes at once (`None` where that has
    /// none, and for every box if the camera is no pinhole), each with the distance from the eye
    /// to the box less its [`BoxProjector::enlargement`] (negative where the eye is that close):
    /// the same rectangles, for the many small boxes of the pixel bins, with each step worked
    /// out for the four boxes together (vector lanes).
    ///
    /// The corners are those of [`BoxProjector::footprint`], written as the centre's
    /// camera-local coordinates `mₐ = a·(c − eye)` plus `±` each of the three half edges
    /// `(hₖ + δ)·aₖ` (`a` a camera axis): the same points up to rounding, which the
    /// enlargement covers.
    #[inline(always)]
    #[must_use]
    pub fn pinhole_footprints(&self, boxes: &[Aabb; 4], widening: f64) -> [Option<(ImageRect, f64)>; 4] {
        let (Model::Perspective(_), Some(p)) = (&self.camera.model, self.pinhole) else {
            return [None; 4];
        };
        let camera = self.camera;
        let eye = camera.eye.to_array();
        let axes = [camera.right.to_array(), camera.up.to_array(), camera.forward.to_array()];
        // lane `l` is box `l`; each step runs over the four lanes before the next (independent
        // work the processor overlaps)
        let lanes = |f: &dyn Fn(usize) -> f64| -> [f64; 4] { std::array::from_fn(f) };
        let half: [[f64; 4]; 3] = std::array::from_fn(|k| lanes(&|l| 0.5 * (boxes[l].max[k] - boxes[l].min[k])));
        let to_centre: [[f64; 4]; 3] =
            std::array::from_fn(|k| lanes(&|l| 0.5 * (boxes[l].min[k] + boxes[l].max[k]) - eye[k]));
        let length = |v: &[[f64; 4]; 3], l: usize| (v[0][l] * v[0][l] + v[1][l] * v[1][l] + v[2][l] * v[2][l]).sqrt();
        let delta =
            lanes(&|l| MARGIN * (2.0 * length(&half, l) + length(&to_centre, l)) + 100.0 * self.origin_rounding);
        // per camera axis `a`: the centre's coordinate, and the enlarged box's half edge along
        // world axis `k` in camera coordinates
        let middle: [[f64; 4]; 3] = std::array::from_fn(|a| {
            lanes(&|l| to_centre[0][l] * axes[a][0] + to_centre[1][l] * axes[a][1] + to_centre[2][l] * axes[a][2])
        });
        let edge: [[[f64; 4]; 3]; 3] =
            std::array::from_fn(|a| std::array::from_fn(|k| lanes(&|l| (half[k][l] + delta[l]) * axes[a][k])));
        let (mut x_low, mut x_high, mut y_low, mut y_high) = (
            [f64::INFINITY; 4],
            [f64::NEG_INFINITY; 4],
            [f64::INFINITY; 4],
            [f64::NEG_INFINITY; 4],
        );
        let mut nearest_z = [f64::INFINITY; 4];
        for corner in 0..8 {
            let sign = |k: usize| if corner & (1 << k) == 0 { -1.0 } else { 1.0 };
            let local = |a: usize| {
                lanes(&|l| middle[a][l] + sign(0) * edge[a][0][l] + sign(1) * edge[a][1][l] + sign(2) * edge[a][2][l])
            };
            let (x, y, z) = (local(0), local(1), local(2));
            for l in 0..4 {
                let inverse = 1.0 / z[l];
                let (u, v) = (p.cx + p.ax * (x[l] * inverse), p.cy - p.ay * (y[l] * inverse));
                // plain comparisons, as in `bounding_rect`: NaN is caught below
                x_low[l] = if u < x_low[l] { u } else { x_low[l] };
                x_high[l] = if u > x_high[l] { u } else { x_high[l] };
                y_low[l] = if v < y_low[l] { v } else { y_low[l] };
                y_high[l] = if v > y_high[l] { v } else { y_high[l] };
                nearest_z[l] = if z[l] < nearest_z[l] { z[l] } else { nearest_z[l] };
            }
        }
        // the distance from the eye to the box: its offset from the box along each axis
        let outside: [[f64; 4]; 3] =
            std::array::from_fn(|k| lanes(&|l| (boxes[l].min[k] - eye[k]).max(eye[k] - boxes[l].max[k]).max(0.0)));
        let near = lanes(&|l| length(&outside, l) - delta[l]);
        let eye_finite = camera.eye.is_finite();
        std::array::from_fn(|l| {
            let rect = ImageRect {
                x0: x_low[l] - widening,
                x1: x_high[l] + widening,
                y0: y_low[l] - widening,
                y1: y_high[l] + widening,
            };
            // strictly in front, by more than rounding could move a corner across the plane
            let in_front = nearest_z[l] > delta[l];
            let finite = [rect.x0, rect.x1, rect.y0, rect.y1].iter().all(|v| v.is_finite());
            (in_front && finite && eye_finite && !boxes[l].is_empty()).then_some((rect, near[l]))
        })
    }

    /// The footprint of a pinhole for a ball (centre `centre`, radius `radius`) holding a
    /// surface whose box is `bounds`, with the distance from the eye to the ball less the
    /// enlargement (negative where the eye is that close); `None` where the camera is no pinhole
    /// or the enlarged ball is not wholly in front of the eye by more than the enlargement.
    ///
    /// Maths. The ball is enlarged by the box's enlargement `δ` ([`BoxProjector::enlargement`]),
    /// `R = radius + δ`. In camera-local coordinates, with centre `m`, the ratio `x/z` over the
    /// ball depends on `(x, z)` alone, which fill the disc of radius `R` around `(mₓ, m_z)`: its
    /// extremes are the slopes `s` of the two lines through the eye tangent to that disc, the
    /// roots of `s²(m_z² − R²) − 2s·mₓm_z + mₓ² − R² = 0`,
    /// `s = (mₓm_z ± R·√(mₓ² + m_z² − R²)) / (m_z² − R²)`; likewise `y/z`. The rectangle of
    /// those image positions bounds the ball's image exactly, so a pixel outside it has a ray
    /// missing the enlarged ball; it is widened by `widening` and by `10⁻⁹` of each position
    /// for the rounding of the roots (relative to their size, a few `10⁻¹⁶`).
    #[must_use]
    pub fn ball_footprint(&self, centre: DVec3, radius: f64, bounds: &Aabb, widening: f64) -> Option<(ImageRect, f64)> {
        let (Model::Perspective(_), Some(p)) = (&self.camera.model, self.pinhole) else {
            return None;
        };
        if !(centre.is_finite()
            && radius.is_finite()
            && radius >= 0.0
            && bounds.is_finite()
            && self.camera.eye.is_finite())
        {
            return None;
        }
        let delta = self.enlargement(bounds);
        let reach = radius + delta;
        let m = self.camera.world_to_local(centre);
        // (finite: every input was checked above)
        if m.z - reach <= delta {
            return None;
        }
        let depth = m.z * m.z - reach * reach;
        let slopes = |lateral: f64| {
            let spread = reach * (lateral * lateral + depth).sqrt();
            ((lateral * m.z - spread) / depth, (lateral * m.z + spread) / depth)
        };
        let ((x_low, x_high), (y_low, y_high)) = (slopes(m.x), slopes(m.y));
        let widen = |v: f64| widening + 1e-9 * v.abs();
        let (x0, x1) = (p.cx + p.ax * x_low, p.cx + p.ax * x_high);
        let (y0, y1) = (p.cy - p.ay * y_high, p.cy - p.ay * y_low);
        let rect = ImageRect {
            x0: x0 - widen(x0),
            x1: x1 + widen(x1),
            y0: y0 - widen(y0),
            y1: y1 + widen(y1),
        };
        let finite = [rect.x0, rect.x1, rect.y0, rect.y1].iter().all(|v| v.is_finite());
        let near = (centre - self.camera.eye).length() - radius - delta;
        finite.then_some((rect, near))
    }

    /// [`BoxProjector::footprint`] of a pinhole, also for a box reaching behind the eye plane
    /// (a ground polygon under the eye), whose corners have no images: the enlarged box is first
    /// cut by the plane `z = z_c` (camera-local depth), keeping the part in front, and the
    /// rectangle bounds the images of that part's corners (the box's corners in front and
    /// where its edges cross the plane). With `R` the distance from the eye to the enlarged
    /// box and `T` the largest `|(x, y)|/z` of a direction through the image,
    /// `z_c = R / (2·√(1 + T²))`: a point of the box in front of the cut lies farther than `R`
    /// from the eye, so it is seen at `|(x, y)| ≥ √(R² − z²) > T·z` — outside the image. `None`
    /// where the eye is in the enlarged box or the cut lies within the enlargement.
    #[must_use]
    pub fn footprint_clipped(&self, bounds: &Aabb, widening: f64) -> Option<ImageRect> {
        let (Model::Perspective(_), Some(p)) = (&self.camera.model, self.pinhole) else {
            return None;
        };
        let (delta, corners) = self.local_corners(bounds)?;
        let [lx, ly, lz] = corners;
        if lz.iter().all(|&z| z > delta) {
            return p.corners_rect(&corners, widening);
        }
        let camera = self.camera;
        let enlarged = bounds.expanded(delta);
        let reach = (camera.eye.clamp(enlarged.min, enlarged.max) - camera.eye).length();
        let (w, h) = (f64::from(camera.width), f64::from(camera.height));
        let tx = p.cx.abs().max((w - p.cx).abs()) / p.ax;
        let ty = p.cy.abs().max((h - p.cy).abs()) / p.ay;
        let cut = 0.5 * reach / (1.0 + tx * tx + ty * ty).sqrt();
        if cut.is_nan() || cut <= delta {
            return None;
        }
        // the corners in front of the cut and the crossings of the twelve edges (corners `c` and
        // `c | 1 << a` for bit `a` of `c` clear)
        let (mut xs, mut ys) = (Vec::with_capacity(20), Vec::with_capacity(20));
        for c in 0..8 {
            if lz[c] >= cut {
                let (x, y) = p.project(lx[c], ly[c], lz[c]);
                xs.push(x);
                ys.push(y);
            }
            for a in 0..3 {
                let d = c | 1 << a;
                if c & 1 << a != 0 || (lz[c] >= cut) == (lz[d] >= cut) {
                    continue;
                }
                let f = (cut - lz[c]) / (lz[d] - lz[c]);
                let (x, y) = p.project(lx[c] + f * (lx[d] - lx[c]), ly[c] + f * (ly[d] - ly[c]), cut);
                xs.push(x);
                ys.push(y);
            }
        }
        bounding_rect(&xs, &ys, widening)
    }

    /// The enlargement `δ` of `bounds` and the camera-local coordinates of the enlarged box's
    /// corners, one array per axis (corner `c` is the low corner plus edge `a` where bit `a`
    /// of `c` is set): the first corner's coordinates plus the box's edges mapped once (sums of
    /// f64 terms: their rounding, like the projection's, is covered by `δ`).
    #[inline(always)]
    fn local_corners(&self, bounds: &Aabb) -> Option<(f64, [[f64; 8]; 3])> {
        let camera = self.camera;
        if !bounds.is_finite() || bounds.is_empty() || !camera.eye.is_finite() {
            return None;
        }
        let delta = enlargement(bounds, camera.eye, self.origin_rounding);
        let enlarged = bounds.expanded(delta);
        let first = camera.world_to_local(enlarged.min);
        let size = enlarged.max - enlarged.min;
        let edges = [
            size.x * DVec3::new(camera.right.x, camera.up.x, camera.forward.x),
            size.y * DVec3::new(camera.right.y, camera.up.y, camera.forward.y),
            size.z * DVec3::new(camera.right.z, camera.up.z, camera.forward.z),
        ];
        let mut local = [[first.x; 8], [first.y; 8], [first.z; 8]];
        for (axis, values) in local.iter_mut().enumerate() {
            for (c, value) in values.iter_mut().enumerate() {
                for (a, edge) in edges.iter().enumerate() {
                    if c & (1 << a) != 0 {
                        *value += edge[axis];
                    }
                }
            }
        }
        Some((delta, local))
    }
}

impl PinholeScales {
    /// The image position of camera-local `(x, y, z)`, `z > 0`.
    #[inline(always)]
    fn project(&self, x: f64, y: f64, z: f64) -> (f64, f64) {
        let inverse = 1.0 / z;
        (self.cx + self.ax * (x * inverse), self.cy - self.ay * (y * inverse))
    }

    /// [`bounding_rect`] of the images of eight camera-local corners (one array per axis, as
    /// [`BoxProjector::local_corners`] gives them), all in front of the eye.
    #[inline(always)]
    fn corners_rect(&self, [lx, ly, lz]: &[[f64; 8]; 3], widening: f64) -> Option<ImageRect> {
        let (mut xs, mut ys) = ([0.0; 8], [0.0; 8]);
        for c in 0..8 {
            (xs[c], ys[c]) = self.project(lx[c], ly[c], lz[c]);
        }
        bounding_rect(&xs, &ys, widening)
    }
}

/// The bounding rectangle of the image positions `(xs[i], ys[i])`, widened by `widening` pixels
/// on every side; `None` unless it is finite.
#[inline(always)]
fn bounding_rect(xs: &[f64], ys: &[f64], widening: f64) -> Option<ImageRect> {
    // plain comparisons: every value here is finite or ±∞, never NaN (checked below)
    let lowest = |v: &[f64]| v.iter().fold(f64::INFINITY, |m, &x| if x < m { x } else { m });
    let highest = |v: &[f64]| v.iter().fold(f64::NEG_INFINITY, |m, &x| if x > m { x } else { m });
    let rect = ImageRect {
        x0: lowest(xs) - widening,
        x1: highest(xs) + widening,
        y0: lowest(ys) - widening,
        y1: highest(ys) + widening,
    };
    [rect.x0, rect.x1, rect.y0, rect.y1]
        .iter()
        .all(|v| v.is_finite())
        .then_some(rect)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Orthographic, Perspective};
    use glam::{DVec2, DVec3};
    use rand::{Rng, SeedableRng};
    use std::ops::Range;
    use zeroset_primitives::{Interval, Ray};

    /// A random box: its centre's coordinates drawn from `centre`, its half-extents from `half`.
    fn random_box(rng: &mut impl Rng, centre: [Range<f64>; 3], half: Range<f64>) -> Aabb {
        let [x, y, z] = centre;
        let c = DVec3::new(rng.random_range(x), rng.random_range(y), rng.random_range(z));
        let h = DVec3::new(
            rng.random_range(half.clone()),
            rng.random_range(half.clone()),
            rng.random_range(half),
        );
        Aabb::new(c - h, c + h)
    }

    /// A `width × height` camera at `z = −10` (eye `x` and `y` within ±5) looking along `+z`
    /// tilted by up to `tilt` on each axis, its vertical field of view drawn from `fov` (degrees).
    fn random_camera(rng: &mut impl Rng, width: u32, height: u32, tilt: f64, fov: Range<f64>) -> Camera {
        let eye = DVec3::new(rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0), -10.0);
        let direction = DVec3::new(rng.random_range(-tilt..tilt), rng.random_range(-tilt..tilt), 1.0);
        Camera::new(eye, direction, DVec3::Y, rng.random_range(fov), width, height).unwrap()
    }

    /// A pinhole whose principal point is offset by up to `offset` pixels on each axis.
    fn random_pinhole(rng: &mut impl Rng, offset: f64) -> Model {
        Model::Perspective(Perspective {
            principal_offset: DVec2::new(rng.random_range(-offset..offset), rng.random_range(-offset..offset)),
        })
    }

    /// Checks that every pixel of `camera` whose centre lies outside `rect` has a ray missing
    /// `bounds` grown by half the footprint's margin (the f64 slab test of `Aabb::clip`);
    /// returns how many pixels inside `rect` meet it and how many are left out.
    fn check_pixels_outside(camera: &Camera, bounds: &Aabb, rect: &ImageRect, trial: usize) -> (usize, usize) {
        let grown = bounds.expanded(0.5 * enlargement(bounds, camera.eye, 0.0));
        count_pixels(camera, rect, trial, |ray| grown.clip(ray, Interval::POSITIVE).is_some())
    }

    /// Checks that no pixel of `camera` whose centre lies outside `rect` has a ray that
    /// `meets` the shape; returns how many pixels inside `rect` meet it and how many are left
    /// out.
    fn count_pixels(camera: &Camera, rect: &ImageRect, trial: usize, meets: impl Fn(&Ray) -> bool) -> (usize, usize) {
        let (mut meeting, mut left_out) = (0, 0);
        for j in 0..camera.height {
            for i in 0..camera.width {
                let meets = meets(&camera.pixel_ray(i, j).unwrap());
                if rect.holds_pixel(i, j) {
                    meeting += usize::from(meets);
                } else {
                    left_out += 1;
                    assert!(
                        !meets,
                        "trial {trial}: pixel ({i}, {j}) outside {rect:?} meets the shape"
                    );
                }
            }
        }
        (meeting, left_out)
    }

    /// Over random pinhole (principal offsets included) and orthographic cameras and random
    /// boxes, near and far, in view and beside it: every pixel whose centre is outside the
    /// footprint has a ray that misses the box grown by half the margin (the f64 slab test of
    /// `Aabb::clip`), and the footprint leaves pixels out in most trials.
    #[test]
    fn pixels_outside_the_footprint_miss_the_box() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(71);
        let (width, height) = (48u32, 32u32);
        let (mut culled, mut rects, mut hits) = (0usize, 0usize, 0usize);
        for trial in 0..400 {
            let mut camera = random_camera(&mut rng, width, height, 0.3, 10.0..90.0);
            camera.model = if trial % 3 == 0 {
                Model::Orthographic(Orthographic {
                    width: rng.random_range(2.0..30.0),
                })
            } else {
                random_pinhole(&mut rng, 8.0)
            };
            let bounds = random_box(&mut rng, [-8.0..8.0, -8.0..8.0, -12.0..20.0], 0.01..3.0);
            let Some(rect) = camera.footprint(&bounds) else {
                continue;
            };
            rects += 1;
            let (meeting, left_out) = check_pixels_outside(&camera, &bounds, &rect, trial);
            hits += meeting;
            culled += left_out;
        }
        assert!(rects > 200, "{rects} footprints");
        assert!(culled > 100 * rects, "{culled} pixels left out over {rects} footprints");
        assert!(hits > 20 * rects, "{hits} pixels meeting their boxes");
    }

    /// Four boxes at a time give each box's own footprint (to within rounding, `10⁻⁹` pixels)
    /// and its distance less the enlargement, `None` exactly where the single-box footprint has
    /// none (boxes beside, behind and around the eye, a pinhole with principal offsets and
    /// with a mesh's origin rounding), and `None` for every box through an orthographic camera.
    #[test]
    fn four_boxes_at_a_time_give_each_box_s_footprint() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(72);
        let (mut compared, mut without) = (0, 0);
        for trial in 0..500 {
            let mut camera = random_camera(&mut rng, 640, 480, 0.5, 10.0..90.0);
            camera.model = random_pinhole(&mut rng, 30.0);
            let eye = camera.eye;
            let projector = camera.box_projector(if trial % 2 == 0 { 0.0 } else { 1e-6 });
            let boxes: [Aabb; 4] =
                std::array::from_fn(|_| random_box(&mut rng, [-8.0..8.0, -8.0..8.0, -14.0..20.0], 0.001..2.0));
            let four = projector.pinhole_footprints(&boxes, TIGHT_WIDENING);
            for (bounds, found) in boxes.iter().zip(four) {
                match (projector.footprint(bounds, TIGHT_WIDENING), found) {
                    (Some(one), Some((rect, near))) => {
                        compared += 1;
                        let scale = 1e-9 * (1.0 + one.x0.abs().max(one.x1.abs()).max(one.y0.abs()).max(one.y1.abs()));
                        for (a, b) in [
                            (one.x0, rect.x0),
                            (one.x1, rect.x1),
                            (one.y0, rect.y0),
                            (one.y1, rect.y1),
                        ] {
                            assert!((a - b).abs() <= scale, "trial {trial}: {one:?} against {rect:?}");
                        }
                        let distance = (eye.clamp(bounds.min, bounds.max) - eye).length();
                        let expected = distance - projector.enlargement(bounds);
                        assert!(
                            (near - expected).abs() <= 1e-12 * (1.0 + distance),
                            "trial {trial}: {near} against {expected}"
                        );
                    }
                    (None, None) => without += 1,
                    (one, four) => panic!("trial {trial}: {one:?} against {four:?} for {bounds:?}"),
                }
            }
        }
        assert!(
            compared > 1000 && without > 100,
            "{compared} compared, {without} without a footprint"
        );
        let mut orthographic = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 40.0, 64, 48).unwrap();
        orthographic.model = Model::Orthographic(Orthographic { width: 10.0 });
        let bounds = Aabb::new(DVec3::new(-1.0, -1.0, 4.0), DVec3::new(1.0, 1.0, 5.0));
        assert!(orthographic
            .box_projector(0.0)
            .footprint(&bounds, TIGHT_WIDENING)
            .is_some());
        assert_eq!(
            orthographic
                .box_projector(0.0)
                .pinhole_footprints(&[bounds; 4], TIGHT_WIDENING),
            [None; 4]
        );
    }

    /// A ball's footprint: every pixel whose centre it leaves out has a ray that misses the ball
    /// grown by half the enlargement (the distance from the centre to the ray, in f64), the
    /// rectangle lies within the footprint of the ball's box and is smaller than it, and `near`
    /// is the distance to the ball less the enlargement; `None` for a ball reaching behind the
    /// eye plane and for an orthographic camera.
    #[test]
    fn pixels_outside_a_ball_s_footprint_miss_the_ball() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(73);
        let (width, height) = (64u32, 48u32);
        let (mut rects, mut culled, mut meeting, mut smaller) = (0usize, 0usize, 0usize, 0usize);
        for trial in 0..300 {
            let mut camera = random_camera(&mut rng, width, height, 0.3, 20.0..90.0);
            camera.model = random_pinhole(&mut rng, 6.0);
            let eye = camera.eye;
            let centre = DVec3::new(
                rng.random_range(-8.0..8.0),
                rng.random_range(-8.0..8.0),
                rng.random_range(-12.0..20.0),
            );
            let radius = rng.random_range(0.05..3.0);
            let bounds = Aabb::new(centre - DVec3::splat(radius), centre + DVec3::splat(radius));
            let projector = camera.box_projector(0.0);
            let Some((rect, near)) = projector.ball_footprint(centre, radius, &bounds, TIGHT_WIDENING) else {
                let local = camera.world_to_local(centre);
                assert!(
                    local.z - radius <= 2.0 * projector.enlargement(&bounds) + 1e-9,
                    "trial {trial}: in front, no footprint"
                );
                continue;
            };
            rects += 1;
            let delta = projector.enlargement(&bounds);
            let distance = (centre - eye).length() - radius - delta;
            assert!(
                (near - distance).abs() <= 1e-12 * (1.0 + distance.abs()),
                "trial {trial}"
            );
            let grown = radius + 0.5 * delta;
            // whether a ray comes within `grown` of the centre (its closest approach, t ≥ 0)
            let meets = |ray: &Ray| {
                let t = (centre - ray.origin).dot(ray.dir).max(0.0) / ray.dir.length_squared();
                (ray.at(t) - centre).length() <= grown
            };
            // just outside each side of the rectangle (a millionth of a pixel), along it
            for k in 0..=64 {
                let (u, v) = (f64::from(k) / 64.0, 1e-6);
                let (x, y) = (rect.x0 + u * (rect.x1 - rect.x0), rect.y0 + u * (rect.y1 - rect.y0));
                for (px, py) in [(rect.x0 - v, y), (rect.x1 + v, y), (x, rect.y0 - v), (x, rect.y1 + v)] {
                    let ray = camera.ray_through(px, py).unwrap();
                    assert!(
                        !meets(&ray),
                        "trial {trial}: ({px}, {py}) just outside {rect:?} meets the ball"
                    );
                }
            }
            let (inside, outside) = count_pixels(&camera, &rect, trial, meets);
            meeting += inside;
            culled += outside;
            if let Some(boxed) = projector.footprint(&bounds, TIGHT_WIDENING) {
                let within = rect.x0 >= boxed.x0 - 1e-6
                    && rect.x1 <= boxed.x1 + 1e-6
                    && rect.y0 >= boxed.y0 - 1e-6
                    && rect.y1 <= boxed.y1 + 1e-6;
                assert!(within, "trial {trial}: {rect:?} outside the box's {boxed:?}");
                let area = |r: &ImageRect| (r.x1 - r.x0) * (r.y1 - r.y0);
                smaller += usize::from(area(&rect) < 0.95 * area(&boxed));
            }
        }
        assert!(
            rects > 100 && culled > 50 * rects && meeting > 5 * rects,
            "{rects} rects, {culled} culled, {meeting} meeting"
        );
        assert!(smaller > rects / 2, "{smaller} of {rects} smaller than the box's");
        let mut orthographic = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 40.0, 64, 48).unwrap();
        orthographic.model = Model::Orthographic(Orthographic { width: 10.0 });
        let bounds = Aabb::new(DVec3::new(-1.0, -1.0, 4.0), DVec3::new(1.0, 1.0, 6.0));
        assert_eq!(
            orthographic
                .box_projector(0.0)
                .ball_footprint(DVec3::new(0.0, 0.0, 5.0), 1.0, &bounds, TIGHT_WIDENING),
            None
        );
    }

    /// The cut footprint of boxes reaching behind a pinhole's eye plane (long slabs under and
    /// beside the eye, boxes around it or behind it): every pixel whose centre it leaves out has
    /// a ray that misses the box grown by half the margin, the pixels meeting the box are held,
    /// and most footprints leave pixels out (the ground's sky). Boxes wholly in front get the
    /// plain footprint.
    #[test]
    fn pixels_outside_the_cut_footprint_miss_the_box() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(73);
        let (width, height) = (48u32, 32u32);
        let (mut cut, mut culled, mut hits, mut none) = (0usize, 0usize, 0usize, 0usize);
        for trial in 0..400 {
            let eye = DVec3::new(
                rng.random_range(-3.0..3.0),
                rng.random_range(0.2..5.0),
                rng.random_range(-3.0..3.0),
            );
            let direction = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-0.8..0.3),
                rng.random_range(-1.0..1.0),
            );
            let Ok(mut camera) = Camera::new(eye, direction, DVec3::Y, rng.random_range(10.0..120.0), width, height)
            else {
                continue;
            };
            camera.model = random_pinhole(&mut rng, 8.0);
            let bounds = if trial % 2 == 0 {
                // a thick ground slab under the eye, reaching far behind it
                let half = rng.random_range(5.0..200.0);
                let top = rng.random_range(-0.5..0.1);
                Aabb::new(
                    DVec3::new(-half, top - rng.random_range(0.0..0.5), -half),
                    DVec3::new(half, top, half),
                )
            } else {
                random_box(&mut rng, [-6.0..6.0, -6.0..6.0, -6.0..6.0], 0.01..6.0)
            };
            let projector = camera.box_projector(0.0);
            let Some(rect) = projector.footprint_clipped(&bounds, 1.0) else {
                none += 1;
                continue;
            };
            if projector.footprint(&bounds, 1.0) == Some(rect) {
                continue;
            }
            cut += 1;
            let (meeting, left_out) = check_pixels_outside(&camera, &bounds, &rect, trial);
            hits += meeting;
            culled += usize::from(left_out > 0);
        }
        assert!(cut > 150, "{cut} cut footprints ({none} without one)");
        assert!(culled > cut / 3, "{culled} of {cut} cut footprints leave pixels out");
        assert!(hits > 100 * cut, "{hits} pixels meeting their boxes");
    }

    /// Over random cameras and random sets of up to 40 boxes: every pixel the coverage leaves
    /// out has a ray that misses every box grown by half its margin, every pixel some box's
    /// footprint holds is held, and the coverage leaves out pixels the single box around them all
    /// would hold.
    #[test]
    fn pixels_outside_the_coverage_miss_every_box() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(72);
        let (width, height) = (48u32, 32u32);
        let (mut covered, mut finer) = (0usize, 0usize);
        for trial in 0..200 {
            let eye = DVec3::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0), -12.0);
            let mut camera = Camera::new(eye, DVec3::Z, DVec3::Y, rng.random_range(20.0..70.0), width, height).unwrap();
            if trial % 4 == 0 {
                camera.model = Model::Orthographic(Orthographic {
                    width: rng.random_range(5.0..30.0),
                });
            }
            let boxes: Vec<Aabb> = (0..rng.random_range(1..=40))
                .map(|_| random_box(&mut rng, [-6.0..6.0, -4.0..4.0, -2.0..8.0], 0.01..1.0))
                .collect();
            let Some(coverage) = camera.coverage(&boxes, 0.0) else {
                continue;
            };
            covered += 1;
            let all = boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(*b));
            let whole = camera.footprint(&all).unwrap();
            let rects: Vec<ImageRect> = boxes.iter().map(|b| camera.footprint(b).unwrap()).collect();
            for j in 0..height {
                for i in 0..width {
                    let held = coverage.holds_pixel(i, j);
                    assert_eq!(
                        held,
                        rects.iter().any(|r| r.holds_pixel(i, j)),
                        "trial {trial}, pixel ({i}, {j})"
                    );
                    if held {
                        continue;
                    }
                    finer += usize::from(whole.holds_pixel(i, j));
                    let ray = camera.pixel_ray(i, j).unwrap();
                    for b in &boxes {
                        let delta = enlargement(b, camera.eye, 0.0);
                        assert!(
                            b.expanded(0.5 * delta).clip(&ray, Interval::POSITIVE).is_none(),
                            "trial {trial}: pixel ({i}, {j}) meets {b:?}"
                        );
                    }
                }
            }
        }
        assert!(covered > 150, "{covered} coverages");
        assert!(finer > 1000, "{finer} pixels left out inside the whole box's footprint");
    }

    /// No footprint where the camera cannot give one: a box reaching behind the pinhole's eye
    /// plane, an unbounded or empty box, a panorama.
    #[test]
    fn no_footprint_where_rays_are_not_confined() {
        let camera = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 40.0, 64, 48).unwrap();
        let in_front = Aabb::new(DVec3::new(-1.0, -1.0, 4.0), DVec3::new(1.0, 1.0, 6.0));
        let rect = camera.footprint(&in_front).expect("a box in front has a footprint");
        assert!(rect.holds_pixel(32, 24) && !rect.holds_pixel(0, 0));
        let behind = Aabb::new(DVec3::new(-1.0, -1.0, -1.0), DVec3::new(1.0, 1.0, 6.0));
        assert_eq!(camera.footprint(&behind), None);
        assert_eq!(camera.footprint(&Aabb::EVERYTHING), None);
        assert_eq!(camera.footprint(&Aabb::EMPTY), None);
        let mut panorama = camera.clone();
        panorama.model = Model::Equirectangular(crate::camera::Equirectangular {
            azimuth: (-3.0, 3.0),
            elevation: (-1.5, 1.5),
        });
        assert_eq!(panorama.footprint(&in_front), None);
    }
}
