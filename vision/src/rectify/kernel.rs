//! The inner loop of rectification: bilinear interpolation of a run of rectified pixels whose
//! 2x2 source windows all lie inside the camera image.
//!
//! The loop works in blocks: the windows of a block are first read into two small stack
//! arrays (the top and bottom pixel pairs, one 16-bit read each), then the interpolation of the
//! whole block runs as plain arithmetic over arrays, which the compiler vectorises. The
//! function is compiled for several instruction sets (AVX2, SSE4.1, baseline x86-64 or the
//! target's default) and the best one the CPU supports is chosen at run time by the
//! `multiversion` crate. That crate's dispatcher contains `unsafe` code of its own (calling a
//! `#[target_feature]` function after checking the CPU), which is why this one function is
//! exempt from the crate's `deny(unsafe_code)`; the function body itself is safe Rust.

use multiversion::multiversion;

use super::reference::WEIGHT_ONE;

/// Pixels per block: the stack arrays of one block fit comfortably in L1.
const BLOCK: usize = 64;

/// Interpolate `out.len()` rectified pixels. Pixel `i` has the top-left source neighbour at
/// `offsets[i]` in `pixels` (rows `stride` bytes apart) and the weights `weights_x[i]`,
/// `weights_y[i]` (1/256, `0..=255`) of its right and lower neighbours. Every window must lie
/// inside `pixels` (`offsets[i] + stride + 2 <= pixels.len()`); an offset past that is read as
/// the last window instead (never happens with tables built by this module).
#[allow(unsafe_code)]
#[multiversion(targets("x86_64+avx2+fma", "x86_64+sse4.1"))]
pub(super) fn interpolate_run(
    pixels: &[u8],
    stride: usize,
    offsets: &[u32],
    weights_x: &[u8],
    weights_y: &[u8],
    out: &mut [u8],
) {
    let Some(last_window) = pixels.len().checked_sub(stride + 2) else {
        return;
    };
    let blocks = out
        .chunks_mut(BLOCK)
        .zip(offsets.chunks(BLOCK))
        .zip(weights_x.chunks(BLOCK))
        .zip(weights_y.chunks(BLOCK));
    for (((out, offsets), weights_x), weights_y) in blocks {
        let mut top = [0u16; BLOCK];
        let mut bottom = [0u16; BLOCK];
        for ((top, bottom), &offset) in top.iter_mut().zip(bottom.iter_mut()).zip(offsets) {
            let o = (offset as usize).min(last_window);
            let window = &pixels[o..o + stride + 2];
            *top = u16::from_le_bytes([window[0], window[1]]);
            *bottom = u16::from_le_bytes([window[stride], window[stride + 1]]);
        }
        let pixels = out
            .iter_mut()
            .zip(&top)
            .zip(&bottom)
            .zip(weights_x)
            .zip(weights_y);
        for ((((out, &top), &bottom), &wx), &wy) in pixels {
            let [top_left, top_right] = top.to_le_bytes().map(u32::from);
            let [bottom_left, bottom_right] = bottom.to_le_bytes().map(u32::from);
            let (wx, wy) = (u32::from(wx), u32::from(wy));
            let top = top_left * (WEIGHT_ONE - wx) + top_right * wx;
            let bottom = bottom_left * (WEIGHT_ONE - wx) + bottom_right * wx;
            *out =
                ((top * (WEIGHT_ONE - wy) + bottom * wy + WEIGHT_ONE * WEIGHT_ONE / 2) >> 16) as u8;
        }
    }
}
