//! Rendering straight into the output files: the window is traced in bands of rows, and each
//! finished band is handed to every [`BandSink`] (the EXR writer, the PNG previews) while the
//! other bands are still being traced, so that when the last band is traced only that band is
//! left to write.
//!
//! **Order.** Threads take bands in increasing order (rayon's `par_bridge` hands out the
//! indices of an ordered iterator), so bands finish roughly in order. A finished band goes
//! through two stages per sink:
//!
//! 1. [`BandSink::prepare`], on the thread that traced it, at once: the work that needs no order
//!    (converting samples to the file's layout, compressing EXR blocks, 8-bit preview pixels).
//! 2. [`BandSink::write`], strictly in increasing band order, one band at a time per sink: the
//!    work that does (appending to the file, a PNG's deflate stream).
//!
//! The thread that finishes band `b` writes, for each sink that no other thread is writing,
//! every band from that sink's next one up to the first not yet traced. Sinks advance
//! independently (the EXR file and three previews can be written by different threads at
//! once), and nothing ever waits for a lock: a sink another thread is writing is left to that
//! thread, which looks again for finished bands before it lets go. No rayon work runs inside a
//! sink, so a thread that writes cannot be handed a band whose sink it is already writing.
//!
//! **Memory.** A band's samples are dropped (their buffer kept for a later band) as soon as every
//! sink has written it, and no band is started more than [`bands_held`] bands ahead of the
//! slowest sink: a thread that would go further first writes what it can, then waits for the
//! writer. So at most [`bands_held`] band buffers exist at once, whatever the outputs' speed
//! (a fast trace into a slow disk held 70 bands of a 16000-pixel-wide render, 512 MB, before).
//! The lowest band not yet written is always being traced or ready to write, so the wait ends.
//!
//! **Samples.** Rows are the same rows [`crate::render::render_view`] traces (the same row
//! function, the same pixels), so a streamed file holds exactly the samples of the in-memory
//! [`crate::render::Frame`], bit for bit; the band boundaries are aligned to what the sinks ask
//! ([`BandSink::row_alignment`], an EXR codec's lines per block).

use crate::camera::Camera;
use crate::render::{FrameLayout, RenderOptions, TraceStats, Tracer};
use crate::scene::Scene;
use anyhow::Result;
use rayon::iter::{ParallelBridge, ParallelIterator};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

/// Rows per band before alignment: small enough that the last band's writing is a sliver of
/// the render, large enough that each band is a sizeable task (a 4K band is 61,440 pixels).
pub const BAND_ROWS: u32 = 16;

/// Most band buffers a streamed render holds at once with `threads` threads tracing: bands are
/// started at most this many ahead of the slowest sink (see the module docs), two per thread
/// and two more, so that every thread can trace one band while another waits to be written.
#[must_use]
pub fn bands_held(threads: usize) -> usize {
    2 * threads.max(1) + 2
}

/// Rows of a band for sinks asking rows in multiples of `alignment`.
#[must_use]
pub fn band_rows(alignment: u32) -> u32 {
    let alignment = alignment.max(1);
    BAND_ROWS.div_ceil(alignment) * alignment
}

/// An output that takes the frame's rows band by band, in order.
///
/// Bands are whole rows of the window, `rows` being interleaved samples as in
/// [`crate::render::Frame::samples`], `first_row` the full-image row number of the first.
/// Finishing the file (its offset table, renaming it into place) is the concrete type's own
/// method, called after the render.
pub trait BandSink: Sync {
    /// Every band but the last has a multiple of this many rows (counted from the window's
    /// top); 1 when any will do.
    fn row_alignment(&self) -> u32 {
        1
    }

    /// Work on a band that needs no order; called once per band, on any thread, in any order.
    /// What it returns is handed to [`BandSink::write`] with the same band.
    ///
    /// # Errors
    /// Encoding fails.
    fn prepare(&self, first_row: u32, rows: &[f32]) -> Result<Vec<u8>>;

    /// Takes a band: called once per band, in increasing row order, never for two bands at once.
    ///
    /// # Errors
    /// Writing fails; the render then stops.
    fn write(&self, first_row: u32, rows: &[f32], prepared: Vec<u8>) -> Result<()>;
}

/// A traced band waiting for the sinks that have not written it yet.
struct Slot {
    /// The band's samples, dropped once every sink has taken them.
    rows: Option<Arc<Vec<f32>>>,
    /// Each sink's prepared bytes, taken by that sink's write.
    prepared: Vec<Option<Vec<u8>>>,
}

/// Traces `camera`'s view of `scene` as `options` ask, handing every band of rows to each of
/// `sinks` as the module docs describe; returns when every sink has written every band.
///
/// # Errors
/// A sink's `prepare` or `write` fails: no further band is traced and the first error is
/// returned (the sinks are then incomplete; dropping them discards their files).
pub fn render_view_to(
    scene: &Scene,
    camera: &Camera,
    options: &RenderOptions,
    sinks: &[&dyn BandSink],
) -> Result<TraceStats> {
    let layout = FrameLayout::new(camera, options);
    let (row_len, height) = (layout.row_len(), layout.window.height());
    let alignment = sinks.iter().map(|s| s.row_alignment().max(1)).max().unwrap_or(1);
    let band_rows = band_rows(alignment);
    let bands = height.div_ceil(band_rows) as usize;
    let band_range = |b: usize| {
        let y0 = layout.window.y0 + b as u32 * band_rows;
        (y0, (y0 + band_rows).min(layout.window.y1))
    };
    let slots: Vec<Mutex<Slot>> = (0..bands)
        .map(|_| {
            Mutex::new(Slot {
                rows: None,
                prepared: Vec::new(),
            })
        })
        .collect();
    // each sink's next band to write; holding the lock is being its writer
    let cursors: Vec<Mutex<usize>> = sinks.iter().map(|_| Mutex::new(0)).collect();
    // the same, readable without waiting for a writer (updated after each band written)
    let written: Vec<AtomicUsize> = sinks.iter().map(|_| AtomicUsize::new(0)).collect();
    let slowest = || written.iter().map(|w| w.load(Ordering::Acquire)).min().unwrap_or(bands);
    let ahead = bands_held(rayon::current_num_threads());
    let failed = AtomicBool::new(false);
    let first_error: Mutex<Option<anyhow::Error>> = Mutex::new(None);
    let fail = |e: anyhow::Error| {
        failed.store(true, Ordering::Relaxed);
        first_error
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .get_or_insert(e);
    };
    // band buffers every sink has written, for the next bands to trace into (see below)
    let spare: Mutex<Vec<Vec<f32>>> = Mutex::new(Vec::new());
    let lock = |b: usize| slots[b].lock().unwrap_or_else(PoisonError::into_inner);
    let ready = |b: usize| b < bands && lock(b).rows.is_some();
    // writes sink `k`'s finished bands in order, unless another thread is already doing so
    let drain = |k: usize| {
        while let Ok(mut next) = cursors[k].try_lock() {
            while *next < bands && !failed.load(Ordering::Relaxed) {
                let taken = {
                    let mut slot = lock(*next);
                    let rows = slot.rows.clone();
                    let prepared = rows.as_ref().and_then(|_| slot.prepared[k].take());
                    if slot.prepared.iter().all(Option::is_none) {
                        slot.rows = None;
                    }
                    rows.zip(prepared)
                };
                let Some((rows, prepared)) = taken else { break };
                if let Err(e) = sinks[k].write(band_range(*next).0, &rows, prepared) {
                    fail(e);
                    return;
                }
                if let Ok(buffer) = Arc::try_unwrap(rows) {
                    spare.lock().unwrap_or_else(PoisonError::into_inner).push(buffer);
                }
                *next += 1;
                written[k].store(*next, Ordering::Release);
            }
            let following = *next;
            drop(next);
            // a band that finished while this thread held the cursor (its tracer saw the cursor
            // taken and left it) is written by this thread
            if failed.load(Ordering::Relaxed) || !ready(following) {
                return;
            }
        }
    };

    let tracer = Tracer::new(scene, camera, options, &layout);
    let traced_nanos = AtomicU64::new(0);
    (0..bands).par_bridge().for_each(|b| {
        if failed.load(Ordering::Relaxed) {
            return;
        }
        // not more than `ahead` bands past the slowest sink: write what can be written, else wait
        while b >= slowest() + ahead {
            if failed.load(Ordering::Relaxed) {
                return;
            }
            for k in 0..sinks.len() {
                drain(k);
            }
            if b >= slowest() + ahead {
                std::thread::sleep(Duration::from_micros(100));
            }
        }
        let (y0, y1) = band_range(b);
        // a written band's buffer, whose pages are mapped and likely in cache, rather than fresh
        // memory that the kernel faults in and zeroes page by page (3 % of the quadrics scene's
        // default render); its old samples are all overwritten, as every path of the tracer
        // writes every sample of every pixel (a hit's, a miss's or a pixel without a ray's)
        let recycled = spare.lock().unwrap_or_else(PoisonError::into_inner).pop();
        let mut rows = recycled.unwrap_or_default();
        if cfg!(debug_assertions) {
            // a sample the tracer failed to write would show as NaN in the tests' images
            rows.fill(f32::NAN);
        }
        rows.resize(row_len * (y1 - y0) as usize, 0.0);
        tracer.rows(y0, &mut rows);
        traced_nanos.fetch_max(tracer.elapsed().as_nanos() as u64, Ordering::Relaxed);
        let prepared: Result<Vec<Option<Vec<u8>>>> =
            sinks.iter().map(|sink| sink.prepare(y0, &rows).map(Some)).collect();
        match prepared {
            Ok(_) if sinks.is_empty() => {}
            Ok(prepared) => {
                *lock(b) = Slot {
                    rows: Some(Arc::new(rows)),
                    prepared,
                };
            }
            Err(e) => return fail(e),
        }
        for k in 0..sinks.len() {
            drain(k);
        }
    });
    // every band is traced: whatever a sink has not written yet is written now
    for k in 0..sinks.len() {
        drain(k);
    }
    let stats = tracer.finish(Duration::from_nanos(traced_nanos.into_inner()));
    if let Some(e) = first_error.into_inner().unwrap_or_else(PoisonError::into_inner) {
        return Err(e);
    }
    debug_assert!(cursors
        .iter()
        .all(|c| *c.lock().unwrap_or_else(PoisonError::into_inner) == bands));
    Ok(stats)
}
