//! Ray batches in and answers out: the columns of a batch as `zeroset query` reads them, the
//! bodies of `cast_rays`, `test_occlusions`, `count_intersections` and `time_first_hits`, and
//! `rays_pinhole`. Every array they make is estimated first and reserved fallibly
//! ([`crate::guards`]): a batch too large for memory raises `MemoryError`.

use glam::{DMat3, DVec3};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use std::borrow::Cow;
use std::sync::atomic::{AtomicBool, Ordering};
use zeroset::camera::{Camera, Model, OpenCv};
use zeroset::primitives::offset::PointPrecision;
use zeroset::primitives::{Interval, Ray};
use zeroset::query::rays::{scene_magnitude, trace_columns, RangeConvention, RayColumns, RaySetup};
use zeroset::query::{trace_batch, QueryHit, QueryRay};

use crate::guards::{ensure_memory, error, try_vec, try_with_capacity};
use crate::hits::{self, HitArrays};
use crate::scene::{affine, PyScene};

/// `origin_precision` as `zeroset query --origin-precision` takes it (`f32`, `f64` or a bound).
pub fn parse_precision(text: Option<&str>, have_normals: bool) -> PyResult<Option<PointPrecision>> {
    match (text, have_normals) {
        (None, false) => Ok(None),
        (None, true) => Err(error(
            "normals are only used with origin_precision= f32, f64 or a bound",
        )),
        (Some(_), false) => Err(error("origin_precision needs the surface normals: pass normals=")),
        (Some(t), true) => t
            .parse::<PointPrecision>()
            .map(Some)
            .map_err(|m| error(format!("origin_precision: {m}"))),
    }
}

/// The columns of a ray batch as flat slices, borrowed from the arrays when they are
/// C-contiguous (the Python layer makes them so) and copied otherwise.
pub struct Columns<'a> {
    origins: Cow<'a, [f64]>,
    directions: Cow<'a, [f64]>,
    tmin: Cow<'a, [f64]>,
    tmax: Cow<'a, [f64]>,
    normals: Option<Cow<'a, [f64]>>,
}

impl<'a> Columns<'a> {
    pub fn new(
        origins: &'a PyReadonlyArray2<'_, f64>,
        directions: &'a PyReadonlyArray2<'_, f64>,
        tmin: &'a PyReadonlyArray1<'_, f64>,
        tmax: &'a PyReadonlyArray1<'_, f64>,
        normals: Option<&'a PyReadonlyArray2<'_, f64>>,
    ) -> PyResult<Self> {
        Ok(Self {
            origins: rows_of_three(origins, "origins")?,
            directions: rows_of_three(directions, "directions")?,
            tmin: flat(tmin, "tmin")?,
            tmax: flat(tmax, "tmax")?,
            normals: normals.map(|v| rows_of_three(v, "normals")).transpose()?,
        })
    }

    /// The columns as `zeroset query`'s ray columns (lengths checked).
    fn view(&self) -> PyResult<RayColumns<'_>> {
        RayColumns::new(
            &self.origins,
            &self.directions,
            &self.tmin,
            &self.tmax,
            self.normals.as_deref(),
        )
        .map_err(error)
    }
}

/// `zeroset query`'s ray setup: its range convention and, with a precision, spawned origins.
fn ray_setup(closed: bool, precision: Option<PointPrecision>, magnitude: f64) -> RaySetup {
    RaySetup {
        range: RangeConvention::closed_if(closed),
        origin_precision: precision,
        magnitude,
    }
}

/// The error of the first bad ray, as `zeroset query` words it.
fn bad_ray((index, message): (usize, String)) -> PyErr {
    error(format!("ray {index}: {message}"))
}

/// Every ray of the columns (range convention alone), built in parallel without the GIL, each by
/// `zeroset query`'s own [`zeroset::query::rays::ray_from_fields`], into a vector reserved
/// fallibly for them and for `answer_bytes` a ray of what `what` makes of them.
pub(crate) fn query_rays(
    py: Python<'_>,
    columns: &Columns<'_>,
    closed: bool,
    what: &str,
    answer_bytes: usize,
) -> PyResult<Vec<QueryRay>> {
    let view = columns.view()?;
    let n = view.len();
    let what = format!("{what} of {n} rays");
    let per_ray = std::mem::size_of::<QueryRay>() + answer_bytes;
    ensure_memory(&what, (n as u64).saturating_mul(per_ray as u64))?;
    let mut rays = try_with_capacity::<QueryRay>(n, &what)?;
    let setup = ray_setup(closed, None, 0.0);
    let failed = AtomicBool::new(false);
    py.detach(|| {
        // an indexed extend within the capacity reserved: written in place, nothing reallocated
        rays.par_extend((0..n).into_par_iter().map(|i| {
            view.ray(i, &setup).unwrap_or_else(|_| {
                failed.store(true, Ordering::Relaxed);
                QueryRay {
                    ray: Ray::new(DVec3::ZERO, DVec3::Z),
                    range: Interval::POSITIVE,
                }
            })
        }));
    });
    if failed.into_inner() {
        // the first bad ray by index, as `zeroset query` reports it
        let first = py.detach(|| {
            (0..n)
                .into_par_iter()
                .find_map_first(|i| view.ray(i, &setup).err().map(|message| (i, message)))
        });
        return Err(bad_ray(first.expect("a ray failed to build")));
    }
    Ok(rays)
}

/// A copy of `values` into a vector reserved fallibly (after the memory check).
fn copied<'a>(values: impl Iterator<Item = &'a f64>, len: usize, what: &str) -> PyResult<Vec<f64>> {
    let what = format!("copying {what} ({len} values, not contiguous)");
    ensure_memory(&what, (len as u64).saturating_mul(8))?;
    let mut out = try_with_capacity(len, &what)?;
    out.extend(values.copied());
    Ok(out)
}

/// The rows of an `(N, 3)` float64 array as one flat slice (borrowed when C-contiguous).
pub(crate) fn rows_of_three<'a>(array: &'a PyReadonlyArray2<'_, f64>, what: &str) -> PyResult<Cow<'a, [f64]>> {
    let shape = array.shape();
    if shape[1] != 3 {
        return Err(error(format!("{what}: expected shape (N, 3), got {shape:?}")));
    }
    Ok(match array.as_slice() {
        Ok(flat) => Cow::Borrowed(flat),
        Err(_) => Cow::Owned(copied(array.as_array().iter(), array.len(), what)?),
    })
}

/// A 1-D float64 array as a slice (borrowed when contiguous).
fn flat<'a>(array: &'a PyReadonlyArray1<'_, f64>, what: &str) -> PyResult<Cow<'a, [f64]>> {
    Ok(match array.as_slice() {
        Ok(flat) => Cow::Borrowed(flat),
        Err(_) => Cow::Owned(copied(array.as_array().iter(), array.len(), what)?),
    })
}

impl PyScene {
    /// `cast_rays` of the rays `columns` into arrays whose real fields are of type `F`: the
    /// fields `outputs` (all when `None`), the rays' range closed where `closed`, their origins
    /// moved off surfaces where a `precision` is given. The arrays are estimated first
    /// (`MemoryError` where they do not fit) and made fallibly.
    pub fn cast_rays_as<'py, F: hits::Real>(
        &self,
        py: Python<'py>,
        columns: &Columns<'_>,
        closed: bool,
        precision: Option<PointPrecision>,
        outputs: Option<&[String]>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let view = columns.view()?;
        let n = view.len();
        let per_ray = HitArrays::<F>::bytes_per_ray(outputs)?;
        ensure_memory(
            &format!("cast_rays of {n} rays"),
            (n as u64).saturating_mul(per_ray as u64),
        )?;
        let arrays = HitArrays::<F>::new(py, n, outputs)?;
        let request = arrays.request();
        let chunks = arrays.chunks(n)?;
        self.with(py, |state| {
            let scene = state.built();
            let magnitude = if precision.is_some() {
                scene_magnitude(scene)
            } else {
                0.0
            };
            trace_columns(scene, &view, &ray_setup(closed, precision, magnitude), request, chunks)
        })
        .map_err(bad_ray)?;
        arrays.into_dict(py)
    }

    /// The body of `time_first_hits`: `trace_batch` on the rays built beforehand, timed alone.
    pub fn time_first_hits_of(
        &self,
        py: Python<'_>,
        origins: &PyReadonlyArray2<'_, f64>,
        directions: &PyReadonlyArray2<'_, f64>,
    ) -> PyResult<f64> {
        let (tmin, tmax) = (
            PyArray1::from_vec(py, vec![0.0]),
            PyArray1::from_vec(py, vec![f64::INFINITY]),
        );
        let (tmin, tmax) = (tmin.readonly(), tmax.readonly());
        let columns = Columns::new(origins, directions, &tmin, &tmax, None)?;
        let rays = query_rays(py, &columns, false, "time_first_hits", std::mem::size_of::<QueryHit>())?;
        Ok(self.with(py, |state| {
            let scene = state.built();
            let start = std::time::Instant::now();
            let hits = trace_batch(scene, &rays);
            let seconds = start.elapsed().as_secs_f64();
            drop(hits);
            seconds
        }))
    }

    /// The body of `test_occlusions`.
    pub fn occlusions<'py>(
        &self,
        py: Python<'py>,
        columns: &Columns<'_>,
        closed: bool,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let rays = query_rays(py, columns, closed, "test_occlusions", 1)?;
        let mut blocked = try_with_capacity::<bool>(rays.len(), "test_occlusions: the answers")?;
        self.with(py, |state| {
            let scene = state.built();
            blocked.par_extend(rays.par_iter().map(|q| scene.occluded(&q.ray, q.range)));
        });
        Ok(PyArray1::from_vec(py, blocked))
    }

    /// The body of `count_intersections`.
    pub fn crossings<'py>(
        &self,
        py: Python<'py>,
        columns: &Columns<'_>,
        closed: bool,
    ) -> PyResult<Bound<'py, PyArray1<i64>>> {
        let rays = query_rays(py, columns, closed, "count_intersections", 8)?;
        let mut counts = try_with_capacity::<i64>(rays.len(), "count_intersections: the answers")?;
        self.with(py, |state| {
            let scene = state.built();
            counts.par_extend(rays.par_iter().map(|q| scene.count_crossings(&q.ray, q.range) as i64));
        });
        Ok(PyArray1::from_vec(py, counts))
    }
}

/// Flat origins and directions of a batch of rays.
type RayArrays<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// Pixel-centre rays of a calibrated OpenCV camera (see `zeroset.rays_pinhole`): the rays of
/// zeroset's `OpenCv` camera model placed by the extrinsics. The two arrays are estimated first
/// (`MemoryError` where they do not fit) and written in place.
#[pyfunction]
#[pyo3(signature = (intrinsics, extrinsics, width, height, distortion = [0.0; 5]))]
pub fn rays_pinhole<'py>(
    py: Python<'py>,
    intrinsics: [[f64; 3]; 3],
    extrinsics: [[f64; 4]; 4],
    width: u32,
    height: u32,
    distortion: [f64; 5],
) -> PyResult<RayArrays<'py>> {
    let [[fx, skew, cx], [zero, fy, cy], last] = intrinsics;
    if skew != 0.0 || zero != 0.0 || last != [0.0, 0.0, 1.0] {
        return Err(error(format!(
            "intrinsics: expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), got {intrinsics:?}"
        )));
    }
    let camera_from_world = affine(extrinsics, "extrinsics")?;
    let rotation = camera_from_world.matrix3;
    let orthonormal = (rotation * rotation.transpose() - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .all(|x| x.abs() < 1e-9);
    if !orthonormal || rotation.determinant() < 0.0 {
        return Err(error(
            "extrinsics: the 3×3 part must be a rotation (orthonormal, determinant +1)",
        ));
    }
    // OpenCV rows of R: right, down, forward; the camera sits at −Rᵀt
    let eye = -(rotation.transpose() * camera_from_world.translation);
    let camera = Camera::new(eye, rotation.row(2), -rotation.row(1), 90.0, width, height)
        .and_then(|c| {
            c.with_model(Model::OpenCv(OpenCv {
                fx,
                fy,
                cx,
                cy,
                distortion,
            }))
        })
        .map_err(|e| error(format!("rays_pinhole: {e}")))?;
    let pixels = u64::from(width) * u64::from(height);
    let what = format!("rays_pinhole of {width}x{height} pixels");
    // origins and directions, three float64 each a pixel
    ensure_memory(&what, pixels.saturating_mul(48))?;
    let n = usize::try_from(pixels).map_err(|_| error(format!("{what}: too many pixels")))?;
    let values = n
        .checked_mul(3)
        .ok_or_else(|| error(format!("{what}: too many pixels")))?;
    let mut origins = try_vec(values, 0.0, &what)?;
    let mut directions = try_vec(values, 0.0, &what)?;
    let columns = width.max(1) as usize;
    let missing: usize = py.detach(|| {
        origins
            .par_chunks_exact_mut(3)
            .zip(directions.par_chunks_exact_mut(3))
            .enumerate()
            .map(
                |(k, (o, d))| match camera.pixel_ray((k % columns) as u32, (k / columns) as u32) {
                    Ok(ray) => {
                        o.copy_from_slice(&ray.origin.to_array());
                        d.copy_from_slice(&ray.dir.to_array());
                        0
                    }
                    Err(_) => 1,
                },
            )
            .sum()
    });
    if missing > 0 {
        return Err(error(format!(
            "rays_pinhole: {missing} of {n} pixels have no ray (the distortion cannot be inverted there)"
        )));
    }
    Ok((PyArray1::from_vec(py, origins), PyArray1::from_vec(py, directions)))
}
