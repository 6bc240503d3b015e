//! The `zeroset` command line. [`main`] is public so a user's own binary can register its
//! primitive types and then run the same CLI (see `docs/adding-a-primitive.md`).

use crate::aov::Aov;
use crate::output::exr::{write_exr, ExrHeader};
use crate::output::png::write_previews;
use crate::query::{first_hits, format_hits, parse_rays_with};
use crate::render::{render, RenderOptions, Window};
use crate::scene::Scene;
use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
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
}

/// `zeroset query`.
#[derive(Debug, clap::Args)]
pub struct QueryArgs {
    /// Scene file (RON).
    pub scene: PathBuf,
    /// Rays, one per line: `ox,oy,oz,dx,dy,dz[,tmin,tmax][,nx,ny,nz]`. The range is open at
    /// `tmin` (default 0): the first hit with `t > tmin`, so an origin on a surface does not
    /// report it at `t = 0`.
    #[arg(long)]
    pub rays: PathBuf,
    /// Include `tmin` in the range (`tmin ≤ t ≤ tmax`; default `tmin < t ≤ tmax`).
    #[arg(long)]
    pub closed_range: bool,
    /// The origins are surface points known to this precision (`f32`, `f64`, or an absolute error
    /// bound such as `1e-6`); every line then gives the surface normal `nx,ny,nz` and the origin
    /// is moved off the surface so the ray cannot re-hit it through rounding (see
    /// `docs/numerics.md`, "Spawning rays").
    #[arg(long, value_name = "f32|f64|E")]
    pub origin_precision: Option<zeroset_primitives::offset::PointPrecision>,
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
    crate::diagnostics::print_load_warnings(&scene);
    if args.width.is_some() || args.height.is_some() {
        let w = args.width.unwrap_or(scene.camera.width);
        let h = args.height.unwrap_or(scene.camera.height);
        scene.camera = scene
            .camera
            .with_resolution(w, h)
            .map_err(|e| anyhow::anyhow!("--width/--height: {e}"))?;
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

    let options = RenderOptions {
        aovs,
        crop,
        depth_miss: args.depth_miss,
        progress: true,
    };
    let before = zeroset_primitives::uncertain_counts();
    let frame = render(&scene, &options);
    if let Some(message) = crate::diagnostics::uncertain_message(crate::diagnostics::uncertain_since(before)) {
        eprintln!("{message}");
    }

    let exr_path = dir.join(format!("{stem}.exr"));
    let header = ExrHeader {
        world_to_camera: scene.camera.world_to_camera(),
        world_to_ndc: scene.camera.world_to_ndc(0.01, 1000.0),
        scene_file: args.scene.display().to_string(),
        depth_miss: args.depth_miss,
    };
    write_exr(&frame, &exr_path, &header).with_context(|| format!("writing {}", exr_path.display()))?;
    let mut written = vec![exr_path];
    if scene.outputs.previews && !args.no_previews {
        written.extend(write_previews(&frame, &dir, &stem).context("writing PNG previews")?);
    }
    for path in &written {
        eprintln!("wrote {}", path.display());
    }
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
    crate::diagnostics::print_load_warnings(&scene);
    let text = std::fs::read_to_string(&args.rays).with_context(|| format!("reading {}", args.rays.display()))?;
    let setup = crate::query_rays::RaySetup {
        range: if args.closed_range {
            crate::query_rays::RangeConvention::Closed
        } else {
            crate::query_rays::RangeConvention::OpenStart
        },
        origin_precision: args.origin_precision,
        magnitude: crate::query_rays::scene_magnitude(&scene),
    };
    let rays = parse_rays_with(&text, &args.rays.display().to_string(), &setup)?;
    let before = zeroset_primitives::uncertain_counts();
    let start = Instant::now();
    let hits = first_hits(&scene, &rays);
    let elapsed = start.elapsed();
    if let Some(message) = crate::diagnostics::uncertain_message(crate::diagnostics::uncertain_since(before)) {
        eprintln!("{message}");
    }
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
