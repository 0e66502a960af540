//! The felt surface: what the finger is held on when it explores a bas-relief, compared with
//! the true surface of the scene.
//!
//! The twin's virtual operator sweeps the explorable area in a raster (rows along `x`, one way
//! then back) with a light, constant push into the relief (`+z`) while the real control cycle
//! renders the relief through the CiA 402 twin ([`crate::haptic_bench::rig`]). Every period in
//! which the thimble is on the surface (at or under the rendered relief's height) is a
//! **contact sample**: the thimble's height is compared with the true surface's at the same
//! point of the area. Held back by a wall, the hand lifts over it, as a finger would. The
//! figures, over the visited cells (each its samples' median error, so that the area counts and
//! not the time spent on it): the median and 95th percentile of the height error, the
//! fraction of the visited area (cells of [`FeltSettings::cell_m`]) whose median error exceeds
//! the threshold, and the force the wires put on the thimble during contact (its 99th
//! percentile and largest, against the push: the excursions at steps).

use videt_control::Surface;
use videt_sim::{Vec3, VirtualOperator, Waypoint};

use crate::haptic_bench::rig::Trace;

/// How the area is swept and judged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeltSettings {
    /// The area swept `[x0, y0, x1, y1]`, metres.
    pub area_m: [f64; 4],
    /// Distance between two rows, metres.
    pub row_spacing_m: f64,
    /// Speed along a row, m/s.
    pub speed_m_s: f64,
    /// The push into the relief, newtons.
    pub push_n: f64,
    /// Held back across by more than this, the hand lifts (over a step), newtons.
    pub lift_above_n: f64,
    /// Side of the cells the area is judged in, metres.
    pub cell_m: f64,
    /// A cell is off when its median height error exceeds this, metres.
    pub threshold_m: f64,
}

impl FeltSettings {
    /// 1 cm rows at 8 cm/s with a 1 N push, lifting when held back by more than 3 N, judged in
    /// 5 mm cells at 5 mm, over `area_m`.
    pub fn over(area_m: [f64; 4]) -> FeltSettings {
        FeltSettings {
            area_m,
            row_spacing_m: 0.01,
            speed_m_s: 0.08,
            push_n: 1.0,
            lift_above_n: 3.0,
            cell_m: 0.005,
            threshold_m: 0.005,
        }
    }

    /// The rows' `y`, from `y0` to `y1`.
    fn rows(&self) -> Vec<f64> {
        let [_, y0, _, y1] = self.area_m;
        let n = ((y1 - y0) / self.row_spacing_m).floor().max(0.0) as usize;
        (0..=n)
            .map(|k| y0 + k as f64 * self.row_spacing_m)
            .collect()
    }

    /// Simulated seconds the sweep takes from `start_m`, with a second to settle.
    pub fn duration_s(&self, start_m: Vec3) -> f64 {
        self.script(start_m)
            .last()
            .map(|w| w.time_s + 1.0)
            .unwrap_or(1.0)
    }

    fn script(&self, start_m: Vec3) -> Vec<Waypoint> {
        let [x0, _, x1, _] = self.area_m;
        let mut at = start_m;
        let mut t = 0.0;
        let mut out = vec![Waypoint {
            time_s: 0.0,
            target_m: start_m,
        }];
        let mut go = |to: Vec3, out: &mut Vec<Waypoint>| {
            let d = Vec3::new(to.x - at.x, to.y - at.y, 0.0).norm();
            t += (d / self.speed_m_s).max(0.05);
            out.push(Waypoint {
                time_s: t,
                target_m: to,
            });
            at = to;
        };
        for (k, y) in self.rows().into_iter().enumerate() {
            let (a, b) = if k % 2 == 0 { (x0, x1) } else { (x1, x0) };
            go(Vec3::new(a, y, start_m.z), &mut out);
            go(Vec3::new(b, y, start_m.z), &mut out);
        }
        out
    }

    /// The operator: from `start_m`, the raster at the push.
    pub fn operator(&self, start_m: Vec3) -> VirtualOperator {
        VirtualOperator::new(self.script(start_m), 200.0, 6.0)
            .pressing(Vec3::z(), self.push_n)
            .lifting_over(self.lift_above_n)
    }
}

/// What the finger was held on, against the true surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeltSurface {
    /// Contact samples with a known true height.
    pub samples: usize,
    /// Median over the visited cells of each cell's median |felt - true| height, metres.
    pub median_m: f64,
    /// 95th percentile of the same, metres.
    pub p95_m: f64,
    /// Cells visited in contact (with a known true height).
    pub cells: usize,
    /// Fraction of them whose median error exceeds the threshold.
    pub off_fraction: f64,
    /// Of the visited cells, those across which the true surface itself spans more than the
    /// threshold (a depth step or a steep slope inside the cell): a finger held on a wall
    /// there is off the truth on either side of it.
    pub step_cells: usize,
    /// 95th percentile of the cells' median error over the other cells (the faces), metres.
    pub p95_off_steps_m: f64,
    /// 99th percentile of the wires' force on the thimble in contact, newtons.
    pub force_p99_n: f64,
    /// Largest force in contact, newtons.
    pub force_max_n: f64,
}

/// Probes per side of a cell where the true surface's span is sampled.
const STEP_PROBES: usize = 5;

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let k = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[k.min(sorted.len() - 1)]
}

/// The felt surface of `trace` (a sweep of `relief`) against `truth_z(x, y)` (the true surface's
/// device `z` there, `None` unknown), judged with `settings`.
pub fn felt_surface(
    trace: &Trace,
    relief: &impl Surface,
    truth_z: impl Fn(f64, f64) -> Option<f64>,
    settings: &FeltSettings,
) -> FeltSurface {
    let [x0, y0, x1, y1] = settings.area_m;
    let nx = ((x1 - x0) / settings.cell_m).ceil().max(1.0) as usize;
    let ny = ((y1 - y0) / settings.cell_m).ceil().max(1.0) as usize;
    let mut per_cell: Vec<Vec<f64>> = vec![Vec::new(); nx * ny];
    // Whether the truth spans more than the threshold across a cell (sampled on a grid of
    // STEP_PROBES x STEP_PROBES points, the cell's edges included).
    let t = |k: usize| k as f64 / (STEP_PROBES - 1) as f64;
    let spans_a_step = |cell: usize| {
        let (i, j) = (cell % nx, cell / nx);
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for a in 0..STEP_PROBES {
            for b in 0..STEP_PROBES {
                let x = x0 + (i as f64 + t(a)) * settings.cell_m;
                let y = y0 + (j as f64 + t(b)) * settings.cell_m;
                if let Some(z) = truth_z(x.min(x1), y.min(y1)) {
                    lo = lo.min(z);
                    hi = hi.max(z);
                }
            }
        }
        hi - lo > settings.threshold_m
    };
    let mut errors = Vec::with_capacity(trace.samples.len());
    let mut forces = Vec::with_capacity(trace.samples.len());
    for s in &trace.samples {
        let p = s.position_m;
        if !(p.x >= x0 && p.x <= x1 && p.y >= y0 && p.y <= y1) {
            continue;
        }
        // On the surface: at or under the rendered relief.
        if relief.contact(&p).is_none() {
            continue;
        }
        forces.push(s.wire_force_n.norm());
        let Some(z) = truth_z(p.x, p.y) else {
            continue;
        };
        let e = (p.z - z).abs();
        errors.push(e);
        let i = (((p.x - x0) / settings.cell_m) as usize).min(nx - 1);
        let j = (((p.y - y0) / settings.cell_m) as usize).min(ny - 1);
        per_cell[j * nx + i].push(e);
    }
    forces.sort_by(f64::total_cmp);
    // Per cell, the median error: the area counts, not the time spent on it.
    let mut cell_errors = Vec::new();
    let mut face_errors = Vec::new();
    for (k, c) in per_cell.iter_mut().enumerate() {
        if c.is_empty() {
            continue;
        }
        c.sort_by(f64::total_cmp);
        let e = percentile(c, 0.5);
        cell_errors.push(e);
        if !spans_a_step(k) {
            face_errors.push(e);
        }
    }
    cell_errors.sort_by(f64::total_cmp);
    face_errors.sort_by(f64::total_cmp);
    let cells = cell_errors.len();
    let off = cell_errors
        .iter()
        .filter(|&&e| e > settings.threshold_m)
        .count();
    FeltSurface {
        samples: errors.len(),
        median_m: percentile(&cell_errors, 0.5),
        p95_m: percentile(&cell_errors, 0.95),
        cells,
        off_fraction: if cells > 0 {
            off as f64 / cells as f64
        } else {
            f64::NAN
        },
        step_cells: cells - face_errors.len(),
        p95_off_steps_m: percentile(&face_errors, 0.95),
        force_p99_n: percentile(&forces, 0.99),
        force_max_n: forces.last().copied().unwrap_or(f64::NAN),
    }
}

/// The felt surface as a map: per cell of `cell_m`, the median height the thimble was held
/// at in contact (`NaN` where it never touched), row-major from `[x0, y0]`.
#[derive(Debug, Clone, PartialEq)]
pub struct FeltMap {
    /// The area mapped `[x0, y0, x1, y1]`, metres.
    pub area_m: [f64; 4],
    /// Side of a cell, metres.
    pub cell_m: f64,
    /// Cells along `x` and `y`.
    pub cells: [usize; 2],
    /// Median contact height per cell, metres.
    pub z_m: Vec<f64>,
}

impl FeltMap {
    /// The felt height at `(x, y)`, `None` where the finger never touched.
    pub fn at(&self, x: f64, y: f64) -> Option<f64> {
        let [x0, y0, x1, y1] = self.area_m;
        if !(x >= x0 && x <= x1 && y >= y0 && y <= y1) {
            return None;
        }
        let i = (((x - x0) / self.cell_m) as usize).min(self.cells[0] - 1);
        let j = (((y - y0) / self.cell_m) as usize).min(self.cells[1] - 1);
        let z = self.z_m[j * self.cells[0] + i];
        z.is_finite().then_some(z)
    }
}

/// The [`FeltMap`] of `trace` (a sweep of `relief`) in cells of `cell_m` over
/// `settings.area_m`.
pub fn felt_map(
    trace: &Trace,
    relief: &impl Surface,
    settings: &FeltSettings,
    cell_m: f64,
) -> FeltMap {
    let [x0, y0, x1, y1] = settings.area_m;
    let nx = ((x1 - x0) / cell_m).ceil().max(1.0) as usize;
    let ny = ((y1 - y0) / cell_m).ceil().max(1.0) as usize;
    let mut per_cell: Vec<Vec<f64>> = vec![Vec::new(); nx * ny];
    for s in &trace.samples {
        let p = s.position_m;
        if !(p.x >= x0 && p.x <= x1 && p.y >= y0 && p.y <= y1) || relief.contact(&p).is_none() {
            continue;
        }
        let i = (((p.x - x0) / cell_m) as usize).min(nx - 1);
        let j = (((p.y - y0) / cell_m) as usize).min(ny - 1);
        per_cell[j * nx + i].push(p.z);
    }
    let z_m = per_cell
        .iter_mut()
        .map(|c| {
            c.sort_by(f64::total_cmp);
            percentile(c, 0.5)
        })
        .collect();
    FeltMap {
        area_m: settings.area_m,
        cell_m,
        cells: [nx, ny],
        z_m,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::haptic_bench::rig::TruthSample;
    use videt_control::safety::SafetyState;
    use videt_control::surface::Plane;
    use videt_control::FeltTally;

    /// A trace of the thimble held 0.5 mm into the wall `z = 0.4` (outward `-z`) on a 1 mm
    /// grid over `[0, 0.1] x [0, 0.05]`, and once above it, out of contact.
    fn pressed_trace() -> Trace {
        let sample = |x: f64, y: f64, z: f64| TruthSample {
            time_s: 0.0,
            position_m: Vec3::new(x, y, z),
            velocity_m_s: Vec3::zeros(),
            wire_force_n: Vec3::new(0.0, 0.0, -1.0),
            hand_force_n: Vec3::zeros(),
            max_tension_n: 0.0,
            tension_n: [0.0; 3],
            measured_tension_n: [0.0; 3],
            torque_nm: [0.0; 3],
            pulley_speed_rad_s: [0.0; 3],
        };
        let mut samples: Vec<TruthSample> = (0..100)
            .flat_map(|i| (0..50).map(move |j| (i, j)))
            .map(|(i, j)| {
                sample(
                    0.0005 + 0.001 * f64::from(i),
                    0.0005 + 0.001 * f64::from(j),
                    0.4005,
                )
            })
            .collect();
        samples.push(sample(0.02, 0.02, 0.3));
        Trace {
            samples,
            final_safety: SafetyState::Normal,
            cycles: 0,
            felt: FeltTally::new(),
        }
    }

    #[test]
    fn the_felt_surface_is_compared_cell_by_cell_with_the_truth() {
        let wall = Plane::new(Vec3::new(0.0, 0.0, 0.4), -Vec3::z()).unwrap();
        let settings = FeltSettings::over([0.0, 0.0, 0.1, 0.05]);
        // The truth: the wall's height for x < 0.03, 9.5 mm nearer beyond (off by 10 mm), unknown
        // for y > 0.04.
        let truth = |x: f64, y: f64| (y <= 0.04).then_some(if x < 0.03 { 0.4 } else { 0.3905 });
        let felt = felt_surface(&pressed_trace(), &wall, truth, &settings);
        // 20 x 8 cells of 5 mm with truth; 6 of 20 columns right, 14 off by 10 mm.
        assert_eq!(felt.cells, 20 * 8);
        assert!((felt.off_fraction - 14.0 / 20.0).abs() < 1e-12, "{felt:?}");
        assert!((felt.median_m - 0.010).abs() < 1e-9, "{felt:?}");
        assert!((felt.p95_m - 0.010).abs() < 1e-9, "{felt:?}");
        // The column of cells whose right edge is on the step spans it; the faces' p95 is
        // that of the other 19 columns.
        assert_eq!(felt.step_cells, 8, "{felt:?}");
        assert!((felt.p95_off_steps_m - 0.010).abs() < 1e-9, "{felt:?}");
        // The sample out of contact is not counted; the forces are those in contact.
        assert_eq!(felt.samples, 100 * 40);
        assert!((felt.force_max_n - 1.0).abs() < 1e-12);
        let map = felt_map(&pressed_trace(), &wall, &settings, 0.0025);
        assert_eq!(map.at(0.05, 0.045), Some(0.4005));
        assert_eq!(map.at(0.2, 0.0), None);
    }

    #[test]
    fn the_raster_covers_the_area_row_by_row() {
        let s = FeltSettings::over([0.0, 0.0, 0.1, 0.03]);
        let script = s.script(Vec3::new(0.05, 0.05, 0.2));
        // Start, then two waypoints per row at y = 0, 0.01, 0.02, 0.03.
        assert_eq!(script.len(), 1 + 2 * 4);
        assert_eq!(script[1].target_m, Vec3::new(0.0, 0.0, 0.2));
        assert_eq!(script[2].target_m, Vec3::new(0.1, 0.0, 0.2));
        assert_eq!(script[3].target_m, Vec3::new(0.1, 0.01, 0.2));
        assert!(script.windows(2).all(|w| w[1].time_s > w[0].time_s));
        // 10 cm at 8 cm/s per row.
        assert!((script[2].time_s - script[1].time_s - 1.25).abs() < 1e-9);
    }
}
