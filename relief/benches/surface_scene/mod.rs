//! Shared synthetic scene for the surface benchmarks.

use rand::{Rng, SeedableRng};
use videt_control::SceneMap;
use videt_relief::{PinholeCamera, ReliefParams, SceneSegment3};

/// The scene map and camera of the benchmarks: a 40 x 30 cm area, a 640 x 480 camera.
pub fn setup() -> (ReliefParams, PinholeCamera) {
    let map = SceneMap::new([0.0, 0.0], [0.4, 0.3], [640, 480], 0.45, 0.08, [0.5, 5.0]).unwrap();
    let cam = PinholeCamera {
        focal_px: 600.0,
        cx_px: 320.0,
        cy_px: 240.0,
    };
    (ReliefParams::new(map), cam)
}

/// `n` matched segments like an indoor scene's: box outlines at a few depths plus loose edges
/// (random, fixed seed), in the camera frame.
pub fn scene_segments(n: usize, seed: u64) -> Vec<SceneSegment3> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(n);
    let back = |u: f64, v: f64, z: f64| [(u - 320.0) * z / 600.0, (v - 240.0) * z / 600.0, z];
    // Box outlines: 4 edges each, fronto-parallel.
    while out.len() + 4 <= n / 2 {
        let (u, v) = (rng.random_range(20.0..560.0), rng.random_range(20.0..400.0));
        let (w, h) = (rng.random_range(20.0..80.0), rng.random_range(20.0..80.0));
        let z = rng.random_range(0.8..4.5);
        let c = [
            back(u, v, z),
            back(u + w, v, z),
            back(u + w, v + h, z),
            back(u, v + h, z),
        ];
        for k in 0..4 {
            out.push(SceneSegment3 {
                a_m: c[k],
                b_m: c[(k + 1) % 4],
            });
        }
    }
    // Loose edges with depth varying along them.
    while out.len() < n {
        let (u, v) = (rng.random_range(0.0..640.0), rng.random_range(0.0..480.0));
        let len = rng.random_range(8.0..60.0);
        let ang: f64 = rng.random_range(0.0..std::f64::consts::PI);
        let (za, zb) = (rng.random_range(0.8..4.5), rng.random_range(0.8..4.5));
        out.push(SceneSegment3 {
            a_m: back(u, v, za),
            b_m: back(u + len * ang.cos(), v + len * ang.sin(), zb),
        });
    }
    out
}
