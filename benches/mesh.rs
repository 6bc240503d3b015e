//! Mesh benchmark: `cargo bench --bench mesh [-- 4 6 8]` (run `scenes/bench/make_meshes.sh`
//! first; it needs python3 with numpy and trimesh).
//!
//! For each level of the displaced icosphere (`scenes/bench/mesh{4,6,8}.ron`) it prints the BVH
//! build time (`Mesh::new` on the loaded arrays, 2 threads, median of 5), bytes per triangle
//! (`Mesh::memory_bytes`), and primary-ray throughput at 1 and 2 threads (median of 7): "trace" is
//! `Scene::intersect` on the precomputed 1280×720 camera rays, storing `t` and the triangle per ray
//! (what Embree's side returns, less u, v, Ng); "render" is the full default-AOV render. When
//! `embreex` is importable it then runs `../shared/anchors/embree/bench_embreex.py` on the same
//! meshes and rays in the same process run and prints its figures beside ours.

use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;
use zeroset::render::{render, RenderOptions};
use zeroset::scene::mesh_io::read_mesh;
use zeroset::scene::Scene;
use zeroset_primitives::{Interval, Mesh, Ray};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

struct Ours {
    level: u32,
    triangles: usize,
    build_s: f64,
    bytes_per_tri: f64,
    trace: [f64; 2],
    render2: f64,
    hits: usize,
}

fn bench_level(root: &Path, level: u32) -> Result<Ours, String> {
    let mesh_path = root.join(format!("scenes/bench/meshes/mesh{level}.ply"));
    let data = read_mesh(&mesh_path).map_err(|e| format!("{e} (run scenes/bench/make_meshes.sh)"))?;
    let pool2 = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let builds: Vec<f64> = (0..5)
        .map(|_| {
            let d = data.clone();
            let start = Instant::now();
            let mesh = pool2.install(|| Mesh::new(d.vertices, d.indices, None).unwrap());
            let s = start.elapsed().as_secs_f64();
            drop(mesh);
            s
        })
        .collect();
    let mesh = Mesh::new(data.vertices.clone(), data.indices.clone(), None).unwrap();
    let bytes_per_tri = mesh.memory_bytes() as f64 / mesh.triangle_count() as f64;
    let triangles = mesh.triangle_count();
    drop(mesh);
    let scene = Scene::load(&root.join(format!("scenes/bench/mesh{level}.ron"))).map_err(|e| e.to_string())?;
    let cam = &scene.camera;
    let rays: Vec<Ray> = (0..cam.height)
        .flat_map(|y| (0..cam.width).map(move |x| (x, y)))
        .map(|(x, y)| cam.pixel_ray(x, y).expect("the benchmark cameras are pinholes"))
        .collect();
    let n = rays.len() as f64;
    let mut out = vec![(f32::INFINITY, u32::MAX); rays.len()];
    let mut trace = [0.0; 2];
    let mut hits = 0;
    for (slot, threads) in [1, 2].into_iter().enumerate() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let mut run = || {
            let start = Instant::now();
            pool.install(|| {
                out.par_chunks_mut(1280).zip(rays.par_chunks(1280)).for_each(|(o, r)| {
                    for (o, ray) in o.iter_mut().zip(r) {
                        *o = match scene.intersect(ray, Interval::POSITIVE) {
                            Some((_, raw)) => (raw.t as f32, raw.feature),
                            None => (f32::INFINITY, u32::MAX),
                        };
                    }
                });
            });
            start.elapsed().as_secs_f64()
        };
        run();
        trace[slot] = n / median((0..7).map(|_| run()).collect()) / 1e6;
        hits = out.iter().filter(|o| o.1 != u32::MAX).count();
    }
    let options = RenderOptions {
        aovs: scene.outputs.aovs.clone(),
        ..RenderOptions::default()
    };
    let render2 =
        n / median(
            (0..7)
                .map(|_| pool2.install(|| render(&scene, &options)).elapsed.as_secs_f64())
                .collect(),
        ) / 1e6;
    Ok(Ours {
        level,
        triangles,
        build_s: median(builds),
        bytes_per_tri,
        trace,
        render2,
        hits,
    })
}

/// Embree's figures for one level: (level, build s, 1-thread Mrays/s, 2-thread Mrays/s, hits).
type EmbreeRow = (u32, f64, f64, f64, u64);

/// Embree's figures per level.
fn embree(root: &Path, levels: &[u32]) -> Result<Vec<EmbreeRow>, String> {
    let ok = Command::new("python3")
        .args(["-c", "import embreex, numpy"])
        .status()
        .map_err(|e| e.to_string())?;
    if !ok.success() {
        return Err("embreex not importable (pip install embreex numpy trimesh)".into());
    }
    let json: PathBuf = std::env::temp_dir().join(format!("zeroset-embree-{}.json", std::process::id()));
    let mut cmd = Command::new("python3");
    cmd.current_dir(root.join("../shared/anchors/embree"))
        .arg("bench_embreex.py")
        .arg("--levels")
        .args(levels.iter().map(u32::to_string))
        .arg("--json")
        .arg(&json);
    let status = cmd.status().map_err(|e| e.to_string())?;
    if !status.success() {
        return Err(format!("bench_embreex.py failed: {status}"));
    }
    let summary = Command::new("python3")
        .args([
            "-c",
            "import json,sys\nfor r in json.load(open(sys.argv[1]))['levels']:\n print(r['level'], r['build_s']['median'], r['trace1_full_mrays']['median'], r['trace2_full_mrays']['median'], r['hits'])",
        ])
        .arg(&json)
        .output()
        .map_err(|e| e.to_string())?;
    let _ = std::fs::remove_file(&json);
    Ok(String::from_utf8_lossy(&summary.stdout)
        .lines()
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            Some((
                f.first()?.parse().ok()?,
                f.get(1)?.parse().ok()?,
                f.get(2)?.parse().ok()?,
                f.get(3)?.parse().ok()?,
                f.get(4)?.parse().ok()?,
            ))
        })
        .collect())
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut levels: Vec<u32> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    if levels.is_empty() {
        levels = vec![4, 6, 8];
    }
    let mut ours = Vec::new();
    for &level in &levels {
        match bench_level(&root, level) {
            Ok(o) => ours.push(o),
            Err(e) => println!("level {level}: skipped: {e}"),
        }
    }
    let theirs = match embree(&root, &ours.iter().map(|o| o.level).collect::<Vec<_>>()) {
        Ok(v) => v,
        Err(e) => {
            println!("Embree: skipped: {e}");
            Vec::new()
        }
    };
    println!();
    println!("| level | triangles | build s | B/tri | trace 1T Mrays/s | trace 2T | render 2T | hits | Embree build s | Embree 1T | Embree 2T | Embree hits | 2T ratio |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for o in &ours {
        let e = theirs.iter().find(|e| e.0 == o.level);
        let (eb, e1, e2, eh, ratio) = match e {
            Some(e) => (
                format!("{:.3}", e.1),
                format!("{:.1}", e.2),
                format!("{:.1}", e.3),
                e.4.to_string(),
                format!("{:.2}", o.trace[1] / e.3),
            ),
            None => ("–".into(), "–".into(), "–".into(), "–".into(), "–".into()),
        };
        println!(
            "| {} | {} | {:.3} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {eb} | {e1} | {e2} | {eh} | {ratio} |",
            o.level, o.triangles, o.build_s, o.bytes_per_tri, o.trace[0], o.trace[1], o.render2, o.hits
        );
    }
}
