//! The arrays `cast_rays` returns, filled in place.
//!
//! Each requested field is one numpy array, allocated (uninitialised) while the GIL is held and
//! then split into one piece per chunk of [`COLUMN_CHUNK`] rays; on a rayon thread, with the GIL
//! released, [`trace_columns`] has each piece fill its rows with the miss values, a column at a
//! time, then hands it the answers of the chunk's hits (and uncertain misses), which write their
//! row of every field while the chunk is in cache. Nothing is copied after that: the arrays go
//! back to Python as they are.
//!
//! Fields (one row per ray): `t` (`+∞` on a miss), `hit` bool, `point` ×3 and `normal` ×3 (zero
//! on a miss), `object_id` i32 (−1 on a miss), `uv` ×2 (zero where the primitive has none),
//! `primitive_id` i64 (the primitive's part, −1 on a miss), `uncertain` bool. The real fields
//! (`t`, `point`, `normal`, `uv`) are f64, or f32 ([`Real`]): the f64 values rounded to nearest,
//! half the bytes to write and keep (the dtype Open3D's `cast_rays` returns).
//!
//! [`trace_columns`]: zeroset::query::rays::trace_columns

use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use zeroset::primitives::{HitRequest, SurfaceHit};
use zeroset::query::rays::{ChunkAnswers, COLUMN_CHUNK};

use crate::pages::uninit_array;

/// Every field, in the order of the returned dict.
pub const FIELDS: [&str; 8] = [
    "t",
    "hit",
    "point",
    "normal",
    "object_id",
    "uv",
    "primitive_id",
    "uncertain",
];

/// The element type of the real fields: f64, or f32 (each value the f64 one rounded to nearest).
pub trait Real: numpy::Element + Copy + Send {
    /// `x` in this type.
    fn of(x: f64) -> Self;
}

impl Real for f64 {
    #[inline(always)]
    fn of(x: f64) -> Self {
        x
    }
}

impl Real for f32 {
    #[inline(always)]
    fn of(x: f64) -> Self {
        x as f32
    }
}

/// The output arrays of one batch (`None`: not requested), real fields of type `F`.
pub struct HitArrays<'py, F: Real> {
    t: Option<Bound<'py, PyArray1<F>>>,
    hit: Option<Bound<'py, PyArray1<bool>>>,
    point: Option<Bound<'py, PyArray2<F>>>,
    normal: Option<Bound<'py, PyArray2<F>>>,
    object_id: Option<Bound<'py, PyArray1<i32>>>,
    uv: Option<Bound<'py, PyArray2<F>>>,
    primitive_id: Option<Bound<'py, PyArray1<i64>>>,
    uncertain: Option<Bound<'py, PyArray1<bool>>>,
}

/// One chunk's rows of every requested array.
pub struct HitChunk<'a, F> {
    t: Option<&'a mut [F]>,
    hit: Option<&'a mut [bool]>,
    point: Option<&'a mut [F]>,
    normal: Option<&'a mut [F]>,
    object_id: Option<&'a mut [i32]>,
    uv: Option<&'a mut [F]>,
    primitive_id: Option<&'a mut [i64]>,
    uncertain: Option<&'a mut [bool]>,
}

/// Uninitialised `(n,)` array, when `wanted` (in memory of its own when large: [`crate::pages`]);
/// `MemoryError` where it cannot be allocated.
fn vector<'py, T: numpy::Element>(
    py: Python<'py>,
    n: usize,
    wanted: bool,
) -> PyResult<Option<Bound<'py, PyArray1<T>>>> {
    // SAFETY: every element is written (by `HitChunk::misses`, all of its chunk's rows) before
    // the array reaches Python (the chunks cover all rows); on an error the array is dropped
    // unread
    wanted.then(|| unsafe { uninit_array(py, [n]) }).transpose()
}

/// Uninitialised `(n, width)` array, when `wanted`.
fn rows<'py, F: Real>(
    py: Python<'py>,
    n: usize,
    width: usize,
    wanted: bool,
) -> PyResult<Option<Bound<'py, PyArray2<F>>>> {
    // SAFETY: as in `vector`
    wanted.then(|| unsafe { uninit_array(py, [n, width]) }).transpose()
}

/// The data of a new array as one mutable slice.
///
/// # Safety
/// No other reference to the array's data may exist while the slice lives (the arrays of
/// [`HitArrays::new`] are fresh and reach Python only after the slices are gone).
#[allow(clippy::mut_from_ref)]
unsafe fn data_mut<'a, T: numpy::Element, D: numpy::ndarray::Dimension>(
    array: Option<&'a Bound<'_, numpy::PyArray<T, D>>>,
) -> PyResult<Option<&'a mut [T]>> {
    array
        .map(|a| unsafe { a.as_slice_mut() })
        .transpose()
        .map_err(|e| crate::error(e.to_string()))
}

/// The pieces of one array's data, `per_ray` elements a ray, one per chunk of rays (`count`).
fn pieces<T>(data: Option<&mut [T]>, per_ray: usize, count: usize) -> std::vec::IntoIter<Option<&mut [T]>> {
    let pieces: Vec<Option<&mut [T]>> = match data {
        None => (0..count).map(|_| None).collect(),
        Some(data) => data.chunks_mut(per_ray * COLUMN_CHUNK).map(Some).collect(),
    };
    pieces.into_iter()
}

/// Whether `field` is among `wanted` (all are when `None`), after every name was checked.
fn checked_wants(wanted: Option<&[String]>) -> PyResult<impl Fn(&str) -> bool + '_> {
    if let Some(names) = wanted {
        if let Some(unknown) = names.iter().find(|name| !FIELDS.contains(&name.as_str())) {
            return Err(crate::error(format!(
                "outputs: unknown field `{unknown}`; expected some of {}",
                FIELDS.join(", ")
            )));
        }
    }
    Ok(move |field: &str| wanted.is_none_or(|names| names.iter().any(|name| name == field)))
}

impl<'py, F: Real> HitArrays<'py, F> {
    /// Bytes a ray of the fields named in `wanted` (all of them when `None`).
    ///
    /// # Errors
    /// An unknown field name.
    pub fn bytes_per_ray(wanted: Option<&[String]>) -> PyResult<usize> {
        let wants = checked_wants(wanted)?;
        let real = std::mem::size_of::<F>();
        let sizes = [
            ("t", real),
            ("hit", 1),
            ("point", 3 * real),
            ("normal", 3 * real),
            ("object_id", 4),
            ("uv", 2 * real),
            ("primitive_id", 8),
            ("uncertain", 1),
        ];
        Ok(sizes
            .iter()
            .filter(|(name, _)| wants(name))
            .map(|(_, bytes)| bytes)
            .sum())
    }

    /// The arrays of `n` rays for the fields named in `wanted` (all of them when `None`).
    ///
    /// # Errors
    /// An unknown field name; `MemoryError` where an array cannot be allocated.
    pub fn new(py: Python<'py>, n: usize, wanted: Option<&[String]>) -> PyResult<Self> {
        let wants = checked_wants(wanted)?;
        Ok(Self {
            t: vector(py, n, wants("t"))?,
            hit: vector(py, n, wants("hit"))?,
            point: rows(py, n, 3, wants("point"))?,
            normal: rows(py, n, 3, wants("normal"))?,
            object_id: vector(py, n, wants("object_id"))?,
            uv: rows(py, n, 2, wants("uv"))?,
            primitive_id: vector(py, n, wants("primitive_id"))?,
            uncertain: vector(py, n, wants("uncertain"))?,
        })
    }

    /// What the hits must be completed with: a normal only if `normal` was requested, uv only
    /// if `uv` was (the point and `t` come with every hit).
    pub fn request(&self) -> HitRequest {
        HitRequest {
            normal: self.normal.is_some(),
            uv: self.uv.is_some(),
            error: false,
        }
    }

    /// The arrays split into one [`HitChunk`] per chunk of `n` rays.
    ///
    /// # Errors
    /// Never for arrays made by [`HitArrays::new`] (they are contiguous).
    pub fn chunks(&self, n: usize) -> PyResult<Vec<HitChunk<'_, F>>> {
        let count = n.div_ceil(COLUMN_CHUNK);
        // SAFETY: the arrays were made by `new` and nothing else refers to their data (see
        // `data_mut`); each is split once, into disjoint pieces
        let (mut t, mut hit, mut point, mut normal, mut object_id, mut uv, mut primitive_id, mut uncertain) = unsafe {
            (
                pieces(data_mut(self.t.as_ref())?, 1, count),
                pieces(data_mut(self.hit.as_ref())?, 1, count),
                pieces(data_mut(self.point.as_ref())?, 3, count),
                pieces(data_mut(self.normal.as_ref())?, 3, count),
                pieces(data_mut(self.object_id.as_ref())?, 1, count),
                pieces(data_mut(self.uv.as_ref())?, 2, count),
                pieces(data_mut(self.primitive_id.as_ref())?, 1, count),
                pieces(data_mut(self.uncertain.as_ref())?, 1, count),
            )
        };
        Ok((0..count)
            .map(|_| HitChunk {
                t: t.next().flatten(),
                hit: hit.next().flatten(),
                point: point.next().flatten(),
                normal: normal.next().flatten(),
                object_id: object_id.next().flatten(),
                uv: uv.next().flatten(),
                primitive_id: primitive_id.next().flatten(),
                uncertain: uncertain.next().flatten(),
            })
            .collect())
    }

    /// The requested arrays keyed by field name, in the order of [`FIELDS`].
    ///
    /// # Errors
    /// A failing dict insertion (out of memory).
    pub fn into_dict(self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        let arrays: [(&str, Option<Bound<'py, PyAny>>); 8] = [
            ("t", self.t.map(Bound::into_any)),
            ("hit", self.hit.map(Bound::into_any)),
            ("point", self.point.map(Bound::into_any)),
            ("normal", self.normal.map(Bound::into_any)),
            ("object_id", self.object_id.map(Bound::into_any)),
            ("uv", self.uv.map(Bound::into_any)),
            ("primitive_id", self.primitive_id.map(Bound::into_any)),
            ("uncertain", self.uncertain.map(Bound::into_any)),
        ];
        for (name, array) in arrays {
            if let Some(array) = array {
                out.set_item(name, array)?;
            }
        }
        Ok(out)
    }
}

impl<F: Real> ChunkAnswers for HitChunk<'_, F> {
    /// Every requested field's rows `0..len` set to the miss values, a whole column at a time.
    fn misses(&mut self, len: usize) {
        fill(self.t.as_deref_mut(), len, F::of(f64::INFINITY));
        fill(self.hit.as_deref_mut(), len, false);
        fill(self.point.as_deref_mut(), 3 * len, F::of(0.0));
        fill(self.normal.as_deref_mut(), 3 * len, F::of(0.0));
        fill(self.object_id.as_deref_mut(), len, -1);
        fill(self.uv.as_deref_mut(), 2 * len, F::of(0.0));
        fill(self.primitive_id.as_deref_mut(), len, -1);
        fill(self.uncertain.as_deref_mut(), len, false);
    }

    /// Row `i` of every requested field: the hit's values (an uncertain miss keeps the miss
    /// values [`ChunkAnswers::misses`] wrote), and the `uncertain` flag.
    fn put(&mut self, i: usize, found: Option<&(u32, SurfaceHit)>, uncertain: bool) {
        if let Some((object, hit)) = found {
            let [x, y, z] = hit.point.to_array();
            let [nx, ny, nz] = hit.normal.unwrap_or_default().to_array();
            let [u, v] = hit.uv.unwrap_or_default().to_array();
            put(self.t.as_deref_mut(), i, [F::of(hit.t)]);
            put(self.hit.as_deref_mut(), i, [true]);
            put(self.point.as_deref_mut(), i, [F::of(x), F::of(y), F::of(z)]);
            put(self.normal.as_deref_mut(), i, [F::of(nx), F::of(ny), F::of(nz)]);
            put(self.object_id.as_deref_mut(), i, [*object as i32]);
            put(self.uv.as_deref_mut(), i, [F::of(u), F::of(v)]);
            put(self.primitive_id.as_deref_mut(), i, [i64::from(hit.feature)]);
        }
        put(self.uncertain.as_deref_mut(), i, [uncertain]);
    }
}

/// The first `len` elements of a requested field set to `value`.
#[inline(always)]
fn fill<T: Copy>(out: Option<&mut [T]>, len: usize, value: T) {
    if let Some(out) = out {
        out[..len].fill(value);
    }
}

/// Writes row `i` of a field of `W` elements a ray, when requested.
#[inline(always)]
fn put<T: Copy, const W: usize>(out: Option<&mut [T]>, i: usize, value: [T; W]) {
    if let Some(out) = out {
        out[W * i..W * (i + 1)].copy_from_slice(&value);
    }
}
