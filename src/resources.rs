//! The one guarded entry for what a user's numbers size: frames, sample buffers, ray and output
//! arrays, pose lists and input files. The command line, the views and the Python bindings all
//! come through here before allocating, so an absurd `width`, `spp`, ray count or file is
//! refused at once with the estimate in the message, never an allocation abort.
//!
//! - **Memory**: [`ensure_memory`] compares an estimate with [`memory_room`], the least of
//!   Linux's `MemAvailable` (`/proc/meminfo`: free memory plus what the kernel can reclaim
//!   without swapping), the room under the process's cgroup (v2) limit (`memory.max −
//!   memory.current`, as in a container) and the address space left under `RLIMIT_AS`
//!   (`ulimit -v`: the limit less the process's virtual size, `/proc/self/statm`). Where none can
//!   be read (other systems) the check is skipped; estimates under [`UNCHECKED_BYTES`] are not
//!   checked (reading the limits would cost more than they risk). What is then allocated is
//!   reserved fallibly ([`try_with_capacity`], [`try_vec`]), so an allocation that fails anyway
//!   is the same error, not an abort. [`RenderMemory`] is what a render holds.
//! - **Threads**: [`capped_threads`], at most [`THREADS_PER_CORE`] per core.
//! - **Input files**: [`open_input`] and [`read_input_to_string`] read only regular files (a FIFO
//!   or device could wait for ever or never end; it is refused without being waited on) of at
//!   most [`input_limit`] bytes, [`DEFAULT_INPUT_LIMIT`] unless the environment variable
//!   [`INPUT_LIMIT_VAR`] says otherwise.

use std::fmt;

mod input;
pub use input::{
    check_input_path, file_kind, input_limit, input_limit_or, open_input, read_input_to_string, BoundedReader,
    InputFile,
};

/// Most worker threads per available core: more only adds scheduling overhead (and a pool of
/// 100,000 threads takes minutes to start).
pub const THREADS_PER_CORE: usize = 4;

/// Estimates below this many bytes are not checked against the limits.
pub const UNCHECKED_BYTES: u64 = 16 << 20;

/// Bytes a thread holds per sample of a pixel with several samples: the sample's position, lens
/// point and time, its stratification scratch, its hit record and count entry (all but the
/// scratch in vectors grown by doubling, so counted twice), rounded up (a test in
/// `render::sampled` checks that it covers them).
pub const BYTES_PER_SAMPLE: u64 = 640;

/// The largest input file read unless [`INPUT_LIMIT_VAR`] says otherwise: 4 GiB.
pub const DEFAULT_INPUT_LIMIT: u64 = 4 << 30;

/// The environment variable that sets the input-file limit, in bytes.
pub const INPUT_LIMIT_VAR: &str = "ZEROSET_MAX_INPUT_BYTES";

/// What bounds the memory a process can still take.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Limit {
    /// The system's available memory (`MemAvailable`).
    Available,
    /// The cgroup's `memory.max`.
    Cgroup,
    /// `RLIMIT_AS` (`ulimit -v`), of this many bytes.
    AddressSpace(u64),
}

/// Bytes that can still be allocated, and the limit that says so.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Room {
    /// Bytes left.
    pub bytes: u64,
    /// The limit they are left under.
    pub limit: Limit,
}

/// An allocation refused before it was tried (the estimate exceeds the room), or tried and
/// failed (`room` is `None`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NotEnoughMemory {
    /// What needed it, e.g. "rendering 1000x1000 with 4 channels at 16 spp".
    pub what: String,
    /// The estimate, in bytes.
    pub needed: u64,
    /// The room it was compared with; `None` where the allocation itself failed.
    pub room: Option<Room>,
}

impl fmt::Display for NotEnoughMemory {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let needed = human_bytes(self.needed);
        match self.room {
            Some(Room { bytes, limit }) => {
                let under = match limit {
                    Limit::Available => "is available".to_string(),
                    Limit::Cgroup => "is left under the cgroup's memory.max".to_string(),
                    Limit::AddressSpace(total) => format!(
                        "is left under the address-space limit of {} (ulimit -v)",
                        human_bytes(total)
                    ),
                };
                write!(
                    f,
                    "{} needs about {needed} of memory but only {} {under}; reduce it",
                    self.what,
                    human_bytes(bytes)
                )
            }
            None => write!(
                f,
                "{} needs about {needed} of memory, which could not be allocated; reduce it",
                self.what
            ),
        }
    }
}

impl std::error::Error for NotEnoughMemory {}

/// The room this process has for new allocations: the least of the available memory, the
/// cgroup's room and the address space under `RLIMIT_AS`; `None` where none is known.
#[must_use]
pub fn memory_room() -> Option<Room> {
    let available = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| parse_mem_available(&text))
        .map(|bytes| Room {
            bytes,
            limit: Limit::Available,
        });
    let cgroup = cgroup_room_now().map(|bytes| Room {
        bytes,
        limit: Limit::Cgroup,
    });
    [available, cgroup, address_space_room()]
        .into_iter()
        .flatten()
        .min_by_key(|room| room.bytes)
}

/// Bytes the process can still allocate, if known ([`memory_room`]).
#[must_use]
pub fn available_memory() -> Option<u64> {
    memory_room().map(|room| room.bytes)
}

/// The room under the process's cgroup v2 limit, if it has one.
fn cgroup_room_now() -> Option<u64> {
    // the process's cgroup v2 directory: the `0::/path` line of /proc/self/cgroup
    let group = std::fs::read_to_string("/proc/self/cgroup")
        .ok()
        .and_then(|text| text.lines().find_map(|l| l.strip_prefix("0::").map(str::to_string)))
        .unwrap_or_else(|| "/".to_string());
    let read =
        |name: &str| std::fs::read_to_string(format!("/sys/fs/cgroup{}/{name}", group.trim_end_matches('/'))).ok();
    cgroup_room(&read("memory.max")?, &read("memory.current")?)
}

/// Room left under a cgroup v2 limit: `memory.max` (bytes, or `max` for none) minus
/// `memory.current`.
fn cgroup_room(max: &str, current: &str) -> Option<u64> {
    let max: u64 = max.trim().parse().ok()?; // "max": no limit
    let current: u64 = current.trim().parse().ok()?;
    Some(max.saturating_sub(current))
}

/// `MemAvailable` in bytes from the text of `/proc/meminfo`.
fn parse_mem_available(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// The address space left under `RLIMIT_AS`, if it is limited.
#[cfg(target_os = "linux")]
fn address_space_room() -> Option<Room> {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit only writes the struct it is given
    if unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut limit) } != 0 || limit.rlim_cur == libc::RLIM_INFINITY {
        return None;
    }
    #[allow(clippy::unnecessary_cast)] // rlim_t is narrower than u64 on some targets
    let total = limit.rlim_cur as u64;
    // SAFETY: sysconf reads a constant of the system
    let page = u64::try_from(unsafe { libc::sysconf(libc::_SC_PAGESIZE) }).unwrap_or(4096);
    let used = std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|text| parse_statm_size(&text, page))
        .unwrap_or(0);
    Some(address_space_left(total, used))
}

#[cfg(not(target_os = "linux"))]
fn address_space_room() -> Option<Room> {
    None
}

/// The room under an address-space limit of `total` bytes of which `used` are mapped.
fn address_space_left(total: u64, used: u64) -> Room {
    Room {
        bytes: total.saturating_sub(used),
        limit: Limit::AddressSpace(total),
    }
}

/// The virtual size in bytes from the text of `/proc/self/statm` (its first field, in pages).
fn parse_statm_size(statm: &str, page: u64) -> Option<u64> {
    statm.split_whitespace().next()?.parse::<u64>().ok()?.checked_mul(page)
}

/// Refuses `estimated_bytes` for `what` when it exceeds the room ([`memory_room`]); estimates
/// under [`UNCHECKED_BYTES`] always pass.
///
/// # Errors
/// The estimate does not fit, with both numbers in the message.
pub fn ensure_memory(what: &str, estimated_bytes: u64) -> Result<(), NotEnoughMemory> {
    if estimated_bytes < UNCHECKED_BYTES {
        return Ok(());
    }
    ensure_within(what, estimated_bytes, memory_room())
}

fn ensure_within(what: &str, estimated_bytes: u64, room: Option<Room>) -> Result<(), NotEnoughMemory> {
    match room {
        Some(room) if estimated_bytes > room.bytes => Err(NotEnoughMemory {
            what: what.to_string(),
            needed: estimated_bytes,
            room: Some(room),
        }),
        _ => Ok(()),
    }
}

/// An empty vector with room for `n` items, reserved fallibly.
///
/// # Errors
/// The reservation failed (an error naming `what` and the bytes, instead of an abort).
pub fn try_with_capacity<T>(n: usize, what: &str) -> Result<Vec<T>, NotEnoughMemory> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| NotEnoughMemory {
        what: what.to_string(),
        needed: (n as u64).saturating_mul(std::mem::size_of::<T>() as u64),
        room: None,
    })?;
    Ok(v)
}

/// `n` copies of `value`, reserved fallibly.
///
/// # Errors
/// As [`try_with_capacity`].
pub fn try_vec<T: Clone>(n: usize, value: T, what: &str) -> Result<Vec<T>, NotEnoughMemory> {
    let mut v = try_with_capacity(n, what)?;
    v.resize(n, value);
    Ok(v)
}

/// What a render holds at its peak, in the terms of [`RenderMemory::bytes`]. The scene itself
/// (meshes, octrees) is not counted: it is loaded before the check, within its own limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RenderMemory {
    /// Width of the window rendered, in pixels.
    pub width: u32,
    /// Height of the window rendered, in pixels.
    pub height: u32,
    /// float32 samples a pixel (all AOVs' channels).
    pub channels: u64,
    /// Whole frames of the window's samples held at once (the command line's EXR writer: the
    /// interleaved frame, its planar copy and the compressed blocks; Python: the returned planes).
    pub frames: u64,
    /// Pixels of the band buffers held besides the frames (a render in bands: for a streamed
    /// render, [`crate::render::stream::bands_held`] bands).
    pub band_pixels: u64,
    /// Bytes a band pixel holds besides its samples (a streamed render: the EXR blocks encoded
    /// from the band, at most its samples' bytes and a header a block, and 3 a pixel for each
    /// 8-bit preview written as the bands arrive).
    pub band_extra: u64,
    /// Bytes a pixel of the window held in whole planes besides the frames and previews (a
    /// streamed depth preview keeps its `f32` depths, 4, then makes its 8-bit image, 3).
    pub planes: u64,
    /// 8-bit RGB previews (3 bytes a pixel each).
    pub previews: u64,
    /// Samples per pixel.
    pub spp: u32,
    /// Threads tracing at once, each with its own sample buffers.
    pub threads: usize,
}

impl RenderMemory {
    /// Bytes of the frames, bands, previews, planes and each thread's per-pixel sample buffers
    /// ([`BYTES_PER_SAMPLE`] a sample when `spp > 1`), saturating instead of overflowing.
    #[must_use]
    pub fn bytes(&self) -> u64 {
        let pixels = u64::from(self.width) * u64::from(self.height);
        let pixel_bytes = self.channels.saturating_mul(4);
        let frames = pixels.saturating_mul(pixel_bytes).saturating_mul(self.frames);
        let band = self
            .band_pixels
            .saturating_mul(pixel_bytes.saturating_add(self.band_extra));
        let previews = pixels.saturating_mul(3).saturating_mul(self.previews);
        let planes = pixels.saturating_mul(self.planes);
        let per_thread = if self.spp > 1 {
            u64::from(self.spp).saturating_mul(BYTES_PER_SAMPLE)
        } else {
            0
        };
        frames
            .saturating_add(band)
            .saturating_add(previews)
            .saturating_add(planes)
            .saturating_add(per_thread.saturating_mul(self.threads as u64))
    }

    /// The estimate ([`RenderMemory::bytes`]), refused where it does not fit ([`ensure_memory`]).
    ///
    /// # Errors
    /// The render does not fit, with its size, channels and samples in the message.
    pub fn ensure(&self) -> Result<u64, NotEnoughMemory> {
        let bytes = self.bytes();
        ensure_memory(
            &format!(
                "rendering {}x{} with {} channels at {} spp",
                self.width, self.height, self.channels, self.spp
            ),
            bytes,
        )?;
        Ok(bytes)
    }
}

/// Samples a second one thread traces at best (a single sphere at 1 spp, writing included, traced
/// 256 million pixels in 25 s on 2 threads): what [`long_work_warning`] divides by, so its
/// times are lower bounds.
pub const SAMPLES_PER_THREAD_SECOND: f64 = 5e6;

/// Seconds of estimated work above which [`long_work_warning`] warns.
pub const LONG_WORK_SECONDS: f64 = 180.0;

/// A warning (without a `warning:` prefix) for a render of `views` views of `width × height`
/// pixels at `spp` samples on `threads` threads whose samples would take more than
/// [`LONG_WORK_SECONDS`] even at [`SAMPLES_PER_THREAD_SECOND`]; `None` below that.
#[must_use]
pub fn long_work_warning(width: u32, height: u32, spp: u32, views: usize, threads: usize) -> Option<String> {
    let samples = f64::from(width) * f64::from(height) * f64::from(spp) * views.max(1) as f64;
    let seconds = samples / (SAMPLES_PER_THREAD_SECOND * threads.max(1) as f64);
    (seconds > LONG_WORK_SECONDS).then(|| {
        let time = if seconds < 7200.0 {
            format!("{:.0} minutes", seconds / 60.0)
        } else {
            format!("{:.1} hours", seconds / 3600.0)
        };
        let views = if views > 1 {
            format!(" × {views} views")
        } else {
            String::new()
        };
        format!(
            "{width}x{height} at {spp} spp{views} is {samples:.1e} samples: at least {time} on {threads} \
             thread(s) (at {SAMPLES_PER_THREAD_SECOND:.0e} samples a second each, a simple scene's rate); \
             Ctrl-C stops it and removes the unfinished outputs"
        )
    })
}

/// The thread count to use for a requested count, and a warning (without a `warning:` prefix)
/// when it was capped at [`THREADS_PER_CORE`] × the available cores (`flag` names the option in
/// the warning).
#[must_use]
pub fn capped_threads(requested: usize, flag: &str) -> (usize, Option<String>) {
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    let cap = cores * THREADS_PER_CORE;
    if requested > cap {
        (
            cap,
            Some(format!(
                "{flag} {requested} capped at {cap} ({THREADS_PER_CORE} × {cores} cores)"
            )),
        )
    } else {
        (requested, None)
    }
}

/// User + system CPU time of this process so far, in seconds (Linux `/proc/self/stat`; `None`
/// elsewhere). On a machine shared with other work, CPU time is the fairer measure of a phase's
/// cost than its wall time.
#[must_use]
pub fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // the fields after the parenthesised command name; utime and stime are fields 14 and 15
    let (_, after) = stat.rsplit_once(')')?;
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0) // USER_HZ, 100 on every Linux ABI
}

/// `1234567` → `"1.2 MB"` (decimal units).
#[must_use]
pub fn human_bytes(bytes: u64) -> String {
    let b = bytes as f64;
    match bytes {
        0..1_000 => format!("{bytes} B"),
        1_000..1_000_000 => format!("{:.1} kB", b / 1e3),
        1_000_000..1_000_000_000 => format!("{:.1} MB", b / 1e6),
        1_000_000_000..1_000_000_000_000 => format!("{:.1} GB", b / 1e9),
        _ => format!("{:.1} TB", b / 1e12),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mem_available_is_parsed_in_bytes() {
        let text = "MemTotal:       24000000 kB\nMemFree:  100 kB\nMemAvailable:   2048 kB\n";
        assert_eq!(parse_mem_available(text), Some(2048 * 1024));
        assert_eq!(parse_mem_available("MemTotal: 1 kB\n"), None);
    }

    #[test]
    fn cgroup_room_is_the_limit_less_the_usage() {
        assert_eq!(cgroup_room("8589934592\n", "1073741824\n"), Some(7 << 30));
        assert_eq!(cgroup_room("max\n", "1073741824\n"), None);
        assert_eq!(cgroup_room("100\n", "200\n"), Some(0));
    }

    #[test]
    fn address_space_room_is_the_limit_less_the_mapped_size() {
        assert_eq!(parse_statm_size("1000 200 30 4 0 500 0\n", 4096), Some(4_096_000));
        assert_eq!(parse_statm_size("", 4096), None);
        let room = address_space_left(2 << 30, 500 << 20);
        assert_eq!(room.bytes, (2 << 30) - (500 << 20));
        let err = ensure_within("rendering 8x8 with 4 channels at 10000000 spp", 5 << 30, Some(room))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("5.4 GB") && err.contains("1.6 GB") && err.contains("address-space limit of 2.1 GB"),
            "{err}"
        );
        assert_eq!(address_space_left(100, 200).bytes, 0);
    }

    #[test]
    fn estimate_of_a_huge_frame_is_refused_with_its_size() {
        // 100000² pixels × 10 channels × 4 B × 3 frames = 1.2 TB, plus 3 previews of 3 B a pixel
        let render = RenderMemory {
            width: 100_000,
            height: 100_000,
            channels: 10,
            frames: 3,
            band_pixels: 0,
            previews: 3,
            spp: 1,
            threads: 2,
            ..RenderMemory::default()
        };
        let estimate = render.bytes();
        assert_eq!(estimate, 100_000 * 100_000 * (10 * 4 * 3 + 9));
        let available = Some(Room {
            bytes: 16 << 30,
            limit: Limit::Available,
        });
        let err = ensure_within("the render", estimate, available)
            .unwrap_err()
            .to_string();
        assert!(err.contains("1.3 TB") && err.contains("17.2 GB is available"), "{err}");
        ensure_within("the render", estimate, None).unwrap();
        // the one entry refuses it too, wherever the room is smaller than 1 TB
        if available_memory().is_some_and(|a| a < 1 << 40) {
            let err = render.ensure().unwrap_err().to_string();
            assert!(err.starts_with("rendering 100000x100000 with 10 channels at 1 spp needs about 1.3 TB"));
        }
        // samples per pixel saturate instead of overflowing
        let samples = RenderMemory {
            width: 1,
            height: 1,
            channels: 1,
            frames: 1,
            band_pixels: 0,
            previews: 0,
            spp: u32::MAX,
            threads: usize::MAX,
            ..RenderMemory::default()
        };
        assert_eq!(samples.bytes(), u64::MAX);
        // a band and its per-thread samples: 16 spp × 640 B × 4 threads
        let band = RenderMemory {
            width: 10,
            height: 10,
            channels: 2,
            frames: 0,
            band_pixels: 50,
            previews: 0,
            spp: 16,
            threads: 4,
            ..RenderMemory::default()
        };
        assert_eq!(band.bytes(), 50 * 8 + 16 * 640 * 4);
        // a streamed 16000² render of 7 channels on 2 threads holds 6 bands of 16 rows, each
        // pixel with its 28 B of samples, 28 B of EXR blocks and 1 B of block headers, and a
        // depth preview's planes (7 B a pixel): 87.6 MB + 1.79 GB, not three 7.2 GB frames
        let streamed = RenderMemory {
            width: 16_000,
            height: 16_000,
            channels: 7,
            band_pixels: 6 * 16 * 16_000,
            band_extra: 29,
            planes: 7,
            spp: 1,
            threads: 2,
            ..RenderMemory::default()
        };
        assert_eq!(streamed.bytes(), 1_536_000 * 57 + 256_000_000 * 7);
        assert_eq!(human_bytes(streamed.bytes()), "1.9 GB");
    }

    #[test]
    fn small_estimates_pass_and_failed_reservations_are_errors() {
        ensure_memory("a small thing", UNCHECKED_BYTES - 1).unwrap();
        assert_eq!(try_vec(3, 7u8, "three bytes").unwrap(), [7, 7, 7]);
        let err = try_with_capacity::<u64>(usize::MAX / 4, "a huge buffer").unwrap_err();
        assert_eq!(err.room, None);
        assert!(err.to_string().starts_with("a huge buffer needs about"), "{err}");
    }

    #[test]
    fn long_work_is_announced() {
        // 4000² × 1000 spp = 1.6e10 samples; at 5e6 a second on 2 threads: 1600 s = 27 minutes
        let warning = long_work_warning(4000, 4000, 1000, 1, 2).unwrap();
        assert!(
            warning.starts_with("4000x4000 at 1000 spp is 1.6e10 samples: at least 27 minutes on 2 thread(s)"),
            "{warning}"
        );
        // 1.6e12 samples on 16 threads: 20000 s = 5.6 hours
        assert!(long_work_warning(40_000, 40_000, 1000, 1, 16)
            .unwrap()
            .contains("at least 5.6 hours"));
        // 1920x1080 at 64 spp on 2 threads: 13.3 s, no warning; 2 views × 100 spp of 4000²: 320 s
        assert_eq!(long_work_warning(1920, 1080, 64, 1, 2), None);
        assert!(long_work_warning(4000, 4000, 100, 2, 2).unwrap().contains("× 2 views"));
    }

    #[test]
    fn threads_are_capped() {
        let cores = std::thread::available_parallelism().unwrap().get();
        assert_eq!(capped_threads(1, "--threads"), (1, None));
        let (n, warning) = capped_threads(100_000, "--threads");
        assert_eq!(n, cores * THREADS_PER_CORE);
        assert!(warning.unwrap().contains("--threads 100000"));
    }

    #[test]
    fn human_bytes_units() {
        assert_eq!(human_bytes(999), "999 B");
        assert_eq!(human_bytes(1_500_000), "1.5 MB");
        assert_eq!(human_bytes(40_000_000_000), "40.0 GB");
    }
}
