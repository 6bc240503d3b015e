//! Cameras: a pose (eye and orthonormal basis) shared by every model, a projection [`Model`], a
//! thin lens and a shutter.
//!
//! Basis (right-handed, as in the benchmark harnesses): forward `f = normalize(look_at − eye)`,
//! right `r = normalize(f × up)`, true up `u = r × f` (so `up` need only not be parallel to `f`).
//! **Image positions** are continuous pixel coordinates `(x, y)`, `x` to the right and `y` down,
//! with row 0 at the top; pixel `(i, j)` is sampled through its centre `(i + ½, j + ½)`. Every
//! model maps an image position to a unit-direction ray (so the ray parameter `t` is metric
//! distance), and a world point back to the image position it is seen at ([`Camera::project`]):
//!
//! | model | file | rays | depth `Z` |
//! |---|---|---|---|
//! | `Perspective` (default) | [`perspective`] | from the eye, through a plane; optional principal-point offset | planar, along `forward` |
//! | `Orthographic(width)` | [`orthographic`] | parallel to `forward`, from the eye plane | planar (= ray distance) |
//! | `Equirectangular` | [`equirectangular`] | from the eye, linear in azimuth and elevation | ray distance |
//! | `Fisheye(fov_deg)` | [`fisheye`] | from the eye, equidistant `r = f·θ`, up to 360° | ray distance |
//! | `OpenCv(fx, fy, cx, cy, distortion)` | [`opencv`] | from the eye, Brown–Conrady distortion inverted | planar, along `forward` |
//!
//! So `Z` is planar wherever a view axis exists and the ray distance elsewhere; the `Distance`
//! AOV is the ray distance for every model. Some image positions have no ray ([`NoRay`]): those
//! outside a fisheye's image circle, and OpenCV pixels whose undistortion does not converge;
//! the renderer writes the miss values there and counts them.
//!
//! **Perspective.** Pixel `(i, j)` of the default model is the ray from `eye` along
//! `f + x·r + y·u` with
//! `x = ((i + ½)/W·2 − 1)·tan(θv/2)·W/H` and `y = (1 − (j + ½)/H·2)·tan(θv/2)`,
//! normalised. Pixels are square: `tan(θv/2)/tan(θh/2) = H/W`.
//!
//! **Thin lens** (perspective only, [`lens`]): with `aperture > 0` rays start on a lens disk
//! and meet on the focus plane; with `aperture = 0` [`Camera::lens_ray`] returns the pinhole ray
//! itself, bit for bit.
//!
//! **Shutter.** The shutter is open over the frame times `[open, close]` (default `[0, 1]`);
//! moving objects are keyed at frame times 0 and 1 (see `scene.rs`).
//!
//! **Camera spaces.** For the EXR `worldToCamera` attribute and camera-space normals: origin at
//! the eye, `+x` right, `+y` up, the camera looking along `−z` (the OpenGL/Nuke convention, also
//! NeRF's). For camera files ([`crate::output::cameras_json`]): the OpenCV convention, `+x`
//! right, `+y` down, `+z` forward ([`Camera::opencv_extrinsics`]).

pub mod desc;
pub mod equirectangular;
pub mod fisheye;
pub mod lens;
pub mod opencv;
pub mod orthographic;
pub mod perspective;
pub mod pose;

pub use equirectangular::Equirectangular;
pub use fisheye::Fisheye;
pub use lens::concentric_disk;
pub use opencv::OpenCv;
pub use orthographic::Orthographic;
pub use perspective::Perspective;

use glam::{DMat3, DMat4, DVec2, DVec3};
use std::ops::Range;
use zeroset_primitives::Ray;

/// A projection model (module table); each variant's file states its maths.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Model {
    /// The pinhole (the default), field of view in [`Camera::tan_half_vfov`].
    Perspective(Perspective),
    /// Parallel rays.
    Orthographic(Orthographic),
    /// Azimuth × elevation panorama.
    Equirectangular(Equirectangular),
    /// Equidistant fisheye.
    Fisheye(Fisheye),
    /// Calibrated pinhole with Brown–Conrady distortion.
    OpenCv(OpenCv),
}

impl Model {
    /// The variant's name as scene files and camera files write it.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Model::Perspective(_) => "Perspective",
            Model::Orthographic(_) => "Orthographic",
            Model::Equirectangular(_) => "Equirectangular",
            Model::Fisheye(_) => "Fisheye",
            Model::OpenCv(_) => "OpenCv",
        }
    }

    /// Whether depth `Z` is planar (the model has a view axis) rather than the ray distance.
    #[must_use]
    pub fn planar_depth(&self) -> bool {
        matches!(self, Model::Perspective(_) | Model::Orthographic(_) | Model::OpenCv(_))
    }
}

/// Why an image position has no ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoRay {
    /// Outside the model's field (a fisheye's image circle).
    OutsideField,
    /// The OpenCV undistortion did not converge there (see [`opencv`]).
    NotConverged,
}

impl std::fmt::Display for NoRay {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            NoRay::OutsideField => "outside the camera's field of view",
            NoRay::NotConverged => "the lens undistortion does not converge there",
        })
    }
}

/// A validated camera: pose, model, lens and shutter.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Eye position (world space).
    pub eye: DVec3,
    /// Unit view direction.
    pub forward: DVec3,
    /// Unit right vector.
    pub right: DVec3,
    /// Unit true-up vector.
    pub up: DVec3,
    /// `tan(θv/2)`: the vertical field of view of the `Perspective` model (unused by others).
    pub tan_half_vfov: f64,
    /// The projection model.
    pub model: Model,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Lens radius (world units); 0 is the pinhole.
    pub aperture: f64,
    /// Distance from the eye to the plane in focus, along `forward`.
    pub focus_distance: f64,
    /// Frame times `(open, close)` during which the shutter is open.
    pub shutter: (f64, f64),
}

/// Why a camera description is impossible, naming the field.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("camera: field `{field}`: {problem}")]
pub struct CameraError {
    /// Offending field.
    pub field: &'static str,
    /// What is wrong.
    pub problem: String,
}

pub(crate) fn err(field: &'static str, problem: impl Into<String>) -> CameraError {
    CameraError {
        field,
        problem: problem.into(),
    }
}

impl Camera {
    /// A camera at `eye` looking along `direction` (any length > 0), with `up` orthonormalised
    /// against it, vertical field of view `vfov_deg` ∈ (0°, 180°) and `width × height` pixels.
    pub fn new(
        eye: DVec3,
        direction: DVec3,
        up: DVec3,
        vfov_deg: f64,
        width: u32,
        height: u32,
    ) -> Result<Self, CameraError> {
        if !eye.is_finite() {
            return Err(err("eye", format!("must be finite, got {eye}")));
        }
        if !direction.is_finite() || direction.length() == 0.0 {
            return Err(err(
                "look_at",
                "the view direction must be finite and non-zero (look_at equals eye?)",
            ));
        }
        if !up.is_finite() || up.length() == 0.0 {
            return Err(err("up", format!("must be finite and non-zero, got {up}")));
        }
        if !(vfov_deg > 0.0 && vfov_deg < 180.0) {
            return Err(err("vfov_deg", format!("must lie in (0, 180) degrees, got {vfov_deg}")));
        }
        if width == 0 || height == 0 {
            return Err(err(
                if width == 0 { "width" } else { "height" },
                "must be at least 1 pixel",
            ));
        }
        let forward = direction.normalize();
        let side = forward.cross(up.normalize());
        if side.length() < 1e-9 {
            return Err(err("up", "is parallel to the view direction"));
        }
        let right = side.normalize();
        let true_up = right.cross(forward);
        Ok(Self {
            eye,
            forward,
            right,
            up: true_up,
            tan_half_vfov: (vfov_deg.to_radians() * 0.5).tan(),
            width,
            height,
            aperture: 0.0,
            focus_distance: direction.length(),
            shutter: (0.0, 1.0),
            model: Model::Perspective(Perspective::default()),
        })
    }

    /// The same camera with projection `model`, validated (the thin lens is perspective-only).
    pub fn with_model(mut self, model: Model) -> Result<Self, CameraError> {
        match &model {
            Model::Perspective(p) => {
                if !p.principal_offset.is_finite() {
                    return Err(err("principal_offset", "must be finite"));
                }
            }
            Model::Orthographic(o) => {
                if !(o.width.is_finite() && o.width > 0.0) {
                    return Err(err(
                        "model",
                        format!("Orthographic width must be finite and > 0, got {}", o.width),
                    ));
                }
            }
            Model::Equirectangular(e) => e.validate().map_err(|m| err("model", format!("Equirectangular {m}")))?,
            Model::Fisheye(f) => {
                if !(f.half_fov > 0.0 && f.half_fov <= std::f64::consts::PI) {
                    return Err(err(
                        "model",
                        format!(
                            "Fisheye fov_deg must lie in (0, 360], got {}",
                            2.0 * f.half_fov.to_degrees()
                        ),
                    ));
                }
            }
            Model::OpenCv(c) => c.validate().map_err(|m| err("model", format!("OpenCv {m}")))?,
        }
        self.model = model;
        self.check_lens_model()?;
        Ok(self)
    }

    pub(crate) fn check_lens_model(&self) -> Result<(), CameraError> {
        if self.aperture > 0.0 && !matches!(self.model, Model::Perspective(_)) {
            return Err(err(
                "aperture",
                format!(
                    "the thin lens is only modelled for Perspective, not {}",
                    self.model.name()
                ),
            ));
        }
        Ok(())
    }

    /// The same camera (model, lens, shutter, resolution) placed at `eye` looking along
    /// `direction` with `up`, validated as [`Camera::new`] does.
    pub fn with_pose(&self, eye: DVec3, direction: DVec3, up: DVec3) -> Result<Self, CameraError> {
        let posed = Self::new(
            eye,
            direction,
            up,
            2.0 * self.tan_half_vfov.atan().to_degrees(),
            self.width,
            self.height,
        )?;
        Ok(Self {
            eye: posed.eye,
            forward: posed.forward,
            right: posed.right,
            up: posed.up,
            ..self.clone()
        })
    }

    /// The same camera with the shutter open over frame times `[open, close]`.
    pub fn with_shutter(mut self, open: f64, close: f64) -> Result<Self, CameraError> {
        if !(open.is_finite() && close.is_finite() && open <= close) {
            return Err(err(
                "shutter",
                format!("needs finite open ≤ close, got ({open}, {close})"),
            ));
        }
        self.shutter = (open, close);
        Ok(self)
    }

    /// The same camera at another resolution, keeping the field of view: the perspective's
    /// vertical field, an orthographic frame's world width, the angular ranges of the panoramic
    /// models; a perspective's principal offset and OpenCV intrinsics scale with the image.
    pub fn with_resolution(&self, width: u32, height: u32) -> Result<Self, CameraError> {
        let mut camera = Self::new(
            self.eye,
            self.forward,
            self.up,
            2.0 * self.tan_half_vfov.atan().to_degrees(),
            width,
            height,
        )?;
        camera.aperture = self.aperture;
        camera.focus_distance = self.focus_distance;
        camera.shutter = self.shutter;
        let sx = f64::from(width) / f64::from(self.width);
        let sy = f64::from(height) / f64::from(self.height);
        camera.model = match self.model {
            Model::Perspective(p) => Model::Perspective(p.rescaled(sx, sy)),
            Model::OpenCv(c) => Model::OpenCv(c.rescaled(sx, sy)),
            other => other,
        };
        Ok(camera)
    }

    /// The vertical field of view (degrees) giving horizontal field `hfov_deg` at this aspect.
    #[must_use]
    pub fn vfov_from_hfov(hfov_deg: f64, width: u32, height: u32) -> f64 {
        2.0 * ((hfov_deg.to_radians() * 0.5).tan() * f64::from(height) / f64::from(width))
            .atan()
            .to_degrees()
    }

    /// `tan(θh/2) = tan(θv/2)·W/H`.
    #[must_use]
    pub fn tan_half_hfov(&self) -> f64 {
        self.tan_half_vfov * f64::from(self.width) / f64::from(self.height)
    }

    /// The unit-direction ray through image position `(x, y)` in pixels (`(i + ½, j + ½)` is the
    /// centre of pixel `(i, j)`), or why there is none.
    #[inline]
    pub fn ray_through(&self, x: f64, y: f64) -> Result<Ray, NoRay> {
        match &self.model {
            Model::Perspective(p) => Ok(p.ray(self, x, y)),
            Model::Orthographic(o) => Ok(o.ray(self, x, y)),
            Model::Equirectangular(e) => Ok(e.ray(self, x, y)),
            Model::Fisheye(f) => f.ray(self, x, y).ok_or(NoRay::OutsideField),
            Model::OpenCv(c) => c.ray(self, x, y).ok_or(NoRay::NotConverged),
        }
    }

    /// The ray through the centre of pixel `(i, j)`.
    #[inline]
    pub fn pixel_ray(&self, i: u32, j: u32) -> Result<Ray, NoRay> {
        self.ray_through(f64::from(i) + 0.5, f64::from(j) + 0.5)
    }

    /// The pixel rays of columns `x0 .. x0 + width`, row by row ([`PixelRays`]).
    #[must_use]
    pub fn pixel_rays(&self, x0: u32, width: usize) -> PixelRays<'_> {
        let screen_x = match &self.model {
            Model::Perspective(p) => (0..width)
                .map(|c| p.screen_x(self, f64::from(x0 + c as u32) + 0.5))
                .collect(),
            _ => Vec::new(),
        };
        PixelRays {
            camera: self,
            x0,
            screen_x,
        }
    }

    /// `a·right + b·up + c·forward` for camera-local `(a, b, c)`.
    #[inline]
    #[must_use]
    pub fn local_to_world(&self, local: DVec3) -> DVec3 {
        local.x * self.right + local.y * self.up + local.z * self.forward
    }

    /// Camera-local coordinates `(a, b, c)` of world point `p` (along `right`, `up`, `forward`,
    /// from the eye).
    #[inline]
    #[must_use]
    pub fn world_to_local(&self, p: DVec3) -> DVec3 {
        let d = p - self.eye;
        DVec3::new(d.dot(self.right), d.dot(self.up), d.dot(self.forward))
    }

    /// The image position where world point `p` is seen: the model's forward projection, the
    /// inverse of [`Camera::ray_through`] (`None` where the model sees nothing: behind a planar
    /// camera, at the eye). The position may lie outside the image.
    #[must_use]
    pub fn project(&self, p: DVec3) -> Option<DVec2> {
        let local = self.world_to_local(p);
        match &self.model {
            Model::Perspective(m) => m.project(self, local),
            Model::Orthographic(m) => Some(m.project(self, local)),
            Model::Equirectangular(m) => m.project(self, local),
            Model::Fisheye(m) => m.project(self, local),
            Model::OpenCv(m) => m.project(local),
        }
    }

    /// Planar depth of a world point: its distance along the view axis, `⟨p − eye, forward⟩`.
    #[inline]
    #[must_use]
    pub fn planar_depth(&self, p: DVec3) -> f64 {
        (p - self.eye).dot(self.forward)
    }

    /// Depth `Z` of a hit at `point`, ray distance `t`: planar where the model has a view axis,
    /// `t` otherwise (module table).
    #[inline]
    #[must_use]
    pub fn depth(&self, point: DVec3, t: f64) -> f64 {
        if self.model.planar_depth() {
            self.planar_depth(point)
        } else {
            t
        }
    }

    /// OpenCV intrinsics `K` (pixel centres at integers), for the models that have one: the
    /// pinhole ones, the orthographic (affine, no division by depth) and the fisheye
    /// (`cv2.fisheye`'s `K`); `None` for the equirectangular.
    #[must_use]
    pub fn intrinsics(&self) -> Option<DMat3> {
        match &self.model {
            Model::Perspective(m) => Some(m.intrinsics(self)),
            Model::Orthographic(m) => Some(m.intrinsics(self)),
            Model::Equirectangular(_) => None,
            Model::Fisheye(m) => Some(m.intrinsics(self)),
            Model::OpenCv(m) => Some(m.intrinsics()),
        }
    }

    /// World → camera in the OpenCV convention (`+x` right, `+y` down, `+z` forward): `(R, t)`
    /// with `x_cam = R·x_world + t`.
    #[must_use]
    pub fn opencv_extrinsics(&self) -> (DMat3, DVec3) {
        let rotation = DMat3::from_cols(self.right, -self.up, self.forward).transpose();
        (rotation, -(rotation * self.eye))
    }

    /// Camera → world in the OpenGL convention (`+x` right, `+y` up, looking along `−z`), the
    /// `transform_matrix` of NeRF's `transforms.json`.
    #[must_use]
    pub fn camera_to_world(&self) -> DMat4 {
        DMat4::from_cols(
            self.right.extend(0.0),
            self.up.extend(0.0),
            (-self.forward).extend(0.0),
            self.eye.extend(1.0),
        )
    }

    /// World → camera space (module docs: `+x` right, `+y` up, looking along `−z`).
    #[must_use]
    pub fn world_to_camera(&self) -> DMat4 {
        self.camera_to_world().inverse()
    }

    /// World → normalised device coordinates: `x, y ∈ [−1, 1]` across the image (left → right,
    /// bottom → top), `z ∈ [−1, 1]` between near plane `near` and far plane `far`, after the
    /// perspective divide (OpenGL convention). Only models with a linear projection have one:
    /// perspective, orthographic, and OpenCV (its undistorted pinhole, `K` alone); `None` for
    /// the panoramic models.
    #[must_use]
    pub fn world_to_ndc(&self, near: f64, far: f64) -> Option<DMat4> {
        let projection = match &self.model {
            Model::Perspective(m) => m.projection(self, near, far),
            Model::Orthographic(m) => m.projection(self, near, far),
            Model::OpenCv(m) => m.projection(self, near, far),
            Model::Equirectangular(_) | Model::Fisheye(_) => return None,
        };
        Some(projection * self.world_to_camera())
    }
}

/// The rays through the pixel centres of a run of columns ([`Camera::pixel_rays`]), the same as
/// [`Camera::pixel_ray`]'s bit for bit: for the perspective model, what a ray depends on of its
/// column (its image-plane coordinate, two divisions) is worked out once per column and what it
/// depends on of its row once per row ([`PixelRays::row`]), leaving the normalisation per pixel.
pub struct PixelRays<'a> {
    camera: &'a Camera,
    x0: u32,
    /// [`Perspective::screen_x`] of each column (empty for the other models).
    screen_x: Vec<f64>,
}

impl PixelRays<'_> {
    /// The first column.
    #[inline]
    #[must_use]
    pub fn x0(&self) -> u32 {
        self.x0
    }

    /// The rays of row `j`.
    #[inline]
    #[must_use]
    pub fn row(&self, j: u32) -> RowRays<'_> {
        let screen_y = match &self.camera.model {
            Model::Perspective(p) => p.screen_y(self.camera, f64::from(j) + 0.5),
            _ => 0.0,
        };
        RowRays {
            rays: self,
            j,
            screen_y,
            directions: &[],
            first_direction: 0,
        }
    }

    /// [`PixelRays::row`] with the directions of the columns `columns` worked out at once into
    /// `directions` (perspective model; the others', and other columns', per pixel): the same
    /// normalisation, bit for bit, run over the columns in vector lanes rather than one pixel's
    /// square root and division at a time on each ray's path to its intersection tests.
    #[must_use]
    pub fn row_with<'b>(&'b self, j: u32, columns: Range<usize>, directions: &'b mut Vec<DVec3>) -> RowRays<'b> {
        let row = self.row(j);
        directions.clear();
        let first = columns.start;
        if let Some(screen_x) = self.screen_x.get(columns) {
            directions.resize(screen_x.len(), DVec3::ZERO);
            zeroset_primitives::with_fma!(normalised_directions(
                camera: &Camera = self.camera,
                screen_x: &[f64] = screen_x,
                screen_y: f64 = row.screen_y,
                directions: &mut [DVec3] = &mut directions[..],
            ) -> ());
        }
        RowRays {
            directions: &directions[..],
            first_direction: first,
            ..row
        }
    }
}

/// [`Perspective::ray_at`]'s direction through `(screen_x[c], screen_y)` into `directions[c]`,
/// for every column `c`.
#[inline(always)]
fn normalised_directions(camera: &Camera, screen_x: &[f64], screen_y: f64, directions: &mut [DVec3]) {
    for (direction, &sx) in directions.iter_mut().zip(screen_x) {
        *direction = Perspective::ray_at(camera, sx, screen_y).dir;
    }
}

/// The rays of one row of [`PixelRays`].
pub struct RowRays<'a> {
    rays: &'a PixelRays<'a>,
    j: u32,
    /// [`Perspective::screen_y`] of the row (perspective model only).
    screen_y: f64,
    /// The directions of the columns from `first_direction` on, where worked out beforehand
    /// ([`PixelRays::row_with`]).
    directions: &'a [DVec3],
    first_direction: usize,
}

impl RowRays<'_> {
    /// [`Camera::pixel_ray`] of the pixel in column `x0 + column` of this row, written into
    /// `out` (left as it was where the pixel has no ray), one component at a time: the render
    /// loop's ray lives in one place, written here and read by the intersection tests, rather
    /// than being returned and copied. (Returned, it was copied in 16-byte pieces that straddle the writes that made it,
    /// which cannot be served from the store buffer: a store-forwarding stall on every pixel,
    /// about a sixth of the quadrics scene's Depth render.)
    #[inline(always)]
    pub fn ray_into(&self, column: usize, out: &mut Ray) -> Result<(), NoRay> {
        // a pinhole's ray: from the eye, along the direction worked out beforehand or now
        let dir = match self.directions.get(column.wrapping_sub(self.first_direction)) {
            Some(&direction) => direction,
            None => match self.rays.screen_x.get(column) {
                Some(&sx) => Perspective::ray_at(self.rays.camera, sx, self.screen_y).dir,
                None => {
                    *out = self.rays.camera.pixel_ray(self.rays.x0 + column as u32, self.j)?;
                    return Ok(());
                }
            },
        };
        let eye = self.rays.camera.eye;
        out.origin.x = eye.x;
        out.origin.y = eye.y;
        out.origin.z = eye.z;
        out.dir.x = dir.x;
        out.dir.y = dir.y;
        out.dir.z = dir.z;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The benchmark scenes' camera (shared with the other camera modules' tests).
    pub(super) fn camera() -> Camera {
        Camera::new(
            DVec3::new(0.0, 3.0, -9.0),
            DVec3::new(0.0, -2.2, 9.0),
            DVec3::Y,
            40.0,
            1280,
            720,
        )
        .unwrap()
    }

    #[test]
    fn centre_ray_is_forward_and_corners_match_fov() {
        let c = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 90.0, 2, 2).unwrap();
        // pixel (0,0) of a 2×2 image: x = −½·tan45·1, y = +½
        let r = c.pixel_ray(0, 0).unwrap();
        let expected = (DVec3::Z + 0.5 * DVec3::X + 0.5 * DVec3::Y).normalize(); // right = Z × Y = −X
        assert!((r.dir - expected).length() < 1e-15, "{r:?}");
        let even = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 60.0, 3, 3).unwrap();
        assert!((even.pixel_ray(1, 1).unwrap().dir - DVec3::Z).length() < 1e-15);
    }

    /// A run of columns' rays, row by row, are `pixel_ray`'s bit for bit: the perspective
    /// model (with a principal offset, whose screen coordinates are worked out once per column
    /// and row) and another model (traced by `pixel_ray` itself), from column 0 and from a crop's
    /// first column; with the directions of some columns worked out beforehand (`row_with`:
    /// all, a span, none, a span past the row's end) too.
    #[test]
    fn pixel_rays_equal_pixel_ray() {
        let mut directions = Vec::new();
        let mut offset = camera();
        offset.model = Model::Perspective(Perspective {
            principal_offset: DVec2::new(13.25, -7.5),
        });
        let mut ortho = camera();
        ortho.model = Model::Orthographic(Orthographic { width: 6.0 });
        for (name, c) in [("pinhole", camera()), ("offset", offset), ("orthographic", ortho)] {
            for (x0, width) in [(0u32, 1280usize), (517, 61)] {
                let rays = c.pixel_rays(x0, width);
                let spans = [
                    None,
                    Some(0..width),
                    Some(3..width / 2),
                    Some(5..5),
                    Some(width - 2..width + 9),
                ];
                for (j, span) in [0u32, 1, 359, 719]
                    .into_iter()
                    .flat_map(|j| spans.clone().map(|s| (j, s)))
                {
                    let row = match span {
                        None => rays.row(j),
                        Some(span) => rays.row_with(j, span, &mut directions),
                    };
                    for column in 0..width {
                        let expected = c.pixel_ray(x0 + column as u32, j).unwrap();
                        let mut got = Ray::new(DVec3::NAN, DVec3::NAN);
                        row.ray_into(column, &mut got).unwrap();
                        assert_eq!(
                            got.origin.to_array(),
                            expected.origin.to_array(),
                            "{name} ({column}, {j})"
                        );
                        assert_eq!(got.dir.to_array(), expected.dir.to_array(), "{name} ({column}, {j})");
                    }
                }
            }
        }
    }

    #[test]
    fn hfov_conversion_keeps_square_pixels() {
        let v = Camera::vfov_from_hfov(90.0, 1920, 1080);
        let c = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, v, 1920, 1080).unwrap();
        assert!((c.tan_half_hfov() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn impossible_cameras_are_errors() {
        assert_eq!(
            Camera::new(DVec3::ZERO, DVec3::Y, DVec3::Y, 40.0, 10, 10)
                .unwrap_err()
                .field,
            "up"
        );
        assert_eq!(
            Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 180.0, 10, 10)
                .unwrap_err()
                .field,
            "vfov_deg"
        );
        assert_eq!(
            Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 0.0, 10, 10)
                .unwrap_err()
                .field,
            "vfov_deg"
        );
        assert_eq!(
            Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Y, 40.0, 0, 10)
                .unwrap_err()
                .field,
            "width"
        );
        assert_eq!(
            Camera::new(DVec3::ZERO, DVec3::ZERO, DVec3::Y, 40.0, 1, 1)
                .unwrap_err()
                .field,
            "look_at"
        );
        assert_eq!(
            Camera::new(DVec3::NAN, DVec3::Z, DVec3::Y, 40.0, 1, 1)
                .unwrap_err()
                .field,
            "eye"
        );
    }

    #[test]
    fn camera_space_looks_down_negative_z() {
        let c = camera();
        let m = c.world_to_camera();
        let ahead = m.transform_point3(c.eye + 5.0 * c.forward);
        assert!((ahead - DVec3::new(0.0, 0.0, -5.0)).length() < 1e-12);
        let ndc = c
            .world_to_ndc(0.1, 100.0)
            .unwrap()
            .project_point3(c.eye + 5.0 * c.forward + 1.0 * c.right);
        assert!(ndc.x > 0.0 && ndc.y.abs() < 1e-12);
    }
}
