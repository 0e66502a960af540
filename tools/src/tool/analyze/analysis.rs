//! The designer's analysis at one point: the sweep of the index V over every direction of the
//! contact force with its summary, the isotropic force limit and the field `f_c` (the JSON report
//! and what the text report prints), and the per-direction V and workspace grid of isotropic
//! force limits that the plots draw.

use nalgebra::Vector2;
use serde::Serialize;
use videt_control::analysis::{
    evaluate_direction, isotropic_limit_at, setup_field, sweep_planar, sweep_spatial,
    AnalysisSetup, SummaryBuilder, SweepSummary, WireDevice,
};
use videt_control::RigPlanar;

use super::request::Request;

/// One direction of the JSON output.
#[derive(Debug, Serialize)]
#[serde(untagged)]
enum VEntry {
    Planar {
        direction_deg: f64,
        v: f64,
    },
    Spatial {
        azimuth_deg: f64,
        elevation_deg: f64,
        v: f64,
    },
}

/// The JSON output.
#[derive(Debug, Serialize)]
pub(super) struct Report {
    algorithm: &'static str,
    fc_n: f64,
    pub(super) position_m: Vec<f64>,
    pub(super) isotropic_force_n: f64,
    v_index: Vec<VEntry>,
}

/// Everything computed for one algorithm at the point.
pub(super) struct Analysis {
    pub(super) report: Report,
    pub(super) summary: SweepSummary,
    pub(super) field_n: Vec<f64>,
}

pub(super) fn analyse(request: &Request, setup: &AnalysisSetup) -> Analysis {
    let mut summary = SummaryBuilder::default();
    let mut entries = Vec::new();
    let (position_m, isotropic, field_n) = match request {
        Request::Planar { rig, at_m } => {
            let map = rig.wire_map(at_m).expect("checked regular");
            sweep_planar(&map, setup, |deg, s| {
                summary.add(s);
                entries.push(VEntry::Planar {
                    direction_deg: deg,
                    v: s.v,
                });
            });
            let fc = setup_field(&map, setup);
            (
                vec![at_m.x, at_m.y],
                isotropic_limit_at(rig, at_m, setup).unwrap_or(0.0),
                vec![fc.x, fc.y],
            )
        }
        Request::Spatial { rig, at_m } => {
            let map = rig.wire_map(at_m).expect("checked regular");
            sweep_spatial(&map, setup, |az, el, s| {
                summary.add(s);
                entries.push(VEntry::Spatial {
                    azimuth_deg: az,
                    elevation_deg: el,
                    v: s.v,
                });
            });
            let fc = setup_field(&map, setup);
            (
                vec![at_m.x, at_m.y, at_m.z],
                isotropic_limit_at(rig, at_m, setup).unwrap_or(0.0),
                vec![fc.x, fc.y, fc.z],
            )
        }
    };
    Analysis {
        report: Report {
            algorithm: setup.algorithm.name(),
            fc_n: setup.field_n,
            position_m,
            isotropic_force_n: isotropic,
            v_index: entries,
        },
        summary: summary.finish(),
        field_n,
    }
}

/// Evaluate the V index of the setup for one planar direction (for plots).
pub(super) fn planar_v(rig: &RigPlanar, at: &Vector2<f64>, setup: &AnalysisSetup, deg: f64) -> f64 {
    let map = rig.wire_map(at).expect("checked regular");
    let a = deg.to_radians();
    evaluate_direction(&map, &Vector2::new(a.cos(), a.sin()), setup).v
}

pub(super) fn isotropic_grid<const N: usize, D: WireDevice<N>>(
    device: &D,
    point: impl Fn(f64, f64) -> nalgebra::SVector<f64, N>,
    setup: &AnalysisSetup,
    xs: &[f64],
    ys: &[f64],
    valid: impl Fn(&nalgebra::SVector<f64, N>) -> bool,
) -> Vec<Vec<Option<f64>>> {
    ys.iter()
        .map(|&y| {
            xs.iter()
                .map(|&x| {
                    let p = point(x, y);
                    if valid(&p) {
                        isotropic_limit_at(device, &p, setup)
                    } else {
                        None
                    }
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tool::analyze::tests::args;
    use crate::tool::analyze::{parse_request, parse_setup};

    fn report(line: &[&str]) -> Report {
        let a = args(line);
        analyse(&parse_request(&a).unwrap(), &parse_setup(&a).unwrap()).report
    }

    #[test]
    fn paper_prototype_numbers() {
        let r = report(&[
            "--planar",
            "--guide",
            "0,0",
            "--guide",
            "0.52,0",
            "--at",
            "0.26,0.26",
            "--algorithm",
            "P1",
            "--fc",
            "2",
        ]);
        assert!((r.isotropic_force_n - std::f64::consts::SQRT_2).abs() < 1e-9);
        assert_eq!(r.v_index.len(), 360);
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(json["algorithm"], "P1");
        assert_eq!(json["fc_n"], 2.0);
        assert_eq!(json["position_m"], serde_json::json!([0.26, 0.26]));
        assert_eq!(json["v_index"][90]["direction_deg"], 90.0);
        // Fig. 19: P1 without field renders nothing straight up, everything straight down.
        let r = report(&["--planar", "--algorithm", "P1"]);
        let v = |deg: usize| match r.v_index[deg] {
            VEntry::Planar { v, .. } => v,
            _ => unreachable!(),
        };
        assert!(v(90).abs() < 1e-12 && (v(270) - 1.0).abs() < 1e-12);
        assert_eq!(r.isotropic_force_n, 0.0);
    }

    #[test]
    fn spatial_rig_answers() {
        let r = report(&[
            "--guide",
            "0,0",
            "--guide",
            "0.4,0",
            "--guide",
            "0.1,0.35",
            "--at",
            "0.15,0.12,0.3",
            "--algorithm",
            "F2",
            "--fc",
            "2",
        ]);
        assert_eq!(r.v_index.len(), 2522);
        assert!(r.isotropic_force_n > 0.5);
    }
}
