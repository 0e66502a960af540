//! Fuzzes the bas-relief builder on arbitrary segment sets: segments decoded from the bytes go
//! through `surface::build_from_scene` (camera-frame segments seen through a pinhole, with
//! points) or `surface::build_from_device` (segments already in device coordinates), and a model
//! that is built is queried (`height_at`, `first_hit`). Coordinates are decoded so that most
//! land in and around the workspace (where the triangulation, the crossing splits and the
//! occlusion decisions happen) while any f64 at all — NaN, infinities, subnormals, huge values
//! — can occur too. Layout: `docs/fuzzing.md`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use videt_control::{SceneMap, Vec3};
use videt_relief::{
    build_from_device, build_from_scene, DeviceSegment, PinholeCamera, ReliefParams, SceneSegment3,
};

/// Reads the fuzz bytes as numbers.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn byte(&mut self) -> Option<u8> {
        let (&b, rest) = self.0.split_first()?;
        self.0 = rest;
        Some(b)
    }

    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let b: [u8; N] = self.0.get(..N)?.try_into().ok()?;
        self.0 = &self.0[N..];
        Some(b)
    }

    /// One coordinate: a tag byte, then either 2 bytes spread over `[lo, hi]` with a little
    /// margin (most tags), or a raw f64 (any bit pattern).
    fn coordinate(&mut self, lo: f64, hi: f64) -> Option<f64> {
        let tag = self.byte()?;
        if tag >= 0xF0 {
            return Some(f64::from_le_bytes(self.take::<8>()?));
        }
        let t = f64::from(u16::from_le_bytes(self.take::<2>()?)) / f64::from(u16::MAX);
        let margin = 0.1 * (hi - lo);
        Some(lo - margin + t * (hi - lo + 2.0 * margin))
    }

    fn point(&mut self, ranges: [[f64; 2]; 3]) -> Option<[f64; 3]> {
        Some([
            self.coordinate(ranges[0][0], ranges[0][1])?,
            self.coordinate(ranges[1][0], ranges[1][1])?,
            self.coordinate(ranges[2][0], ranges[2][1])?,
        ])
    }
}

/// The default camera view's settings (the 40 x 30 cm area of `params_for_view`), with the
/// tunable tolerances taken from the bytes.
fn params(b: &mut Bytes<'_>) -> Option<ReliefParams> {
    let map = SceneMap::new([0.0, 0.0], [0.4, 0.3], [640, 480], 0.45, 0.08, [0.5, 5.0]).ok()?;
    let mut p = ReliefParams::new(map);
    let knobs = b.byte()?;
    if knobs & 1 != 0 {
        p.crossing_tolerance_m = f64::from(b.byte()?) * 1e-4;
    }
    if knobs & 2 != 0 {
        p.merge_distance_m = f64::from(b.byte()?.max(1)) * 1e-5;
    }
    if knobs & 4 != 0 {
        p.grid_cells_per_triangle = f64::from(b.byte()?.max(1)) / 16.0;
    }
    Some(p)
}

fuzz_target!(|data: &[u8]| {
    let mut b = Bytes(data);
    let Some(mode) = b.byte() else {
        return;
    };
    let Some(params) = params(&mut b) else {
        return;
    };
    let built = if mode & 1 == 0 {
        // Camera frame: x, y across the view, z the scene depth (0.5 to 5 m).
        let ranges = [[-2.0, 2.0], [-1.5, 1.5], [0.3, 5.5]];
        let camera = PinholeCamera {
            focal_px: 640.0,
            cx_px: 319.5,
            cy_px: 239.5,
        };
        let mut segments = Vec::new();
        let mut points = Vec::new();
        while let Some(kind) = b.byte() {
            if kind < 0xE0 {
                let (Some(a_m), Some(b_m)) = (b.point(ranges), b.point(ranges)) else {
                    break;
                };
                segments.push(SceneSegment3 { a_m, b_m });
            } else {
                let Some(p) = b.point(ranges) else { break };
                points.push(p);
            }
        }
        build_from_scene(&segments, &points, &camera, &params)
    } else {
        // Device frame: the area, z from the relief's front (0.37 m) to the back plane (0.45 m).
        let ranges = [[0.0, 0.4], [0.0, 0.3], [0.37, 0.45]];
        let mut segments = Vec::new();
        let mut points = Vec::new();
        while let Some(kind) = b.byte() {
            if kind < 0xE0 {
                let (Some(a_m), Some(b_m)) = (b.point(ranges), b.point(ranges)) else {
                    break;
                };
                segments.push(DeviceSegment { a_m, b_m });
            } else {
                let Some(p) = b.point(ranges) else { break };
                points.push(p);
            }
        }
        build_from_device(&segments, &points, &params)
    };
    let Ok((model, report)) = built else {
        return;
    };
    let _ = report;
    let [x0, y0, x1, y1] = model.area_m();
    for (i, j) in [(1, 1), (1, 3), (2, 2), (3, 1), (3, 3)] {
        let (x, y) = (
            x0 + (x1 - x0) * f64::from(i) / 4.0,
            y0 + (y1 - y0) * f64::from(j) / 4.0,
        );
        if let Some(h) = model.height_at(x, y) {
            assert!(h.z_m.is_finite(), "height {} at ({x}, {y})", h.z_m);
        }
    }
    let _ = model.first_hit(
        &Vec3::new(0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.0),
        &Vec3::new(0.5 * (x0 + x1), 0.5 * (y0 + y1), 1.0),
    );
});
