//! Local updates: the stereo pipeline's local mode re-matches a region of interest around the
//! finger's path; the new segments replace the old ones inside that region and the surface is
//! rebuilt (a full rebuild of a few hundred segments takes well under the vision period; see the
//! `surface_build` benchmark).

use crate::clip::clip_to_rect;
use crate::input::{PinholeCamera, SceneSegment3};

/// The 3D point seen at image fraction `s` along a segment whose endpoints project to `ua`, `ub`
/// at depths `za`, `zb` (perspective: `1/Z` is linear in `s`).
fn point_at(
    camera: &PinholeCamera,
    ua: [f64; 2],
    ub: [f64; 2],
    za: f64,
    zb: f64,
    s: f64,
) -> [f64; 3] {
    let z = 1.0 / ((1.0 - s) / za + s / zb);
    let u = ua[0] + (ub[0] - ua[0]) * s;
    let v = ua[1] + (ub[1] - ua[1]) * s;
    [
        (u - camera.cx_px) * z / camera.focal_px,
        (v - camera.cy_px) * z / camera.focal_px,
        z,
    ]
}

/// The segments for a rebuild after a local re-match: the parts of `previous` outside the image
/// rectangle `roi_px = [u0, v0, u1, v1]` and the parts of `fresh` inside it. Segments that do
/// not project (behind the camera, not finite) are passed on unchanged for the build to reject
/// with a reason.
pub fn merge_region(
    previous: &[SceneSegment3],
    fresh: &[SceneSegment3],
    camera: &PinholeCamera,
    roi_px: [f64; 4],
) -> Vec<SceneSegment3> {
    let roi = [
        roi_px[0].min(roi_px[2]),
        roi_px[1].min(roi_px[3]),
        roi_px[0].max(roi_px[2]),
        roi_px[1].max(roi_px[3]),
    ];
    let mut out = Vec::with_capacity(previous.len() + fresh.len());
    for seg in previous {
        let (Some((ua, za)), Some((ub, zb))) = (camera.project(&seg.a_m), camera.project(&seg.b_m))
        else {
            out.push(*seg);
            continue;
        };
        match clip_to_rect(ua, ub, roi) {
            None => out.push(*seg),
            Some((s0, s1)) => {
                let at = |s| point_at(camera, ua, ub, za, zb, s);
                if s0 > 0.0 {
                    out.push(SceneSegment3 {
                        a_m: seg.a_m,
                        b_m: at(s0),
                    });
                }
                if s1 < 1.0 {
                    out.push(SceneSegment3 {
                        a_m: at(s1),
                        b_m: seg.b_m,
                    });
                }
            }
        }
    }
    for seg in fresh {
        let (Some((ua, za)), Some((ub, zb))) = (camera.project(&seg.a_m), camera.project(&seg.b_m))
        else {
            out.push(*seg);
            continue;
        };
        if let Some((s0, s1)) = clip_to_rect(ua, ub, roi) {
            let at = |s| point_at(camera, ua, ub, za, zb, s);
            out.push(SceneSegment3 {
                a_m: at(s0),
                b_m: at(s1),
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn old_parts_outside_and_new_parts_inside_the_region() {
        let cam = PinholeCamera {
            focal_px: 500.0,
            cx_px: 200.0,
            cy_px: 150.0,
        };
        // A horizontal 3D line at 2 m from u = 100 to u = 300.
        let z = 2.0;
        let x = |u: f64| (u - 200.0) * z / 500.0;
        let old = [SceneSegment3 {
            a_m: [x(100.0), 0.0, z],
            b_m: [x(300.0), 0.0, z],
        }];
        let new = [SceneSegment3 {
            a_m: [x(120.0), 0.1, z],
            b_m: [x(280.0), 0.1, z],
        }];
        let roi = [150.0, 100.0, 250.0, 200.0];
        let merged = merge_region(&old, &new, &cam, roi);
        assert_eq!(merged.len(), 3);
        let u = |p: &[f64; 3]| cam.project(p).unwrap().0[0];
        assert!((u(&merged[0].b_m) - 150.0).abs() < 1e-9);
        assert!((u(&merged[1].a_m) - 250.0).abs() < 1e-9);
        assert!(
            (u(&merged[2].a_m) - 150.0).abs() < 1e-9 && (u(&merged[2].b_m) - 250.0).abs() < 1e-9
        );
        assert!((merged[2].a_m[2] - z).abs() < 1e-12);
    }
}
