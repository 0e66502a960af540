//! What the finger feels, on every device and with every algorithm (`docs/felt-force.md`):
//!
//! - the felt bound: the rendered force never exceeds what was asked (`f_e` plus the field or
//!   the free-space pull) by more than the floor's own pull and the margin;
//! - continuity: nearby poses and forces give nearby set-points, also across the places where a
//!   projection used to switch (a wire turning across the normal, the border of the reachable
//!   set, a force shrinking to zero from different directions, the onset of a contact).
//!
//! Over the workspaces of the three-wire WireMan, the planar prototype, the one-wire device and
//! the four-wire rig, forces from 0 to 20 N in every direction.

use proptest::prelude::*;
use videt_control::{
    Algorithm, ForceField, ForceLimits, ForceSettings, PlanarDevice, PolarDevice, Rig3, Rig4, Vec3,
    WireDevice, FELT_MARGIN_N,
};

/// The settings of `algorithm`: with `pull`, the field algorithms' 1 N field and the 0.5 N
/// free-space pull; without, the paper's bare projections (no field, no pull).
fn settings(algorithm: Algorithm, pull: bool) -> ForceSettings {
    let field = if pull && matches!(algorithm, Algorithm::F1 | Algorithm::F2 | Algorithm::Qp) {
        ForceField::towards_frame(1.0)
    } else {
        ForceField::none()
    };
    ForceSettings {
        algorithm,
        limits: ForceLimits::default(),
        field,
        free_space_field_n: if pull { 0.5 } else { 0.0 },
    }
}

/// Set-points (padded to four) and the rendered force, the field and the floor's pull.
struct Rendered {
    tensions_n: [f64; 4],
    rendered_n: Vec3,
    field_n: Vec3,
    floor_pull_n: f64,
}

fn render<const N: usize, D: WireDevice<N>>(
    device: &D,
    position_m: &Vec3,
    desired_n: &Vec3,
    in_contact: bool,
    algorithm: Algorithm,
    pull: bool,
) -> Option<Rendered> {
    let s = settings(algorithm, pull);
    let p = device.constrain(position_m);
    let f = device.constrain(desired_n);
    let out = device.forces(&p, &f, in_contact, 1.0, &s)?;
    let mut tensions_n = [0.0; 4];
    tensions_n[..N].copy_from_slice(&out.tensions.tensions_n);
    Some(Rendered {
        tensions_n,
        rendered_n: out.tensions.rendered_n,
        field_n: out.field_force_n,
        floor_pull_n: device.force_of(&p, &[s.limits.t_min_n; N]).norm(),
    })
}

/// The bound at one input, with every algorithm.
fn check_bound<const N: usize, D: WireDevice<N>>(
    device: &D,
    p: &Vec3,
    f: &Vec3,
    in_contact: bool,
    pull: bool,
) -> Result<(), TestCaseError> {
    for algorithm in Algorithm::ALL {
        let Some(r) = render(device, p, f, in_contact, algorithm, pull) else {
            continue;
        };
        let asked = device.constrain(f).norm();
        let allowed = asked + r.field_n.norm() + r.floor_pull_n + FELT_MARGIN_N;
        prop_assert!(
            r.rendered_n.norm() <= allowed + 1e-9,
            "{:?} {algorithm:?} at {p:?}, f {f:?}: |f| {} > {allowed} (tensions {:?})",
            D::KIND,
            r.rendered_n.norm(),
            r.tensions_n
        );
        prop_assert!(r.tensions_n[..N].iter().all(|&t| (0.3..=15.0).contains(&t)));
    }
    Ok(())
}

/// Largest tension difference between two inputs, with every algorithm.
fn check_close<const N: usize, D: WireDevice<N>>(
    device: &D,
    a: (&Vec3, &Vec3, bool),
    b: (&Vec3, &Vec3, bool),
    tolerance_n: f64,
    pull: bool,
) -> Result<(), TestCaseError> {
    for algorithm in Algorithm::ALL {
        let (Some(ra), Some(rb)) = (
            render(device, a.0, a.1, a.2, algorithm, pull),
            render(device, b.0, b.1, b.2, algorithm, pull),
        ) else {
            continue;
        };
        let step = (0..N)
            .map(|i| (ra.tensions_n[i] - rb.tensions_n[i]).abs())
            .fold(0.0, f64::max);
        prop_assert!(
            step <= tolerance_n,
            "{:?} {algorithm:?}: set-points {:?} -> {:?} between {a:?} and {b:?}",
            D::KIND,
            &ra.tensions_n[..N],
            &rb.tensions_n[..N]
        );
    }
    Ok(())
}

/// A force of magnitude `10^exponent` (0 below -4) along the direction of `d`.
fn force(d: [f64; 3], exponent: f64) -> Vec3 {
    let v = Vec3::from(d);
    if v.norm() < 1e-3 || exponent < -4.0 {
        return Vec3::zeros();
    }
    v.normalize() * 10f64.powf(exponent)
}

/// The position of each device's workspace for a point of the unit cube.
fn workspace(kind: usize, u: [f64; 3]) -> Vec3 {
    match kind {
        // WireMan: over and around the guide triangle, in front of the frame.
        0 => Vec3::new(-0.1 + 0.55 * u[0], -0.1 + 0.5 * u[1], 0.08 + 0.42 * u[2]),
        // Planar prototype: the x-z plane in front of its guides.
        1 => Vec3::new(-0.1 + 0.72 * u[0], 0.0, 0.08 + 0.42 * u[2]),
        // One wire: anywhere 0.1-0.6 m from the guide.
        2 => {
            let d = Vec3::new(u[0] - 0.5, u[1] - 0.5, u[2] - 0.3);
            let d = if d.norm() < 1e-3 {
                Vec3::z()
            } else {
                d.normalize()
            };
            d * (0.1 + 0.5 * u[2])
        }
        // Four wires: inside the cube frame, away from its faces.
        _ => Vec3::new(-0.05 + 0.5 * u[0], -0.1 + 0.5 * u[1], 0.05 + 0.5 * u[2]),
    }
}

/// A check generic over the device, called once per device kind.
trait DeviceCheck {
    fn run<const N: usize, D: WireDevice<N>>(&mut self, device: &D) -> Result<(), TestCaseError>;
}

fn on_device(kind: usize, check: &mut impl DeviceCheck) -> Result<(), TestCaseError> {
    match kind {
        0 => check.run(&Rig3::paper_frame()),
        1 => check.run(&PlanarDevice::paper_prototype()),
        2 => check.run(&PolarDevice::at_origin()),
        _ => check.run(&Rig4::cube_frame()),
    }
}

struct Bound {
    p: Vec3,
    f: Vec3,
    in_contact: bool,
    pull: bool,
}

impl DeviceCheck for Bound {
    fn run<const N: usize, D: WireDevice<N>>(&mut self, device: &D) -> Result<(), TestCaseError> {
        check_bound(device, &self.p, &self.f, self.in_contact, self.pull)
    }
}

struct Nearby {
    a: (Vec3, Vec3, bool),
    b: (Vec3, Vec3, bool),
    tolerance_n: f64,
    pull: bool,
}

impl DeviceCheck for Nearby {
    fn run<const N: usize, D: WireDevice<N>>(&mut self, device: &D) -> Result<(), TestCaseError> {
        check_close(
            device,
            (&self.a.0, &self.a.1, self.a.2),
            (&self.b.0, &self.b.1, self.b.2),
            self.tolerance_n,
            self.pull,
        )
    }
}

/// Inputs this close (metres, newtons) ...
const NEARBY: f64 = 1e-7;
/// ... give set-points this close (a Lipschitz constant of 10^4 N per unit at most).
const NEARBY_TOLERANCE_N: f64 = 1e-3;

proptest! {
    #![proptest_config(ProptestConfig { cases: 4096, rng_seed: proptest::test_runner::RngSeed::Fixed(43), ..ProptestConfig::default() })]

    #[test]
    fn every_device_and_algorithm_keeps_the_felt_bound(
        kind in 0usize..4, u in proptest::array::uniform3(0.0f64..1.0),
        d in proptest::array::uniform3(-1.0f64..1.0), exponent in -5.0f64..1.3, in_contact: bool, pull: bool,
    ) {
        let f = force(d, exponent);
        on_device(kind, &mut Bound { p: workspace(kind, u), f, in_contact, pull })?;
    }

    #[test]
    fn nearby_inputs_give_nearby_setpoints(
        kind in 0usize..4, u in proptest::array::uniform3(0.0f64..1.0),
        d in proptest::array::uniform3(-1.0f64..1.0), exponent in -5.0f64..1.3, in_contact: bool,
        dp in proptest::array::uniform3(-1.0f64..1.0), df in proptest::array::uniform3(-1.0f64..1.0),
        pull: bool,
    ) {
        let p = workspace(kind, u);
        let f = force(d, exponent);
        let q = p + Vec3::from(dp) * NEARBY;
        let g = f + Vec3::from(df) * NEARBY;
        on_device(kind, &mut Nearby { a: (p, f, in_contact), b: (q, g, in_contact), tolerance_n: NEARBY_TOLERANCE_N, pull })?;
    }

    /// Where a wire turns across the normal (`n·u_i` = 0), the paper's P2 switched that wire
    /// between `t_min` and a share of the normal force; here the set-points pass through.
    #[test]
    fn a_wire_turning_across_the_normal_moves_nothing_abruptly(
        kind in 0usize..4, u in proptest::array::uniform3(0.0f64..1.0),
        d in proptest::array::uniform3(-1.0f64..1.0), exponent in -3.0f64..1.3, wire in 0usize..4, pull: bool,
    ) {
        let p = workspace(kind, u);
        let mut check = AcrossWire { p, d: Vec3::from(d), magnitude: 10f64.powf(exponent), wire, pull };
        on_device(kind, &mut check)?;
    }

    /// A force shrinking to zero from two directions: the set-points meet.
    #[test]
    fn forces_down_to_zero_meet_from_every_direction(
        kind in 0usize..4, u in proptest::array::uniform3(0.0f64..1.0),
        d1 in proptest::array::uniform3(-1.0f64..1.0), d2 in proptest::array::uniform3(-1.0f64..1.0),
        in_contact: bool, pull: bool,
    ) {
        let p = workspace(kind, u);
        let tiny = |d: [f64; 3]| {
            let v = Vec3::from(d);
            if v.norm() < 1e-3 { Vec3::zeros() } else { v.normalize() * NEARBY }
        };
        on_device(kind, &mut Nearby { a: (p, tiny(d1), in_contact), b: (p, tiny(d2), in_contact), tolerance_n: NEARBY_TOLERANCE_N, pull })?;
    }

    /// The onset of a contact: just before it (free space) and at a depth of a few nanometres,
    /// the set-points are the same to within the tolerance.
    #[test]
    fn contact_onset_is_not_a_step(
        kind in 0usize..4, u in proptest::array::uniform3(0.0f64..1.0),
        d in proptest::array::uniform3(-1.0f64..1.0),
    ) {
        let p = workspace(kind, u);
        let v = Vec3::from(d);
        prop_assume!(v.norm() > 1e-3);
        let touch = v.normalize() * NEARBY;
        on_device(kind, &mut Nearby { a: (p, Vec3::zeros(), false), b: (p, touch, true), tolerance_n: NEARBY_TOLERANCE_N, pull: true })?;
    }
}

struct AcrossWire {
    p: Vec3,
    d: Vec3,
    magnitude: f64,
    wire: usize,
    pull: bool,
}

impl DeviceCheck for AcrossWire {
    fn run<const N: usize, D: WireDevice<N>>(&mut self, device: &D) -> Result<(), TestCaseError> {
        let p = device.constrain(&self.p);
        let u = device.pull_direction(&p, self.wire % N);
        // A direction across the wire (in the device's force space), tilted by ±ε along it.
        let across = device.constrain(&(self.d - u * self.d.dot(&u)));
        prop_assume!(across.norm() > 1e-3);
        let across = (across - u * across.dot(&u)).normalize();
        let at = |tilt: f64| (across + u * tilt).normalize() * self.magnitude;
        for contact in [true, false] {
            check_close(
                device,
                (&p, &at(-NEARBY), contact),
                (&p, &at(NEARBY), contact),
                NEARBY_TOLERANCE_N,
                self.pull,
            )?;
        }
        Ok(())
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2048, rng_seed: proptest::test_runner::RngSeed::Fixed(44), ..ProptestConfig::default() })]

    /// The border of the reachable set: a force whose tensions put wire `j` exactly at `t_min`
    /// (or `t_max`), moved ±ε across that face. Exact on one side, projected on the other: the
    /// paper's P2 jumped there; every projection now meets the exact tensions.
    #[test]
    fn the_border_of_the_reachable_set_is_crossed_smoothly(
        planar: bool, u in proptest::array::uniform3(0.0f64..1.0),
        t in proptest::array::uniform3(0.31f64..14.0), wire in 0usize..3, at_max: bool,
    ) {
        let limits = ForceLimits::default();
        let bound = if at_max { limits.t_max_n } else { limits.t_min_n };
        for algorithm in Algorithm::ALL {
            let projection = algorithm.projection();
            if planar {
                let rig = videt_control::RigPlanar::paper_prototype();
                let p = workspace(1, u);
                let Some(map) = rig.wire_map(&videt_control::Vec2::new(p.x, p.z)) else { continue };
                let j = wire % 2;
                let mut tensions = [t[0], t[1]];
                tensions[j] = bound;
                let f = map.force(&tensions);
                let face = map.tension_matrix().row(j).transpose().normalize();
                let a = videt_control::project(&map, &(f - face * NEARBY), projection, &limits);
                let b = videt_control::project(&map, &(f + face * NEARBY), projection, &limits);
                let step = (0..2).map(|i| (a.tensions_n[i] - b.tensions_n[i]).abs()).fold(0.0, f64::max);
                prop_assert!(step <= NEARBY_TOLERANCE_N, "planar {algorithm:?}: {:?} -> {:?}", a.tensions_n, b.tensions_n);
            } else {
                let p = workspace(0, u);
                let Some(map) = Rig3::paper_frame().wire_map(&p) else { continue };
                let mut tensions = t;
                tensions[wire] = bound;
                let f = map.force(&tensions);
                let face = map.tension_matrix().row(wire).transpose().normalize();
                let a = videt_control::project(&map, &(f - face * NEARBY), projection, &limits);
                let b = videt_control::project(&map, &(f + face * NEARBY), projection, &limits);
                let step = (0..3).map(|i| (a.tensions_n[i] - b.tensions_n[i]).abs()).fold(0.0, f64::max);
                prop_assert!(step <= NEARBY_TOLERANCE_N, "{algorithm:?} at {p:?}: {:?} -> {:?}", a.tensions_n, b.tensions_n);
            }
        }
    }
}

/// The case of the box scene that hit a finger barely touching a side wall with 15 N: every
/// device, every algorithm, a 4 mN touch in every horizontal direction.
#[test]
fn a_barely_touching_finger_feels_a_light_force() {
    struct Touch;
    impl DeviceCheck for Touch {
        fn run<const N: usize, D: WireDevice<N>>(
            &mut self,
            device: &D,
        ) -> Result<(), TestCaseError> {
            for (x, y, z) in [(0.18, 0.1, 0.3), (0.05, 0.25, 0.2), (0.3, 0.02, 0.45)] {
                let p = device.constrain(&Vec3::new(x, y, z));
                for deg in (0..360).step_by(5) {
                    let a = (deg as f64).to_radians();
                    let f = Vec3::new(a.cos(), a.sin(), 0.0) * 0.004;
                    for (algorithm, pull) in Algorithm::ALL
                        .into_iter()
                        .flat_map(|a| [(a, true), (a, false)])
                    {
                        let Some(r) = render(device, &p, &f, true, algorithm, pull) else {
                            continue;
                        };
                        let light = r.field_n.norm() + r.floor_pull_n + FELT_MARGIN_N + 0.004;
                        prop_assert!(
                            r.rendered_n.norm() <= light + 1e-9,
                            "{:?} {algorithm:?} at {p:?} {deg}°: {:?}",
                            D::KIND,
                            r.tensions_n
                        );
                        prop_assert!(
                            r.tensions_n[..N].iter().all(|&t| t < 2.0),
                            "{:?} {algorithm:?} at {p:?} {deg}°: {:?}",
                            D::KIND,
                            r.tensions_n
                        );
                    }
                }
            }
            Ok(())
        }
    }
    for kind in 0..4 {
        on_device(kind, &mut Touch).unwrap();
    }
}
