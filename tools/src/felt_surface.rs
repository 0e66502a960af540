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
    /// 99th percentile of the wires' force on the thimble in contact, newtons.
    pub force_p99_n: f64,
    /// Largest force in contact, newtons.
    pub force_max_n: f64,
}

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
    let mut cell_errors: Vec<f64> = per_cell
        .iter_mut()
        .filter(|c| !c.is_empty())
        .map(|c| {
            c.sort_by(f64::total_cmp);
            percentile(c, 0.5)
        })
        .collect();
    cell_errors.sort_by(f64::total_cmp);
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
        force_p99_n: percentile(&forces, 0.99),
        force_max_n: forces.last().copied().unwrap_or(f64::NAN),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
