//! Files of the stereo pipeline: loading images with clear errors, writing the results as
//! JSON and overlay PNGs. (I/O only; the pipeline itself never touches files.)

use crate::error::VisionError;
use crate::pipeline::PipelineOutput;
use crate::segments::Segment;
use image::{GrayImage, Rgb, RgbImage};
use serde_json::json;
use std::path::Path;

/// Largest image side the loaders accept, pixels.
pub const MAX_IMAGE_SIDE_PX: u32 = 16_384;
/// Most pixels an image the loaders accept may have (4096 x 4096): the decoder's and the stereo
/// pipeline's buffers grow with it, so a file's header alone never makes them allocate more.
pub const MAX_IMAGE_PIXELS: u64 = 4096 * 4096;
/// Most bytes the decoder may allocate (a [`MAX_IMAGE_PIXELS`] image of 16-bit RGBA).
const MAX_DECODE_BYTES: u64 = MAX_IMAGE_PIXELS * 8;

/// Loads an image file as 8-bit grey; errors name the file and say what is wrong.
pub fn load_gray_image(path: &Path) -> Result<GrayImage, VisionError> {
    let io_error = |message: String| VisionError::Io {
        path: path.display().to_string(),
        message,
    };
    let bytes = std::fs::read(path).map_err(|e| io_error(format!("cannot read: {e}")))?;
    decode_gray_image(&bytes).map_err(io_error)
}

/// Decodes an image held in memory (PNG, JPEG, PNM; the format from the content) as 8-bit grey.
/// The size is read from the header first: an image with no pixels, a side above
/// [`MAX_IMAGE_SIDE_PX`] or more than [`MAX_IMAGE_PIXELS`] pixels is refused before any pixel
/// is decoded. The error says what is wrong.
pub fn decode_gray_image(bytes: &[u8]) -> Result<GrayImage, String> {
    if bytes.is_empty() {
        return Err("the file is empty".into());
    }
    let unreadable = |e: &dyn std::fmt::Display| format!("not a readable image: {e}");
    let reader = || {
        image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| unreadable(&e))
    };
    let (width, height) = reader()?.into_dimensions().map_err(|e| unreadable(&e))?;
    check_image_size(width, height)?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE_PX);
    limits.max_image_height = Some(MAX_IMAGE_SIDE_PX);
    limits.max_alloc = Some(MAX_DECODE_BYTES);
    let mut reader = reader()?;
    reader.limits(limits);
    let image = reader.decode().map_err(|e| unreadable(&e))?.to_luma8();
    check_image_size(image.width(), image.height())?;
    Ok(image)
}

/// Whether the loaders accept an image of `width` x `height` pixels; the error says why not.
pub fn check_image_size(width: u32, height: u32) -> Result<(), String> {
    if width == 0 || height == 0 {
        return Err(format!("the image has no pixels ({width}x{height})"));
    }
    if width > MAX_IMAGE_SIDE_PX
        || height > MAX_IMAGE_SIDE_PX
        || u64::from(width) * u64::from(height) > MAX_IMAGE_PIXELS
    {
        return Err(format!(
            "the image is {width}x{height} pixels; at most {MAX_IMAGE_SIDE_PX} per side and \
             {MAX_IMAGE_PIXELS} in all are accepted"
        ));
    }
    Ok(())
}

/// Writes `segments.json`, `matches.json`, `segments3d.json` and the overlays
/// `left_segments.png`, `right_segments.png`, `matches.png` into `dir` (created if missing).
pub fn write_results(
    dir: &Path,
    output: &PipelineOutput,
    left: &GrayImage,
    right: &GrayImage,
) -> Result<(), VisionError> {
    std::fs::create_dir_all(dir).map_err(|e| VisionError::Io {
        path: dir.display().to_string(),
        message: format!("cannot create the output directory: {e}"),
    })?;
    let endpoints = |s: &[Segment]| -> Vec<[f32; 4]> {
        s.iter()
            .map(|s| [s.start[0], s.start[1], s.end[0], s.end[1]])
            .collect()
    };
    let segments = json!({
        "left": endpoints(&output.left_segments),
        "right": endpoints(&output.right_segments),
    });
    let matches = json!({
        "matches": output.matches.iter().map(|m| json!({
            "left": m.left,
            "right": m.right,
            "disparity": m.disparity_px,
            "support": m.support,
            "nearly_horizontal": m.nearly_horizontal,
        })).collect::<Vec<_>>(),
    });
    let v = |p: &nalgebra::Vector3<f64>| [p.x, p.y, p.z];
    let segments_3d = json!({
        "frame": "left rectified camera, metres (x right, y down, z forward)",
        "segments": output.segments_3d.iter().map(|s| json!({
            "match": s.match_index,
            "start_m": v(&s.start_m),
            "end_m": v(&s.end_m),
            "start_sigma_m": v(&s.start_sigma_m),
            "end_sigma_m": v(&s.end_sigma_m),
        })).collect::<Vec<_>>(),
    });
    write_atomically(&dir.join("segments.json"), segments.to_string().as_bytes())?;
    write_atomically(&dir.join("matches.json"), matches.to_string().as_bytes())?;
    write_atomically(
        &dir.join("segments3d.json"),
        segments_3d.to_string().as_bytes(),
    )?;

    let mut left_overlay = grey_to_rgb(left);
    for s in &output.left_segments {
        draw_segment(&mut left_overlay, s, Rgb([255, 40, 40]));
    }
    save_png(&dir.join("left_segments.png"), &left_overlay)?;
    let mut right_overlay = grey_to_rgb(right);
    for s in &output.right_segments {
        draw_segment(&mut right_overlay, s, Rgb([255, 40, 40]));
    }
    save_png(&dir.join("right_segments.png"), &right_overlay)?;

    let mut matches_overlay = grey_to_rgb(left);
    let (lo, hi) = output
        .matches
        .iter()
        .flat_map(|m| m.disparity_px)
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), d| {
            (lo.min(d), hi.max(d))
        });
    for m in &output.matches {
        let d = 0.5 * (m.disparity_px[0] + m.disparity_px[1]);
        let t = if hi > lo { (d - lo) / (hi - lo) } else { 0.5 };
        draw_segment(
            &mut matches_overlay,
            &output.left_segments[m.left as usize],
            colour_map(t),
        );
    }
    save_png(&dir.join("matches.png"), &matches_overlay)
}

/// Blue (far, small disparity) to red (near, large disparity).
fn colour_map(t: f32) -> Rgb<u8> {
    let t = t.clamp(0.0, 1.0);
    let r = (255.0 * (1.5 * t - 0.25).clamp(0.0, 1.0)) as u8;
    let g = (255.0 * (1.0 - (2.0 * t - 1.0).abs())) as u8;
    let b = (255.0 * (1.25 - 1.5 * t).clamp(0.0, 1.0)) as u8;
    Rgb([r, g, b])
}

fn grey_to_rgb(image: &GrayImage) -> RgbImage {
    RgbImage::from_fn(image.width(), image.height(), |x, y| {
        let v = image.get_pixel(x, y)[0] / 2 + 40;
        Rgb([v, v, v])
    })
}

fn draw_segment(image: &mut RgbImage, s: &Segment, colour: Rgb<u8>) {
    let steps = s.length_px.ceil().max(1.0) as usize * 2;
    for k in 0..=steps {
        let t = k as f32 / steps as f32;
        let x = (s.start[0] + t * (s.end[0] - s.start[0])).round();
        let y = (s.start[1] + t * (s.end[1] - s.start[1])).round();
        if x >= 0.0 && y >= 0.0 && (x as u32) < image.width() && (y as u32) < image.height() {
            image.put_pixel(x as u32, y as u32, colour);
        }
    }
}

fn save_png(path: &Path, image: &RgbImage) -> Result<(), VisionError> {
    let mut bytes = Vec::new();
    image
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .map_err(|e| VisionError::Io {
            path: path.display().to_string(),
            message: format!("cannot encode PNG: {e}"),
        })?;
    write_atomically(path, &bytes)
}

/// Writes through a temporary file in the same directory, synced, then renamed into place.
fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), VisionError> {
    use std::io::Write;
    let err = |e: std::io::Error| VisionError::Io {
        path: path.display().to_string(),
        message: format!("cannot write: {e}"),
    };
    let tmp = path.with_extension("tmp");
    let mut file = std::fs::File::create(&tmp).map_err(err)?;
    file.write_all(bytes).map_err(err)?;
    file.sync_all().map_err(err)?;
    std::fs::rename(&tmp, path).map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unreadable_and_empty_files_give_clear_errors() {
        let dir = std::env::temp_dir().join(format!("videt-vision-io-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let empty = dir.join("empty.png");
        std::fs::write(&empty, b"").unwrap();
        let e = load_gray_image(&empty).unwrap_err().to_string();
        assert!(e.contains("empty"), "{e}");
        let junk = dir.join("junk.png");
        std::fs::write(&junk, b"not an image").unwrap();
        let e = load_gray_image(&junk).unwrap_err().to_string();
        assert!(e.contains("not a readable image"), "{e}");
        let e = load_gray_image(&dir.join("missing.png"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("cannot read"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn oversized_images_are_refused_from_their_header() {
        // A PGM header announcing 20000 x 20000 pixels followed by no pixel data: refused for
        // its size before the decoder allocates anything.
        let e = decode_gray_image(b"P5\n20000 20000\n255\n").unwrap_err();
        assert!(e.contains("20000x20000"), "{e}");
        assert!(e.contains("at most"), "{e}");
        // Within each side's bound but too many pixels in all.
        let e = decode_gray_image(b"P5\n16000 16000\n255\n").unwrap_err();
        assert!(e.contains("16000x16000"), "{e}");
        let e = decode_gray_image(b"P5\n0 7\n255\n").unwrap_err();
        assert!(
            e.contains("not a readable image") || e.contains("no pixels"),
            "{e}"
        );
        // A small image decodes.
        let mut pgm = b"P5\n4 3\n255\n".to_vec();
        pgm.extend(0..12u8);
        let image = decode_gray_image(&pgm).unwrap();
        assert_eq!(image.dimensions(), (4, 3));
        assert_eq!(image.as_raw()[5], 5);
    }
}
