//! Looking at the surface: the mesh as PLY, and a shaded depth image as PNG.

use std::io::Write;
use std::path::Path;

use crate::model::ReliefModel;

/// Writing a file failed.
#[derive(Debug)]
pub struct ExportError {
    /// The file.
    pub path: std::path::PathBuf,
    /// What went wrong.
    pub message: String,
}

impl core::fmt::Display for ExportError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "cannot write {}: {}", self.path.display(), self.message)
    }
}

impl std::error::Error for ExportError {}

/// Write `bytes` to `path` atomically: a temporary file beside it, flushed to disk, then renamed.
fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    let err = |e: std::io::Error| ExportError {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = std::path::PathBuf::from(tmp);
    let mut f = std::fs::File::create(&tmp).map_err(err)?;
    f.write_all(bytes).map_err(err)?;
    f.sync_all().map_err(err)?;
    drop(f);
    std::fs::rename(&tmp, path).map_err(err)
}

/// The mesh as ASCII PLY: vertices with their outward normals (metres), triangles.
pub fn ply_text(model: &ReliefModel) -> String {
    use std::fmt::Write as _;
    let v = model.vertices();
    let n = model.vertex_normals();
    let t = model.triangles();
    let mut s = String::with_capacity(64 * (v.len() + t.len()) + 256);
    let _ = write!(
        s,
        "ply\nformat ascii 1.0\ncomment VIDET bas-relief surface, device frame, metres\n\
         element vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
         property double nx\nproperty double ny\nproperty double nz\n\
         element face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        v.len(),
        t.len()
    );
    for (p, q) in v.iter().zip(n) {
        let _ = writeln!(s, "{} {} {} {} {} {}", p[0], p[1], p[2], q[0], q[1], q[2]);
    }
    for f in t {
        let _ = writeln!(s, "3 {} {} {}", f[0], f[1], f[2]);
    }
    s
}

/// Write the mesh as ASCII PLY to `path` (atomically).
pub fn write_ply(model: &ReliefModel, path: &Path) -> Result<(), ExportError> {
    write_atomically(path, ply_text(model).as_bytes())
}

/// A shaded depth image of the relief, `width_px` wide (the area's aspect), image-up = `+y`:
/// brightness is nearness to the user (the back plane dark), modulated by Lambert shading of the
/// interpolated normals under a light from the upper left.
pub fn depth_image(model: &ReliefModel, width_px: u32) -> image::GrayImage {
    let [x0, y0, x1, y1] = model.area_m();
    let w = width_px.clamp(2, 8192);
    let h = (((y1 - y0) / (x1 - x0)) * w as f64)
        .round()
        .clamp(2.0, 8192.0) as u32;
    let back = model.back_plane_z_m();
    let nearest = model.vertices().iter().map(|v| v[2]).fold(back, f64::min);
    let range = (back - nearest).max(1e-9);
    // Light from the upper left, towards the surface (+z).
    let light = {
        let l = [-0.5f64, 0.5, -1.0];
        let n = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
        [l[0] / n, l[1] / n, l[2] / n]
    };
    image::GrayImage::from_fn(w, h, |i, j| {
        let x = x0 + (i as f64 + 0.5) / w as f64 * (x1 - x0);
        let y = y1 - (j as f64 + 0.5) / h as f64 * (y1 - y0);
        match model.height_at(x, y) {
            Some(s) => {
                let nearness = ((back - s.z_m) / range).clamp(0.0, 1.0);
                let lambert =
                    (s.normal.x * light[0] + s.normal.y * light[1] + s.normal.z * light[2])
                        .max(0.0);
                let v = 40.0 + 150.0 * nearness + 65.0 * lambert;
                image::Luma([v.clamp(0.0, 255.0) as u8])
            }
            None => image::Luma([0]),
        }
    })
}

/// Write the shaded depth image as PNG to `path` (atomically).
pub fn write_depth_png(model: &ReliefModel, width_px: u32, path: &Path) -> Result<(), ExportError> {
    let img = depth_image(model, width_px);
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| ExportError {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    write_atomically(path, &bytes)
}

/// What `videt vision ... --surface` writes: `DIR/surface.ply` and `DIR/surface_depth.png`
/// (640 px wide). Returns the two paths.
pub fn write_surface_outputs(
    model: &ReliefModel,
    dir: &Path,
) -> Result<[std::path::PathBuf; 2], ExportError> {
    let ply = dir.join("surface.ply");
    let png = dir.join("surface_depth.png");
    write_ply(model, &ply)?;
    write_depth_png(model, 640, &png)?;
    Ok([ply, png])
}
