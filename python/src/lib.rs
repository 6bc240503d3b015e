//! `zeroset._zeroset`: the compiled core of the Python package.
//!
//! Everything here forwards to the `zeroset` crate — scene loading, the query path of
//! `zeroset query`, the renderer and the EXR writer — and only converts numpy arrays in and out.
//! The GIL is released while rays are traced (rayon runs inside). The pure-Python layer
//! (`zeroset/__init__.py`) shapes arrays, keeps the recipe a scene was built from (for pickling
//! to Dask workers) and documents the conventions.
//!
//! - [`scene`]: the `_Scene` class, the objects added from Python, every method Python calls;
//! - [`rays`]: ray batches in and answers out (`cast_rays`, `test_occlusions`,
//!   `count_intersections`), and `rays_pinhole`;
//! - [`points`]: point queries (`point_query`: Φ, nearest points, distances, signs) and every
//!   crossing along rays (`list_intersections`);
//! - [`render`]: `Scene.render`, into new planes or the caller's arrays, in bands;
//! - [`exr`]: `write_exr`, `read_exr`, `aov_channels`;
//! - [`guards`]: `ZerosetError`, and what keeps a call from killing the interpreter: the memory
//!   each call needs estimated by the command line's own check and refused as `MemoryError`,
//!   fallible allocations, capped thread pools;
//! - [`hits`]: the arrays `cast_rays` fills in place; [`pages`]: large output arrays in memory
//!   mapped for them alone.

use pyo3::prelude::*;

mod exr;
mod guards;
mod hits;
mod pages;
mod points;
mod rays;
mod render;
mod scene;

pub(crate) use guards::error;
use guards::ZerosetError;

#[pymodule]
fn _zeroset(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<scene::PyScene>()?;
    m.add_function(wrap_pyfunction!(rays::rays_pinhole, m)?)?;
    m.add_function(wrap_pyfunction!(exr::write_exr, m)?)?;
    m.add_function(wrap_pyfunction!(exr::read_exr, m)?)?;
    m.add_function(wrap_pyfunction!(exr::aov_channels, m)?)?;
    m.add_function(wrap_pyfunction!(exr::_empty_f32, m)?)?;
    m.add("ZerosetError", m.py().get_type::<ZerosetError>())?;
    Ok(())
}
