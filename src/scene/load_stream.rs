//! Loading a large `objects` list as a stream: the file is read in blocks, the list's elements
//! are found by the lexer of [`crate::scene::parallel_parse`], parsed in batches on worker threads and
//! built into [`Object`](crate::scene::objects::Object)s on the calling thread in file order, each batch
//! of descriptions dropped once built.
//!
//! Memory is thus the built objects plus a few blocks and batches in flight, not the file text
//! and a description per object besides (a million spheres: 129 MB of text and 400 B of
//! description each). The objects are built exactly as a load in one piece builds them (same
//! order, materials, warnings).
//!
//! Anything unusual gives `None`, and the caller loads the whole text in one piece, so that every
//! message keeps its exact line and column: a list of fewer than [`PARALLEL_OBJECTS`] elements, no
//! top-level `objects` list, inner attributes (`#![enable(...)]`), a batch or the rest of the scene
//! that does not parse, an object that does not build, text that is not UTF-8, a read error.

use crate::scene::desc::Material;
use crate::scene::desc::{ron_options, ObjectDesc, SceneDesc, PARSE_STACK_BYTES};
use crate::scene::fast_sphere::{parse_plain_sphere, PlainSphere};
use crate::scene::objects::{BuiltObjects, ObjectBuilder};
use crate::scene::parallel_parse::{objects_list_start, scan_elements, ListScan, PARALLEL_OBJECTS};
use crate::scene::shape_desc::BuildContext;
use std::collections::BTreeMap;
use std::io::Read;
use std::ops::Range;
use std::sync::mpsc;
use std::sync::Mutex;
use zeroset_primitives::Sphere;

/// Bytes read at a time.
const BLOCK_BYTES: usize = 1 << 20;

/// Text of the elements parsed as one batch (about 2,000 spheres): large enough that a parser per
/// batch costs nothing, small enough that batches in flight stay a few MB.
const BATCH_BYTES: usize = 256 << 10;

/// Batches parsed ahead of the build, per worker.
const AHEAD_PER_WORKER: usize = 4;

/// The objects of `source` built in `context`, with the rest of its description, or `None` (see
/// the module docs). On `None`, meshes this attempt loaded are forgotten again, so that the load
/// in one piece reports their warnings.
pub(crate) fn load_streamed(source: impl Read, context: &BuildContext) -> Option<BuiltObjects> {
    load_streamed_in_blocks(source, context, BLOCK_BYTES)
}

/// [`load_streamed`], reading `block_bytes` at a time.
fn load_streamed_in_blocks(source: impl Read, context: &BuildContext, block_bytes: usize) -> Option<BuiltObjects> {
    let loaded_before: Vec<std::path::PathBuf> = lock(&context.loaded).keys().cloned().collect();
    let built = stream(source, context, block_bytes);
    if built.is_none() {
        lock(&context.loaded).retain(|path, _| loaded_before.contains(path));
        context.take_warnings();
    }
    built
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A source read in blocks.
struct Blocks<R> {
    source: R,
    eof: bool,
}

impl<R: Read> Blocks<R> {
    /// Appends up to `n` bytes to `buf` (fewer only at the end); `None` on a read error.
    fn append(&mut self, buf: &mut Vec<u8>, n: usize) -> Option<()> {
        let limit = u64::try_from(n).unwrap_or(u64::MAX);
        let read = (&mut self.source).take(limit).read_to_end(buf).ok()?;
        self.eof = read < n;
        Some(())
    }
}

/// A batch of elements to parse: its sequence number, its text as a RON list, the byte ranges of
/// its elements in that text.
type Job = (usize, String, Vec<Range<usize>>);

fn stream(source: impl Read, context: &BuildContext, block_bytes: usize) -> Option<BuiltObjects> {
    let mut blocks = Blocks { source, eof: false };
    // the text up to the list's `[`, read in growing blocks (the lexer restarts on each)
    let mut buf = Vec::new();
    let list_start = loop {
        let n = block_bytes.max(buf.len());
        blocks.append(&mut buf, n)?;
        if let Some(at) = objects_list_start(&buf) {
            break at;
        }
        if blocks.eof {
            return None;
        }
    };
    if buf[..list_start].windows(3).any(|w| w == b"#![") {
        return None;
    }
    let mut pending = buf.split_off(list_start);
    let prefix = buf;
    let workers = rayon::current_num_threads().clamp(1, 64);
    let sphere_is_builtin = crate::scene::registry::is_builtin("Sphere");
    let (jobs, job_queue) = mpsc::sync_channel::<Job>(workers * AHEAD_PER_WORKER);
    let job_queue = Mutex::new(job_queue);
    std::thread::scope(|scope| {
        // owned here, so that any early return closes the queue and the workers stop
        let jobs = jobs;
        let (done, parsed) = mpsc::channel::<(usize, Option<Parsed>)>();
        for _ in 0..workers {
            let (job_queue, done) = (&job_queue, done.clone());
            std::thread::Builder::new()
                .name("scene parser".into())
                .stack_size(PARSE_STACK_BYTES)
                .spawn_scoped(scope, move || loop {
                    let Ok((seq, text, elements)) = lock(job_queue).recv() else {
                        return;
                    };
                    let objects = parse_batch(&text, &elements, sphere_is_builtin);
                    if done.send((seq, objects)).is_err() {
                        return;
                    }
                })
                .ok()?;
        }
        drop(done);
        let mut build = InOrder {
            builder: ObjectBuilder::new(context, 0),
            parsed,
            waiting: BTreeMap::new(),
            next: 0,
            sent: 0,
        };
        let mut elements = Vec::new();
        let mut started = false;
        let list_end = loop {
            elements.clear();
            let scan = scan_elements(&pending, 0, &mut elements);
            let (resume, end) = match scan {
                ListScan::Unsure => return None,
                ListScan::Open(_) if blocks.eof => return None,
                // a short list so far: read on (in growing blocks: it is scanned again) before
                // deciding
                ListScan::Open(_) if !started && elements.len() < PARALLEL_OBJECTS => {
                    let n = block_bytes.max(pending.len());
                    blocks.append(&mut pending, n)?;
                    continue;
                }
                ListScan::Closed(_) if !started && elements.len() < PARALLEL_OBJECTS => return None,
                ListScan::Open(resume) => (resume, None),
                ListScan::Closed(end) => (end, Some(end)),
            };
            started = true;
            for batch in batches(&elements) {
                let text = std::str::from_utf8(&pending[batch.start..batch.end]).ok()?;
                let source = format!("[{text}\n]");
                // element ranges in `source` (after its `[`)
                let shift = |e: &Range<usize>| e.start - batch.start + 1..e.end - batch.start + 1;
                let ranges = elements[batch.elements].iter().map(shift).collect();
                build.wait_until_below(workers * AHEAD_PER_WORKER)?;
                jobs.send((build.sent, source, ranges)).ok()?;
                build.sent += 1;
                build.take_ready()?;
            }
            if let Some(end) = end {
                break end;
            }
            pending.drain(..resume);
            blocks.append(&mut pending, block_bytes)?;
        };
        drop(jobs);
        build.wait_until_below(1)?;
        // the rest of the scene: its text before the list and from the list's `]` on
        let mut skeleton = prefix;
        skeleton.extend_from_slice(&pending[list_end..]);
        drop(pending);
        blocks.source.read_to_end(&mut skeleton).ok()?;
        let skeleton = String::from_utf8(skeleton).ok()?;
        let desc = std::thread::Builder::new()
            .name("scene parser".into())
            .stack_size(PARSE_STACK_BYTES)
            .spawn_scoped(scope, move || ron_options().from_str::<SceneDesc>(&skeleton).ok())
            .ok()?
            .join()
            .ok()??;
        if !desc.objects.is_empty() {
            return None;
        }
        let ObjectBuilder {
            mut objects, warnings, ..
        } = build.builder;
        objects.shrink_to_fit();
        Some(BuiltObjects {
            skeleton: desc,
            objects,
            warnings,
        })
    })
}

/// Consecutive elements: the byte range from the first's start to the last's end, and their
/// indices in the scanned elements.
struct Batch {
    start: usize,
    end: usize,
    elements: Range<usize>,
}

/// A parsed batch: its plain spheres built (on the parsing thread, so that the calling thread
/// only stores them), or the descriptions of its elements.
enum Parsed {
    /// Every element a plain sphere that builds: name, sphere, material.
    Spheres(Vec<(Option<String>, Sphere, Material)>),
    Descriptions(Vec<ObjectDesc>),
}

/// A batch's elements parsed (`text` a RON list, `elements` the byte ranges of its elements),
/// or `None` if it does not parse or gives another number of elements. Plain spheres are read
/// by [`parse_plain_sphere`] and built; if any element is not one, the whole list is parsed by
/// RON, and if one does not build, the batch is given as descriptions, whose build reports it.
fn parse_batch(text: &str, elements: &[Range<usize>], sphere_is_builtin: bool) -> Option<Parsed> {
    // one comma between elements (as the list scan guarantees), else RON says what is wrong
    let one_comma = elements
        .windows(2)
        .all(|pair| text[pair[0].end..pair[1].start].trim_ascii() == ",");
    if one_comma {
        let fast: Option<Vec<PlainSphere>> = elements
            .iter()
            .map(|e| parse_plain_sphere(&text[e.clone()], sphere_is_builtin))
            .collect();
        if let Some(fast) = fast {
            let spheres: Result<Vec<Sphere>, _> = fast.iter().map(|p| p.sphere.sphere()).collect();
            return Some(match spheres {
                Ok(spheres) => Parsed::Spheres(
                    fast.into_iter()
                        .zip(spheres)
                        .map(|(p, sphere)| (p.name, sphere, p.material))
                        .collect(),
                ),
                Err(_) => Parsed::Descriptions(fast.into_iter().map(PlainSphere::into_desc).collect()),
            });
        }
    }
    // a panic is a batch that did not parse: the load in one piece meets it again
    std::panic::catch_unwind(|| ron_options().from_str::<Vec<ObjectDesc>>(text))
        .ok()
        .and_then(Result::ok)
        .filter(|objects| objects.len() == elements.len())
        .map(Parsed::Descriptions)
}

/// `elements` grouped into consecutive batches of about [`BATCH_BYTES`] of text.
fn batches(elements: &[Range<usize>]) -> Vec<Batch> {
    let mut out: Vec<Batch> = Vec::new();
    for (i, e) in elements.iter().enumerate() {
        match out.last_mut() {
            Some(b) if e.end - b.start <= BATCH_BYTES => {
                b.end = e.end;
                b.elements.end = i + 1;
            }
            _ => out.push(Batch {
                start: e.start,
                end: e.end,
                elements: i..i + 1,
            }),
        }
    }
    out
}

/// Parsed batches built in the order they were sent, whatever order they come back in.
struct InOrder<'c> {
    builder: ObjectBuilder<'c>,
    parsed: mpsc::Receiver<(usize, Option<Parsed>)>,
    /// Batches back before their turn.
    waiting: BTreeMap<usize, Option<Parsed>>,
    /// The next batch to build.
    next: usize,
    /// Batches sent.
    sent: usize,
}

impl InOrder<'_> {
    /// Builds the batches that are back and due; `None` if one did not parse or an object did
    /// not build.
    fn take_ready(&mut self) -> Option<()> {
        while let Ok((seq, objects)) = self.parsed.try_recv() {
            self.waiting.insert(seq, objects);
        }
        self.build_due()
    }

    /// Waits for batches (building them) until fewer than `limit` are parsed or parsing.
    fn wait_until_below(&mut self, limit: usize) -> Option<()> {
        self.build_due()?;
        while self.sent - self.next >= limit {
            let (seq, objects) = self.parsed.recv().ok()?;
            self.waiting.insert(seq, objects);
            self.build_due()?;
        }
        Some(())
    }

    fn build_due(&mut self) -> Option<()> {
        while let Some(parsed) = self.waiting.remove(&self.next) {
            match parsed? {
                Parsed::Spheres(spheres) => {
                    for (name, sphere, material) in spheres {
                        self.builder.push_sphere(name, sphere, material).ok()?;
                    }
                }
                Parsed::Descriptions(objects) => {
                    for object in objects {
                        self.builder.push(object).ok()?;
                    }
                }
            }
            self.next += 1;
        }
        Some(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scene of `n` spheres, every third named with brackets, commas and comment markers in
    /// its name, between comments holding the same.
    fn spheres(n: usize) -> String {
        let mut text = String::from("Scene(camera: (), /* objects: [ */ objects: [\n");
        for i in 0..n {
            if i % 3 == 0 {
                text.push_str(&format!(
                    "(name: \"s [{i}], // /* ]\", shape: Sphere(center: ({i}, 0, 0), radius: 0.5)), /* ] , */\n"
                ));
            } else {
                text.push_str(&format!("(shape: Sphere(center: ({i}, 1, 0))), // ], [\n"));
            }
        }
        text.push_str("], ambient: (0.2, 0.2, 0.2))\n");
        text
    }

    #[test]
    fn a_large_list_is_streamed_whatever_the_block_size() {
        let text = spheres(PARALLEL_OBJECTS + 1_234);
        for block in [1 << 20, 4096, 61, 7] {
            let built = load_streamed_in_blocks(text.as_bytes(), &BuildContext::default(), block)
                .unwrap_or_else(|| panic!("streamed in {block}-byte blocks"));
            assert_eq!(built.objects.len(), PARALLEL_OBJECTS + 1_234);
            assert_eq!(built.skeleton.ambient, glam::DVec3::splat(0.2));
            for (i, object) in built.objects.iter().enumerate().step_by(997) {
                let bounds = object.primitive.bounds();
                let (x, r) = (i as f64, if i % 3 == 0 { 0.5 } else { 1.0 });
                assert_eq!(bounds.min.x, x - r, "object {i}");
                let name = (i % 3 == 0).then(|| format!("s [{i}], // /* ]"));
                assert_eq!(object.name.as_deref(), name.as_deref(), "object {i}");
            }
        }
    }

    #[test]
    fn short_lists_and_doubtful_text_are_left_to_the_load_in_one_piece() {
        let context = BuildContext::default();
        assert!(load_streamed(spheres(100).as_bytes(), &context).is_none());
        let text = spheres(PARALLEL_OBJECTS);
        let with_attribute = format!("#![enable(implicit_some)]\n{text}");
        assert!(load_streamed(with_attribute.as_bytes(), &context).is_none());
        let bad_object = text.replacen("radius: 0.5", "radius: -1", 1);
        assert!(load_streamed(bad_object.as_bytes(), &context).is_none());
        let bad_rest = text.replace("ambient: (0.2, 0.2, 0.2)", "ambient: (0.2, 0.2)");
        assert!(load_streamed(bad_rest.as_bytes(), &context).is_none());
        let unclosed = &text[..text.len() - 40];
        assert!(load_streamed(unclosed.as_bytes(), &context).is_none());
        // errors in plain spheres (which the fast path would read) are the load in one piece's
        let bad_number = text.replacen("radius: 0.5", "radius: 0.5e", 1);
        assert!(load_streamed(bad_number.as_bytes(), &context).is_none());
        let bad_field = text.replacen("radius: 0.5", "radius: 0.5, colour: (1, 1, 1)", 1);
        assert!(load_streamed(bad_field.as_bytes(), &context).is_none());
        let two_commas = text.replacen("0.5)), /*", "0.5)),, /*", 1);
        assert!(load_streamed(two_commas.as_bytes(), &context).is_none());
        let mut plain = String::from("Scene(camera: (), objects: [\n");
        for i in 0..PARALLEL_OBJECTS {
            plain.push_str(&format!("(shape: Sphere(center: ({i}, 0, 0), radius: 0.5)),\n"));
        }
        assert!(load_streamed(format!("{plain}])").as_bytes(), &context).is_some());
        assert!(load_streamed(format!("{plain},])").as_bytes(), &context).is_none());
        let negative = plain.replacen("radius: 0.5", "radius: -0.5", 1);
        assert!(load_streamed(format!("{negative}])").as_bytes(), &context).is_none());
        assert!(load_streamed(text.as_bytes(), &context).is_some());
    }

    /// Plain spheres (read by the fast path) and the same spheres in a batch that RON parses
    /// (one comment in it) build into the same objects as RON's parse of the whole text.
    #[test]
    fn fast_and_ron_parsed_batches_build_the_same_objects() {
        let n = PARALLEL_OBJECTS + 300;
        let mut text = String::from("Scene(camera: (), objects: [\n");
        for i in 0..n {
            let (x, r) = (f64::from(i as u32) * 0.37 - 1e3, 0.05 + f64::from(i as u32 % 7) / 3.0);
            if i % 10 == 0 {
                let c = f64::from(i as u32 % 97) / 97.0;
                text.push_str(&format!(
                    "(name: \"ball {i}\", shape: Sphere(center: ({x:?}, {r:e}, -3), radius: {r:?}), material: (color: ({c}, 0.5, 1))),\n"
                ));
            } else if i == n - 5 {
                text.push_str("/* RON for this batch */ (shape: Sphere(radius: 2)),\n");
            } else {
                text.push_str(&format!(
                    "(shape: Sphere(center: ({x:?}, {r:e}, -3), radius: {r:?})),\n"
                ));
            }
        }
        text.push_str("])\n");
        let context = BuildContext::default();
        let streamed = load_streamed(text.as_bytes(), &context).expect("streamed");
        let desc = ron_options().from_str::<SceneDesc>(&text).expect("RON parse");
        let mut builder = ObjectBuilder::new(&context, n);
        for object in desc.objects {
            builder.push(object).expect("built");
        }
        assert_eq!(streamed.objects.len(), n);
        for (i, (a, b)) in streamed.objects.iter().zip(&builder.objects).enumerate() {
            assert_eq!(format!("{a:?}"), format!("{b:?}"), "object {i}");
        }
        // equal materials share one allocation, whichever path built them
        let mut shared: std::collections::HashMap<String, *const Material> = std::collections::HashMap::new();
        for object in &streamed.objects {
            let first = *shared
                .entry(format!("{:?}", object.material))
                .or_insert(std::sync::Arc::as_ptr(&object.material));
            assert_eq!(first, std::sync::Arc::as_ptr(&object.material));
        }
        assert_eq!(
            shared.len(),
            1 + (0..n)
                .step_by(10)
                .map(|i| i % 97)
                .collect::<std::collections::HashSet<_>>()
                .len()
        );
    }
}
