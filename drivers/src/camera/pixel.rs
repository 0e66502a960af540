//! Pixel-format conversion from camera formats to the HAL's grey and RGB frames.

use videt_hal::{GrayFrame, RgbFrame};

/// A malformed frame buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BufferTooShort {
    /// Bytes needed.
    pub needed: usize,
    /// Bytes given.
    pub got: usize,
}

/// Copy a GREY (Y8) image with row stride `stride` into `out`, reusing its buffer.
pub fn grey_from_y8(
    data: &[u8],
    width: u32,
    height: u32,
    stride: usize,
    out: &mut GrayFrame,
) -> Result<(), BufferTooShort> {
    let (w, h) = (width as usize, height as usize);
    let needed = if h == 0 { 0 } else { stride * (h - 1) + w };
    if data.len() < needed || stride < w {
        return Err(BufferTooShort {
            needed,
            got: data.len(),
        });
    }
    out.width = width;
    out.height = height;
    out.data.clear();
    for row in 0..h {
        out.data
            .extend_from_slice(&data[row * stride..row * stride + w]);
    }
    Ok(())
}

/// Convert a YUYV (YUV 4:2:2) image with row stride `stride` into grey (the Y samples) and,
/// when `rgb` is given, RGB (BT.601, limited range).
pub fn from_yuyv(
    data: &[u8],
    width: u32,
    height: u32,
    stride: usize,
    grey: &mut GrayFrame,
    mut rgb: Option<&mut RgbFrame>,
) -> Result<(), BufferTooShort> {
    let (w, h) = (width as usize, height as usize);
    let needed = if h == 0 { 0 } else { stride * (h - 1) + 2 * w };
    if data.len() < needed || stride < 2 * w || w % 2 != 0 {
        return Err(BufferTooShort {
            needed,
            got: data.len(),
        });
    }
    grey.width = width;
    grey.height = height;
    grey.data.clear();
    if let Some(rgb) = rgb.as_deref_mut() {
        rgb.width = width;
        rgb.height = height;
        rgb.data.clear();
    }
    for row in 0..h {
        let line = &data[row * stride..row * stride + 2 * w];
        for px in line.chunks_exact(4) {
            let (y0, u, y1, v) = (px[0], px[1], px[2], px[3]);
            grey.data.push(y0);
            grey.data.push(y1);
            if let Some(rgb) = rgb.as_deref_mut() {
                for y in [y0, y1] {
                    let c = 1.164 * (f32::from(y) - 16.0);
                    let d = f32::from(u) - 128.0;
                    let e = f32::from(v) - 128.0;
                    let r = c + 1.596 * e;
                    let g = c - 0.392 * d - 0.813 * e;
                    let b = c + 2.017 * d;
                    rgb.data.extend_from_slice(&[
                        r.round().clamp(0.0, 255.0) as u8,
                        g.round().clamp(0.0, 255.0) as u8,
                        b.round().clamp(0.0, 255.0) as u8,
                    ]);
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yuyv_gives_luma_and_bt601_colour() {
        // Two pixels of white (Y 235, neutral chroma) then two of pure red-ish.
        let data = [235, 128, 235, 128, 81, 90, 81, 240];
        let mut g = GrayFrame::default();
        let mut c = RgbFrame::default();
        from_yuyv(&data, 4, 1, 8, &mut g, Some(&mut c)).unwrap();
        assert_eq!(g.data, vec![235, 235, 81, 81]);
        assert_eq!(&c.data[..3], &[255, 255, 255]);
        let red = &c.data[6..9];
        assert!(red[0] > 240 && red[1] < 10 && red[2] < 10, "{red:?}");
    }

    #[test]
    fn strides_are_honoured_and_short_buffers_refused() {
        let data = [1, 2, 9, 9, 3, 4, 9, 9];
        let mut g = GrayFrame::default();
        grey_from_y8(&data, 2, 2, 4, &mut g).unwrap();
        assert_eq!(g.data, vec![1, 2, 3, 4]);
        assert_eq!(
            grey_from_y8(&data[..5], 2, 2, 4, &mut g),
            Err(BufferTooShort { needed: 6, got: 5 })
        );
        assert!(
            from_yuyv(&data, 3, 1, 8, &mut g, None).is_err(),
            "odd width"
        );
    }
}
