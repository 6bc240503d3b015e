//! Errors, and the guards that keep a call from killing the interpreter.
//!
//! Everything a user's numbers size (render planes and bands, sample buffers, ray and output
//! arrays) is estimated first through [`zeroset::resources`], the command line's own entry
//! ([`ensure_memory`], [`zeroset::resources::RenderMemory`]), and refused with the estimate as
//! Python's `MemoryError`; what is then allocated is reserved fallibly ([`try_with_capacity`],
//! [`try_vec`], [`try_new_array`]), so an allocation that fails anyway raises `MemoryError` too,
//! never an abort or a `PanicException`. Thread counts are capped as the command line caps them
//! ([`thread_pool`]). Every other refusal is a [`ZerosetError`].

use numpy::ndarray::Dimension;
use numpy::npyffi::{get_type_object, npy_intp, NpyTypes, PY_ARRAY_API};
use numpy::{Element, PyArray, PyArrayDescrMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyMemoryError, PyRuntimeWarning, PyValueError};
use pyo3::prelude::*;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};
use zeroset::resources::{self, NotEnoughMemory};

create_exception!(
    _zeroset,
    ZerosetError,
    PyValueError,
    "A scene, ray batch or argument zeroset cannot accept; the message names the place."
);

/// A [`ZerosetError`] with `message`.
pub fn error(message: impl std::fmt::Display) -> PyErr {
    ZerosetError::new_err(message.to_string())
}

/// A refused or failed allocation as `MemoryError`, its estimate and the room in the message.
#[allow(clippy::needless_pass_by_value)] // used as `map_err(memory_error)`
pub fn memory_error(refused: NotEnoughMemory) -> PyErr {
    PyMemoryError::new_err(refused.to_string())
}

/// [`zeroset::resources::ensure_memory`]: `MemoryError` where `bytes` for `what` do not fit.
pub fn ensure_memory(what: &str, bytes: u64) -> PyResult<()> {
    resources::ensure_memory(what, bytes).map_err(memory_error)
}

/// An empty vector with room for `n` items, or `MemoryError`.
pub fn try_with_capacity<T>(n: usize, what: &str) -> PyResult<Vec<T>> {
    resources::try_with_capacity(n, what).map_err(memory_error)
}

/// `n` copies of `value`, or `MemoryError`.
pub fn try_vec<T: Clone>(n: usize, value: T, what: &str) -> PyResult<Vec<T>> {
    resources::try_vec(n, value, what).map_err(memory_error)
}

/// A new C-ordered numpy array of `shape`, its elements not yet written; numpy's own
/// `MemoryError` (or `ValueError` for a shape too large to index) where it cannot be made, where
/// `PyArray::new` would panic.
///
/// # Safety
/// Every element must be written before the array's values reach Python.
pub unsafe fn try_new_array<'py, T: Element, D: Dimension>(
    py: Python<'py>,
    shape: D,
) -> PyResult<Bound<'py, PyArray<T, D>>> {
    let mut dims: Vec<npy_intp> = shape
        .slice()
        .iter()
        .map(|&d| npy_intp::try_from(d).map_err(|_| memory_error_for_shape(&shape)))
        .collect::<PyResult<_>>()?;
    // SAFETY: the array type and a new reference to the dtype (stolen by the call), a valid
    // dims pointer of `ndim` entries, no strides, data or base object: numpy allocates the data
    // and returns a new reference, or null with the error set
    unsafe {
        let ptr = PY_ARRAY_API.PyArray_NewFromDescr(
            py,
            get_type_object(py, NpyTypes::PyArray_Type),
            T::get_dtype(py).into_dtype_ptr(),
            dims.len() as std::ffi::c_int,
            dims.as_mut_ptr(),
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            0,
            std::ptr::null_mut(),
        );
        Ok(Bound::from_owned_ptr_or_err(py, ptr)?.cast_into_unchecked())
    }
}

fn memory_error_for_shape<D: Dimension>(shape: &D) -> PyErr {
    PyMemoryError::new_err(format!("an array of shape {:?} is too large to index", shape.slice()))
}

/// A rayon pool of `threads` threads, capped at [`resources::THREADS_PER_CORE`] × the cores as
/// the command line caps `--threads` (a `RuntimeWarning` says so), made on first use and kept
/// for later calls (a Dask worker renders tile after tile with the same count).
pub fn thread_pool(py: Python<'_>, threads: usize) -> PyResult<Arc<rayon::ThreadPool>> {
    static POOLS: OnceLock<Mutex<HashMap<usize, Arc<rayon::ThreadPool>>>> = OnceLock::new();
    if threads == 0 {
        return Err(error("threads must be at least 1"));
    }
    let (threads, warning) = resources::capped_threads(threads, "threads");
    if let Some(warning) = warning {
        let message = std::ffi::CString::new(warning).map_err(error)?;
        // stack level 2: the line of the user's `Scene.render` call
        PyErr::warn(py, &py.get_type::<PyRuntimeWarning>(), &message, 2)?;
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
