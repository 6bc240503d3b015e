//! Outputs written while the frame is traced (`zeroset::render::stream`): the streamed EXR is byte for
//! byte the file the whole-frame writer makes, for every codec, and holds the in-memory frame's
//! samples in every channel, misses included; the streamed previews have the whole-frame
//! previews' pixels; sinks get every band once, in order, whatever the thread count; a sink
//! that fails stops the render and the destination keeps its old file.

use exr::prelude::*;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use zeroset::aov::Aov;
use zeroset::output::exr::{write_exr_with, ExrCompression, ExrHeader};
use zeroset::output::exr_stream::ExrStream;
use zeroset::output::png::{write_previews, PREVIEWS};
use zeroset::output::png_stream::PreviewStream;
use zeroset::render::stream::{bands_held, render_view_to, BandSink};
use zeroset::render::{render_view, Frame, FrameLayout, RenderOptions, Window};
use zeroset::scene::Scene;

mod support;
use support::{bits, frame_channel, scene_from_ron};

/// Sky above two objects (misses), a plane at grazing angles; `extra` goes into the scene
/// (such as a `sampling`). The height is not a multiple of any band or block height.
fn scene(extra: &str) -> Scene {
    let text = format!(
        "Scene(camera: (eye: (0.5, 1.8, -6.0), look_at: (-0.3, 0.4, 0.8), vfov_deg: 42, width: 72, height: 75), \
         objects: [(shape: Sphere(center: (-0.8, 0.5, 0.3), radius: 1.0)), \
                   (shape: Box(min: (0.4, -0.5, -0.5), max: (1.6, 1.0, 0.7))), \
                   (shape: Plane(normal: (0, 1, 0), offset: -0.5))], \
         lights: [Directional(direction: (-0.4, -1.0, 0.6))]{extra})"
    );
    scene_from_ron(&text, "streamed.ron")
}

fn header(scene: &Scene, depth_miss: f32) -> ExrHeader {
    ExrHeader {
        world_to_camera: scene.camera.world_to_camera(),
        world_to_ndc: scene.camera.world_to_ndc(0.01, 1000.0),
        scene_file: "streamed.ron".into(),
        depth_miss,
        camera_attributes: Vec::new(),
    }
}

fn options(crop: Option<Window>, depth_miss: f32) -> RenderOptions {
    RenderOptions {
        aovs: Aov::ALL.to_vec(),
        crop,
        depth_miss,
        ..RenderOptions::default()
    }
}

/// The whole image, and a crop whose top row is odd and whose height is prime.
fn windows() -> [Option<Window>; 2] {
    [
        None,
        Some(Window {
            x0: 5,
            y0: 3,
            x1: 70,
            y1: 74,
        }),
    ]
}

/// The samples of channel `name` of a frame, planar.
#[test]
fn streamed_exr_is_the_whole_frame_file_byte_for_byte_for_every_codec() {
    let dir = tempfile::tempdir().unwrap();
    for (extra, depth_miss) in [("", f32::INFINITY), (", sampling: (spp: 4, seed: 3)", 7.5)] {
        let scene = scene(extra);
        let header = header(&scene, depth_miss);
        for crop in windows() {
            let options = options(crop, depth_miss);
            let frame = render_view(&scene, &scene.camera, &options);
            let layout = FrameLayout::new(&scene.camera, &options);
            assert_eq!(frame.layout(), layout);
            let misses = frame_channel(&frame, "A").iter().filter(|a| **a == 0.0).count();
            assert!(misses > 100, "the window has misses ({misses})");
            for codec in ExrCompression::ALL {
                let whole = dir.path().join("whole.exr");
                write_exr_with(&frame, &whole, &header, codec).unwrap();
                let streamed = dir.path().join("streamed.exr");
                let exr = ExrStream::create(&streamed, &layout, &header, codec).unwrap();
                let stats = render_view_to(&scene, &scene.camera, &options, &[&exr]).unwrap();
                exr.finish().unwrap();
                assert_eq!(stats.spp, frame.spp);
                let (a, b) = (std::fs::read(&whole).unwrap(), std::fs::read(&streamed).unwrap());
                assert!(
                    a == b,
                    "{codec:?} {crop:?} {extra}: the streamed file differs from the whole-frame file"
                );

                // and, read back independently, every channel is the frame's, bit for bit
                let image = read_all_flat_layers_from_file(&streamed).unwrap();
                let layer = &image.layer_data[0];
                let w = frame.window;
                assert_eq!(layer.size, Vec2(w.width() as usize, w.height() as usize));
                assert_eq!(layer.attributes.layer_position, Vec2(w.x0 as i32, w.y0 as i32));
                assert_eq!(layer.channel_data.list.len(), frame.channel_count());
                for channel in &layer.channel_data.list {
                    let name = channel.name.to_string();
                    let FlatSamples::F32(values) = &channel.sample_data else {
                        panic!("{name} is not f32")
                    };
                    assert_eq!(bits(values), bits(&frame_channel(&frame, &name)), "{codec:?} {name}");
                }
                let z = frame_channel(&frame, "Z");
                assert_eq!(z.iter().filter(|v| **v == depth_miss).count(), misses, "misses' Z");
            }
        }
    }
}

/// Decoded 8-bit RGB pixels of a PNG file.
fn pixels(path: &Path) -> (u32, u32, Vec<u8>) {
    let image = image::open(path).unwrap().to_rgb8();
    (image.width(), image.height(), image.into_raw())
}

#[test]
fn streamed_previews_have_the_whole_frame_previews_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let background = [0.2, 0.3, 0.9];
    // a finite depth for misses: it counts for the depth scale but is drawn as a miss
    for depth_miss in [f32::INFINITY, 40.0] {
        let scene = scene("");
        for crop in windows() {
            let options = options(crop, depth_miss);
            let frame = render_view(&scene, &scene.camera, &options);
            let whole = write_previews(&frame, dir.path(), "whole", background).unwrap();
            assert_eq!(whole.len(), 3);
            let layout = frame.layout();
            let streams: Vec<PreviewStream> = PREVIEWS
                .iter()
                .map(|(aov, name)| {
                    PreviewStream::create(
                        &dir.path().join(format!("streamed.{name}.png")),
                        *aov,
                        &layout,
                        background,
                    )
                    .unwrap()
                })
                .collect();
            let sinks: Vec<&dyn BandSink> = streams.iter().map(|s| s as &dyn BandSink).collect();
            render_view_to(&scene, &scene.camera, &options, &sinks).unwrap();
            for stream in streams {
                stream.finish().unwrap();
            }
            for (_, name) in PREVIEWS {
                let a = pixels(&dir.path().join(format!("whole.{name}.png")));
                let b = pixels(&dir.path().join(format!("streamed.{name}.png")));
                assert_eq!((a.0, a.1), (frame.window.width(), frame.window.height()));
                assert!(
                    a == b,
                    "{name} preview, {crop:?}, miss depth {depth_miss}: pixels differ"
                );
                // not a blank image: misses and hits look different
                let distinct: std::collections::BTreeSet<&[u8]> = b.2.chunks_exact(3).collect();
                assert!(distinct.len() > 10, "{name}: {} colours", distinct.len());
            }
        }
    }
}

/// A sink that records the bands it is given and checks them against a frame.
struct Recorder<'a> {
    frame: &'a Frame,
    prepared: AtomicUsize,
    written: Mutex<Vec<(u32, usize)>>,
    /// Fail the write of the band starting at this row.
    fail_at: Option<u32>,
}

impl BandSink for Recorder<'_> {
    fn row_alignment(&self) -> u32 {
        8
    }

    fn prepare(&self, first_row: u32, _rows: &[f32]) -> anyhow::Result<Vec<u8>> {
        self.prepared.fetch_add(1, Ordering::Relaxed);
        Ok(first_row.to_le_bytes().to_vec())
    }

    fn write(&self, first_row: u32, rows: &[f32], prepared: Vec<u8>) -> anyhow::Result<()> {
        assert_eq!(prepared, first_row.to_le_bytes(), "the band's own prepared bytes");
        if self.fail_at == Some(first_row) {
            anyhow::bail!("disk full at row {first_row}");
        }
        let row_len = self.frame.window.width() as usize * self.frame.channel_count();
        let at = (first_row - self.frame.window.y0) as usize * row_len;
        assert!(
            bits(rows) == bits(&self.frame.samples[at..at + rows.len()]),
            "rows from {first_row} are the frame's"
        );
        self.written.lock().unwrap().push((first_row, rows.len() / row_len));
        Ok(())
    }
}

#[test]
fn sinks_get_every_band_once_in_order_on_any_thread_count() {
    let scene = scene("");
    let options = options(windows()[1], f32::INFINITY);
    let frame = render_view(&scene, &scene.camera, &options);
    for threads in [1, 3, 8] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let sinks = [0, 1].map(|_| Recorder {
            frame: &frame,
            prepared: AtomicUsize::new(0),
            written: Mutex::new(Vec::new()),
            fail_at: None,
        });
        let list: Vec<&dyn BandSink> = sinks.iter().map(|s| s as &dyn BandSink).collect();
        pool.install(|| render_view_to(&scene, &scene.camera, &options, &list))
            .unwrap();
        for sink in &sinks {
            let written = sink.written.lock().unwrap().clone();
            // bands of 16 rows (a multiple of the alignment 8) from the window's top, the last
            // one shorter: 3, 19, 35, 51, 67 (7 rows)
            let expected: Vec<(u32, usize)> = vec![(3, 16), (19, 16), (35, 16), (51, 16), (67, 7)];
            assert_eq!(written, expected, "{threads} threads");
            assert_eq!(sink.prepared.load(Ordering::Relaxed), expected.len());
        }
    }
}

#[test]
fn a_failing_sink_stops_the_render_and_the_old_file_stays() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene("");
    // a taller image: 30 bands, so stopping early is visible
    let scene = {
        let mut s = scene;
        s.camera = s.camera.with_resolution(40, 480).unwrap();
        s
    };
    let options = options(None, f32::INFINITY);
    let frame = render_view(&scene, &scene.camera, &options);
    let path = dir.path().join("old.exr");
    std::fs::write(&path, b"the old file").unwrap();
    let exr = ExrStream::create(
        &path,
        &frame.layout(),
        &header(&scene, f32::INFINITY),
        ExrCompression::None,
    )
    .unwrap();
    let failing = Recorder {
        frame: &frame,
        prepared: AtomicUsize::new(0),
        written: Mutex::new(Vec::new()),
        fail_at: Some(32),
    };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let err = pool
        .install(|| render_view_to(&scene, &scene.camera, &options, &[&exr, &failing]))
        .unwrap_err();
    assert_eq!(err.to_string(), "disk full at row 32");
    assert_eq!(failing.written.lock().unwrap().clone(), vec![(0, 16), (16, 16)]);
    let traced = failing.prepared.load(Ordering::Relaxed);
    assert!(traced < 30, "tracing stopped after the failure ({traced} of 30 bands)");
    drop(exr); // unfinished: its temporary file is deleted
    assert_eq!(std::fs::read(&path).unwrap(), b"the old file");
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, vec!["old.exr".to_string()], "no temporary file is left");
}

/// A sink slower than the trace: counts the bands traced and not yet written (each is held in
/// memory meanwhile), and the most at once.
struct Slow {
    held: AtomicUsize,
    most: AtomicUsize,
    written: AtomicUsize,
}

impl BandSink for Slow {
    fn prepare(&self, _first_row: u32, _rows: &[f32]) -> anyhow::Result<Vec<u8>> {
        let now = self.held.fetch_add(1, Ordering::SeqCst) + 1;
        self.most.fetch_max(now, Ordering::SeqCst);
        Ok(Vec::new())
    }

    fn write(&self, _first_row: u32, _rows: &[f32], _prepared: Vec<u8>) -> anyhow::Result<()> {
        // a slow disk: every band takes a while to write, while the others trace on
        std::thread::sleep(std::time::Duration::from_millis(3));
        self.held.fetch_sub(1, Ordering::SeqCst);
        self.written.fetch_add(1, Ordering::SeqCst);
        Ok(())
    }
}

/// 60 bands of 16 rows traced by 1, 3 and 6 threads into a sink far slower than the trace: no
/// more than `bands_held(threads)` (4, 8, 14) are ever held, and every band is written. Without
/// the bound the fast trace ran ahead by most of the 60.
#[test]
fn bands_traced_ahead_of_a_slow_sink_are_bounded() {
    let mut scene = scene("");
    scene.camera = scene.camera.with_resolution(8, 960).unwrap();
    let options = options(None, f32::INFINITY);
    for threads in [1, 3, 6] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let slow = Slow {
            held: AtomicUsize::new(0),
            most: AtomicUsize::new(0),
            written: AtomicUsize::new(0),
        };
        pool.install(|| render_view_to(&scene, &scene.camera, &options, &[&slow]))
            .unwrap();
        assert_eq!(slow.written.load(Ordering::SeqCst), 60, "{threads} threads");
        let most = slow.most.load(Ordering::SeqCst);
        assert!(
            most <= bands_held(threads) && bands_held(threads) == 2 * threads + 2,
            "{threads} threads: {most} bands held at once"
        );
    }
}
