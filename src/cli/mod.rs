//! The `zeroset` command line. [`main`] is public so a user's own binary can register its
//! primitive types and then run the same CLI (see `docs/adding-a-primitive.md`).

mod points;
mod query;
mod render;

use points::points_command;
use query::query_command;
use render::render_command;

use crate::output::exr::ExrCompression;
use crate::output::merge::merge_crops;
use crate::resources::capped_threads;
use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

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
    /// First hits of a batch of rays (CSV or NumPy .npy in and out, streamed); every crossing
    /// with `--all-hits`.
    Query(QueryArgs),
    /// Point queries: nearest surface point, distance, signed distance, occupancy or Φ at each
    /// point of a file (CSV or NumPy .npy in and out, streamed).
    Points(PointsArgs),
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
    #[arg(long, value_name = "f32|f64|E", allow_hyphen_values = true)]
    pub origin_precision: Option<zeroset_primitives::offset::PointPrecision>,
    /// Order in which each chunk's rays are traced (the answers and the output order are the
    /// same): `input` as given, `sorted` grouped for coherence (direction octant, origin cell,
    /// direction) and traced in packets. `input` (whose runs of 8 rays pointing alike, such as a
    /// camera's rays in pixel order, are traced as packets too) is the faster on every batch
    /// measured (`docs/performance.md`).
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
    /// Every crossing along each ray instead of the first hit: one row per crossing,
    /// `ray,t,px,py,pz,nx,ny,nz,id,primitive,u,v,entering` (`ray` the 0-based input row,
    /// `entering` 1 where the ray enters the solid), rays in input order, crossings in
    /// increasing `t`; a crossing at an edge shared by triangles is reported once.
    #[arg(long, conflicts_with = "uncertain")]
    pub all_hits: bool,
}

/// `zeroset points`.
#[derive(Debug, clap::Args)]
pub struct PointsArgs {
    /// Scene file (RON).
    pub scene: PathBuf,
    /// Points: CSV `x,y,z` per line, or a `.npy` array of shape (N, 3); `-` for stdin.
    #[arg(long)]
    pub points: PathBuf,
    /// Input format (default: from the extension, `.npy` or CSV).
    #[arg(long, value_enum, ignore_case = true)]
    pub points_format: Option<BatchFormat>,
    /// What to compute: `closest` (x,y,z,distance,lower,upper,id,primitive), `distance`
    /// (distance,lower,upper), `signed` (signed_distance,lower,upper; negative inside),
    /// `occupancy` (1 inside, 0 outside) or `phi` (phi,gx,gy,gz). `lower == upper` where the
    /// distance is exact; otherwise they bound it and `distance` is the upper end.
    #[arg(long, value_enum, ignore_case = true)]
    pub query: crate::query::point_table::PointQuery,
    /// How a mesh decides inside from outside (signed, occupancy): fast-winding (default),
    /// winding, pseudonormal or parity. Analytic solids use the sign of Φ.
    #[arg(long, default_value = "fast-winding")]
    pub sign: zeroset_primitives::SignMethod,
    /// Output file (`.npy` or CSV by extension), or `-` for stdout (CSV unless `--format npy`).
    #[arg(short, long, default_value = "-")]
    pub output: PathBuf,
    /// Output format (default: from the output's extension).
    #[arg(long, value_enum, ignore_case = true)]
    pub format: Option<BatchFormat>,
    /// Worker threads (default: all cores).
    #[arg(short = 't', long)]
    pub threads: Option<usize>,
}

/// Runs the CLI on the process arguments; prints errors to stderr and returns a failing exit
/// code on any error.
#[must_use]
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    // an interrupt removes the unfinished outputs (the finished and previous ones stay)
    if let Err(e) = crate::output::interrupt::install_handlers() {
        eprintln!("warning: interrupts will not clean up temporary outputs: {e}");
    }
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
        Command::Points(args) => with_threads(args.threads, || points_command(&args)),
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
        let (n, warning) = capped_threads(requested, "--threads");
        if let Some(w) = warning {
            eprintln!("warning: {w}");
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

/// The warning for rays whose root finder ran out of its evaluation budget.
fn uncertain_warning(count: u64, what: &str, flag: &str) -> String {
    format!(
        "warning: {count} {what} may be wrong: the root finder ran out of its evaluation budget \
         (counted as misses past that point; a tighter `lipschitz` bound or search box helps) or \
         a `Function` root could not be decided exactly (below); {flag} flags them"
    )
}
