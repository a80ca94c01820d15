//! Test support for the workspace's zero-allocation claims ("hot paths allocate nothing"):
//! a global allocator that counts allocations per thread.
//!
//! A `#[global_allocator]` is process-wide, so each allocation test is its own test binary
//! (`tests/alloc.rs` of a crate) that installs [`CountingAllocator`]. Counting is per
//! thread, so the test harness's other threads (and other tests running in parallel) do
//! not disturb a measurement.
//!
//! ```
//! // In a test binary:
//! // #[global_allocator]
//! // static GLOBAL: alloc_counter::CountingAllocator = alloc_counter::CountingAllocator;
//! // Without the allocator installed nothing is counted, so this doc test sees zero:
//! let n = alloc_counter::allocations(|| drop(std::hint::black_box(vec![1.0_f64; 8])));
//! assert_eq!(n, 0);
//! ```

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

thread_local! {
    static COUNT: Cell<usize> = const { Cell::new(0) };
    /// Bytes allocated minus bytes freed by this thread.
    static LIVE: Cell<isize> = const { Cell::new(0) };
    /// The largest `LIVE` since [`reset_peak`].
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

fn bump() {
    // `try_with`: never panic inside the allocator, even during thread teardown.
    let _ = COUNT.try_with(|c| c.set(c.get() + 1));
}

fn grow(bytes: isize) {
    let _ = LIVE.try_with(|l| {
        let now = l.get().saturating_add(bytes);
        l.set(now);
        let _ = PEAK.try_with(|p| p.set(p.get().max(now)));
    });
}

/// The system allocator, counting `alloc`, `alloc_zeroed` and `realloc` calls of the
/// current thread (frees are not counted).
#[derive(Debug, Clone, Copy, Default)]
pub struct CountingAllocator;

// SAFETY: every call forwards to `System` with the caller's arguments unchanged.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        bump();
        grow(layout.size() as isize);
        // SAFETY: forwarded contract.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        bump();
        grow(layout.size() as isize);
        // SAFETY: forwarded contract.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        bump();
        grow(new_size as isize - layout.size() as isize);
        // SAFETY: forwarded contract.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        grow(-(layout.size() as isize));
        // SAFETY: forwarded contract.
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// Allocations made so far by the current thread (0 unless [`CountingAllocator`] is the
/// global allocator).
pub fn count() -> usize {
    COUNT.with(Cell::get)
}

/// Number of allocations the current thread makes while running `f`.
pub fn allocations(f: impl FnOnce()) -> usize {
    let before = count();
    f();
    count() - before
}

/// The peak of the bytes the current thread holds (allocated minus freed) while running
/// `f`, above what it held before: the heap high-water mark of `f` on this thread (0
/// unless [`CountingAllocator`] is the global allocator). Allocations made on other
/// threads (a thread pool) are not seen.
pub fn peak_bytes<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let before = LIVE.with(Cell::get);
    PEAK.with(|p| p.set(before));
    let out = f();
    let peak = PEAK.with(Cell::get);
    (out, usize::try_from(peak - before).unwrap_or(0))
}
