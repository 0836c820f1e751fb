//! The system allocator, asking the kernel to back large blocks with transparent huge pages.
//!
//! A large run's node, candidate and contact arrays span hundreds of megabytes, and the
//! contact passes read them at indices from lists: with 4 KiB pages nearly every such read
//! also misses the address translation cache. Where the kernel gives transparent huge pages
//! only on request (`/sys/kernel/mm/transparent_hugepage/enabled` at `madvise`, a common
//! default), [`HugePages`] requests them for every block of at least [`LARGE`] bytes, so
//! one translation covers 2 MiB. It changes where memory lies, never a value; elsewhere
//! than on Linux it is the system allocator. A binary opts in with
//! `#[global_allocator] static ALLOCATOR: HugePages = HugePages;` (docs/PERFORMANCE.md
//! has what it gains).

use std::alloc::{GlobalAlloc, Layout, System};

/// Blocks at least this large (bytes) are advised: two huge pages, so that at least one
/// aligned huge page lies inside.
pub const LARGE: usize = 4 << 20;

/// The system allocator with large blocks advised for transparent huge pages.
#[derive(Clone, Copy, Debug, Default)]
pub struct HugePages;

// SAFETY: every call is forwarded to `System` with the caller's arguments; the advice only
// changes how the kernel backs the pages of a block just allocated, within that block.
unsafe impl GlobalAlloc for HugePages {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded under the caller's contract.
        let block = unsafe { System.alloc(layout) };
        advise(block, layout.size());
        block
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded under the caller's contract.
        let block = unsafe { System.alloc_zeroed(layout) };
        advise(block, layout.size());
        block
    }

    unsafe fn dealloc(&self, block: *mut u8, layout: Layout) {
        // SAFETY: forwarded under the caller's contract.
        unsafe { System.dealloc(block, layout) }
    }

    unsafe fn realloc(&self, block: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: forwarded under the caller's contract.
        let moved = unsafe { System.realloc(block, layout, new_size) };
        advise(moved, new_size);
        moved
    }
}

/// Advises the whole pages inside `size` bytes at `block` for huge pages when the block is
/// large (a failed advice is ignored: the pages stay small).
#[cfg(target_os = "linux")]
fn advise(block: *mut u8, size: usize) {
    if block.is_null() || size < LARGE {
        return;
    }
    // SAFETY: `sysconf` reads a constant of the system.
    let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    let Ok(page) = usize::try_from(page) else {
        return;
    };
    if page == 0 {
        return;
    }
    let start = (block as usize).next_multiple_of(page);
    let end = (block as usize + size) / page * page;
    if end > start {
        // SAFETY: the range lies within the block just allocated, whose pages are ours;
        // the advice changes no content.
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise(_block: *mut u8, _size: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    /// Blocks small and large, zeroed and grown, come back as the system gives them: the
    /// contents survive a growth past the threshold and a zeroed block is zero.
    #[test]
    fn large_and_small_blocks_keep_their_contents() {
        let a = HugePages;
        for size in [64, LARGE - 1, LARGE, 3 * LARGE] {
            let layout = Layout::from_size_align(size, 8).unwrap();
            // SAFETY: a non-zero layout; the block is freed with it below.
            unsafe {
                let zeroed = a.alloc_zeroed(layout);
                assert!(!zeroed.is_null());
                assert!((0..size).step_by(4093).all(|i| *zeroed.add(i) == 0));
                for i in (0..size).step_by(4093) {
                    *zeroed.add(i) = (i % 251) as u8;
                }
                let grown = a.realloc(zeroed, layout, 2 * size + LARGE);
                assert!(!grown.is_null());
                assert!(
                    (0..size)
                        .step_by(4093)
                        .all(|i| *grown.add(i) == (i % 251) as u8)
                );
                let bigger = Layout::from_size_align(2 * size + LARGE, 8).unwrap();
                a.dealloc(grown, bigger);
            }
        }
    }
}
