//! Chessboard inner-corner detection on grey images.
//!
//! 1. X-junction candidates from the ChESS response ([`super::corner_response`]).
//! 2. Grid growth from a seed and its two nearest non-collinear neighbours: each missing grid
//!    position is predicted by parallelogram completion (or linear extrapolation) from its labelled
//!    neighbours and takes the nearest unused candidate within a fraction of the local spacing.
//! 3. A `cols x rows` window of the grown grid is accepted when its squares alternate dark/bright
//!    (the colour test rejects diagonal lattices and clutter).
//! 4. Canonical ordering, identical for every camera looking at the board's front: row-major,
//!    `cols` corners per row, the column direction crossed with the row direction points into the
//!    image (clockwise in image coordinates), and the square between the first four corners is dark
//!    (which fixes the 180° ambiguity when `cols + rows` is odd; otherwise the first corner is the
//!    one nearest the image's top-left).
//! 5. Sub-pixel refinement ([`super::subpixel`]).

use std::collections::{BTreeMap, BTreeSet};

use super::corner_response::{chess_response, local_maxima, Candidate, FloatImage};
use super::subpixel::{refine_corner, SubPixSettings};

/// Inner-corner counts of a chessboard.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardSize {
    /// Inner corners per row (along the board's long side by convention, e.g. 9 of a 9x6 board).
    pub cols: usize,
    /// Inner corners per column.
    pub rows: usize,
}

/// Detected corners, row-major (`rows` rows of `cols` corners), pixels.
pub type Corners = Vec<[f64; 2]>;

/// Ring radii (pixels) tried for the corner response, in order.
const RESPONSE_RADII: [usize; 3] = [5, 3, 8];
/// Maximum number of candidates kept per image.
const MAX_CANDIDATES: usize = 1500;
/// Maximum number of seeds tried per radius.
const MAX_SEEDS: usize = 60;
/// A candidate joins the grid when within this fraction of the local spacing of the prediction.
const ACCEPT_FRACTION: f64 = 0.3;

type Grid = BTreeMap<(i32, i32), usize>;

/// [`find_chessboard`] on a camera frame.
pub fn find_chessboard_in_frame(frame: &videt_hal::GrayFrame, size: BoardSize) -> Option<Corners> {
    find_chessboard(
        frame.width as usize,
        frame.height as usize,
        &frame.data,
        size,
    )
}

/// Find the `size` inner corners of a chessboard in a grey image (`width * height` pixels,
/// row-major). `None` when no complete board is found (never panics on any input).
pub fn find_chessboard(
    width: usize,
    height: usize,
    pixels: &[u8],
    size: BoardSize,
) -> Option<Corners> {
    if size.cols < 2 || size.rows < 2 || width < 16 || height < 16 || pixels.len() != width * height
    {
        return None;
    }
    // Corners are located and refined on the lightly smoothed image: the [1 2 1] kernel makes
    // the central-difference gradients of the refinement less sensitive to edge orientation.
    let smooth = FloatImage::from_gray(width, height, pixels).smoothed();
    for radius in RESPONSE_RADII {
        let response = chess_response(&smooth, radius);
        let max = response.iter().copied().fold(0.0f32, f32::max);
        if max <= 0.0 {
            continue;
        }
        let mut candidates = local_maxima(&response, width, height, 3, 0.02 * max);
        candidates.truncate(MAX_CANDIDATES);
        if let Some(corners) = find_grid(&smooth, &candidates, size) {
            return Some(refine_all(&smooth, corners, size));
        }
    }
    None
}

/// Sub-pixel refinement of every corner, window sized from the smallest grid spacing.
fn refine_all(img: &FloatImage, corners: Corners, size: BoardSize) -> Corners {
    let spacing = min_spacing(&corners, size);
    let half_window = ((spacing * 0.5).floor() as usize).clamp(2, 11);
    let settings = SubPixSettings {
        half_window,
        ..SubPixSettings::default()
    };
    corners
        .iter()
        .map(|&c| refine_corner(img, c, &settings))
        .collect()
}

/// Smallest distance between grid neighbours.
pub fn min_spacing(corners: &[[f64; 2]], size: BoardSize) -> f64 {
    let mut best = f64::INFINITY;
    for r in 0..size.rows {
        for c in 0..size.cols {
            let p = corners[r * size.cols + c];
            if c + 1 < size.cols {
                best = best.min(dist(p, corners[r * size.cols + c + 1]));
            }
            if r + 1 < size.rows {
                best = best.min(dist(p, corners[(r + 1) * size.cols + c]));
            }
        }
    }
    best
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

fn pos(c: &Candidate) -> [f64; 2] {
    [c.x, c.y]
}

/// Try seeds strongest first; the first grid that yields a valid board wins.
fn find_grid(img: &FloatImage, candidates: &[Candidate], size: BoardSize) -> Option<Corners> {
    let mut tried = BTreeSet::new();
    for seed in 0..candidates.len().min(MAX_SEEDS) {
        if tried.contains(&seed) {
            continue;
        }
        let Some((n1, n2)) = seed_neighbours(candidates, seed) else {
            continue;
        };
        let grid = grow(candidates, seed, n1, n2, size);
        if let Some(corners) = board_from_grid(img, candidates, &grid, size) {
            return Some(corners);
        }
        // Candidates absorbed into a failed grid make poor seeds too.
        if grid.len() > 8 {
            tried.extend(grid.values().copied());
        }
    }
    None
}

/// The nearest neighbour of the seed and the nearest one roughly perpendicular to it.
fn seed_neighbours(candidates: &[Candidate], seed: usize) -> Option<(usize, usize)> {
    let s = pos(&candidates[seed]);
    let mut near: Vec<(f64, usize)> = candidates
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != seed)
        .map(|(i, c)| (dist(s, pos(c)), i))
        .filter(|(d, _)| *d > 3.0)
        .collect();
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    near.truncate(8);
    let &(d1, n1) = near.first()?;
    let v1 = sub(pos(&candidates[n1]), s);
    for &(d2, n2) in &near[1..] {
        if d2 > 2.0 * d1 {
            break;
        }
        let v2 = sub(pos(&candidates[n2]), s);
        let cos = (v1[0] * v2[0] + v1[1] * v2[1]) / (d1 * d2);
        if cos.abs() < 0.6 {
            return Some((n1, n2));
        }
    }
    None
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

/// Grow a labelled grid from the seed triangle.
fn grow(candidates: &[Candidate], seed: usize, n1: usize, n2: usize, size: BoardSize) -> Grid {
    let mut grid = Grid::new();
    let mut used = BTreeSet::new();
    for (key, idx) in [((0, 0), seed), ((1, 0), n1), ((0, 1), n2)] {
        grid.insert(key, idx);
        used.insert(idx);
    }
    let limit = 4 * size.cols * size.rows;
    loop {
        let mut added = false;
        let frontier: BTreeSet<(i32, i32)> = grid
            .keys()
            .flat_map(|&(i, j)| [(i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)])
            .filter(|k| !grid.contains_key(k))
            .collect();
        for key in frontier {
            let Some((predicted, spacing)) = predict(candidates, &grid, key) else {
                continue;
            };
            let radius = ACCEPT_FRACTION * spacing;
            let mut best: Option<(f64, usize)> = None;
            for (i, c) in candidates.iter().enumerate() {
                if used.contains(&i) {
                    continue;
                }
                let d = dist(predicted, pos(c));
                if d < radius && best.is_none_or(|(bd, _)| d < bd) {
                    best = Some((d, i));
                }
            }
            if let Some((_, i)) = best {
                grid.insert(key, i);
                used.insert(i);
                added = true;
            }
        }
        if !added || grid.len() > limit {
            return grid;
        }
    }
}

/// Predicted image position of grid position `key` and the local spacing, from labelled
/// neighbours: parallelogram completion when possible, else linear extrapolation.
fn predict(candidates: &[Candidate], grid: &Grid, key: (i32, i32)) -> Option<([f64; 2], f64)> {
    let (i, j) = key;
    let at = |k: (i32, i32)| grid.get(&k).map(|&idx| pos(&candidates[idx]));
    let (mut sum, mut n, mut spacing) = ([0.0, 0.0], 0.0, f64::INFINITY);
    for (di, dj) in [(1, 1), (1, -1), (-1, 1), (-1, -1)] {
        if let (Some(a), Some(b), Some(c)) =
            (at((i - di, j)), at((i, j - dj)), at((i - di, j - dj)))
        {
            sum[0] += a[0] + b[0] - c[0];
            sum[1] += a[1] + b[1] - c[1];
            n += 1.0;
            spacing = spacing.min(dist(a, c)).min(dist(b, c));
        }
    }
    if n == 0.0 {
        for (di, dj) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
            if let (Some(a), Some(b)) = (at((i - di, j - dj)), at((i - 2 * di, j - 2 * dj))) {
                sum[0] += 2.0 * a[0] - b[0];
                sum[1] += 2.0 * a[1] - b[1];
                n += 1.0;
                spacing = spacing.min(dist(a, b));
            }
        }
    }
    (n > 0.0).then(|| ([sum[0] / n, sum[1] / n], spacing))
}

/// Find a complete `cols x rows` window of the grid whose squares alternate in brightness and
/// return its corners in canonical order.
fn board_from_grid(
    img: &FloatImage,
    candidates: &[Candidate],
    grid: &Grid,
    size: BoardSize,
) -> Option<Corners> {
    if grid.len() < size.cols * size.rows {
        return None;
    }
    let imin = grid.keys().map(|k| k.0).min()?;
    let imax = grid.keys().map(|k| k.0).max()?;
    let jmin = grid.keys().map(|k| k.1).min()?;
    let jmax = grid.keys().map(|k| k.1).max()?;
    let mut best: Option<(f64, Vec<[f64; 2]>)> = None;
    let shapes = if size.cols == size.rows {
        vec![false]
    } else {
        vec![false, true]
    };
    for transpose in shapes {
        // (w, h): extent along grid i and j.
        let (w, h) = if transpose {
            (size.rows, size.cols)
        } else {
            (size.cols, size.rows)
        };
        for i0 in imin..=imax - w as i32 + 1 {
            for j0 in jmin..=jmax - h as i32 + 1 {
                let mut pts = Vec::with_capacity(size.cols * size.rows);
                // Row-major in board terms: r along j (or i when transposed), c along the other.
                'fill: for r in 0..size.rows {
                    for c in 0..size.cols {
                        let key = if transpose {
                            (i0 + r as i32, j0 + c as i32)
                        } else {
                            (i0 + c as i32, j0 + r as i32)
                        };
                        match grid.get(&key) {
                            Some(&idx) => pts.push(pos(&candidates[idx])),
                            None => break 'fill,
                        }
                    }
                }
                if pts.len() != size.cols * size.rows {
                    continue;
                }
                if let Some(margin) = checker_margin(img, &pts, size) {
                    if best.as_ref().is_none_or(|(m, _)| margin > *m) {
                        best = Some((margin, pts));
                    }
                }
            }
        }
    }
    let (_, pts) = best?;
    Some(canonical_order(img, pts, size))
}

/// Mean brightness near the centre of the square with corners (c, r), (c+1, r), (c, r+1),
/// (c+1, r+1).
fn square_brightness(
    img: &FloatImage,
    pts: &[[f64; 2]],
    size: BoardSize,
    c: usize,
    r: usize,
) -> f64 {
    let p00 = pts[r * size.cols + c];
    let p10 = pts[r * size.cols + c + 1];
    let p01 = pts[(r + 1) * size.cols + c];
    let p11 = pts[(r + 1) * size.cols + c + 1];
    let centre = [
        (p00[0] + p10[0] + p01[0] + p11[0]) / 4.0,
        (p00[1] + p10[1] + p01[1] + p11[1]) / 4.0,
    ];
    let mut sum = 0.0;
    let mut n = 0.0;
    for corner in [p00, p10, p01, p11] {
        for t in [0.0, 0.25] {
            sum += img.sample(
                centre[0] + t * (corner[0] - centre[0]),
                centre[1] + t * (corner[1] - centre[1]),
            );
            n += 1.0;
        }
    }
    sum / n
}

/// The grey-level gap between the darkest bright square and the brightest dark square, when the
/// squares alternate (`None` otherwise).
fn checker_margin(img: &FloatImage, pts: &[[f64; 2]], size: BoardSize) -> Option<f64> {
    let (mut even_min, mut even_max, mut odd_min, mut odd_max) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for r in 0..size.rows - 1 {
        for c in 0..size.cols - 1 {
            let v = square_brightness(img, pts, size, c, r);
            if (r + c) % 2 == 0 {
                even_min = even_min.min(v);
                even_max = even_max.max(v);
            } else {
                odd_min = odd_min.min(v);
                odd_max = odd_max.max(v);
            }
        }
    }
    if size.rows == 2 && size.cols == 2 {
        return None;
    }
    let margin = (odd_min - even_max).max(even_min - odd_max);
    (margin > 5.0).then_some(margin)
}

/// Reorder a row-major board so that it satisfies the canonical orientation (module docs).
fn canonical_order(img: &FloatImage, pts: Vec<[f64; 2]>, size: BoardSize) -> Corners {
    let (cols, rows) = (size.cols, size.rows);
    let mut options = Vec::new();
    for flip_c in [false, true] {
        for flip_r in [false, true] {
            let reordered: Vec<[f64; 2]> = (0..rows)
                .flat_map(|r| (0..cols).map(move |c| (r, c)))
                .map(|(r, c)| {
                    let sc = if flip_c { cols - 1 - c } else { c };
                    let sr = if flip_r { rows - 1 - r } else { r };
                    pts[sr * cols + sc]
                })
                .collect();
            let dc = sub(reordered[cols - 1], reordered[0]);
            let dr = sub(reordered[(rows - 1) * cols], reordered[0]);
            if dc[0] * dr[1] - dc[1] * dr[0] > 0.0 {
                options.push(reordered);
            }
        }
    }
    // Two options remain, related by a 180° turn.
    if (cols + rows) % 2 == 1 {
        let darkness = |p: &Vec<[f64; 2]>| square_brightness(img, p, size, 0, 0);
        options.sort_by(|a, b| darkness(a).total_cmp(&darkness(b)));
    } else {
        options.sort_by(|a, b| (a[0][0] + a[0][1]).total_cmp(&(b[0][0] + b[0][1])));
    }
    options.into_iter().next().unwrap_or(pts)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::calib::geometry::apply_homography;
    use nalgebra::Matrix3;

    /// Render a chessboard of `size` inner corners, one unit per square, through the plane-to-image
    /// homography `h` (3x3 supersampling). Board squares: the square between inner corners
    /// (0,0)..(1,1) is dark. A one-square white margin, grey background.
    pub(crate) fn render_board(
        size: BoardSize,
        h: &Matrix3<f64>,
        width: usize,
        height: usize,
    ) -> Vec<u8> {
        let h_inv = h.try_inverse().expect("invertible");
        let mut px = vec![0u8; width * height];
        for y in 0..height {
            for x in 0..width {
                let mut acc = 0.0f64;
                for sy in 0..3 {
                    for sx in 0..3 {
                        let u = x as f64 + (sx as f64 + 0.5) / 3.0 - 0.5;
                        let v = y as f64 + (sy as f64 + 0.5) / 3.0 - 0.5;
                        let [bx, by] = apply_homography(&h_inv, [u, v]);
                        // Squares span [-1, cols] x [-1, rows]; margin of one more square.
                        let (c, r) = ((bx + 1.0).floor(), (by + 1.0).floor());
                        let inside_squares =
                            c >= 0.0 && r >= 0.0 && c <= size.cols as f64 && r <= size.rows as f64;
                        let inside_margin = bx > -2.0
                            && by > -2.0
                            && bx < size.cols as f64 + 1.0
                            && by < size.rows as f64 + 1.0;
                        acc += if inside_squares {
                            if (c + r) as i64 % 2 == 0 {
                                35.0
                            } else {
                                215.0
                            }
                        } else if inside_margin {
                            215.0
                        } else {
                            120.0
                        };
                    }
                }
                px[y * width + x] = (acc / 9.0).round() as u8;
            }
        }
        px
    }

    fn perspective() -> Matrix3<f64> {
        // Squares of about 24 px, tilted and in perspective.
        Matrix3::new(24.0, 5.0, 110.0, -4.0, 25.0, 100.0, 0.0005, 0.0007, 1.0)
    }

    #[test]
    fn synthetic_board_corners_are_found_in_order_within_a_tenth_of_a_pixel() {
        let size = BoardSize { cols: 9, rows: 6 };
        let h = perspective();
        let (w, hgt) = (400, 330);
        let img = render_board(size, &h, w, hgt);
        let corners = find_chessboard(w, hgt, &img, size).expect("board found");
        assert_eq!(corners.len(), 54);
        let mut worst: f64 = 0.0;
        for r in 0..size.rows {
            for c in 0..size.cols {
                let truth = apply_homography(&h, [c as f64, r as f64]);
                worst = worst.max(dist(corners[r * size.cols + c], truth));
            }
        }
        eprintln!("synthetic board: worst corner error {worst:.4} px");
        assert!(worst < 0.1, "worst corner error {worst} px");
    }

    #[test]
    fn ordering_is_canonical_under_rotation_of_the_board() {
        // The same board turned by 180° in the image: the first corner must still be the one next
        // to the dark corner square, i.e. the labels follow the board, not the image.
        let size = BoardSize { cols: 9, rows: 6 };
        let turn = Matrix3::new(-1.0, 0.0, 8.0, 0.0, -1.0, 5.0, 0.0, 0.0, 1.0);
        let h = perspective() * turn;
        let img = render_board(size, &h, 400, 330);
        let corners = find_chessboard(400, 330, &img, size).expect("board found");
        // Board point (c, r) of the turned rendering is plane point (8 - c, 5 - r); the dark first
        // square of the rendering is at plane (0,0)..(1,1) again, so labels are plane labels.
        let first = apply_homography(&h, [0.0, 0.0]);
        assert!(
            dist(corners[0], first) < 0.1,
            "{:?} vs {first:?}",
            corners[0]
        );
    }

    #[test]
    fn no_board_gives_none() {
        let size = BoardSize { cols: 9, rows: 6 };
        let flat = vec![128u8; 320 * 240];
        assert!(find_chessboard(320, 240, &flat, size).is_none());
        // Pseudo-random texture.
        let mut state = 12345u32;
        let noise: Vec<u8> = (0..320 * 240)
            .map(|_| {
                state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
                (state >> 24) as u8
            })
            .collect();
        assert!(find_chessboard(320, 240, &noise, size).is_none());
        // Wrong buffer length and tiny images are rejected, not indexed out of bounds.
        assert!(find_chessboard(320, 240, &flat[..100], size).is_none());
        assert!(find_chessboard(4, 4, &flat[..16], size).is_none());
    }

    #[test]
    fn board_with_other_corner_count_is_not_reported_as_9x6() {
        let h = perspective();
        let img = render_board(BoardSize { cols: 7, rows: 5 }, &h, 400, 330);
        assert!(find_chessboard(400, 330, &img, BoardSize { cols: 9, rows: 6 }).is_none());
        assert!(find_chessboard(400, 330, &img, BoardSize { cols: 7, rows: 5 }).is_some());
    }
}
