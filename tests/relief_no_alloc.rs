//! The relief path of the control thread allocates and frees nothing: 20 000 periods of the
//! proxy rendering a box relief (queries, proxy, blended swaps) while a vision thread publishes
//! rebuilt surfaces, under a global allocator that counts allocations made on the control thread.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use videt_config::Config;
use videt_control::{Surface, Vec3};
use videt_runtime::snapshot::SurfaceFeed;
use videt_service::relief_feed::relief_channel;
use videt_service::relief_scene::{blend_params, box_relief, proxy_params};

#[global_allocator]
static GLOBAL: videt_testkit::CountingAllocator = videt_testkit::CountingAllocator;

#[test]
fn rendering_the_relief_allocates_nothing_on_the_control_thread() {
    let config = Config::default();
    let layout = videt_runtime::setup::relief_layout(&config);
    let (model, _) = box_relief(&layout, 0.0).unwrap();
    let (mut writer, mut feed) = relief_channel(
        model,
        proxy_params(),
        blend_params(&config),
        config.control.stiffness_n_per_m,
        1e-3,
    )
    .unwrap();
    let done = Arc::new(AtomicBool::new(false));
    let vision_done = Arc::clone(&done);
    let vision = std::thread::spawn(move || {
        let mut published = 0u32;
        let mut lift = 0.0;
        while !vision_done.load(Ordering::Relaxed) {
            lift = if lift == 0.0 { 0.003 } else { 0.0 };
            let (m, _) = box_relief(&layout, lift).unwrap();
            writer.publish(m);
            published += 1;
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        published
    });
    let [cx, cy] = layout.centre_m;
    let mut contacts = 0u32;
    let mut versions = std::collections::HashSet::with_capacity(1 << 16);
    let mut seen = Vec::with_capacity(20_000);
    let before = videt_testkit::this_thread();
    for k in 0..20_000u32 {
        // Slide back and forth across the box, pressing 5 mm below its top.
        let phase = (k % 4000) as f64 / 4000.0;
        let x = cx - 0.05 + 0.1 * (1.0 - (2.0 * phase - 1.0).abs());
        let finger = Vec3::new(x, cy, 0.34);
        let view = feed.current();
        if seen.len() < seen.capacity() {
            seen.push(view.version);
        }
        if view.surface.contact(&finger).is_some() {
            contacts += 1;
        }
        if k % 500 == 0 {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
    }
    let after = videt_testkit::this_thread();
    done.store(true, Ordering::Relaxed);
    let published = vision.join().unwrap();
    versions.extend(seen);
    assert_eq!(after, before, "allocations or frees on the control thread");
    assert!(contacts > 10_000, "in contact {contacts} periods");
    assert!(
        versions.len() > 5,
        "{} surface versions rendered ({published} published)",
        versions.len()
    );
}
