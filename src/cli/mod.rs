//! The `zeroset` command line. [`main`] is public so a user's own binary can register its
//! primitive types and then run the same CLI (see `docs/adding-a-primitive.md`).

pub mod resources;

use crate::aov::Aov;
use crate::camera::Camera;
use crate::cli::resources::{capped_threads, check_memory, process_cpu_seconds, render_memory_estimate};
use crate::diagnostics::{uncertain_message, uncertain_since};
use crate::output::atomic::{check_destination, write_atomically, AtomicFile, WritebackFile};
use crate::output::cameras_json::{cameras_json, exr_camera_attributes, transforms_json};
use crate::output::exr::{size_estimate, write_exr_with, ExrCompression, ExrHeader};
use crate::output::exr_stream::ExrStream;
use crate::output::merge::merge_crops;
use crate::output::png::{write_previews, PREVIEWS};
use crate::output::png_stream::PreviewStream;
use crate::query::rays::{scene_magnitude, RangeConvention, RaySetup};
use crate::query::{
    run_batch_in, CsvHits, CsvRays, HitSink, NpyHits, NpyRays, NpyStream, RaySource, VecRays, CHUNK_RAYS,
};
use crate::render::stream::{render_view_to, BandSink};
use crate::render::views::{render_views, view_files};
use crate::render::{Frame, FrameLayout, RenderOptions, Window};
use crate::scene::Scene;
use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use rayon::iter::{IntoParallelIterator, ParallelIterator};
use std::io::{BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;
use zeroset_primitives::root::budget_exhaustions;

/// zeroset: a ray caster for implicit surfaces with exact depth and normal AOVs.
#[derive(Debug, Parser)]
#[command(version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a scene to EXR (all requested AOVs) and PNG previews.
    Render(RenderArgs),
    /// First hits of a batch of rays (CSV or NumPy .npy in and out, streamed).
    Query(QueryArgs),
    /// Assemble crops (renders with `--crop`) into the full frame, bit for bit.
    Merge(MergeArgs),
    /// List the primitive names scene files may use.
    Primitives,
}

/// `zeroset render`.
#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    /// Scene file (RON).
    pub scene: PathBuf,
    /// Output: a directory (files named after the scene) or a path ending in `.exr`; any other
    /// extension is an error unless the path is an existing directory.
    #[arg(short, long, default_value = "out")]
    pub output: PathBuf,
    /// Override the image width (the vertical field of view is kept).
    #[arg(long)]
    pub width: Option<u32>,
    /// Override the image height.
    #[arg(long)]
    pub height: Option<u32>,
    /// Worker threads (default: all cores; at most 4 × the cores).
    #[arg(short = 't', long)]
    pub threads: Option<usize>,
    /// AOVs to write, comma-separated, or `all` (default: the scene's `outputs.aovs`).
    #[arg(long, value_delimiter = ',')]
    pub aov: Option<Vec<String>>,
    /// Render only the pixel window `x0,y0,x1,y1` (half-open): the EXR keeps the full display
    /// window with this data window. Stitch crops with `zeroset merge a.exr b.exr -o full.exr`
    /// (exact); with oiiotool use `--add` (`oiiotool a.exr b.exr --add -o full.exr`, exact for
    /// crops that do not overlap), never `--over` (it turns the misses' `Z = inf` into 0).
    #[arg(long, value_delimiter = ',')]
    pub crop: Option<Vec<u32>>,
    /// Value for `Z` and `distance` where nothing was hit (default `inf`; e.g. 0 for pipelines
    /// that want it).
    #[arg(long, default_value_t = f32::INFINITY)]
    pub depth_miss: f32,
    /// Skip the PNG previews.
    #[arg(long)]
    pub no_previews: bool,
    /// Samples per pixel (default: the scene's `sampling.spp`, itself 1 by default).
    #[arg(long)]
    pub spp: Option<u32>,
    /// EXR compression (lossless): none (default, the fastest), rle (2–3× the CPU time of none
    /// for 55–70 % of the size), zips or zip (deflate: 7–22× the time, 13–40 % of the size), piz.
    #[arg(long, value_enum, default_value_t = ExrCompression::default(), ignore_case = true)]
    pub compression: ExrCompression,
    /// Fill the uncovered part of pixels with the scene background in `Beauty` (default: black,
    /// `R, G, B` premultiplied by `A` as EXR expects).
    #[arg(long)]
    pub background: bool,
    /// Render only view I of the scene's `views` (to `NAME.IIII.exr`).
    #[arg(long, value_name = "I")]
    pub view: Option<usize>,
    /// Also write `transforms.json` (NeRF / instant-ngp convention) beside the EXRs.
    #[arg(long)]
    pub transforms: bool,
}

/// `zeroset merge`.
#[derive(Debug, clap::Args)]
pub struct MergeArgs {
    /// Crops of one frame (EXR files written with `--crop`) that tile its display window.
    #[arg(required = true)]
    pub crops: Vec<PathBuf>,
    /// The full frame (EXR).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Formats of `zeroset query` input and output.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BatchFormat {
    /// Comma-separated text.
    Csv,
    /// NumPy `.npy` array.
    Npy,
}

impl BatchFormat {
    /// The format a path's extension names (`.npy`), CSV otherwise.
    fn of(path: &Path) -> Self {
        if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy")) {
            Self::Npy
        } else {
            Self::Csv
        }
    }
}

/// `zeroset query`.
#[derive(Debug, clap::Args)]
pub struct QueryArgs {
    /// Scene file (RON).
    pub scene: PathBuf,
    /// Rays: CSV `ox,oy,oz,dx,dy,dz[,tmin,tmax][,nx,ny,nz]` per line, or a `.npy` array of shape
    /// (N, 6), (N, 8), (N, 9) or (N, 11); `-` for stdin. The range is open at `tmin` (default 0):
    /// the first hit with `t > tmin`, so an origin on a surface does not report it at `t = 0`.
    #[arg(long, required_unless_present = "pixels", conflicts_with = "pixels")]
    pub rays: Option<PathBuf>,
    /// Image positions instead of rays, one per line: `x,y[,view]` (pixel (i, j)'s centre is
    /// (i + 0.5, j + 0.5)); rays from the scene's camera, or from `--camera`'s.
    #[arg(long)]
    pub pixels: Option<PathBuf>,
    /// Scene file whose camera (and views) turn `--pixels` into rays (default: the queried scene).
    #[arg(long, requires = "pixels", value_name = "SCENE")]
    pub camera: Option<PathBuf>,
    /// Format of `--rays` (default: from its extension, `.npy` or CSV).
    #[arg(long, value_enum, ignore_case = true)]
    pub rays_format: Option<BatchFormat>,
    /// Include `tmin` in the range (`tmin ≤ t ≤ tmax`; default `tmin < t ≤ tmax`).
    #[arg(long)]
    pub closed_range: bool,
    /// The origins are surface points known to this precision (`f32`, `f64`, or an absolute error
    /// bound such as `1e-6`); every ray then gives the surface normal `nx,ny,nz` and the origin
    /// is moved off the surface so the ray cannot re-hit it through rounding (see
    /// `docs/numerics.md`, "Spawning rays").
    #[arg(long, value_name = "f32|f64|E")]
    pub origin_precision: Option<zeroset_primitives::offset::PointPrecision>,
    /// Order in which each chunk's rays are traced (the answers and the output order are the
    /// same): `input` as given, `sorted` grouped for coherence (direction octant, origin cell,
    /// direction) and traced in packets. `input` is the faster on every batch measured (see the
    /// README's "Command line", `zeroset query`): random rays, camera rays in pixel order or
    /// shuffled, many cameras' rays shuffled together.
    #[arg(long, value_enum, default_value = "input", ignore_case = true)]
    pub ray_order: crate::query::RayOrder,
    /// Output (`-` for stdout): CSV, or `.npy` (f8, shape (N, 11)).
    #[arg(short, long, default_value = "-")]
    pub output: PathBuf,
    /// Format of the output (default: from its extension, `.npy` or CSV).
    #[arg(long, value_enum, ignore_case = true)]
    pub format: Option<BatchFormat>,
    /// Worker threads (default: all cores; at most 4 × the cores).
    #[arg(short = 't', long)]
    pub threads: Option<usize>,
    /// Add an `uncertain` column: 1 where the ray's answer is not guaranteed (the root finder ran
    /// out of its evaluation budget, or a `Function` root could not be decided exactly).
    #[arg(long)]
    pub uncertain: bool,
}

/// Runs the CLI on the process arguments; prints errors to stderr and returns a failing exit
/// code on any error.
#[must_use]
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_message(&e));
            ExitCode::FAILURE
        }
    }
}

/// Runs one parsed command.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(args) => with_threads(args.threads, || render_command(&args)),
        Command::Query(args) => with_threads(args.threads, || query_command(&args)),
        Command::Merge(args) => {
            merge_crops(&args.crops, &args.output)?;
            eprintln!("wrote {}", args.output.display());
            Ok(())
        }
        Command::Primitives => {
            for name in crate::scene::registry::registered_names() {
                println!("{name}");
            }
            Ok(())
        }
    }
}

/// An error and its causes on one line, each cause only if its text is not already there (a
/// message that quotes its OS error is not followed by the same OS error again).
#[must_use]
pub fn error_message(error: &anyhow::Error) -> String {
    let mut message = String::new();
    for cause in error.chain() {
        let text = cause.to_string();
        if message.contains(&text) {
            continue;
        }
        if !message.is_empty() {
            message.push_str(": ");
        }
        message.push_str(&text);
    }
    message
}

fn with_threads(threads: Option<usize>, f: impl FnOnce() -> Result<()> + Send) -> Result<()> {
    let threads = threads.map(|requested| {
        let (n, warning) = capped_threads(requested);
        if let Some(w) = warning {
            eprintln!("{w}");
        }
        n
    });
    match threads {
        None => f(),
        Some(0) => bail!("--threads must be at least 1"),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .context("creating the thread pool")?
            .install(f),
    }
}

fn render_command(args: &RenderArgs) -> Result<()> {
    let wall = Instant::now();
    let mut scene = Scene::load(&args.scene)?;
    let load_time = wall.elapsed();
    crate::diagnostics::print_load_warnings(&scene);
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
    let aovs = match &args.aov {
        Some(names) => Aov::parse_list(names).map_err(|m| anyhow::anyhow!("--aov {m}"))?,
        None => scene.outputs.aovs.clone(),
    };
    let (dir, stem) = output_location(&args.output, &args.scene)?;
    let previews = scene.outputs.previews && !args.no_previews;

    // resources, before any tracing: memory for the buffers, a writable directory with room
    let window = crop.unwrap_or(Window {
        x0: 0,
        y0: 0,
        x1: scene.camera.width,
        y1: scene.camera.height,
    });
    let pixels = u64::from(window.width()) * u64::from(window.height());
    let mut distinct = aovs.clone();
    distinct.sort();
    distinct.dedup();
    let channels: u64 = distinct.iter().map(|a| a.channels().len() as u64).sum();
    let preview_count = if previews {
        distinct
            .iter()
            .filter(|a| matches!(a, Aov::Beauty | Aov::Depth | Aov::Normal))
            .count() as u64
    } else {
        0
    };
    let memory = render_memory_estimate(
        pixels,
        channels,
        preview_count,
        u64::from(scene.sampling.spp),
        rayon::current_num_threads() as u64,
    );
    check_memory(
        &format!(
            "rendering {}x{} with {channels} channels at {} spp",
            window.width(),
            window.height(),
            scene.sampling.spp
        ),
        memory,
    )?;
    let disk = size_estimate(pixels, channels, u64::from(window.height())) + pixels * 3 * preview_count;
    check_destination(&dir, disk)?;

    let views = view_files(&scene, &stem);
    let selected: Vec<usize> = match args.view {
        None => (0..views.len()).collect(),
        Some(_) if scene.views.is_empty() => bail!("--view: {} has no `views`", args.scene.display()),
        Some(i) if i >= views.len() => bail!("--view {i}: the scene has views 0 to {}", views.len() - 1),
        Some(i) => vec![i],
    };
    write_camera_files(&views, &dir, &stem, args.transforms)?;
    let options = RenderOptions {
        aovs,
        crop,
        depth_miss: args.depth_miss,
        progress: selected.len() == 1,
        background: args.background,
    };
    let cameras: Vec<&Camera> = selected.iter().map(|&i| views[i].0).collect();
    let background = scene.background.as_vec3().to_array();
    let write_seconds = std::sync::Mutex::new(0.0f64);
    // the EXR header of view `index` through `camera`
    let exr_header = |camera: &Camera, index: usize| ExrHeader {
        world_to_camera: camera.world_to_camera(),
        world_to_ndc: camera.world_to_ndc(0.01, 1000.0),
        scene_file: args.scene.display().to_string(),
        depth_miss: args.depth_miss,
        camera_attributes: exr_camera_attributes(camera, index),
    };
    // writes view `k` of `selected` from its frame (EXR and previews in parallel, each atomically)
    let write_view = |k: usize, frame: &Frame| -> Result<()> {
        let index = selected[k];
        let (camera, file) = (views[index].0, &views[index].1);
        let write_start = Instant::now();
        let exr_path = dir.join(file);
        eprintln!(
            "writing {}{} …",
            exr_path.display(),
            if previews { " and PNG previews" } else { "" }
        );
        let header = exr_header(camera, index);
        let preview_stem = file.trim_end_matches(".exr");
        let (exr, pngs) = rayon::join(
            || write_exr_with(frame, &exr_path, &header, args.compression),
            || {
                if previews {
                    write_previews(frame, &dir, preview_stem, background)
                } else {
                    Ok(Vec::new())
                }
            },
        );
        exr?;
        let mut written = vec![exr_path];
        written.extend(pngs.context("writing PNG previews")?);
        report_written(&written, file, frame.not_converged);
        *write_seconds.lock().unwrap_or_else(std::sync::PoisonError::into_inner) += write_start.elapsed().as_secs_f64();
        Ok(())
    };
    let cpu_before_trace = process_cpu_seconds();
    let exhausted_before = budget_exhaustions();
    let function_before = zeroset_primitives::uncertain_counts();
    let (trace_seconds, rays) = if cameras.len() == 1 {
        // one view: its files are written while it is traced (crate::render::stream)
        let index = selected[0];
        let (camera, file) = (views[index].0, &views[index].1);
        let layout = FrameLayout::new(camera, &options);
        let exr_path = dir.join(file);
        let exr = ExrStream::create(&exr_path, &layout, &exr_header(camera, index), args.compression)?;
        let preview_stem = file.trim_end_matches(".exr");
        let pngs: Vec<PreviewStream> = if previews {
            PREVIEWS
                .iter()
                .filter(|(aov, _)| layout.channel_offset(*aov).is_some())
                .map(|(aov, name)| {
                    let path = dir.join(format!("{preview_stem}.{name}.png"));
                    PreviewStream::create(&path, *aov, &layout, background)
                })
                .collect::<Result<_>>()?
        } else {
            Vec::new()
        };
        eprintln!(
            "writing {}{} as rows are traced …",
            exr_path.display(),
            if previews { " and PNG previews" } else { "" }
        );
        let mut sinks: Vec<&dyn BandSink> = vec![&exr];
        sinks.extend(pngs.iter().map(|p| p as &dyn BandSink));
        let trace_start = Instant::now();
        let stats = render_view_to(&scene, camera, &options, &sinks)?;
        drop(sinks);
        warn_uncertain(uncertain_events_since(exhausted_before, function_before));
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
        // the writing that was not overlapped with the trace
        *write_seconds.lock().unwrap_or_else(std::sync::PoisonError::into_inner) =
            trace_start.elapsed().saturating_sub(stats.elapsed).as_secs_f64();
        let window = layout.window;
        let rays = u64::from(window.width()) * u64::from(window.height()) * u64::from(stats.spp);
        (stats.elapsed.as_secs_f64(), rays)
    } else {
        let trace_start = Instant::now();
        let rays = AtomicU64::new(0);
        render_views(&scene, &cameras, &options, |k, frame| {
            write_view(k, &frame)?;
            let pixels = u64::from(frame.window.width()) * u64::from(frame.window.height());
            rays.fetch_add(pixels * u64::from(frame.spp), Ordering::Relaxed);
            Ok::<(), anyhow::Error>(())
        })?;
        warn_uncertain(uncertain_events_since(exhausted_before, function_before));
        // views trace and write at once: the trace time is the total less the writing
        let total = trace_start.elapsed().as_secs_f64();
        (total, rays.into_inner())
    };
    if let Some(message) = uncertain_message(uncertain_since(function_before)) {
        eprintln!("{message}");
    }
    let write_seconds = write_seconds
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let cpu = match (cpu_before_trace, process_cpu_seconds()) {
        (Some(a), Some(b)) => format!("; CPU {:.2} s", b - a),
        _ => String::new(),
    };
    // one view writes while it traces: its write time is what was left after the trace
    let (what, trace, write) = if cameras.len() == 1 {
        let c = cameras[0];
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
        significant_seconds(trace_seconds),
        rays as f64 / trace_seconds.max(1e-12) / 1e6,
        wall.elapsed().as_secs_f64(),
        load_time.as_secs_f64(),
        write_seconds,
    );
    Ok(())
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
fn uncertain_events_since(exhausted_before: u64, function_before: zeroset_primitives::UncertainCounts) -> u64 {
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

/// The warning for rays whose root finder ran out of its evaluation budget.
fn uncertain_warning(count: u64, what: &str, flag: &str) -> String {
    format!(
        "warning: {count} {what} may be wrong: the root finder ran out of its evaluation budget \
         (counted as misses past that point; a tighter `lipschitz` bound or search box helps) or \
         a `Function` root could not be decided exactly (below); {flag} flags them"
    )
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

fn query_command(args: &QueryArgs) -> Result<()> {
    let wall = Instant::now();
    let scene = Scene::load(&args.scene)?;
    crate::diagnostics::print_load_warnings(&scene);
    let setup = RaySetup {
        range: RangeConvention::closed_if(args.closed_range),
        origin_precision: args.origin_precision,
        magnitude: scene_magnitude(&scene),
    };
    let function_before = zeroset_primitives::uncertain_counts();
    let mut source: Box<dyn RaySource + Send> = match (&args.rays, &args.pixels) {
        (Some(rays), _) => {
            let rays_name = rays.display().to_string();
            // `Stdin`, not its lock: the rays are read on whichever thread of the pool is free
            let input: Box<dyn std::io::Read + Send> = if rays.as_os_str() == "-" {
                Box::new(std::io::stdin())
            } else {
                Box::new(std::fs::File::open(rays).with_context(|| format!("reading {rays_name}"))?)
            };
            let input = BufReader::with_capacity(1 << 20, input);
            match args.rays_format.unwrap_or_else(|| BatchFormat::of(rays)) {
                BatchFormat::Csv => Box::new(CsvRays::with_setup(input, &rays_name, setup)),
                BatchFormat::Npy => Box::new(NpyRays::with_setup(input, &rays_name, setup)?),
            }
        }
        (None, Some(pixels)) => Box::new(VecRays::new(crate::query::pixels::pixel_rays_from_files(
            &scene,
            args.camera.as_deref(),
            pixels,
        )?)),
        (None, None) => bail!("give --rays or --pixels"),
    };
    let to_stdout = args.output.as_os_str() == "-";
    let format = args.format.unwrap_or_else(|| BatchFormat::of(&args.output));
    let counts = if to_stdout {
        // `Stdout`, not its lock: the rows are written on whichever thread of the pool is free
        let stdout = BufWriter::with_capacity(1 << 20, std::io::stdout());
        let mut sink: Box<dyn HitSink + Send> = match format {
            BatchFormat::Csv => Box::new(CsvHits::new(stdout, args.uncertain)),
            BatchFormat::Npy => {
                let Some(rows) = source.len_hint() else {
                    bail!("writing .npy to stdout needs .npy rays (the row count goes first); use -o FILE.npy");
                };
                Box::new(NpyStream(NpyHits::with_rows(stdout, rows, args.uncertain)))
            }
        };
        run_batch_in(&scene, source.as_mut(), sink.as_mut(), args.ray_order)?
    } else {
        check_destination(&crate::output::atomic::parent_dir(&args.output), 0)?;
        let mut file = AtomicFile::create(&args.output)?;
        let counts = {
            let writer = BufWriter::with_capacity(1 << 20, WritebackFile::new(file.file()));
            let mut sink: Box<dyn HitSink + Send> = match format {
                BatchFormat::Csv => Box::new(CsvHits::new(writer, args.uncertain)),
                BatchFormat::Npy => Box::new(NpyHits::seekable(writer, args.uncertain)),
            };
            run_batch_in(&scene, source.as_mut(), sink.as_mut(), args.ray_order)
                .with_context(|| format!("writing {}", args.output.display()))?
        };
        file.commit()?;
        counts
    };
    let elapsed = wall.elapsed().as_secs_f64();
    if counts.uncertain > 0 {
        eprintln!("{}", uncertain_warning(counts.uncertain, "rays", "--uncertain"));
    }
    if let Some(message) = uncertain_message(uncertain_since(function_before)) {
        eprintln!("{message}");
    }
    eprintln!(
        "{} rays, {} hits in {elapsed:.3} s end to end ({:.2} Mrays/s; chunks of {CHUNK_RAYS})",
        counts.rays,
        counts.hits,
        counts.rays as f64 / elapsed.max(1e-12) / 1e6
    );
    Ok(())
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
