//! The bas-relief model and its real-time queries: height and interpolated normal under a
//! point, penetration depth, the first crossing of a motion, and the paper's distance to impact
//! along the direction of the last two finger positions.
//!
//! The surface is a height field `z = h(x, y)` over the explorable area (solid on the `+z` side),
//! continued beyond the area by the back plane. Queries allocate nothing: a point query reads
//! one grid cell's short triangle list; a motion walks the cells it crosses (at most
//! `nx + ny + 2`), testing each listed triangle once per cell.

use videt_control::relief::{height_field_contact, HeightSample, ReliefSurface, SegmentHit};
use videt_control::{Contact, Surface, Vec3};

use crate::clip::clip_to_rect;
use crate::grid::TriangleGrid;
use crate::input::ReliefParams;

/// Barycentric tolerance for "inside a triangle".
const BARY_EPS: f64 = 1e-9;

/// Per-triangle precomputed geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TriangleGeometry {
    /// First vertex `(x, y, z)`.
    origin: [f64; 3],
    /// Maps `(x - x0, y - y0)` to barycentrics `(l1, l2)`: row-major 2x2.
    to_bary: [f64; 4],
    /// `z = z0 + gx (x - x0) + gy (y - y0)`.
    gradient: [f64; 2],
    /// Outward unit normal of the face.
    face_normal: [f64; 3],
    /// Degenerate (no area on the plane): skipped by queries.
    degenerate: bool,
}

/// The paper's impact: where the finger's current motion, continued, meets the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Impact {
    /// Distance from the current position to the impact point, metres.
    pub distance_m: f64,
    /// The impact point, metres.
    pub point_m: Vec3,
    /// Interpolated outward normal there.
    pub normal: Vec3,
}

/// Size figures of a model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelStats {
    /// Vertices.
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Grid cells along `x` and `y`.
    pub grid_cells: [usize; 2],
    /// Most triangles in one grid cell.
    pub max_triangles_per_cell: usize,
    /// Triangle-cell entries.
    pub grid_entries: usize,
}

/// A bas-relief surface: a triangulated height field with per-vertex normals and a grid.
#[derive(Debug, Clone, PartialEq)]
pub struct ReliefModel {
    area: [f64; 4],
    back_z: f64,
    vertices: Vec<[f64; 3]>,
    normals: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
    geometry: Vec<TriangleGeometry>,
    grid: TriangleGrid,
    grid_cells_per_triangle: f64,
}

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if n > 0.0 && n.is_finite() {
        [v[0] / n, v[1] / n, v[2] / n]
    } else {
        [0.0, 0.0, -1.0]
    }
}

impl ReliefModel {
    /// A model from a mesh: vertices `(x, y, z)` and triangles (counter-clockwise on the `x`-`y`
    /// plane, covering `area = [x0, y0, x1, y1]`), with the back plane `back_z` beyond the area.
    pub fn from_mesh(
        vertices: Vec<[f64; 3]>,
        triangles: Vec<[u32; 3]>,
        area: [f64; 4],
        back_z: f64,
        params: &ReliefParams,
    ) -> ReliefModel {
        ReliefModel::from_mesh_with_grid(
            vertices,
            triangles,
            area,
            back_z,
            params.grid_cells_per_triangle,
        )
    }

    /// [`ReliefModel::from_mesh`] with only the setting it uses: the acceleration grid's cells
    /// per triangle (a recorded model is rebuilt with it).
    pub fn from_mesh_with_grid(
        vertices: Vec<[f64; 3]>,
        triangles: Vec<[u32; 3]>,
        area: [f64; 4],
        back_z: f64,
        grid_cells_per_triangle: f64,
    ) -> ReliefModel {
        let mut normals = vec![[0.0f64; 3]; vertices.len()];
        let mut geometry = Vec::with_capacity(triangles.len());
        let mut flat = Vec::with_capacity(triangles.len());
        for t in &triangles {
            let [p0, p1, p2] = t.map(|i| vertices[i as usize]);
            let e1 = [p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]];
            let e2 = [p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]];
            // e1 x e2 points to +z for a counter-clockwise triangle; the outward normal is its
            // opposite. Its length is twice the area: the area weighting of vertex normals.
            let c = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            let outward = [-c[0], -c[1], -c[2]];
            for &i in t {
                let n = &mut normals[i as usize];
                for k in 0..3 {
                    n[k] += outward[k];
                }
            }
            let det = e1[0] * e2[1] - e1[1] * e2[0];
            let scale = (e1[0].abs() + e1[1].abs()) * (e2[0].abs() + e2[1].abs());
            let degenerate = !(det.abs() > 1e-14 * scale && det.is_finite());
            let inv = if degenerate { 0.0 } else { 1.0 / det };
            let to_bary = [e2[1] * inv, -e2[0] * inv, -e1[1] * inv, e1[0] * inv];
            // z - z0 = dz1 l1 + dz2 l2 with (l1, l2) = M^-1 (x - x0, y - y0).
            let gradient = [
                e1[2] * to_bary[0] + e2[2] * to_bary[2],
                e1[2] * to_bary[1] + e2[2] * to_bary[3],
            ];
            geometry.push(TriangleGeometry {
                origin: p0,
                to_bary,
                gradient,
                face_normal: normalize([gradient[0], gradient[1], -1.0]),
                degenerate,
            });
            flat.push([[p0[0], p0[1]], [p1[0], p1[1]], [p2[0], p2[1]]]);
        }
        for n in &mut normals {
            *n = normalize(*n);
        }
        let grid = TriangleGrid::build(area, &flat, grid_cells_per_triangle);
        ReliefModel {
            area,
            back_z,
            vertices,
            normals,
            triangles,
            geometry,
            grid,
            grid_cells_per_triangle,
        }
    }

    /// The acceleration grid's cells per triangle the model was built with: with the mesh, the
    /// area and the back plane, what [`ReliefModel::from_mesh`] needs to rebuild it exactly.
    pub fn grid_cells_per_triangle(&self) -> f64 {
        self.grid_cells_per_triangle
    }

    /// Vertices `(x, y, z)`, metres.
    pub fn vertices(&self) -> &[[f64; 3]] {
        &self.vertices
    }

    /// Per-vertex outward unit normals (area-weighted).
    pub fn vertex_normals(&self) -> &[[f64; 3]] {
        &self.normals
    }

    /// Triangles (vertex indices, counter-clockwise on the `x`-`y` plane).
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The explorable area `[x0, y0, x1, y1]`, metres.
    pub fn area_m(&self) -> [f64; 4] {
        self.area
    }

    /// The back plane's `z`, metres.
    pub fn back_plane_z_m(&self) -> f64 {
        self.back_z
    }

    /// Size figures.
    pub fn stats(&self) -> ModelStats {
        ModelStats {
            vertices: self.vertices.len(),
            triangles: self.triangles.len(),
            grid_cells: self.grid.dimensions(),
            max_triangles_per_cell: self.grid.max_per_cell(),
            grid_entries: self.grid.entries(),
        }
    }

    fn inside_area(&self, x: f64, y: f64) -> bool {
        x >= self.area[0] && x <= self.area[2] && y >= self.area[1] && y <= self.area[3]
    }

    /// Barycentrics of `(x, y)` in triangle `k`.
    fn bary(&self, k: usize, x: f64, y: f64) -> [f64; 3] {
        let g = &self.geometry[k];
        let (dx, dy) = (x - g.origin[0], y - g.origin[1]);
        let l1 = g.to_bary[0] * dx + g.to_bary[1] * dy;
        let l2 = g.to_bary[2] * dx + g.to_bary[3] * dy;
        [1.0 - l1 - l2, l1, l2]
    }

    /// The triangle under `(x, y)` (inside the area) and the barycentrics there.
    fn locate(&self, x: f64, y: f64) -> Option<(usize, [f64; 3])> {
        let [ix, iy] = self.grid.cell_xy(x, y);
        let mut best: Option<(usize, [f64; 3], f64)> = None;
        for &k in self.grid.cell(ix, iy) {
            let k = k as usize;
            if self.geometry[k].degenerate {
                continue;
            }
            let b = self.bary(k, x, y);
            let worst = b[0].min(b[1]).min(b[2]);
            if worst >= -BARY_EPS {
                return Some((k, b));
            }
            if best.is_none_or(|(_, _, w)| worst > w) {
                best = Some((k, b, worst));
            }
        }
        best.map(|(k, b, _)| (k, b))
    }

    fn plane_z(&self, k: usize, x: f64, y: f64) -> f64 {
        let g = &self.geometry[k];
        g.origin[2] + g.gradient[0] * (x - g.origin[0]) + g.gradient[1] * (y - g.origin[1])
    }

    fn back_plane_sample(&self) -> HeightSample {
        HeightSample {
            z_m: self.back_z,
            normal: -Vec3::z(),
            face_normal: -Vec3::z(),
        }
    }

    /// The surface under `(x_m, y_m)`: height and normals (the back plane beyond the area).
    pub fn height_at(&self, x_m: f64, y_m: f64) -> Option<HeightSample> {
        if !(x_m.is_finite() && y_m.is_finite()) {
            return None;
        }
        if !self.inside_area(x_m, y_m) {
            return Some(self.back_plane_sample());
        }
        let Some((k, b)) = self.locate(x_m, y_m) else {
            return Some(self.back_plane_sample());
        };
        let t = self.triangles[k];
        let mut n = [0.0; 3];
        for (i, &v) in t.iter().enumerate() {
            let vn = self.normals[v as usize];
            let w = b[i].clamp(0.0, 1.0);
            for c in 0..3 {
                n[c] += w * vn[c];
            }
        }
        let n = normalize(n);
        Some(HeightSample {
            z_m: self.plane_z(k, x_m, y_m),
            normal: Vec3::new(n[0], n[1], n[2]),
            face_normal: Vec3::from(self.geometry[k].face_normal),
        })
    }

    /// First crossing into the solid of the motion `from -> to` (see [`ReliefSurface`]).
    pub fn first_hit(&self, from: &Vec3, to: &Vec3) -> Option<SegmentHit> {
        if !(from.iter().chain(to.iter()).all(|c| c.is_finite())) {
            return None;
        }
        let here = self.height_at(from.x, from.y)?;
        if from.z >= here.z_m {
            return Some(SegmentHit {
                t: 0.0,
                point_m: *from,
                face_normal: here.face_normal,
            });
        }
        let d = to - from;
        let plane_hit = |t_lo: f64, t_hi: f64| -> Option<SegmentHit> {
            if d.z <= 0.0 {
                return None;
            }
            let t = (self.back_z - from.z) / d.z;
            (t >= t_lo && t <= t_hi).then(|| SegmentHit {
                t,
                point_m: from + d * t,
                face_normal: -Vec3::z(),
            })
        };
        let clip = clip_to_rect([from.x, from.y], [to.x, to.y], self.area);
        let Some((t_in, t_out)) = clip else {
            return plane_hit(0.0, 1.0);
        };
        if t_in > 0.0 {
            if let Some(h) = plane_hit(0.0, t_in) {
                return Some(h);
            }
        }
        let mut best: Option<(f64, usize)> = None;
        self.grid
            .walk([from.x, from.y], [d.x, d.y], t_in, t_out, |cell, t_exit| {
                for &k in cell {
                    let k = k as usize;
                    let g = &self.geometry[k];
                    if g.degenerate {
                        continue;
                    }
                    let h0 = from.z - self.plane_z(k, from.x, from.y);
                    let hd = d.z - (g.gradient[0] * d.x + g.gradient[1] * d.y);
                    if hd <= 0.0 {
                        continue;
                    }
                    let t = -h0 / hd;
                    if !(0.0..=1.0).contains(&t) || best.is_some_and(|(b, _)| t >= b) {
                        continue;
                    }
                    let b = self.bary(k, from.x + d.x * t, from.y + d.y * t);
                    if b[0].min(b[1]).min(b[2]) >= -BARY_EPS {
                        best = Some((t, k));
                    }
                }
                best.is_some_and(|(t, _)| t <= t_exit)
            });
        if let Some((t, k)) = best {
            return Some(SegmentHit {
                t,
                point_m: from + d * t,
                face_normal: Vec3::from(self.geometry[k].face_normal),
            });
        }
        if t_out < 1.0 {
            return plane_hit(t_out, 1.0);
        }
        None
    }

    /// The paper's distance to impact: continue the motion from `previous_m` to `current_m`
    /// beyond `current_m` (at most `max_distance_m`) and return where it meets the surface.
    /// `None` when the finger is not moving or the ray misses.
    pub fn impact(
        &self,
        previous_m: &Vec3,
        current_m: &Vec3,
        max_distance_m: f64,
    ) -> Option<Impact> {
        let d = current_m - previous_m;
        let len = d.norm();
        if !(len > 1e-12 && len.is_finite() && max_distance_m > 0.0 && max_distance_m.is_finite()) {
            return None;
        }
        let end = current_m + d * (max_distance_m / len);
        let hit = self.first_hit(current_m, &end)?;
        let normal = self
            .height_at(hit.point_m.x, hit.point_m.y)
            .map_or(hit.face_normal, |h| h.normal);
        Some(Impact {
            distance_m: hit.t * max_distance_m,
            point_m: hit.point_m,
            normal,
        })
    }

    /// Brute force reference of [`ReliefModel::height_at`]: scans every triangle (for tests
    /// and benchmarks).
    pub fn height_at_brute_force(&self, x_m: f64, y_m: f64) -> Option<f64> {
        if !(x_m.is_finite() && y_m.is_finite()) {
            return None;
        }
        if !self.inside_area(x_m, y_m) {
            return Some(self.back_z);
        }
        let mut best: Option<(usize, f64)> = None;
        for k in 0..self.triangles.len() {
            if self.geometry[k].degenerate {
                continue;
            }
            let b = self.bary(k, x_m, y_m);
            let worst = b[0].min(b[1]).min(b[2]);
            if worst >= -BARY_EPS {
                return Some(self.plane_z(k, x_m, y_m));
            }
            if best.is_none_or(|(_, w)| worst > w) {
                best = Some((k, worst));
            }
        }
        best.map(|(k, _)| self.plane_z(k, x_m, y_m))
    }

    /// Brute force reference of [`ReliefModel::first_hit`]'s `t` inside the area: tests every
    /// triangle.
    pub fn first_hit_brute_force(&self, from: &Vec3, to: &Vec3) -> Option<f64> {
        let d = to - from;
        let mut best: Option<f64> = None;
        for k in 0..self.triangles.len() {
            let g = &self.geometry[k];
            if g.degenerate {
                continue;
            }
            let h0 = from.z - self.plane_z(k, from.x, from.y);
            let hd = d.z - (g.gradient[0] * d.x + g.gradient[1] * d.y);
            if hd <= 0.0 {
                continue;
            }
            let t = -h0 / hd;
            if !(0.0..=1.0).contains(&t) || best.is_some_and(|b| t >= b) {
                continue;
            }
            let b = self.bary(k, from.x + d.x * t, from.y + d.y * t);
            if b[0].min(b[1]).min(b[2]) >= -BARY_EPS {
                best = Some(t);
            }
        }
        best
    }
}

impl Surface for ReliefModel {
    fn contact(&self, position_m: &Vec3) -> Option<Contact> {
        height_field_contact(self, position_m)
    }
}

impl ReliefSurface for ReliefModel {
    fn height(&self, x_m: f64, y_m: f64) -> Option<HeightSample> {
        self.height_at(x_m, y_m)
    }

    fn segment_hit(&self, from_m: &Vec3, to_m: &Vec3) -> Option<SegmentHit> {
        self.first_hit(from_m, to_m)
    }
}
