//! EXR output: a render with every AOV is written with `write_exr`, read back with the `exr`
//! crate, and checked for the documented layout (channel names, FLOAT samples, default-codec
//! scanline blocks, windows, header matrices) and bit-exact values; identical frames give
//! identical bytes; crops merge back into the full frame bit for bit; beauty is premultiplied.

use exr::meta::attribute::{AttributeValue, IntegerBounds, SampleType, Text};
use exr::meta::{BlockDescription, MetaData};
use exr::prelude::*;
use glam::DVec3;
use std::collections::BTreeSet;
use std::path::Path;
use zeroset::aov::Aov;
use zeroset::output::exr::{write_exr, write_exr_with, ExrCompression, ExrHeader};
use zeroset::output::merge::merge_crops;
use zeroset::render::{render, Frame, RenderOptions, Window};
use zeroset::scene::Scene;

mod support;
use support::{aovs_except, bits, frame_channel, scene_from_ron};

const W: u32 = 64;
const H: u32 = 36;
const EYE: DVec3 = DVec3::new(0.5, 1.8, -6.0);
const LOOK_AT: DVec3 = DVec3::new(-0.3, 0.4, 0.8);
const VFOV_DEG: f64 = 42.0;

/// The channel names documented in `src/aov.rs`, all AOVs.
const ALL_CHANNELS: [&str; 18] = [
    "R", "G", "B", "A", "Z", "distance", "N.X", "N.Y", "N.Z", "P.X", "P.Y", "P.Z", "Nc.X", "Nc.Y", "Nc.Z", "id", "u",
    "v",
];

fn documented_channels() -> BTreeSet<String> {
    ALL_CHANNELS.iter().map(|c| c.to_string()).collect()
}

fn scene() -> Scene {
    // some pixels miss (sky above the spheres), the plane is seen at grazing angles far away
    let text = format!(
        "Scene(camera: (eye: ({}, {}, {}), look_at: ({}, {}, {}), vfov_deg: {VFOV_DEG}, width: {W}, height: {H}), \
         objects: [(shape: Sphere(center: (-0.8, 0.5, 0.3), radius: 1.0)), \
                   (shape: Box(min: (0.4, -0.5, -0.5), max: (1.6, 1.0, 0.7))), \
                   (shape: Plane(normal: (0, 1, 0), offset: -0.5))], \
         lights: [Directional(direction: (-0.4, -1.0, 0.6))])",
        EYE.x, EYE.y, EYE.z, LOOK_AT.x, LOOK_AT.y, LOOK_AT.z
    );
    scene_from_ron(&text, "exr_test.ron")
}

fn header(scene: &Scene, depth_miss: f32) -> ExrHeader {
    ExrHeader {
        world_to_camera: scene.camera.world_to_camera(),
        world_to_ndc: scene.camera.world_to_ndc(0.01, 1000.0),
        scene_file: "exr_test.ron".into(),
        depth_miss,
        camera_attributes: Vec::new(),
    }
}

fn render_with(scene: &Scene, crop: Option<Window>) -> Frame {
    render(
        scene,
        &RenderOptions {
            aovs: aovs_except(&[Aov::ShadingNormal, Aov::Uncertain]),
            crop,
            ..RenderOptions::default()
        },
    )
}

fn write(frame: &Frame, header: &ExrHeader, dir: &Path, name: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    write_exr(frame, &path, header).expect("write_exr");
    path
}

/// Applies an Imath (row-vector, row-major) 4×4 matrix to a point: `[x y z 1]·M`.
fn imath_apply(m: &[f32; 16], p: DVec3) -> [f64; 4] {
    let v = [p.x, p.y, p.z, 1.0];
    let mut out = [0.0; 4];
    for (j, o) in out.iter_mut().enumerate() {
        for (i, vi) in v.iter().enumerate() {
            *o += vi * f64::from(m[4 * i + j]);
        }
    }
    out
}

/// The camera basis computed independently from the documented construction.
fn basis() -> (DVec3, DVec3, DVec3) {
    let f = (LOOK_AT - EYE).normalize();
    let r = f.cross(DVec3::Y).normalize();
    let u = r.cross(f);
    (f, r, u)
}

#[test]
fn full_render_layout_values_and_header() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene();
    let frame = render_with(&scene, None);
    let path = write(&frame, &header(&scene, f32::INFINITY), dir.path(), "full.exr");

    // --- layout, from the raw header
    let meta = MetaData::read_from_file(&path, true).expect("valid EXR");
    assert_eq!(meta.headers.len(), 1, "single-part file");
    let h = &meta.headers[0];
    assert!(!h.deep);
    assert_eq!(h.compression, ExrCompression::default().codec());
    assert_eq!(h.blocks, BlockDescription::ScanLines);
    let names: BTreeSet<String> = h.channels.list.iter().map(|c| c.name.to_string()).collect();
    assert_eq!(names, documented_channels(), "exactly the documented channel names");
    assert_eq!(h.channels.list.len(), 18);
    for c in &h.channels.list {
        assert_eq!(c.sample_type, SampleType::F32, "channel {} must be FLOAT", c.name);
        assert_eq!((c.sampling.x(), c.sampling.y()), (1, 1));
    }
    let full = IntegerBounds::new(Vec2(0, 0), Vec2(W as usize, H as usize));
    assert_eq!(h.shared_attributes.display_window, full);
    assert_eq!(h.data_window(), full);

    // --- custom attributes
    let other = &h.own_attributes.other;
    assert_eq!(
        other.get(&Text::from("zeroset/scene")),
        Some(&AttributeValue::Text(Text::from("exr_test.ron")))
    );
    assert_eq!(
        other.get(&Text::from("zeroset/depthMiss")),
        Some(&AttributeValue::F32(f32::INFINITY))
    );
    assert!(other.contains_key(&Text::from("zeroset/depth")));

    // --- world → camera: a point straight ahead at distance 5 is (0, 0, −5); right/up map to +x/+y
    let (f, r, u) = basis();
    let w2c = h.own_attributes.world_to_camera.expect("worldToCamera attribute");
    for (world, camera) in [
        (EYE + 5.0 * f, [0.0, 0.0, -5.0]),
        (EYE + 2.0 * r - 3.0 * u + 7.0 * f, [2.0, -3.0, -7.0]),
        (EYE, [0.0, 0.0, 0.0]),
    ] {
        let c = imath_apply(&w2c, world);
        for k in 0..3 {
            assert!(
                (c[k] - camera[k]).abs() < 1e-5,
                "worldToCamera({world}) = {c:?}, expected {camera:?}"
            );
        }
        assert!((c[3] - 1.0).abs() < 1e-6, "affine: w = {}", c[3]);
    }

    // --- world → NDC (OpenGL, near/far 0.01/1000): the image corners map to ±1 after the divide
    let ndc = h
        .own_attributes
        .world_to_normalized_device
        .expect("worldToNDC attribute");
    let tan_v = (VFOV_DEG.to_radians() / 2.0).tan();
    let tan_h = tan_v * f64::from(W) / f64::from(H);
    let (near, far) = (0.01, 1000.0);
    for (sx, sy, depth) in [(0.0, 0.0, 5.0), (1.0, 1.0, 5.0), (-1.0, 0.5, 20.0), (0.25, -1.0, 2.0)] {
        let world = EYE + depth * (f + sx * tan_h * r + sy * tan_v * u);
        let c = imath_apply(&ndc, world);
        let (x, y, z) = (c[0] / c[3], c[1] / c[3], c[2] / c[3]);
        let z_expected = (far + near) / (far - near) - 2.0 * far * near / ((far - near) * depth);
        assert!((c[3] - depth).abs() < 1e-4 * depth, "clip w is the depth: {}", c[3]);
        assert!(
            (x - sx).abs() < 1e-5 && (y - sy).abs() < 1e-5 && (z - z_expected).abs() < 1e-5,
            "worldToNDC: ({x}, {y}, {z}), expected ({sx}, {sy}, {z_expected})"
        );
    }

    // --- values, bit for bit
    let image = read_all_flat_layers_from_file(&path).expect("readable");
    assert_eq!(image.layer_data.len(), 1);
    let layer = &image.layer_data[0];
    assert_eq!(layer.size, Vec2(W as usize, H as usize));
    assert_eq!(layer.attributes.layer_position, Vec2(0, 0));
    assert_eq!(layer.channel_data.list.len(), 18);
    let mut infinite_z = 0;
    for channel in &layer.channel_data.list {
        let name = channel.name.to_string();
        let FlatSamples::F32(values) = &channel.sample_data else {
            panic!("{name} is not f32");
        };
        let expected = frame_channel(&frame, &name);
        assert_eq!(values.len(), (W * H) as usize);
        assert!(bits(values) == bits(&expected), "channel {name} differs from the frame");
        if name == "Z" {
            infinite_z = values.iter().filter(|z| **z == f32::INFINITY).count();
        }
    }
    assert!(
        infinite_z > 10,
        "misses must be stored as +inf depth ({infinite_z} found)"
    );
    // sanity: the frame is not trivial (several ids, finite depths)
    let ids: BTreeSet<u32> = frame_channel(&frame, "id").iter().map(|x| x.to_bits()).collect();
    assert_eq!(ids.len(), 4, "background and three objects: {ids:?}");
}

#[test]
fn crop_keeps_display_window_and_sets_data_window() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene();
    let crop = Window {
        x0: 11,
        y0: 5,
        x1: 50,
        y1: 31,
    };
    let frame = render_with(&scene, Some(crop));
    let path = write(&frame, &header(&scene, f32::INFINITY), dir.path(), "crop.exr");

    let meta = MetaData::read_from_file(&path, true).expect("valid EXR");
    let h = &meta.headers[0];
    assert_eq!(
        h.shared_attributes.display_window,
        IntegerBounds::new(Vec2(0, 0), Vec2(W as usize, H as usize)),
        "display window is the full image"
    );
    assert_eq!(
        h.data_window(),
        IntegerBounds::new(Vec2(11, 5), Vec2(39, 26)),
        "data window is the crop"
    );

    let image = read_all_flat_layers_from_file(&path).unwrap();
    let layer = &image.layer_data[0];
    assert_eq!(layer.size, Vec2(39, 26));
    assert_eq!(layer.attributes.layer_position, Vec2(11, 5));
    // the crop's samples equal the corresponding pixels of a full render
    let full = render_with(&scene, None);
    for channel in &layer.channel_data.list {
        let name = channel.name.to_string();
        let FlatSamples::F32(values) = &channel.sample_data else {
            panic!("{name} is not f32");
        };
        let whole = frame_channel(&full, &name);
        let expected: Vec<f32> = (5..31)
            .flat_map(|y| (11..50).map(move |x| (x, y)))
            .map(|(x, y)| whole[y * W as usize + x])
            .collect();
        assert!(bits(values) == bits(&expected), "channel {name} of the crop");
    }
}

#[test]
fn subset_of_aovs_and_depth_miss_value() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene();
    let frame = render(
        &scene,
        &RenderOptions {
            aovs: vec![Aov::Distance, Aov::Depth, Aov::Depth],
            depth_miss: 0.0,
            ..RenderOptions::default()
        },
    );
    let path = write(&frame, &header(&scene, 0.0), dir.path(), "subset.exr");
    let image = read_all_flat_layers_from_file(&path).unwrap();
    let layer = &image.layer_data[0];
    let names: BTreeSet<String> = layer.channel_data.list.iter().map(|c| c.name.to_string()).collect();
    assert_eq!(
        names,
        ["Z", "distance"].iter().map(|s| s.to_string()).collect(),
        "duplicates ignored"
    );
    let meta = MetaData::read_from_file(&path, true).unwrap();
    assert_eq!(
        meta.headers[0]
            .own_attributes
            .other
            .get(&Text::from("zeroset/depthMiss")),
        Some(&AttributeValue::F32(0.0))
    );
    for channel in &layer.channel_data.list {
        let FlatSamples::F32(values) = &channel.sample_data else {
            panic!()
        };
        assert!(values.iter().all(|v| v.is_finite() && *v >= 0.0));
        assert!(values.contains(&0.0), "misses written as 0");
        assert!(bits(values) == bits(&frame_channel(&frame, &channel.name.to_string())));
    }
}

/// The names of the header attributes in file order, parsed from the raw bytes (magic, version,
/// then `name\0type\0size value` until an empty name).
fn raw_attribute_names(bytes: &[u8]) -> Vec<String> {
    let mut names = Vec::new();
    let mut at = 8;
    loop {
        let end = at + bytes[at..].iter().position(|b| *b == 0).unwrap();
        if end == at {
            return names;
        }
        names.push(String::from_utf8(bytes[at..end].to_vec()).unwrap());
        let type_end = end + 1 + bytes[end + 1..].iter().position(|b| *b == 0).unwrap();
        let size = i32::from_le_bytes(bytes[type_end + 1..type_end + 5].try_into().unwrap()) as usize;
        at = type_end + 5 + size;
    }
}

#[test]
fn identical_frames_give_identical_bytes_with_sorted_attributes() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene();
    let frame = render_with(&scene, None);
    for codec in ExrCompression::ALL {
        let mut files = Vec::new();
        for k in 0..4 {
            let path = dir.path().join(format!("{codec:?}{k}.exr"));
            write_exr_with(&frame, &path, &header(&scene, f32::INFINITY), codec).unwrap();
            files.push(std::fs::read(&path).unwrap());
        }
        for f in &files[1..] {
            assert!(*f == files[0], "{codec:?}: identical frames, different bytes");
        }
        let names = raw_attribute_names(&files[0]);
        let mut sorted = names.clone();
        sorted.sort();
        assert_eq!(names, sorted, "attributes sorted by name");
        for n in [
            "zeroset/depth",
            "zeroset/depthMiss",
            "zeroset/scene",
            "worldToCamera",
            "channels",
        ] {
            assert!(names.iter().any(|x| x == n), "{n} in {names:?}");
        }
        // still a valid file with the same values
        let image = read_all_flat_layers_from_file(dir.path().join(format!("{codec:?}0.exr"))).unwrap();
        for channel in &image.layer_data[0].channel_data.list {
            let FlatSamples::F32(values) = &channel.sample_data else {
                panic!()
            };
            assert!(bits(values) == bits(&frame_channel(&frame, &channel.name.to_string())));
        }
    }
}

#[test]
fn merged_crops_equal_the_full_render_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene();
    let head = header(&scene, f32::INFINITY);
    let full = render_with(&scene, None);
    let full_path = write(&full, &head, dir.path(), "full.exr");
    // three crops tiling the frame: a top band, and the bottom split at an odd column
    let windows = [
        Window {
            x0: 0,
            y0: 0,
            x1: W,
            y1: 13,
        },
        Window {
            x0: 0,
            y0: 13,
            x1: 29,
            y1: H,
        },
        Window {
            x0: 29,
            y0: 13,
            x1: W,
            y1: H,
        },
    ];
    let crops: Vec<_> = windows
        .iter()
        .enumerate()
        .map(|(k, w)| {
            write(
                &render_with(&scene, Some(*w)),
                &head,
                dir.path(),
                &format!("crop{k}.exr"),
            )
        })
        .collect();
    let merged = dir.path().join("merged.exr");
    // any order
    merge_crops(&[crops[2].clone(), crops[0].clone(), crops[1].clone()], &merged).unwrap();
    let a = read_all_flat_layers_from_file(&merged).unwrap();
    let b = read_all_flat_layers_from_file(&full_path).unwrap();
    assert_eq!(a.attributes.display_window, b.attributes.display_window);
    let (la, lb) = (&a.layer_data[0], &b.layer_data[0]);
    assert_eq!(la.size, lb.size);
    assert_eq!(la.attributes.layer_position, Vec2(0, 0));
    assert_eq!(la.channel_data.list.len(), 18);
    let mut infinite_z = 0;
    for (ca, cb) in la.channel_data.list.iter().zip(&lb.channel_data.list) {
        assert_eq!(ca.name, cb.name);
        let (FlatSamples::F32(va), FlatSamples::F32(vb)) = (&ca.sample_data, &cb.sample_data) else {
            panic!()
        };
        assert!(bits(va) == bits(vb), "channel {} differs after merge", ca.name);
        if ca.name.to_string() == "Z" {
            infinite_z = va.iter().filter(|z| **z == f32::INFINITY).count();
        }
    }
    assert!(infinite_z > 10, "misses stay +inf: {infinite_z}");
    // header attributes kept: the merged file differs from the full render in nothing
    assert_eq!(la.attributes, lb.attributes);
    assert_eq!(
        std::fs::read(&merged).unwrap(),
        std::fs::read(&full_path).unwrap(),
        "same bytes as the full render"
    );

    // crops that do not tile the frame are refused, naming the problem
    let overlapping = write(
        &render_with(
            &scene,
            Some(Window {
                x0: 28,
                y0: 13,
                x1: W,
                y1: H,
            }),
        ),
        &head,
        dir.path(),
        "overlap.exr",
    );
    let err = format!(
        "{:#}",
        merge_crops(&[crops[0].clone(), crops[1].clone(), overlapping], &merged).unwrap_err()
    );
    assert!(err.contains("overlap"), "{err}");
    let err = format!("{:#}", merge_crops(&crops[..2], &merged).unwrap_err());
    assert!(err.contains("missing"), "{err}");
    let other = header(&scene, 0.0);
    let different = write(&render_with(&scene, Some(windows[2])), &other, dir.path(), "other.exr");
    let err = format!(
        "{:#}",
        merge_crops(&[crops[0].clone(), crops[1].clone(), different], &merged).unwrap_err()
    );
    assert!(err.contains("attributes differ"), "{err}");
    // the failed merges left the earlier result untouched
    assert_eq!(std::fs::read(&merged).unwrap(), std::fs::read(&full_path).unwrap());
}

#[test]
fn beauty_is_premultiplied_unless_the_background_is_asked_for() {
    for spp in [1, 4] {
        let mut scene = scene();
        scene.background = DVec3::new(0.25, 0.5, 0.75);
        scene.sampling.spp = spp;
        let options = |background| RenderOptions {
            aovs: vec![Aov::Beauty, Aov::Alpha],
            background,
            ..RenderOptions::default()
        };
        let plain = render(&scene, &options(false));
        let filled = render(&scene, &options(true));
        let (mut misses, mut partial) = (0, 0);
        for y in 0..H {
            for x in 0..W {
                let a = plain.pixel(Aov::Alpha, x, y).unwrap()[0];
                let rgb = plain.pixel(Aov::Beauty, x, y).unwrap();
                let with_bg = filled.pixel(Aov::Beauty, x, y).unwrap();
                if a == 0.0 {
                    misses += 1;
                    assert_eq!(rgb, [0.0, 0.0, 0.0], "a miss is black ({x}, {y})");
                }
                if a > 0.0 && a < 1.0 {
                    partial += 1;
                }
                // filled = premultiplied + (1 − A)·background
                for k in 0..3 {
                    let expected = f64::from(rgb[k]) + (1.0 - f64::from(a)) * scene.background[k];
                    assert!(
                        (f64::from(with_bg[k]) - expected).abs() < 1e-5,
                        "spp {spp} ({x}, {y}) channel {k}: {} vs {expected}",
                        with_bg[k]
                    );
                }
            }
        }
        assert!(misses > 10, "spp {spp}: the test needs misses");
        if spp > 1 {
            assert!(partial > 10, "spp {spp}: the test needs partly covered pixels");
        }
    }
}
