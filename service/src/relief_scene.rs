//! The twin's bas-relief demonstrations, in front of the configured rig: a box on a back plane,
//! built from known segments with the real surface builder, and a virtual operator who presses
//! onto the box top, slides off its edge down onto the base and climbs back; and, for any relief
//! (the one of a real stereo pair), an operator who presses into it and sweeps across it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use videt_config::Config;
use videt_control::blend::BlendParams;
use videt_control::proxy::ProxyParams;
use videt_relief::{
    build_from_device, BuildError, BuildReport, DeviceSegment, ReliefLayout, ReliefModel,
    ReliefShape,
};
use videt_runtime::snapshot::SnapshotWriter;
use videt_sim::{Vec3, VirtualOperator, Waypoint};

/// How the sweeping operator explores a relief.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepPath {
    /// Half the width of each sweep along `x`, about the area's centre, metres.
    pub half_width_m: f64,
    /// `y` offsets of the two sweeps from the area's centre, metres (the first goes towards
    /// `+x`, the second comes back).
    pub rows_m: [f64; 2],
    /// How far the hand aims beyond the surface (into the solid), metres: with the hand's
    /// 200 N/m it presses with about this times 200 N.
    pub press_m: f64,
    /// Sliding speed, m/s.
    pub speed_m_s: f64,
    /// Height above the surface the hand approaches and leaves at, metres.
    pub clearance_m: f64,
    /// Spacing of the hand's waypoints along the sweeps (they follow the surface), metres.
    pub step_m: f64,
    /// Steepest the hand's path rises or falls, height per distance slid (> 0).
    pub max_slope: f64,
}

impl SweepPath {
    /// The default path with both sweeps along the area's centre line: for the planar device,
    /// whose thimble moves in the `x`-`z` plane through it.
    pub fn along_centre_line() -> SweepPath {
        SweepPath {
            rows_m: [0.0, 0.0],
            ..SweepPath::default()
        }
    }
}

impl Default for SweepPath {
    /// Two 14 cm sweeps 4.5 cm apart, pressing 1 cm deep at 5 cm/s, waypoints every 4 mm, the
    /// hand's path no steeper than 1:1.
    fn default() -> Self {
        SweepPath {
            half_width_m: 0.07,
            rows_m: [0.03, -0.015],
            press_m: 0.01,
            speed_m_s: 0.05,
            clearance_m: 0.01,
            step_m: 0.004,
            max_slope: 1.0,
        }
    }
}

/// The box's vision thread: the box over `layout` rebuilt every second and published to
/// `writer`, nothing while `stall` is set (`sim-fault vision-stall`, a stalled camera), at the
/// vision thread's `priority`. It runs as long as the process.
pub fn spawn_box_rebuilds(
    layout: ReliefLayout,
    mut writer: SnapshotWriter<ReliefModel>,
    stall: Arc<AtomicBool>,
    priority: Option<u8>,
) -> std::io::Result<()> {
    std::thread::Builder::new()
        .name("videt-vision".into())
        .spawn(move || {
            videt_runtime::rt::enter_vision_priority(priority);
            loop {
                std::thread::sleep(std::time::Duration::from_secs(1));
                if stall.load(Ordering::Relaxed) {
                    continue;
                }
                match box_relief(&layout, 0.0) {
                    Ok((model, _)) => {
                        writer.publish(model);
                    }
                    Err(e) => tracing::warn!("surface rebuild failed: {e}"),
                }
            }
        })
        .map(|_| ())
}

/// The demo box's segments (device coordinates), centred on the area: a 5 x 5 cm top at
/// `z = 0.335 - lift_m` and a 9 x 9 cm base outline at `z = 0.352`.
pub fn box_segments(layout: &ReliefLayout, lift_m: f64) -> Vec<DeviceSegment> {
    let [cx, cy] = layout.centre_m;
    let square = |half: f64, z: f64| {
        let c = [
            [cx - half, cy - half],
            [cx + half, cy - half],
            [cx + half, cy + half],
            [cx - half, cy + half],
        ];
        (0..4)
            .map(|k| DeviceSegment {
                a_m: [c[k][0], c[k][1], z],
                b_m: [c[(k + 1) % 4][0], c[(k + 1) % 4][1], z],
            })
            .collect::<Vec<_>>()
    };
    let mut segs = square(0.025, 0.335 - lift_m);
    segs.extend(square(0.045, 0.352));
    segs
}

/// Build the demo box relief. Its segments are the outlines of a frustum's top and base, whose
/// sides are slopes by design: it is built with the paper's interpolated shape, which spans
/// them as the ramps they are (the stepped shape would read them as the depth steps of an
/// occluding edge).
pub fn box_relief(
    layout: &ReliefLayout,
    lift_m: f64,
) -> Result<(ReliefModel, BuildReport), BuildError> {
    let mut params = layout
        .params([640, 480], [0.5, 5.0])
        .map_err(BuildError::Triangulation)?;
    params.shape = ReliefShape::Interpolated;
    build_from_device(&box_segments(layout, lift_m), &[], &params)
}

/// Proxy settings of the demo: light friction.
pub fn proxy_params() -> ProxyParams {
    ProxyParams {
        static_friction: 0.2,
        dynamic_friction: 0.15,
        ..ProxyParams::default()
    }
}

/// Blend settings of the demo: at least 0.1 s, at most 0.05 N per period from a swap.
pub fn blend_params(config: &Config) -> BlendParams {
    BlendParams {
        blend_time_s: 0.1,
        max_step_n: 0.05,
        stale_after_s: config.vision.surface_max_age_s.max(1e-3),
        fade_time_s: config.vision.surface_fade_s.max(1e-3),
    }
}

/// A virtual operator starting at `start_m` who presses onto the box top (aiming at the back
/// plane), slides 8 cm along `x` off the box's edge onto the base, and climbs back, every
/// `period_s` seconds (at least 5).
pub fn box_operator(layout: &ReliefLayout, start_m: Vec3, period_s: f64) -> VirtualOperator {
    let [cx, cy] = layout.centre_m;
    let press = Vec3::new(cx, cy, layout.back_plane_z_m);
    let wp = |time_s: f64, target_m: Vec3| Waypoint { time_s, target_m };
    VirtualOperator::new(
        vec![
            wp(0.0, start_m),
            wp(0.8, press),
            wp(2.3, press + Vec3::new(0.08, 0.0, 0.0)),
            wp(3.8, press),
            wp(4.5, press),
            wp(5.0, start_m),
        ],
        200.0,
        6.0,
    )
    .repeating(period_s.max(5.0))
}

/// A virtual operator starting at `start_m` who explores `model`: approaches the surface above
/// the first sweep's start, presses into it, slides across the area along `x`, moves over to the
/// second row, slides back, lifts off and returns to the start; the script repeats. The hand's
/// waypoints follow the relief (each aims `press_m` beyond the surface under it), so the finger
/// stays in contact over hills and hollows; like a person feeling their way, the hand rises
/// ahead of a step up and comes down after a step down no steeper than `max_slope` (height per
/// distance slid), so the finger meets the relief's steep faces at a moderate speed. Returns the
/// operator and the script's period, seconds.
pub fn sweep_operator(
    layout: &ReliefLayout,
    model: &ReliefModel,
    start_m: Vec3,
    path: &SweepPath,
) -> (VirtualOperator, f64) {
    let [cx, cy] = layout.centre_m;
    let surface_z = |x: f64, y: f64| {
        model
            .height_at(x, y)
            .map_or(layout.back_plane_z_m, |s| s.z_m)
    };
    let speed = path.speed_m_s.max(1e-3);
    let step = path.step_m.max(1e-4);
    let (x0, x1) = (cx - path.half_width_m, cx + path.half_width_m);
    let (y0, y1) = (cy + path.rows_m[0], cy + path.rows_m[1]);
    // The slide's samples (x, y, time to reach from the previous one), then the hand's depth.
    let mut samples: Vec<(f64, f64, f64)> = vec![(x0, y0, 0.0)];
    for (from, to) in [
        ([x0, y0], [x1, y0]),
        ([x1, y0], [x1, y1]),
        ([x1, y1], [x0, y1]),
    ] {
        let length = (to[0] - from[0]).hypot(to[1] - from[1]);
        let n = ((length / step).ceil() as usize).clamp(1, 10_000);
        for k in 1..=n {
            let s = k as f64 / n as f64;
            samples.push((
                from[0] + s * (to[0] - from[0]),
                from[1] + s * (to[1] - from[1]),
                length / n as f64 / speed,
            ));
        }
    }
    let mut z: Vec<f64> = samples
        .iter()
        .map(|&(x, y, _)| surface_z(x, y) + path.press_m)
        .collect();
    // Nearer to the user (smaller z) wins: rise ahead of steps up, come down after steps down.
    let slope = path.max_slope.max(0.05);
    for i in 1..z.len() {
        let run = (samples[i].0 - samples[i - 1].0).hypot(samples[i].1 - samples[i - 1].1);
        z[i] = z[i].min(z[i - 1] + slope * run);
    }
    for i in (0..z.len().saturating_sub(1)).rev() {
        let run = (samples[i].0 - samples[i + 1].0).hypot(samples[i].1 - samples[i + 1].1);
        z[i] = z[i].min(z[i + 1] + slope * run);
    }
    let mut waypoints = vec![Waypoint {
        time_s: 0.0,
        target_m: start_m,
    }];
    let mut t = 0.8;
    let first = Vec3::new(x0, y0, surface_z(x0, y0) - path.clearance_m);
    waypoints.push(Waypoint {
        time_s: t,
        target_m: first,
    });
    t += 0.4;
    for (&(x, y, dt), &z) in samples.iter().zip(&z) {
        t += dt;
        waypoints.push(Waypoint {
            time_s: t,
            target_m: Vec3::new(x, y, z),
        });
    }
    t += 0.4;
    waypoints.push(Waypoint {
        time_s: t,
        target_m: Vec3::new(x0, y1, surface_z(x0, y1) - path.clearance_m),
    });
    let period_s = t + 1.0;
    let operator = VirtualOperator::new(waypoints, 200.0, 6.0).repeating(period_s);
    (operator, period_s)
}
