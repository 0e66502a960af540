//! Rectified 640x480 stereo pairs with exact ground truth, for held-out accuracy figures:
//! real photographs printed on planes in 3D, seen by a rig like the product's (focal 536 px,
//! baseline 6 cm) whose two cameras each blur, vignette, differ in gain and offset and add
//! sensor noise (`videt_evaluation::synthetic::render_rig`).
//!
//! ```text
//! cargo run --release -p videt-evaluation --example synthesise_stereo -- TEXTURE_DIR OUT_DIR [--force]
//! cargo run --release -p videt-evaluation --example synthesise_stereo -- \
//!     --import NAME LEFT RIGHT DISP_LEFT SCALE ATTRIBUTION OUT_DIR [--force]
//! ```
//!
//! The first form writes one directory per scene into OUT_DIR, skipping the ones already there
//! (unless `--force`). TEXTURE_DIR holds the photographs as `NAME.png` or `NAME.jpg`
//! (scikit-image's sample data: astronaut, brick, camera, chelsea, coffee, grass, gravel, page,
//! rocket, text). The scenes:
//!
//! - `syn-poster`: a photograph on one slanted plane filling most of the view, before a wall;
//! - `syn-map`: a printed map and a photograph lying on gravel seen obliquely (the disparity
//!   grows down the image);
//! - `syn-page`: a printed page on a tilted board above a desk;
//! - `syn-desk`, `syn-shelf`: five or six photographs at different depths and slants before a
//!   textured wall (piecewise planar, with occlusions).
//!
//! The second form prepares a real pair with ground truth at the camera's size: both images
//! (any format) and the left ground truth (8-bit, disparity x SCALE, 0 = unknown) are halved
//! (2 x 2 means) while they stay at least 640x480, then cropped about the centre to at most
//! 640x480; the left pixels that the right camera cannot see (the left ground truth warped into
//! the right view puts a nearer point on their right pixel) are set to unknown.
//!
//! Each directory gets `left.png`, `right.png`, `disp_left.pgm` (and `disp_right.pgm` for the
//! synthesised scenes), all in the Middlebury 8-bit convention (disparity x scale, 0 =
//! unknown), `scale.txt` and `ATTRIBUTION.txt` (the sources of the photographs; for an
//! imported pair a copy of the file ATTRIBUTION). The run prints, per pair, the
//! disparity range and the median grey-level difference between the left pixels and their
//! right correspondents, a check of the ground truth.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use videt_evaluation::synthetic::{
    plane_axes, printed_map, render_rig, Imaging, Lcg, Panel, Rig, Texture,
};

/// The product's camera.
const WIDTH: usize = 640;
/// The product's camera.
const HEIGHT: usize = 480;
/// Focal length of the rectified rig, pixels (the product's cameras: about 536).
const FOCAL_PX: f64 = 536.0;
/// Baseline of the rig, metres.
const BASELINE_M: f64 = 0.06;

/// Where each photograph comes from and under which terms.
const SOURCES: [(&str, &str); 10] = [
    (
        "astronaut",
        "the astronaut Eileen Collins, NASA Great Images database (https://flic.kr/p/r9qvLn); \
         public domain (no known copyright restrictions)",
    ),
    (
        "brick",
        "a brick wall, CC0Textures (Bricks25), perspective-corrected, cropped and scaled by \
         scikit-image; CC0",
    ),
    (
        "camera",
        "a photographer with a camera, by Lav Varshney; CC0",
    ),
    ("chelsea", "Chelsea the cat, by Stefan van der Walt; CC0"),
    (
        "coffee",
        "a coffee cup on a wooden table, by Rachel Michetti (courtesy of Pikolo Espresso Bar); \
         CC0",
    ),
    (
        "grass",
        "grass, by linolafett on DeviantArt (Grass-01), cropped by scikit-image; CC0",
    ),
    (
        "gravel",
        "gravel, CC0Textures (Gravel04), rescaled, cropped and made grey by scikit-image; CC0",
    ),
    (
        "page",
        "a scanned printed page made by the scikit-image project; distributed in scikit-image \
         under its BSD-3-Clause licence (no separate licence stated)",
    ),
    (
        "rocket",
        "the launch of DSCOVR on a Falcon 9, SpaceX \
         (https://www.flickr.com/photos/spacexphotos/16511594820/); public domain",
    ),
    (
        "text",
        "handwritten formulas on paper, Wikipedia's File:Corner.png; public domain (no known \
         copyright restrictions)",
    ),
];

/// The photographs, loaded once each.
struct Textures {
    dir: PathBuf,
    loaded: BTreeMap<String, (Arc<Texture>, String)>,
}

impl Textures {
    fn get(&mut self, name: &str) -> Result<Arc<Texture>, String> {
        if let Some((t, _)) = self.loaded.get(name) {
            return Ok(t.clone());
        }
        for ext in ["png", "jpg"] {
            let path = self.dir.join(format!("{name}.{ext}"));
            if path.exists() {
                let img = image::open(&path)
                    .map_err(|e| format!("{}: {e}", path.display()))?
                    .to_luma8();
                let t = Arc::new(Texture::from_gray(
                    img.width() as usize,
                    img.height() as usize,
                    img.as_raw(),
                ));
                let file = format!("{name}.{ext}");
                self.loaded.insert(name.to_string(), (t.clone(), file));
                return Ok(t);
            }
        }
        Err(format!(
            "{}: no {name}.png or {name}.jpg",
            self.dir.display()
        ))
    }

    /// The attribution lines of `names`.
    fn attribution(&self, names: &[&str]) -> String {
        names
            .iter()
            .map(|n| {
                let file = self.loaded.get(*n).map_or("?", |(_, f)| f.as_str());
                let source = SOURCES
                    .iter()
                    .find(|(s, _)| s == n)
                    .map_or("source unknown", |(_, s)| s);
                format!("- {file}: {source}\n")
            })
            .collect()
    }
}

/// A scene: its panels (far to near does not matter: depth decides) and the photographs used.
struct Scene {
    name: &'static str,
    what: &'static str,
    panels: Vec<Panel>,
    photos: Vec<&'static str>,
    /// Extra attribution lines (textures that are no photograph).
    notes: Vec<String>,
}

/// A print of `texture` `width_m` wide, its height from the texture's aspect ratio.
fn print(
    centre: [f64; 3],
    width_m: f64,
    yaw: f64,
    pitch: f64,
    roll: f64,
    texture: Arc<Texture>,
) -> Panel {
    let height_m = width_m * texture.height as f64 / texture.width as f64;
    Panel::new(
        centre,
        [width_m, height_m],
        plane_axes(yaw, pitch, roll),
        texture,
    )
}

/// A point `offset_m` along the axes of a plane through `centre`, raised `raise_m` towards
/// the camera.
fn on_plane(centre: [f64; 3], axes: [[f64; 3]; 3], offset_m: [f64; 2], raise_m: f64) -> [f64; 3] {
    std::array::from_fn(|i| {
        centre[i] + offset_m[0] * axes[0][i] + offset_m[1] * axes[1][i] - raise_m * axes[2][i]
    })
}

/// A mural of `texture` on a fronto-parallel wall at depth `z`, scaled to fill both views.
fn mural(z: f64, texture: Arc<Texture>) -> Panel {
    let aspect = texture.width as f64 / texture.height as f64;
    let (w, h) = (
        2.1 * z * WIDTH as f64 / FOCAL_PX / 2.0 + BASELINE_M,
        2.1 * z * HEIGHT as f64 / FOCAL_PX / 2.0,
    );
    let size = if w / h > aspect {
        [w, w / aspect]
    } else {
        [h * aspect, h]
    };
    Panel::new(
        [BASELINE_M / 2.0, 0.0, z],
        size,
        plane_axes(0.0, 0.0, 0.0),
        texture,
    )
}

fn scenes(t: &mut Textures) -> Result<Vec<Scene>, String> {
    let mut out = Vec::new();
    // Wooden planks: the right edge of the coffee photograph, where only the table shows.
    let coffee = t.get("coffee")?;
    let wood = Arc::new(coffee.crop(480, 0, 120, 400));

    // A poster on a slanted board before a mural.
    out.push(Scene {
        name: "syn-poster",
        what: "a photograph (astronaut) on a board 1.15 m wide at 1.2 m, turned 25 degrees, \
               before a wall at 2 m with a mural (rocket)",
        panels: vec![
            mural(2.0, t.get("rocket")?).shaded(0.9),
            print(
                [0.03, -0.02, 1.2],
                1.15,
                25.0,
                -4.0,
                1.5,
                t.get("astronaut")?,
            )
            .shaded(0.95),
        ],
        photos: vec!["rocket", "astronaut"],
        notes: vec![],
    });

    // A map and a photograph lying on gravel, looked at from above at a slant.
    let ground_axes = plane_axes(-8.0, 58.0, 0.0);
    let ground_centre = [0.0, 0.05, 1.0];
    let mut rng = Lcg::new(11);
    let map = Arc::new(Texture::from_gray(
        900,
        640,
        &printed_map(900, 640, &mut rng),
    ));
    out.push(Scene {
        name: "syn-map",
        what: "a printed map (0.8 x 0.57 m) and a photograph (coffee, 0.3 m) lying on gravel, \
               seen obliquely from 0.6 m (bottom) to 5.5 m (top)",
        panels: vec![
            Panel::new(
                on_plane(ground_centre, ground_axes, [0.0, -5.0], 0.0),
                [8.0, 12.0],
                ground_axes,
                t.get("gravel")?,
            )
            .repeated([16.0, 24.0])
            .shaded(0.9),
            Panel::new(
                on_plane(ground_centre, ground_axes, [-0.05, 0.05], 0.002),
                [0.8, 0.8 * 640.0 / 900.0],
                plane_axes(-8.0, 58.0, 9.0),
                map,
            )
            .shaded(1.1),
            print(
                on_plane(ground_centre, ground_axes, [0.3, -0.5], 0.003),
                0.3,
                -8.0,
                58.0,
                -20.0,
                coffee.clone(),
            ),
        ],
        photos: vec!["gravel", "coffee"],
        notes: vec![
            "- the map: a map-like texture generated by videt_evaluation::synthetic::printed_map \
             (seed 11)\n"
                .into(),
        ],
    });

    // A page on a tilted board above a wooden desk with a sheet of notes, before a wall.
    let desk_axes = plane_axes(5.0, 62.0, 0.0);
    let desk_centre = [0.0, 0.25, 1.0];
    out.push(Scene {
        name: "syn-page",
        what: "a printed page (0.42 m wide) on a board at 0.6 m tilted 35 degrees, above a \
               wooden desk with a sheet of handwritten notes and a photograph (chelsea), before \
               a plastered wall at 1.8 m",
        panels: vec![
            mural(1.8, t.get("gravel")?)
                .repeated([3.0, 3.0])
                .shaded(0.75),
            Panel::new(desk_centre, [3.0, 3.0], desk_axes, wood.clone()).repeated([10.0, 3.0]),
            print(
                on_plane(desk_centre, desk_axes, [-0.35, -0.1], 0.002),
                0.45,
                5.0,
                62.0,
                -12.0,
                t.get("text")?,
            )
            .shaded(1.1),
            print(
                on_plane(desk_centre, desk_axes, [0.4, -0.35], 0.002),
                0.3,
                5.0,
                62.0,
                8.0,
                t.get("chelsea")?,
            ),
            print([0.02, -0.01, 0.6], 0.42, -10.0, 35.0, 0.0, t.get("page")?).shaded(1.05),
        ],
        photos: vec!["gravel", "coffee", "text", "chelsea", "page"],
        notes: vec!["  (the desk's wood: the right edge of coffee.png, tiled)\n".into()],
    });

    // A desk: prints standing at several depths and slants before a hedge.
    out.push(Scene {
        name: "syn-desk",
        what: "five prints (camera, chelsea, coffee, gravel, text) from 0.6 to 1.5 m at various \
               slants before a hedge (grass) at 2.2 m",
        panels: vec![
            mural(2.2, t.get("grass")?)
                .repeated([4.0, 3.0])
                .shaded(0.85),
            print([-0.45, -0.18, 1.5], 0.55, 20.0, 0.0, 0.0, t.get("camera")?),
            print([0.38, -0.22, 1.2], 0.6, -25.0, 10.0, 2.0, t.get("chelsea")?).shaded(1.05),
            print([-0.12, 0.17, 0.9], 0.45, 12.0, 30.0, -3.0, coffee.clone()).shaded(0.95),
            print([0.27, 0.14, 0.72], 0.26, -35.0, 0.0, 0.0, t.get("gravel")?).shaded(1.1),
            print([-0.2, 0.06, 0.62], 0.3, 15.0, -20.0, 6.0, t.get("text")?).shaded(1.15),
        ],
        photos: vec!["grass", "camera", "chelsea", "coffee", "gravel", "text"],
        notes: vec![],
    });

    // A shelf: six panels at depths 0.55 to 2 m before a plastered wall.
    out.push(Scene {
        name: "syn-shelf",
        what: "six panels (astronaut, rocket, a brick pavement, page, grass, camera) from 0.55 \
               to 2 m before a plastered wall (gravel) at 2.8 m",
        panels: vec![
            mural(2.8, t.get("gravel")?)
                .repeated([4.0, 4.0])
                .shaded(0.8),
            print(
                [-0.55, -0.15, 2.0],
                0.8,
                15.0,
                0.0,
                0.0,
                t.get("astronaut")?,
            ),
            print([0.5, -0.3, 1.6], 0.75, -10.0, -10.0, 0.0, t.get("rocket")?),
            print([0.02, 0.16, 1.1], 0.45, 32.0, 5.0, 0.0, t.get("brick")?).shaded(0.9),
            print([0.3, 0.12, 0.8], 0.3, -20.0, 20.0, -4.0, t.get("page")?).shaded(1.1),
            print([-0.28, 0.2, 0.66], 0.22, 40.0, 0.0, 0.0, t.get("grass")?),
            print(
                [0.06, -0.12, 0.56],
                0.16,
                -15.0,
                10.0,
                0.0,
                t.get("camera")?,
            ),
        ],
        photos: vec![
            "gravel",
            "astronaut",
            "rocket",
            "brick",
            "page",
            "grass",
            "camera",
        ],
        notes: vec![],
    });
    Ok(out)
}

/// The two cameras' imperfections for the scene numbered `k`: the right camera a little
/// brighter, lower in offset, blurrier and more vignetted than the left.
fn imaging(k: u64) -> [Imaging; 2] {
    [
        Imaging {
            blur_sigma_px: 0.7,
            vignetting: 0.10,
            gain: 1.0,
            offset: 0.0,
            noise_sigma: 2.0,
            seed: 1000 + 2 * k,
        },
        Imaging {
            blur_sigma_px: 0.85,
            vignetting: 0.14,
            gain: 1.05,
            offset: -4.0,
            noise_sigma: 2.0,
            seed: 1001 + 2 * k,
        },
    ]
}

/// The largest integer scale (at most 16) that keeps `max_d x scale` within 8 bits.
fn scale_for(max_d: f32) -> u32 {
    ((255.0 / max_d.max(1.0)).floor() as u32).clamp(1, 16)
}

/// An 8-bit ground truth as a binary PGM (P5): `round(d x scale)`, 0 where unknown (never 0
/// where known).
fn to_pgm(values: &[f32], w: usize, h: usize, scale: u32) -> Vec<u8> {
    let mut out = format!("P5\n{w} {h}\n255\n").into_bytes();
    out.extend(values.iter().map(|&d| {
        if d.is_finite() && d > 0.0 {
            (d * scale as f32).round().clamp(1.0, 255.0) as u8
        } else {
            0
        }
    }));
    out
}

/// The disparity range of the known values, and the median |left - right| grey-level
/// difference at the true correspondences `(x, y) -> (round(x - d), y)` of the known pixels.
fn check(left: &[u8], right: &[u8], truth: &[f32], w: usize) -> (f32, f32, f32) {
    let (mut lo, mut hi) = (f32::MAX, f32::MIN);
    let mut diffs = Vec::new();
    for (i, &d) in truth.iter().enumerate() {
        if !d.is_finite() {
            continue;
        }
        lo = lo.min(d);
        hi = hi.max(d);
        let (x, y) = (i % w, i / w);
        let xr = (x as f32 - d).round();
        if xr >= 0.0 {
            diffs.push((i32::from(left[i]) - i32::from(right[y * w + xr as usize])).unsigned_abs());
        }
    }
    diffs.sort_unstable();
    let median = diffs.get(diffs.len() / 2).map_or(f32::NAN, |&v| v as f32);
    (lo, hi, median)
}

/// Sets to unknown the left pixels whose point the right camera cannot see: the left map is
/// warped into the right view (neighbours within 1 px of each other taken as one surface,
/// filled between), keeping the nearest point at each right pixel; a left pixel is hidden
/// when that nearest point is more than 1 px of disparity nearer than its own.
fn mask_occluded(truth: &mut [f32], w: usize, h: usize) {
    for y in 0..h {
        let row = &mut truth[y * w..(y + 1) * w];
        let mut nearest = vec![f32::MIN; w];
        let mut splat = |xr: f32, d: f32| {
            let p = xr.round();
            if p >= 0.0 && (p as usize) < w {
                let n = &mut nearest[p as usize];
                *n = n.max(d);
            }
        };
        for x in 0..w {
            let d = row[x];
            if !d.is_finite() {
                continue;
            }
            splat(x as f32 - d, d);
            let Some(&d1) = row.get(x + 1) else { continue };
            if d1.is_finite() && (d1 - d).abs() <= 1.0 {
                // One surface from x to x + 1: every right pixel between.
                let (a, b) = (x as f32 - d, x as f32 + 1.0 - d1);
                let mut p = a.min(b).ceil();
                while p <= a.max(b) {
                    let t = if b != a { (p - a) / (b - a) } else { 0.0 };
                    splat(p, d + t * (d1 - d));
                    p += 1.0;
                }
            }
        }
        for x in 0..w {
            let d = row[x];
            let p = (x as f32 - d).round();
            if d.is_finite() && p >= 0.0 && nearest[p as usize] > d + 1.0 {
                row[x] = f32::NAN;
            }
        }
    }
}

/// Writes a pair directory atomically (into `NAME.tmp`, then renamed).
fn write_pair(
    out: &Path,
    name: &str,
    left: &image::GrayImage,
    right: &image::GrayImage,
    disp: [Option<&[f32]>; 2],
    attribution: &str,
) -> Result<u32, Box<dyn std::error::Error>> {
    let (w, h) = (left.width() as usize, left.height() as usize);
    let max_d = disp
        .iter()
        .flatten()
        .flat_map(|d| d.iter().copied().filter(|v| v.is_finite()))
        .fold(0f32, f32::max);
    let scale = scale_for(max_d);
    let tmp = out.join(format!("{name}.tmp"));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp)?;
    }
    std::fs::create_dir_all(&tmp)?;
    left.save(tmp.join("left.png"))?;
    right.save(tmp.join("right.png"))?;
    for (side, d) in ["left", "right"].iter().zip(disp) {
        if let Some(d) = d {
            std::fs::write(tmp.join(format!("disp_{side}.pgm")), to_pgm(d, w, h, scale))?;
        }
    }
    std::fs::write(tmp.join("scale.txt"), format!("{scale}\n"))?;
    std::fs::write(tmp.join("ATTRIBUTION.txt"), attribution)?;
    let dest = out.join(name);
    if dest.exists() {
        std::fs::remove_dir_all(&dest)?;
    }
    std::fs::rename(&tmp, &dest)?;
    Ok(scale)
}

fn synthesise(
    texture_dir: &Path,
    out: &Path,
    force: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut textures = Textures {
        dir: texture_dir.to_path_buf(),
        loaded: BTreeMap::new(),
    };
    let rig = Rig::new(WIDTH, HEIGHT, FOCAL_PX, BASELINE_M);
    std::fs::create_dir_all(out)?;
    for (k, scene) in scenes(&mut textures)?.into_iter().enumerate() {
        if !force && out.join(scene.name).join("disp_left.pgm").exists() {
            println!("{}: already there", scene.name);
            continue;
        }
        let [l, r] = imaging(k as u64);
        let pair = render_rig(&rig, &scene.panels, [&l, &r]);
        let image = |v: Vec<u8>| image::GrayImage::from_raw(WIDTH as u32, HEIGHT as u32, v);
        let (left, right) = (
            image(pair.left).ok_or("size")?,
            image(pair.right).ok_or("size")?,
        );
        // Check on the non-occluded pixels, as the evaluation sees them.
        let mut visible = pair.disparity_left.clone();
        for (i, d) in visible.iter_mut().enumerate() {
            let (x, y) = ((i % WIDTH) as f32, i / WIDTH);
            let xr = (x - *d).round();
            let seen =
                xr >= 0.0 && (pair.disparity_right[y * WIDTH + xr as usize] - *d).abs() <= 1.0;
            if !seen {
                *d = f32::NAN;
            }
        }
        let (lo, hi, median) = check(left.as_raw(), right.as_raw(), &visible, WIDTH);
        let occluded = visible.iter().filter(|d| d.is_nan()).count() as f64 / visible.len() as f64;
        let attribution = format!(
            "Synthesised rectified pair `{}`: {}.\n\
             Rendered by videt_evaluation::synthetic::render_rig: a pinhole pair {WIDTH}x{HEIGHT}, \
             focal {FOCAL_PX} px, baseline {BASELINE_M} m; per camera Gaussian optical blur \
             (left {} px, right {} px), vignetting ({}, {}), gain/offset (left {}/{}, right {}/{}), \
             Gaussian sensor noise of {} grey levels; textures sampled bilinearly, {}x{} rays per \
             pixel. The ground truth is exact up to its 8 bits (disp_left.pgm, disp_right.pgm: \
             disparity x scale.txt): the left pixel at x matches the right pixel at x - disparity.\n\n\
             Photographs (grey), as distributed in scikit-image's sample data \
             (skimage/data):\n{}{}",
            scene.name,
            scene.what,
            l.blur_sigma_px,
            r.blur_sigma_px,
            l.vignetting,
            r.vignetting,
            l.gain,
            l.offset,
            r.gain,
            r.offset,
            l.noise_sigma,
            rig.supersampling,
            rig.supersampling,
            textures.attribution(&scene.photos),
            scene.notes.concat(),
        );
        let scale = write_pair(
            out,
            scene.name,
            &left,
            &right,
            [Some(&pair.disparity_left), Some(&pair.disparity_right)],
            &attribution,
        )?;
        println!(
            "{}: {WIDTH}x{HEIGHT}, disparity {lo:.1}..{hi:.1} px, ground truth x{scale}, \
             {:.1} % occluded, median |left - right| {median} grey levels",
            scene.name,
            100.0 * occluded
        );
    }
    Ok(())
}

/// 2 x 2 means of an 8-bit image.
fn halve_image(img: &image::GrayImage) -> image::GrayImage {
    let (w, h) = (img.width() / 2, img.height() / 2);
    image::GrayImage::from_fn(w, h, |x, y| {
        let s: u32 = [(0, 0), (1, 0), (0, 1), (1, 1)]
            .iter()
            .map(|&(dx, dy)| u32::from(img.get_pixel(2 * x + dx, 2 * y + dy)[0]))
            .sum();
        image::Luma([((s + 2) / 4) as u8])
    })
}

/// 2 x 2 means of a disparity map, halved (unknown where a value is unknown or the four
/// disagree by more than 1 px: a depth edge).
fn halve_truth(d: &[f32], w: usize, h: usize) -> Vec<f32> {
    let (hw, hh) = (w / 2, h / 2);
    let mut out = vec![f32::NAN; hw * hh];
    for y in 0..hh {
        for x in 0..hw {
            let v =
                [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(dx, dy)| d[(2 * y + dy) * w + 2 * x + dx]);
            let (lo, hi) = v
                .iter()
                .fold((f32::MAX, f32::MIN), |(a, b), &c| (a.min(c), b.max(c)));
            if v.iter().all(|c| c.is_finite()) && hi - lo <= 1.0 {
                out[y * hw + x] = v.iter().sum::<f32>() / 8.0;
            }
        }
    }
    out
}

fn import(args: &[String], force: bool) -> Result<(), Box<dyn std::error::Error>> {
    let [name, left, right, disp, scale, attribution, out] = args else {
        return Err("--import NAME LEFT RIGHT DISP_LEFT SCALE ATTRIBUTION OUT_DIR".into());
    };
    let out = Path::new(out);
    if !force && out.join(name).join("disp_left.pgm").exists() {
        println!("{name}: already there");
        return Ok(());
    }
    let scale: f32 = scale.parse()?;
    let mut left = image::open(left)?.to_luma8();
    let mut right = image::open(right)?.to_luma8();
    let gt = image::open(disp)?.to_luma8();
    if left.dimensions() != right.dimensions() || left.dimensions() != gt.dimensions() {
        return Err("the images and the ground truth differ in size".into());
    }
    let (mut w, mut h) = (left.width() as usize, left.height() as usize);
    let mut truth: Vec<f32> = gt
        .as_raw()
        .iter()
        .map(|&v| {
            if v == 0 {
                f32::NAN
            } else {
                f32::from(v) / scale
            }
        })
        .collect();
    while w / 2 >= WIDTH && h / 2 >= HEIGHT {
        left = halve_image(&left);
        right = halve_image(&right);
        truth = halve_truth(&truth, w, h);
        (w, h) = (w / 2, h / 2);
    }
    let (cw, ch) = (w.min(WIDTH), h.min(HEIGHT));
    let (x0, y0) = ((w - cw) / 2, (h - ch) / 2);
    let crop = |img: &image::GrayImage| {
        image::imageops::crop_imm(img, x0 as u32, y0 as u32, cw as u32, ch as u32).to_image()
    };
    let (left, right) = (crop(&left), crop(&right));
    let mut truth: Vec<f32> = (0..ch)
        .flat_map(|y| truth[(y0 + y) * w + x0..(y0 + y) * w + x0 + cw].to_vec())
        .collect();
    let known = truth.iter().filter(|d| d.is_finite()).count();
    mask_occluded(&mut truth, cw, ch);
    let visible = truth.iter().filter(|d| d.is_finite()).count();
    let (lo, hi, median) = check(left.as_raw(), right.as_raw(), &truth, cw);
    let attribution = std::fs::read_to_string(attribution)?;
    let scale_out = write_pair(out, name, &left, &right, [Some(&truth), None], &attribution)?;
    println!(
        "{name}: {cw}x{ch}, disparity {lo:.1}..{hi:.1} px, ground truth x{scale_out}, \
         {:.1} % of the known pixels occluded, median |left - right| {median} grey levels",
        100.0 * (known - visible) as f64 / known.max(1) as f64
    );
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let force = args.iter().any(|a| a == "--force");
    let args: Vec<String> = args.into_iter().filter(|a| a != "--force").collect();
    match args.as_slice() {
        [flag, rest @ ..] if flag == "--import" => import(rest, force),
        [textures, out] => synthesise(Path::new(textures), Path::new(out), force),
        _ => Err("usage: synthesise_stereo TEXTURE_DIR OUT_DIR [--force] | \
                  --import NAME LEFT RIGHT DISP_LEFT SCALE ATTRIBUTION OUT_DIR [--force]"
            .into()),
    }
}
