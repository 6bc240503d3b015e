//! Scaffolding shared by the integration tests (`mod support;` in each): running the `zeroset`
//! binary and judging its exit, writing scene files, reading EXR channels.
//!
//! Each test file uses a part of it, so unused items are allowed here.
#![allow(dead_code)]

pub mod layers;

use exr::meta::MetaData;
use exr::prelude::*;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use zeroset::aov::Aov;
use zeroset::render::Frame;
use zeroset::scene::Scene;

/// A 4K frame of one sphere on a plane, no lights: cheap per pixel, long enough as a whole for
/// a signal or a kill to land while its outputs are being written.
pub const FOUR_K_SPHERE_AND_PLANE: &str = "Scene(
    camera: (eye: (0, 1, -6), look_at: (0, 0.5, 0), vfov_deg: 40, width: 3840, height: 2160),
    objects: [
        (shape: Sphere(center: (0, 1, 0), radius: 1)),
        (shape: Plane(normal: (0, 1, 0), offset: 0)),
    ],
)";

/// The `zeroset` binary, run from the repository root (so `scenes/…` paths resolve).
pub fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_zeroset"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

/// Runs the binary with `args` to completion.
pub fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("the binary runs")
}

/// The command's standard output, lossily decoded.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The command's standard error, lossily decoded.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The command succeeded; otherwise fails with its status and both streams.
pub fn assert_ok(o: &Output, what: &str) {
    assert!(
        o.status.success(),
        "{what}: exit {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status,
        stdout(o),
        stderr(o)
    );
}

/// The command failed cleanly: non-zero status that is not a panic's (101), no panic message,
/// and stderr mentions every one of `needles`. Returns stderr.
pub fn assert_fails(o: &Output, needles: &[&str], what: &str) -> String {
    let err = stderr(o);
    assert!(!o.status.success(), "{what}: should fail, but exited 0\nstderr:\n{err}");
    assert_ne!(o.status.code(), Some(101), "{what}: exit code 101 is a panic\n{err}");
    assert!(o.status.code().is_some(), "{what}: killed by a signal\n{err}");
    assert!(!err.contains("panicked"), "{what}: panicked\n{err}");
    for n in needles {
        assert!(err.contains(n), "{what}: stderr should mention {n:?}:\n{err}");
    }
    err
}

/// A path as a command-line argument.
pub fn p(path: &Path) -> &str {
    path.to_str().expect("a UTF-8 path")
}

/// Writes `text` to `dir/name` (a scene, rays, …) and returns the path.
pub fn write_file(dir: &Path, name: impl AsRef<Path>, text: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    path
}

/// The names of the files in `dir`.
pub fn file_names(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect()
}

/// The channel names of an EXR file's first layer (from its header alone).
pub fn channel_names(path: &Path) -> BTreeSet<String> {
    let meta = MetaData::read_from_file(path, true).expect("valid EXR");
    meta.headers[0]
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect()
}

/// Every channel of a single-layer EXR of `FLOAT` channels: `(name, samples)`, row-major.
pub fn read_channels(path: &Path) -> Vec<(String, Vec<f32>)> {
    let image = read_all_flat_layers_from_file(path).unwrap_or_else(|e| panic!("{} unreadable: {e}", path.display()));
    image.layer_data[0]
        .channel_data
        .list
        .iter()
        .map(|ch| {
            let FlatSamples::F32(v) = &ch.sample_data else {
                panic!("{} is not FLOAT", ch.name)
            };
            (ch.name.to_string(), v.clone())
        })
        .collect()
}

/// One channel of an EXR file, row-major, as `f32` whatever its sample type.
pub fn read_channel(path: &Path, name: &str) -> Vec<f32> {
    let image = read_all_flat_layers_from_file(path).unwrap_or_else(|e| panic!("{} unreadable: {e}", path.display()));
    let channel = image.layer_data[0]
        .channel_data
        .list
        .iter()
        .find(|c| c.name.to_string() == name)
        .unwrap_or_else(|| panic!("{}: no channel {name}", path.display()));
    channel.sample_data.values_as_f32().collect()
}

/// A scene from RON `text`, named `name` in its errors; panics with the error and the text.
pub fn scene_from_ron(text: &str, name: &str) -> Scene {
    Scene::from_ron(text, name).unwrap_or_else(|e| panic!("scene should load: {e}\n{text}"))
}

/// The bit patterns of `values`: equal exactly where the values are bit-identical (NaNs and
/// signed zeros included, which `==` on floats would not tell apart).
pub fn bits(values: &[f32]) -> Vec<u32> {
    values.iter().map(|x| x.to_bits()).collect()
}

/// [`bits`] of every sample of `frame`.
pub fn frame_bits(frame: &Frame) -> Vec<u32> {
    bits(&frame.samples)
}

/// The frame's value of channel `name` as a planar vector over the window.
pub fn frame_channel(frame: &Frame, name: &str) -> Vec<f32> {
    for aov in &frame.aovs {
        if let Some(k) = aov.channels().iter().position(|c| *c == name) {
            return frame.planar_channel(*aov, k);
        }
    }
    panic!("channel {name} not in the frame");
}

/// Every AOV of [`Aov::ALL`] but `excluded`, in [`Aov::ALL`]'s order.
pub fn aovs_except(excluded: &[Aov]) -> Vec<Aov> {
    Aov::ALL.into_iter().filter(|a| !excluded.contains(a)).collect()
}
