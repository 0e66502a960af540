//! Scenes of known geometry built from known segments, queried against analytic answers; and
//! property tests with garbage input.

use super::*;
use proptest::prelude::*;
use videt_control::proxy::{GodObject, ProxyParams};
use videt_control::relief::ReliefSurface;
use videt_control::{SceneMap, Surface, Vec3};

const BACK_Z: f64 = 0.45;

fn params() -> ReliefParams {
    let map = SceneMap::new([0.0, 0.0], [0.4, 0.3], [640, 480], BACK_Z, 0.08, [0.5, 5.0]).unwrap();
    ReliefParams::new(map)
}

fn seg(a: [f64; 3], b: [f64; 3]) -> DeviceSegment {
    DeviceSegment { a_m: a, b_m: b }
}

/// A square outline `[x0, y0]-[x1, y1]` at height `z`.
fn square(x0: f64, y0: f64, x1: f64, y1: f64, z: f64) -> [DeviceSegment; 4] {
    [
        seg([x0, y0, z], [x1, y0, z]),
        seg([x1, y0, z], [x1, y1, z]),
        seg([x1, y1, z], [x0, y1, z]),
        seg([x0, y1, z], [x0, y0, z]),
    ]
}

/// The step scene: `z = 0.40` for `x <= 0.19`, `0.42` for `x >= 0.21`, a ramp between (the
/// paper's interpolated surface).
fn step_scene() -> ReliefModel {
    let segs = [
        seg([0.10, 0.05, 0.40], [0.10, 0.25, 0.40]),
        seg([0.19, 0.05, 0.40], [0.19, 0.25, 0.40]),
        seg([0.21, 0.05, 0.42], [0.21, 0.25, 0.42]),
        seg([0.30, 0.05, 0.42], [0.30, 0.25, 0.42]),
    ];
    build_from_device(&segs, &[], &interpolated()).unwrap().0
}

/// The paper's surface: interpolated across steps (the scenes whose queries are checked
/// against analytic ramps).
fn interpolated() -> ReliefParams {
    let mut p = params();
    p.shape = ReliefShape::Interpolated;
    p
}

/// Depth steps kept as steps, with the default step settings.
fn stepped() -> ReliefParams {
    let mut p = params();
    p.shape = ReliefShape::Stepped;
    p
}

/// The box scene: a 10 cm square top at `z = 0.38` on a 20 cm base outline at `0.43` (the
/// paper's interpolated surface).
fn box_scene() -> ReliefModel {
    let mut segs = square(0.15, 0.10, 0.25, 0.20, 0.38).to_vec();
    segs.extend(square(0.10, 0.05, 0.30, 0.25, 0.43));
    build_from_device(&segs, &[], &interpolated()).unwrap().0
}

#[test]
fn plane_scene_is_flat_inside_and_frames_to_the_back_plane() {
    let mut segs = square(0.1, 0.05, 0.3, 0.25, 0.40).to_vec();
    segs.push(seg([0.1, 0.05, 0.40], [0.3, 0.25, 0.40]));
    let (m, report) = build_from_device(&segs, &[], &params()).unwrap();
    assert_eq!(report.constraints_kept, 5);
    assert!(report.rejections.is_empty(), "{:?}", report.rejections);
    for (x, y) in [(0.15, 0.1), (0.2, 0.15), (0.29, 0.24), (0.11, 0.2)] {
        let h = m.height_at(x, y).unwrap();
        assert!((h.z_m - 0.40).abs() < 1e-12, "{x} {y}: {}", h.z_m);
        assert!(h.normal.z < -0.8, "{:?}", h.normal);
        assert!((h.face_normal + Vec3::z()).norm() < 1e-9);
    }
    // The area's border and beyond: the back plane.
    assert!((m.height_at(0.0, 0.0).unwrap().z_m - BACK_Z).abs() < 1e-12);
    assert!((m.height_at(0.2, 0.0).unwrap().z_m - BACK_Z).abs() < 1e-12);
    assert!((m.height_at(-1.0, 7.0).unwrap().z_m - BACK_Z).abs() < 1e-12);
    // Penetration along z.
    let c = m.contact(&Vec3::new(0.2, 0.15, 0.403)).unwrap();
    assert!((c.depth_m - 0.003).abs() < 1e-12);
    assert!(m.contact(&Vec3::new(0.2, 0.15, 0.399)).is_none());
    // The bas-relief condition: every outward normal within 90° of -z.
    assert!(m.vertex_normals().iter().all(|n| n[2] < 0.0));
}

#[test]
fn step_scene_matches_the_analytic_step() {
    let m = step_scene();
    for y in [0.06, 0.15, 0.24] {
        for (x, z) in [
            (0.12, 0.40),
            (0.18, 0.40),
            (0.2, 0.41),
            (0.205, 0.415),
            (0.25, 0.42),
        ] {
            let h = m.height_at(x, y).unwrap();
            assert!((h.z_m - z).abs() < 1e-12, "({x}, {y}): {} vs {z}", h.z_m);
        }
    }
    // The ramp's face normal: gradient dz/dx = 1 -> (1, 0, -1)/sqrt 2.
    let ramp = m.height_at(0.2, 0.15).unwrap().face_normal;
    assert!((ramp - Vec3::new(1.0, 0.0, -1.0).normalize()).norm() < 1e-9);
    // Interpolated normals vary continuously across the ramp's edges.
    let a = m.height_at(0.19 - 1e-7, 0.15).unwrap().normal;
    let b = m.height_at(0.19 + 1e-7, 0.15).unwrap().normal;
    assert!((a - b).norm() < 1e-4, "{a:?} vs {b:?}");
}

#[test]
fn box_scene_rays_and_impacts() {
    let m = box_scene();
    assert!((m.height_at(0.2, 0.15).unwrap().z_m - 0.38).abs() < 1e-12);
    // Side of the box: halfway between the top edge (x=0.25, 0.38) and the base (x=0.30, 0.43).
    assert!((m.height_at(0.275, 0.15).unwrap().z_m - 0.405).abs() < 1e-12);
    // Straight down onto the top: the paper's distance to impact.
    let imp = m
        .impact(
            &Vec3::new(0.2, 0.15, 0.30),
            &Vec3::new(0.2, 0.15, 0.31),
            1.0,
        )
        .unwrap();
    assert!((imp.distance_m - 0.07).abs() < 1e-9, "{imp:?}");
    assert!((imp.point_m.z - 0.38).abs() < 1e-9);
    // Sideways at z = 0.40 from x = 0.05 (above the base, in front of the box side): the side
    // face z = 0.43 - (0.30 - x) is reached at x = 0.28.
    let imp = m
        .impact(
            &Vec3::new(0.31, 0.15, 0.40),
            &Vec3::new(0.305, 0.15, 0.40),
            1.0,
        )
        .unwrap();
    assert!((imp.point_m.x - 0.27).abs() < 1e-9, "{imp:?}");
    assert!((imp.distance_m - 0.035).abs() < 1e-9);
    // Moving away from everything: no impact before the limit.
    assert!(m
        .impact(
            &Vec3::new(0.2, 0.15, 0.31),
            &Vec3::new(0.2, 0.15, 0.30),
            0.2
        )
        .is_none());
    // Outside the area the back plane catches the ray.
    let imp = m
        .impact(
            &Vec3::new(-0.2, -0.2, 0.40),
            &Vec3::new(-0.2, -0.2, 0.41),
            1.0,
        )
        .unwrap();
    assert!((imp.distance_m - 0.04).abs() < 1e-9);
}

#[test]
fn grid_queries_agree_with_brute_force() {
    use rand::{Rng, SeedableRng};
    let m = box_scene();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    for _ in 0..2000 {
        let (x, y) = (rng.random_range(-0.01..0.41), rng.random_range(-0.01..0.31));
        let fast = m.height_at(x, y).unwrap().z_m;
        let slow = m.height_at_brute_force(x, y).unwrap();
        assert!((fast - slow).abs() < 1e-12, "({x}, {y}) {fast} vs {slow}");
        let from = Vec3::new(x, y, rng.random_range(0.3..0.37));
        let to = from
            + Vec3::new(
                rng.random_range(-0.1..0.1),
                rng.random_range(-0.1..0.1),
                0.08,
            );
        let inside = |p: &Vec3| p.x >= 0.0 && p.x <= 0.4 && p.y >= 0.0 && p.y <= 0.3;
        if inside(&from) && inside(&to) {
            let a = m.first_hit(&from, &to).map(|h| h.t);
            let b = m.first_hit_brute_force(&from, &to);
            match (a, b) {
                (Some(a), Some(b)) => assert!((a - b).abs() < 1e-9, "{a} vs {b}"),
                (None, None) => {}
                other => panic!("{other:?} for {from:?} -> {to:?}"),
            }
        }
    }
}

#[test]
fn scene_segments_through_a_pinhole_land_at_their_relief_depth() {
    let cam = PinholeCamera {
        focal_px: 500.0,
        cx_px: 320.0,
        cy_px: 240.0,
    };
    let p = params();
    // A fronto-parallel rectangle at 2 m, filling the middle of the image.
    let z = 2.0;
    let pt = |u: f64, v: f64| [(u - 320.0) * z / 500.0, (v - 240.0) * z / 500.0, z];
    let segs = [
        SceneSegment3 {
            a_m: pt(160.0, 120.0),
            b_m: pt(480.0, 120.0),
        },
        SceneSegment3 {
            a_m: pt(480.0, 120.0),
            b_m: pt(480.0, 360.0),
        },
        SceneSegment3 {
            a_m: pt(480.0, 360.0),
            b_m: pt(160.0, 360.0),
        },
        SceneSegment3 {
            a_m: pt(160.0, 360.0),
            b_m: pt(160.0, 120.0),
        },
    ];
    let (m, _) = build_from_scene(&segs, &[[0.0, 0.0, -1.0]], &cam, &p).unwrap();
    let expected = p.scene_map.scene_depth_to_relief_z(z);
    let [x, y] = p.scene_map.image_to_workspace(320.0, 240.0);
    assert!((m.height_at(x, y).unwrap().z_m - expected).abs() < 1e-12);
    let [x, y] = p.scene_map.image_to_workspace(200.0, 300.0);
    assert!((m.height_at(x, y).unwrap().z_m - expected).abs() < 1e-12);
}

#[test]
fn view_settings_span_the_segments_depths() {
    let segs = [
        SceneSegment3 {
            a_m: [0.0, 0.0, 1.5],
            b_m: [0.1, 0.0, 3.0],
        },
        SceneSegment3 {
            a_m: [0.0, 0.0, f64::NAN],
            b_m: [0.1, 0.0, -1.0],
        },
    ];
    let p = params_for_view(&segs, [640, 480]).unwrap();
    assert!((p.scene_map.scene_depth_to_relief_z(1.5) - 0.37).abs() < 1e-12);
    assert!((p.scene_map.scene_depth_to_relief_z(3.0) - 0.45).abs() < 1e-12);
    assert!(params_for_view(&segs[1..], [640, 480]).is_err());
}

#[test]
fn crossing_segments_are_split_or_dropped_with_a_reason() {
    // Two crossing segments at the same height: split at a shared vertex.
    let same = [
        seg([0.1, 0.1, 0.40], [0.3, 0.2, 0.40]),
        seg([0.1, 0.2, 0.40], [0.3, 0.1, 0.40]),
    ];
    let (m, r) = build_from_device(&same, &[], &params()).unwrap();
    assert_eq!(r.crossings_split, 1);
    assert_eq!(r.constraint_edges, 4);
    assert!((m.height_at(0.2, 0.15).unwrap().z_m - 0.40).abs() < 1e-12);
    // At different heights: the farther one is occluded.
    let occluded = [
        seg([0.1, 0.1, 0.40], [0.3, 0.2, 0.40]),
        seg([0.1, 0.2, 0.43], [0.3, 0.1, 0.43]),
    ];
    let (m, r) = build_from_device(&occluded, &[], &params()).unwrap();
    assert_eq!(r.constraints_kept, 1);
    assert!(matches!(
        r.rejections[0],
        Rejection {
            item: InputItem::Segment(1),
            reason: RejectReason::CrossesNearerSegment { other: 0, .. }
        }
    ));
    assert!((m.height_at(0.2, 0.15).unwrap().z_m - 0.40).abs() < 1e-12);
    // Duplicates, NaN, zero length and out-of-area input.
    let junk = [
        seg([0.1, 0.1, 0.40], [0.3, 0.2, 0.40]),
        seg([0.3, 0.2, 0.40], [0.1, 0.1, 0.40]),
        seg([f64::NAN, 0.1, 0.4], [0.2, 0.2, 0.4]),
        seg([0.2, 0.2, 0.4], [0.2, 0.2, 0.4]),
        seg([1.0, 1.0, 0.4], [2.0, 1.0, 0.4]),
    ];
    let (_, r) = build_from_device(&junk, &[[0.2, 0.2, f64::INFINITY]], &params()).unwrap();
    let reasons: Vec<_> = r.rejections.iter().map(|r| r.reason).collect();
    assert!(reasons.contains(&RejectReason::Duplicate));
    assert!(reasons.contains(&RejectReason::NotFinite));
    assert!(reasons.contains(&RejectReason::Degenerate));
    assert!(reasons.contains(&RejectReason::OutsideArea));
    // Nothing usable at all.
    assert!(matches!(
        build_from_device(&[], &[], &params()),
        Err(BuildError::NoUsableInput(_))
    ));
    let mut bad = params();
    bad.merge_distance_m = -1.0;
    match build_from_device(&same, &[], &bad) {
        Err(BuildError::Params(e)) => assert_eq!(e.field, "merge_distance_m"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn exports_write_ply_and_png() {
    let m = box_scene();
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("surface.ply");
    let png = dir.path().join("surface_depth.png");
    export::write_ply(&m, &ply).unwrap();
    export::write_depth_png(&m, 200, &png).unwrap();
    let text = std::fs::read_to_string(&ply).unwrap();
    assert!(text.starts_with("ply\n"));
    assert!(text.contains(&format!("element face {}", m.triangles().len())));
    let img = image::open(&png).unwrap().to_luma8();
    assert_eq!(img.width(), 200);
    assert_eq!(img.height(), 150);
    // The box top is brighter than the back plane at the corner.
    assert!(img.get_pixel(100, 75)[0] > img.get_pixel(2, 2)[0]);
    let [a, b] = export::write_surface_outputs(&m, dir.path()).unwrap();
    assert!(a.ends_with("surface.ply") && b.ends_with("surface_depth.png"));
    assert_eq!(image::open(&b).unwrap().width(), 640);
    assert!(export::write_ply(&m, &dir.path().join("missing/dir/x.ply")).is_err());
}

fn garbage_value() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -0.1..0.5f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(-f64::INFINITY),
        1 => Just(1e300),
        1 => Just(0.2),
        1 => Just(0.4),
    ]
}

fn garbage_segment() -> impl Strategy<Value = DeviceSegment> {
    prop::array::uniform6(garbage_value()).prop_map(|v| DeviceSegment {
        a_m: [v[0], v[1], v[2]],
        b_m: [v[3], v[4], v[5]],
    })
}

fn grid_segment() -> impl Strategy<Value = DeviceSegment> {
    // Segments on a coarse lattice: many duplicates, shared endpoints, overlaps and crossings.
    (0..9u8, 0..7u8, 0..9u8, 0..7u8, 0..5u8, 0..5u8).prop_map(|(a, b, c, d, za, zb)| {
        DeviceSegment {
            a_m: [
                0.02 + a as f64 * 0.045,
                0.02 + b as f64 * 0.04,
                0.37 + za as f64 * 0.02,
            ],
            b_m: [
                0.02 + c as f64 * 0.045,
                0.02 + d as f64 * 0.04,
                0.37 + zb as f64 * 0.02,
            ],
        }
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, rng_seed: proptest::test_runner::RngSeed::Fixed(3), ..ProptestConfig::default() })]

    /// Garbage in: the build returns a model or an error, never panics; a model's queries never
    /// return NaN and stay within the relief range; the proxy never ends inside.
    #[test]
    fn garbage_never_panics_and_queries_stay_finite(
        segs in prop::collection::vec(prop_oneof![garbage_segment(), grid_segment()], 0..60),
        queries in prop::collection::vec((-0.05..0.45f64, -0.05..0.35f64, 0.3..0.5f64), 1..40),
    ) {
        let p = params();
        if let Ok((m, _)) = build_from_device(&segs, &[], &p) {
            let mut proxy = GodObject::new(ProxyParams { static_friction: 0.3, dynamic_friction: 0.2, ..ProxyParams::default() }).unwrap();
            for (x, y, z) in queries {
                let h = m.height(x, y).unwrap();
                prop_assert!(h.z_m.is_finite() && h.normal.iter().all(|c| c.is_finite()));
                prop_assert!(h.z_m >= BACK_Z - 0.08 - 1e-9 && h.z_m <= BACK_Z + 1e-9);
                prop_assert!(h.normal.z < 0.0);
                if let Some(c) = m.contact(&Vec3::new(x, y, z)) {
                    prop_assert!(c.depth_m.is_finite() && c.depth_m > 0.0);
                }
                let finger = Vec3::new(x, y, z);
                let pc = proxy.update(&m, &finger);
                let under = m.height(pc.proxy_m.x, pc.proxy_m.y).unwrap().z_m;
                prop_assert!(pc.proxy_m.z < under, "proxy {:?} inside (surface {under})", pc.proxy_m);
                prop_assert!(pc.offset_m.iter().all(|c| c.is_finite()));
            }
        }
    }
}

/// Two parallel segments 7 cm apart: a near one (`z = 0.38`) at `x = 0.15`, a far one
/// (`z = 0.43`) at `x = 0.22`, the depth step of an occluding edge in front of a background.
fn occluding_edge(shape: ReliefShape) -> ReliefModel {
    let segs = [
        seg([0.15, 0.05, 0.38], [0.15, 0.25, 0.38]),
        seg([0.22, 0.05, 0.43], [0.22, 0.25, 0.43]),
    ];
    let mut p = params();
    p.shape = shape;
    // 3 mm walls whatever the rise (the default widens a 5 cm step's wall to 12.5 mm).
    p.step_max_wall_slope = 100.0;
    build_from_device(&segs, &[], &p).unwrap().0
}

#[test]
fn a_depth_step_is_kept_as_a_step_at_the_near_edge() {
    let stepped = occluding_edge(ReliefShape::Stepped);
    let ramped = occluding_edge(ReliefShape::Interpolated);
    for y in [0.08, 0.15, 0.22] {
        // On the near segment: its height.
        assert!((stepped.height_at(0.15, y).unwrap().z_m - 0.38).abs() < 1e-9);
        // Past the 3 mm wall, the far height all the way to the far segment.
        for x in [0.154, 0.16, 0.185, 0.21] {
            let z = stepped.height_at(x, y).unwrap().z_m;
            assert!((z - 0.43).abs() < 1e-9, "({x}, {y}): {z}");
        }
        // Inside the wall (at most 3 mm wide, narrower where a triangle's edge crosses it
        // obliquely), in between: the surface is continuous.
        let wall = stepped.height_at(0.1505, y).unwrap().z_m;
        assert!(wall > 0.38 && wall < 0.43, "{wall}");
        // The paper's surface ramps across the gap instead.
        let mid = ramped.height_at(0.185, y).unwrap().z_m;
        assert!((mid - 0.405).abs() < 1e-9, "{mid}");
    }
    // Still a bas-relief: every normal within 90 degrees of -z, no hole.
    assert!(stepped.vertex_normals().iter().all(|n| n[2] < 0.0));
    for k in 0..=200 {
        let x = 0.1 + 0.15 * f64::from(k) / 200.0;
        assert!(stepped
            .height_at(x, 0.15)
            .is_some_and(|h| h.z_m.is_finite()));
    }
}

#[test]
fn a_gentle_slope_is_not_a_step() {
    // 2 cm over 7 cm (a slope of 0.29, below the default 0.5): interpolated as a ramp.
    let segs = [
        seg([0.15, 0.05, 0.40], [0.15, 0.25, 0.40]),
        seg([0.22, 0.05, 0.42], [0.22, 0.25, 0.42]),
    ];
    let (m, _) = build_from_device(&segs, &[], &stepped()).unwrap();
    for y in [0.08, 0.15, 0.22] {
        let mid = m.height_at(0.185, y).unwrap().z_m;
        assert!((mid - 0.41).abs() < 1e-9, "{mid}");
    }
}

#[test]
fn the_area_keeps_the_height_near_its_border_and_only_the_frame_ramps() {
    // A plane of segments at z = 0.40 well inside the area (x 0.1..0.3, y 0.05..0.25).
    let mut segs = square(0.1, 0.05, 0.3, 0.25, 0.40).to_vec();
    segs.push(seg([0.1, 0.05, 0.40], [0.3, 0.25, 0.40]));
    let stepped = build_from_device(&segs, &[], &stepped()).unwrap().0;
    let ramped = build_from_device(&segs, &[], &interpolated()).unwrap().0;
    // Between the segments and the frame's inner edge (5 mm): the plane's height.
    for (x, y) in [
        (0.006, 0.15),
        (0.05, 0.15),
        (0.2, 0.01),
        (0.39, 0.29),
        (0.35, 0.006),
    ] {
        let z = stepped.height_at(x, y).unwrap().z_m;
        assert!((z - 0.40).abs() < 1e-9, "({x}, {y}): {z}");
        assert!(
            ramped.height_at(x, y).unwrap().z_m > 0.40 + 1e-4,
            "({x}, {y})"
        );
    }
    // The frame ramps to the back plane at the area's edge, and beyond is the back plane.
    let frame = stepped.height_at(0.0025, 0.15).unwrap().z_m;
    assert!(frame > 0.40 && frame < BACK_Z, "{frame}");
    assert!((stepped.height_at(0.0, 0.15).unwrap().z_m - BACK_Z).abs() < 1e-12);
    assert!((stepped.height_at(-0.1, 0.15).unwrap().z_m - BACK_Z).abs() < 1e-12);
    assert!(stepped.vertex_normals().iter().all(|n| n[2] < 0.0));
}
