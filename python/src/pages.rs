//! Output arrays whose first write is cheap: memory mapped for the array alone, starting on a
//! 2 MiB boundary, with transparent huge pages asked for (Linux).
//!
//! A fresh numpy array of many megabytes is mapped memory that the kernel zeroes page by page
//! as it is first written. numpy asks for huge pages too, but its arrays start wherever `malloc`
//! put them, so the partial 2 MiB blocks at either end are faulted in 4 KiB at a time: touching
//! the 86 bytes a ray of `cast_rays`' every output for 10⁶ rays took about 26 ms in numpy's
//! arrays (some 4,600 page faults) against 12 ms in aligned ones (44 faults) on this project's
//! VM. Each array here gets its own mapping (so dropping one array returns its memory at once),
//! owned by a [`MappedBuffer`] that numpy holds as the array's base object.
//!
//! Zeroing fresh memory still costs (the kernel clears every page), so a mapping whose arrays are
//! gone is kept for the next batch rather than unmapped: up to [`POOL_BYTES`] in all, marked
//! `MADV_FREE` so that the kernel may take its pages back whenever it needs memory (they then
//! read as zero). A batch of the same size as the last one, the usual loop, then writes into
//! memory that is already mapped, without a page fault or a zeroing.
//!
//! Elsewhere, below [`MIN_BYTES`], or where the mapping fails, the array is numpy's own, made
//! fallibly: memory that cannot be had is a `MemoryError`, never an abort.

use numpy::ndarray::{ArrayView, Dimension, IntoDimension};
use numpy::{Element, PyArray};
use pyo3::prelude::*;

use crate::guards::{try_new_array, try_vec};

/// Arrays smaller than this are numpy's own (a huge page would mostly be unused).
pub const MIN_BYTES: usize = 4 << 20;

/// The huge-page size the data is aligned to.
#[cfg(target_os = "linux")]
const HUGE_PAGE: usize = 2 << 20;

/// The most bytes of mappings kept for reuse once their arrays are gone.
pub const POOL_BYTES: usize = 512 << 20;

/// Mappings whose arrays are gone, kept for reuse (see the module docs).
#[cfg(target_os = "linux")]
static POOL: std::sync::Mutex<Vec<Mapping>> = std::sync::Mutex::new(Vec::new());

/// One anonymous mapping: `mapped` bytes from `base`, the data `rounded` bytes from `data`.
#[cfg(target_os = "linux")]
struct Mapping {
    base: *mut std::ffi::c_void,
    mapped: usize,
    data: *mut u8,
    rounded: usize,
}

// SAFETY: plain memory that only its one owner (a buffer, or the pool) refers to
#[cfg(target_os = "linux")]
unsafe impl Send for Mapping {}

/// The memory of one array: an anonymous private mapping, returned to the pool (or unmapped)
/// when the last array viewing it is gone.
#[pyclass(frozen)]
pub struct MappedBuffer {
    #[cfg(target_os = "linux")]
    mapping: std::mem::ManuallyDrop<Mapping>,
}

// SAFETY: the mapping is plain memory that nothing else refers to
unsafe impl Sync for MappedBuffer {}

#[cfg(target_os = "linux")]
impl Drop for MappedBuffer {
    fn drop(&mut self) {
        // SAFETY: dropped once, here; no array views the memory any more (numpy releases its
        // base object after the array's data)
        let mapping = unsafe { std::mem::ManuallyDrop::take(&mut self.mapping) };
        let mut pool = POOL.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let pooled: usize = pool.iter().map(|m| m.rounded).sum();
        if pooled + mapping.rounded <= POOL_BYTES {
            // SAFETY: the data range lies inside the mapping; the kernel may now reclaim its
            // pages lazily (they read as zero afterwards), which only ever costs a later zeroing
            unsafe {
                libc::madvise(mapping.data.cast(), mapping.rounded, libc::MADV_FREE);
            }
            pool.push(mapping);
        } else {
            drop(pool);
            // SAFETY: `base`/`mapped` are what `mmap` returned; nothing refers to the memory
            unsafe {
                libc::munmap(mapping.base, mapping.mapped);
            }
        }
    }
}

impl MappedBuffer {
    /// At least `bytes` of writable memory starting on a [`HUGE_PAGE`] boundary (a pooled mapping
    /// of the same rounded size, or a fresh one with huge pages asked for), and its start;
    /// `None` where a fresh mapping fails (the caller falls back to numpy's allocator).
    #[cfg(target_os = "linux")]
    fn new(bytes: usize) -> Option<(Self, *mut u8)> {
        let rounded = bytes.checked_add(HUGE_PAGE - 1)? / HUGE_PAGE * HUGE_PAGE;
        let reused = {
            let mut pool = POOL.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
            let found = pool.iter().position(|m| m.rounded == rounded);
            found.map(|k| pool.swap_remove(k))
        };
        let mapping = match reused {
            Some(mapping) => mapping,
            None => {
                let mapped = rounded.checked_add(HUGE_PAGE)?;
                // SAFETY: a fresh anonymous mapping, its result checked
                let base = unsafe {
                    libc::mmap(
                        std::ptr::null_mut(),
                        mapped,
                        libc::PROT_READ | libc::PROT_WRITE,
                        libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                        -1,
                        0,
                    )
                };
                if base == libc::MAP_FAILED {
                    return None;
                }
                let skip = (HUGE_PAGE - base as usize % HUGE_PAGE) % HUGE_PAGE;
                // SAFETY: `skip < HUGE_PAGE`: inside the mapping
                let data = unsafe { base.cast::<u8>().add(skip) };
                // SAFETY: `data .. data + rounded` lies inside the mapping; the advice is only a
                // hint, which a kernel without transparent huge pages refuses harmlessly
                unsafe {
                    libc::madvise(data.cast(), rounded, libc::MADV_HUGEPAGE);
                }
                Mapping {
                    base,
                    mapped,
                    data,
                    rounded,
                }
            }
        };
        let data = mapping.data;
        Some((
            Self {
                mapping: std::mem::ManuallyDrop::new(mapping),
            },
            data,
        ))
    }

    #[cfg(not(target_os = "linux"))]
    fn new(_bytes: usize) -> Option<(Self, *mut u8)> {
        None
    }
}

/// A new C-ordered array of `shape` whose elements are still to be written: in its own aligned
/// mapping when it holds at least [`MIN_BYTES`] (see the module docs), else numpy's.
///
/// # Errors
/// `MemoryError` where neither a mapping nor numpy's allocator has the memory.
///
/// # Safety
/// Every element must be written before the array's values reach Python (until then they are
/// zero, uninitialised, or left from an earlier batch's array).
pub unsafe fn uninit_array<'py, T: Element, D: Dimension>(
    py: Python<'py>,
    shape: impl IntoDimension<Dim = D>,
) -> PyResult<Bound<'py, PyArray<T, D>>> {
    let shape = shape.into_dimension();
    // a shape whose size overflows goes to numpy, which refuses it
    let bytes = shape
        .size_checked()
        .and_then(|n| n.checked_mul(std::mem::size_of::<T>()));
    if let Some(bytes) = bytes.filter(|&b| b >= MIN_BYTES) {
        if let Some((buffer, data)) = MappedBuffer::new(bytes) {
            // SAFETY: `data` points to `bytes` writable bytes aligned for any `T`, which the
            // caller writes before they are read
            if let Ok(array) = unsafe { mapped_array(py, buffer, data.cast::<T>(), shape.clone()) } {
                return Ok(array);
            }
        }
    }
    // SAFETY: as the caller promises
    unsafe { try_new_array(py, shape) }
}

/// The array of `shape` over the memory at `data` that `buffer` owns, `buffer` becoming the
/// array's base object (so the mapping lives, unmoved, as long as the array).
///
/// # Safety
/// `data` points into `buffer`'s mapping, aligned for `T`, with room for `shape`'s elements.
unsafe fn mapped_array<'py, T: Element, D: Dimension>(
    py: Python<'py>,
    buffer: MappedBuffer,
    data: *mut T,
    shape: D,
) -> PyResult<Bound<'py, PyArray<T, D>>> {
    let owner = Bound::new(py, buffer)?;
    // SAFETY: as the caller promises; `owner` keeps the memory while the array lives
    Ok(unsafe {
        let view = ArrayView::from_shape_ptr(shape, data.cast_const());
        PyArray::borrow_from_array(&view, owner.into_any())
    })
}

/// The memory of one float32 output plane of `len` values, written in place by the renderer and
/// then handed to numpy without a copy: its own aligned mapping where it holds at least
/// [`MIN_BYTES`] (a pooled one after the first render of a size: no page faults, no zeroing),
/// else a `Vec`. Every value is written before the plane becomes an array.
pub enum Plane {
    /// A mapping: its owner and the `len` floats at `data`.
    Mapped {
        buffer: MappedBuffer,
        data: *mut f32,
        len: usize,
    },
    /// numpy's memory, through a `Vec`.
    Owned(Vec<f32>),
}

// SAFETY: `data` points into the mapping that `buffer` owns, which nothing else refers to
unsafe impl Send for Plane {}

impl Plane {
    /// A plane of `len` floats (their values unspecified until written), `what` in the message
    /// of a `MemoryError` where it cannot be allocated.
    pub fn try_new(len: usize, what: &str) -> PyResult<Self> {
        let bytes = len.saturating_mul(std::mem::size_of::<f32>());
        if bytes >= MIN_BYTES {
            if let Some((buffer, data)) = MappedBuffer::new(bytes) {
                return Ok(Self::Mapped {
                    buffer,
                    data: data.cast(),
                    len,
                });
            }
        }
        try_vec(len, 0.0, what).map(Self::Owned)
    }

    /// The plane's values, to write.
    pub fn as_mut_slice(&mut self) -> &mut [f32] {
        match self {
            // SAFETY: `len` floats at `data`, aligned (a page boundary), initialised (a fresh
            // mapping reads as zero, a pooled one as what it last held: any bits are a valid
            // f32), and borrowed mutably with `self`
            Self::Mapped { data, len, .. } => unsafe { std::slice::from_raw_parts_mut(*data, *len) },
            Self::Owned(values) => values,
        }
    }

    /// The plane as a C-ordered array of `shape` (whose size is the plane's length), owning its
    /// memory.
    pub fn into_array<'py, D: Dimension>(
        self,
        py: Python<'py>,
        shape: impl IntoDimension<Dim = D>,
    ) -> PyResult<Bound<'py, PyArray<f32, D>>> {
        let shape = shape.into_dimension();
        match self {
            Self::Mapped { buffer, data, len } => {
                assert_eq!(shape.size(), len, "the shape holds the plane");
                // SAFETY: `len` initialised floats at `data`, a page boundary in `buffer`'s mapping
                unsafe { mapped_array(py, buffer, data, shape) }
            }
            Self::Owned(values) => {
                let array = numpy::ndarray::Array::from_shape_vec(shape, values)
                    .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
                Ok(numpy::IntoPyArray::into_pyarray(array, py))
            }
        }
    }
}
