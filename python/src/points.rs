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
use zeroset::query::point_table::PointQuery;
use zeroset::query::QueryRay;

use crate::guards::{ensure_memory, error, try_vec};
use crate::scene::PyScene;

/// The query named as Python names it.
fn query_named(name: &str) -> PyResult<PointQuery> {
    Ok(match name {
        "closest" => PointQuery::Closest,
        "distance" => PointQuery::Distance,
        "signed" => PointQuery::Signed,
        "occupancy" => PointQuery::Occupancy,
        "phi" => PointQuery::Phi,
        other => {
            return Err(error(format!(
                "unknown point query `{other}`; one of closest, distance, signed, occupancy, phi"
            )))
        }
    })
}

/// The sign method named as the command line names it.
pub fn sign_named(name: &str) -> PyResult<SignMethod> {
    SignMethod::from_name(name).ok_or_else(|| {
        let names: Vec<&str> = SignMethod::ALL.iter().map(|m| m.name()).collect();
        error(format!("unknown sign method `{name}`; one of {}", names.join(", ")))
    })
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
        let shape = points.shape();
        if shape.len() != 2 || shape[1] != 3 {
            return Err(error(format!("points must have shape (N, 3), got {shape:?}")));
        }
        let n = shape[0];
        let width = query.columns().len();
        let flat = points.as_slice().map_err(|_| error("points must be C-contiguous"))?;
        let what = format!("{} of {n} points", query.columns()[0]);
        ensure_memory(&what, (n as u64).saturating_mul(8 * width as u64))?;
        let mut values = try_vec(n * width, 0.0f64, &what)?;
        let failed = self.with(py, |state| {
            let scene = state.built();
            values
                .par_chunks_mut(width.max(1))
                .zip(flat.par_chunks(3))
                .enumerate()
                .with_min_len(256)
                .find_map_first(|(i, (row, p))| {
                    let p = DVec3::new(p[0], p[1], p[2]);
                    query.answer(scene, p, sign, row).err().map(|e| (i, e))
                })
        });
        if let Some((i, e)) = failed {
            return Err(error(format!("point {i}: {e}")));
        }
        let array = PyArray1::from_vec(py, values);
        Ok(array.reshape([n, width])?)
    }

    /// Every crossing of each ray (see `Scene.list_intersections`): a dict of flat arrays in
    /// Open3D's layout, `ray_splits` (`N + 1` offsets) and per crossing `ray_ids`, `t_hit`,
    /// `geometry_ids`, `primitive_ids`, `primitive_uvs`, `normals`, `entering`.
    pub fn crossing_lists<'py>(&self, py: Python<'py>, rays: Vec<QueryRay>) -> PyResult<Bound<'py, PyDict>> {
        let per_ray: Vec<Vec<RayCrossing>> = self.with(py, |state| {
            let scene = state.built();
            rays.par_iter()
                .map_init(Vec::new, |found, q| {
                    scene.all_hits(&q.ray, q.range, found);
                    found.clone()
                })
                .collect()
        });
        let total: usize = per_ray.iter().map(Vec::len).sum();
        ensure_memory("list_intersections: the crossings", (total as u64).saturating_mul(72))?;
        let mut splits = Vec::with_capacity(per_ray.len() + 1);
        let (mut ray_ids, mut t, mut geometry, mut primitive) = (
            Vec::with_capacity(total),
            Vec::with_capacity(total),
            Vec::with_capacity(total),
            Vec::with_capacity(total),
        );
        let (mut uvs, mut normals, mut entering) = (
            Vec::with_capacity(2 * total),
            Vec::with_capacity(3 * total),
            Vec::with_capacity(total),
        );
        splits.push(0u64);
        for (i, crossings) in per_ray.iter().enumerate() {
            for c in crossings {
                ray_ids.push(i as u64);
                t.push(c.hit.t);
                geometry.push(c.object);
                primitive.push(c.hit.feature);
                uvs.extend_from_slice(&c.hit.uv.map_or([f64::NAN; 2], |uv| uv.to_array()));
                normals.extend_from_slice(&c.hit.normal.map_or([f64::NAN; 3], |n| n.to_array()));
                entering.push(c.entering);
            }
            splits.push(ray_ids.len() as u64);
        }
        let dict = PyDict::new(py);
        dict.set_item("ray_splits", PyArray1::from_vec(py, splits))?;
        dict.set_item("ray_ids", PyArray1::from_vec(py, ray_ids))?;
        dict.set_item("t_hit", PyArray1::from_vec(py, t))?;
        dict.set_item("geometry_ids", PyArray1::from_vec(py, geometry))?;
        dict.set_item("primitive_ids", PyArray1::from_vec(py, primitive))?;
        dict.set_item("primitive_uvs", PyArray1::from_vec(py, uvs).reshape([total, 2])?)?;
        dict.set_item("normals", PyArray1::from_vec(py, normals).reshape([total, 3])?)?;
        dict.set_item("entering", PyArray1::from_vec(py, entering))?;
        Ok(dict)
    }
}
