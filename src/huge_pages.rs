//! The system allocator, asking the kernel to back large blocks with 2 MiB pages.
//!
//! The kd-tree build writes each level's reference lists into large fresh vectors, and every
//! first touch of a 4 KiB page is a fault: on the 1M peer mesh about a tenth of a one-thread
//! build went to faulting and zeroing pages. Where transparent huge pages are enabled only on
//! request (`/sys/kernel/mm/transparent_hugepage/enabled` = `madvise`, a common default), a block
//! of at least `LARGE` bytes is advised as `MADV_HUGEPAGE`, so it faults once per 2 MiB. With
//! THP `always` the advice changes nothing; with `never`, or off Linux, there is none.

use std::alloc::{GlobalAlloc, Layout, System};

/// The page size the advice asks for (x86-64 and aarch64 with 4 KiB base pages).
const HUGE_PAGE: usize = 2 << 20;
/// Blocks from this size on are advised: at most the two partial 2 MiB pages at their ends stay
/// small, so the advice covers at least half of such a block.
const LARGE: usize = 2 * HUGE_PAGE;

/// `System`, with huge-page advice for large blocks.
pub struct HugePageSystem;

impl HugePageSystem {
    /// Advises the whole 2 MiB pages inside `[p, p + size)`.
    fn advise(p: *mut u8, size: usize) {
        if size < LARGE {
            return;
        }
        let start = (p as usize).next_multiple_of(HUGE_PAGE);
        let end = (p as usize + size) / HUGE_PAGE * HUGE_PAGE;
        if end > start {
            advise_huge(start as *mut u8, end - start);
        }
    }
}

#[cfg(target_os = "linux")]
fn advise_huge(start: *mut u8, len: usize) {
    // SAFETY: the range lies inside a live allocation; the advice changes how the kernel backs
    // it, never its contents. A refusal (THP compiled out) only leaves small pages.
    unsafe { libc::madvise(start.cast(), len, libc::MADV_HUGEPAGE) };
}

#[cfg(not(target_os = "linux"))]
fn advise_huge(_start: *mut u8, _len: usize) {}

// SAFETY: every call forwards to `System` with the caller's layout; the advice does not touch
// the memory.
unsafe impl GlobalAlloc for HugePageSystem {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            Self::advise(p, layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // A large zeroed block is a fresh mapping whose pages are not touched yet.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            Self::advise(p, layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            Self::advise(p, new_size);
        }
        p
    }
}
