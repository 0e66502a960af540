//! Checks of `videt init --json` output against the twin's true frame.

/// Distance between two points of the frame plane, metres.
pub fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// The sides and guide points `json` reports are within 0.5 mm and 1 mm of the twin's true
/// guides `truth_m` (frame plane, metres), the guides expressed in the paper's frame: x0 at the
/// origin, x1 on +x, x2 at y > 0.
pub fn assert_matches_truth(json: &serde_json::Value, truth_m: [[f64; 2]; 3]) {
    let sides: Vec<f64> = serde_json::from_value(json["sides_m"].clone()).unwrap();
    let guides: Vec<[f64; 3]> = serde_json::from_value(json["guides_m"].clone()).unwrap();
    let t = truth_m;
    let truth = [dist(t[0], t[1]), dist(t[0], t[2]), dist(t[1], t[2])];
    for k in 0..3 {
        assert!(
            (sides[k] - truth[k]).abs() < 0.5e-3,
            "side {k}: {} vs {}",
            sides[k],
            truth[k]
        );
    }
    let ex = [
        (t[1][0] - t[0][0]) / truth[0],
        (t[1][1] - t[0][1]) / truth[0],
    ];
    let ey = [-ex[1], ex[0]];
    for i in 0..3 {
        let d = [t[i][0] - t[0][0], t[i][1] - t[0][1]];
        let expected = [d[0] * ex[0] + d[1] * ex[1], d[0] * ey[0] + d[1] * ey[1]];
        let e = dist([guides[i][0], guides[i][1]], expected);
        assert!(
            e < 1e-3 && guides[i][2] == 0.0,
            "guide {i}: {:?} vs {expected:?}",
            guides[i]
        );
    }
}
