//! Up-front resource checks: a render or query whose buffers cannot fit is refused before any
//! work with the estimate in the message (never an allocation abort), and thread counts are
//! capped.
//!
//! Available memory is Linux's `MemAvailable` (`/proc/meminfo`: free memory plus what the kernel
//! can reclaim without swapping), or less where the process's cgroup (v2) limits it
//! (`memory.max − memory.current`, as in a container). Where neither can be read (other
//! systems) the memory check is skipped.

use crate::output::atomic::human_bytes;
use anyhow::{bail, Result};

/// Most worker threads per available core: more only adds scheduling overhead (and a pool of
/// 100,000 threads takes minutes to start).
pub const THREADS_PER_CORE: usize = 4;

/// Bytes the kernel says can be allocated without swapping, if known.
#[must_use]
pub fn available_memory() -> Option<u64> {
    let system = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| parse_mem_available(&text));
    // the process's cgroup v2 directory: the `0::/path` line of /proc/self/cgroup
    let group = std::fs::read_to_string("/proc/self/cgroup")
        .ok()
        .and_then(|text| text.lines().find_map(|l| l.strip_prefix("0::").map(str::to_string)))
        .unwrap_or_else(|| "/".to_string());
    let read =
        |name: &str| std::fs::read_to_string(format!("/sys/fs/cgroup{}/{name}", group.trim_end_matches('/'))).ok();
    let cgroup = match (read("memory.max"), read("memory.current")) {
        (Some(max), Some(current)) => cgroup_room(&max, &current),
        _ => None,
    };
    match (system, cgroup) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
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

/// Fails with the estimate when `estimated_bytes` exceeds the available memory.
///
/// # Errors
/// The estimate does not fit.
pub fn check_memory(what: &str, estimated_bytes: u64) -> Result<()> {
    check_memory_against(what, estimated_bytes, available_memory())
}

fn check_memory_against(what: &str, estimated_bytes: u64, available: Option<u64>) -> Result<()> {
    if let Some(available) = available {
        if estimated_bytes > available {
            bail!(
                "{what} needs about {} of memory but only {} is available; reduce it",
                human_bytes(estimated_bytes),
                human_bytes(available)
            );
        }
    }
    Ok(())
}

/// Memory of a render, in bytes: the interleaved frame, the planar copy and compressed blocks
/// of the EXR writer (each at most the frame's size), the previews' 8-bit images, and each
/// thread's per-pixel sample buffers (about 256 B per sample: position, lens point, time, hit
/// record).
#[must_use]
pub fn render_memory_estimate(pixels: u64, channels: u64, previews: u64, spp: u64, threads: u64) -> u64 {
    let frame = pixels.saturating_mul(channels).saturating_mul(4);
    let preview_bytes = pixels.saturating_mul(3).saturating_mul(previews);
    let per_thread = if spp > 1 { spp.saturating_mul(256) } else { 0 };
    frame
        .saturating_mul(3)
        .saturating_add(preview_bytes)
        .saturating_add(per_thread.saturating_mul(threads))
}

/// The thread count to use for a requested `--threads`, and a warning when it was capped at
/// [`THREADS_PER_CORE`] × the available cores.
#[must_use]
pub fn capped_threads(requested: usize) -> (usize, Option<String>) {
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    let cap = cores * THREADS_PER_CORE;
    if requested > cap {
        (
            cap,
            Some(format!(
                "warning: --threads {requested} capped at {cap} ({THREADS_PER_CORE} × {cores} cores)"
            )),
        )
    } else {
        (requested, None)
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
    fn estimate_of_a_huge_frame_is_refused_with_its_size() {
        // 100000² pixels × 10 channels × 4 B × 3 = 1.2 TB, plus 3 previews of 3 B per pixel
        let estimate = render_memory_estimate(100_000 * 100_000, 10, 3, 1, 2);
        assert_eq!(estimate, 100_000 * 100_000 * (10 * 4 * 3 + 9));
        let err = check_memory_against("the render", estimate, Some(16 << 30))
            .unwrap_err()
            .to_string();
        assert!(err.contains("1.3 TB") && err.contains("17.2 GB"), "{err}");
        check_memory_against("the render", estimate, None).unwrap();
        // samples per pixel saturate instead of overflowing
        assert_eq!(render_memory_estimate(1, 1, 0, u64::MAX, 4), u64::MAX);
    }

    #[test]
    fn threads_are_capped() {
        let cores = std::thread::available_parallelism().unwrap().get();
        assert_eq!(capped_threads(1), (1, None));
        let (n, warning) = capped_threads(100_000);
        assert_eq!(n, cores * THREADS_PER_CORE);
        assert!(warning.unwrap().contains("100000"));
    }
}
