//! Projection of the desired force onto the forces the wires can make (paper section 5).
//!
//! The reachable set is `F = { V t : t_min <= t_i <= t_max }`. When `t = J^T f` has every
//! component in range the force is rendered exactly (every algorithm); otherwise the algorithm's
//! projection decides which force of `F` to render. Every result has each tension in
//! `[t_min, t_max]`, reports saturation at `t_max`, and is finite for any input; it is
//! continuous in the force and in the map, and within the felt bound of [`crate::felt`]
//! (`docs/felt-force.md`).
//!
//! The functions are generic over the number of wires `N` (2: planar device, 3: wearable device;
//! `N <= 3`), over a [`WireMap`] built by the rig.

use nalgebra::SVector;

pub use crate::algorithm::{Algorithm, FieldRule, Projection, ALGORITHM_NAMES};
use crate::box_qp::BoxQp;
use crate::felt::{govern, FELT_MARGIN_N};
use crate::kinematics::Rig3;
use crate::wire_map::WireMap;
use crate::Vec3;

/// Tension limits of the wires.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceLimits {
    /// Minimum tension that keeps a wire taut, newtons (>= 0).
    pub t_min_n: f64,
    /// Maximum tension, newtons (the paper's device: 15 N).
    pub t_max_n: f64,
}

impl Default for ForceLimits {
    fn default() -> Self {
        ForceLimits {
            t_min_n: 0.3,
            t_max_n: 15.0,
        }
    }
}

/// Why tension limits were refused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LimitsError {
    /// Minimum tension given, newtons.
    pub t_min_n: f64,
    /// Maximum tension given, newtons.
    pub t_max_n: f64,
}

impl core::fmt::Display for LimitsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "tension limits t_min = {} N, t_max = {} N: need finite 0 <= t_min <= t_max",
            self.t_min_n, self.t_max_n
        )
    }
}

impl ForceLimits {
    /// Validated limits: finite, `0 <= t_min <= t_max`.
    pub fn new(t_min_n: f64, t_max_n: f64) -> Result<ForceLimits, LimitsError> {
        if t_min_n.is_finite() && t_max_n.is_finite() && t_min_n >= 0.0 && t_min_n <= t_max_n {
            Ok(ForceLimits { t_min_n, t_max_n })
        } else {
            Err(LimitsError { t_min_n, t_max_n })
        }
    }
}

/// The tensions chosen for a target force, and what was lost on the way.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distribution<const N: usize> {
    /// Tension set-points, newtons, each within `[t_min, t_max]`.
    pub tensions_n: [f64; N],
    /// The force those tensions make on the thimble, newtons.
    pub rendered_n: SVector<f64, N>,
    /// True when some tension had to be clamped at `t_max`.
    pub saturated: bool,
    /// True when the target was not reachable exactly (outside the wire cone, or needing a
    /// tension below `t_min` or above `t_max`).
    pub projected: bool,
}

impl<const N: usize> Default for Distribution<N> {
    fn default() -> Self {
        Distribution {
            tensions_n: [0.0; N],
            rendered_n: SVector::zeros(),
            saturated: false,
            projected: false,
        }
    }
}

/// Clamp a tension into the limits without panicking on bad limits or NaN (NaN -> `t_min`).
#[inline]
pub fn clamp_tension(t: f64, limits: &ForceLimits) -> f64 {
    let t = if t.is_nan() { limits.t_min_n } else { t };
    t.max(limits.t_min_n).min(limits.t_max_n)
}

/// Every wire at `t_min` (the safe state, or where the map is singular).
pub fn minimum_tension<const N: usize>(
    map: Option<&WireMap<N>>,
    limits: &ForceLimits,
) -> Distribution<N> {
    let t = clamp_tension(limits.t_min_n, limits);
    let tensions_n = [t; N];
    Distribution {
        tensions_n,
        rendered_n: map.map_or_else(SVector::zeros, |m| m.force(&tensions_n)),
        saturated: false,
        projected: true,
    }
}

/// How much more the force along the normal `n = f/|f|` weighs than the rest of the force
/// error in P2 and QP (`κ`): a wire pulling at `acos(a)` from the normal is used for exactness
/// along it in proportion to `κ a² / (1 + κ a²)`, so a wire that would pull almost across the
/// normal (`a -> 0`) fades out instead of being driven to `t_max` for a sliver of force.
pub const NORMAL_WEIGHT: f64 = 100.0;

/// How much of [`NORMAL_WEIGHT`] applies to a force of `magnitude_n` where the floor pulls
/// `floor_pull_n`: `min(1, |f| / |F0|)²`. Below the floor's own pull the direction of a force
/// says little (and none at 0), so the normal is weighed in gradually and the tensions stay
/// continuous through `f = 0`.
pub fn normal_weight_fade(magnitude_n: f64, floor_pull_n: f64) -> f64 {
    if floor_pull_n.is_nan() || floor_pull_n <= 1e-12 {
        return 1.0;
    }
    let x = (magnitude_n / floor_pull_n).min(1.0);
    if x.is_finite() {
        x * x
    } else {
        1.0
    }
}

/// Tension set-points for `target_n` (contact force plus field) with `projection`.
///
/// Inside `F` (every `t = J^T f` within the limits) the target is rendered exactly, whatever
/// the projection. Outside, the projection decides; every one is continuous in the target and
/// in the map (no jump where the set of pulling wires changes, at the border of `F`, or at a
/// zero force), and the felt bound ([`crate::felt`]) holds: the rendered force never exceeds
/// `|target| + |F0| + FELT_MARGIN_N`.
pub fn project<const N: usize>(
    map: &WireMap<N>,
    target_n: &SVector<f64, N>,
    projection: Projection,
    limits: &ForceLimits,
) -> Distribution<N> {
    const { assert!(N >= 1 && N <= 3, "1 to 3 wires") };
    if !target_n.iter().all(|c| c.is_finite()) {
        return minimum_tension(Some(map), limits);
    }
    let raw = map.tensions(target_n);
    let in_range = raw
        .iter()
        .all(|&t| t >= limits.t_min_n && t <= limits.t_max_n);
    // The floor's pull `F0 = V t_min`: the fade of the normal's weight and the felt bound.
    let floor = map.force(&[limits.t_min_n; N]);
    let (mut tensions, mut projected) = if in_range {
        (raw, false)
    } else {
        let clamped = raw.map(|t| clamp_tension(t, limits));
        let t = match projection {
            Projection::ClampNegative => clamped,
            Projection::ExactAlongNormal => {
                exact_along_normal(map, target_n, &clamped, limits, floor.norm())
            }
            Projection::NormalFirstNearest => {
                normal_first_nearest(map, target_n, limits, floor.norm())
            }
        };
        (t, true)
    };
    let limit = target_n.norm() + floor.norm() + FELT_MARGIN_N;
    if govern(&mut tensions, limits.t_min_n, &floor, limit, |t| {
        map.force(t)
    }) {
        projected = true;
    }
    let mut out = Distribution {
        tensions_n: [0.0; N],
        rendered_n: SVector::zeros(),
        saturated: false,
        projected,
    };
    // Saturated: a tension the target needed above t_max, or one at t_max in a projection.
    let at_max = limits.t_max_n * (1.0 - 1e-12) - 1e-12;
    for ((o, &t), &r) in out
        .tensions_n
        .iter_mut()
        .zip(tensions.iter())
        .zip(raw.iter())
    {
        if r > limits.t_max_n || (projected && t >= at_max) {
            out.saturated = true;
        }
        *o = clamp_tension(t, limits);
    }
    out.rendered_n = map.force(&out.tensions_n);
    out
}

/// P2, continuous: from P1's tensions `t1` (the target's tensions clamped into the box), the
/// tensions nearest `t1` that make the force along `n` as close to `|f|` as the weight allows:
/// minimise `κφ (aᵀt − |f|)² + |t − t1|²` over the box, `a_i = n·u_i`, `κ` =
/// [`NORMAL_WEIGHT`], `φ` = [`normal_weight_fade`]. Like the paper's `t' = (n^T V_P)^+ r`, the
/// correction is the least change of tension along the wires that pull along `n`; unlike it, it
/// starts from `t1` (so it meets the exact tensions at the border of `F`) and fades out a wire as
/// it turns across the normal (so the tensions do not jump when the set of pulling wires
/// changes). Where a wire pulls along `n` (`a_i` well above `1/√κ`) the force along `n` is within
/// `1/(1 + κ Σ a_i²)` of exact.
fn exact_along_normal<const N: usize>(
    map: &WireMap<N>,
    target_n: &SVector<f64, N>,
    clamped: &[f64; N],
    limits: &ForceLimits,
    floor_pull_n: f64,
) -> [f64; N] {
    let Some(normal) = NormalTerms::of(map, target_n, floor_pull_n) else {
        return *clamped;
    };
    let mut qp = tension_programme(limits);
    for i in 0..N {
        for j in 0..N {
            qp.hessian[i][j] =
                normal.weight * normal.along[i] * normal.along[j] + if i == j { 1.0 } else { 0.0 };
        }
        qp.linear[i] = normal.weight * normal.magnitude * normal.along[i] + clamped[i];
    }
    qp.solve()
}

/// A programme over the tension box `[t_min, t_max]`, its `H` and `g` zero (to be filled).
fn tension_programme<const N: usize>(limits: &ForceLimits) -> BoxQp<N> {
    BoxQp {
        hessian: [[0.0; N]; N],
        linear: [0.0; N],
        lo: limits.t_min_n,
        hi: limits.t_max_n.max(limits.t_min_n),
    }
}

/// What P2 and QP weigh the force along the normal with: `|f|`, `a_i = n·u_i` and `κφ`.
struct NormalTerms<const N: usize> {
    magnitude: f64,
    along: [f64; N],
    weight: f64,
}

impl<const N: usize> NormalTerms<N> {
    /// The terms of `target_n` (`None` for a zero force: it has no normal).
    fn of(map: &WireMap<N>, target_n: &SVector<f64, N>, floor_pull_n: f64) -> Option<Self> {
        let magnitude = target_n.norm();
        if magnitude < 1e-12 {
            return None;
        }
        let n = target_n / magnitude;
        Some(NormalTerms {
            magnitude,
            along: core::array::from_fn(|i| n.dot(&map.pull_direction(i))),
            weight: NORMAL_WEIGHT * normal_weight_fade(magnitude, floor_pull_n),
        })
    }
}

/// QP, continuous: the reachable force nearest the target, the error along `n` weighed
/// `1 + κφ` times the error across it: minimise `(Vt − f)ᵀ (I + κφ n nᵀ) (Vt − f)` over the
/// box. Strictly convex (`V` is invertible), so its one minimiser moves continuously with the
/// pose and the target.
fn normal_first_nearest<const N: usize>(
    map: &WireMap<N>,
    target_n: &SVector<f64, N>,
    limits: &ForceLimits,
    floor_pull_n: f64,
) -> [f64; N] {
    // A zero force has no normal: plain nearest.
    let normal = NormalTerms::of(map, target_n, floor_pull_n).unwrap_or(NormalTerms {
        magnitude: 0.0,
        along: [0.0; N],
        weight: 0.0,
    });
    let mut qp = tension_programme(limits);
    for i in 0..N {
        let ui = map.pull_direction(i);
        for j in 0..N {
            qp.hessian[i][j] =
                ui.dot(&map.pull_direction(j)) + normal.weight * normal.along[i] * normal.along[j];
        }
        qp.linear[i] = ui.dot(target_n) + normal.weight * normal.along[i] * normal.magnitude;
    }
    qp.solve()
}

/// Tension set-points for `desired_n` at `position_m` of a three-wire rig with the algorithm's
/// projection (no field: see [`crate::field`]). Where the Jacobian is singular every wire gets
/// `t_min`. Never NaN for finite input.
pub fn distribute(
    rig: &Rig3,
    position_m: &Vec3,
    desired_n: &Vec3,
    algorithm: Algorithm,
    limits: &ForceLimits,
) -> Distribution<3> {
    match rig.wire_map(position_m) {
        Some(map) => project(&map, desired_n, algorithm.projection(), limits),
        None => minimum_tension(None, limits),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planar::{RigPlanar, Vec2};
    use crate::v_index;
    use proptest::prelude::*;

    fn rig() -> Rig3 {
        Rig3::paper_frame()
    }

    fn no_floor() -> ForceLimits {
        ForceLimits {
            t_min_n: 0.0,
            t_max_n: 15.0,
        }
    }

    /// The prototype at x = z = 0.26: pulls u0 = (-1,-1)/√2, u1 = (1,-1)/√2.
    fn prototype_map() -> WireMap<2> {
        RigPlanar::paper_prototype()
            .wire_map(&Vec2::new(0.26, 0.26))
            .unwrap()
    }

    #[test]
    fn inside_the_cone_the_force_is_exact() {
        let p = Vec3::new(0.18, 0.1, 0.3);
        let f = Vec3::new(0.5, 0.2, -4.0);
        for alg in Algorithm::ALL {
            let d = distribute(&rig(), &p, &f, alg, &ForceLimits::default());
            assert!(!d.projected && !d.saturated);
            assert!((d.rendered_n - f).norm() < 1e-9, "{alg:?}");
        }
    }

    #[test]
    fn hand_computed_planar_cases() {
        let map = prototype_map();
        let s = core::f64::consts::FRAC_1_SQRT_2;
        // f = (1, 0): t = J^T f = V^T f = (-s, s): wire 1 positive, wire 0 negative.
        let f = Vec2::new(1.0, 0.0);
        let limits = no_floor();
        // P1: t = (0, s), f = s (s, -s) = (0.5, -0.5); V = 0.5.
        let d1 = project(&map, &f, Projection::ClampNegative, &limits);
        assert!((d1.tensions_n[0]).abs() < 1e-12 && (d1.tensions_n[1] - s).abs() < 1e-12);
        assert!((d1.rendered_n - Vec2::new(0.5, -0.5)).norm() < 1e-12);
        assert!((v_index(&d1.rendered_n, &f) - 0.5).abs() < 1e-12);
        // P2: from t1 = (0, s), minimise κ (s t - 1)² + (t - s)² for wire 1 (a = n·u1 = s):
        // t = s (1 + κ) / (1 + κ/2); the force along n is 1 - 0.5/(1 + κ/2), within 1 %.
        let d2 = project(&map, &f, Projection::ExactAlongNormal, &limits);
        let k = NORMAL_WEIGHT;
        assert_eq!(d2.tensions_n[0], 0.0);
        assert!((d2.tensions_n[1] - s * (1.0 + k) / (1.0 + k / 2.0)).abs() < 1e-12);
        assert!((d2.rendered_n.dot(&f) - (1.0 - 0.5 / (1.0 + k / 2.0))).abs() < 1e-12);
        // Within the felt bound: |f| + 0 (no floor) + the margin.
        assert!(d2.rendered_n.norm() <= 1.0 + FELT_MARGIN_N);
        // QP: the same wire; with e = t u1 - f it minimises |e|² + κ (n·e)² = t² - 2 s t + 1 +
        // κ (s t - 1)²: the same t as P2 here (wire 0 stays at its floor in both).
        let dq = project(&map, &f, Projection::NormalFirstNearest, &limits);
        let t_q = (s + k * s) / (1.0 + k * 0.5);
        assert!(
            (dq.tensions_n[1] - t_q).abs() < 1e-12,
            "{:?}",
            dq.tensions_n
        );
        // Pushing 10 N sideways: being exact along n would render 14 N; the bound holds it to
        // |f| + the margin.
        let big = Vec2::new(10.0, 0.0);
        for p in [Projection::ExactAlongNormal, Projection::NormalFirstNearest] {
            let d = project(&map, &big, p, &limits);
            assert!(
                (d.rendered_n.norm() - (10.0 + FELT_MARGIN_N)).abs() < 1e-9,
                "{p:?}"
            );
        }
        // Straight up (region C): no wire can pull; every algorithm holds t_min.
        let floor = ForceLimits {
            t_min_n: 0.5,
            t_max_n: 15.0,
        };
        for p in [
            Projection::ClampNegative,
            Projection::ExactAlongNormal,
            Projection::NormalFirstNearest,
        ] {
            let d = project(&map, &Vec2::new(0.0, 2.0), p, &floor);
            assert!(
                d.tensions_n.iter().all(|t| (t - 0.5).abs() < 1e-12),
                "{p:?}"
            );
        }
    }

    #[test]
    fn a_light_touch_on_a_side_wall_is_not_a_jab() {
        // The case of the box scene: a side wall's normal almost across every wire, 4 mN asked.
        // The paper's P2 gave one wire 15 N; every projection now stays near the floor.
        let p = Vec3::new(0.18, 0.1, 0.3);
        let map = rig().wire_map(&p).unwrap();
        let limits = ForceLimits::default();
        let floor = map.force(&[limits.t_min_n; 3]);
        // A normal across wire 0 and slightly along wire 1 and against the floor's pull.
        let u0 = map.pull_direction(0);
        let mut n = floor.cross(&u0).normalize();
        if n.dot(&map.pull_direction(1)) < 0.0 {
            n = -n;
        }
        let f = n * 0.004;
        for alg in Algorithm::ALL {
            let d = project(&map, &f, alg.projection(), &limits);
            assert!(
                d.rendered_n.norm() <= f.norm() + floor.norm() + FELT_MARGIN_N + 1e-9,
                "{alg:?}: {:?}",
                d.tensions_n
            );
            assert!(
                d.tensions_n.iter().all(|&t| t < 1.0),
                "{alg:?}: {:?}",
                d.tensions_n
            );
        }
    }

    #[test]
    fn limits_are_respected_and_saturation_reported() {
        let p = Vec3::new(0.18, 0.1, 0.3);
        let f = Vec3::new(0.0, 0.0, -100.0);
        for alg in Algorithm::ALL {
            let d = distribute(&rig(), &p, &f, alg, &ForceLimits::default());
            assert!(d.saturated, "{alg:?}");
            assert!(d.tensions_n.iter().all(|&t| (0.3..=15.0).contains(&t)));
        }
        // Bad limits (t_min > t_max) or NaN input never panic nor produce NaN.
        let bad = ForceLimits {
            t_min_n: 5.0,
            t_max_n: 1.0,
        };
        let d = distribute(
            &rig(),
            &p,
            &Vec3::new(f64::NAN, 0.0, 1.0),
            Algorithm::Qp,
            &bad,
        );
        assert!(d.tensions_n.iter().all(|t| t.is_finite()));
        assert!(ForceLimits::new(5.0, 1.0).is_err() && ForceLimits::new(0.0, 15.0).is_ok());
    }

    fn limits_strategy() -> impl Strategy<Value = ForceLimits> {
        (0.0f64..1.0, 2.0f64..20.0).prop_map(|(t_min_n, t_max_n)| ForceLimits { t_min_n, t_max_n })
    }

    fn floor_pull(map: &WireMap<3>, limits: &ForceLimits) -> f64 {
        map.force(&[limits.t_min_n; 3]).norm()
    }

    /// The weighted error P2's correction minimises, and QP's.
    fn along_error(map: &WireMap<3>, f: &Vec3, t: &[f64; 3]) -> f64 {
        let n = f.normalize();
        (map.force(t).dot(&n) - f.norm()).abs()
    }

    fn qp_cost(map: &WireMap<3>, f: &Vec3, t: &[f64; 3], limits: &ForceLimits) -> f64 {
        let e = map.force(t) - f;
        let floor = map.force(&[limits.t_min_n; 3]).norm();
        let w = NORMAL_WEIGHT * normal_weight_fade(f.norm(), floor);
        e.norm_squared() + w * e.dot(&f.normalize()).powi(2)
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 1024, rng_seed: proptest::test_runner::RngSeed::Fixed(42), ..ProptestConfig::default() })]

        #[test]
        fn setpoints_stay_in_limits_and_finite(
            x in -0.3f64..0.7, y in -0.3f64..0.6, z in -0.1f64..0.8,
            fx in -1e3f64..1e3, fy in -1e3f64..1e3, fz in -1e3f64..1e3,
            limits in limits_strategy(), alg in 0usize..5,
        ) {
            let d = distribute(&rig(), &Vec3::new(x, y, z), &Vec3::new(fx, fy, fz), Algorithm::ALL[alg], &limits);
            for &t in &d.tensions_n {
                prop_assert!(t.is_finite());
                prop_assert!(t >= limits.t_min_n && t <= limits.t_max_n, "{t} outside {limits:?}");
            }
            prop_assert!(d.rendered_n.iter().all(|c| c.is_finite()));
        }

        #[test]
        fn inside_the_cone_every_algorithm_is_exact(
            x in 0.05f64..0.32, y in 0.03f64..0.25, z in 0.05f64..0.6,
            t0 in 0.5f64..10.0, t1 in 0.5f64..10.0, t2 in 0.5f64..10.0, alg in 0usize..5,
        ) {
            let p = Vec3::new(x, y, z);
            let map = rig().wire_map(&p).unwrap();
            let f = map.force(&[t0, t1, t2]);
            let d = project(&map, &f, Algorithm::ALL[alg].projection(), &ForceLimits { t_min_n: 0.4, t_max_n: 15.0 });
            prop_assert!(!d.projected);
            prop_assert!((v_index(&d.rendered_n, &f) - 1.0).abs() < 1e-9);
            prop_assert!((d.rendered_n - f).norm() < 1e-9);
        }

        #[test]
        fn p2_corrects_p1_along_the_normal_and_never_away(
            x in -0.2f64..0.6, y in -0.2f64..0.5, z in 0.05f64..0.6,
            fx in -10.0f64..10.0, fy in -10.0f64..10.0, fz in -10.0f64..10.0, limits in limits_strategy(),
        ) {
            let p = Vec3::new(x, y, z);
            let f = Vec3::new(fx, fy, fz);
            prop_assume!(f.norm() > 1e-3);
            let map = rig().wire_map(&p).unwrap();
            let clamped = map.tensions(&f).map(|t| clamp_tension(t, &limits));
            let t2 = exact_along_normal(&map, &f, &clamped, &limits, floor_pull(&map, &limits));
            prop_assert!(along_error(&map, &f, &t2) <= along_error(&map, &f, &clamped) + 1e-9);
            // Where a wire pulling along n is free (inside its limits), the remaining error along
            // n is its correction over κφ a_i (the KKT condition of the correction).
            let n = f.normalize();
            let floor = map.force(&[limits.t_min_n; 3]).norm();
            let w = NORMAL_WEIGHT * normal_weight_fade(f.norm(), floor);
            let signed = f.norm() - map.force(&t2).dot(&n);
            for i in 0..3 {
                let a = n.dot(&map.pull_direction(i));
                let free = t2[i] > limits.t_min_n + 1e-9 && t2[i] < limits.t_max_n - 1e-9;
                if free && a > 0.1 {
                    prop_assert!((w * a * signed - (t2[i] - clamped[i])).abs() < 1e-6 * (1.0 + t2[i]),
                        "wire {i}: {} vs {}", w * a * signed, t2[i] - clamped[i]);
                }
            }
        }

        #[test]
        fn qp_is_the_weighted_nearest_of_the_three(
            x in -0.2f64..0.6, y in -0.2f64..0.5, z in 0.05f64..0.6,
            fx in -20.0f64..20.0, fy in -20.0f64..20.0, fz in -20.0f64..20.0,
            limits in limits_strategy(),
        ) {
            let p = Vec3::new(x, y, z);
            let f = Vec3::new(fx, fy, fz);
            prop_assume!(f.norm() > 1e-3);
            let map = rig().wire_map(&p).unwrap();
            let q = normal_first_nearest(&map, &f, &limits, floor_pull(&map, &limits));
            let clamped = map.tensions(&f).map(|t| clamp_tension(t, &limits));
            let p2 = exact_along_normal(&map, &f, &clamped, &limits, floor_pull(&map, &limits));
            let cost = |t: &[f64; 3]| qp_cost(&map, &f, t, &limits);
            prop_assert!(cost(&q) <= cost(&clamped) + 1e-9 * (1.0 + cost(&clamped)));
            prop_assert!(cost(&q) <= cost(&p2) + 1e-9 * (1.0 + cost(&p2)));
        }
    }
}
