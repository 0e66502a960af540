//! The compact remap table: the per-pixel reference table regrouped into *shift blocks* that the
//! inner loop can interpolate with whole-vector operations.
//!
//! In a rectified row the source positions follow a smooth curve: x advances by about one
//! pixel per pixel and y changes slowly. A shift block is a stretch of at most [`BLOCK_LEN`]
//! consecutive rectified pixels (all with a source) whose top-left source pixels lie on two
//! adjacent source rows `y`, `y + 1` and whose columns stay within [`MAX_SHIFT`] of a straight
//! unit-slope line `x = lo + i`. Pixel `i` of the block then reads its 2x2 window at
//! `base + i + shift` on rows `row` and `row + 1` (`row` is `y` or `y + 1`, `shift` in
//! `0..MAX_SHIFT`), so the block needs only three source rows of `BLOCK_LEN + MAX_SHIFT` bytes
//! and one code byte per pixel: bit `shift` set (one-hot) and bit 7 set when `row = y + 1`.
//! Pixels that fit no block (too close to the image's first or last rows) become single-pixel
//! blocks read with an ordinary offset.
//!
//! Weights are stored as 8-bit values (`0..=255`): a reference weight of 256/256 is folded into
//! the next source pixel with weight 0, which interpolates the same value. Where that fold
//! would move the window past the last source column or row, the pixel is listed as an *edge
//! pixel* and recomputed with the reference formula after the blocks (its block entry then
//! uses the unfolded window with zero weights, a harmless placeholder).

use super::reference::{MapEntry, OUTSIDE};

/// Maximum number of rectified pixels in a shift block (the vector width of the inner loop).
pub(super) const BLOCK_LEN: usize = 32;

/// Number of distinct column shifts a shift block can hold (bits 0..=6 of a code byte).
pub(super) const MAX_SHIFT: usize = 7;

/// Bytes of one source row read by a shift block: pixel `i < BLOCK_LEN` with shift
/// `s < MAX_SHIFT` reads columns `i + s` and `i + s + 1`.
pub(super) const BLOCK_SPAN: usize = BLOCK_LEN + MAX_SHIFT;

/// Code bit selecting the lower of the block's two top rows.
pub(super) const LOWER_ROW: u8 = 0x80;

/// A group of consecutive rectified pixels that all have a source pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Block {
    /// Up to [`BLOCK_LEN`] pixels interpolated from three source rows starting at `base`.
    Shift {
        /// Index of the first rectified pixel.
        start: u32,
        /// Number of pixels (`1..=BLOCK_LEN`).
        len: u32,
        /// Index of the block's first pixel in the per-pixel arrays.
        entry: u32,
        /// Source offset of the first byte of the block's top row.
        base: u32,
    },
    /// One pixel read with its own source offset.
    Single {
        /// Index of the rectified pixel.
        index: u32,
        /// Index of the pixel in the per-pixel arrays.
        entry: u32,
        /// Source offset of the top-left neighbour (whole 2x2 window inside the image).
        offset: u32,
    },
}

/// A rectified pixel recomputed with the reference formula after the blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct EdgePixel {
    /// Index of the rectified pixel.
    pub(super) index: u32,
    /// Its reference table entry.
    pub(super) entry: MapEntry,
}

/// The compact table of one camera.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct RemapTable {
    /// Blocks in increasing pixel order, not overlapping; pixels in no block have no source.
    pub(super) blocks: Vec<Block>,
    /// Per pixel of the blocks, in block order: shift code (see the module docs), then
    /// [`BLOCK_LEN`] zero bytes of padding so that every block can read a whole vector.
    pub(super) codes: Vec<u8>,
    /// Per pixel: weight of the right neighbour, 1/256 (`0..=255`), padded like `codes`.
    pub(super) weights_x: Vec<u8>,
    /// Per pixel: weight of the lower neighbour, 1/256 (`0..=255`), padded like `codes`.
    pub(super) weights_y: Vec<u8>,
    /// Pixels overwritten with the reference formula after the blocks.
    pub(super) edge_pixels: Vec<EdgePixel>,
    /// Number of rectified pixels with a source.
    pub(super) valid_pixels: usize,
}

/// A pixel with a source, after folding full weights: top-left source column and row, and
/// 8-bit weights.
#[derive(Debug, Clone, Copy)]
struct Folded {
    index: usize,
    x: usize,
    y: usize,
    weight_x: u8,
    weight_y: u8,
}

impl RemapTable {
    /// The compact form of a reference table of a `w` x `h` image (`entries` row-major,
    /// `w * h` long).
    pub(super) fn from_entries(entries: &[MapEntry], w: usize, h: usize) -> Self {
        let mut edge_pixels = Vec::new();
        let pixels: Vec<Folded> = entries
            .iter()
            .enumerate()
            .filter(|(_, e)| e.offset != OUTSIDE)
            .map(|(index, e)| {
                let offset = e.offset as usize;
                let (x, weight_x) = fold_weight(offset % w, e.weight_x);
                let (y, weight_y) = fold_weight(offset / w, e.weight_y);
                if x + 2 <= w && y + 2 <= h {
                    return Folded {
                        index,
                        x,
                        y,
                        weight_x,
                        weight_y,
                    };
                }
                edge_pixels.push(EdgePixel {
                    index: index as u32,
                    entry: *e,
                });
                Folded {
                    index,
                    x: offset % w,
                    y: offset / w,
                    weight_x: 0,
                    weight_y: 0,
                }
            })
            .collect();
        let mut table = RemapTable {
            blocks: Vec::new(),
            codes: Vec::with_capacity(pixels.len() + BLOCK_LEN),
            weights_x: Vec::with_capacity(pixels.len() + BLOCK_LEN),
            weights_y: Vec::with_capacity(pixels.len() + BLOCK_LEN),
            edge_pixels,
            valid_pixels: pixels.len(),
        };
        let mut first = 0;
        while first < pixels.len() {
            let len = shift_block_len(&pixels[first..]);
            table.push_block(&pixels[first..first + len], w, h);
            first += len;
        }
        for column in [&mut table.codes, &mut table.weights_x, &mut table.weights_y] {
            column.resize(column.len() + BLOCK_LEN, 0);
        }
        table
    }

    /// Append `pixels` (one shift block's worth) as a shift block, or as single pixels when
    /// the block's three source rows are not all inside the image.
    fn push_block(&mut self, pixels: &[Folded], w: usize, h: usize) {
        let row = pixels.iter().map(|p| p.y).min().unwrap_or(0);
        let lo = pixels
            .iter()
            .enumerate()
            .map(|(i, p)| p.x as isize - i as isize)
            .min()
            .unwrap_or(0);
        let base = (row * w) as isize + lo;
        let entry = self.codes.len() as u32;
        if base >= 0 && base as usize + 2 * w + BLOCK_SPAN <= w * h {
            self.blocks.push(Block::Shift {
                start: pixels[0].index as u32,
                len: pixels.len() as u32,
                entry,
                base: base as u32,
            });
            for (i, p) in pixels.iter().enumerate() {
                let shift = (p.x as isize - i as isize - lo) as u32;
                let lower = if p.y > row { LOWER_ROW } else { 0 };
                self.codes.push((1u8 << shift) | lower);
                self.weights_x.push(p.weight_x);
                self.weights_y.push(p.weight_y);
            }
        } else {
            for (i, p) in pixels.iter().enumerate() {
                debug_assert!(p.y + 2 <= h && p.x + 2 <= w);
                self.blocks.push(Block::Single {
                    index: p.index as u32,
                    entry: entry + i as u32,
                    offset: (p.y * w + p.x) as u32,
                });
                self.codes.push(0);
                self.weights_x.push(p.weight_x);
                self.weights_y.push(p.weight_y);
            }
        }
    }
}

/// Length of the longest shift block at the start of `pixels` (at least 1): consecutive
/// rectified pixels, at most [`BLOCK_LEN`], on two adjacent source rows, with column shifts
/// spanning fewer than [`MAX_SHIFT`] values.
fn shift_block_len(pixels: &[Folded]) -> usize {
    let first = pixels[0];
    let (mut row_lo, mut row_hi) = (first.y, first.y);
    let (mut shift_lo, mut shift_hi) = (first.x as isize, first.x as isize);
    let mut len = 1;
    while len < pixels.len().min(BLOCK_LEN) {
        let p = pixels[len];
        let shift = p.x as isize - len as isize;
        let (rows_lo, rows_hi) = (row_lo.min(p.y), row_hi.max(p.y));
        let (shifts_lo, shifts_hi) = (shift_lo.min(shift), shift_hi.max(shift));
        if p.index != first.index + len
            || rows_hi - rows_lo > 1
            || shifts_hi - shifts_lo >= MAX_SHIFT as isize
        {
            break;
        }
        (row_lo, row_hi, shift_lo, shift_hi) = (rows_lo, rows_hi, shifts_lo, shifts_hi);
        len += 1;
    }
    len
}

/// Source coordinate and 8-bit weight equal to (`coordinate`, `weight` in `0..=256`): a full
/// weight moves to the next coordinate with weight 0.
fn fold_weight(coordinate: usize, weight: u16) -> (usize, u8) {
    match u8::try_from(weight) {
        Ok(weight) => (coordinate, weight),
        Err(_) => (coordinate + 1, 0),
    }
}
