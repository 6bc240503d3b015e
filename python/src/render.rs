//! Renders: the body of `Scene.render`, into planes numpy then owns or into the caller's `out`
//! arrays, the window traced in bands of about a million pixels. Before anything is allocated,
//! the planes, the band and each thread's sample buffers are estimated by the command line's own
//! [`RenderMemory`] and refused with `MemoryError` where they do not fit; the planes and the band
//! are then made fallibly.

use glam::DVec3;
use numpy::{PyArrayDyn, PyArrayMethods, PyReadwriteArrayDyn};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use zeroset::aov::Aov;
use zeroset::camera::Camera;
use zeroset::render::{render_view_into, FrameLayout, RenderOptions, Window};
use zeroset::resources::RenderMemory;
use zeroset::scene::Scene;

use crate::guards::{error, memory_error, thread_pool};
use crate::pages::Plane;
use crate::scene::PyScene;

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
///
/// # Errors
/// `MemoryError` where a plane or the band cannot be allocated.
fn render_planes(
    scene: &Scene,
    camera: &Camera,
    options: &RenderOptions,
    window: Window,
) -> PyResult<(Vec<Aov>, Vec<Plane>)> {
    let (w, h) = (window.width() as usize, window.height() as usize);
    let aovs = window_layout(camera, options, window).aovs;
    let mut planes = Vec::with_capacity(aovs.len());
    for aov in &aovs {
        let c = aov.channels().len();
        let len = w
            .checked_mul(h)
            .and_then(|p| p.checked_mul(c))
            .ok_or_else(|| error(format!("a {w}x{h} plane of {c} channels is too large to index")))?;
        planes.push(Plane::try_new(len, &format!("the {aov:?} plane of {w}x{h} pixels"))?);
    }
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
    render_rows_into(scene, camera, options, window, &mut rows)?;
    Ok((aovs, planes))
}

/// Renders `window` into `rows`: per AOV of its layout ([`window_layout`], in that order), the
/// window's rows, each `width × channels` samples (channels interleaved), or `None` for an AOV
/// the caller does not keep. The window is rendered in bands of about a million pixels into one
/// interleaved buffer (reused from band to band) and gathered from it into the rows: the peak
/// memory is the rows plus one band.
///
/// # Errors
/// `MemoryError` where the band cannot be allocated.
fn render_rows_into(
    scene: &Scene,
    camera: &Camera,
    options: &RenderOptions,
    window: Window,
    rows: &mut [Option<Vec<&mut [f32]>>],
) -> PyResult<()> {
    let w = window.width() as usize;
    let band_rows = band_rows(window);
    let layout = window_layout(camera, options, window);
    let stride = layout.channel_count();
    // pooled like the planes: a Dask worker renders tile after tile of one size
    let band_len = (w * band_rows as usize).saturating_mul(stride);
    let mut band_buffer = Plane::try_new(band_len, &format!("a band of {w}x{band_rows} pixels"))?;
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
    Ok(())
}

/// Rows of a band of `window`: about a million pixels (at least one row, at most the window).
fn band_rows(window: Window) -> u32 {
    let (w, h) = (window.width() as usize, window.height() as usize);
    ((1usize << 20) / w.max(1)).clamp(1, h.max(1)) as u32
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

/// The arguments of `Scene.render` but `out` (see [`PyScene::render_request`]).
pub struct RenderRequest {
    pub aovs: Option<Vec<String>>,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub crop: Option<(u32, u32, u32, u32)>,
    pub spp: Option<u32>,
    pub depth_miss: f32,
    pub view: Option<([f64; 3], [f64; 3], [f64; 3])>,
    pub background: bool,
    pub threads: Option<usize>,
}

impl PyScene {
    /// The body of `Scene.render`: the camera and window of `request`, the memory it needs
    /// checked ([`RenderMemory`]: the planes, unless `out` takes the AOVs, one band, and each
    /// thread's sample buffers), then the render, into new planes or `out`'s arrays.
    pub fn render_request<'py>(
        &self,
        py: Python<'py>,
        request: RenderRequest,
        out: Option<Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let RenderRequest {
            aovs,
            width,
            height,
            crop,
            spp,
            depth_miss,
            view,
            background,
            threads,
        } = request;
        let pool = threads.map(|n| thread_pool(py, n)).transpose()?;
        let threads = pool
            .as_ref()
            .map_or_else(rayon::current_num_threads, |p| p.current_num_threads());
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
            let layout = window_layout(&camera, &options, window);
            RenderMemory {
                width: window.width(),
                height: window.height(),
                channels: layout.channel_count() as u64,
                frames: u64::from(given.is_none()),
                band_pixels: u64::from(window.width()) * u64::from(band_rows(window)),
                previews: 0,
                spp: spp.unwrap_or(scene.sampling.spp),
                threads,
                ..RenderMemory::default()
            }
            .ensure()
            .map_err(memory_error)?;
            let mut targets = match given.take() {
                Some(given) => Some(out_targets(given, &layout.aovs, window)?),
                None => None,
            };
            // the scene's own spp comes back after this render (the lock is held)
            let saved_spp = scene.sampling.spp;
            if let Some(spp) = spp {
                scene.sampling.spp = spp;
            }
            let scene = &*scene;
            let mut render = || match &mut targets {
                Some(targets) => render_rows_into(scene, &camera, &options, window, targets).map(|()| None),
                None => render_planes(scene, &camera, &options, window).map(Some),
            };
            let planes = match &pool {
                Some(pool) => pool.install(render),
                None => render(),
            };
            state.scene.sampling.spp = saved_spp;
            Ok(planes?.map(|(aovs, planes)| ((window.width() as usize, window.height() as usize), aovs, planes)))
        })?;
        drop(borrowed);
        match (frame, out) {
            (Some(frame), _) => plane_arrays(py, frame.0, frame.1, frame.2),
            (None, Some(out)) => Ok(out),
            (None, None) => unreachable!("a render without `out` returns its planes"),
        }
    }
}
