//! The straightforward chain linker the optimised one in the parent module must reproduce
//! exactly (bounds-checked neighbour search, a visited flag per pixel). Tests only.
#![allow(dead_code)]

use crate::canny::EDGE;

/// Ordered edge-pixel chains stored flat: chain `i` is `points[starts[i]..starts[i + 1]]`.
#[derive(Debug, Default, Clone)]
pub struct ReferenceChains {
    points: Vec<[u16; 2]>,
    starts: Vec<u32>,
    visited: Vec<bool>,
    backward: Vec<[u16; 2]>,
    edge_list: Vec<u32>,
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

impl ReferenceChains {
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
        self.visited.clear();
        self.visited.resize(n, false);
        if width < 3 || height < 3 {
            return;
        }
        // The edge pixels in raster order (runs of 16 pixels without an edge are skipped with
        // a vectorised OR).
        self.edge_list.clear();
        for y in 1..height - 1 {
            let row = &edges[y * width..(y + 1) * width];
            let mut x = 1;
            while x < width - 1 {
                let end = (x + 16).min(width - 1);
                if row[x..end].iter().fold(0u8, |acc, &v| acc | v) & EDGE != 0 {
                    for (xx, &v) in row.iter().enumerate().take(end).skip(x) {
                        if v == EDGE {
                            self.edge_list.push((y * width + xx) as u32);
                        }
                    }
                }
                x = end;
            }
        }
        // Pass 1: from curve ends; pass 2: what is left (closed curves, junction remainders).
        let offsets = [
            1isize,
            width as isize,
            -1,
            -(width as isize),
            width as isize + 1,
            width as isize - 1,
            -(width as isize) - 1,
            -(width as isize) + 1,
        ];
        for pass in 0..2 {
            for k in 0..self.edge_list.len() {
                let i = self.edge_list[k] as usize;
                if self.visited[i] {
                    continue;
                }
                let (x, y) = (i % width, i / width);
                if pass == 0 {
                    // Edge pixels are at least one pixel inside the border.
                    let degree = offsets
                        .iter()
                        .filter(|&&o| edges[i.wrapping_add_signed(o)] == EDGE)
                        .count();
                    if degree == 1 {
                        self.walk_chain(edges, width, height, x, y, false, min_pixels);
                    }
                } else {
                    self.walk_chain(edges, width, height, x, y, true, min_pixels);
                }
            }
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn walk_chain(
        &mut self,
        edges: &[u8],
        width: usize,
        height: usize,
        x: usize,
        y: usize,
        both_ways: bool,
        min_pixels: usize,
    ) {
        let start = self.points.len();
        self.visited[y * width + x] = true;
        self.points.push([x as u16, y as u16]);
        follow(
            edges,
            width,
            height,
            &mut self.visited,
            x,
            y,
            &mut self.points,
        );
        if both_ways {
            self.backward.clear();
            follow(
                edges,
                width,
                height,
                &mut self.visited,
                x,
                y,
                &mut self.backward,
            );
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

/// Follows unvisited edge pixels from `(x, y)`, appending them to `out`.
fn follow(
    edges: &[u8],
    width: usize,
    height: usize,
    visited: &mut [bool],
    mut x: usize,
    mut y: usize,
    out: &mut Vec<[u16; 2]>,
) {
    loop {
        let mut next = None;
        for &(dx, dy) in &NEIGHBOURS {
            let nx = x as i32 + dx;
            let ny = y as i32 + dy;
            if nx <= 0 || ny <= 0 || nx as usize + 1 >= width || ny as usize + 1 >= height {
                continue;
            }
            let i = ny as usize * width + nx as usize;
            if edges[i] == EDGE && !visited[i] {
                next = Some((nx as usize, ny as usize, i));
                break;
            }
        }
        match next {
            Some((nx, ny, i)) => {
                visited[i] = true;
                out.push([nx as u16, ny as u16]);
                x = nx;
                y = ny;
            }
            None => return,
        }
    }
}
