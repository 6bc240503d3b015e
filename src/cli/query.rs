//! `zeroset query`: batches of rays from a file (or image positions), their first hits written
//! as CSV or NPY ([`crate::query`]).

use super::{uncertain_warning, BatchFormat, QueryArgs};
use crate::diagnostics::{uncertain_message, uncertain_since};
use crate::output::atomic::{check_destination, AtomicFile, WritebackFile};
use crate::query::rays::{scene_magnitude, RangeConvention, RaySetup};
use crate::query::{
    run_batch_in, CsvHits, CsvRays, HitSink, NpyHits, NpyRays, NpyStream, RaySource, VecRays, CHUNK_RAYS,
};
use crate::resources::open_input;
use crate::scene::Scene;
use anyhow::{bail, Context, Result};
use std::io::{BufReader, BufWriter};
use std::time::Instant;

pub(super) fn query_command(args: &QueryArgs) -> Result<()> {
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
            // a regular file within the input limit (never a FIFO or device), read with that bound;
            // standard input streams (lines and headers are bounded by the readers)
            let input: Box<dyn std::io::Read + Send> = if rays.as_os_str() == "-" {
                Box::new(std::io::stdin())
            } else {
                let file = open_input(rays, "ray file").with_context(|| format!("reading {rays_name}"))?;
                Box::new(file.into_reader())
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
    if args.all_hits {
        return all_hits_command(args, &scene, source.as_mut(), format, wall);
    }
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

/// `zeroset query --all-hits`: every crossing of every ray, one row each
/// ([`crate::query::all_hits`]).
fn all_hits_command(
    args: &QueryArgs,
    scene: &Scene,
    source: &mut (dyn RaySource + Send),
    format: BatchFormat,
    wall: Instant,
) -> Result<()> {
    use crate::query::all_hits::{run_all_hits, ALL_HITS_COLUMNS};
    use crate::query::point_table::TableSink;
    let (rays, crossings) = if args.output.as_os_str() == "-" {
        if format == BatchFormat::Npy {
            bail!("--all-hits writes .npy to a file only (the row count is known at the end); use -o FILE.npy");
        }
        let mut sink = TableSink::csv(BufWriter::with_capacity(1 << 20, std::io::stdout()), &ALL_HITS_COLUMNS);
        let counts = run_all_hits(scene, source, &mut sink)?;
        sink.finish()?;
        counts
    } else {
        check_destination(&crate::output::atomic::parent_dir(&args.output), 0)?;
        let mut file = AtomicFile::create(&args.output)?;
        let counts = {
            let writer = BufWriter::with_capacity(1 << 20, WritebackFile::new(file.file()));
            let mut sink = match format {
                BatchFormat::Csv => TableSink::csv(writer, &ALL_HITS_COLUMNS),
                BatchFormat::Npy => TableSink::npy(writer, ALL_HITS_COLUMNS.len(), None),
            };
            let counts =
                run_all_hits(scene, source, &mut sink).with_context(|| format!("writing {}", args.output.display()))?;
            sink.finish_seekable()
                .with_context(|| format!("writing {}", args.output.display()))?;
            counts
        };
        file.commit()?;
        counts
    };
    let elapsed = wall.elapsed().as_secs_f64();
    eprintln!(
        "{rays} rays, {crossings} crossings in {elapsed:.3} s end to end ({:.2} Mrays/s)",
        rays as f64 / elapsed.max(1e-12) / 1e6
    );
    Ok(())
}
