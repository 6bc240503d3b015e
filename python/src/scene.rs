//! The `_Scene` class: a loaded scene, the objects added from Python, and every method Python
//! calls on it (the ray queries' bodies are in [`crate::rays`], the render's in
//! [`crate::render`]).

use glam::{DAffine3, DMat3, DMat4, DVec3};
use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use zeroset::camera::Model;
use zeroset::primitives::offset::PointPrecision;
use zeroset::primitives::{Mesh, Primitive, Transformed};
use zeroset::scene::mesh_io::degenerate_warning;
use zeroset::scene::registry::BuildContext;
use zeroset::scene::{ron_options, Object, Scene, SceneDesc};

use crate::guards::{error, try_with_capacity};
use crate::rays::{parse_precision, Columns};
use crate::render::RenderRequest;

/// A loaded scene plus the objects added from Python since its hierarchy was last built.
pub struct State {
    pub scene: Scene,
    /// Objects added with `add_*` that the hierarchy does not hold yet.
    pub pending: Vec<Object>,
}

/// The Python object: the state behind a mutex, taken only with the GIL released (so a thread
/// waiting for it never blocks one that holds it), which lets Dask's threads share one scene.
#[pyclass(name = "_Scene", module = "zeroset._zeroset", frozen)]
pub struct PyScene {
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
    pub fn with<T: Send>(&self, py: Python<'_>, f: impl FnOnce(&mut State) -> T + Send) -> T {
        py.detach(|| f(&mut self.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner)))
    }
}

/// `world_from_local` from a 4×4 row-major affine matrix (last row `0 0 0 1`).
pub fn affine(m: [[f64; 4]; 4], what: &str) -> PyResult<DAffine3> {
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
    pub fn built(&mut self) -> &Scene {
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

/// The rows of an `(N, 3)` array as triples, copied into a vector reserved fallibly.
fn triples<T: numpy::Element + Copy>(array: &PyReadonlyArray2<'_, T>, what: &str) -> PyResult<Vec<[T; 3]>> {
    let view = array.as_array();
    let mut out = try_with_capacity(view.nrows(), what)?;
    out.extend(view.rows().into_iter().map(|r| [r[0], r[1], r[2]]));
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
        let v = triples(&vertices, "add_mesh: the vertices")?;
        let t = triples(&triangles, "add_mesh: the triangles")?;
        let mesh = py
            .detach(|| Mesh::new(v, t, None))
            .map_err(|e| error(format!("add_mesh: field `{}`: {}", e.field, e.problem)))?;
        // degenerate triangles (or all of them: no surface) are warned about, as in a scene file
        if let Some(warning) = degenerate_warning(&mesh) {
            let message = std::ffi::CString::new(format!("add_mesh: {warning}")).map_err(error)?;
            PyErr::warn(py, &py.get_type::<pyo3::exceptions::PyUserWarning>(), &message, 1)?;
        }
        let primitive: Arc<dyn Primitive> = Arc::new(mesh);
        self.with(py, |state| {
            state.push(primitive, matrix, name.map(String::into_boxed_str), Arc::default())
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
        let precision: Option<PointPrecision> = parse_precision(origin_precision.as_deref(), normals.is_some())?;
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
        self.time_first_hits_of(py, &origins, &directions)
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
        let columns = Columns::new(&origins, &directions, &tmin, &tmax, None)?;
        self.occlusions(py, &columns, closed)
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
        let columns = Columns::new(&origins, &directions, &tmin, &tmax, None)?;
        self.crossings(py, &columns, closed)
    }

    /// The rows of `zeroset points --query QUERY --sign SIGN` at each of `points` (`(N, 3)`):
    /// an `(N, columns)` array (see `zeroset.Scene.compute_distance` and its neighbours).
    #[pyo3(signature = (points, query, sign = "fast-winding"))]
    fn point_query<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
        query: &str,
        sign: &str,
    ) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        self.point_rows(py, &points, query, sign)
    }

    /// Every crossing along each ray within its range, in Open3D's flat layout (see
    /// `zeroset.Scene.list_intersections`).
    #[pyo3(signature = (origins, directions, tmin, tmax, closed = false))]
    fn list_intersections<'py>(
        &self,
        py: Python<'py>,
        origins: PyReadonlyArray2<'py, f64>,
        directions: PyReadonlyArray2<'py, f64>,
        tmin: PyReadonlyArray1<'py, f64>,
        tmax: PyReadonlyArray1<'py, f64>,
        closed: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let columns = Columns::new(&origins, &directions, &tmin, &tmax, None)?;
        let rays = crate::rays::query_rays(py, &columns, closed, "list_intersections", 64)?;
        self.crossing_lists(py, rays)
    }

    /// Renders the scene's camera (see `zeroset.Scene.render`), on `threads` threads (default:
    /// rayon's global pool, one thread per core or `RAYON_NUM_THREADS`; capped at 4 per core with
    /// a `RuntimeWarning`). With `out` (`{AOV name: writable float32 array}`, each shaped as the
    /// render returns that AOV, every row contiguous), those AOVs are written into the given
    /// arrays (views into a larger array too) and `out` is returned; the render's other AOVs are
    /// not kept. A render whose planes, band and sample buffers do not fit in memory raises
    /// `MemoryError` with the estimate before anything is allocated.
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
        let request = RenderRequest {
            aovs,
            width,
            height,
            crop,
            spp,
            depth_miss,
            view,
            background,
            threads,
        };
        self.render_request(py, request, out)
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
