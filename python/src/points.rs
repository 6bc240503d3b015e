//! Point queries and every crossing along rays: the bodies of `_Scene.point_query` (Φ, ∇Φ,
//! nearest points, distances, signs: `zeroset points`' own rows, [`PointQuery::answer`]) and
//! `_Scene.list_intersections` ([`zeroset::scene::Scene::all_hits`]). Arrays are estimated and
//! reserved fallibly first ([`crate::guards`]); the GIL is released while they are answered.

use glam::DVec3;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use zeroset::primitives::SignMethod;
use zeroset::query::all_hits::RayCrossing;
use zeroset::query::point_table::{answer_points, PointQuery};
use zeroset::query::QueryRay;

use crate::guards::{ensure_memory, error, try_vec};
use crate::scene::PyScene;

/// The query named as Python names it (the command line's `--query` names).
fn query_named(name: &str) -> PyResult<PointQuery> {
    use clap::ValueEnum;
    PointQuery::from_str(name, false).map_err(|_| {
        let names: Vec<String> = PointQuery::value_variants()
            .iter()
            .filter_map(|q| Some(q.to_possible_value()?.get_name().to_string()))
            .collect();
        error(format!("unknown point query `{name}`; one of {}", names.join(", ")))
    })
}

/// The sign method named as the command line names it.
pub fn sign_named(name: &str) -> PyResult<SignMethod> {
    name.parse().map_err(error)
}

impl PyScene {
    /// The rows of `zeroset points --query QUERY` for every point of `points` (`(N, 3)` f64,
    /// C-contiguous), as an `(N, columns)` f64 array.
    pub fn point_rows<'py>(
        &self,
        py: Python<'py>,
        points: &PyReadonlyArray2<'py, f64>,
        query: &str,
        sign: &str,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let query = query_named(query)?;
        let sign = sign_named(sign)?;
        let n = points.shape()[0];
        let width = query.columns().len();
        // borrowed where the array is contiguous, else copied
        let flat = crate::rays::rows_of_three(points, "points")?;
        let what = format!("{} of {n} points", query.columns()[0]);
        // the rows, and their copy in Morton order with the order itself (see `answer_points`)
        ensure_memory(&what, (n as u64).saturating_mul(16 * width as u64 + 8))?;
        let mut values = try_vec(n * width, 0.0f64, &what)?;
        let failed = self.with(py, |state| {
            let point = |i: usize| DVec3::new(flat[3 * i], flat[3 * i + 1], flat[3 * i + 2]);
            answer_points(state.built(), n, point, query, sign, &mut values)
        });
        if let Err((i, e)) = failed {
            return Err(error(format!("point {i}: {e}")));
        }
        let array = PyArray1::from_vec(py, values);
        array.reshape([n, width])
    }

    /// Every crossing of each ray (see `Scene.list_intersections`): a dict of flat arrays in
    /// Open3D's layout, `ray_splits` (`N + 1` offsets) and per crossing `ray_ids`, `t_hit`,
    /// `geometry_ids`, `primitive_ids`, `primitive_uvs`, `normals`, `entering`.
    pub fn crossing_lists<'py>(&self, py: Python<'py>, rays: Vec<QueryRay>) -> PyResult<Bound<'py, PyDict>> {
        // each chunk of rays flattened on its own thread, the chunks then joined in order
        let chunks: Vec<Flat> = self.with(py, |state| {
            let scene = state.built();
            rays.par_chunks(2048)
                .map(|chunk| {
                    let mut flat = Flat::default();
                    let mut found = Vec::new();
                    for q in chunk {
                        scene.all_hits(&q.ray, q.range, &mut found);
                        flat.push(&found);
                    }
                    flat
                })
                .collect()
        });
        let total: usize = chunks.iter().map(|c| c.t.len()).sum();
        ensure_memory("list_intersections: the crossings", (total as u64).saturating_mul(80))?;
        let mut splits = Vec::with_capacity(rays.len() + 1);
        let mut all = Flat::default();
        splits.push(0i64);
        for chunk in chunks {
            for count in &chunk.counts {
                let ray = (splits.len() - 1) as i64;
                all.ray_ids.extend(std::iter::repeat_n(ray, *count as usize));
                splits.push(splits[splits.len() - 1] + i64::from(*count));
            }
            all.append(chunk);
        }
        let Flat {
            ray_ids,
            t,
            geometry,
            primitive,
            uvs,
            normals,
            entering,
            ..
        } = all;
        let dict = PyDict::new(py);
        dict.set_item("ray_splits", PyArray1::from_vec(py, splits))?;
        dict.set_item("ray_ids", PyArray1::from_vec(py, ray_ids))?;
        let total = t.len();
        dict.set_item("t_hit", PyArray1::from_vec(py, t))?;
        dict.set_item("geometry_ids", PyArray1::from_vec(py, geometry))?;
        dict.set_item("primitive_ids", PyArray1::from_vec(py, primitive))?;
        dict.set_item("primitive_uvs", PyArray1::from_vec(py, uvs).reshape([total, 2])?)?;
        dict.set_item("normals", PyArray1::from_vec(py, normals).reshape([total, 3])?)?;
        dict.set_item("entering", PyArray1::from_vec(py, entering))?;
        Ok(dict)
    }
}

/// Crossings of a run of rays, flattened: per ray its count, per crossing its values.
#[derive(Default)]
struct Flat {
    counts: Vec<u32>,
    ray_ids: Vec<i64>,
    t: Vec<f64>,
    geometry: Vec<u32>,
    primitive: Vec<u32>,
    uvs: Vec<f64>,
    normals: Vec<f64>,
    entering: Vec<bool>,
}

impl Flat {
    /// Appends one ray's crossings.
    fn push(&mut self, crossings: &[RayCrossing]) {
        self.counts.push(crossings.len() as u32);
        for c in crossings {
            self.t.push(c.hit.t);
            self.geometry.push(c.object);
            self.primitive.push(c.hit.feature);
            self.uvs
                .extend_from_slice(&c.hit.uv.map_or([f64::NAN; 2], |uv| uv.to_array()));
            self.normals
                .extend_from_slice(&c.hit.normal.map_or([f64::NAN; 3], |n| n.to_array()));
            self.entering.push(c.entering);
        }
    }

    /// Appends another run's crossings (its counts are the caller's to place).
    fn append(&mut self, mut other: Flat) {
        self.t.append(&mut other.t);
        self.geometry.append(&mut other.geometry);
        self.primitive.append(&mut other.primitive);
        self.uvs.append(&mut other.uvs);
        self.normals.append(&mut other.normals);
        self.entering.append(&mut other.entering);
    }
}
