//! The array of 4-wide nodes: one zero-initialised allocation, 64-byte aligned, whose pages
//! the operating system maps only once they are written.
//!
//! The builder does not know how many nodes a subtree will need until it is built, only a bound
//! (`items − 1`). Subtrees built in parallel each get a range of that bound and write their nodes
//! from its start, depth first; the rest of each range stays zero and is never referenced. The
//! array is obtained from `calloc`, which for a large block returns fresh zero pages from the
//! operating system without writing them, so the unused parts of the ranges take address space
//! but no memory (glibc; an allocator that clears the block itself costs memory, never
//! correctness). A zero [`Quad`] is a valid, empty node (`len = 0`). The address space taken is
//! 128 bytes per item (10⁶ scene objects: 128 MB of address space for 56 MB of nodes in use).

use super::quad::Quad;
use std::alloc::Layout;
use std::fmt;
use std::ptr::NonNull;

/// The alignment of a [`Quad`] (two cache lines from a cache-line boundary).
const QUAD_ALIGN: usize = std::mem::align_of::<Quad>();

/// Zero-initialised nodes (see the module docs).
pub(crate) struct QuadArray {
    /// The first node, `QUAD_ALIGN`-aligned inside the allocation.
    first: NonNull<Quad>,
    len: usize,
    /// The allocation (aligned to 16 only, so that the allocator's `calloc` serves it).
    base: NonNull<u8>,
    layout: Layout,
}

// SAFETY: a `QuadArray` owns its nodes exclusively, like a `Box<[Quad]>`, and `Quad` is plain data.
unsafe impl Send for QuadArray {}
// SAFETY: shared access only reads the nodes.
unsafe impl Sync for QuadArray {}

impl QuadArray {
    /// `len` zero nodes. Aborts like `Vec` where the allocator has no memory to give.
    pub(crate) fn zeroed(len: usize) -> Self {
        let layout = len
            .checked_mul(std::mem::size_of::<Quad>())
            .and_then(|size| size.checked_add(QUAD_ALIGN))
            .and_then(|size| Layout::from_size_align(size, 16).ok())
            .expect("a node array within the address space");
        // SAFETY: the layout's size is at least `QUAD_ALIGN`, not zero
        let base = unsafe { std::alloc::alloc_zeroed(layout) };
        let Some(base) = NonNull::new(base) else {
            std::alloc::handle_alloc_error(layout)
        };
        let offset = base.as_ptr().align_offset(QUAD_ALIGN);
        // SAFETY: `offset < QUAD_ALIGN` (the allocation is aligned to 16, a divisor of
        // `QUAD_ALIGN`), so `len` nodes from there end inside the allocation; the bytes are
        // zero, a valid `Quad`
        let first = unsafe { NonNull::new_unchecked(base.as_ptr().add(offset).cast::<Quad>()) };
        Self {
            first,
            len,
            base,
            layout,
        }
    }

    /// Keeps the first `len` nodes (the rest stays allocated, unused).
    pub(crate) fn truncate(&mut self, len: usize) {
        self.len = self.len.min(len);
    }
}

impl std::ops::Deref for QuadArray {
    type Target = [Quad];

    fn deref(&self) -> &[Quad] {
        // SAFETY: `first` is aligned and points at `len` initialised nodes owned by `self`
        unsafe { std::slice::from_raw_parts(self.first.as_ptr(), self.len) }
    }
}

impl std::ops::DerefMut for QuadArray {
    fn deref_mut(&mut self) -> &mut [Quad] {
        // SAFETY: as for `deref`, and `&mut self` is exclusive
        unsafe { std::slice::from_raw_parts_mut(self.first.as_ptr(), self.len) }
    }
}

impl Drop for QuadArray {
    fn drop(&mut self) {
        // SAFETY: `base` was allocated with `layout` by `zeroed`
        unsafe { std::alloc::dealloc(self.base.as_ptr(), self.layout) }
    }
}

impl Clone for QuadArray {
    /// Copies the nodes in use (`len > 0`) only, so that the copy's unused room stays untouched
    /// like the original's.
    fn clone(&self) -> Self {
        let mut copy = Self::zeroed(self.len);
        for (to, from) in copy.iter_mut().zip(self.iter()) {
            if from.len > 0 {
                *to = *from;
            }
        }
        copy
    }
}

impl Default for QuadArray {
    fn default() -> Self {
        Self::zeroed(0)
    }
}

impl fmt::Debug for QuadArray {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("QuadArray").field("len", &self.len).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nodes_are_aligned_zero_and_writable() {
        for len in [0, 1, 2, 33, 1000] {
            let mut quads = QuadArray::zeroed(len);
            assert_eq!(quads.len(), len);
            assert_eq!(quads.as_ptr() as usize % 64, 0);
            assert!(quads
                .iter()
                .all(|q| q.len == 0 && q.child == [0; 4] && q.lo == [[0.0; 4]; 3]));
            if len > 0 {
                quads[len - 1].len = 1;
                quads[len - 1].child[2] = 7;
                let copy = quads.clone();
                assert_eq!(copy[len - 1].child, [0, 0, 7, 0]);
                assert!(copy[..len - 1].iter().all(|q| q.len == 0 && q.child == [0; 4]));
                quads.truncate(1);
                assert_eq!(quads.len(), 1);
            }
        }
    }
}
