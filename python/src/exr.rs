//! EXR files and arrays from Python: `write_exr`, `read_exr`, `aov_channels`, and the
//! uninitialised arrays `zeroset.dask` fetches frames into.

use glam::DMat4;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArrayMethods, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::PyOSError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::borrow::Cow;
use std::path::{Path, PathBuf};
use zeroset::aov::Aov;
use zeroset::output::exr::{write_exr as write_frame, ExrHeader};
use zeroset::render::{Frame, Window};

use crate::guards::{ensure_memory, error, try_with_capacity};
use crate::pages;

/// An AOV plane as `write_exr` receives it: name, flat data, `(height, width, channels)`.
type NamedPlane<'py> = (String, PyReadonlyArray1<'py, f32>, (usize, usize, usize));

/// Writes AOV arrays (keyed by AOV name, `(H, W)` or `(H, W, C)` float32) as zeroset's EXR. The
/// interleaved frame and the writer's copies are estimated first (`MemoryError` where they do not
/// fit).
#[pyfunction]
#[pyo3(signature = (path, arrays, world_to_camera = None, scene_file = String::new(), depth_miss = f32::INFINITY))]
pub fn write_exr(
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
    let pixels = w
        .checked_mul(h)
        .ok_or_else(|| error(format!("write_exr: {w}x{h} pixels are too many")))?;
    let mut aovs = Vec::new();
    let mut planes: Vec<Cow<'_, [f32]>> = Vec::new();
    for (name, data, (ah, aw, c)) in &arrays {
        let aov = Aov::from_str(name, true).map_err(|_| error(format!("write_exr: `{name}` is not an AOV name")))?;
        if (*ah, *aw) != (h, w) || *c != aov.channels().len() {
            return Err(error(format!(
                "write_exr: `{name}` has shape ({ah}, {aw}, {c}); expected ({h}, {w}, {})",
                aov.channels().len()
            )));
        }
        if Some(data.len()) != pixels.checked_mul(*c) {
            return Err(error(format!(
                "write_exr: `{name}` has {} values; ({h}, {w}, {c}) needs {}",
                data.len(),
                pixels.saturating_mul(*c)
            )));
        }
        aovs.push(aov);
        planes.push(match data.as_slice() {
            Ok(values) => Cow::Borrowed(values),
            Err(_) => Cow::Owned(data.to_vec()?),
        });
    }
    let stride: usize = aovs.iter().map(|a| a.channels().len()).sum();
    let what = format!("write_exr of {w}x{h} pixels with {stride} channels");
    // the interleaved frame, and the writer's planar copy and compressed blocks (each at most
    // the frame's size)
    let frame_bytes = (pixels as u64).saturating_mul(4 * stride as u64);
    ensure_memory(&what, frame_bytes.saturating_mul(3))?;
    let mut samples = try_with_capacity(pixels.saturating_mul(stride), &what)?;
    for p in 0..pixels {
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
pub fn read_exr<'py>(py: Python<'py>, path: PathBuf) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
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
pub fn aov_channels(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    use clap::ValueEnum;
    let out = PyDict::new(py);
    for aov in Aov::value_variants() {
        out.set_item(format!("{aov:?}"), aov.channels().to_vec())?;
    }
    Ok(out)
}

/// An uninitialised C-ordered float32 array of `shape`, for a caller that writes every element
/// (`zeroset.dask.fetch`): large ones in pooled mappings ([`pages`]), so that a loop fetching
/// frames of one size faults no page in. `MemoryError` where it cannot be allocated.
#[pyfunction]
pub fn _empty_f32(py: Python<'_>, shape: Vec<usize>) -> PyResult<Bound<'_, numpy::PyArrayDyn<f32>>> {
    // SAFETY: the caller writes every element before reading any (until then they are zero or
    // left from an earlier array: valid floats either way)
    unsafe { pages::uninit_array(py, numpy::ndarray::IxDyn(&shape)) }
}
