//! Test support. For the real-time rules: a global allocator that counts, per thread, the
//! allocations and frees made, so a test can prove that code running on a thread (the control
//! thread, a warm pipeline) allocates and frees nothing. For a full disk: [`SmallDisk`]. For the
//! service's binary, built from its own package: [`videtd_bin`].
//!
//! ```ignore
//! #[global_allocator]
//! static GLOBAL: videt_testkit::CountingAllocator = videt_testkit::CountingAllocator;
//!
//! let (_, counts) = videt_testkit::count_allocations(|| run_the_loop());
//! assert_eq!(counts, videt_testkit::AllocCounts::default());
//! ```

mod service_binary;
mod small_disk;

pub use service_binary::videtd_bin;
pub use small_disk::SmallDisk;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

/// Allocation events on one thread.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AllocCounts {
    /// Allocations (a reallocation counts as one).
    pub allocations: u64,
    /// Frees.
    pub deallocations: u64,
}

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
    static DEALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn bump(counter: &'static std::thread::LocalKey<Cell<u64>>) {
    // `try_with`: a thread being torn down may still free memory.
    let _ = counter.try_with(|c| c.set(c.get() + 1));
}

/// The system allocator, counting every allocation and free on the thread that makes it.
#[derive(Debug, Clone, Copy, Default)]
pub struct CountingAllocator;

// SAFETY: every call is forwarded unchanged to the system allocator; counting only touches
// const-initialised thread-local cells, which never allocate.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        bump(&ALLOCATIONS);
        // SAFETY: forwarded with the caller's guarantees.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        bump(&ALLOCATIONS);
        // SAFETY: forwarded with the caller's guarantees.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        bump(&DEALLOCATIONS);
        // SAFETY: forwarded with the caller's guarantees.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        bump(&ALLOCATIONS);
        // SAFETY: forwarded with the caller's guarantees.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// The calling thread's counts so far (meaningful only with [`CountingAllocator`] installed as
/// the global allocator).
pub fn this_thread() -> AllocCounts {
    AllocCounts {
        allocations: ALLOCATIONS.with(Cell::get),
        deallocations: DEALLOCATIONS.with(Cell::get),
    }
}

/// Run `f` and return what it allocated and freed on the calling thread.
pub fn count_allocations<R>(f: impl FnOnce() -> R) -> (R, AllocCounts) {
    let before = this_thread();
    let result = f();
    let after = this_thread();
    (
        result,
        AllocCounts {
            allocations: after.allocations - before.allocations,
            deallocations: after.deallocations - before.deallocations,
        },
    )
}
