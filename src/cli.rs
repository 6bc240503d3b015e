//! The `zeroset` command line. [`main`] is public so a user's own binary can register its
//! primitive types and then run the same CLI (see `docs/adding-a-primitive.md`).

use crate::aov::Aov;
use crate::camera::Camera;
use crate::output::cameras_json::{cameras_json, exr_camera_attributes, transforms_json};
use crate::output::exr::{write_exr, ExrHeader};
use crate::output::png::write_previews;
use crate::query::{first_hits, format_hits, parse_rays};
use crate::render::{render_view, Frame, RenderOptions, Window};
use crate::scene::Scene;
use crate::views::{render_views, view_files};
use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

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
    /// First hits of a batch of rays (CSV in, CSV out).
    Query(QueryArgs),
    /// List the primitive names scene files may use.
    Primitives,
}

/// `zeroset render`.
#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    /// Scene file (RON).
    pub scene: PathBuf,
    /// Output: a directory (files named after the scene) or a path ending in `.exr`.
    #[arg(short, long, default_value = "out")]
    pub output: PathBuf,
    /// Override the image width (the vertical field of view is kept).
    #[arg(long)]
    pub width: Option<u32>,
    /// Override the image height.
    #[arg(long)]
    pub height: Option<u32>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// AOVs to write, comma-separated (default: the scene's `outputs.aovs`).
    #[arg(long, value_delimiter = ',', value_enum, ignore_case = true)]
    pub aov: Option<Vec<Aov>>,
    /// Render only the pixel window `x0,y0,x1,y1` (half-open): the EXR keeps the full display
    /// window with this data window, so crops of one frame can be stitched (e.g. `oiiotool
    /// a.exr b.exr --over -o full.exr`, or any EXR tool honouring data windows).
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
    /// Render only view I of the scene's `views` (to `NAME.IIII.exr`).
    #[arg(long, value_name = "I")]
    pub view: Option<usize>,
    /// Also write `transforms.json` (NeRF / instant-ngp convention) beside the EXRs.
    #[arg(long)]
    pub transforms: bool,
}

/// `zeroset query`.
#[derive(Debug, clap::Args)]
pub struct QueryArgs {
    /// Scene file (RON).
    pub scene: PathBuf,
    /// Rays, one per line: `ox,oy,oz,dx,dy,dz[,tmin,tmax]`.
    #[arg(long, required_unless_present = "pixels", conflicts_with = "pixels")]
    pub rays: Option<PathBuf>,
    /// Image positions instead of rays, one per line: `x,y[,view]` (pixel (i, j)'s centre is
    /// (i + 0.5, j + 0.5)); rays from the scene's camera, or from `--camera`'s.
    #[arg(long)]
    pub pixels: Option<PathBuf>,
    /// Scene file whose camera (and views) turn `--pixels` into rays (default: the queried scene).
    #[arg(long, requires = "pixels", value_name = "SCENE")]
    pub camera: Option<PathBuf>,
    /// Output CSV (`-` for stdout).
    #[arg(short, long, default_value = "-")]
    pub output: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

/// Runs the CLI on the process arguments; prints errors to stderr and returns a failing exit
/// code on any error.
#[must_use]
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Runs one parsed command.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(args) => with_threads(args.threads, || render_command(&args)),
        Command::Query(args) => with_threads(args.threads, || query_command(&args)),
        Command::Primitives => {
            for name in crate::registry::registered_names() {
                println!("{name}");
            }
            Ok(())
        }
    }
}

fn with_threads(threads: Option<usize>, f: impl FnOnce() -> Result<()> + Send) -> Result<()> {
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
    let load_start = Instant::now();
    let mut scene = Scene::load(&args.scene)?;
    let load_time = load_start.elapsed();
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
            if w.x0 >= w.x1 || w.y0 >= w.y1 || w.x1 > scene.camera.width || w.y1 > scene.camera.height {
                bail!(
                    "--crop {},{},{},{}: need x0 < x1 ≤ {} and y0 < y1 ≤ {}",
                    c[0],
                    c[1],
                    c[2],
                    c[3],
                    scene.camera.width,
                    scene.camera.height
                );
            }
            Some(w)
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
    let aovs = args.aov.clone().unwrap_or_else(|| scene.outputs.aovs.clone());
    let (dir, stem) = output_location(&args.output, &args.scene)?;
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;

    let views = view_files(&scene, &stem);
    write_camera_files(&views, &dir, &stem, args.transforms)?;
    let selected: Vec<usize> = match args.view {
        None => (0..views.len()).collect(),
        Some(_) if scene.views.is_empty() => bail!("--view: {} has no `views`", args.scene.display()),
        Some(i) if i >= views.len() => bail!("--view {i}: the scene has views 0 to {}", views.len() - 1),
        Some(i) => vec![i],
    };
    let options = RenderOptions {
        aovs,
        crop,
        depth_miss: args.depth_miss,
        progress: selected.len() == 1,
    };
    let cameras: Vec<&Camera> = selected.iter().map(|&i| views[i].0).collect();
    let start = Instant::now();
    let write_view = |k: usize, frame: Frame| -> Result<Frame> {
        let index = selected[k];
        let (camera, file) = (views[index].0, &views[index].1);
        let exr_path = dir.join(file);
        let header = ExrHeader {
            world_to_camera: camera.world_to_camera(),
            world_to_ndc: camera.world_to_ndc(0.01, 1000.0),
            scene_file: args.scene.display().to_string(),
            depth_miss: args.depth_miss,
            camera_attributes: exr_camera_attributes(camera, index, file),
        };
        write_exr(&frame, &exr_path, &header).with_context(|| format!("writing {}", exr_path.display()))?;
        let mut written = vec![exr_path];
        if scene.outputs.previews && !args.no_previews {
            let preview_stem = file.trim_end_matches(".exr");
            written.extend(write_previews(&frame, &dir, preview_stem).context("writing PNG previews")?);
        }
        for path in &written {
            eprintln!("wrote {}", path.display());
        }
        if frame.not_converged > 0 {
            eprintln!(
                "warning: {file}: {} pixel samples had no ray because the lens undistortion did not converge to \
                 1e-12 px there (strong distortion beyond its invertible region); they hold the miss values",
                frame.not_converged
            );
        }
        Ok(frame)
    };
    if cameras.len() == 1 {
        let frame = write_view(0, render_view(&scene, cameras[0], &options))?;
        println!(
            "rendered {}x{} at {} spp ({} objects, load+BVH {:.3} s) in {:.3} s: {:.2} Mrays/s on {} threads",
            frame.window.width(),
            frame.window.height(),
            scene.sampling.spp,
            scene.objects.len(),
            load_time.as_secs_f64(),
            frame.elapsed.as_secs_f64(),
            frame.mrays_per_second(),
            rayon::current_num_threads()
        );
        return Ok(());
    }
    let rays = AtomicU64::new(0);
    render_views(&scene, &cameras, &options, |k, frame| {
        let frame = write_view(k, frame)?;
        let pixels = u64::from(frame.window.width()) * u64::from(frame.window.height());
        rays.fetch_add(pixels * u64::from(frame.spp), Ordering::Relaxed);
        Ok::<(), anyhow::Error>(())
    })?;
    let elapsed = start.elapsed().as_secs_f64();
    println!(
        "rendered {} views at {} spp ({} objects, load+BVH {:.3} s) in {:.3} s ({:.4} s per view, files included): \
         {:.2} Mrays/s on {} threads",
        cameras.len(),
        scene.sampling.spp,
        scene.objects.len(),
        load_time.as_secs_f64(),
        elapsed,
        elapsed / cameras.len() as f64,
        rays.into_inner() as f64 / elapsed.max(1e-12) / 1e6,
        rayon::current_num_threads()
    );
    Ok(())
}

/// Writes `NAME.cameras.json` for every view (and `transforms.json` when asked) into `dir`.
fn write_camera_files(views: &[(&Camera, String)], dir: &Path, stem: &str, transforms: bool) -> Result<()> {
    let path = dir.join(format!("{stem}.cameras.json"));
    std::fs::write(&path, cameras_json(views)).with_context(|| format!("writing {}", path.display()))?;
    eprintln!("wrote {}", path.display());
    if transforms {
        let text = transforms_json(views).map_err(|m| anyhow::anyhow!("--transforms: {m}"))?;
        let path = dir.join("transforms.json");
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// `(directory, file stem)` for the outputs.
fn output_location(output: &Path, scene: &Path) -> Result<(PathBuf, String)> {
    if output.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        let dir = output.parent().map_or_else(|| PathBuf::from("."), Path::to_path_buf);
        let stem = output
            .file_stem()
            .context("output file name")?
            .to_string_lossy()
            .into_owned();
        Ok((
            if dir.as_os_str().is_empty() {
                PathBuf::from(".")
            } else {
                dir
            },
            stem,
        ))
    } else {
        let stem = scene
            .file_stem()
            .context("scene file name")?
            .to_string_lossy()
            .into_owned();
        Ok((output.to_path_buf(), stem))
    }
}

fn query_command(args: &QueryArgs) -> Result<()> {
    let scene = Scene::load(&args.scene)?;
    let rays = match (&args.rays, &args.pixels) {
        (Some(file), _) => {
            let text = std::fs::read_to_string(file).with_context(|| format!("reading {}", file.display()))?;
            parse_rays(&text, &file.display().to_string())?
        }
        (None, Some(pixels)) => crate::pixels::pixel_rays_from_files(&scene, args.camera.as_deref(), pixels)?,
        (None, None) => bail!("give --rays or --pixels"),
    };
    let start = Instant::now();
    let hits = first_hits(&scene, &rays);
    let elapsed = start.elapsed();
    let csv = format_hits(&scene, &hits);
    if args.output.as_os_str() == "-" {
        print!("{csv}");
    } else {
        std::fs::write(&args.output, csv).with_context(|| format!("writing {}", args.output.display()))?;
    }
    eprintln!(
        "{} rays, {} hits in {:.3} s ({:.2} Mrays/s)",
        rays.len(),
        hits.iter().filter(|h| h.is_some()).count(),
        elapsed.as_secs_f64(),
        rays.len() as f64 / elapsed.as_secs_f64().max(1e-12) / 1e6
    );
    Ok(())
}
