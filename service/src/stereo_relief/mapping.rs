//! From the stereo pipeline's 3D segments to the surface builder's input: the scene segments,
//! the left camera's pinhole, the robust scene depth range mapped onto the relief, the build
//! settings for one view without a rig, and the builder's report as text.

use std::time::Duration;

use videt_relief::{BuildReport, PinholeCamera, ReliefParams, SceneSegment3};
use videt_vision::{RectifiedGeometry, Segment3d};

/// Lower and upper percentiles of the segments' endpoint depths mapped onto the relief range.
const DEPTH_PERCENTILES: [f64; 2] = [0.02, 0.98];

/// The left camera's pinhole of a rectified geometry.
pub fn pinhole(geometry: &RectifiedGeometry) -> PinholeCamera {
    PinholeCamera {
        focal_px: geometry.focal_px,
        cx_px: geometry.cx_px,
        cy_px: geometry.cy_px,
    }
}

/// The pipeline's 3D segments as the surface builder's input (appended to `out`).
pub fn scene_segments(segments: &[Segment3d], out: &mut Vec<SceneSegment3>) {
    out.extend(segments.iter().map(|s| SceneSegment3 {
        a_m: [s.start_m.x, s.start_m.y, s.start_m.z],
        b_m: [s.end_m.x, s.end_m.y, s.end_m.z],
    }));
}

/// The scene depth range mapped onto the relief: the 2nd and 98th percentiles of the segments'
/// endpoint depths (in front of the camera), widened to at least 10 % of the far depth.
pub fn scene_depth_range(segments: &[SceneSegment3]) -> Result<[f64; 2], String> {
    let mut depths: Vec<f64> = segments
        .iter()
        .flat_map(|s| [s.a_m[2], s.b_m[2]])
        .filter(|z| z.is_finite() && *z > 0.0)
        .collect();
    if depths.is_empty() {
        return Err("no 3D segment in front of the camera: no scene depth range".into());
    }
    depths.sort_by(f64::total_cmp);
    let at = |q: f64| depths[((depths.len() - 1) as f64 * q).round() as usize];
    let (near, mut far) = (at(DEPTH_PERCENTILES[0]), at(DEPTH_PERCENTILES[1]));
    if far < near * 1.1 {
        far = near * 1.1;
    }
    Ok([near, far])
}

/// Device area a tool builds a relief on when there is no rig: 40 cm wide, at the origin.
pub const VIEW_AREA_WIDTH_M: f64 = 0.4;
/// Back plane of that relief, device `z`, metres.
pub const VIEW_BACK_PLANE_Z_M: f64 = 0.45;

/// Checks a relief depth for [`view_params`]: in `(0, 0.45)` metres.
pub fn check_view_relief_depth(relief_depth_m: f64) -> Result<(), String> {
    if relief_depth_m.is_finite() && relief_depth_m > 0.0 && relief_depth_m < VIEW_BACK_PLANE_Z_M {
        Ok(())
    } else {
        Err(format!(
            "relief depth {relief_depth_m} m must be in (0, {VIEW_BACK_PLANE_Z_M})"
        ))
    }
}

/// Build settings for one camera view without a rig (as `params_for_view` of the surface
/// module, but with the robust [`scene_depth_range`] and a chosen relief depth): the image
/// stretched over a 40 cm wide area at the origin (the image's aspect), `relief_depth_m` of
/// relief in front of a back plane at 45 cm.
pub fn view_params(
    segments: &[SceneSegment3],
    image_size_px: [u32; 2],
    relief_depth_m: f64,
) -> Result<ReliefParams, String> {
    check_view_relief_depth(relief_depth_m)?;
    let [w, h] = image_size_px;
    if w == 0 || h == 0 {
        return Err(format!("image size {w}x{h} has no pixels"));
    }
    let depth_range = scene_depth_range(segments)?;
    let size = [
        VIEW_AREA_WIDTH_M,
        VIEW_AREA_WIDTH_M * f64::from(h) / f64::from(w),
    ];
    let map = videt_control::SceneMap::new(
        [0.0, 0.0],
        size,
        image_size_px,
        VIEW_BACK_PLANE_Z_M,
        relief_depth_m,
        depth_range,
    )
    .map_err(|e| e.to_string())?;
    Ok(ReliefParams::new(map))
}

/// A short name for a rejection reason (for counting them by kind).
pub fn reason_label(reason: &videt_relief::RejectReason) -> &'static str {
    use videt_relief::RejectReason as R;
    match reason {
        R::NotFinite => "coordinate not finite",
        R::BehindCamera => "behind the camera",
        R::OutsideArea => "outside the explorable area",
        R::Degenerate => "shorter than the merge distance",
        R::Duplicate => "duplicate",
        R::CrossesNearerSegment { .. } => "crosses a nearer segment (occluded, kept as points)",
        R::OverlapsSegment { .. } => "overlaps a nearer segment (kept as points)",
        R::TriangulationConflict => "triangulation conflict",
    }
}

/// The build report as text: segments used and rejected (counted by reason), mesh size, time.
pub fn report_text(report: &BuildReport) -> String {
    use std::fmt::Write as _;
    let mut by_reason: Vec<(&'static str, usize)> = Vec::new();
    for r in &report.rejections {
        let label = reason_label(&r.reason);
        match by_reason.iter_mut().find(|(l, _)| *l == label) {
            Some((_, n)) => *n += 1,
            None => by_reason.push((label, 1)),
        }
    }
    let t = &report.timings;
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "surface: {} segments given, {} used as constraint edges ({} edges after {} crossings split), {} rejected",
        report.segments_in,
        report.constraints_kept,
        report.constraint_edges,
        report.crossings_split,
        report.rejections.len()
    );
    for (label, n) in by_reason {
        let _ = writeln!(s, "  rejected: {n:4} {label}");
    }
    let _ = writeln!(
        s,
        "mesh: {} vertices, {} triangles ({} points merged)",
        report.vertices, report.triangles, report.points_merged
    );
    let _ = writeln!(
        s,
        "build: {:.3} ms (cleaning {:.3}, crossings {:.3}, triangulation {:.3}, model {:.3})",
        ms(t.cleaning + t.crossings + t.triangulation + t.model),
        ms(t.cleaning),
        ms(t.crossings),
        ms(t.triangulation),
        ms(t.model)
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_range_ignores_a_few_outliers() {
        let seg = |z: f64| SceneSegment3 {
            a_m: [0.0, 0.0, z],
            b_m: [0.1, 0.0, z],
        };
        let mut segs: Vec<_> = (0..100).map(|k| seg(2.0 + k as f64 * 0.02)).collect();
        segs.push(seg(0.01));
        segs.push(seg(f64::NAN));
        let [near, far] = scene_depth_range(&segs).unwrap();
        assert!(near > 1.9 && far < 4.1 && far > 3.8, "{near} {far}");
        assert!(scene_depth_range(&[seg(-1.0)]).is_err());
    }
}
