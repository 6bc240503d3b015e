//! Asking memory ahead: software prefetches of a node's cache lines (x86-64 `prefetcht0`, a
//! hint that never faults; nothing elsewhere), and the rule for when a walk should issue them
//! (only over nodes larger than a core's L2 cache, [`worth_prefetching`]).

/// Node bytes from which the walks prefetch ([`worth_prefetching`]): 512 KiB, the L2 cache of a
/// Zen 2/3 core (1 MiB on Zen 4 and recent Intel cores).
const PREFETCH_MIN_BYTES: usize = 512 << 10;

/// Whether a walk over `nodes` should prefetch the entered children ([`prefetch_children`]):
/// only where the nodes outgrow a core's L2 cache. In a smaller hierarchy they are in cache
/// already, and the prefetch loop's data-dependent trip count only costs mispredicted branches
/// (see docs/performance.md).
#[inline(always)]
pub(crate) fn worth_prefetching<N>(nodes: &[N]) -> bool {
    std::mem::size_of_val(nodes) >= PREFETCH_MIN_BYTES
}

/// Asks memory for the cache line holding `*p` (a hint: it never faults, whatever the address;
/// nothing on other architectures than x86-64).
#[inline(always)]
pub fn prefetch<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: a prefetch never faults, whatever the address
        unsafe { _mm_prefetch::<_MM_HINT_T0>(p.cast::<i8>()) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Asks memory for every cache line of `nodes[index]` (a hint: any index will do).
#[inline(always)]
pub(crate) fn prefetch_node<N>(nodes: &[N], index: usize) {
    let bytes = nodes.as_ptr().wrapping_add(index).cast::<u8>();
    for line in 0..std::mem::size_of::<N>().div_ceil(64) {
        prefetch(bytes.wrapping_add(64 * line));
    }
}
