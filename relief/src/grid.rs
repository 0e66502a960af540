//! Uniform grid over the explorable area: each cell lists the triangles that overlap it, all in
//! one flat array built with the surface, so a point query looks at one short list and a motion
//! walks the cells it crosses.

/// The acceleration grid of a relief.
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleGrid {
    origin: [f64; 2],
    cell: [f64; 2],
    n: [usize; 2],
    /// `starts[c]..starts[c + 1]` indexes `items` for cell `c` (row-major, `x` fastest).
    starts: Vec<u32>,
    items: Vec<u32>,
    max_per_cell: usize,
}

/// Whether triangle `t` (x-y) overlaps the rectangle `[x0, y0, x1, y1]` (separating axes).
fn overlaps(t: &[[f64; 2]; 3], r: [f64; 4]) -> bool {
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for p in t {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    if lo[0] > r[2] || hi[0] < r[0] || lo[1] > r[3] || hi[1] < r[1] {
        return false;
    }
    let corners = [[r[0], r[1]], [r[2], r[1]], [r[2], r[3]], [r[0], r[3]]];
    for i in 0..3 {
        let a = t[i];
        let b = t[(i + 1) % 3];
        let c = t[(i + 2) % 3];
        let n = [a[1] - b[1], b[0] - a[0]];
        let side = |p: [f64; 2]| n[0] * (p[0] - a[0]) + n[1] * (p[1] - a[1]);
        let inner = side(c);
        // All corners strictly on the other side of edge a-b than the triangle: separated.
        let scale = 1e-12 * (n[0].abs() + n[1].abs()) * (r[2] - r[0] + r[3] - r[1]);
        if inner >= 0.0 {
            if corners.iter().all(|&p| side(p) < -scale) {
                return false;
            }
        } else if corners.iter().all(|&p| side(p) > scale) {
            return false;
        }
    }
    true
}

impl TriangleGrid {
    /// A grid over `area = [x0, y0, x1, y1]` with about `cells_per_triangle` cells per triangle.
    pub fn build(area: [f64; 4], triangles: &[[[f64; 2]; 3]], cells_per_triangle: f64) -> Self {
        let (w, h) = ((area[2] - area[0]).max(1e-9), (area[3] - area[1]).max(1e-9));
        let target = (triangles.len() as f64 * cells_per_triangle).clamp(1.0, 1_048_576.0);
        let nx = ((target * w / h).sqrt().round() as usize).clamp(1, 1024);
        let ny = ((target / nx as f64).ceil() as usize).clamp(1, 1024);
        let cell = [w / nx as f64, h / ny as f64];
        let origin = [area[0], area[1]];
        let ncells = nx * ny;
        // A margin makes the lists conservative for points on cell borders.
        let margin = 1e-9 * (w + h);
        let cell_range = |t: &[[f64; 2]; 3]| {
            let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
            for p in t {
                for k in 0..2 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            let idx = |v: f64, k: usize, n: usize| {
                (((v - origin[k]) / cell[k]).floor().max(0.0) as usize).min(n - 1)
            };
            (
                [idx(lo[0] - margin, 0, nx), idx(lo[1] - margin, 1, ny)],
                [idx(hi[0] + margin, 0, nx), idx(hi[1] + margin, 1, ny)],
            )
        };
        let rect = |ix: usize, iy: usize| {
            [
                origin[0] + ix as f64 * cell[0] - margin,
                origin[1] + iy as f64 * cell[1] - margin,
                origin[0] + (ix + 1) as f64 * cell[0] + margin,
                origin[1] + (iy + 1) as f64 * cell[1] + margin,
            ]
        };
        // One pass collects (cell, triangle) pairs; a counting sort makes the flat lists.
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(triangles.len() * 4);
        for (k, t) in triangles.iter().enumerate() {
            let (lo, hi) = cell_range(t);
            let single = lo == hi;
            for iy in lo[1]..=hi[1] {
                for ix in lo[0]..=hi[0] {
                    // A triangle within one cell overlaps it; larger ones are tested exactly.
                    if single || overlaps(t, rect(ix, iy)) {
                        pairs.push(((iy * nx + ix) as u32, k as u32));
                    }
                }
            }
        }
        let mut starts = vec![0u32; ncells + 1];
        for &(c, _) in &pairs {
            starts[c as usize + 1] += 1;
        }
        let max_per_cell = starts.iter().copied().max().unwrap_or(0) as usize;
        for c in 0..ncells {
            starts[c + 1] += starts[c];
        }
        let mut fill = starts.clone();
        let mut items = vec![0u32; pairs.len()];
        for &(c, k) in &pairs {
            items[fill[c as usize] as usize] = k;
            fill[c as usize] += 1;
        }
        TriangleGrid {
            origin,
            cell,
            n: [nx, ny],
            starts,
            items,
            max_per_cell,
        }
    }

    /// Cells along `x` and `y`.
    pub fn dimensions(&self) -> [usize; 2] {
        self.n
    }

    /// Most triangles listed in one cell (bounds the work of a point query).
    pub fn max_per_cell(&self) -> usize {
        self.max_per_cell
    }

    /// Entries in the flat list (triangle-cell overlaps).
    pub fn entries(&self) -> usize {
        self.items.len()
    }

    /// The cell coordinates of a point (clamped into the grid).
    pub fn cell_xy(&self, x: f64, y: f64) -> [usize; 2] {
        let ix = ((x - self.origin[0]) / self.cell[0]).floor();
        let iy = ((y - self.origin[1]) / self.cell[1]).floor();
        [
            (ix.max(0.0) as usize).min(self.n[0] - 1),
            (iy.max(0.0) as usize).min(self.n[1] - 1),
        ]
    }

    /// The triangles of cell `(ix, iy)`.
    pub fn cell(&self, ix: usize, iy: usize) -> &[u32] {
        let c = iy * self.n[0] + ix;
        &self.items[self.starts[c] as usize..self.starts[c + 1] as usize]
    }

    /// Walk the cells crossed by `p(t) = a + t d` for `t` in `[t0, t1]`, in order, calling
    /// `visit(cell triangles, t_exit)` until it returns `true`. Bounded by `nx + ny + 2` cells.
    pub fn walk(
        &self,
        a: [f64; 2],
        d: [f64; 2],
        t0: f64,
        t1: f64,
        mut visit: impl FnMut(&[u32], f64) -> bool,
    ) {
        let start = [a[0] + d[0] * t0, a[1] + d[1] * t0];
        let [mut ix, mut iy] = self.cell_xy(start[0], start[1]);
        let step = |dk: f64| -> (i64, f64) {
            if dk > 0.0 {
                (1, 1.0)
            } else if dk < 0.0 {
                (-1, 0.0)
            } else {
                (0, 0.0)
            }
        };
        let (sx, bx) = step(d[0]);
        let (sy, by) = step(d[1]);
        let next_t = |i: usize, k: usize, s: i64, b: f64| -> f64 {
            if s == 0 {
                f64::INFINITY
            } else {
                let boundary = self.origin[k] + (i as f64 + b) * self.cell[k];
                let ak = if k == 0 { a[0] } else { a[1] };
                (boundary - ak) / d[k]
            }
        };
        let mut tx = next_t(ix, 0, sx, bx);
        let mut ty = next_t(iy, 1, sy, by);
        let limit = self.n[0] + self.n[1] + 2;
        for _ in 0..limit {
            let t_exit = tx.min(ty).min(t1);
            if visit(self.cell(ix, iy), t_exit) || t_exit >= t1 {
                return;
            }
            if tx <= ty {
                let next = ix as i64 + sx;
                if next < 0 || next >= self.n[0] as i64 {
                    return;
                }
                ix = next as usize;
                tx = next_t(ix, 0, sx, bx);
            } else {
                let next = iy as i64 + sy;
                if next < 0 || next >= self.n[1] as i64 {
                    return;
                }
                iy = next as usize;
                ty = next_t(iy, 1, sy, by);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_triangle_is_listed_where_it_lies() {
        let tris = [
            [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
            [[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        ];
        let g = TriangleGrid::build([0.0, 0.0, 1.0, 1.0], &tris, 8.0);
        let [nx, ny] = g.dimensions();
        assert_eq!(nx * ny, 16);
        // Corner cells hold only their triangle; diagonal cells hold both.
        assert_eq!(g.cell(0, 0), &[0]);
        assert_eq!(g.cell(nx - 1, ny - 1), &[1]);
        assert_eq!(g.cell(1, 1).len(), 2);
        let mut visited = 0;
        g.walk([0.05, 0.05], [0.9, 0.0], 0.0, 1.0, |_, _| {
            visited += 1;
            false
        });
        assert_eq!(visited, nx);
    }
}
