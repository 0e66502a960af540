//! The text output of `videt analyze`: the rig, the point, the limits and the field, the
//! isotropic force limit, and a table comparing every algorithm at the point.

use std::fmt::Write as _;

use videt_control::analysis::AnalysisSetup;
use videt_control::Algorithm;

use super::analysis::{analyse, Analysis};
use super::request::Request;

fn fmt_vec(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x:.3}")).collect();
    format!("[{}]", parts.join(", "))
}

pub(super) fn text_report(request: &Request, setup: &AnalysisSetup, main: &Analysis) -> String {
    let mut s = String::new();
    let (rig_text, directions) = match request {
        Request::Planar { rig, .. } => (
            format!(
                "planar 2-wire, guides at x = {} m and {} m (x-z plane)",
                rig.guides_x_m()[0],
                rig.guides_x_m()[1]
            ),
            "360 directions in the x-z plane",
        ),
        Request::Spatial { rig, .. } => {
            let g = rig.guides_m();
            (
                format!(
                    "3-wire, guides at ({}, {}), ({}, {}), ({}, {}) m",
                    g[0].x, g[0].y, g[1].x, g[1].y, g[2].x, g[2].y
                ),
                "2522 directions over the sphere",
            )
        }
    };
    let _ = writeln!(s, "rig:        {rig_text}");
    let _ = writeln!(s, "thimble:    {} m", fmt_vec(&main.report.position_m));
    let _ = writeln!(
        s,
        "limits:     t_min = {} N, t_max = {} N; contact force |f_e| = {} N over {directions}",
        setup.limits.t_min_n, setup.limits.t_max_n, setup.force_n
    );
    let _ = writeln!(
        s,
        "algorithm:  {} with |f_c| = {} N, f_c = {} N",
        setup.algorithm.name(),
        setup.field_n,
        fmt_vec(&main.field_n)
    );
    let _ = writeln!(
        s,
        "isotropic force limit (radius of S_f): {:.4} N",
        main.report.isotropic_force_n
    );
    let _ = writeln!(
        s,
        "\ncomparison at this point (same |f_c|, |f_e|, limits):\n  alg  |f_c| dir   mean V  min V   mean|1-V|  exact   mean |f-f'e| N  isotropic N"
    );
    for alg in Algorithm::ALL {
        let setup_k = AnalysisSetup {
            algorithm: alg,
            ..*setup
        };
        let a = if alg == setup.algorithm {
            None
        } else {
            Some(analyse(request, &setup_k))
        };
        let a = a.as_ref().unwrap_or(main);
        let dir = match alg.field_rule() {
            videt_control::FieldRule::Constant => "-z      ",
            videt_control::FieldRule::Bisector => "bisector",
        };
        let sum = &a.summary;
        let _ = writeln!(
            s,
            "  {:<4} {dir}  {:>6.3}  {:>6.3}  {:>9.4}  {:>5.1}%  {:>14.4}  {:>10.4}",
            alg.name(),
            sum.mean_v,
            sum.min_v,
            sum.mean_miss,
            100.0 * sum.exact_share,
            sum.mean_error_n,
            a.report.isotropic_force_n
        );
    }
    s
}
