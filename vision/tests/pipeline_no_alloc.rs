//! Once warm, the Canny detector and the whole stereo pipeline (whole-image and local runs)
//! perform no heap allocation per frame (counted by a global allocator wrapper, per thread).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use videt_vision::canny::{CannyParams, CannyWorkspace};
use videt_vision::{GrayView, LocalRegion, RectifiedGeometry, StereoPipeline, VisionParams};

struct CountingAllocator;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn count() {
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

// SAFETY: delegates every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

fn allocations() -> usize {
    ALLOCATIONS.with(|c| c.get())
}

#[test]
fn warm_canny_and_pipeline_do_not_allocate() {
    let Some(dir) = videt_testdata::data_dir("stereo/venus") else {
        return;
    };
    let left = image::open(dir.join("left.ppm")).unwrap().to_luma8();
    let right = image::open(dir.join("right.ppm")).unwrap().to_luma8();
    let lv = GrayView::from_image(&left).unwrap();
    let rv = GrayView::from_image(&right).unwrap();

    let mut canny = CannyWorkspace::new();
    canny.detect(&lv, &CannyParams::default()).unwrap();
    let before = allocations();
    for _ in 0..3 {
        canny.detect(&lv, &CannyParams::default()).unwrap();
        canny.detect(&rv, &CannyParams::default()).unwrap();
    }
    assert_eq!(allocations(), before, "Canny allocated once warm");

    let params = VisionParams::default();
    let geometry = RectifiedGeometry {
        focal_px: 3740.0,
        cx_px: 216.5,
        cy_px: 191.0,
        baseline_m: 0.16,
    };
    let region = LocalRegion {
        centre_px: [300.0, 200.0],
        size_px: [100.0, 100.0],
        velocity_px_per_frame: [4.0, 0.0],
    };
    let mut pipeline = StereoPipeline::new();
    // Warm: the same frames twice (buffers grow to their working size).
    for _ in 0..2 {
        pipeline.run(&lv, &rv, Some(&geometry), &params).unwrap();
        pipeline
            .run_local(&lv, &rv, Some(&geometry), &params, &region)
            .unwrap();
    }
    let before = allocations();
    for _ in 0..3 {
        let matches = pipeline
            .run(&lv, &rv, Some(&geometry), &params)
            .unwrap()
            .matches
            .len();
        assert!(matches > 100);
        pipeline
            .run_local(&lv, &rv, Some(&geometry), &params, &region)
            .unwrap();
    }
    assert_eq!(allocations(), before, "the pipeline allocated once warm");
}
