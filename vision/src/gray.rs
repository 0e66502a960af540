//! Borrowed views of 8-bit grey images (whole frames or rectangular windows of them).

use crate::error::VisionError;

/// A read-only view of an 8-bit grey image or of a rectangular window inside one.
///
/// Pixel `(x, y)` of the view is `data[(y0 + y) * stride + x0 + x]`; coordinates reported by the
/// pipeline are in the full frame (`origin_px` is added back).
#[derive(Debug, Clone, Copy)]
pub struct GrayView<'a> {
    data: &'a [u8],
    stride: usize,
    /// Top-left corner of the view in the full frame, pixels.
    origin_px: (usize, usize),
    width: usize,
    height: usize,
}

impl<'a> GrayView<'a> {
    /// A view of a whole row-major frame `width x height` with no padding.
    pub fn new(data: &'a [u8], width: usize, height: usize) -> Result<Self, VisionError> {
        if width == 0 || height == 0 {
            return Err(VisionError::EmptyImage { width, height });
        }
        if data.len() != width * height {
            return Err(VisionError::BufferSize {
                expected: width * height,
                actual: data.len(),
            });
        }
        Ok(Self {
            data,
            stride: width,
            origin_px: (0, 0),
            width,
            height,
        })
    }

    /// A view of the whole of an `image` crate grey image.
    pub fn from_image(image: &'a image::GrayImage) -> Result<Self, VisionError> {
        Self::new(
            image.as_raw(),
            image.width() as usize,
            image.height() as usize,
        )
    }

    /// The window `rect` of this view (clipped to it); `None` when the clipped window is empty.
    pub fn window(&self, rect: PixelRect) -> Option<GrayView<'a>> {
        let rect = rect.clip(self.width, self.height)?;
        Some(GrayView {
            data: self.data,
            stride: self.stride,
            origin_px: (self.origin_px.0 + rect.x, self.origin_px.1 + rect.y),
            width: rect.width,
            height: rect.height,
        })
    }

    /// Width of the view, pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height of the view, pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Top-left corner of the view in the full frame, pixels.
    pub fn origin_px(&self) -> (usize, usize) {
        self.origin_px
    }

    /// Row `y` of the view.
    #[inline]
    pub fn row(&self, y: usize) -> &'a [u8] {
        let start = (self.origin_px.1 + y) * self.stride + self.origin_px.0;
        &self.data[start..start + self.width]
    }
}

/// An axis-aligned rectangle of pixels: columns `x..x + width`, rows `y..y + height`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelRect {
    /// First column.
    pub x: usize,
    /// First row.
    pub y: usize,
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
}

impl PixelRect {
    /// The rectangle clipped to a `width x height` frame; `None` if nothing is left.
    pub fn clip(self, width: usize, height: usize) -> Option<PixelRect> {
        let x1 = (self.x.saturating_add(self.width)).min(width);
        let y1 = (self.y.saturating_add(self.height)).min(height);
        if self.x >= x1 || self.y >= y1 {
            return None;
        }
        Some(PixelRect {
            x: self.x,
            y: self.y,
            width: x1 - self.x,
            height: y1 - self.y,
        })
    }

    /// Whether the point `(x, y)` (pixels, sub-pixel allowed) lies inside the rectangle.
    pub fn contains(&self, x: f32, y: f32) -> bool {
        x >= self.x as f32
            && y >= self.y as f32
            && x <= (self.x + self.width) as f32 - 1.0
            && y <= (self.y + self.height) as f32 - 1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_rows_address_the_frame() {
        let data: Vec<u8> = (0..20).collect();
        let view = GrayView::new(&data, 5, 4).unwrap();
        let w = view
            .window(PixelRect {
                x: 1,
                y: 2,
                width: 3,
                height: 5,
            })
            .unwrap();
        assert_eq!(w.height(), 2);
        assert_eq!(w.row(0), &[11, 12, 13]);
        assert_eq!(w.origin_px(), (1, 2));
    }

    #[test]
    fn bad_buffers_are_rejected() {
        assert!(GrayView::new(&[0u8; 3], 2, 2).is_err());
        assert!(GrayView::new(&[], 0, 0).is_err());
    }
}
