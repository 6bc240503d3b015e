//! Outputs never lose data: a 4K multi-AOV render over an existing EXR, killed with SIGKILL at 7
//! moments spread over its run (the files are written while the frame is traced), always leaves
//! a complete readable EXR — the old one or the new one — and complete previews; nothing but
//! hidden temporary files is left beside them, and only the last killed run's (each run removes
//! those its killed predecessors left).

#![cfg(unix)]

mod support;

use exr::meta::attribute::{AttributeValue, Text};
use exr::prelude::*;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use support::{bin, write_file, FOUR_K_SPHERE_AND_PLANE};

/// A cheap scene (one sphere, one plane, no shadows) so the 4K frame traces in about a second.
const SCENE: &str = FOUR_K_SPHERE_AND_PLANE;

const AOVS: &str = "Beauty,Alpha,Depth,Distance,Normal,Position,PrimitiveId";

/// The render command writing `dir/scene.exr`, its misses' depth set to `depth_miss` (which
/// tells the old file from the new one).
fn render_command(scene: &Path, dir: &Path, depth_miss: &str) -> Command {
    let mut c = bin();
    c.args([
        "render",
        scene.to_str().unwrap(),
        "-o",
        dir.to_str().unwrap(),
        "--aov",
        AOVS,
    ])
    .args(["--depth-miss", depth_miss, "-t", "2"]);
    c
}

/// The `zeroset/depthMiss` attribute of a complete, readable EXR (every channel decoded).
fn depth_miss_of_complete_file(path: &Path) -> f32 {
    let image = read_all_flat_layers_from_file(path).unwrap_or_else(|e| panic!("{} unreadable: {e}", path.display()));
    let layer = &image.layer_data[0];
    assert_eq!(layer.size, Vec2(3840, 2160));
    assert_eq!(layer.channel_data.list.len(), 13);
    match layer.attributes.other.get(&Text::from("zeroset/depthMiss")) {
        Some(AttributeValue::F32(v)) => *v,
        other => panic!("zeroset/depthMiss: {other:?}"),
    }
}

/// Seconds after "key " in the summary line.
fn seconds_after(line: &str, key: &str) -> f64 {
    let rest = &line[line.find(key).unwrap_or_else(|| panic!("{key} in {line}")) + key.len()..];
    rest.split_whitespace().next().unwrap().parse().unwrap()
}

#[test]
fn sigkill_at_seven_moments_leaves_the_old_or_the_new_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_file(dir.path(), "scene.ron", SCENE);
    let out = dir.path().join("out");
    let exr = out.join("scene.exr");

    // the old file (misses at depth 0), and the wall time of a whole run
    let started = Instant::now();
    let o = render_command(&scene, &out, "0").output().unwrap();
    let wall = started.elapsed().as_secs_f64();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = String::from_utf8_lossy(&o.stdout).lines().last().unwrap().to_string();
    let trace = seconds_after(&summary, "trace ");
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("as rows are traced"),
        "the files are written while tracing"
    );
    assert_eq!(depth_miss_of_complete_file(&exr), 0.0);
    let previews = ["scene.beauty.png", "scene.depth.png", "scene.normal.png"];

    // the files are written while the frame is traced, so the kills are spread over the whole
    // run: two early in the trace (the files half written under temporary names), then on to
    // the end of the trace, the finishing of the files and their renaming
    let moments = [0.1, 0.25, 0.45, 0.65, 0.8, 0.9, 0.97].map(|f| f * wall);
    let (mut old, mut new) = (0, 0);
    // the size of the largest EXR a killed run left unfinished (each run removes the ones its
    // killed predecessors left, so it is read after each kill)
    let unfinished_exrs = || -> Vec<u64> {
        std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap())
            .filter(|e| e.file_name().to_string_lossy().starts_with(".scene.exr."))
            .map(|e| e.metadata().unwrap().len())
            .collect()
    };
    let mut largest_unfinished = 0;
    for delay in moments {
        let mut child = render_command(&scene, &out, "inf")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let start = Instant::now();
        std::thread::sleep((start + Duration::from_secs_f64(delay)).saturating_duration_since(Instant::now()));
        child.kill().unwrap(); // SIGKILL
        let status = child.wait().unwrap();
        let miss = depth_miss_of_complete_file(&exr);
        if miss == 0.0 {
            old += 1;
        } else if miss == f32::INFINITY {
            new += 1;
        } else {
            panic!("depthMiss {miss}");
        }
        for png in previews {
            let size = image::image_dimensions(out.join(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
            assert_eq!(size, (3840, 2160));
            image::open(out.join(png)).unwrap_or_else(|e| panic!("{png} incomplete: {e}"));
        }
        // only the outputs and hidden temporary files of killed writes
        for entry in std::fs::read_dir(&out).unwrap() {
            let name = entry.unwrap().file_name().to_string_lossy().into_owned();
            assert!(
                name == "scene.exr"
                    || name == "scene.cameras.json"
                    || previews.contains(&name.as_str())
                    || (name.starts_with('.') && name.ends_with(".tmp")),
                "unexpected file {name}"
            );
        }
        let left = unfinished_exrs();
        assert!(
            left.len() <= 1,
            "only the last killed run's temporary EXR is left: {left:?}"
        );
        largest_unfinished = largest_unfinished.max(left.into_iter().max().unwrap_or(0));
        eprintln!("killed {delay:.2} s after the start (trace {trace:.2} s, wall {wall:.2} s; status {status}): depthMiss {miss}");
    }
    assert!(
        old >= 2,
        "kills early in the trace must leave the old file ({old} old, {new} new)"
    );
    // the killed runs had written rows: their (hidden, never renamed) EXRs hold more than a header
    assert!(
        largest_unfinished > 10 << 20,
        "rows are written while tracing (largest unfinished file {largest_unfinished} B)"
    );
}
