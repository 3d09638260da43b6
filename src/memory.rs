//! A global allocator that asks Linux for transparent huge pages on large allocations.
//!
//! The big numeric buffers of segloc (the Cholesky factor of a pose graph, the stereo cost
//! volumes) are allocated fresh and filled once. With 4 KiB pages the kernel takes one page
//! fault per page and zeroes it: for the 15 MB factor of sphere2500 that is about 3,700
//! faults, a tenth of a cold solve. Where transparent huge pages are enabled in `madvise`
//! mode (the usual default), `madvise(MADV_HUGEPAGE)` on a fresh mapping makes the kernel
//! back it with 2 MiB pages instead, 512 times fewer faults.
//!
//! [`HugePageAllocator`] wraps the system allocator and advises every allocation of at
//! least [`HUGE_PAGE_THRESHOLD`] bytes; smaller ones are untouched. The advice is only a
//! hint: where the kernel has no huge pages it is ignored, and on other systems nothing is
//! done. The `segloc` binary installs it; a program using the library may do the same:
//!
//! ```no_run
//! #[global_allocator]
//! static ALLOCATOR: segloc::memory::HugePageAllocator = segloc::memory::HugePageAllocator;
//! ```

use std::alloc::{GlobalAlloc, Layout, System};

/// Allocations of at least this many bytes are advised to use huge pages (4 MiB: two huge
/// pages, so that at least one aligned 2 MiB page lies inside).
pub const HUGE_PAGE_THRESHOLD: usize = 4 << 20;

/// Size of a transparent huge page on x86-64 and aarch64 Linux.
const HUGE_PAGE: usize = 2 << 20;

/// The system allocator, with `MADV_HUGEPAGE` advice on large allocations.
pub struct HugePageAllocator;

// SAFETY: every call is forwarded to `System` with the same arguments; `advise` only passes
// the interior of a block just returned by `System` to `madvise`, which does not change its
// contents or validity.
unsafe impl GlobalAlloc for HugePageAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let ptr = System.alloc(layout);
        advise_large(ptr, layout.size());
        ptr
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let ptr = System.alloc_zeroed(layout);
        advise_large(ptr, layout.size());
        ptr
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let new = System.realloc(ptr, layout, new_size);
        advise_large(new, new_size);
        new
    }
}

/// [`advise_huge_pages`] for allocations of at least [`HUGE_PAGE_THRESHOLD`] bytes.
fn advise_large(ptr: *mut u8, size: usize) {
    if size >= HUGE_PAGE_THRESHOLD {
        advise_huge_pages(ptr, size);
    }
}

/// Asks the kernel to back the 2 MiB-aligned interior of `[ptr, ptr + size)` with
/// transparent huge pages, before the buffer is first touched: it then faults (and zeroes)
/// 2 MiB at a time instead of 4 KiB. Only advice: a no-op off Linux, for a null pointer or
/// a range holding no whole huge page, and an error from the kernel is ignored. `ptr` must
/// point into a live allocation of at least `size` bytes (anything else is harmless to the
/// program's memory, as `madvise` changes only how pages are backed).
pub fn advise_huge_pages(ptr: *mut u8, size: usize) {
    if ptr.is_null() {
        return;
    }
    let start = (ptr as usize).next_multiple_of(HUGE_PAGE);
    let end = (ptr as usize + size) / HUGE_PAGE * HUGE_PAGE;
    if end > start {
        #[cfg(target_os = "linux")]
        // SAFETY: the range lies inside the caller's live allocation; MADV_HUGEPAGE changes
        // only how the kernel backs it, never its contents. A failure leaves it as it was.
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_and_small_allocations_round_trip() {
        let a = HugePageAllocator;
        for size in [64, HUGE_PAGE_THRESHOLD, 3 * HUGE_PAGE_THRESHOLD + 17] {
            let layout = Layout::from_size_align(size, 64).unwrap();
            // SAFETY: the layout has a non-zero size; the block is freed with it.
            unsafe {
                let p = a.alloc_zeroed(layout);
                assert!(!p.is_null());
                assert_eq!(*p.add(size - 1), 0);
                *p.add(size - 1) = 7;
                let q = a.realloc(p, layout, size * 2);
                assert_eq!(*q.add(size - 1), 7);
                a.dealloc(q, Layout::from_size_align(size * 2, 64).unwrap());
            }
        }
    }
}
