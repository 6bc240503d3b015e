//! Outputs never lose data: a 4K multi-AOV render over an existing EXR, killed with SIGKILL at 7
//! moments spread over its trace and its write, always leaves a complete readable EXR — the old
//! one or the new one — and complete previews; nothing but hidden temporary files is left
//! beside them.

#![cfg(unix)]

mod support;

use exr::meta::attribute::{AttributeValue, Text};
use exr::prelude::*;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};
use support::{bin, write_file};

/// A cheap scene (one sphere, one plane, no shadows) so the 4K frame traces in about a second.
const SCENE: &str = "Scene(
    camera: (eye: (0, 1, -6), look_at: (0, 0.5, 0), vfov_deg: 40, width: 3840, height: 2160),
    objects: [
        (shape: Sphere(center: (0, 1, 0), radius: 1)),
        (shape: Plane(normal: (0, 1, 0), offset: 0)),
    ],
)";

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

    // the old file (misses at depth 0), and the timings of a whole run
    let o = render_command(&scene, &out, "0").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = String::from_utf8_lossy(&o.stdout).lines().last().unwrap().to_string();
    let (trace, write) = (seconds_after(&summary, "trace "), seconds_after(&summary, "write "));
    assert_eq!(depth_miss_of_complete_file(&exr), 0.0);
    let previews = ["scene.beauty.png", "scene.depth.png", "scene.normal.png"];

    // kills: two during the trace (after the start), five spread over the write (after the
    // "writing" status line)
    let moments: [(bool, f64); 7] = [
        (false, 0.3 * trace),
        (false, 0.7 * trace),
        (true, 0.0),
        (true, 0.25 * write),
        (true, 0.5 * write),
        (true, 0.75 * write),
        (true, 1.0 * write),
    ];
    let (mut old, mut new) = (0, 0);
    for (after_writing, delay) in moments {
        let mut child = render_command(&scene, &out, "inf")
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stderr = child.stderr.take().unwrap();
        let (tx, rx) = mpsc::channel();
        let reader = std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(std::result::Result::ok) {
                if line.starts_with("writing ") {
                    let _ = tx.send(Instant::now());
                }
            }
        });
        let start = Instant::now();
        let from = if after_writing {
            rx.recv_timeout(Duration::from_secs(120))
                .expect("the writing status line")
        } else {
            start
        };
        std::thread::sleep((from + Duration::from_secs_f64(delay)).saturating_duration_since(Instant::now()));
        child.kill().unwrap(); // SIGKILL
        let status = child.wait().unwrap();
        reader.join().unwrap();
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
        eprintln!(
            "killed {delay:.2} s after {} (status {status}): depthMiss {miss}",
            if after_writing { "writing" } else { "start" }
        );
    }
    assert!(
        old >= 2,
        "kills during the trace must leave the old file ({old} old, {new} new)"
    );
}
