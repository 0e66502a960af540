//! A profile answers the control thread's contact queries without allocating.

use videt_control::planar::Vec2;
use videt_control::{Profile, SolidSide, Surface, Vec3};

#[global_allocator]
static GLOBAL: videt_testkit::CountingAllocator = videt_testkit::CountingAllocator;

#[test]
fn contact_queries_do_not_allocate() {
    let profile = videt_experiments::fig18::fig18_profile();
    let closed = Profile::<8>::closed(
        &[
            Vec2::new(0.1, 0.1),
            Vec2::new(0.3, 0.1),
            Vec2::new(0.3, 0.3),
            Vec2::new(0.1, 0.3),
        ],
        SolidSide::Right,
    )
    .unwrap();
    let points: Vec<Vec3> = (0..400)
        .map(|k| Vec3::new(0.0005 * k as f64, 0.01, 0.25 + 0.0003 * k as f64))
        .collect();
    let before = videt_testkit::this_thread();
    let mut contacts = 0usize;
    for p in &points {
        contacts += usize::from(profile.contact(p).is_some());
        contacts += usize::from(closed.contact(p).is_some());
    }
    let after = videt_testkit::this_thread();
    assert_eq!(after, before, "a contact query allocated");
    assert!(contacts > 0);
}
