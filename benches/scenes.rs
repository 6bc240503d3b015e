//! Whole-scene primary-ray benchmark: `cargo bench --bench scenes [-- SCENE.ron ...]`.
//!
//! For each scene (default: `scenes/bench/*.ron`) it reports scene load + BVH build time, then
//! renders the scene's default outputs (beauty, A, Z, N) at its own resolution `RUNS` times on 1
//! and on 2 threads and prints the median wall time and Mrays/s, plus the process's peak
//! resident memory. The reference figures from `../shared/anchors/README.md` (same scenes, a
//! 2-core machine of the same kind) are printed beside them.

use std::path::PathBuf;
use std::time::Instant;
use zeroset::render::{render, RenderOptions};
use zeroset::scene::Scene;

const RUNS: usize = 7;

/// Mrays/s of the reference systems on the same scenes (2 threads): POV-Ray 3.7, Mitsuba 3 LLVM
/// AOV integrator, Mitsuba 3 scalar AOV integrator.
fn reference(stem: &str) -> Option<(f64, f64, f64)> {
    match stem {
        "spheres1k" => Some((5.9, 13.1, 1.9)),
        "quadrics" => Some((10.1, 45.5, 0.7)),
        _ => None,
    }
}

fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("VmHWM:")).map(str::to_owned))
        .and_then(|l| l.split_whitespace().nth(1).and_then(|kb| kb.parse::<f64>().ok()))
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    let scenes: Vec<PathBuf> = if args.is_empty() {
        let mut v: Vec<PathBuf> = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/bench"))
            .expect("scenes/bench exists")
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "ron"))
            .collect();
        v.sort();
        v
    } else {
        args.iter().map(PathBuf::from).collect()
    };
    println!(
        "| scene | objects | load+BVH ms | threads | median s | Mrays/s | POV-Ray | Mitsuba LLVM | Mitsuba scalar | peak RSS MiB |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for path in scenes {
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        let start = Instant::now();
        let scene = match Scene::load(&path) {
            Ok(s) => s,
            Err(e) => {
                println!("| {stem} | skipped: {e} |");
                continue;
            }
        };
        let load_ms = start.elapsed().as_secs_f64() * 1e3;
        let options = RenderOptions {
            aovs: scene.outputs.aovs.clone(),
            ..RenderOptions::default()
        };
        let rays = f64::from(scene.camera.width) * f64::from(scene.camera.height);
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let times: Vec<f64> = (0..RUNS)
                .map(|_| pool.install(|| render(&scene, &options)).elapsed.as_secs_f64())
                .collect();
            let t = median(times);
            let (pov, mitsuba, scalar) = match (threads, reference(&stem)) {
                (2, Some((a, b, c))) => (format!("{a}"), format!("{b}"), format!("{c}")),
                _ => ("–".into(), "–".into(), "–".into()),
            };
            println!(
                "| {stem} | {} | {load_ms:.1} | {threads} | {t:.4} | {:.2} | {pov} | {mitsuba} | {scalar} | {:.0} |",
                scene.objects.len(),
                rays / t / 1e6,
                peak_rss_mib()
            );
        }
    }
}
