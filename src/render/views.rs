//! Many views per run: every pose of the scene's `views` rendered from one loaded scene and one
//! hierarchy, with output files `NAME.0000.exr`, `NAME.0001.exr`, … (a scene without `views`
//! renders its camera to `NAME.exr`).
//!
//! Views are rendered in batches of as many views as the pool has threads: the views of a batch
//! run at once, each with its rows spread over the same threads (rayon's work stealing balances
//! rows of one view against the file writing of another), so the threads stay busy while a
//! finished view is compressed and written, and at most one batch of frames is in memory.

use crate::camera::Camera;
use crate::render::{render_view, Frame, RenderOptions};
use crate::scene::Scene;
use rayon::prelude::*;

/// Every view of `scene` with the EXR file name it is written to: `STEM.IIII.exr` for the
/// scene's `views` (four digits, more when there are more than 10,000), or the camera alone as
/// `STEM.exr`.
#[must_use]
pub fn view_files<'a>(scene: &'a Scene, stem: &str) -> Vec<(&'a Camera, String)> {
    if scene.views.is_empty() {
        return vec![(&scene.camera, format!("{stem}.exr"))];
    }
    let digits = scene.views.len().saturating_sub(1).to_string().len().max(4);
    scene
        .views
        .iter()
        .enumerate()
        .map(|(index, camera)| (camera, format!("{stem}.{index:0digits$}.exr")))
        .collect()
}

/// Renders `views` of `scene` as `options` ask, calling `finish(k, frame)` for the `k`-th view
/// of the slice as soon as its frame is done (from a pool thread; views finish in any order
/// within a batch). Stops at the first batch in which `finish` fails, returning that error.
pub fn render_views<E: Send>(
    scene: &Scene,
    views: &[&Camera],
    options: &RenderOptions,
    finish: impl Fn(usize, Frame) -> Result<(), E> + Sync,
) -> Result<(), E> {
    let batch = rayon::current_num_threads().max(1);
    for (b, cameras) in views.chunks(batch).enumerate() {
        cameras
            .par_iter()
            .enumerate()
            .map(|(k, camera)| finish(b * batch + k, render_view(scene, camera, options)))
            .collect::<Result<Vec<()>, E>>()?;
    }
    Ok(())
}
