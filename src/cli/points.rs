//! `zeroset points`: point queries (nearest point, distance, signed distance, occupancy, Φ) over
//! a file of points, written as CSV or NPY ([`crate::query::point_table`]).

use super::{BatchFormat, PointsArgs};
use crate::output::atomic::{check_destination, AtomicFile, WritebackFile};
use crate::query::point_table::{run_points, CsvPoints, NpyPoints, PointSource, TableSink};
use crate::resources::open_input;
use crate::scene::Scene;
use anyhow::{bail, Context, Result};
use std::io::{BufReader, BufWriter};
use std::time::Instant;

pub(super) fn points_command(args: &PointsArgs) -> Result<()> {
    let wall = Instant::now();
    let scene = Scene::load(&args.scene)?;
    crate::diagnostics::print_load_warnings(&scene);
    let name = args.points.display().to_string();
    let input: Box<dyn std::io::Read + Send> = if args.points.as_os_str() == "-" {
        Box::new(std::io::stdin())
    } else {
        let file = open_input(&args.points, "point file").with_context(|| format!("reading {name}"))?;
        Box::new(file.into_reader())
    };
    let input = BufReader::with_capacity(1 << 20, input);
    let mut source: Box<dyn PointSource + Send> =
        match args.points_format.unwrap_or_else(|| BatchFormat::of(&args.points)) {
            BatchFormat::Csv => Box::new(CsvPoints::new(input, &name)),
            BatchFormat::Npy => Box::new(NpyPoints::new(input, &name)?),
        };
    let columns = args.query.columns();
    let format = args.format.unwrap_or_else(|| BatchFormat::of(&args.output));
    let count = if args.output.as_os_str() == "-" {
        let stdout = BufWriter::with_capacity(1 << 20, std::io::stdout());
        let mut sink = match format {
            BatchFormat::Csv => TableSink::csv(stdout, columns),
            BatchFormat::Npy => {
                let Some(rows) = source.len_hint() else {
                    bail!("writing .npy to stdout needs .npy points (the row count goes first); use -o FILE.npy");
                };
                TableSink::npy(stdout, columns.len(), Some(rows))
            }
        };
        let count = run_points(&scene, source.as_mut(), &name, args.query, args.sign, &mut sink)?;
        sink.finish()?;
        count
    } else {
        check_destination(&crate::output::atomic::parent_dir(&args.output), 0)?;
        let mut file = AtomicFile::create(&args.output)?;
        let count = {
            let writer = BufWriter::with_capacity(1 << 20, WritebackFile::new(file.file()));
            let mut sink = match format {
                BatchFormat::Csv => TableSink::csv(writer, columns),
                BatchFormat::Npy => TableSink::npy(writer, columns.len(), source.len_hint()),
            };
            let count = run_points(&scene, source.as_mut(), &name, args.query, args.sign, &mut sink)
                .with_context(|| format!("writing {}", args.output.display()))?;
            sink.finish_seekable()
                .with_context(|| format!("writing {}", args.output.display()))?;
            count
        };
        file.commit()?;
        count
    };
    let elapsed = wall.elapsed().as_secs_f64();
    eprintln!(
        "{count} points in {elapsed:.3} s end to end ({:.2} Mpoints/s)",
        count as f64 / elapsed.max(1e-12) / 1e6
    );
    Ok(())
}
