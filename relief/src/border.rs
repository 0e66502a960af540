//! The inner border of the frame ([`ReliefShape::Stepped`](super::ReliefShape::Stepped)):
//! a ring of vertices along the frame's inner edge, each at the height of the nearest segment
//! or point, so that the explorable area keeps the height of what is near its border instead of
//! ramping down to the back plane across the gap to the first segment. Only the frame (the
//! band `frame_width_m` wide) ramps to the back plane: the area's edge, a wall the finger can
//! follow.

/// Nearest-neighbour heights over a uniform bucket grid of the vertices.
pub(super) struct NearestHeight<'a> {
    points: &'a [[f64; 3]],
    origin: [f64; 2],
    cell_m: f64,
    cells: [usize; 2],
    /// Points of cell `k`: `order[start[k]..start[k + 1]]`.
    start: Vec<u32>,
    order: Vec<u32>,
}

impl<'a> NearestHeight<'a> {
    /// A grid over `points` (at least one) inside `rect = [x0, y0, x1, y1]`, about two points a
    /// cell.
    pub(super) fn new(points: &'a [[f64; 3]], rect: [f64; 4]) -> NearestHeight<'a> {
        let (w, h) = ((rect[2] - rect[0]).max(1e-9), (rect[3] - rect[1]).max(1e-9));
        let cell_m = (w * h * 2.0 / points.len().max(1) as f64).sqrt().max(1e-6);
        let cells = [
            ((w / cell_m).ceil() as usize).clamp(1, 1024),
            ((h / cell_m).ceil() as usize).clamp(1, 1024),
        ];
        let mut grid = NearestHeight {
            points,
            origin: [rect[0], rect[1]],
            cell_m,
            cells,
            start: vec![0; cells[0] * cells[1] + 1],
            order: vec![0; points.len()],
        };
        for p in points {
            let k = grid.cell_index(grid.cell_of(p[0], p[1]));
            grid.start[k + 1] += 1;
        }
        for k in 0..cells[0] * cells[1] {
            grid.start[k + 1] += grid.start[k];
        }
        let mut fill = grid.start.clone();
        for (i, p) in points.iter().enumerate() {
            let k = grid.cell_index(grid.cell_of(p[0], p[1]));
            grid.order[fill[k] as usize] = i as u32;
            fill[k] += 1;
        }
        grid
    }

    fn cell_of(&self, x: f64, y: f64) -> [usize; 2] {
        let c = |v: f64, o: f64, n: usize| {
            (((v - o) / self.cell_m).floor().max(0.0) as usize).min(n - 1)
        };
        [
            c(x, self.origin[0], self.cells[0]),
            c(y, self.origin[1], self.cells[1]),
        ]
    }

    fn cell_index(&self, [i, j]: [usize; 2]) -> usize {
        j * self.cells[0] + i
    }

    /// The height of the point nearest to `(x, y)` on the plane; `None` without points.
    pub(super) fn at(&self, x: f64, y: f64) -> Option<f64> {
        let [ci, cj] = self.cell_of(x, y);
        let mut best: Option<(f64, f64)> = None;
        let rings = self.cells[0].max(self.cells[1]);
        for r in 0..=rings {
            // Every point outside rings 0..r is farther than r cells.
            if let Some((d2, _)) = best {
                let reach = r.saturating_sub(1) as f64 * self.cell_m;
                if d2 <= reach * reach {
                    break;
                }
            }
            let (i0, i1) = (ci as isize - r as isize, ci as isize + r as isize);
            let (j0, j1) = (cj as isize - r as isize, cj as isize + r as isize);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let on_ring = i == i0 || i == i1 || j == j0 || j == j1;
                    if !on_ring
                        || i < 0
                        || j < 0
                        || i as usize >= self.cells[0]
                        || j as usize >= self.cells[1]
                    {
                        continue;
                    }
                    let k = self.cell_index([i as usize, j as usize]);
                    for &p in &self.order[self.start[k] as usize..self.start[k + 1] as usize] {
                        let q = self.points[p as usize];
                        let d2 = (q[0] - x).powi(2) + (q[1] - y).powi(2);
                        if best.is_none_or(|(b, _)| d2 < b) {
                            best = Some((d2, q[2]));
                        }
                    }
                }
            }
        }
        best.map(|(_, z)| z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_height_agrees_with_brute_force() {
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let points: Vec<[f64; 3]> = (0..300)
            .map(|_| [0.05 + 0.1 * rnd(), 0.02 + 0.05 * rnd(), rnd()])
            .collect();
        let grid = NearestHeight::new(&points, [0.0, 0.0, 0.2, 0.15]);
        for _ in 0..500 {
            let (x, y) = (0.2 * rnd(), 0.15 * rnd());
            let brute = points
                .iter()
                .min_by(|a, b| {
                    let da = (a[0] - x).powi(2) + (a[1] - y).powi(2);
                    let db = (b[0] - x).powi(2) + (b[1] - y).powi(2);
                    da.total_cmp(&db)
                })
                .map(|p| p[2]);
            assert_eq!(grid.at(x, y), brute, "at ({x}, {y})");
        }
        assert_eq!(
            NearestHeight::new(&[], [0.0, 0.0, 1.0, 1.0]).at(0.5, 0.5),
            None
        );
    }
}
