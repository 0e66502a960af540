//! Bench inputs: a 640x480 rectified pair made from a Middlebury pair of the shared data
//! (teddy, bilinearly upscaled from 450x375; disparities scale by 640/450), or a synthetic
//! textured pair when the data is absent.

use image::{imageops::FilterType, GrayImage};

/// The 640x480 bench pair (left, right).
pub fn vga_pair() -> (GrayImage, GrayImage) {
    if let Some(dir) = videt_testdata::data_dir("stereo/teddy") {
        let load = |name: &str| {
            let img = image::open(dir.join(name))
                .expect("readable bench image")
                .to_luma8();
            image::imageops::resize(&img, 640, 480, FilterType::Triangle)
        };
        return (load("left.ppm"), load("right.ppm"));
    }
    synthetic_pair(640, 480, 20)
}

/// A deterministic textured pair with a constant disparity.
pub fn synthetic_pair(w: u32, h: u32, disparity: u32) -> (GrayImage, GrayImage) {
    let mut state = 7u64;
    let mut left = GrayImage::new(w + disparity, h);
    for _ in 0..400 {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let x0 = (state >> 33) as u32 % (w + disparity);
        let y0 = (state >> 17) as u32 % h;
        let v = (state >> 50) as u8;
        for y in y0..(y0 + 24).min(h) {
            for x in x0..(x0 + 30).min(w + disparity) {
                left.put_pixel(x, y, image::Luma([v]));
            }
        }
    }
    let l = image::imageops::crop_imm(&left, disparity, 0, w, h).to_image();
    let r = image::imageops::crop_imm(&left, 0, 0, w, h).to_image();
    (l, r)
}
