//! Whole-scene primary-ray benchmark: `cargo bench --bench scenes [-- [--runs N] [--threads 1,2]
//! [--size WxH] SCENE.ron ...]`.
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

/// Command-line settings.
struct Settings {
    runs: usize,
    threads: Vec<usize>,
    size: Option<(u32, u32)>,
    scenes: Vec<PathBuf>,
}

fn settings() -> Settings {
    let mut s = Settings {
        runs: 7,
        threads: vec![1, 2],
        size: None,
        scenes: Vec::new(),
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--runs" => s.runs = args.next().and_then(|v| v.parse().ok()).expect("--runs N"),
            "--threads" => {
                s.threads = args
                    .next()
                    .expect("--threads 1,2")
                    .split(',')
                    .map(|t| t.parse().expect("thread count"))
                    .collect()
            }
            "--size" => {
                let v = args.next().expect("--size WxH");
                let (w, h) = v.split_once('x').expect("--size WxH");
                s.size = Some((w.parse().expect("width"), h.parse().expect("height")));
            }
            "--bench" => {}
            other => s.scenes.push(PathBuf::from(other)),
        }
    }
    s
}

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
    let settings = settings();
    let scenes: Vec<PathBuf> = if settings.scenes.is_empty() {
        let mut v: Vec<PathBuf> = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/bench"))
            .expect("scenes/bench exists")
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "ron"))
            .collect();
        v.sort();
        v
    } else {
        settings.scenes.clone()
    };
    println!(
        "| scene | objects | load+BVH ms | threads | median s | Mrays/s | POV-Ray | Mitsuba LLVM | Mitsuba scalar | peak RSS MiB |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for path in scenes {
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        let start = Instant::now();
        let mut scene = match Scene::load(&path) {
            Ok(s) => s,
            Err(e) => {
                println!("| {stem} | skipped: {e} |");
                continue;
            }
        };
        let load_ms = start.elapsed().as_secs_f64() * 1e3;
        if let Some((w, h)) = settings.size {
            scene.camera = scene.camera.with_resolution(w, h).expect("valid size");
        }
        let options = RenderOptions {
            aovs: scene.outputs.aovs.clone(),
            ..RenderOptions::default()
        };
        let rays = f64::from(scene.camera.width) * f64::from(scene.camera.height);
        for &threads in &settings.threads {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let times: Vec<f64> = (0..settings.runs)
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
