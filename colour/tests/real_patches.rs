//! Classification of hand-labelled colour patches of real camera images (Middlebury left images
//! in the shared data), in plain RGB and in the default chromaticity space.
//!
//! Each patch was chosen by looking at the image (a 7x7 window on a uniformly coloured surface)
//! and labelled with the level triple of the colour a person names it by, *before* any level was
//! computed: red `HLL`, green `LHL`, yellow `HHL`, orange `HML`, white `HHH`, black `LLL`,
//! pink/magenta `HLH`, maroon `MLL`, periwinkle blue `MMH`, yellow-green `MHL`. Coordinates are
//! image pixels (column, row).
//!
//! Run `cargo test -p videt-colour --test real_patches -- --nocapture` for the per-patch table and
//! the accuracy of both spaces.

use videt_colour::level::parse_triple;
use videt_colour::training::load_rgb;
use videt_colour::{ColourReader, QuantizerConfig, SamplerConfig};

/// (data set, column, row, expected triple, what it is)
const PATCHES: &[(&str, u32, u32, &str, &str)] = &[
    ("teddy", 360, 75, "HLH", "pink teddy bear, body"),
    ("teddy", 330, 85, "HLH", "pink teddy bear, arm"),
    ("teddy", 185, 300, "LHL", "green frog, back"),
    ("teddy", 230, 290, "LHL", "green frog, leg"),
    ("teddy", 185, 343, "HHL", "yellow frog belly"),
    ("teddy", 325, 200, "MLL", "maroon box side"),
    ("teddy", 165, 160, "MMH", "blue paint on the canvas"),
    ("teddy", 150, 200, "MMH", "blue paint, lower"),
    ("teddy", 75, 190, "HML", "orange pepper on the cloth"),
    ("teddy", 30, 330, "HHH", "white cloth"),
    ("teddy", 320, 135, "HHH", "white inside of the box"),
    ("teddy", 390, 270, "MHL", "yellow-green succulent leaf"),
    ("teddy", 225, 356, "HLL", "red frog lips"),
    ("cones", 75, 240, "HLL", "red cone, shaded smudge"),
    ("cones", 140, 175, "HLL", "red cone, lit"),
    ("cones", 10, 200, "HLL", "red cone at the left border"),
    ("cones", 115, 310, "LHL", "green cone"),
    ("cones", 240, 300, "LHL", "green cone, right"),
    ("cones", 220, 175, "HHL", "yellow cloth"),
    ("cones", 105, 15, "HHL", "yellow flower centre"),
    ("tsukuba", 235, 160, "HML", "orange lamp shade"),
    ("tsukuba", 150, 190, "HHH", "white plaster head"),
    ("tsukuba", 297, 100, "HHL", "yellow can"),
    ("tsukuba", 320, 15, "LLL", "black equipment on the shelf"),
    ("venus", 320, 100, "LLL", "black area of the poster"),
];

/// Correct classifications of every patch with `config`, printing the table.
fn score(config: QuantizerConfig, name: &str) -> Option<usize> {
    let mut correct = 0;
    for &(set, u, v, expected, what) in PATCHES {
        let dir = videt_testdata::data_dir(&format!("stereo/{set}"))?;
        let frame = load_rgb(&dir.join("left.ppm")).expect("readable data set image");
        let mut reader = ColourReader::new(SamplerConfig::default(), config).unwrap();
        let reading = reader
            .read_pixel(&frame, f64::from(u) + 0.5, f64::from(v) + 0.5)
            .expect("patch inside the image");
        let want = parse_triple(expected).expect("valid fixture");
        let ok = reading.levels == want;
        correct += usize::from(ok);
        let got: String = reading.levels.iter().map(|l| l.letter()).collect();
        println!(
            "{name:>12} {set:>8} ({u:3},{v:3}) rgb {:3?} want {expected} got {got} {} {what}",
            reading.rgb,
            if ok { "ok " } else { "MISS" }
        );
    }
    Some(correct)
}

#[test]
fn chromaticity_classifies_real_patches_better_than_plain_rgb() {
    let Some(plain) = score(QuantizerConfig::plain_rgb(), "plain RGB") else {
        return;
    };
    let chroma = score(QuantizerConfig::default(), "chromaticity").unwrap();
    let n = PATCHES.len();
    println!(
        "accuracy: plain RGB {plain}/{n} ({:.0} %), chromaticity {chroma}/{n} ({:.0} %)",
        100.0 * plain as f64 / n as f64,
        100.0 * chroma as f64 / n as f64
    );
    // Regression guards at the measured figures: the default must stay the better space.
    assert!(chroma > plain, "chromaticity {chroma} vs plain {plain}");
    assert!(chroma >= 17, "chromaticity {chroma}/{n}");
    assert!(plain >= 12, "plain RGB {plain}/{n}");
}

/// The level image of a real photograph uses several level colours (a colour scene is not
/// flattened to one or two) and keeps the red and green cones apart.
#[test]
fn level_image_of_cones_separates_red_and_green_cones() {
    let Some(dir) = videt_testdata::data_dir("stereo/cones") else {
        return;
    };
    let frame = load_rgb(&dir.join("left.ppm")).unwrap();
    let levels = videt_colour::training::quantize_image(
        &frame,
        SamplerConfig {
            window_px: 3,
            statistic: videt_colour::WindowStatistic::Median,
        },
        QuantizerConfig::default(),
    )
    .unwrap();
    let at = |u: u32, v: u32| {
        let i = 3 * (v * frame.width + u) as usize;
        [levels.data[i], levels.data[i + 1], levels.data[i + 2]]
    };
    assert_eq!(at(140, 175), [255, 0, 0]);
    let green_cone = at(115, 310);
    assert_eq!(
        (green_cone[1], green_cone[2]),
        (255, 0),
        "green cone {green_cone:?}"
    );
    assert!(green_cone[0] < 255);
    let mut used = std::collections::BTreeSet::new();
    for px in levels.data.chunks_exact(3) {
        used.insert([px[0], px[1], px[2]]);
    }
    assert!(used.len() >= 8, "{} level colours", used.len());
}
