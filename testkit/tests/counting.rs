//! The counting allocator sees this thread's allocations and frees, and not other threads'.

use videt_testkit::{count_allocations, AllocCounts, CountingAllocator};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

#[test]
fn counts_this_threads_allocations_only() {
    let (_, counts) = count_allocations(|| drop(std::hint::black_box(vec![1u8; 64])));
    assert_eq!(
        counts,
        AllocCounts {
            allocations: 1,
            deallocations: 1
        }
    );
    let (_, counts) = count_allocations(|| {
        std::thread::spawn(|| drop(vec![0u8; 32])).join().unwrap();
    });
    // Spawning allocates on this thread; the child's own vector is not counted here.
    let (_, quiet) = count_allocations(|| std::hint::black_box(1 + 1));
    assert_eq!(quiet, AllocCounts::default());
    assert!(counts.allocations >= 1);
}
