//! `zeroset render`: the scene loaded and adjusted by the options, resources checked up front,
//! the views traced and written (one view streamed band by band as it is traced, several each
//! written from its frame), and a summary line.

use super::{uncertain_warning, RenderArgs};
use crate::aov::Aov;
use crate::camera::Camera;
use crate::diagnostics::{uncertain_message, uncertain_since};
use crate::output::atomic::{check_destination, require_file_destination, write_atomically};
use crate::output::cameras_json::{cameras_json, exr_camera_attributes, transforms_json};
use crate::output::exr::{size_estimate, write_exr_with, ExrCompression, ExrHeader};
use crate::output::exr_stream::ExrStream;
use crate::output::merge::SPP_ATTRIBUTE;
use crate::output::png::{write_previews, PREVIEWS};
use crate::output::png_stream::PreviewStream;
use crate::render::stream::{band_rows, bands_held, render_view_to, BandSink};
use crate::render::views::{render_views, view_files};
use crate::render::{Frame, FrameLayout, RenderOptions, Window};
use crate::resources::{human_bytes, long_work_warning, process_cpu_seconds, RenderMemory};
use crate::scene::Scene;
use anyhow::{bail, Context, Result};
use rayon::iter::{IntoParallelIterator, ParallelIterator};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};
use zeroset_primitives::root::budget_exhaustions;
use zeroset_primitives::UncertainCounts;

/// Runs `zeroset render`.
pub(super) fn render_command(args: &RenderArgs) -> Result<()> {
    let wall = Instant::now();
    let mut scene = Scene::load(&args.scene)?;
    let load_time = wall.elapsed();
    crate::diagnostics::print_load_warnings(&scene);
    let crop = apply_overrides(&mut scene, args)?;
    let aovs = match &args.aov {
        Some(names) => Aov::parse_list(names).map_err(|m| anyhow::anyhow!("--aov {m}"))?,
        None => scene.outputs.aovs.clone(),
    };
    let (dir, stem) = output_location(&args.output, &args.scene)?;
    let previews = scene.outputs.previews && !args.no_previews;
    let views = view_files(&scene, &stem);
    let selected = selected_views(args, &scene, views.len())?;
    // every file the render writes, checked before any is written (cameras.json comes first)
    for path in output_files(&views, &selected, &dir, &stem, previews, args.transforms) {
        require_file_destination(&path).with_context(|| format!("-o {}", args.output.display()))?;
    }
    check_resources(&scene, &aovs, crop, previews, selected.len(), &dir, args.compression)?;
    write_camera_files(&views, &dir, &stem, args.transforms)?;
    let options = RenderOptions {
        aovs,
        crop,
        depth_miss: args.depth_miss,
        progress: selected.len() == 1,
        background: args.background,
    };
    let job = Job {
        scene: &scene,
        args,
        options: &options,
        dir: &dir,
        previews,
        background: scene.background.as_vec3().to_array(),
    };
    let cpu_before_trace = process_cpu_seconds();
    let before = UncertainBefore::now();
    let traced = if let [index] = selected[..] {
        job.streamed(views[index].0, index, &views[index].1, &before)?
    } else {
        let views: Vec<(&Camera, usize, &str)> =
            selected.iter().map(|&i| (views[i].0, i, views[i].1.as_str())).collect();
        job.whole_frames(&views, &before)?
    };
    if let Some(message) = uncertain_message(uncertain_since(before.function)) {
        eprintln!("{message}");
    }
    let cameras: Vec<&Camera> = selected.iter().map(|&i| views[i].0).collect();
    print_summary(&scene, &cameras, crop, &traced, wall, load_time, cpu_before_trace);
    Ok(())
}

/// Applies the options that change the scene (`--width`/`--height`, `--spp`) and checks the
/// others that need it (`--crop` against the image, `--depth-miss`); returns the crop window.
fn apply_overrides(scene: &mut Scene, args: &RenderArgs) -> Result<Option<Window>> {
    if args.width.is_some() || args.height.is_some() {
        let w = args.width.unwrap_or(scene.camera.width);
        let h = args.height.unwrap_or(scene.camera.height);
        scene.camera = scene
            .camera
            .with_resolution(w, h)
            .map_err(|e| anyhow::anyhow!("--width/--height: {e}"))?;
        for view in &mut scene.views {
            *view = view
                .with_resolution(w, h)
                .map_err(|e| anyhow::anyhow!("--width/--height: {e}"))?;
        }
    }
    let crop = match &args.crop {
        None => None,
        Some(c) => {
            if c.len() != 4 {
                bail!("--crop takes four numbers x0,y0,x1,y1, got {}", c.len());
            }
            let w = Window {
                x0: c[0],
                y0: c[1],
                x1: c[2],
                y1: c[3],
            };
            Some(
                w.within(scene.camera.width, scene.camera.height)
                    .map_err(|m| anyhow::anyhow!("--crop {},{},{},{}: {m}", c[0], c[1], c[2], c[3]))?,
            )
        }
    };
    if let Some(spp) = args.spp {
        if spp == 0 {
            bail!("--spp must be at least 1");
        }
        scene.sampling.spp = spp;
    }
    if args.depth_miss.is_nan() {
        bail!("--depth-miss must be a number or ±inf, not NaN");
    }
    Ok(crop)
}

/// The resources a render of `views` views needs, checked before any tracing: memory for its
/// buffers, and a writable directory `dir` with room for the EXR and the previews. One view is
/// streamed ([`render_view_to`]): it holds [`bands_held`] bands (their samples, the EXR blocks
/// encoded from them, the preview rows) and, with a depth preview, that preview's whole planes
/// (its `f32` depths, then its 8-bit image). Several views are rendered a batch of one per thread
/// at a time, each holding its frame, the EXR writer's copies and its previews. The estimate is
/// printed; work estimated at more than a few minutes is announced ([`long_work_warning`]).
fn check_resources(
    scene: &Scene,
    aovs: &[Aov],
    crop: Option<Window>,
    previews: bool,
    views: usize,
    dir: &Path,
    compression: ExrCompression,
) -> Result<()> {
    let window = crop.unwrap_or(Window {
        x0: 0,
        y0: 0,
        x1: scene.camera.width,
        y1: scene.camera.height,
    });
    let pixels = u64::from(window.width()) * u64::from(window.height());
    let mut distinct = aovs.to_vec();
    distinct.sort();
    distinct.dedup();
    let channels: u64 = distinct.iter().map(|a| a.channels().len() as u64).sum();
    let previewed = |a: &&Aov| previews && matches!(a, Aov::Beauty | Aov::Depth | Aov::Normal);
    let preview_count = distinct.iter().filter(previewed).count() as u64;
    let depth_previewed = distinct.iter().filter(previewed).any(|a| *a == Aov::Depth);
    let threads = rayon::current_num_threads();
    let memory = if views == 1 {
        let rows = band_rows(compression.codec().scan_lines_per_block() as u32).min(window.height());
        let streamed_previews = preview_count - u64::from(depth_previewed);
        RenderMemory {
            width: window.width(),
            height: window.height(),
            channels,
            band_pixels: bands_held(threads) as u64 * u64::from(rows) * u64::from(window.width()),
            // the encoded EXR blocks (at most the samples' bytes, and a block header counted as a
            // byte a pixel), the streamed previews' 8-bit rows
            band_extra: 4 * channels + 1 + 3 * streamed_previews,
            planes: if depth_previewed { 4 + 3 } else { 0 },
            spp: scene.sampling.spp,
            threads,
            ..RenderMemory::default()
        }
    } else {
        let in_flight = views.clamp(1, threads.max(1)) as u64;
        RenderMemory {
            width: window.width(),
            height: window.height(),
            channels,
            frames: 3 * in_flight,
            previews: preview_count * in_flight,
            spp: scene.sampling.spp,
            threads,
            ..RenderMemory::default()
        }
    };
    let estimate = memory.ensure()?;
    eprintln!(
        "memory: about {} for the render's buffers ({})",
        human_bytes(estimate),
        if views == 1 {
            "bands streamed to the outputs"
        } else {
            "whole frames, one per view in flight"
        }
    );
    if let Some(warning) = long_work_warning(window.width(), window.height(), scene.sampling.spp, views, threads) {
        eprintln!("warning: {warning}");
    }
    let disk = size_estimate(pixels, channels, u64::from(window.height())) + pixels * 3 * preview_count;
    check_destination(dir, disk.saturating_mul(views.max(1) as u64))
}

/// The indices of the views to render among `count`: all, or the one `--view` names.
fn selected_views(args: &RenderArgs, scene: &Scene, count: usize) -> Result<Vec<usize>> {
    Ok(match args.view {
        None => (0..count).collect(),
        Some(_) if scene.views.is_empty() => bail!("--view: {} has no `views`", args.scene.display()),
        Some(i) if i >= count => bail!("--view {i}: the scene has views 0 to {}", count - 1),
        Some(i) => vec![i],
    })
}

/// The uncertain-root counters before the trace.
struct UncertainBefore {
    exhausted: u64,
    function: UncertainCounts,
}

impl UncertainBefore {
    fn now() -> Self {
        Self {
            exhausted: budget_exhaustions(),
            function: zeroset_primitives::uncertain_counts(),
        }
    }

    /// Warns when rays' answers became uncertain since.
    fn warn_since(&self) {
        warn_uncertain(uncertain_events_since(self.exhausted, self.function));
    }
}

/// What a finished trace reports: its time, its rays and the writing not overlapped with it.
struct Traced {
    seconds: f64,
    rays: u64,
    write_seconds: f64,
}

/// What tracing and writing the views share.
struct Job<'a> {
    scene: &'a Scene,
    args: &'a RenderArgs,
    options: &'a RenderOptions,
    dir: &'a Path,
    previews: bool,
    background: [f32; 3],
}

impl Job<'_> {
    /// The EXR header of view `index` through `camera`.
    fn exr_header(&self, camera: &Camera, index: usize) -> ExrHeader {
        ExrHeader {
            world_to_camera: camera.world_to_camera(),
            world_to_ndc: camera.world_to_ndc(0.01, 1000.0),
            scene_file: self.args.scene.display().to_string(),
            depth_miss: self.args.depth_miss,
            camera_attributes: {
                let mut attributes = exr_camera_attributes(camera, index);
                // crops merge only with crops of the same samples (`zeroset merge` compares it)
                let spp = i32::try_from(self.scene.sampling.spp).unwrap_or(i32::MAX);
                attributes.push((
                    SPP_ATTRIBUTE.to_string(),
                    exr::meta::attribute::AttributeValue::I32(spp),
                ));
                attributes
            },
        }
    }

    /// `" and PNG previews"` where previews are written.
    fn and_previews(&self) -> &'static str {
        if self.previews {
            " and PNG previews"
        } else {
            ""
        }
    }

    /// One view (`index`, written to `file`), its EXR and previews written band by band while
    /// it is traced ([`crate::render::stream`]).
    fn streamed(&self, camera: &Camera, index: usize, file: &str, before: &UncertainBefore) -> Result<Traced> {
        let layout = FrameLayout::new(camera, self.options);
        let exr_path = self.dir.join(file);
        let exr = ExrStream::create(
            &exr_path,
            &layout,
            &self.exr_header(camera, index),
            self.args.compression,
        )?;
        let preview_stem = file.trim_end_matches(".exr");
        let pngs: Vec<PreviewStream> = if self.previews {
            PREVIEWS
                .iter()
                .filter(|(aov, _)| layout.channel_offset(*aov).is_some())
                .map(|(aov, name)| {
                    let path = self.dir.join(format!("{preview_stem}.{name}.png"));
                    PreviewStream::create(&path, *aov, &layout, self.background)
                })
                .collect::<Result<_>>()?
        } else {
            Vec::new()
        };
        eprintln!(
            "writing {}{} as rows are traced …",
            exr_path.display(),
            self.and_previews()
        );
        let mut sinks: Vec<&dyn BandSink> = vec![&exr];
        sinks.extend(pngs.iter().map(|p| p as &dyn BandSink));
        let trace_start = Instant::now();
        let stats = render_view_to(self.scene, camera, self.options, &sinks)?;
        drop(sinks);
        before.warn_since();
        let (exr_done, pngs_done) = rayon::join(
            || exr.finish(),
            || {
                pngs.into_par_iter()
                    .map(|p| {
                        let path = p.path().to_path_buf();
                        p.finish().map(|()| path)
                    })
                    .collect::<Result<Vec<PathBuf>>>()
            },
        );
        exr_done?;
        let mut written = vec![exr_path];
        written.extend(pngs_done.context("writing PNG previews")?);
        report_written(&written, file, stats.not_converged);
        let window = layout.window;
        Ok(Traced {
            seconds: stats.elapsed.as_secs_f64(),
            rays: u64::from(window.width()) * u64::from(window.height()) * u64::from(stats.spp),
            // the writing that was not overlapped with the trace
            write_seconds: trace_start.elapsed().saturating_sub(stats.elapsed).as_secs_f64(),
        })
    }

    /// Several views `(camera, index, file)`, each traced into a frame and written from it
    /// ([`render_views`]); views trace and write at once, so the trace time includes writing.
    fn whole_frames(&self, views: &[(&Camera, usize, &str)], before: &UncertainBefore) -> Result<Traced> {
        let write_seconds = Mutex::new(0.0f64);
        let trace_start = Instant::now();
        let rays = AtomicU64::new(0);
        let cameras: Vec<&Camera> = views.iter().map(|v| v.0).collect();
        render_views(self.scene, &cameras, self.options, |k, frame| {
            let (camera, index, file) = views[k];
            let write_start = Instant::now();
            self.write_frame(camera, index, file, &frame)?;
            *write_seconds.lock().unwrap_or_else(PoisonError::into_inner) += write_start.elapsed().as_secs_f64();
            let pixels = u64::from(frame.window.width()) * u64::from(frame.window.height());
            rays.fetch_add(pixels * u64::from(frame.spp), Ordering::Relaxed);
            Ok::<(), anyhow::Error>(())
        })?;
        before.warn_since();
        Ok(Traced {
            seconds: trace_start.elapsed().as_secs_f64(),
            rays: rays.into_inner(),
            write_seconds: write_seconds.into_inner().unwrap_or_else(PoisonError::into_inner),
        })
    }

    /// Writes view `index` (through `camera`, to `file`) from its frame: EXR and previews in
    /// parallel, each atomically.
    fn write_frame(&self, camera: &Camera, index: usize, file: &str, frame: &Frame) -> Result<()> {
        let exr_path = self.dir.join(file);
        eprintln!("writing {}{} …", exr_path.display(), self.and_previews());
        let header = self.exr_header(camera, index);
        let preview_stem = file.trim_end_matches(".exr");
        let (exr, pngs) = rayon::join(
            || write_exr_with(frame, &exr_path, &header, self.args.compression),
            || {
                if self.previews {
                    write_previews(frame, self.dir, preview_stem, self.background)
                } else {
                    Ok(Vec::new())
                }
            },
        );
        exr?;
        let mut written = vec![exr_path];
        written.extend(pngs.context("writing PNG previews")?);
        report_written(&written, file, frame.not_converged);
        Ok(())
    }
}

/// The line a finished render prints on stdout: what was traced, at what speed, and the wall
/// time's parts. One view writes while it traces: its write time is what was left after the
/// trace.
fn print_summary(
    scene: &Scene,
    cameras: &[&Camera],
    crop: Option<Window>,
    traced: &Traced,
    wall: Instant,
    load_time: Duration,
    cpu_before_trace: Option<f64>,
) {
    let cpu = match (cpu_before_trace, process_cpu_seconds()) {
        (Some(a), Some(b)) => format!("; CPU {:.2} s", b - a),
        _ => String::new(),
    };
    let (what, trace, write) = if let [c] = cameras {
        let w = crop.map_or(c.width, |w| w.width());
        let h = crop.map_or(c.height, |w| w.height());
        (format!("{w}x{h}"), "trace", " after the trace")
    } else {
        (format!("{} views", cameras.len()), "trace and write", "")
    };
    println!(
        "rendered {what} at {} spp ({} objects) on {} threads: {trace} {} s ({:.2} Mrays/s), wall {:.3} s (load+BVH {:.3} s, write {:.3} s{write}{cpu})",
        scene.sampling.spp,
        scene.objects.len(),
        rayon::current_num_threads(),
        significant_seconds(traced.seconds),
        traced.rays as f64 / traced.seconds.max(1e-12) / 1e6,
        wall.elapsed().as_secs_f64(),
        load_time.as_secs_f64(),
        traced.write_seconds,
    );
}

/// `seconds` with three decimals, or with three significant digits where that needs more (a
/// small render's trace takes well under a millisecond, which three decimals would print as 0).
fn significant_seconds(seconds: f64) -> String {
    let decimals = if seconds > 0.0 && seconds < 0.1 {
        (2.0 - seconds.log10().floor()).min(12.0) as usize
    } else {
        3
    };
    format!("{seconds:.decimals$}")
}

/// Prints the files written for view file `file`, and a warning for its samples without a ray.
fn report_written(written: &[PathBuf], file: &str, not_converged: u64) {
    for path in written {
        eprintln!("wrote {}", path.display());
    }
    if not_converged > 0 {
        eprintln!(
            "warning: {file}: {not_converged} pixel samples had no ray because the lens undistortion did not converge to \
             1e-12 px there (strong distortion beyond its invertible region); they hold the miss values"
        );
    }
}

/// Uncertain events since the counts taken before tracing: the generic root finder's budget
/// exhaustions and the `Function` roots the interval isolation could not decide.
fn uncertain_events_since(exhausted_before: u64, function_before: UncertainCounts) -> u64 {
    let f = uncertain_since(function_before);
    budget_exhaustions() - exhausted_before + f.tangent + f.exhausted + f.undefined
}

/// Warns when rays' answers are uncertain after a render.
fn warn_uncertain(exhausted: u64) {
    if exhausted > 0 {
        eprintln!(
            "{}",
            uncertain_warning(exhausted, "rays (primary or shadow)", "--aov Uncertain")
        );
    }
}

/// Writes `NAME.cameras.json` for every view (and `transforms.json` when asked) into `dir`,
/// each atomically.
/// The paths of the files a render writes: each selected view's EXR and previews, the cameras
/// file and, with `--transforms`, `transforms.json`.
fn output_files(
    views: &[(&Camera, String)],
    selected: &[usize],
    dir: &Path,
    stem: &str,
    previews: bool,
    transforms: bool,
) -> Vec<PathBuf> {
    let mut paths = vec![dir.join(format!("{stem}.cameras.json"))];
    if transforms {
        paths.push(dir.join("transforms.json"));
    }
    for &i in selected {
        let file = &views[i].1;
        paths.push(dir.join(file));
        if previews {
            let preview_stem = file.trim_end_matches(".exr");
            paths.extend(
                PREVIEWS
                    .iter()
                    .map(|(_, name)| dir.join(format!("{preview_stem}.{name}.png"))),
            );
        }
    }
    paths
}

fn write_camera_files(views: &[(&Camera, String)], dir: &Path, stem: &str, transforms: bool) -> Result<()> {
    let path = dir.join(format!("{stem}.cameras.json"));
    let text = cameras_json(views);
    write_atomically(&path, |w| Ok(w.write_all(text.as_bytes())?))?;
    eprintln!("wrote {}", path.display());
    if transforms {
        let text = transforms_json(views).map_err(|m| anyhow::anyhow!("--transforms: {m}"))?;
        let path = dir.join("transforms.json");
        write_atomically(&path, |w| Ok(w.write_all(text.as_bytes())?))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// `(directory, file stem)` for the outputs: a path ending in `.exr` names the EXR file; an
/// existing directory or a path without an extension is the directory; anything else (`-o
/// img.png`) is refused rather than created as a directory.
fn output_location(output: &Path, scene: &Path) -> Result<(PathBuf, String)> {
    match output.extension() {
        Some(e) if e.eq_ignore_ascii_case("exr") => {
            let stem = output
                .file_stem()
                .context("output file name")?
                .to_string_lossy()
                .into_owned();
            Ok((crate::output::atomic::parent_dir(output), stem))
        }
        Some(e) if !output.is_dir() => bail!(
            "-o {}: the output is a directory or a file ending in .exr, not .{} (PNG previews are written next to the EXR)",
            output.display(),
            e.to_string_lossy()
        ),
        _ => {
            let stem = scene
                .file_stem()
                .context("scene file name")?
                .to_string_lossy()
                .into_owned();
            Ok((output.to_path_buf(), stem))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::significant_seconds;

    /// Three decimals from a tenth of a second on, three significant digits below.
    #[test]
    fn trace_seconds_keep_three_significant_digits() {
        assert_eq!(significant_seconds(1.5), "1.500");
        assert_eq!(significant_seconds(0.25), "0.250");
        assert_eq!(significant_seconds(0.0301), "0.0301");
        assert_eq!(significant_seconds(0.000_443), "0.000443");
        assert_eq!(significant_seconds(0.0), "0.000");
    }
}
