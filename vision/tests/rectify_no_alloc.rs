//! Rectifying into correctly sized frames performs no heap allocation (counted by a global
//! allocator wrapper, per thread).

#[path = "../benches/common/mod.rs"]
mod common;

use videt_hal::{GrayFrame, StereoFrame};
use videt_vision::rectify::StereoRectifier;

#[global_allocator]
static GLOBAL: videt_testkit::CountingAllocator = videt_testkit::CountingAllocator;

/// Allocations made so far on this thread.
fn allocations() -> u64 {
    videt_testkit::this_thread().allocations
}

#[test]
fn rectifying_into_sized_frames_does_not_allocate() {
    let rectifier = StereoRectifier::from_calibration(&common::rig_calibration()).unwrap();
    let frame = StereoFrame {
        left: GrayFrame {
            width: 640,
            height: 480,
            data: (0..640 * 480).map(|i| (i % 251) as u8).collect(),
        },
        right: GrayFrame {
            width: 640,
            height: 480,
            data: (0..640 * 480).map(|i| (i % 241) as u8).collect(),
        },
        ..StereoFrame::default()
    };
    let mut left = GrayFrame::default();
    let mut right = GrayFrame::default();
    // First call sizes the outputs (allocates).
    let before = allocations();
    rectifier.apply(&frame, &mut left, &mut right).unwrap();
    assert!(
        allocations() > before,
        "the counter must see the first, sizing call"
    );
    // Later calls reuse them.
    let before = allocations();
    for _ in 0..3 {
        rectifier.apply(&frame, &mut left, &mut right).unwrap();
    }
    assert_eq!(allocations() - before, 0, "rectification allocated");
    assert_eq!(
        (left.width, left.height, left.data.len()),
        (640, 480, 640 * 480)
    );
    assert!(left.data.iter().any(|&p| p != 0) && right.data.iter().any(|&p| p != 0));
}
