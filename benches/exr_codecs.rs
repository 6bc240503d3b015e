//! EXR codec table: `cargo bench --bench exr_codecs [-- [--runs N] [--size WxH] SCENE.ron ...]`.
//!
//! For each scene (default: `scenes/bench/*.ron` that load) it renders the default AOVs (beauty,
//! A, Z, N: 8 channels) and all AOVs (21 channels) once, then writes each with every lossless
//! codec the `exr` crate offers (`zeroset render --compression`), `RUNS` times, and prints the
//! median write time (wall, all threads; and the process's CPU time from `/proc/self/stat`, less
//! sensitive to other load on the machine), the file size, and both relative to uncompressed. Each
//! file is read back and compared bit for bit with the frame, so a lossy codec cannot win.

use exr::prelude::{read_all_flat_layers_from_file, FlatSamples};
use std::path::PathBuf;
use std::time::Instant;
use zeroset::aov::Aov;
use zeroset::output::exr::{write_exr_with, ExrCompression, ExrHeader};
use zeroset::render::{render, Frame, RenderOptions};
use zeroset::scene::Scene;

fn main() {
    let mut runs = 3;
    let mut size = None;
    let mut scenes: Vec<PathBuf> = Vec::new();
    let mut args = std::env::args().skip(1).filter(|a| a != "--bench");
    while let Some(a) = args.next() {
        match a.as_str() {
            "--runs" => runs = args.next().and_then(|v| v.parse().ok()).expect("--runs N"),
            "--size" => {
                let v = args.next().expect("--size WxH");
                let (w, h) = v.split_once('x').expect("--size WxH");
                size = Some((w.parse().expect("width"), h.parse().expect("height")));
            }
            other => scenes.push(other.into()),
        }
    }
    if scenes.is_empty() {
        let mut found: Vec<PathBuf> = std::fs::read_dir("scenes/bench")
            .expect("scenes/bench")
            .map(|e| e.expect("entry").path())
            .filter(|p| p.extension().is_some_and(|e| e == "ron"))
            .collect();
        found.sort();
        scenes = found;
    }
    let dir = tempfile::tempdir().expect("temporary directory");
    println!("| scene | AOVs | codec | write ms (median of {runs}) | CPU ms | MB | CPU / none | size / none |");
    println!("|---|---|---|---|---|---|---|---|");
    for path in &scenes {
        let mut scene = match Scene::load(path) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("skipping {}: {e}", path.display());
                continue;
            }
        };
        if let Some((w, h)) = size {
            scene.camera = scene.camera.with_resolution(w, h).expect("valid size");
        }
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        for (label, aovs) in [("default", Aov::DEFAULT.to_vec()), ("all", Aov::ALL.to_vec())] {
            let frame = render(
                &scene,
                &RenderOptions {
                    aovs,
                    ..RenderOptions::default()
                },
            );
            let header = ExrHeader {
                world_to_camera: scene.camera.world_to_camera(),
                world_to_ndc: scene.camera.world_to_ndc(0.01, 1000.0),
                scene_file: path.display().to_string(),
                depth_miss: f32::INFINITY,
                camera_attributes: Vec::new(),
            };
            let mut baseline = None;
            for codec in ExrCompression::ALL {
                let file = dir.path().join(format!("{name}-{label}-{codec:?}.exr"));
                let cpu_start = cpu_seconds();
                let mut times: Vec<f64> = (0..runs)
                    .map(|_| {
                        let start = Instant::now();
                        write_exr_with(&frame, &file, &header, codec).expect("write");
                        start.elapsed().as_secs_f64()
                    })
                    .collect();
                let cpu = (cpu_seconds() - cpu_start) / runs as f64;
                times.sort_by(f64::total_cmp);
                let time = times[times.len() / 2];
                let bytes = std::fs::metadata(&file).expect("written").len() as f64;
                check_exact(&frame, &file);
                let (c0, b0) = *baseline.get_or_insert((cpu, bytes));
                println!(
                    "| {name} {}x{} | {label} | {codec:?} | {:.0} | {:.0} | {:.2} | {:.2} | {:.3} |",
                    frame.width,
                    frame.height,
                    time * 1e3,
                    cpu * 1e3,
                    bytes / 1e6,
                    cpu / c0,
                    bytes / b0
                );
            }
        }
    }
}

/// User + system CPU time of this process so far (Linux; 0 elsewhere), in seconds.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // fields after the parenthesised command name; utime and stime are fields 14 and 15
    let after = stat.rsplit_once(')').map_or("", |(_, rest)| rest);
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks: f64 = fields[11].parse::<f64>().unwrap_or(0.0) + fields[12].parse::<f64>().unwrap_or(0.0);
    ticks / 100.0 // USER_HZ
}

/// Every channel read back equals the frame's bits.
fn check_exact(frame: &Frame, file: &std::path::Path) {
    let image = read_all_flat_layers_from_file(file).expect("readable");
    for channel in &image.layer_data[0].channel_data.list {
        let name = channel.name.to_string();
        let (aov, k) = frame
            .aovs
            .iter()
            .find_map(|a| a.channels().iter().position(|c| *c == name).map(|k| (*a, k)))
            .expect("a frame channel");
        let FlatSamples::F32(values) = &channel.sample_data else {
            panic!("{name} is not f32")
        };
        let expected = frame.planar_channel(aov, k);
        assert!(
            values
                .iter()
                .map(|v| v.to_bits())
                .eq(expected.iter().map(|v| v.to_bits())),
            "{}: channel {name} differs",
            file.display()
        );
    }
}
