//! The inner loops of rectification: interpolating every block of a [`RemapTable`], and
//! splitting a colour frame into channel planes and merging them back.
//!
//! A shift block (see [`super::layout`]) is computed for all [`BLOCK_LEN`] lanes at once from
//! three fixed-size source row windows: for each of the [`MAX_SHIFT`] possible column shifts
//! the shifted rows are masked with the lanes whose code selects that shift and merged, then
//! the row bit picks the top and bottom pairs and the bilinear formula runs on whole vectors.
//! Every operation is a plain array operation without branches, so the compiler vectorises the
//! block (byte lanes for the selection, 32-bit lanes for the arithmetic).
//!
//! The functions are compiled for several instruction sets (AVX-512BW, AVX2, SSE4.1 or SSSE3,
//! and the target's baseline) and the best one the CPU supports is chosen at run time by the
//! `multiversion` crate. That crate's dispatcher contains `unsafe` code of its own (calling a
//! `#[target_feature]` function after checking the CPU), which is why these functions are
//! exempt from the crate's `deny(unsafe_code)`; their bodies are safe Rust.

use multiversion::multiversion;

use super::layout::{Block, RemapTable, BLOCK_LEN, BLOCK_SPAN, LOWER_ROW, MAX_SHIFT};
use super::reference::WEIGHT_ONE;

/// Bilinear interpolation with weights in 1/256 (the reference formula).
#[inline(always)]
fn bilinear(top_left: u8, top_right: u8, bottom_left: u8, bottom_right: u8, wx: u8, wy: u8) -> u8 {
    let [top_left, top_right, bottom_left, bottom_right] =
        [top_left, top_right, bottom_left, bottom_right].map(u32::from);
    let (wx, wy) = (u32::from(wx), u32::from(wy));
    let top = top_left * (WEIGHT_ONE - wx) + top_right * wx;
    let bottom = bottom_left * (WEIGHT_ONE - wx) + bottom_right * wx;
    ((top * (WEIGHT_ONE - wy) + bottom * wy + WEIGHT_ONE * WEIGHT_ONE / 2) >> 16) as u8
}

/// Rectify `pixels` (rows `stride` bytes apart, the size the table was built for) into `out`
/// (same size): blocks interpolated, pixels without a source set to 0. Edge pixels are left
/// to the caller.
#[allow(unsafe_code)]
#[multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+sse4.1"
))]
pub(super) fn remap(table: &RemapTable, pixels: &[u8], stride: usize, out: &mut [u8]) {
    warm_cache(pixels);
    let mut written = 0;
    for block in &table.blocks {
        match *block {
            Block::Shift {
                start,
                len,
                entry,
                base,
            } => {
                let (start, len, entry, base) =
                    (start as usize, len as usize, entry as usize, base as usize);
                out[written..start].fill(0);
                let rows = [0, 1, 2].map(|r| {
                    let row: &[u8; BLOCK_SPAN] = pixels
                        [base + r * stride..base + r * stride + BLOCK_SPAN]
                        .try_into()
                        .expect("slice of BLOCK_SPAN bytes");
                    row
                });
                let lanes = entry..entry + BLOCK_LEN;
                let codes: &[u8; BLOCK_LEN] = table.codes[lanes.clone()]
                    .try_into()
                    .expect("slice of BLOCK_LEN bytes");
                let weights_x: &[u8; BLOCK_LEN] = table.weights_x[lanes.clone()]
                    .try_into()
                    .expect("slice of BLOCK_LEN bytes");
                let weights_y: &[u8; BLOCK_LEN] = table.weights_y[lanes]
                    .try_into()
                    .expect("slice of BLOCK_LEN bytes");
                // Lanes past `len` compute values for the following pixels, which are written
                // again later (by their own block, the gap fill or the tail fill).
                if let Some(dst) = out.get_mut(start..start + BLOCK_LEN) {
                    let dst: &mut [u8; BLOCK_LEN] =
                        dst.try_into().expect("slice of BLOCK_LEN bytes");
                    shift_block(&rows, codes, weights_x, weights_y, dst);
                } else {
                    let mut dst = [0u8; BLOCK_LEN];
                    shift_block(&rows, codes, weights_x, weights_y, &mut dst);
                    out[start..start + len].copy_from_slice(&dst[..len]);
                }
                written = start + len;
            }
            Block::Single {
                index,
                entry,
                offset,
            } => {
                let (index, entry, o) = (index as usize, entry as usize, offset as usize);
                out[written..index].fill(0);
                let window = &pixels[o..o + stride + 2];
                out[index] = bilinear(
                    window[0],
                    window[1],
                    window[stride],
                    window[stride + 1],
                    table.weights_x[entry],
                    table.weights_y[entry],
                );
                written = index + 1;
            }
        }
    }
    out[written..].fill(0);
}

/// Bytes per cache line on the CPUs the stack runs on.
const CACHE_LINE: usize = 64;

/// Read one byte of every cache line of `bytes`, in order. A camera frame usually arrives
/// uncached (written by DMA, or evicted by the rest of the pipeline since the last frame), and
/// the blocks read it in an order (three rows at a time, following curved rows) that the
/// hardware prefetcher does not follow well; one sequential pass first brings the whole frame
/// (300 KB at 640x480) into the cache at streaming speed. In the pipeline this takes the
/// rectification of a pair from about 0.5 to about 0.4 ms (`pipeline_timing rectify_compare`).
#[inline(always)]
fn warm_cache(bytes: &[u8]) {
    let touched = bytes
        .iter()
        .step_by(CACHE_LINE)
        .fold(0u8, |acc, &b| acc ^ b);
    std::hint::black_box(touched);
}

/// All lanes of one shift block from its three source rows.
#[inline(always)]
fn shift_block(
    rows: &[&[u8; BLOCK_SPAN]; 3],
    codes: &[u8; BLOCK_LEN],
    weights_x: &[u8; BLOCK_LEN],
    weights_y: &[u8; BLOCK_LEN],
    out: &mut [u8; BLOCK_LEN],
) {
    for i in 0..BLOCK_LEN {
        let code = codes[i];
        // Left and right pixels of the selected column on each of the three rows.
        let mut left = [0u8; 3];
        let mut right = [0u8; 3];
        for shift in 0..MAX_SHIFT {
            let mask = ((code >> shift) & 1).wrapping_neg();
            for r in 0..3 {
                left[r] |= rows[r][i + shift] & mask;
                right[r] |= rows[r][i + shift + 1] & mask;
            }
        }
        let lower = u8::from(code & LOWER_ROW != 0).wrapping_neg();
        let pick = |upper: u8, below: u8| (below & lower) | (upper & !lower);
        out[i] = bilinear(
            pick(left[0], left[1]),
            pick(right[0], right[1]),
            pick(left[1], left[2]),
            pick(right[1], right[2]),
            weights_x[i],
            weights_y[i],
        );
    }
}

/// Pixels split or merged at a time by [`split_channels`] and [`merge_channels`].
const CHANNEL_CHUNK: usize = 16;

/// Splits interleaved RGB bytes into three planes of `interleaved.len() / 3` bytes each. The
/// fixed-size inner loop lets the compiler use byte shuffles where the CPU has them.
#[allow(unsafe_code)]
#[multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+ssse3"
))]
pub(super) fn split_channels(interleaved: &[u8], r: &mut [u8], g: &mut [u8], b: &mut [u8]) {
    let mut pixels = interleaved.chunks_exact(3 * CHANNEL_CHUNK);
    let mut planes = r
        .chunks_exact_mut(CHANNEL_CHUNK)
        .zip(g.chunks_exact_mut(CHANNEL_CHUNK))
        .zip(b.chunks_exact_mut(CHANNEL_CHUNK));
    for (px, ((r, g), b)) in (&mut pixels).zip(&mut planes) {
        let px: &[u8; 3 * CHANNEL_CHUNK] = px.try_into().expect("a chunk of whole pixels");
        for k in 0..CHANNEL_CHUNK {
            r[k] = px[3 * k];
            g[k] = px[3 * k + 1];
            b[k] = px[3 * k + 2];
        }
    }
    let done = interleaved.len() / 3 / CHANNEL_CHUNK * CHANNEL_CHUNK;
    for (i, px) in pixels.remainder().chunks_exact(3).enumerate() {
        (r[done + i], g[done + i], b[done + i]) = (px[0], px[1], px[2]);
    }
}

/// Merges three planes into interleaved RGB bytes (the inverse of [`split_channels`]).
#[allow(unsafe_code)]
#[multiversion(targets(
    "x86_64+avx512f+avx512bw+avx512vl+avx2+fma",
    "x86_64+avx2+fma",
    "x86_64+ssse3"
))]
pub(super) fn merge_channels(r: &[u8], g: &[u8], b: &[u8], interleaved: &mut [u8]) {
    let mut pixels = interleaved.chunks_exact_mut(3 * CHANNEL_CHUNK);
    let planes = r
        .chunks_exact(CHANNEL_CHUNK)
        .zip(g.chunks_exact(CHANNEL_CHUNK))
        .zip(b.chunks_exact(CHANNEL_CHUNK));
    for (px, ((r, g), b)) in (&mut pixels).zip(planes) {
        let px: &mut [u8; 3 * CHANNEL_CHUNK] = px.try_into().expect("a chunk of whole pixels");
        for k in 0..CHANNEL_CHUNK {
            px[3 * k] = r[k];
            px[3 * k + 1] = g[k];
            px[3 * k + 2] = b[k];
        }
    }
    let done = r.len() / CHANNEL_CHUNK * CHANNEL_CHUNK;
    for (i, px) in pixels.into_remainder().chunks_exact_mut(3).enumerate() {
        px.copy_from_slice(&[r[done + i], g[done + i], b[done + i]]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whole chunks and a remainder: the planes are the interleaved channels, and merging them
    /// gives the interleaved bytes back.
    #[test]
    fn channels_split_and_merge_back_for_any_pixel_count() {
        for n in [
            0,
            1,
            CHANNEL_CHUNK - 1,
            CHANNEL_CHUNK,
            5 * CHANNEL_CHUNK + 7,
        ] {
            let interleaved: Vec<u8> = (0..3 * n).map(|i| (i * 7 % 251) as u8).collect();
            let (mut r, mut g, mut b) = (vec![0; n], vec![0; n], vec![0; n]);
            split_channels(&interleaved, &mut r, &mut g, &mut b);
            for i in 0..n {
                assert_eq!(
                    [r[i], g[i], b[i]],
                    interleaved[3 * i..3 * i + 3],
                    "{n} pixels, pixel {i}"
                );
            }
            let mut merged = vec![0; 3 * n];
            merge_channels(&r, &g, &b, &mut merged);
            assert_eq!(merged, interleaved, "{n} pixels");
        }
    }
}
