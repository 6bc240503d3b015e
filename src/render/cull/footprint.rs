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

use crate::camera::{Camera, Model};
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
mod tests;
