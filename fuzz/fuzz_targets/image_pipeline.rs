//! Fuzzes image decoding into the stereo pipeline: arbitrary bytes through the project's bounded
//! loader `videt_vision::io::decode_gray_image` (PNG, JPEG, PNM as the tools read them; a size
//! above the loader's bounds is refused from the header, before any pixel is decoded). A decoded
//! image is the left image of a pair whose right image is the same shifted by a few columns (a
//! scene at one depth), which goes where `videtd --scene stereo:DIR` sends a pair:
//! `StereoPair::new`, `StereoRelief::build` (edges, chains, segments, matching, 3D, the
//! bas-relief) and one live update around the area's centre (the local pipeline and the merge).
//! Images above 512 x 512 pixels are decoded but not sent on (see below).
#![no_main]

use image::GrayImage;
use libfuzzer_sys::fuzz_target;
use videt_service::stereo_relief::{LiveSettings, PairCamera, StereoPair, StereoRelief};
use videt_config::Config;
use videt_vision::io::{decode_gray_image, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE_PX};

/// Largest image (pixels) sent on to the stereo pipeline.
const PIPELINE_MAX_PIXELS: u64 = 512 * 512;

fuzz_target!(|data: &[u8]| {
    let Ok(left) = decode_gray_image(data) else {
        return;
    };
    let (w, h) = left.dimensions();
    assert!(w > 0 && h > 0 && w <= MAX_IMAGE_SIDE_PX && h <= MAX_IMAGE_SIDE_PX);
    assert!(u64::from(w) * u64::from(h) <= MAX_IMAGE_PIXELS);
    // Every size the loader accepts is decoded above; the pipeline's cost grows faster than
    // the pixel count (a 4096 x 4096 pair takes tens of seconds here), so only images up to
    // 512 x 512 pixels go on, to keep the fuzzer fast: the code paths are the same.
    if u64::from(w) * u64::from(h) > PIPELINE_MAX_PIXELS {
        return;
    }
    let shift = (w / 16).clamp(1, 8);
    let right = GrayImage::from_fn(w, h, |x, y| *left.get_pixel((x + shift).min(w - 1), y));
    let Ok(pair) = StereoPair::new("fuzz".into(), left, right, PairCamera::nominal(w)) else {
        return;
    };
    let layout = videt_runtime::setup::relief_layout(&Config::default());
    let Ok((mut relief, _model, _initial)) =
        StereoRelief::build(pair, &layout, LiveSettings::default())
    else {
        return;
    };
    let [cx, cy] = layout.centre_m;
    let _ = relief.update_around([cx, cy, layout.back_plane_z_m - 0.01], [0.01, 0.0, 0.0]);
});
