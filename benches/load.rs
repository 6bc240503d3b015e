//! Scene loading benchmark: `cargo bench --bench load -- SCENE.ron [--runs N] [--erased]
//! [--descriptions [--sequential]]`.
//!
//! By default the scene is loaded as `zeroset render` loads it ([`Scene::load_timed`]: a large
//! `objects` list streamed, read, parsed and built at once); reported per run are that time and
//! the hierarchy's. `--descriptions` loads in two steps instead, the whole text read, parsed into
//! descriptions ([`parse_scene_desc`], the `objects` list split over threads) and then built,
//! each step timed; `--sequential` with it parses the text in one piece. `--erased`: spheres,
//! boxes and planes parsed through `erased-serde`, as user types are.
//!
//! Then the median of each step and the process's peak resident memory per object. Generate a
//! large scene with `python3 scenes/bench/make_spheres.py 1000000` (see its docstring).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;
use zeroset::scene::registry::BuildContext;
use zeroset::scene::{parse_scene_desc, Scene};

/// The system allocator, counting the bytes currently allocated (the loaded scene's exact heap
/// footprint, which RSS blurs with freed but retained memory).
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to `System`, only counting sizes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LIVE.fetch_add(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LIVE.fetch_add(new_size, Ordering::Relaxed);
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

fn peak_rss_bytes() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("VmHWM:")).map(str::to_owned))
        .and_then(|l| l.split_whitespace().nth(1).and_then(|kb| kb.parse::<f64>().ok()))
        .map_or(f64::NAN, |kb| kb * 1024.0)
}

fn current_rss_bytes() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("VmRSS:")).map(str::to_owned))
        .and_then(|l| l.split_whitespace().nth(1).and_then(|kb| kb.parse::<f64>().ok()))
        .map_or(f64::NAN, |kb| kb * 1024.0)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let mut runs = 3;
    let mut sequential = false;
    let mut descriptions = false;
    let mut path = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--runs" => runs = args.next().and_then(|v| v.parse().ok()).expect("--runs N"),
            "--bench" => {}
            // the whole text parsed in one piece, as before the parallel `objects` split
            "--sequential" => sequential = true,
            // the two-step load: the whole text into descriptions, then built
            "--descriptions" => descriptions = true,
            // re-register the built-in leaf primitives as a user would: parsed through
            // `erased-serde` as before the typed path, for a same-binary comparison
            "--erased" => {
                use zeroset::scene::shapes::*;
                zeroset::scene::registry::register::<SphereDesc>("Sphere");
                zeroset::scene::registry::register::<BoxDesc>("Box");
                zeroset::scene::registry::register::<PlaneDesc>("Plane");
            }
            other => path = Some(std::path::PathBuf::from(other)),
        }
    }
    let path = path.unwrap_or_else(|| {
        eprintln!("usage: cargo bench --bench load -- SCENE.ron [--runs N]");
        std::process::exit(2)
    });
    let (mut read, mut parse, mut build, mut hierarchy) = (vec![], vec![], vec![], vec![]);
    let mut objects = 0;
    let mut retained = f64::NAN;
    let mut heap = f64::NAN;
    let baseline = current_rss_bytes();
    let heap_baseline = LIVE.load(Ordering::Relaxed);
    for run in 0..runs {
        let (t_read, t_parse, t_build, scene, timing) = if descriptions {
            let start = Instant::now();
            let text = std::fs::read_to_string(&path).expect("readable scene");
            let t_read = start.elapsed().as_secs_f64();
            let start = Instant::now();
            let desc = if sequential {
                std::thread::scope(|s| {
                    std::thread::Builder::new()
                        .stack_size(1 << 30)
                        .spawn_scoped(s, || zeroset::scene::ron_options().from_str(&text))
                        .expect("a parser thread")
                        .join()
                        .expect("no panic")
                })
            } else {
                parse_scene_desc(&text)
            }
            .unwrap_or_else(|e| panic!("{e}"));
            let t_parse = start.elapsed().as_secs_f64();
            drop(text);
            let context = BuildContext::new(path.parent().unwrap_or(std::path::Path::new(".")));
            let (scene, timing) = Scene::from_desc_timed(desc, &context).unwrap_or_else(|(l, m)| panic!("{l}: {m}"));
            (t_read, t_parse, timing.objects, scene, timing)
        } else {
            let (scene, timing) = Scene::load_timed(&path).unwrap_or_else(|e| panic!("{e}"));
            // streamed: reading and parsing overlap the build, all in `timing.objects`
            (0.0, 0.0, timing.objects, scene, timing)
        };
        objects = scene.objects.len();
        println!(
            "run {run}: read {t_read:.3} s, parse {t_parse:.3} s, {} {t_build:.3} s, hierarchy {:.3} s (load + hierarchy {:.3} s)",
            if descriptions { "build objects" } else { "read + parse + build objects (streamed)" },
            timing.hierarchy,
            t_read + t_parse + t_build + timing.hierarchy
        );
        read.push(t_read);
        parse.push(t_parse);
        build.push(t_build);
        hierarchy.push(timing.hierarchy);
        if run == 0 {
            retained = current_rss_bytes() - baseline;
            heap = (LIVE.load(Ordering::Relaxed) - heap_baseline) as f64;
        }
        drop(scene);
    }
    let (r, p, b, h) = (median(read), median(parse), median(build), median(hierarchy));
    println!(
        "{}: {objects} objects; median of {runs}: read {r:.3} s, parse {p:.3} s, {} {b:.3} s, hierarchy {h:.3} s; load + hierarchy {:.3} s; loaded scene {:.0} B per object on the heap ({:.0} B of RSS after the first load, text and descriptions freed), peak RSS {:.0} B per object",
        path.display(),
        if descriptions { "build objects" } else { "read + parse + build (streamed)" },
        r + p + b + h,
        heap / objects.max(1) as f64,
        retained / objects.max(1) as f64,
        peak_rss_bytes() / objects.max(1) as f64
    );
}
