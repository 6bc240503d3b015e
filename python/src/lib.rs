//! `zeroset._zeroset`: the compiled core of the Python package.
//!
//! Everything here forwards to the `zeroset` crate — scene loading, the query path of
//! `zeroset query`, the renderer and the EXR writer — and only converts numpy arrays in and out.
//! The GIL is released while rays are traced (rayon runs inside). The pure-Python layer
//! (`zeroset/__init__.py`) shapes arrays, keeps the recipe a scene was built from (for pickling
//! to Dask workers) and documents the conventions.

use glam::{DAffine3, DMat3, DMat4, DVec3};
use numpy::ndarray::Array2;
use numpy::{
    IntoPyArray, PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadwriteArrayDyn,
    PyUntypedArrayMethods,
};
use pyo3::create_exception;
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use std::borrow::Cow;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};
use zeroset::aov::Aov;
use zeroset::camera::{Camera, Model, NoRay, OpenCv};
use zeroset::output::exr::{write_exr as write_frame, ExrHeader};
use zeroset::primitives::offset::PointPrecision;
use zeroset::primitives::{Mesh, Primitive, Ray, Transformed};
use zeroset::query::{trace_batch, QueryRay};
use zeroset::query::rays::{scene_magnitude, trace_columns, RangeConvention, RayColumns, RaySetup};
use zeroset::scene::registry::BuildContext;
use zeroset::render::{render_view_into, Frame, FrameLayout, RenderOptions, Window};
use zeroset::scene::{ron_options, Object, Scene, SceneDesc};

mod hits;
mod pages;
use pages::Plane;

use hits::HitArrays;

create_exception!(
    _zeroset,
    ZerosetError,
    PyValueError,
    "A scene, ray batch or argument zeroset cannot accept; the message names the place."
);

fn error(message: impl std::fmt::Display) -> PyErr {
    ZerosetError::new_err(message.to_string())
}

/// A loaded scene plus the objects added from Python since its hierarchy was last built.
struct State {
    scene: Scene,
    /// Objects added with `add_*` that the hierarchy does not hold yet.
    pending: Vec<Object>,
}

/// The Python object: the state behind a mutex, taken only with the GIL released (so a thread
/// waiting for it never blocks one that holds it), which lets Dask's threads share one scene.
#[pyclass(name = "_Scene", module = "zeroset._zeroset", frozen)]
struct PyScene {
    state: Mutex<State>,
}

impl PyScene {
    fn new(scene: Scene) -> Self {
        Self {
            state: Mutex::new(State {
                scene,
                pending: Vec::new(),
            }),
        }
    }

    /// Runs `f` on the state with the GIL released.
    fn with<T: Send>(&self, py: Python<'_>, f: impl FnOnce(&mut State) -> T + Send) -> T {
        py.detach(|| f(&mut self.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner)))
    }

    /// `cast_rays` of the rays `columns` into arrays whose real fields are of type `F`: the
    /// fields `outputs` (all when `None`), the rays' range closed where `closed`, their origins
    /// moved off surfaces where a `precision` is given.
    fn cast_rays_as<'py, F: hits::Real>(
        &self,
        py: Python<'py>,
        columns: &Columns<'_>,
        closed: bool,
        precision: Option<PointPrecision>,
        outputs: Option<&[String]>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let view = columns.view()?;
        let arrays = HitArrays::<F>::new(py, view.len(), outputs)?;
        let request = arrays.request();
        let chunks = arrays.chunks(view.len())?;
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
}

/// `world_from_local` from a 4×4 row-major affine matrix (last row `0 0 0 1`).
fn affine(m: [[f64; 4]; 4], what: &str) -> PyResult<DAffine3> {
    if m.iter().flatten().any(|x| !x.is_finite()) {
        return Err(error(format!("{what}: every entry must be finite")));
    }
    if m[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err(error(format!(
            "{what}: the last row must be 0 0 0 1 (an affine map), got {:?}",
            m[3]
        )));
    }
    let linear = DMat3::from_cols(
        DVec3::new(m[0][0], m[1][0], m[2][0]),
        DVec3::new(m[0][1], m[1][1], m[2][1]),
        DVec3::new(m[0][2], m[1][2], m[2][2]),
    );
    Ok(DAffine3::from_mat3_translation(
        linear,
        DVec3::new(m[0][3], m[1][3], m[2][3]),
    ))
}

impl State {
    /// The scene with every pending object in its hierarchy.
    fn built(&mut self) -> &Scene {
        if !self.pending.is_empty() {
            let placeholder = Scene::assemble(
                self.scene.camera.clone(),
                Vec::new(),
                Vec::new(),
                DVec3::ZERO,
                DVec3::ZERO,
                self.scene.outputs.clone(),
            );
            let old = std::mem::replace(&mut self.scene, placeholder);
            let mut objects = old.objects;
            objects.append(&mut self.pending);
            let mut scene = Scene::assemble(
                old.camera,
                objects,
                old.lights,
                old.ambient,
                old.background,
                old.outputs,
            );
            scene.sampling = old.sampling;
            scene.source = old.source;
            self.scene = scene;
        }
        &self.scene
    }

    fn push(
        &mut self,
        primitive: Arc<dyn Primitive>,
        matrix: Option<[[f64; 4]; 4]>,
        name: Option<Box<str>>,
        material: Arc<zeroset::scene::Material>,
    ) -> PyResult<usize> {
        let primitive: Arc<dyn Primitive> = match matrix {
            None => primitive,
            Some(m) => Arc::new(
                Transformed::new(primitive, affine(m, "transform")?)
                    .map_err(|e| error(format!("transform: {}", e.problem)))?,
            ),
        };
        self.pending.push(Object {
            name,
            primitive: primitive.into(),
            motion: None,
            material,
        });
        Ok(self.scene.objects.len() + self.pending.len() - 1)
    }
}

/// `origin_precision` as `zeroset query --origin-precision` takes it (`f32`, `f64` or a bound).
fn parse_precision(text: Option<&str>, have_normals: bool) -> PyResult<Option<PointPrecision>> {
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
struct Columns<'a> {
    origins: Cow<'a, [f64]>,
    directions: Cow<'a, [f64]>,
    tmin: Cow<'a, [f64]>,
    tmax: Cow<'a, [f64]>,
    normals: Option<Cow<'a, [f64]>>,
}

impl<'a> Columns<'a> {
    fn new(
        origins: &'a PyReadonlyArray2<'_, f64>,
        directions: &'a PyReadonlyArray2<'_, f64>,
        tmin: &'a PyReadonlyArray1<'_, f64>,
        tmax: &'a PyReadonlyArray1<'_, f64>,
        normals: Option<&'a PyReadonlyArray2<'_, f64>>,
    ) -> PyResult<Self> {
        Ok(Self {
            origins: rows_of_three(origins, "origins")?,
            directions: rows_of_three(directions, "directions")?,
            tmin: flat(tmin),
            tmax: flat(tmax),
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
/// `zeroset query`'s own [`zeroset::query::rays::ray_from_fields`].
fn query_rays(py: Python<'_>, columns: &Columns<'_>, closed: bool) -> PyResult<Vec<QueryRay>> {
    let view = columns.view()?;
    py.detach(|| view.rays(&ray_setup(closed, None, 0.0))).map_err(bad_ray)
}

/// The rows of an `(N, 3)` float64 array as one flat slice (borrowed when C-contiguous).
fn rows_of_three<'a>(array: &'a PyReadonlyArray2<'_, f64>, what: &str) -> PyResult<Cow<'a, [f64]>> {
    let shape = array.shape();
    if shape[1] != 3 {
        return Err(error(format!("{what}: expected shape (N, 3), got {shape:?}")));
    }
    Ok(match array.as_slice() {
        Ok(flat) => Cow::Borrowed(flat),
        Err(_) => Cow::Owned(array.as_array().iter().copied().collect()),
    })
}

/// A 1-D float64 array as a slice (borrowed when contiguous).
fn flat<'a>(array: &'a PyReadonlyArray1<'_, f64>) -> Cow<'a, [f64]> {
    match array.as_slice() {
        Ok(flat) => Cow::Borrowed(flat),
        Err(_) => Cow::Owned(array.as_array().iter().copied().collect()),
    }
}

fn parse_aovs(names: Option<Vec<String>>, scene: &Scene) -> PyResult<Vec<Aov>> {
    match names {
        None => Ok(scene.outputs.aovs.clone()),
        Some(names) => Aov::parse_list(&names).map_err(|m| error(format!("aovs: {m}"))),
    }
}

/// The layout of a render of `window` (its AOVs, in the order their samples interleave).
fn window_layout(camera: &Camera, options: &RenderOptions, window: Window) -> FrameLayout {
    FrameLayout::new(
        camera,
        &RenderOptions {
            crop: Some(window),
            ..options.clone()
        },
    )
}

/// The requested AOVs of `window`, one plane per AOV (pixels row-major, channels interleaved
/// within the AOV), written in place ([`render_rows_into`]) in memory numpy then owns
/// ([`Plane`]: pooled mappings for large ones, so a loop of renders of one size faults no page
/// in). Crops are exact, so the planes equal a single render of the window bit for bit.
fn render_planes(scene: &Scene, camera: &Camera, options: &RenderOptions, window: Window) -> (Vec<Aov>, Vec<Plane>) {
    let (w, h) = (window.width() as usize, window.height() as usize);
    let aovs = window_layout(camera, options, window).aovs;
    let mut planes: Vec<Plane> = aovs.iter().map(|a| Plane::new(w * h * a.channels().len())).collect();
    let mut rows: Vec<Option<Vec<&mut [f32]>>> = planes
        .iter_mut()
        .zip(&aovs)
        .map(|(plane, aov)| {
            Some(
                plane
                    .as_mut_slice()
                    .chunks_exact_mut((w * aov.channels().len()).max(1))
                    .collect(),
            )
        })
        .collect();
    render_rows_into(scene, camera, options, window, &mut rows);
    (aovs, planes)
}

/// Renders `window` into `rows`: per AOV of its layout ([`window_layout`], in that order), the
/// window's rows, each `width × channels` samples (channels interleaved), or `None` for an AOV
/// the caller does not keep. The window is rendered in bands of about a million pixels into one
/// interleaved buffer (reused from band to band) and gathered from it into the rows: the peak
/// memory is the rows plus one band.
fn render_rows_into(
    scene: &Scene,
    camera: &Camera,
    options: &RenderOptions,
    window: Window,
    rows: &mut [Option<Vec<&mut [f32]>>],
) {
    let w = window.width() as usize;
    let h = window.height() as usize;
    let band_rows = ((1usize << 20) / w.max(1)).clamp(1, h.max(1)) as u32;
    let layout = window_layout(camera, options, window);
    let stride = layout.channel_count();
    // pooled like the planes: a Dask worker renders tile after tile of one size
    let mut band_buffer = Plane::new(w * band_rows as usize * stride);
    let band_samples = band_buffer.as_mut_slice();
    let mut y0 = window.y0;
    while y0 < window.y1 {
        let y1 = (y0 + band_rows).min(window.y1);
        let band = RenderOptions {
            crop: Some(Window { y0, y1, ..window }),
            ..options.clone()
        };
        let samples = &mut band_samples[..w * (y1 - y0) as usize * stride];
        render_view_into(scene, camera, &band, samples);
        let first_row = (y0 - window.y0) as usize;
        let mut offset = 0;
        for (aov, rows) in layout.aovs.iter().zip(rows.iter_mut()) {
            let c = aov.channels().len();
            if let Some(rows) = rows {
                let to = &mut rows[first_row..first_row + (y1 - y0) as usize];
                match c {
                    1 => gather::<1>(to, samples, w, stride, offset),
                    2 => gather::<2>(to, samples, w, stride, offset),
                    3 => gather::<3>(to, samples, w, stride, offset),
                    4 => gather::<4>(to, samples, w, stride, offset),
                    _ => {
                        for (to, from) in to.iter_mut().zip(samples.chunks_exact(w * stride)) {
                            for (to, pixel) in to.chunks_exact_mut(c).zip(from.chunks_exact(stride)) {
                                to.copy_from_slice(&pixel[offset..offset + c]);
                            }
                        }
                    }
                }
            }
            offset += c;
        }
        y0 = y1;
    }
}

/// Writes into each row of `rows` the `C` channels from `offset` of every pixel of the matching
/// row of `samples` (`width` pixels a row, interleaved, `stride` samples a pixel), rows in
/// parallel (at least 4096 pixels a task): copies of a size known when compiled, where a slice
/// of run-time length would call `memmove` for each pixel.
fn gather<const C: usize>(rows: &mut [&mut [f32]], samples: &[f32], width: usize, stride: usize, offset: usize) {
    rows.par_iter_mut()
        .zip(samples.par_chunks((width * stride).max(1)))
        .with_min_len(4096usize.div_ceil(width.max(1)))
        .for_each(|(to, from)| {
            for (to, pixel) in to.chunks_exact_mut(C).zip(from.chunks_exact(stride)) {
                let from: &[f32; C] = pixel[offset..offset + C].try_into().expect("C channels");
                to.copy_from_slice(from);
            }
        });
}

/// AOV planes as `(H, W)` or `(H, W, C)` float32 arrays keyed by AOV name (no copy).
fn plane_arrays<'py>(
    py: Python<'py>,
    (w, h): (usize, usize),
    aovs: Vec<Aov>,
    planes: Vec<Plane>,
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    for (aov, plane) in aovs.into_iter().zip(planes) {
        let c = aov.channels().len();
        let name = format!("{aov:?}");
        if c == 1 {
            out.set_item(name, plane.into_array(py, (h, w))?)?;
        } else {
            out.set_item(name, plane.into_array(py, (h, w, c))?)?;
        }
    }
    Ok(out)
}

#[pymethods]
impl PyScene {
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let scene = py.detach(|| Scene::load(&path)).map_err(error)?;
        Ok(Self::new(scene))
    }

    #[staticmethod]
    #[pyo3(signature = (text, path = "<string>".to_string(), base_dir = None))]
    fn from_ron(py: Python<'_>, text: String, path: String, base_dir: Option<PathBuf>) -> PyResult<Self> {
        let context = BuildContext::new(base_dir.unwrap_or_default());
        let scene = py
            .detach(|| Scene::from_ron_in(&text, &path, &context))
            .map_err(error)?;
        Ok(Self::new(scene))
    }

    /// Adds one object written as a scene file's object entry, e.g.
    /// `(shape: Sphere(radius: 1), name: "ball")`; returns its object id.
    #[pyo3(signature = (object_ron, matrix = None, base_dir = None))]
    fn add_object(
        &self,
        py: Python<'_>,
        object_ron: &str,
        matrix: Option<[[f64; 4]; 4]>,
        base_dir: Option<PathBuf>,
    ) -> PyResult<usize> {
        const PREFIX: &str = "Scene(camera: (eye: (0, 0, 1)), objects: [";
        let text = format!("{PREFIX}{object_ron}])");
        let mut desc: SceneDesc = ron_options().from_str(&text).map_err(|e| {
            let mut column = e.span.start.col;
            if e.span.start.line == 1 {
                column = column.saturating_sub(PREFIX.chars().count());
            }
            error(format!("<object>:{}:{column}: {}", e.span.start.line, e.code))
        })?;
        let context = BuildContext::new(base_dir.unwrap_or_default());
        self.with(py, |state| {
            desc.outputs = state.scene.outputs.clone();
            let index = state.scene.objects.len() + state.pending.len();
            let built = Scene::from_desc(desc, &context).map_err(|(location, message)| {
                let location = location.replacen("objects[0]", &format!("objects[{index}]"), 1);
                error(format!("<object>: {location}: {message}"))
            })?;
            let object = built
                .objects
                .into_iter()
                .next()
                .ok_or_else(|| error("no object given"))?;
            state.push(object.primitive.into_shared(), matrix, object.name, object.material)
        })
    }

    /// Adds a triangle mesh from `(N, 3)` float32 vertices and `(M, 3)` uint32 triangles.
    #[pyo3(signature = (vertices, triangles, matrix = None, name = None))]
    fn add_mesh(
        &self,
        py: Python<'_>,
        vertices: PyReadonlyArray2<'_, f32>,
        triangles: PyReadonlyArray2<'_, u32>,
        matrix: Option<[[f64; 4]; 4]>,
        name: Option<String>,
    ) -> PyResult<usize> {
        if vertices.shape()[1] != 3 || triangles.shape()[1] != 3 {
            return Err(error(format!(
                "add_mesh: expected vertices (N, 3) and triangles (M, 3), got {:?} and {:?}",
                vertices.shape(),
                triangles.shape()
            )));
        }
        let v: Vec<[f32; 3]> = vertices
            .as_array()
            .rows()
            .into_iter()
            .map(|r| [r[0], r[1], r[2]])
            .collect();
        let t: Vec<[u32; 3]> = triangles
            .as_array()
            .rows()
            .into_iter()
            .map(|r| [r[0], r[1], r[2]])
            .collect();
        self.with(py, |state| {
            let mesh =
                Mesh::new(v, t, None).map_err(|e| error(format!("add_mesh: field `{}`: {}", e.field, e.problem)))?;
            state.push(Arc::new(mesh), matrix, name.map(String::into_boxed_str), Arc::default())
        })
    }

    /// Number of objects.
    fn object_count(&self, py: Python<'_>) -> usize {
        self.with(py, |state| state.scene.objects.len() + state.pending.len())
    }

    /// Object names (`None` where unnamed), by object id.
    fn object_names(&self, py: Python<'_>) -> Vec<Option<String>> {
        self.with(py, |state| {
            state
                .scene
                .objects
                .iter()
                .chain(&state.pending)
                .map(|o| o.name.as_deref().map(str::to_string))
                .collect()
        })
    }

    /// First hits: the arrays of `zeroset query` (see `zeroset.Scene.cast_rays`), only the
    /// fields named in `outputs` (all when `None`; see `hits::FIELDS`), the real ones float32
    /// where `float32` (else float64).
    ///
    /// One parallel pass without the GIL: each chunk of rays is built from the arrays, traced by
    /// `trace_batch` and written straight into the numpy arrays returned (see `hits`).
    #[pyo3(signature = (origins, directions, tmin, tmax, closed = false, origin_precision = None, normals = None, outputs = None, float32 = false))]
    #[allow(clippy::too_many_arguments)]
    fn cast_rays<'py>(
        &self,
        py: Python<'py>,
        origins: PyReadonlyArray2<'py, f64>,
        directions: PyReadonlyArray2<'py, f64>,
        tmin: PyReadonlyArray1<'py, f64>,
        tmax: PyReadonlyArray1<'py, f64>,
        closed: bool,
        origin_precision: Option<String>,
        normals: Option<PyReadonlyArray2<'py, f64>>,
        outputs: Option<Vec<String>>,
        float32: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let precision = parse_precision(origin_precision.as_deref(), normals.is_some())?;
        let columns = Columns::new(&origins, &directions, &tmin, &tmax, normals.as_ref())?;
        if float32 {
            self.cast_rays_as::<f32>(py, &columns, closed, precision, outputs.as_deref())
        } else {
            self.cast_rays_as::<f64>(py, &columns, closed, precision, outputs.as_deref())
        }
    }

    /// Seconds the Rust API alone takes on these rays: `zeroset::query::trace_batch` on the whole
    /// batch, its rays already built (a `Vec<QueryRay>`), timed around that call in Rust — the
    /// reference of the benchmark's Python-overhead column.
    fn time_first_hits(
        &self,
        py: Python<'_>,
        origins: PyReadonlyArray2<'_, f64>,
        directions: PyReadonlyArray2<'_, f64>,
    ) -> PyResult<f64> {
        let (tmin, tmax) = (
            PyArray1::from_vec(py, vec![0.0]),
            PyArray1::from_vec(py, vec![f64::INFINITY]),
        );
        let (tmin, tmax) = (tmin.readonly(), tmax.readonly());
        let columns = Columns::new(&origins, &directions, &tmin, &tmax, None)?;
        let rays = query_rays(py, &columns, false)?;
        Ok(self.with(py, |state| {
            let scene = state.built();
            let start = std::time::Instant::now();
            let hits = trace_batch(scene, &rays);
            let seconds = start.elapsed().as_secs_f64();
            drop(hits);
            seconds
        }))
    }

    /// Whether anything is hit within each ray's range.
    #[pyo3(signature = (origins, directions, tmin, tmax, closed = false))]
    fn test_occlusions<'py>(
        &self,
        py: Python<'py>,
        origins: PyReadonlyArray2<'py, f64>,
        directions: PyReadonlyArray2<'py, f64>,
        tmin: PyReadonlyArray1<'py, f64>,
        tmax: PyReadonlyArray1<'py, f64>,
        closed: bool,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let rays = query_rays(py, &Columns::new(&origins, &directions, &tmin, &tmax, None)?, closed)?;
        let blocked: Vec<bool> = self.with(py, |state| {
            let scene = state.built();
            rays.par_iter().map(|q| scene.occluded(&q.ray, q.range)).collect()
        });
        Ok(PyArray1::from_vec(py, blocked))
    }

    /// Number of distinct surface crossings within each ray's range (odd: the origin is inside a
    /// closed surface). Crossings at the same `t` (a ray through a shared mesh edge) count once.
    #[pyo3(signature = (origins, directions, tmin, tmax, closed = false))]
    fn count_intersections<'py>(
        &self,
        py: Python<'py>,
        origins: PyReadonlyArray2<'py, f64>,
        directions: PyReadonlyArray2<'py, f64>,
        tmin: PyReadonlyArray1<'py, f64>,
        tmax: PyReadonlyArray1<'py, f64>,
        closed: bool,
    ) -> PyResult<Bound<'py, PyArray1<i64>>> {
        let rays = query_rays(py, &Columns::new(&origins, &directions, &tmin, &tmax, None)?, closed)?;
        let counts: Vec<i64> = self.with(py, |state| {
            let scene = state.built();
            rays.par_iter()
                .map(|q| {
                    let mut range = q.range;
                    let mut count = 0;
                    while let Some((_, hit)) = scene.intersect(&q.ray, range) {
                        count += 1;
                        if hit.t >= range.max {
                            break;
                        }
                        range.min = hit.t.next_up();
                    }
                    count
                })
                .collect()
        });
        Ok(PyArray1::from_vec(py, counts))
    }

    /// Renders the scene's camera (see `zeroset.Scene.render`), on `threads` threads (default:
    /// rayon's global pool, one thread per core or `RAYON_NUM_THREADS`).
    /// With `out` (`{AOV name: writable float32 array}`, each shaped as the render returns that
    /// AOV, every row contiguous), those AOVs are written into the given arrays (views into a
    /// larger array too) and `out` is returned; the render's other AOVs are not kept.
    #[pyo3(signature = (aovs = None, width = None, height = None, crop = None, spp = None, depth_miss = f32::INFINITY, view = None, background = false, threads = None, out = None))]
    #[allow(clippy::too_many_arguments)]
    fn render<'py>(
        &self,
        py: Python<'py>,
        aovs: Option<Vec<String>>,
        width: Option<u32>,
        height: Option<u32>,
        crop: Option<(u32, u32, u32, u32)>,
        spp: Option<u32>,
        depth_miss: f32,
        view: Option<([f64; 3], [f64; 3], [f64; 3])>,
        background: bool,
        threads: Option<usize>,
        out: Option<Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let pool = threads.map(thread_pool).transpose()?;
        if depth_miss.is_nan() {
            return Err(error("depth_miss must be a number or ±inf, not NaN"));
        }
        if spp == Some(0) {
            return Err(error("spp must be at least 1"));
        }
        let mut borrowed = match &out {
            Some(out) => Some(borrow_out_arrays(out)?),
            None => None,
        };
        let mut given = match &mut borrowed {
            Some(borrowed) => Some(out_rows(borrowed)?),
            None => None,
        };
        let frame = self.with(py, |state| -> PyResult<Option<RenderedPlanes>> {
            state.built();
            let scene = &mut state.scene;
            let aovs = parse_aovs(aovs, scene)?;
            let base = match view {
                None => scene.camera.clone(),
                Some((eye, look_at, up)) => {
                    let eye = DVec3::from_array(eye);
                    scene
                        .camera
                        .with_pose(eye, DVec3::from_array(look_at) - eye, DVec3::from_array(up))
                        .map_err(|e| error(format!("view: {e}")))?
                }
            };
            let camera = base
                .with_resolution(
                    width.unwrap_or(scene.camera.width),
                    height.unwrap_or(scene.camera.height),
                )
                .map_err(|e| error(format!("width/height: {e}")))?;
            let window = match crop {
                None => Window {
                    x0: 0,
                    y0: 0,
                    x1: camera.width,
                    y1: camera.height,
                },
                Some((x0, y0, x1, y1)) => Window { x0, y0, x1, y1 }
                    .within(camera.width, camera.height)
                    .map_err(|m| error(format!("crop ({x0}, {y0}, {x1}, {y1}): {m}")))?,
            };
            let options = RenderOptions {
                aovs,
                crop: None,
                depth_miss,
                progress: false,
                background,
            };
            let mut targets = match given.take() {
                Some(given) => Some(out_targets(
                    given,
                    &window_layout(&camera, &options, window).aovs,
                    window,
                )?),
                None => None,
            };
            // the scene's own spp comes back after this render (the lock is held)
            let saved_spp = scene.sampling.spp;
            if let Some(spp) = spp {
                scene.sampling.spp = spp;
            }
            let scene = &*scene;
            let mut render = || match &mut targets {
                Some(targets) => {
                    render_rows_into(scene, &camera, &options, window, targets);
                    None
                }
                None => Some(render_planes(scene, &camera, &options, window)),
            };
            let planes = match &pool {
                Some(pool) => pool.install(render),
                None => render(),
            };
            state.scene.sampling.spp = saved_spp;
            Ok(planes.map(|(aovs, planes)| ((window.width() as usize, window.height() as usize), aovs, planes)))
        })?;
        drop(borrowed);
        match (frame, out) {
            (Some(frame), _) => plane_arrays(py, frame.0, frame.1, frame.2),
            (None, Some(out)) => Ok(out),
            (None, None) => unreachable!("a render without `out` returns its planes"),
        }
    }

    /// The camera: pose, field of view, resolution and its matrices (see `zeroset.Camera`).
    fn camera<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.with(py, |state| state.scene.camera.clone());
        let out = PyDict::new(py);
        out.set_item("eye", c.eye.to_array())?;
        out.set_item("forward", c.forward.to_array())?;
        out.set_item("right", c.right.to_array())?;
        out.set_item("up", c.up.to_array())?;
        out.set_item("tan_half_vfov", c.tan_half_vfov)?;
        out.set_item("width", c.width)?;
        out.set_item("height", c.height)?;
        out.set_item("world_to_camera_gl", rows(&c.world_to_camera()))?;
        out.set_item("model", c.model.name())?;
        let distortion = match &c.model {
            Model::OpenCv(m) => m.distortion,
            _ => [0.0; 5],
        };
        out.set_item("distortion", distortion)?;
        // OpenCV: +x right, +y down, +z forward; pixel (u, v)'s centre at the integer point (u, v)
        out.set_item("intrinsics", c.intrinsics().map(|k| rows3(&k)))?;
        let (r, t) = c.opencv_extrinsics();
        let mut w2c = DMat4::from_mat3(r);
        w2c.w_axis = t.extend(1.0);
        out.set_item("world_to_camera", rows(&w2c))?;
        Ok(out)
    }
}

/// A rayon pool of `threads` threads, made on first use and kept for later calls (a Dask worker
/// renders tile after tile with the same count).
fn thread_pool(threads: usize) -> PyResult<Arc<rayon::ThreadPool>> {
    static POOLS: OnceLock<Mutex<HashMap<usize, Arc<rayon::ThreadPool>>>> = OnceLock::new();
    if threads == 0 {
        return Err(error("threads must be at least 1"));
    }
    let mut pools = POOLS
        .get_or_init(Mutex::default)
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some(pool) = pools.get(&threads) {
        return Ok(Arc::clone(pool));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(move |i| format!("zeroset-{threads}-{i}"))
        .build()
        .map_err(|e| error(format!("threads: {e}")))?;
    Ok(Arc::clone(pools.entry(threads).or_insert(Arc::new(pool))))
}

/// The arrays of a render's `out` dict, borrowed for writing: `(AOV name, array)`.
type OutArrays<'py> = Vec<(String, PyReadwriteArrayDyn<'py, f32>)>;

/// The arrays of `out` borrowed for writing (an error names the entry that is not a writable
/// float32 array, or that overlaps another).
fn borrow_out_arrays<'py>(out: &Bound<'py, PyDict>) -> PyResult<OutArrays<'py>> {
    out.iter()
        .map(|(key, value)| {
            let name: String = key
                .extract()
                .map_err(|_| error(format!("out: keys must be AOV names, got {key}")))?;
            let array = value
                .cast::<PyArrayDyn<f32>>()
                .map_err(|_| error(format!("out[{name:?}]: a float32 numpy array expected")))?;
            let array = array.try_readwrite().map_err(|e| {
                error(format!(
                    "out[{name:?}]: cannot be written ({e}: read-only, or it overlaps another array in use)"
                ))
            })?;
            Ok((name, array))
        })
        .collect()
}

/// One `out` array as the render writes it: `(AOV name, shape, rows)`, each row the contiguous
/// samples of one image row.
type OutRows<'a> = (String, Vec<usize>, Vec<&'a mut [f32]>);

/// The rows of every borrowed `out` array (an error names an array whose rows are not
/// contiguous, or whose shape is not an image's).
fn out_rows<'a>(arrays: &'a mut OutArrays<'_>) -> PyResult<Vec<OutRows<'a>>> {
    arrays
        .iter_mut()
        .map(|(name, array)| {
            let view = array.as_array_mut();
            let shape = view.shape().to_vec();
            if !(2..=3).contains(&shape.len()) {
                return Err(error(format!(
                    "out[{name:?}]: shape {shape:?} is not (H, W) or (H, W, C)"
                )));
            }
            let rows = view
                .into_outer_iter_mut()
                .map(|row| row.into_slice())
                .collect::<Option<Vec<_>>>()
                .ok_or_else(|| {
                    error(format!(
                        "out[{name:?}]: each row must be contiguous (C order within a row)"
                    ))
                })?;
            Ok((name.clone(), shape, rows))
        })
        .collect()
}

/// `given` matched to the AOVs of a render of `window` ([`window_layout`]'s order): each AOV's
/// rows, or `None` where `out` has no array for it. An error names an array for an AOV the
/// render does not make, or of the wrong shape.
fn out_targets<'a>(given: Vec<OutRows<'a>>, aovs: &[Aov], window: Window) -> PyResult<Vec<Option<Vec<&'a mut [f32]>>>> {
    let (w, h) = (window.width() as usize, window.height() as usize);
    let mut targets: Vec<Option<Vec<&'a mut [f32]>>> = aovs.iter().map(|_| None).collect();
    for (name, shape, rows) in given {
        let Some(k) = aovs.iter().position(|a| format!("{a:?}") == name) else {
            let made: Vec<String> = aovs.iter().map(|a| format!("{a:?}")).collect();
            return Err(error(format!(
                "out[{name:?}]: not an AOV of this render (it makes {})",
                made.join(", ")
            )));
        };
        let c = aovs[k].channels().len();
        let want = if c == 1 { vec![h, w] } else { vec![h, w, c] };
        if shape != want {
            return Err(error(format!(
                "out[{name:?}]: shape {shape:?}, the render's is {want:?}"
            )));
        }
        targets[k] = Some(rows);
    }
    Ok(targets)
}

/// A rendered window: `(width, height)`, its AOVs and one plane per AOV.
type RenderedPlanes = ((usize, usize), Vec<Aov>, Vec<Plane>);

/// Flat origins and directions of a batch of rays.
type RayArrays<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// An AOV plane as `write_exr` receives it: name, flat data, `(height, width, channels)`.
type NamedPlane<'py> = (String, PyReadonlyArray1<'py, f32>, (usize, usize, usize));

/// A 3×3 matrix as row-major nested arrays.
fn rows3(m: &DMat3) -> [[f64; 3]; 3] {
    let t = m.transpose();
    [t.x_axis.to_array(), t.y_axis.to_array(), t.z_axis.to_array()]
}

/// A 4×4 matrix as row-major nested arrays.
fn rows(m: &DMat4) -> [[f64; 4]; 4] {
    let t = m.transpose();
    [
        t.x_axis.to_array(),
        t.y_axis.to_array(),
        t.z_axis.to_array(),
        t.w_axis.to_array(),
    ]
}

/// Pixel-centre rays of a calibrated OpenCV camera (see `zeroset.rays_pinhole`): the rays of
/// zeroset's `OpenCv` camera model placed by the extrinsics.
#[pyfunction]
#[pyo3(signature = (intrinsics, extrinsics, width, height, distortion = [0.0; 5]))]
fn rays_pinhole<'py>(
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
    let n = width as usize * height as usize;
    let rays: Vec<Result<Ray, NoRay>> = py.detach(|| {
        (0..n)
            .into_par_iter()
            .map(|k| camera.pixel_ray((k % width as usize) as u32, (k / width as usize) as u32))
            .collect()
    });
    let missing = rays.iter().filter(|r| r.is_err()).count();
    if missing > 0 {
        return Err(error(format!(
            "rays_pinhole: {missing} of {n} pixels have no ray (the distortion cannot be inverted there)"
        )));
    }
    let mut origins = Vec::with_capacity(3 * n);
    let mut directions = Vec::with_capacity(3 * n);
    for ray in rays.into_iter().flatten() {
        origins.extend_from_slice(&ray.origin.to_array());
        directions.extend_from_slice(&ray.dir.to_array());
    }
    Ok((PyArray1::from_vec(py, origins), PyArray1::from_vec(py, directions)))
}

/// Writes AOV arrays (keyed by AOV name, `(H, W)` or `(H, W, C)` float32) as zeroset's EXR.
#[pyfunction]
#[pyo3(signature = (path, arrays, world_to_camera = None, scene_file = String::new(), depth_miss = f32::INFINITY))]
fn write_exr(
    py: Python<'_>,
    path: PathBuf,
    arrays: Vec<NamedPlane<'_>>,
    world_to_camera: Option<[[f64; 4]; 4]>,
    scene_file: String,
    depth_miss: f32,
) -> PyResult<()> {
    use clap::ValueEnum;
    let Some((_, _, (h, w, _))) = arrays.first() else {
        return Err(error("write_exr: no arrays given"));
    };
    let (h, w) = (*h, *w);
    let mut aovs = Vec::new();
    let mut planes = Vec::new();
    for (name, data, (ah, aw, c)) in &arrays {
        let aov = Aov::from_str(name, true).map_err(|_| error(format!("write_exr: `{name}` is not an AOV name")))?;
        if (*ah, *aw) != (h, w) || *c != aov.channels().len() {
            return Err(error(format!(
                "write_exr: `{name}` has shape ({ah}, {aw}, {c}); expected ({h}, {w}, {})",
                aov.channels().len()
            )));
        }
        aovs.push(aov);
        planes.push(data.to_vec()?);
    }
    let stride: usize = aovs.iter().map(|a| a.channels().len()).sum();
    let mut samples = Vec::with_capacity(w * h * stride);
    for p in 0..w * h {
        for (aov, plane) in aovs.iter().zip(&planes) {
            let c = aov.channels().len();
            samples.extend_from_slice(&plane[p * c..p * c + c]);
        }
    }
    let frame = Frame {
        width: w as u32,
        height: h as u32,
        window: Window {
            x0: 0,
            y0: 0,
            x1: w as u32,
            y1: h as u32,
        },
        aovs,
        samples,
        elapsed: std::time::Duration::ZERO,
        spp: 1,
        outside_field: 0,
        not_converged: 0,
    };
    let w2c = match world_to_camera {
        None => DMat4::IDENTITY,
        Some(m) => DMat4::from_cols_array_2d(&m).transpose(),
    };
    let header = ExrHeader {
        world_to_camera: w2c,
        world_to_ndc: None,
        scene_file,
        depth_miss,
        camera_attributes: Vec::new(),
    };
    py.detach(|| write_frame(&frame, &path, &header))
        .map_err(|e| PyOSError::new_err(format!("writing {}: {e}", path.display())))
}

/// Reads every channel of an EXR's first layer: `(channels, header)` where `channels` maps channel
/// names to `(H, W)` float32 arrays over the data window.
#[pyfunction]
fn read_exr<'py>(py: Python<'py>, path: PathBuf) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
    use exr::prelude::*;
    let image = py
        .detach(|| read_all_flat_layers_from_file(&path))
        .map_err(|e| PyOSError::new_err(format!("reading {}: {e}", Path::new(&path).display())))?;
    let layer = image
        .layer_data
        .first()
        .ok_or_else(|| error(format!("{}: no layers", path.display())))?;
    let (w, h) = (layer.size.0, layer.size.1);
    let channels = PyDict::new(py);
    for channel in &layer.channel_data.list {
        let values: Vec<f32> = channel.sample_data.values_as_f32().collect();
        let a = Array2::from_shape_vec((h, w), values).map_err(error)?;
        channels.set_item(channel.name.to_string(), a.into_pyarray(py))?;
    }
    let header = PyDict::new(py);
    let display = image.attributes.display_window;
    header.set_item(
        "display_window",
        (display.position.0, display.position.1, display.size.0, display.size.1),
    )?;
    let position = layer.attributes.layer_position;
    header.set_item("data_window", (position.0, position.1, w, h))?;
    if let Some(m) = layer.attributes.world_to_camera {
        header.set_item("worldToCamera", m.to_vec())?;
    }
    if let Some(m) = layer.attributes.world_to_normalized_device {
        header.set_item("worldToNDC", m.to_vec())?;
    }
    for (name, value) in &layer.attributes.other {
        if let exr::meta::attribute::AttributeValue::Text(t) = value {
            header.set_item(name.to_string(), t.to_string())?;
        }
    }
    Ok((channels, header))
}

/// `{AOV name: [EXR channel names]}` for every AOV the renderer knows.
#[pyfunction]
fn aov_channels(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    use clap::ValueEnum;
    let out = PyDict::new(py);
    for aov in Aov::value_variants() {
        out.set_item(format!("{aov:?}"), aov.channels().to_vec())?;
    }
    Ok(out)
}

/// An uninitialised C-ordered float32 array of `shape`, for a caller that writes every element
/// (`zeroset.dask.fetch`): large ones in pooled mappings ([`pages`]), so that a loop fetching
/// frames of one size faults no page in.
#[pyfunction]
fn _empty_f32(py: Python<'_>, shape: Vec<usize>) -> Bound<'_, numpy::PyArrayDyn<f32>> {
    // SAFETY: the caller writes every element before reading any (until then they are zero or
    // left from an earlier array: valid floats either way)
    unsafe { pages::uninit_array(py, numpy::ndarray::IxDyn(&shape)) }
}

#[pymodule]
fn _zeroset(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyScene>()?;
    m.add_function(wrap_pyfunction!(rays_pinhole, m)?)?;
    m.add_function(wrap_pyfunction!(write_exr, m)?)?;
    m.add_function(wrap_pyfunction!(read_exr, m)?)?;
    m.add_function(wrap_pyfunction!(aov_channels, m)?)?;
    m.add_function(wrap_pyfunction!(_empty_f32, m)?)?;
    m.add("ZerosetError", m.py().get_type::<ZerosetError>())?;
    Ok(())
}
