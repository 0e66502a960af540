//! On the rig calibration, the compact rectification tables give exactly the frames of the
//! plain per-pixel reference tables, for random images.

#[path = "../benches/common/mod.rs"]
mod common;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use videt_hal::{GrayFrame, StereoFrame};
use videt_vision::rectify::reference::ReferenceMap;
use videt_vision::rectify::StereoRectifier;

fn random_frame(rng: &mut ChaCha8Rng, width: u32, height: u32) -> GrayFrame {
    let mut data = vec![0u8; width as usize * height as usize];
    rng.fill(&mut data[..]);
    GrayFrame {
        width,
        height,
        data,
    }
}

#[test]
fn rig_rectification_equals_the_reference_tables_on_random_images() {
    let cal = common::rig_calibration();
    let (w, h) = (cal.image_width, cal.image_height);
    let rectifier = StereoRectifier::from_calibration(&cal).unwrap();
    let reference = [
        ReferenceMap::new(&cal.left(), &cal.r1(), &cal.p1(), w, h),
        ReferenceMap::new(&cal.right(), &cal.r2(), &cal.p2(), w, h),
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let (mut left, mut right) = (GrayFrame::default(), GrayFrame::default());
    let (mut expected_left, mut expected_right) = (GrayFrame::default(), GrayFrame::default());
    for _ in 0..3 {
        let frame = StereoFrame {
            left: random_frame(&mut rng, w, h),
            right: random_frame(&mut rng, w, h),
            ..StereoFrame::default()
        };
        rectifier.apply(&frame, &mut left, &mut right).unwrap();
        reference[0].apply(&frame.left, &mut expected_left).unwrap();
        reference[1]
            .apply(&frame.right, &mut expected_right)
            .unwrap();
        assert!(left == expected_left, "left frames differ");
        assert!(right == expected_right, "right frames differ");
        // The rig's tables have black borders and a large valid area.
        let black = left.data.iter().filter(|&&p| p == 0).count();
        assert!(
            black > 0 && black < left.data.len() / 4,
            "{black} black pixels"
        );
    }
}
