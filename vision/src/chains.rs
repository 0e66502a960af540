//! Linking of edge pixels into ordered chains (8-connected pixel paths).

use crate::canny::EDGE;

/// Ordered edge-pixel chains stored flat: chain `i` is `points[starts[i]..starts[i + 1]]`.
#[derive(Debug, Default, Clone)]
pub struct Chains {
    points: Vec<[u16; 2]>,
    starts: Vec<u32>,
    /// 1 for an edge pixel off the image border that no chain has taken yet. All zero between
    /// calls: every pixel set at the start of [`Chains::link`] is taken before it returns.
    available: Vec<u8>,
    backward: Vec<[u16; 2]>,
    edge_list: Vec<u32>,
    curve_ends: Vec<u32>,
}

/// Offsets of the 8 neighbours, 4-neighbours first so that thin curves are followed pixel by
/// pixel rather than cut across diagonally.
const NEIGHBOURS: [(i32, i32); 8] = [
    (1, 0),
    (0, 1),
    (-1, 0),
    (0, -1),
    (1, 1),
    (-1, 1),
    (-1, -1),
    (1, -1),
];

/// The neighbour offsets of [`NEIGHBOURS`] in a row-major image `width` pixels wide.
fn neighbour_offsets(width: usize) -> [isize; 8] {
    NEIGHBOURS.map(|(dx, dy)| dy as isize * width as isize + dx as isize)
}

impl Chains {
    /// An empty set; buffers grow on first use and are reused afterwards.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of chains.
    pub fn len(&self) -> usize {
        self.starts.len().saturating_sub(1)
    }

    /// Whether there is no chain.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The pixels `[x, y]` of chain `i`, in order along the curve.
    pub fn chain(&self, i: usize) -> &[[u16; 2]] {
        &self.points[self.starts[i] as usize..self.starts[i + 1] as usize]
    }

    /// Links the [`EDGE`] pixels of a `width x height` edge map into chains of at least
    /// `min_pixels` pixels. Chains start at curve ends (pixels with one edge neighbour); closed
    /// curves are then walked both ways from their first pixel in raster order. Every edge pixel
    /// belongs to at most one chain. Pixels on the image border are ignored.
    pub fn link(&mut self, edges: &[u8], width: usize, height: usize, min_pixels: usize) {
        self.points.clear();
        self.starts.clear();
        self.starts.push(0);
        let n = width * height;
        if self.available.len() != n {
            self.available.clear();
            self.available.resize(n, 0);
        }
        if width < 3 || height < 3 {
            return;
        }
        // The edge pixels off the border in raster order, marked available.
        if self.edge_list.len() < n + POSITIONS_PER_WORD {
            self.edge_list.resize(n + POSITIONS_PER_WORD, 0);
        }
        let mut count = 0;
        for y in 1..height - 1 {
            let row = y * width;
            count = push_positions_equal(
                &edges[row + 1..row + width - 1],
                EDGE,
                (row + 1) as u32,
                &mut self.edge_list,
                count,
            );
        }
        let edge_count = count;
        for &i in &self.edge_list[..edge_count] {
            self.available[i as usize] = 1;
        }
        // Pass 1: from curve ends; pass 2: what is left (closed curves, junction remainders).
        // Curve ends (one edge neighbour, a property of the edge map alone) are listed first,
        // in raster order, without a branch per pixel.
        let offsets = neighbour_offsets(width);
        self.curve_ends.clear();
        self.curve_ends.resize(edge_count, 0);
        let mut ends = 0;
        for &i in &self.edge_list[..edge_count] {
            let i = i as usize;
            // Edge pixels are at least one pixel inside the border.
            let degree: u32 = offsets
                .iter()
                .map(|&o| u32::from(edges[i.wrapping_add_signed(o)] == EDGE))
                .sum();
            self.curve_ends[ends] = i as u32;
            ends += usize::from(degree == 1);
        }
        for k in 0..ends {
            let i = self.curve_ends[k] as usize;
            if self.available[i] != 0 {
                self.walk_chain(&offsets, width, i, false, min_pixels);
            }
        }
        for k in 0..edge_count {
            let i = self.edge_list[k] as usize;
            if self.available[i] != 0 {
                self.walk_chain(&offsets, width, i, true, min_pixels);
            }
        }
    }

    fn walk_chain(
        &mut self,
        offsets: &[isize; 8],
        width: usize,
        i: usize,
        both_ways: bool,
        min_pixels: usize,
    ) {
        let start = self.points.len();
        self.available[i] = 0;
        let xy = ((i % width) as u16, (i / width) as u16);
        self.points.push([xy.0, xy.1]);
        follow(offsets, &mut self.available, i, xy, &mut self.points);
        if both_ways {
            self.backward.clear();
            follow(offsets, &mut self.available, i, xy, &mut self.backward);
            if !self.backward.is_empty() {
                let forward_len = self.points.len() - start;
                self.points.extend_from_slice(&self.backward);
                // [start .. forward | backward] -> reverse(backward) + forward.
                self.points[start..].rotate_left(forward_len);
                self.points[start..start + self.backward.len()].reverse();
            }
        }
        if self.points.len() - start >= min_pixels {
            self.starts.push(self.points.len() as u32);
        } else {
            self.points.truncate(start);
        }
    }
}

/// Follows available pixels from pixel `i` at `(x, y)`, taking each one (the first available
/// neighbour in [`NEIGHBOURS`] order) and appending its `[x, y]` to `out`. Available pixels
/// are off the border, so the neighbours of every pixel reached exist.
fn follow(
    offsets: &[isize; 8],
    available: &mut [u8],
    mut i: usize,
    (mut x, mut y): (u16, u16),
    out: &mut Vec<[u16; 2]>,
) {
    loop {
        let Some(k) = (0..8).find(|&k| available[i.wrapping_add_signed(offsets[k])] != 0) else {
            return;
        };
        i = i.wrapping_add_signed(offsets[k]);
        available[i] = 0;
        let (dx, dy) = NEIGHBOURS[k];
        x = x.wrapping_add_signed(dx as i16);
        y = y.wrapping_add_signed(dy as i16);
        out.push([x, y]);
    }
}

/// Bytes compared at once by [`push_positions_equal`].
const POSITIONS_PER_WORD: usize = 16;

/// Writes `first + i` for every `i` with `bytes[i] == value`, in increasing order, into
/// `out[count..]`; returns the new count. `out` must have [`POSITIONS_PER_WORD`] slots to
/// spare beyond the positions written. Sixteen bytes are compared at once into a bit mask
/// (a vector compare and mask extraction on x86-64), whose set bits are then visited.
#[inline]
fn push_positions_equal(
    bytes: &[u8],
    value: u8,
    first: u32,
    out: &mut [u32],
    mut count: usize,
) -> usize {
    let mut chunks = bytes.chunks_exact(POSITIONS_PER_WORD);
    let mut base = first;
    for chunk in &mut chunks {
        let mut equal = chunk
            .iter()
            .enumerate()
            .fold(0u32, |m, (k, &b)| m | (u32::from(b == value) << k));
        // Four positions are written whatever their number (one loop per set bit would end
        // at an unpredictable point in most words), then the rest, if any.
        let found = equal.count_ones() as usize;
        let slots = &mut out[count..count + POSITIONS_PER_WORD];
        for slot in &mut slots[..4] {
            *slot = base + equal.trailing_zeros();
            equal &= equal.wrapping_sub(1);
        }
        let mut k = 4;
        while equal != 0 {
            slots[k] = base + equal.trailing_zeros();
            equal &= equal - 1;
            k += 1;
        }
        count += found;
        base += POSITIONS_PER_WORD as u32;
    }
    for (k, &b) in chunks.remainder().iter().enumerate() {
        out[count] = base + k as u32;
        count += usize::from(b == value);
    }
    count
}

#[cfg(test)]
mod reference;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn assert_same_as_reference(c: &Chains, edges: &[u8], w: usize, h: usize, min: usize) {
        let mut r = reference::ReferenceChains::new();
        r.link(edges, w, h, min);
        assert_eq!(c.len(), r.len());
        for i in 0..c.len() {
            assert_eq!(c.chain(i), r.chain(i), "chain {i}");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 128,
            rng_seed: proptest::test_runner::RngSeed::Fixed(5),
            ..ProptestConfig::default()
        })]

        /// Random edge maps (isolated pixels, blobs, junctions, edges on the border, weak
        /// markers) give exactly the chains of the reference linker, also when one set is
        /// reused across sizes.
        #[test]
        fn optimised_linker_equals_reference(
            w in 1usize..60,
            h in 1usize..50,
            density in 0u32..100,
            seed in any::<u64>(),
            min in 1usize..6,
        ) {
            let mut state = seed | 1;
            let edges: Vec<u8> = (0..w * h)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    let r = (state % 100) as u32;
                    if r < density / 2 { EDGE } else if r < density { 1 } else { 0 }
                })
                .collect();
            let mut c = Chains::new();
            c.link(&edges, w, h, min);
            assert_same_as_reference(&c, &edges, w, h, min);
            let (w2, h2) = (h, w);
            c.link(&edges, w2, h2, min);
            assert_same_as_reference(&c, &edges, w2, h2, min);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 256,
            rng_seed: proptest::test_runner::RngSeed::Fixed(9),
            ..ProptestConfig::default()
        })]

        /// The sixteen-bytes-at-a-time search writes exactly the positions of a plain
        /// comparison after those already there, for any length and density of matches.
        #[test]
        fn pushed_positions_are_every_match(
            bytes in prop::collection::vec(prop_oneof![Just(0u8), Just(1), Just(2), any::<u8>()], 0..70),
            value in prop_oneof![Just(0u8), Just(2), Just(0x80), any::<u8>()],
            first in 0u32..1000,
        ) {
            let mut out = vec![0u32; 3 + bytes.len() + POSITIONS_PER_WORD];
            out[..3].copy_from_slice(&[7, 8, 9]);
            let count = push_positions_equal(&bytes, value, first, &mut out, 3);
            let expected: Vec<u32> = (0..bytes.len() as u32)
                .filter(|&i| bytes[i as usize] == value)
                .map(|i| first + i)
                .collect();
            prop_assert_eq!(&out[..3], &[7, 8, 9]);
            prop_assert_eq!(&out[3..count], &expected[..]);
        }
    }

    fn draw(width: usize, height: usize, pixels: &[(usize, usize)]) -> Vec<u8> {
        let mut e = vec![0u8; width * height];
        for &(x, y) in pixels {
            e[y * width + x] = EDGE;
        }
        e
    }

    #[test]
    fn an_open_curve_is_one_ordered_chain() {
        let pixels: Vec<(usize, usize)> = (2..15).map(|x| (x, 5 + x / 4)).collect();
        let e = draw(20, 12, &pixels);
        let mut c = Chains::new();
        c.link(&e, 20, 12, 3);
        assert_eq!(c.len(), 1);
        let ch = c.chain(0);
        assert_eq!(ch.len(), pixels.len());
        for w in ch.windows(2) {
            let dx = (w[0][0] as i32 - w[1][0] as i32).abs();
            let dy = (w[0][1] as i32 - w[1][1] as i32).abs();
            assert!(dx <= 1 && dy <= 1 && dx + dy > 0);
        }
    }

    #[test]
    fn a_closed_curve_is_walked_both_ways_into_one_chain() {
        let mut pixels = Vec::new();
        for x in 3..10 {
            pixels.push((x, 3));
            pixels.push((x, 9));
        }
        for y in 4..9 {
            pixels.push((3, y));
            pixels.push((9, y));
        }
        let e = draw(14, 14, &pixels);
        let mut c = Chains::new();
        c.link(&e, 14, 14, 3);
        assert_eq!(c.len(), 1);
        assert_eq!(c.chain(0).len(), pixels.len());
        for w in c.chain(0).windows(2) {
            let dx = (w[0][0] as i32 - w[1][0] as i32).abs();
            let dy = (w[0][1] as i32 - w[1][1] as i32).abs();
            assert!(dx <= 1 && dy <= 1);
        }
    }

    #[test]
    fn short_chains_are_dropped() {
        let e = draw(10, 10, &[(2, 2), (3, 2), (7, 7)]);
        let mut c = Chains::new();
        c.link(&e, 10, 10, 3);
        assert!(c.is_empty());
    }
}
