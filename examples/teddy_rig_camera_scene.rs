//! Writes a dense 640 x 480 camera scene for `videtd --sim --scene camera:DIR`: Middlebury
//! teddy (shared data) upscaled to 640 x 480 and seen through a rig shaped like the real one,
//! as raw, distorted frames (`left.png`, `right.png`), with that rig's stereo calibration
//! (`stereo.json`). Teddy at 640 px has disparities up to ~80 px: run it with
//! `vision.max_disparity_px = 96`.
//!
//! `cargo run --release --example teddy_rig_camera_scene -- DIR`

#[path = "../vision/benches/common/mod.rs"]
mod common;

fn main() -> Result<(), String> {
    let dir = std::env::args()
        .nth(1)
        .ok_or("usage: teddy_rig_camera_scene DIR")?;
    let dir = std::path::Path::new(&dir);
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let (left, right) = common::raw_vga_pair();
    for (name, image) in [("left.png", &left), ("right.png", &right)] {
        image
            .save(dir.join(name))
            .map_err(|e| format!("{name}: {e}"))?;
    }
    common::rig_calibration()
        .save(&dir.join("stereo.json"))
        .map_err(|e| e.to_string())?;
    println!(
        "wrote {0}/left.png, {0}/right.png and {0}/stereo.json",
        dir.display()
    );
    Ok(())
}
