//! `zeroset-bench`: speed against error for every primitive and intersection method of zeroset,
//! whole-scene figures, and the peers (parry3d; Embree and Mitsuba 3 when their Python packages
//! import). Run from the repository root:
//!
//!     cargo run --release --manifest-path bench/Cargo.toml            # everything, < 5 min
//!     cargo run --release --manifest-path bench/Cargo.toml -- --help
//!
//! Writes a markdown report to stdout and `bench-results/` (`results.md`, `primitives.csv`,
//! `torus.csv`, `scenes.csv`, `speed-vs-error.svg`).

mod baselines;
mod cases;
mod dd;
mod measure;
mod output;
mod peers;
mod plot;
mod reference;
mod scenes;
mod torus;

use std::path::PathBuf;
use std::time::Instant;

const HELP: &str = "zeroset-bench: speed against error of every zeroset intersection method

USAGE: cargo run --release --manifest-path bench/Cargo.toml -- [OPTIONS]

OPTIONS:
  --out DIR          output directory (default bench-results)
  --rays N           rays per primitive (default 100000)
  --passes N         timed passes per method, median reported (default 5)
  --seed N           ray seed (default 1)
  --only A,B         primitives to run (Sphere,Plane,Triangle,Disk,Polygon,Box,Cylinder,Cone,Ellipsoid)
  --generic-cap N    most Φ evaluations per ray for the generic finder (default 1000; a miss beyond it)
  --torus-rays N     rays for the torus study (default 40000)
  --scene-runs N     renders per scene and thread count (default 5)
  --no-primitives    skip the per-primitive table
  --no-torus         skip the torus study
  --no-scenes        skip the whole-scene figures
  --no-external      skip Embree / Mitsuba 3 (Python)
  --quick            --rays 20000 --torus-rays 10000 --scene-runs 3 (a smoke run)
  -v, --verbose      print each method as it is measured (stderr)
";

fn main() {
    let mut out = PathBuf::from("bench-results");
    let mut opt = cases::CaseOptions {
        rays: 100_000,
        passes: 5,
        seed: 1,
        generic_cap: 1_000,
        only: None,
        progress: false,
    };
    let (mut torus_rays, mut scene_runs) = (40_000usize, 5usize);
    let (mut primitives, mut torus, mut scenes, mut external) = (true, true, true, true);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = |name: &str| -> String {
            args.next().unwrap_or_else(|| {
                eprintln!("{name} needs a value");
                std::process::exit(2)
            })
        };
        let number = |s: String| -> usize {
            s.parse().unwrap_or_else(|_| {
                eprintln!("not a number: {s}");
                std::process::exit(2)
            })
        };
        match a.as_str() {
            "--out" => out = PathBuf::from(value("--out")),
            "--rays" => opt.rays = number(value("--rays")),
            "--passes" => opt.passes = number(value("--passes")).max(1),
            "--seed" => opt.seed = number(value("--seed")) as u64,
            "--only" => opt.only = Some(value("--only").split(',').map(str::to_owned).collect()),
            "--generic-cap" => opt.generic_cap = number(value("--generic-cap")) as u32,
            "--torus-rays" => torus_rays = number(value("--torus-rays")),
            "--scene-runs" => scene_runs = number(value("--scene-runs")).max(1),
            "--no-primitives" => primitives = false,
            "--no-torus" => torus = false,
            "--no-scenes" => scenes = false,
            "--no-external" => external = false,
            "--quick" => {
                opt.rays = 20_000;
                torus_rays = 10_000;
                scene_runs = 3;
            }
            "-v" | "--verbose" => opt.progress = true,
            "-h" | "--help" => {
                print!("{HELP}");
                return;
            }
            other => {
                eprintln!("unknown argument {other}\n\n{HELP}");
                std::process::exit(2);
            }
        }
    }
    std::fs::create_dir_all(&out).expect("create the output directory");
    let start = Instant::now();
    let mut report = output::Report::new(&opt, scene_runs);

    // whole scenes first, so that their peak memory is not the per-primitive ray sets'
    if scenes {
        eprintln!("[zeroset-bench] whole scenes ({scene_runs} renders per thread count) …");
        report.scenes = scenes::run_all(scene_runs);
    }
    if primitives {
        eprintln!(
            "[zeroset-bench] primitives ({} rays each, {} passes) …",
            opt.rays, opt.passes
        );
        report.rows = cases::run_all(&opt);
    }
    if torus {
        eprintln!("[zeroset-bench] torus: generic against closed form ({torus_rays} rays) …");
        report.torus = Some(torus::run(torus_rays, opt.passes, opt.seed));
    }
    if external {
        eprintln!("[zeroset-bench] Embree / Mitsuba 3 harnesses …");
        report.external = peers::run_external();
    }
    report.elapsed_s = start.elapsed().as_secs_f64();
    let text = report.markdown();
    print!("{text}");
    report.write(&out);
    if !report.rows.is_empty() {
        plot::speed_vs_error(&report.rows, &out.join("speed-vs-error.svg")).expect("write the plot");
    }
    eprintln!(
        "[zeroset-bench] done in {:.0} s; wrote {}/{{results.md, primitives.csv, torus.csv, scenes.csv, speed-vs-error.svg}}",
        report.elapsed_s,
        out.display()
    );
}
