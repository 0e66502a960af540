//! A session's topics in Foxglove's well-known schemas (and a few messages of VIDET's own): the
//! thimble's pose, the wires, the forces, the relief, the tensions, the safety state and the
//! timing of every period. The same topics go to an MCAP file (`mcap_export`) or to the
//! live WebSocket view: whatever sinks the [`foxglove::Context`] has.
//!
//! Everything is in the rig's frame (`rig`: the frame plane at `z = 0`, metres), stamped with the
//! period's start on the service's monotonic clock, nanoseconds.

use std::sync::Arc;

use foxglove::messages::{
    line_primitive, ArrowPrimitive, Color, LinePrimitive, Point3, Pose, PoseInFrame, Quaternion,
    SceneEntity, SceneUpdate, SpherePrimitive, Timestamp, TriangleListPrimitive, Vector3,
};
use foxglove::{Channel, Context};
use videt_config::Config;
use videt_control::safety::SafetyState;
use videt_control::DeviceKind;
use videt_runtime::cycle::CycleRecord;
use videt_runtime::telemetry::{CalibrationInForce, RecordedSurface};
use videt_runtime::WIREMAN_WIRES;

/// The frame every message is in: the rig's (the frame plane at `z = 0`), metres.
pub const FRAME_ID: &str = "rig";

/// Length of a force arrow per newton of force, metres (1 cm per N).
pub const FORCE_ARROW_M_PER_N: f64 = 0.01;

/// Side of the square a flat surface is drawn as, metres.
pub const PLANE_SIDE_M: f64 = 0.6;

/// What the scene needs besides the records: the device and its wire guides (exit points),
/// metres, and the tension range the wires' colours span.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneSetup {
    /// The device (`rig.device`: `wireman3`, `planar2`, `polar1`, `spidar4`).
    pub device: String,
    /// Number of actuated wires.
    pub wires: usize,
    /// Each wire's guide (where it leaves the frame), metres, in the rig's frame.
    pub guides_m: Vec<[f64; 3]>,
    /// The tensions the wires' colour ramp spans, N: blue at the first (`control.t_min_n`), red
    /// at the second (`control.t_max_n`, the device's limit of 15 N by default).
    pub tension_range_n: [f64; 2],
}

impl SceneSetup {
    /// From a configuration and the calibration in force: the WireMan's guides are the
    /// calibration's when there is one (else the configured `rig.guides_m`, in the frame plane);
    /// the planar prototype's (`[x, 0, 0]`), the one-wire device's and the four-wire rig's come
    /// from the configuration's rig section.
    pub fn new(config: &Config, calibration: Option<&CalibrationInForce>) -> SceneSetup {
        let kind = DeviceKind::from_name(&config.rig.device).unwrap_or(DeviceKind::Wireman3);
        let rig = &config.rig;
        let guides_m: Vec<[f64; 3]> = match kind {
            DeviceKind::Wireman3 => match calibration {
                Some(c) if c.guides_m.iter().any(|g| g.iter().any(|v| *v != 0.0)) => {
                    c.guides_m.to_vec()
                }
                _ => rig.guides_m.iter().map(|g| [g[0], g[1], 0.0]).collect(),
            },
            DeviceKind::Planar2 => rig
                .planar_guides_x_m
                .iter()
                .map(|x| [*x, 0.0, 0.0])
                .collect(),
            DeviceKind::Polar1 => vec![rig.polar_guide_m],
            DeviceKind::Spidar4 => rig.spidar_guides_m.to_vec(),
        };
        SceneSetup {
            device: kind.name().to_string(),
            wires: kind.wires(),
            guides_m,
            tension_range_n: [config.control.t_min_n, config.control.t_max_n],
        }
    }

    /// The wires a period's record holds (a record has [`WIREMAN_WIRES`] slots).
    fn logged_wires(&self) -> usize {
        self.wires.min(WIREMAN_WIRES).min(self.guides_m.len())
    }
}

/// `/tension`: every wire's measured tension and set-point, the motor torques, the thimble's
/// velocity and the contact, one message per period. Per-wire fields are arrays with one entry
/// per wire of the device (`measured_n[0]` is wire 0).
#[derive(Debug, Clone, Default, PartialEq, foxglove::Encode)]
pub struct Tension {
    /// Period number.
    pub cycle: u64,
    /// Measured tension per wire, N.
    pub measured_n: Vec<f64>,
    /// Tension set-point per wire, N.
    pub setpoint_n: Vec<f64>,
    /// Motor torque command per wire, N·m (positive winds).
    pub torque_nm: Vec<f64>,
    /// Wire length per wire, m.
    pub length_m: Vec<f64>,
    /// Thimble velocity `[x, y, z]`, m/s.
    pub velocity_m_s: Vec<f64>,
    /// Thimble speed (the velocity's magnitude), m/s.
    pub speed_m_s: f64,
    /// Desired force f_e `[x, y, z]`, N.
    pub desired_force_n: Vec<f64>,
    /// Force the set-points render f `[x, y, z]`, N.
    pub rendered_force_n: Vec<f64>,
    /// |f_e|, N.
    pub desired_force_norm_n: f64,
    /// |f|, N.
    pub rendered_force_norm_n: f64,
    /// In contact with the surface.
    pub in_contact: bool,
    /// Penetration depth, m (0 out of contact).
    pub contact_depth_m: f64,
    /// Force scale of the start/stop ramp and the stale-surface fade, `[0, 1]`.
    pub force_scale: f64,
    /// Version of the surface rendered.
    pub surface_version: u64,
}

/// `/safety`: the safety state, logged for the first period and whenever the state, the
/// released wire or the stale-surface flag changes.
#[derive(Debug, Clone, Default, PartialEq, foxglove::Encode)]
pub struct Safety {
    /// Period number.
    pub cycle: u64,
    /// `normal`, `minimum-tension` or `power-off`.
    pub state: String,
    /// Why, outside normal operation (`e-stop`, `over-tension`, ...); empty when normal.
    pub reason: String,
    /// The wire the reason concerns (-1: none).
    pub reason_wire: i32,
    /// Wire released for replacement (-1: none).
    pub released_wire: i32,
    /// The surface is stale (no new model for longer than allowed): forces fade out.
    pub surface_stale: bool,
    /// The session log cannot be written (a full disk): why; empty while it is written (and in
    /// an export of a log).
    pub session_log_error: String,
}

/// `/timing`: the period's timing, one message per period.
#[derive(Debug, Clone, Default, PartialEq, foxglove::Encode)]
pub struct Timing {
    /// Period number.
    pub cycle: u64,
    /// How late the wake-up was, ns.
    pub wake_latency_ns: u64,
    /// The same, µs.
    pub wake_latency_us: f64,
    /// Wake-up to the end of the period's work, ns.
    pub compute_ns: u64,
    /// The same, µs.
    pub compute_us: f64,
}

/// The topics on one `foxglove::Context` (its sinks: an MCAP file, or the live WebSocket
/// server). The messages are kept between periods and refilled in place.
pub struct SessionTopics {
    setup: SceneSetup,
    pose: Channel<PoseInFrame>,
    wires: Channel<SceneUpdate>,
    forces: Channel<SceneUpdate>,
    relief: Channel<SceneUpdate>,
    tension: Channel<Tension>,
    safety: Channel<Safety>,
    timing: Channel<Timing>,
    pose_msg: PoseInFrame,
    wires_msg: SceneUpdate,
    forces_msg: SceneUpdate,
    tension_msg: Tension,
    timing_msg: Timing,
    last_safety: Option<(SafetyState, i8, bool, bool)>,
    /// The session log's write error, for the live view (empty: written, or an export).
    session_log_error: String,
}

impl SessionTopics {
    /// The topic names, in this order: the thimble's pose, the wires, the forces, the relief,
    /// the tensions, the safety state and the timing.
    pub const TOPICS: &'static [&'static str] = &[
        "/thimble/pose",
        "/scene/wires",
        "/scene/forces",
        "/scene/relief",
        "/tension",
        "/safety",
        "/timing",
    ];

    /// The topics of a session of `setup` on `ctx`.
    pub fn new(ctx: &Arc<Context>, setup: SceneSetup) -> SessionTopics {
        let t = Self::TOPICS;
        let wires = setup.logged_wires();
        let line = |i: usize| LinePrimitive {
            r#type: line_primitive::Type::LineStrip as i32,
            pose: Some(identity_pose()),
            thickness: 3.0,
            scale_invariant: true,
            points: vec![point(setup.guides_m[i]), point([0.0; 3])],
            color: Some(tension_colour(0.0, setup.tension_range_n)),
            ..Default::default()
        };
        // The thimble; the guides are where the lines start (static spheres for them would
        // double the message).
        let thimble = SpherePrimitive {
            pose: Some(identity_pose()),
            size: Some(Vector3 {
                x: 0.016,
                y: 0.016,
                z: 0.016,
            }),
            color: Some(rgba(1.0, 0.85, 0.2, 1.0)),
        };
        let wires_msg = SceneUpdate {
            deletions: Vec::new(),
            entities: vec![SceneEntity {
                frame_id: FRAME_ID.into(),
                id: "wires".into(),
                lines: (0..wires).map(line).collect(),
                spheres: vec![thimble],
                ..Default::default()
            }],
        };
        let forces_msg = SceneUpdate {
            deletions: Vec::new(),
            entities: vec![SceneEntity {
                frame_id: FRAME_ID.into(),
                id: "forces".into(),
                ..Default::default()
            }],
        };
        let tension_msg = Tension {
            measured_n: Vec::with_capacity(WIREMAN_WIRES),
            setpoint_n: Vec::with_capacity(WIREMAN_WIRES),
            torque_nm: Vec::with_capacity(WIREMAN_WIRES),
            length_m: Vec::with_capacity(WIREMAN_WIRES),
            velocity_m_s: Vec::with_capacity(3),
            desired_force_n: Vec::with_capacity(3),
            rendered_force_n: Vec::with_capacity(3),
            ..Default::default()
        };
        SessionTopics {
            pose: ctx.channel_builder(t[0]).build(),
            wires: ctx.channel_builder(t[1]).build(),
            forces: ctx.channel_builder(t[2]).build(),
            relief: ctx.channel_builder(t[3]).build(),
            tension: ctx.channel_builder(t[4]).build(),
            safety: ctx.channel_builder(t[5]).build(),
            timing: ctx.channel_builder(t[6]).build(),
            pose_msg: PoseInFrame {
                timestamp: None,
                frame_id: FRAME_ID.into(),
                pose: Some(identity_pose()),
            },
            wires_msg,
            forces_msg,
            tension_msg,
            timing_msg: Timing::default(),
            last_safety: None,
            session_log_error: String::new(),
            setup,
        }
    }

    /// The scene this session draws.
    pub fn setup(&self) -> &SceneSetup {
        &self.setup
    }

    /// One period's messages, stamped with the record's time (`record.time`, the log's
    /// monotonic clock, as ns): pose, wires, forces, tensions, timing; and a safety message when
    /// the safety state (or the released wire, or the stale-surface flag) changed since the
    /// last logged period, and for the first one. Returns the number of messages logged (with a
    /// sink on every topic; a topic without one skips building its message).
    pub fn log_period(&mut self, record: &CycleRecord) -> usize {
        let ns = record.time.as_nanos();
        let stamp = Some(timestamp(ns));
        let at = record.position_m;
        let wires = self.setup.logged_wires();
        let mut logged = 0;

        if self.pose.has_sinks() {
            self.pose_msg.timestamp = stamp;
            if let Some(p) = &mut self.pose_msg.pose {
                p.position = Some(vector(at));
            }
            self.pose.log_with_time(&self.pose_msg, ns);
        }
        logged += 1;

        if self.wires.has_sinks() {
            let range = self.setup.tension_range_n;
            let entity = &mut self.wires_msg.entities[0];
            entity.timestamp = stamp;
            for (w, line) in entity.lines.iter_mut().enumerate() {
                if let Some(end) = line.points.get_mut(1) {
                    *end = point(at);
                }
                line.color = Some(tension_colour(record.tension_measured_n[w], range));
            }
            if let Some(thimble) = entity.spheres.last_mut() {
                thimble.pose = Some(pose_at(at));
            }
            self.wires.log_with_time(&self.wires_msg, ns);
        }
        logged += 1;

        if self.forces.has_sinks() {
            let entity = &mut self.forces_msg.entities[0];
            entity.timestamp = stamp;
            entity.arrows.clear();
            let desired = rgba(0.2, 0.8, 0.3, 0.9);
            let rendered = rgba(1.0, 0.45, 0.1, 0.9);
            for (force, color) in [
                (record.desired_force_n, desired),
                (record.rendered_force_n, rendered),
            ] {
                if let Some(arrow) = force_arrow(at, force, color) {
                    entity.arrows.push(arrow);
                }
            }
            self.forces.log_with_time(&self.forces_msg, ns);
        }
        logged += 1;

        if self.tension.has_sinks() {
            let m = &mut self.tension_msg;
            m.cycle = record.cycle;
            let fill = |v: &mut Vec<f64>, from: &[f64]| {
                v.clear();
                v.extend_from_slice(from);
            };
            fill(&mut m.measured_n, &record.tension_measured_n[..wires]);
            fill(&mut m.setpoint_n, &record.tension_setpoint_n[..wires]);
            fill(&mut m.torque_nm, &record.torque_nm[..wires]);
            fill(&mut m.length_m, &record.lengths_m[..wires]);
            fill(&mut m.velocity_m_s, &record.velocity_m_s);
            fill(&mut m.desired_force_n, &record.desired_force_n);
            fill(&mut m.rendered_force_n, &record.rendered_force_n);
            m.speed_m_s = norm(record.velocity_m_s);
            m.desired_force_norm_n = norm(record.desired_force_n);
            m.rendered_force_norm_n = norm(record.rendered_force_n);
            m.in_contact = record.in_contact;
            m.contact_depth_m = record.contact_depth_m;
            m.force_scale = record.force_scale;
            m.surface_version = record.surface_version;
            self.tension.log_with_time(&self.tension_msg, ns);
        }
        logged += 1;

        logged += usize::from(self.log_safety_change(record));

        if self.timing.has_sinks() {
            self.timing_msg = Timing {
                cycle: record.cycle,
                wake_latency_ns: record.wake_latency_ns,
                wake_latency_us: record.wake_latency_ns as f64 * 1e-3,
                compute_ns: record.compute_ns,
                compute_us: record.compute_ns as f64 * 1e-3,
            };
            self.timing.log_with_time(&self.timing_msg, ns);
        }
        logged += 1;
        logged
    }

    /// The safety message alone, when the safety state, the released wire or the stale-surface
    /// flag differs from the last one logged (or none was): an export that skips periods still
    /// logs every change. Returns whether it logged.
    pub fn log_safety_change(&mut self, record: &CycleRecord) -> bool {
        let safety = (
            record.safety,
            record.released_wire,
            record.surface_stale,
            !self.session_log_error.is_empty(),
        );
        if self.last_safety == Some(safety) {
            return false;
        }
        self.last_safety = Some(safety);
        let state = match record.safety {
            SafetyState::Normal => "normal",
            SafetyState::MinimumTension(_) => "minimum-tension",
            SafetyState::PowerOff(_) => "power-off",
        };
        let reason = record.safety.reason();
        self.safety.log_with_time(
            &Safety {
                cycle: record.cycle,
                state: state.into(),
                reason: reason.map(|r| r.as_str()).unwrap_or("").into(),
                reason_wire: reason.and_then(|r| r.wire()).map_or(-1, i32::from),
                released_wire: i32::from(record.released_wire),
                surface_stale: record.surface_stale,
                session_log_error: self.session_log_error.clone(),
            },
            record.time.as_nanos(),
        );
        true
    }

    /// Draw the wires from the guides of `setup` from now on: a re-initialization measured the
    /// WireMan's base triangle anew (the wires' lines start there; no new channel).
    pub fn set_guides(&mut self, setup: &SceneSetup) {
        let n = self.setup.logged_wires().min(setup.guides_m.len());
        self.setup.guides_m[..n].copy_from_slice(&setup.guides_m[..n]);
        let entity = &mut self.wires_msg.entities[0];
        for (line, guide) in entity.lines.iter_mut().zip(&setup.guides_m[..n]) {
            if let Some(start) = line.points.get_mut(0) {
                *start = point(*guide);
            }
        }
    }

    /// The session log's write error now (`None`: written): the next safety message carries
    /// it, and a change logs one (the live view).
    pub fn set_session_log_error(&mut self, error: Option<String>) {
        self.session_log_error = error.unwrap_or_default();
    }

    /// Forget the safety state last logged: the next period logs it again (a live view repeats
    /// the latched state for clients that subscribed after it changed).
    pub fn forget_logged_safety(&mut self) {
        self.last_safety = None;
    }

    /// A surface version (the relief as a triangle mesh coloured by depth; a plane as a
    /// [`PLANE_SIDE_M`] square about its point), stamped `time_ns`. The entity replaces the
    /// previous version's.
    pub fn log_surface(&mut self, version: u64, surface: &RecordedSurface, time_ns: u64) {
        let triangles = surface_triangles(surface);
        let kind = match surface {
            RecordedSurface::Plane(_) => "plane",
            RecordedSurface::Relief(_) => "relief",
        };
        let update = SceneUpdate {
            deletions: Vec::new(),
            entities: vec![SceneEntity {
                timestamp: Some(timestamp(time_ns)),
                frame_id: FRAME_ID.into(),
                id: "surface".into(),
                metadata: vec![
                    foxglove::messages::KeyValuePair {
                        key: "version".into(),
                        value: version.to_string(),
                    },
                    foxglove::messages::KeyValuePair {
                        key: "kind".into(),
                        value: kind.into(),
                    },
                ],
                triangles: vec![triangles],
                ..Default::default()
            }],
        };
        self.relief.log_with_time(&update, time_ns);
    }
}

/// The triangle list `/scene/relief` draws a surface as.
pub fn surface_triangles(surface: &RecordedSurface) -> TriangleListPrimitive {
    match surface {
        RecordedSurface::Plane(plane) => {
            let p = plane.point_m();
            let n = plane.normal();
            // Two unit tangents of the plane.
            let helper = if n.x.abs() < 0.9 {
                videt_control::Vec3::x()
            } else {
                videt_control::Vec3::y()
            };
            let u = n.cross(&helper).normalize() * (PLANE_SIDE_M / 2.0);
            let v = n.cross(&u);
            let corner = |a: f64, b: f64| {
                let c = p + u * a + v * b;
                point([c.x, c.y, c.z])
            };
            TriangleListPrimitive {
                pose: Some(identity_pose()),
                points: vec![
                    corner(-1.0, -1.0),
                    corner(1.0, -1.0),
                    corner(1.0, 1.0),
                    corner(-1.0, 1.0),
                ],
                color: Some(rgba(0.55, 0.6, 0.7, 0.6)),
                colors: Vec::new(),
                indices: vec![0, 1, 2, 0, 2, 3],
            }
        }
        RecordedSurface::Relief(model) => {
            let vertices = model.vertices();
            let (lo, hi) = vertices
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(v[2]), hi.max(v[2]))
                });
            let span = (hi - lo).max(1e-9);
            TriangleListPrimitive {
                pose: Some(identity_pose()),
                points: vertices.iter().map(|v| point(*v)).collect(),
                color: Some(rgba(0.7, 0.7, 0.7, 0.9)),
                // Nearer the frame (smaller z) lighter: the relief reads without lighting.
                colors: vertices
                    .iter()
                    .map(|v| {
                        let s = 1.0 - (v[2] - lo) / span;
                        rgba(0.25 + 0.65 * s, 0.3 + 0.6 * s, 0.4 + 0.5 * s, 0.9)
                    })
                    .collect(),
                indices: model.triangles().iter().flatten().copied().collect(),
            }
        }
    }
}

/// An arrow from `at` along `force_n`, [`FORCE_ARROW_M_PER_N`] long per newton (`None` for a
/// force too small to draw).
fn force_arrow(at: [f64; 3], force_n: [f64; 3], color: Color) -> Option<ArrowPrimitive> {
    let magnitude = norm(force_n);
    if !magnitude.is_finite() || magnitude * FORCE_ARROW_M_PER_N < 1e-4 {
        return None;
    }
    let length = magnitude * FORCE_ARROW_M_PER_N;
    let head = (0.25 * length).min(0.012);
    let dir = force_n.map(|c| c / magnitude);
    Some(ArrowPrimitive {
        pose: Some(Pose {
            position: Some(vector(at)),
            orientation: Some(x_to(dir)),
        }),
        shaft_length: length - head,
        shaft_diameter: 0.003,
        head_length: head,
        head_diameter: 0.008,
        color: Some(color),
    })
}

/// The rotation taking the x axis to the unit vector `d`.
fn x_to(d: [f64; 3]) -> Quaternion {
    // Half-way vector between x and d: q = (x × d, 1 + x·d), normalised.
    let w = 1.0 + d[0];
    if w < 1e-9 {
        // d = -x: half a turn about z.
        return Quaternion {
            x: 0.0,
            y: 0.0,
            z: 1.0,
            w: 0.0,
        };
    }
    let (x, y, z) = (0.0, -d[2], d[1]);
    let n = (x * x + y * y + z * z + w * w).sqrt();
    Quaternion {
        x: x / n,
        y: y / n,
        z: z / n,
        w: w / n,
    }
}

/// The colour of a wire at `tension_n`: blue at the range's low end, red at its high end.
pub fn tension_colour(tension_n: f64, range_n: [f64; 2]) -> Color {
    let [lo, hi] = range_n;
    let s = if hi > lo && tension_n.is_finite() {
        ((tension_n - lo) / (hi - lo)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    rgba(s, 0.15 * (1.0 - (2.0 * s - 1.0).abs()), 1.0 - s, 1.0)
}

fn rgba(r: f64, g: f64, b: f64, a: f64) -> Color {
    Color { r, g, b, a }
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn point(p: [f64; 3]) -> Point3 {
    Point3 {
        x: p[0],
        y: p[1],
        z: p[2],
    }
}

fn vector(p: [f64; 3]) -> Vector3 {
    Vector3 {
        x: p[0],
        y: p[1],
        z: p[2],
    }
}

fn identity_pose() -> Pose {
    pose_at([0.0; 3])
}

fn pose_at(p: [f64; 3]) -> Pose {
    Pose {
        position: Some(vector(p)),
        orientation: Some(Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }),
    }
}

/// A monotonic time in ns as a protobuf timestamp.
pub(crate) fn timestamp(ns: u64) -> Timestamp {
    let sec = (ns / 1_000_000_000).min(u64::from(u32::MAX)) as u32;
    Timestamp::new(sec, (ns % 1_000_000_000) as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_guides_move_where_the_wires_start_and_nothing_else() {
        let config = Config::default();
        let mut topics = SessionTopics::new(&Context::new(), SceneSetup::new(&config, None));
        let mut moved = SceneSetup::new(&config, None);
        moved.guides_m = vec![[0.01, 0.02, 0.0], [0.4, 0.01, 0.0], [0.2, 0.33, 0.0]];
        topics.set_guides(&moved);
        assert_eq!(topics.setup().guides_m, moved.guides_m);
        let entity = &topics.wires_msg.entities[0];
        for (w, line) in entity.lines.iter().enumerate() {
            let p = &line.points[0];
            assert_eq!([p.x, p.y, p.z], moved.guides_m[w]);
        }
        let thimble = entity.spheres[entity.spheres.len() - 1]
            .pose
            .as_ref()
            .unwrap()
            .position
            .unwrap();
        assert_eq!(
            [thimble.x, thimble.y, thimble.z],
            [0.0; 3],
            "the thimble stays"
        );
    }

    fn rotate(q: &Quaternion, v: [f64; 3]) -> [f64; 3] {
        // v' = v + 2 w (u × v) + 2 u × (u × v)
        let u = [q.x, q.y, q.z];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let t = cross(u, v).map(|c| 2.0 * c);
        let ut = cross(u, t);
        [0, 1, 2].map(|i| v[i] + q.w * t[i] + ut[i])
    }

    #[test]
    fn an_arrow_points_along_its_force_and_is_a_centimetre_per_newton() {
        for f in [
            [3.0, 0.0, 0.0],
            [-2.0, 0.0, 0.0],
            [0.0, 0.0, -4.0],
            [1.0, -2.0, 0.5],
        ] {
            let a = force_arrow([0.1, 0.2, 0.3], f, rgba(1.0, 0.0, 0.0, 1.0)).unwrap();
            let n = norm(f);
            assert!((a.shaft_length + a.head_length - n * 0.01).abs() < 1e-12);
            let q = a.pose.unwrap().orientation.unwrap();
            let d = rotate(&q, [1.0, 0.0, 0.0]);
            for i in 0..3 {
                assert!((d[i] - f[i] / n).abs() < 1e-9, "{f:?} -> {d:?}");
            }
        }
        assert!(force_arrow([0.0; 3], [0.0; 3], rgba(0.0, 0.0, 0.0, 1.0)).is_none());
        assert!(force_arrow([0.0; 3], [f64::NAN, 0.0, 0.0], rgba(0.0, 0.0, 0.0, 1.0)).is_none());
    }

    #[test]
    fn the_tension_ramp_runs_from_blue_at_t_min_to_red_at_t_max() {
        let range = [0.3, 15.0];
        let low = tension_colour(0.0, range);
        let high = tension_colour(20.0, range);
        assert_eq!((low.r, low.b), (0.0, 1.0));
        assert_eq!((high.r, high.b), (1.0, 0.0));
        let mid = tension_colour(7.65, range);
        assert!((mid.r - 0.5).abs() < 1e-9);
        assert_eq!(tension_colour(f64::NAN, range).b, 1.0);
    }

    #[test]
    fn the_guides_come_from_the_calibration_for_the_wireman_and_the_rig_section_otherwise() {
        let mut config = Config::default();
        let s = SceneSetup::new(&config, None);
        assert_eq!((s.device.as_str(), s.wires), ("wireman3", 3));
        assert_eq!(s.guides_m[1], [0.37, 0.0, 0.0]);
        assert_eq!(s.tension_range_n, [0.3, 15.0]);
        let calibration = CalibrationInForce {
            guides_m: [[0.0; 3], [0.4, 0.0, 0.01], [0.2, 0.3, 0.0]],
            ..Default::default()
        };
        let s = SceneSetup::new(&config, Some(&calibration));
        assert_eq!(s.guides_m[1], [0.4, 0.0, 0.01]);
        config.rig.device = "planar2".into();
        let s = SceneSetup::new(&config, Some(&calibration));
        assert_eq!(s.wires, 2);
        assert_eq!(s.guides_m, vec![[0.0; 3], [0.52, 0.0, 0.0]]);
        config.rig.device = "polar1".into();
        config.rig.polar_guide_m = [0.1, 0.2, 0.0];
        let s = SceneSetup::new(&config, None);
        assert_eq!((s.wires, s.guides_m.clone()), (1, vec![[0.1, 0.2, 0.0]]));
    }

    #[test]
    fn a_session_log_that_cannot_be_written_is_a_safety_message_of_its_own() {
        let config = Config::default();
        let mut topics = SessionTopics::new(&Context::new(), SceneSetup::new(&config, None));
        let record = CycleRecord::default();
        assert!(topics.log_safety_change(&record), "the first period logs");
        assert!(!topics.log_safety_change(&record));
        topics.set_session_log_error(Some("No space left on device".into()));
        assert!(topics.log_safety_change(&record), "the failure logs");
        assert!(!topics.log_safety_change(&record));
        topics.set_session_log_error(None);
        assert!(topics.log_safety_change(&record), "the recovery logs");
    }

    #[test]
    fn the_topics_are_the_documented_ones() {
        let ctx = Context::new();
        let topics = SessionTopics::new(&ctx, SceneSetup::new(&Config::default(), None));
        for t in SessionTopics::TOPICS {
            assert!(ctx.get_channel_by_topic(t).is_some(), "{t}");
        }
        let schema = |t: &str| {
            ctx.get_channel_by_topic(t)
                .and_then(|c| c.schema().map(|s| s.name.clone()))
                .unwrap()
        };
        assert_eq!(schema("/thimble/pose"), "foxglove.PoseInFrame");
        assert_eq!(schema("/scene/wires"), "foxglove.SceneUpdate");
        assert_eq!(schema("/tension"), "tension.Tension");
        assert_eq!(topics.setup().wires, 3);
    }
}
