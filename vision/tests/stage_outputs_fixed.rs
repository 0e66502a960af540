//! The outputs of the edge and segment stages on the real pairs of the shared data are pinned
//! bit for bit: the smoothed image, the Sobel gradients and magnitude, the edge map, the
//! sub-pixel offsets of the edge pixels, the chains and the segments (every field's bits) of
//! both images of tsukuba, venus, cones and teddy, of the 640x480 bench pair (teddy upscaled)
//! and of the windows of a 100x100 local run on it. A change that is meant to make these
//! stages faster must leave every fingerprint unchanged. The matches of the whole pipeline on
//! each pair (and of the local run) are pinned too: a change meant to make the matcher faster
//! must leave them unchanged as well.
//!
//! `VIDET_PRINT_FINGERPRINTS=1 cargo test -p videt-vision --test stage_outputs_fixed -- --nocapture`
//! prints the tables.

use image::imageops::FilterType;
use image::GrayImage;
use videt_vision::canny::{CannyWorkspace, EDGE};
use videt_vision::chains::Chains;
use videt_vision::segments::{Segment, SegmentWorkspace};
use videt_vision::{GrayView, LocalRegion, StereoPipeline, VisionParams};

/// FNV-1a, 64 bits.
#[derive(Clone, Copy)]
struct Fingerprint(u64);

impl Fingerprint {
    fn new() -> Self {
        Fingerprint(0xcbf2_9ce4_8422_2325)
    }

    fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }

    fn f32(&mut self, v: f32) {
        self.u32(v.to_bits());
    }
}

/// Fingerprints of one image's stages, in the order of [`STAGES`].
fn image_fingerprints(view: &GrayView<'_>, params: &VisionParams) -> [u64; 7] {
    let mut canny = CannyWorkspace::new();
    canny.detect(view, &params.canny).unwrap();
    let (w, h) = (view.width(), view.height());
    let mut smoothed = Fingerprint::new();
    smoothed.bytes(canny.smoothed());
    let mut gradient = Fingerprint::new();
    for (&gx, &gy) in canny.gx().iter().zip(canny.gy()) {
        gradient.bytes(&gx.to_le_bytes());
        gradient.bytes(&gy.to_le_bytes());
    }
    // The detector keeps only three rows of magnitude: its definition |gx| + |gy| is hashed.
    let mut magnitude = Fingerprint::new();
    for (&gx, &gy) in canny.gx().iter().zip(canny.gy()) {
        magnitude.bytes(&(gx.abs() + gy.abs()).to_le_bytes());
    }
    let mut edges = Fingerprint::new();
    let mut subpixel = Fingerprint::new();
    for (i, &e) in canny.edges().iter().enumerate() {
        let is_edge = e == EDGE;
        edges.bytes(&[u8::from(is_edge)]);
        if is_edge {
            let ((sx, sy), offset) = canny.subpixel_offset(i);
            subpixel.u32(i as u32);
            subpixel.u32(sx as u32);
            subpixel.u32(sy as u32);
            subpixel.f32(offset);
        }
    }
    let mut chains = Chains::new();
    chains.link(canny.edges(), w, h, params.segments.min_chain_pixels);
    let mut chain_print = Fingerprint::new();
    for c in 0..chains.len() {
        chain_print.u32(c as u32);
        for p in chains.chain(c) {
            chain_print.u32(u32::from(p[0]) | (u32::from(p[1]) << 16));
        }
    }
    let mut segments = Vec::new();
    SegmentWorkspace::new().extract(
        &chains,
        &canny,
        view.origin_px(),
        &params.segments,
        &mut segments,
    );
    [
        smoothed.0,
        gradient.0,
        magnitude.0,
        edges.0,
        subpixel.0,
        chain_print.0,
        segments_fingerprint(&segments),
    ]
}

fn segments_fingerprint(segments: &[Segment]) -> u64 {
    let mut f = Fingerprint::new();
    for s in segments {
        for v in [
            s.start[0],
            s.start[1],
            s.end[0],
            s.end[1],
            s.length_px,
            s.angle_rad,
            s.contrast,
            s.side_intensity[0],
            s.side_intensity[1],
        ] {
            f.f32(v);
        }
        f.u32(s.polarity as u32);
        f.u32(s.chain);
    }
    f.0
}

const STAGES: [&str; 7] = [
    "smoothed",
    "gradient",
    "magnitude",
    "edges",
    "subpixel",
    "chains",
    "segments",
];

/// The pinned fingerprints: (input, image, stage fingerprints in the order of [`STAGES`]).
const EXPECTED: &[(&str, &str, [u64; 7])] = &[
    (
        "tsukuba",
        "left",
        [
            0x48d57d2fc4ae2707,
            0x52d1dcbef54145b0,
            0xf3582e3abe102072,
            0x78689b69a2ffb1b5,
            0x39836801004116fd,
            0xea4f88c0735a0cb4,
            0x6d79da2e9907a1b7,
        ],
    ),
    (
        "tsukuba",
        "right",
        [
            0xad4c1203ec7b45c0,
            0x00653aa980e1bd61,
            0xefcae04ad7506f29,
            0xbdccedf1a80ed2ba,
            0x06d73185bb6c365d,
            0x5b937cb9b385fd60,
            0x953508ded93940c8,
        ],
    ),
    (
        "venus",
        "left",
        [
            0x3916f251d218e753,
            0xfe3a02a30aa402e6,
            0xd33fb2bc54e45b4e,
            0xd5d8e9da2f9e36ea,
            0x302d1df29f57533b,
            0xf56e7a6595a866c8,
            0x0bd041ffdff454a3,
        ],
    ),
    (
        "venus",
        "right",
        [
            0x3eea08e5ffe7da06,
            0x1369088d46c98af2,
            0x71c6920a9a8329ec,
            0xbf36a9c52f32e1e7,
            0xb980da9ca8f84f43,
            0xc695c7e878def16d,
            0xd0c8956c7e58359c,
        ],
    ),
    (
        "cones",
        "left",
        [
            0x3c60d58e49dc68a6,
            0xa3f67a017f743615,
            0x2f396454d2590e21,
            0xe40282aa9c32ef12,
            0x7aba1abc8d38627d,
            0x3725bd23c967aebc,
            0x9111343aa15bb97e,
        ],
    ),
    (
        "cones",
        "right",
        [
            0x490ad4163226a7da,
            0x6a6fbe4769e924e4,
            0x3e01cc8f258aee8f,
            0x8d4f47fec208068e,
            0x2e752452d1174903,
            0x3ca5208426b3e8cf,
            0xb831f8119b3cb999,
        ],
    ),
    (
        "teddy",
        "left",
        [
            0x5d650fa29221b805,
            0xceaa46e1b7eb3ac4,
            0x8af2cf0e29d56445,
            0xa718050e971f9677,
            0xd31b6ccade0b7e45,
            0x5c585de6cb1eb03f,
            0x264958954da60c2d,
        ],
    ),
    (
        "teddy",
        "right",
        [
            0xfd1aeb2343e98824,
            0xa36843b9a00a57cf,
            0xc4f5171e84d76cec,
            0xb3686a9a316bbec8,
            0x5f0644abd4de1855,
            0x818d9c09d2d833bb,
            0xc38bf2f83ac0a462,
        ],
    ),
    (
        "teddy640",
        "left",
        [
            0xde43f3b550b690b9,
            0xa6d748f4a44c6807,
            0x59156bd9be420ff2,
            0xfc6624e265de1da1,
            0x3cb36dc40238e2fb,
            0xcdeb8b3cd18a6d30,
            0x6a6bd52f04c9eb13,
        ],
    ),
    (
        "teddy640",
        "right",
        [
            0xd14f4cb86dd7fda0,
            0x31577be02e4e1a3d,
            0xa45b8aac01772782,
            0x986200ff82dbaa43,
            0x64c579d0513f009a,
            0x6c1d0d77da9ced52,
            0xbca34607fef96e8c,
        ],
    ),
    (
        "teddy640-local",
        "left",
        [
            0x18b3e1eff81c77a5,
            0x2ee39b6ffc22f090,
            0x577fb70cd8655427,
            0x263bd075a0969598,
            0x1e1143c9ec8b759c,
            0xc594cfb444f03eff,
            0x3a027dfa347cb88f,
        ],
    ),
    (
        "teddy640-local",
        "right",
        [
            0x230046458f8cef4e,
            0x57d518f1e5cfa8bf,
            0xfa7ddb85c466799a,
            0x8a8f38e650d5e796,
            0xfa661edff45c4c0f,
            0x814b678ba91467c0,
            0xf410e45d8fb62063,
        ],
    ),
];

/// The pinned fingerprints of the matches (see [`matches_fingerprint`]) per input.
const EXPECTED_MATCHES: &[(&str, u64)] = &[
    ("tsukuba", 0xb6c2c6c83dbc678e),
    ("venus", 0x976a1f637e1340fd),
    ("cones", 0x47089bd3dce8d55b),
    ("teddy", 0x87a88e9ace86318a),
    ("teddy640", 0x26d79a9fc85fe318),
    ("teddy640-local", 0x68c74035f2dd1931),
];

fn load(dir: &std::path::Path, name: &str) -> GrayImage {
    image::open(dir.join(name)).unwrap().to_luma8()
}

#[test]
fn edge_and_segment_stages_reproduce_their_pinned_outputs() {
    let params = VisionParams::default();
    let mut inputs: Vec<(String, GrayImage, GrayImage)> = Vec::new();
    for name in ["tsukuba", "venus", "cones", "teddy"] {
        let Some(dir) = videt_testdata::data_dir(&format!("stereo/{name}")) else {
            return;
        };
        inputs.push((
            name.to_string(),
            load(&dir, "left.ppm"),
            load(&dir, "right.ppm"),
        ));
    }
    let teddy = &inputs[3];
    let up = |img: &GrayImage| image::imageops::resize(img, 640, 480, FilterType::Triangle);
    inputs.push(("teddy640".into(), up(&teddy.1), up(&teddy.2)));

    let mut actual: Vec<(String, &str, [u64; 7])> = Vec::new();
    let mut match_prints = Vec::new();
    let mut pipeline = StereoPipeline::new();
    for (name, left, right) in &inputs {
        let lv = GrayView::from_image(left).unwrap();
        let rv = GrayView::from_image(right).unwrap();
        actual.push((name.clone(), "left", image_fingerprints(&lv, &params)));
        actual.push((name.clone(), "right", image_fingerprints(&rv, &params)));
        let out = pipeline.run(&lv, &rv, None, &params).unwrap();
        match_prints.push((name.clone(), matches_fingerprint(out)));
    }
    // The windows of a local run on the 640x480 pair.
    let (_, left, right) = &inputs[4];
    let (lv, rv) = (
        GrayView::from_image(left).unwrap(),
        GrayView::from_image(right).unwrap(),
    );
    let region = LocalRegion {
        centre_px: [400.0, 260.0],
        size_px: [100.0, 100.0],
        velocity_px_per_frame: [3.0, -2.0],
    };
    let out = pipeline
        .run_local(&lv, &rv, None, &params, &region)
        .unwrap();
    let windows = out.local.unwrap();
    match_prints.push(("teddy640-local".into(), matches_fingerprint(out)));
    for (side, view, rect) in [("left", lv, windows.left), ("right", rv, windows.right)] {
        let window = view.window(rect).unwrap();
        actual.push((
            "teddy640-local".into(),
            side,
            image_fingerprints(&window, &params),
        ));
    }

    if std::env::var("VIDET_PRINT_FINGERPRINTS").is_ok_and(|v| v == "1") {
        for (name, side, prints) in &actual {
            let list: Vec<String> = prints.iter().map(|p| format!("0x{p:016x}")).collect();
            println!("    (\"{name}\", \"{side}\", [{}]),", list.join(", "));
        }
        for (name, print) in &match_prints {
            println!("matches {name}: 0x{print:016x}");
        }
    }
    assert_eq!(
        actual.len(),
        EXPECTED.len(),
        "inputs and pinned table differ"
    );
    for ((name, side, prints), (e_name, e_side, e_prints)) in actual.iter().zip(EXPECTED) {
        assert_eq!((name.as_str(), *side), (*e_name, *e_side));
        for (stage, (a, e)) in STAGES.iter().zip(prints.iter().zip(e_prints)) {
            assert_eq!(a, e, "{name} {side}: stage {stage} changed");
        }
    }
    assert_eq!(match_prints.len(), EXPECTED_MATCHES.len());
    for ((name, print), (e_name, e_print)) in match_prints.iter().zip(EXPECTED_MATCHES) {
        assert_eq!(name, e_name);
        assert_eq!(print, e_print, "{name}: matches changed");
    }
}

fn matches_fingerprint(out: &videt_vision::PipelineOutput) -> u64 {
    let mut f = Fingerprint::new();
    for s in [&out.left_segments, &out.right_segments] {
        f.u32(segments_fingerprint(s) as u32);
    }
    for m in &out.matches {
        f.u32(m.left);
        f.u32(m.right);
        f.f32(m.disparity_px[0]);
        f.f32(m.disparity_px[1]);
        f.u32(m.support);
        f.u32(u32::from(m.predicted) | (u32::from(m.nearly_horizontal) << 1));
    }
    f.0
}
