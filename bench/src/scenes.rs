//! Whole-scene figures on `scenes/bench/*.ron`: load + BVH build time, primary-ray Mrays/s on
//! one thread and on all cores (median of N renders), peak resident memory, and the error of the
//! `distance` AOV against a double-double reference per pixel.

use crate::reference::{reference, Shape};
use glam::DVec3;
use rayon::prelude::*;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::time::Instant;
use zeroset::aov::Aov;
use zeroset::render::{render, RenderOptions};
use zeroset::scene::Scene;
use zeroset_primitives::Interval;

/// One scene's figures.
#[derive(Clone, Debug, Default)]
pub struct SceneRow {
    pub scene: String,
    pub objects: usize,
    pub pixels: usize,
    pub load_ms: f64,
    /// (threads, median s, Mrays/s median, min, max)
    pub timings: Vec<(usize, f64, f64, f64, f64)>,
    pub peak_rss_mib: f64,
    /// Pixels compared against the reference, and those whose hit/miss or object disagree.
    pub checked: usize,
    pub disagree: usize,
    /// Relative error of the f32 `distance` AOV and of the f64 `t` behind it.
    pub max_rel_aov: f64,
    pub median_rel_aov: f64,
    pub max_rel_f64: f64,
    pub median_rel_f64: f64,
    pub note: String,
}

#[derive(Deserialize)]
#[serde(rename = "Scene")]
struct SceneFile {
    objects: Vec<ObjectFile>,
}

#[derive(Deserialize)]
struct ObjectFile {
    shape: ShapeFile,
    #[serde(default)]
    transform: Option<ron::Value>,
}

fn y() -> DVec3 {
    DVec3::Y
}
fn yes() -> bool {
    true
}
fn ones() -> DVec3 {
    DVec3::ONE
}

#[derive(Deserialize)]
enum ShapeFile {
    Sphere {
        center: DVec3,
        radius: f64,
    },
    Polygon {
        points: Vec<DVec3>,
    },
    Box {
        min: DVec3,
        max: DVec3,
    },
    Cylinder {
        base: DVec3,
        #[serde(default = "y")]
        axis: DVec3,
        radius: f64,
        height: f64,
        #[serde(default = "yes")]
        capped: bool,
    },
    Ellipsoid {
        center: DVec3,
        #[serde(default = "ones")]
        radii: DVec3,
    },
    Triangle {
        a: DVec3,
        b: DVec3,
        c: DVec3,
    },
}

/// The reference shapes of a scene file, or why there are none (a primitive or a transform the
/// references do not cover).
fn reference_shapes(path: &Path) -> Result<Vec<Shape>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    let file: SceneFile = zeroset::scene::ron_options()
        .from_str(&text)
        .map_err(|e| format!("no reference for this scene ({e})"))?;
    file.objects
        .into_iter()
        .map(|o| {
            if o.transform.is_some() {
                return Err("no reference: transformed objects".to_owned());
            }
            Ok(match o.shape {
                ShapeFile::Sphere { center, radius } => Shape::Sphere { c: center, r: radius },
                ShapeFile::Polygon { points } => Shape::Polygon(points),
                ShapeFile::Box { min, max } => Shape::Cuboid { lo: min, hi: max },
                ShapeFile::Cylinder {
                    base,
                    axis,
                    radius,
                    height,
                    capped,
                } => {
                    if axis.normalize() != DVec3::Y || !capped {
                        return Err("no reference: cylinder not capped along +Y".to_owned());
                    }
                    Shape::Cylinder {
                        base,
                        r: radius,
                        h: height,
                    }
                }
                ShapeFile::Ellipsoid { center, radii } => Shape::Ellipsoid { c: center, radii },
                ShapeFile::Triangle { a, b, c } => Shape::Triangle([a, b, c]),
            })
        })
        .collect()
}

/// Peak resident memory of this process so far (`VmHWM`), MiB.
pub fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("VmHWM:")).map(str::to_owned))
        .and_then(|l| l.split_whitespace().nth(1).and_then(|kb| kb.parse::<f64>().ok()))
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The bench scenes, sorted.
pub fn scene_paths() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/bench");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|d| {
            d.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "ron"))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// Measures every bench scene.
pub fn run_all(runs: usize) -> Vec<SceneRow> {
    scene_paths().iter().map(|p| run_one(p, runs)).collect()
}

fn run_one(path: &Path, runs: usize) -> SceneRow {
    let mut row = SceneRow {
        scene: path.file_stem().unwrap().to_string_lossy().into_owned(),
        ..SceneRow::default()
    };
    let start = Instant::now();
    let scene = match Scene::load(path) {
        Ok(s) => s,
        Err(e) => {
            row.note = format!("not loaded: {e}");
            return row;
        }
    };
    row.load_ms = start.elapsed().as_secs_f64() * 1e3;
    row.objects = scene.objects.len();
    let (w, h) = (scene.camera.width, scene.camera.height);
    row.pixels = w as usize * h as usize;
    let options = RenderOptions {
        aovs: scene.outputs.aovs.clone(),
        ..RenderOptions::default()
    };
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
    let mut thread_counts = vec![1];
    if cores > 1 {
        thread_counts.push(cores);
    }
    for threads in thread_counts {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let mut times: Vec<f64> = (0..runs)
            .map(|_| pool.install(|| render(&scene, &options)).elapsed.as_secs_f64())
            .collect();
        let t = median(&mut times);
        let mr = |s: f64| row.pixels as f64 / s / 1e6;
        row.timings
            .push((threads, t, mr(t), mr(times[times.len() - 1]), mr(times[0])));
    }
    row.peak_rss_mib = peak_rss_mib();

    // depth-AOV error: every pixel's hit against the double-double reference of the object it hit
    let shapes = match reference_shapes(path) {
        Ok(s) => s,
        Err(e) => {
            row.note = e;
            return row;
        }
    };
    let frame = render(
        &scene,
        &RenderOptions {
            aovs: vec![Aov::Distance, Aov::PrimitiveId],
            ..RenderOptions::default()
        },
    );
    // every pixel checks the object it hit; a 1-in-`stride²` grid also checks all objects
    // (hit/miss and which object), which costs `objects` reference tests per pixel
    let stride = if shapes.len() <= 16 { 1 } else { 4 };
    let camera = &scene.camera;
    type PixelResult = (Option<(f64, f64)>, bool, bool);
    let results: Vec<PixelResult> = (0..row.pixels)
        .into_par_iter()
        .map(|i| {
            let (x, yy) = ((i % w as usize) as u32, (i / w as usize) as u32);
            let ray = camera.pixel_ray(x, yy).expect("the benchmark cameras are pinholes");
            let px = frame.pixel(Aov::Distance, x, yy).unwrap()[0];
            let id = frame.pixel(Aov::PrimitiveId, x, yy).unwrap()[0];
            let f64_hit = scene.intersect(&ray, Interval::POSITIVE);
            let full = x % stride == 0 && yy % stride == 0;
            let mut disagree = false;
            if full {
                let best = shapes
                    .iter()
                    .enumerate()
                    .filter_map(|(k, s)| reference(s, &ray, f64::INFINITY).t.map(|t| (k, t.f64())))
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                disagree = match (best, f64_hit) {
                    (None, None) => false,
                    (Some((k, _)), Some((obj, _))) => k != obj as usize,
                    _ => true,
                };
            }
            let errs = if id >= 0.0 {
                let r = reference(&shapes[id as usize], &ray, f64::INFINITY);
                match (r.t, f64_hit) {
                    (Some(t), Some((_, raw))) => {
                        let tr = t.f64();
                        Some((
                            (f64::from(px) - tr).abs() / tr,
                            ((crate::dd::Dd::new(raw.t) - t) / t).abs().f64(),
                        ))
                    }
                    _ => {
                        disagree = true;
                        None
                    }
                }
            } else {
                None
            };
            (errs, disagree, full)
        })
        .collect();
    let mut aov: Vec<f64> = Vec::new();
    let mut f64s: Vec<f64> = Vec::new();
    for (e, d, full) in &results {
        if let Some((a, b)) = e {
            aov.push(*a);
            f64s.push(*b);
        }
        row.disagree += usize::from(*d);
        row.checked += usize::from(*full);
    }
    if !aov.is_empty() {
        row.median_rel_aov = median(&mut aov);
        row.max_rel_aov = aov[aov.len() - 1];
        row.median_rel_f64 = median(&mut f64s);
        row.max_rel_f64 = f64s[f64s.len() - 1];
    }
    if stride > 1 {
        row.note = format!(
            "hit/miss and object checked against all {} objects on every {stride}th pixel in x and y ({} pixels); t error on every hit pixel",
            shapes.len(),
            row.checked
        );
    }
    row
}
