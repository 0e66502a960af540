//! The designer's analysis (paper section 6, Figs. 16 and 19-21): how well a rig renders forces
//! at a point, per algorithm. Pure sweeps that hand each sample to a callback, so they allocate
//! nothing; the `videt analyze` tool collects, prints and plots them.

use nalgebra::{SVector, Vector2, Vector3};

use crate::distribution::{project, Algorithm, ForceLimits};
use crate::field::{field_force, ForceField};
use crate::kinematics::Rig3;
use crate::measures::{isotropic_force_limit_n, v_index};
use crate::planar::RigPlanar;
use crate::wire_map::WireMap;

/// A device the analysis can evaluate: it gives the force map at a position.
pub trait WireDevice<const N: usize> {
    /// The force map at `position_m`, `None` where singular.
    fn wire_map_at(&self, position_m: &SVector<f64, N>) -> Option<WireMap<N>>;
}

impl WireDevice<3> for Rig3 {
    fn wire_map_at(&self, position_m: &Vector3<f64>) -> Option<WireMap<3>> {
        self.wire_map(position_m)
    }
}

impl WireDevice<2> for RigPlanar {
    fn wire_map_at(&self, position_m: &Vector2<f64>) -> Option<WireMap<2>> {
        self.wire_map(position_m)
    }
}

/// What is analysed: algorithm, field magnitude, limits and the contact force magnitude.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnalysisSetup {
    /// Algorithm (field rule and projection).
    pub algorithm: Algorithm,
    /// `|f_c|`, newtons. Constant-direction algorithms point it along `-z` (towards the frame).
    pub field_n: f64,
    /// Tension limits.
    pub limits: ForceLimits,
    /// `|f_e|` of the contact force swept over directions, newtons.
    pub force_n: f64,
}

/// One evaluated direction of the contact force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceSample<const N: usize> {
    /// Target `f'_e = f_e + f_c`, newtons.
    pub target_n: SVector<f64, N>,
    /// Rendered force, newtons.
    pub rendered_n: SVector<f64, N>,
    /// Index V (eq. 8) against the target.
    pub v: f64,
    /// `|f - f'_e|`, newtons.
    pub error_n: f64,
    /// Some tension hit `t_max`.
    pub saturated: bool,
}

/// The field force `f_c` of the setup at the map's position.
pub fn setup_field<const N: usize>(map: &WireMap<N>, setup: &AnalysisSetup) -> SVector<f64, N> {
    field_force(
        setup.algorithm,
        &ForceField::<N>::towards_frame(setup.field_n),
        map,
    )
}

/// Render a contact force of magnitude `setup.force_n` along the unit `direction` (plus the
/// field) and measure it.
pub fn evaluate_direction<const N: usize>(
    map: &WireMap<N>,
    direction: &SVector<f64, N>,
    setup: &AnalysisSetup,
) -> ForceSample<N> {
    let target_n = direction * setup.force_n + setup_field(map, setup);
    let d = project(map, &target_n, setup.algorithm.projection(), &setup.limits);
    ForceSample {
        target_n,
        rendered_n: d.rendered_n,
        v: v_index(&d.rendered_n, &target_n),
        error_n: (d.rendered_n - target_n).norm(),
        saturated: d.saturated,
    }
}

/// Planar sweep (paper Figs. 19-21): the contact force direction every 1 degree, angle in the
/// x-z plane from +x towards +z, 0..359. `sink(angle_deg, sample)`.
pub fn sweep_planar(
    map: &WireMap<2>,
    setup: &AnalysisSetup,
    mut sink: impl FnMut(f64, &ForceSample<2>),
) {
    for deg in 0..360u32 {
        let a = f64::from(deg).to_radians();
        let dir = Vector2::new(libm_cos(a), libm_sin(a));
        sink(f64::from(deg), &evaluate_direction(map, &dir, setup));
    }
}

/// Angular step of the spatial sweep, degrees.
pub const SPATIAL_STEP_DEG: u32 = 5;

/// Spatial sweep over the sphere of directions on an equirectangular grid: elevation from -90
/// to +90 degrees (from the x-y plane towards +z) every [`SPATIAL_STEP_DEG`], azimuth from 0 to
/// 355 (in the x-y plane from +x towards +y) every [`SPATIAL_STEP_DEG`]; the poles once each
/// (azimuth 0). 2522 directions. `sink(azimuth_deg, elevation_deg, sample)`.
pub fn sweep_spatial(
    map: &WireMap<3>,
    setup: &AnalysisSetup,
    mut sink: impl FnMut(f64, f64, &ForceSample<3>),
) {
    let steps = 180 / SPATIAL_STEP_DEG;
    for e in 0..=steps {
        let elevation_deg = -90.0 + f64::from(e * SPATIAL_STEP_DEG);
        let azimuths = if e == 0 || e == steps {
            1
        } else {
            360 / SPATIAL_STEP_DEG
        };
        for a in 0..azimuths {
            let azimuth_deg = f64::from(a * SPATIAL_STEP_DEG);
            let (az, el) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
            let dir = Vector3::new(
                libm_cos(el) * libm_cos(az),
                libm_cos(el) * libm_sin(az),
                libm_sin(el),
            );
            sink(
                azimuth_deg,
                elevation_deg,
                &evaluate_direction(map, &dir, setup),
            );
        }
    }
}

/// The isotropic force limit (radius of `S_f`, newtons) of the setup at `position_m`, or `None`
/// where the device is singular there.
pub fn isotropic_limit_at<const N: usize, D: WireDevice<N> + ?Sized>(
    device: &D,
    position_m: &SVector<f64, N>,
    setup: &AnalysisSetup,
) -> Option<f64> {
    let map = device.wire_map_at(position_m)?;
    Some(isotropic_force_limit_n(
        &map,
        &setup_field(&map, setup),
        &setup.limits,
    ))
}

/// Summary of a sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepSummary {
    /// Number of directions.
    pub count: usize,
    /// Mean of V.
    pub mean_v: f64,
    /// Smallest V.
    pub min_v: f64,
    /// Mean of `|1 - V|`.
    pub mean_miss: f64,
    /// Share of directions rendered exactly (`|f - f'_e| <= 1e-6 |f'_e|`).
    pub exact_share: f64,
    /// Mean force error `|f - f'_e|`, newtons.
    pub mean_error_n: f64,
    /// Number of directions where a tension hit `t_max`.
    pub saturated: usize,
}

/// Accumulates a [`SweepSummary`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SummaryBuilder {
    count: usize,
    sum_v: f64,
    min_v: f64,
    sum_miss: f64,
    exact: usize,
    sum_error: f64,
    saturated: usize,
}

impl SummaryBuilder {
    /// Add a sample.
    pub fn add<const N: usize>(&mut self, sample: &ForceSample<N>) {
        if self.count == 0 {
            self.min_v = sample.v;
        }
        self.count += 1;
        self.sum_v += sample.v;
        self.min_v = self.min_v.min(sample.v);
        self.sum_miss += (1.0 - sample.v).abs();
        if sample.error_n <= 1e-6 * sample.target_n.norm().max(1e-9) {
            self.exact += 1;
        }
        self.sum_error += sample.error_n;
        self.saturated += usize::from(sample.saturated);
    }

    /// The summary so far.
    pub fn finish(&self) -> SweepSummary {
        let n = self.count.max(1) as f64;
        SweepSummary {
            count: self.count,
            mean_v: self.sum_v / n,
            min_v: self.min_v,
            mean_miss: self.sum_miss / n,
            exact_share: self.exact as f64 / n,
            mean_error_n: self.sum_error / n,
            saturated: self.saturated,
        }
    }
}

#[inline]
fn libm_sin(x: f64) -> f64 {
    nalgebra::ComplexField::sin(x)
}

#[inline]
fn libm_cos(x: f64) -> f64 {
    nalgebra::ComplexField::cos(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Vec3;

    fn setup(algorithm: Algorithm, field_n: f64) -> AnalysisSetup {
        AnalysisSetup {
            algorithm,
            field_n,
            limits: ForceLimits {
                t_min_n: 0.0,
                t_max_n: 15.0,
            },
            force_n: 1.0,
        }
    }

    fn prototype_map() -> WireMap<2> {
        RigPlanar::paper_prototype()
            .wire_map(&Vector2::new(0.26, 0.26))
            .unwrap()
    }

    /// Paper Fig. 19: P1, |f_c| = 0, x = z = 0.26: V = 1 in region A (225..315 deg, the wire
    /// cone), V = 0 in region C (45..135 deg, away from both guides), cos² in between.
    #[test]
    fn fig19_p1_without_field() {
        let mut samples = [0.0; 360];
        sweep_planar(&prototype_map(), &setup(Algorithm::P1, 0.0), |deg, s| {
            samples[deg as usize] = s.v;
        });
        for (deg, &v) in samples.iter().enumerate() {
            let expected = match deg {
                225..=315 => 1.0,
                45..=135 => 0.0,
                // One wire pulls: V = cos²(angle to that wire).
                _ => {
                    let a = (deg as f64).to_radians();
                    let wire = if (136..225).contains(&deg) {
                        225f64
                    } else {
                        315f64
                    }
                    .to_radians();
                    (a - wire).cos().powi(2)
                }
            };
            assert!((v - expected).abs() < 1e-9, "{deg}: {v} vs {expected}");
        }
    }

    /// Paper Fig. 20: with |f_c| = 2 N every contact force up to 1.41 N is rendered exactly.
    #[test]
    fn fig20_field_makes_every_direction_renderable() {
        let map = prototype_map();
        for alg in Algorithm::ALL {
            let mut s = setup(alg, 2.0);
            s.force_n = 1.41;
            let mut summary = SummaryBuilder::default();
            sweep_planar(&map, &s, |_, sample| summary.add(sample));
            let sum = summary.finish();
            assert_eq!(sum.exact_share, 1.0, "{alg:?}");
            assert!((sum.min_v - 1.0).abs() < 1e-9);
            s.force_n = 1.5;
            let mut summary = SummaryBuilder::default();
            sweep_planar(&map, &s, |_, sample| summary.add(sample));
            assert!(summary.finish().exact_share < 1.0);
            let limit =
                isotropic_limit_at(&RigPlanar::paper_prototype(), &Vector2::new(0.26, 0.26), &s)
                    .unwrap();
            assert!(
                (limit - core::f64::consts::SQRT_2).abs() < 1e-9,
                "{alg:?}: {limit}"
            );
        }
    }

    /// Paper Fig. 21 against Fig. 20: P2 is at least as good as P1 on V everywhere, and QP as
    /// good as every other within what its finite weight on the normal leaves (2 %).
    #[test]
    fn p2_beats_p1_and_qp_beats_all() {
        let map = prototype_map();
        for field_n in [0.0, 0.5, 1.0, 2.0] {
            let mut v = [[0.0; 360]; 5];
            for (k, alg) in Algorithm::ALL.into_iter().enumerate() {
                let mut s = setup(alg, field_n);
                s.force_n = 3.0;
                s.limits.t_min_n = 0.1;
                sweep_planar(&map, &s, |deg, sample| v[k][deg as usize] = sample.v);
            }
            for deg in 0..360 {
                let miss = |k: usize| (1.0 - v[k][deg]).abs();
                assert!(miss(1) <= miss(0) + 1e-9, "P2 vs P1 at {deg}");
                for k in 0..4 {
                    assert!(
                        miss(4) <= miss(k) + 0.02,
                        "QP vs {k} at {deg}, fc {field_n}"
                    );
                }
            }
        }
    }

    #[test]
    fn spatial_sweep_covers_the_sphere() {
        let rig = Rig3::paper_frame();
        let map = rig.wire_map(&Vec3::new(0.18, 0.1, 0.3)).unwrap();
        let mut count = 0;
        let mut straight_down = 0.0;
        sweep_spatial(&map, &setup(Algorithm::P1, 0.0), |_, el, s| {
            count += 1;
            if el == -90.0 {
                straight_down = s.v;
            }
        });
        assert_eq!(count, 2522);
        assert!(
            (straight_down - 1.0).abs() < 1e-12,
            "-z is inside the cone over the triangle"
        );
    }
}
