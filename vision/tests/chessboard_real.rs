//! Chessboard detection on the real stereo calibration set.

use videt_vision::calib::chessboard::{find_chessboard, BoardSize};
use videt_vision::calib::image_io::load_gray;

#[test]
fn finds_all_54_corners_on_every_shared_image() {
    let Some(dir) = videt_testdata::data_dir("calib/chessboard") else {
        return;
    };
    let size = BoardSize { cols: 9, rows: 6 };
    for side in ["left", "right"] {
        for i in 1..=9 {
            let path = dir.join(format!("{side}{i:02}.jpg"));
            let frame = load_gray(&path).expect("decodes");
            let t = std::time::Instant::now();
            let corners = find_chessboard(
                frame.width as usize,
                frame.height as usize,
                &frame.data,
                size,
            );
            eprintln!(
                "{} {:?} {:?} {:?}",
                path.display(),
                t.elapsed(),
                corners.as_ref().map(|c| c[0]),
                corners.as_ref().map(|c| c[8])
            );
            assert!(corners.is_some(), "{}", path.display());
        }
    }
}
