//! The haptic bench's measurements on the timing-faithful twin: the figures a researcher
//! quotes must hold for the default configuration (simulated clock, deterministic).

use videt_rt_config::Config;
use videt_tools::haptic_bench::rig::Parts;
use videt_tools::haptic_bench::{judge_wall, stiffness_sweep, BenchPlan, Region};

#[test]
fn p2_renders_the_programmed_stiffness_where_the_wires_can_and_nothing_where_they_cannot() {
    let plan = BenchPlan {
        polar_deg: &[0.0, 150.0],
        azimuth_deg: &[0.0],
        ..BenchPlan::QUICK
    };
    let rows = stiffness_sweep(&Config::default(), &plan).unwrap();
    for row in &rows {
        eprintln!(
            "{} {:>3.0}° {:?}: rendered {:.0} N/m (x{:.3}), settled {}",
            row.algorithm, row.polar_deg, row.region, row.rendered_n_per_m, row.ratio, row.settled
        );
        assert_eq!(row.safety, "normal");
        match row.region {
            Region::A => {
                assert!(row.settled);
                assert!((row.ratio - 1.0).abs() < 0.1, "{row:?}");
            }
            // Facing away from every wire: no tension can push the finger out.
            Region::C => assert!(row.ratio.abs() < 0.15, "{row:?}"),
            Region::B => {}
        }
    }
    assert!(rows.iter().any(|r| r.region == Region::A));
    assert!(rows.iter().any(|r| r.region == Region::C));
}

#[test]
fn the_default_wall_is_inside_the_z_width_of_the_configured_parts() {
    let config = Config::default();
    let k = config.control.stiffness_n_per_m;
    let b = config.control.damping_n_s_per_m;
    let default = judge_wall(&config, k, b, Parts::Faithful).unwrap();
    eprintln!("default wall on the configured parts: {default:?}");
    assert!(default.stable, "{default:?}");
    // Without damping the same wall oscillates on the configured parts' delays, and a wall
    // several times stiffer does too: the criterion tells them apart.
    let undamped = judge_wall(&config, k, 0.0, Parts::Faithful).unwrap();
    let stiff = judge_wall(&config, 8.0 * k, b, Parts::Faithful).unwrap();
    eprintln!("undamped: {undamped:?}\nstiff: {stiff:?}");
    assert!(!undamped.stable && !stiff.stable);
}
