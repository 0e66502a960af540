//! Building the bas-relief from 3D segments and points (paper section 3): map them into the
//! device workspace, clean them, triangulate their projection on the constant-depth plane with a
//! constrained Delaunay triangulation whose prescribed edges are the segments, then lift every
//! vertex to its relief height.
//!
//! Cleaning, each with a reason in the [`BuildReport`]: non-finite coordinates and points behind
//! the camera are rejected; geometry outside the area (inside the frame) is clipped off; points
//! closer than `merge_distance_m` are merged (the nearest height wins: the foreground occludes);
//! segments that collapse are dropped; two segments whose images cross are split at the crossing
//! when their heights agree there, otherwise the farther (occluded) one is kept as points only;
//! overlapping collinear segments keep the nearer one. Building never panics.

use spade::{ConstrainedDelaunayTriangulation, HasPosition, Point2, Triangulation};

use crate::border::NearestHeight;
use crate::cell_hash::CellMap;
use crate::clip::clip_to_rect;
use crate::input::{
    DeviceSegment, PinholeCamera, ReliefParams, ReliefParamsError, ReliefShape, SceneSegment3,
};
use crate::model::ReliefModel;
use crate::steps::{cut_steps, MeshTopology};

/// Which input item a rejection refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputItem {
    /// The segment at this index.
    Segment(usize),
    /// The point at this index.
    Point(usize),
}

/// Why an input item (or part of it) was not used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RejectReason {
    /// A coordinate is NaN or infinite.
    NotFinite,
    /// At or behind the camera (`Z <= 0`).
    BehindCamera,
    /// Entirely outside the explorable area (or inside its frame).
    OutsideArea,
    /// Shorter than the merge distance once mapped.
    Degenerate,
    /// The same segment (same merged endpoints) as another one.
    Duplicate,
    /// Its image crosses a nearer segment's at a different height: occluded, kept as points.
    CrossesNearerSegment {
        /// The nearer segment.
        other: usize,
        /// Height difference at the crossing, metres.
        height_gap_m: f64,
    },
    /// Collinear with and overlapping a nearer segment: kept as points.
    OverlapsSegment {
        /// The nearer segment.
        other: usize,
    },
    /// The triangulation could not insert this constraint piece (numerical conflict).
    TriangulationConflict,
}

impl core::fmt::Display for RejectReason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RejectReason::NotFinite => write!(f, "coordinate not finite"),
            RejectReason::BehindCamera => write!(f, "at or behind the camera (Z <= 0)"),
            RejectReason::OutsideArea => write!(f, "outside the explorable area"),
            RejectReason::Degenerate => write!(f, "shorter than the merge distance"),
            RejectReason::Duplicate => write!(f, "duplicate of another segment"),
            RejectReason::CrossesNearerSegment {
                other,
                height_gap_m,
            } => write!(
                f,
                "crosses nearer segment {other} with a {:.1} mm height gap (occluded; kept as points)",
                height_gap_m * 1e3
            ),
            RejectReason::OverlapsSegment { other } => {
                write!(f, "overlaps nearer segment {other} (kept as points)")
            }
            RejectReason::TriangulationConflict => {
                write!(f, "constraint conflicts in the triangulation")
            }
        }
    }
}

/// One rejected (or partly used) input item.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rejection {
    /// The item.
    pub item: InputItem,
    /// Why.
    pub reason: RejectReason,
}

/// What the build did with its input.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BuildReport {
    /// Segments given.
    pub segments_in: usize,
    /// Points given.
    pub points_in: usize,
    /// Segments kept as constraint edges (possibly split).
    pub constraints_kept: usize,
    /// Constraint edges in the triangulation after splitting (the segments', not the frame's).
    pub constraint_edges: usize,
    /// Crossings split into a shared vertex.
    pub crossings_split: usize,
    /// Input points merged into a nearby one.
    pub points_merged: usize,
    /// Edges of the triangulation found to span a depth step, each cut into a wall
    /// ([`ReliefShape::Stepped`]).
    pub depth_steps: usize,
    /// Vertices of the mesh (frame included).
    pub vertices: usize,
    /// Triangles of the mesh.
    pub triangles: usize,
    /// Everything rejected, with reasons.
    pub rejections: Vec<Rejection>,
    /// Time spent per stage.
    pub timings: BuildTimings,
}

/// Time spent in each stage of a build.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BuildTimings {
    /// Mapping, clipping and merging the input.
    pub cleaning: std::time::Duration,
    /// Resolving crossing and overlapping segments.
    pub crossings: std::time::Duration,
    /// The constrained Delaunay triangulation.
    pub triangulation: std::time::Duration,
    /// Normals, per-triangle geometry and the grid.
    pub model: std::time::Duration,
}

/// The surface could not be built.
#[derive(Debug, Clone, PartialEq)]
pub enum BuildError {
    /// A setting is out of range.
    Params(ReliefParamsError),
    /// Nothing usable remained (every item is listed in the report with its reason).
    NoUsableInput(Box<BuildReport>),
    /// The triangulation failed.
    Triangulation(String),
}

impl core::fmt::Display for BuildError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            BuildError::Params(e) => e.fmt(f),
            BuildError::NoUsableInput(r) => write!(
                f,
                "surface: no usable geometry ({} segments, {} points given, {} rejected)",
                r.segments_in,
                r.points_in,
                r.rejections.len()
            ),
            BuildError::Triangulation(e) => write!(f, "surface: triangulation failed: {e}"),
        }
    }
}

impl std::error::Error for BuildError {}

/// How the height varies along a mapped segment, parametrised by the fraction `s` of its
/// workspace (equivalently image) length.
#[derive(Debug, Clone, Copy, PartialEq)]
enum DepthLaw {
    /// Scene depths `Z` at both ends, metres: `1/Z` is linear in `s` (perspective).
    Scene([f64; 2]),
    /// Relief heights at both ends, metres: linear in `s`.
    Relief([f64; 2]),
}

impl DepthLaw {
    fn relief_z(&self, s: f64, params: &ReliefParams) -> f64 {
        match *self {
            DepthLaw::Scene([za, zb]) => {
                let inv = (1.0 - s) / za + s / zb;
                params.scene_map.scene_depth_to_relief_z(1.0 / inv)
            }
            DepthLaw::Relief([a, b]) => a + (b - a) * s,
        }
    }

    /// The law of the piece `[s0, s1]`, re-parametrised over `[0, 1]`.
    fn piece(&self, s0: f64, s1: f64) -> DepthLaw {
        match *self {
            DepthLaw::Scene([za, zb]) => {
                let z = |s: f64| 1.0 / ((1.0 - s) / za + s / zb);
                DepthLaw::Scene([z(s0), z(s1)])
            }
            DepthLaw::Relief([a, b]) => DepthLaw::Relief([a + (b - a) * s0, a + (b - a) * s1]),
        }
    }
}

/// A segment on the workspace plane.
#[derive(Debug, Clone, Copy)]
struct MappedSegment {
    a: [f64; 2],
    b: [f64; 2],
    law: DepthLaw,
    source: usize,
}

/// A mesh vertex as the triangulation stores it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ReliefVertex {
    x: f64,
    y: f64,
    z: f64,
}

impl HasPosition for ReliefVertex {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        Point2::new(self.x, self.y)
    }
}

/// Sentinel of the per-cell vertex chains.
const NO_VERTEX: u32 = u32::MAX;

/// Vertices with merging of near neighbours (a hash grid of the merge distance; each cell
/// chains its vertices through `next`).
struct VertexTable {
    vertices: Vec<ReliefVertex>,
    /// Frame vertices keep the back-plane height.
    pinned: Vec<bool>,
    heads: CellMap<(i64, i64), u32>,
    next: Vec<u32>,
    merge_m: f64,
    merged: usize,
}

impl VertexTable {
    fn new(merge_m: f64) -> VertexTable {
        VertexTable {
            vertices: Vec::with_capacity(1024),
            pinned: Vec::with_capacity(1024),
            heads: CellMap::with_capacity_and_hasher(1024, Default::default()),
            next: Vec::with_capacity(1024),
            merge_m,
            merged: 0,
        }
    }

    fn key(&self, x: f64, y: f64) -> (i64, i64) {
        (
            (x / self.merge_m).floor() as i64,
            (y / self.merge_m).floor() as i64,
        )
    }

    /// The vertex at `(x, y)`: an existing one within the merge distance (its height becomes
    /// the nearer of the two unless pinned), or a new one.
    fn insert(&mut self, x: f64, y: f64, z: f64, pinned: bool) -> u32 {
        let (kx, ky) = self.key(x, y);
        let mut best: Option<(u32, f64)> = None;
        for dx in -1..=1 {
            for dy in -1..=1 {
                let mut i = self
                    .heads
                    .get(&(kx + dx, ky + dy))
                    .copied()
                    .unwrap_or(NO_VERTEX);
                while i != NO_VERTEX {
                    let v = self.vertices[i as usize];
                    let d2 = (v.x - x).powi(2) + (v.y - y).powi(2);
                    if d2 < self.merge_m * self.merge_m && best.is_none_or(|(_, b)| d2 < b) {
                        best = Some((i, d2));
                    }
                    i = self.next[i as usize];
                }
            }
        }
        if let Some((i, _)) = best {
            self.merged += 1;
            let v = &mut self.vertices[i as usize];
            if !self.pinned[i as usize] && z < v.z {
                v.z = z;
            }
            return i;
        }
        let i = self.vertices.len() as u32;
        self.vertices.push(ReliefVertex { x, y, z });
        self.pinned.push(pinned);
        let head = self.heads.entry((kx, ky)).or_insert(NO_VERTEX);
        self.next.push(*head);
        *head = i;
        i
    }

    fn xy(&self, i: u32) -> [f64; 2] {
        let v = self.vertices[i as usize];
        [v.x, v.y]
    }
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn in_rect(p: [f64; 2], r: [f64; 4]) -> bool {
    p[0] >= r[0] && p[0] <= r[2] && p[1] >= r[1] && p[1] <= r[3]
}

/// Build the relief from camera-frame segments and points seen through `camera`.
pub fn build_from_scene(
    segments: &[SceneSegment3],
    points: &[[f64; 3]],
    camera: &PinholeCamera,
    params: &ReliefParams,
) -> Result<(ReliefModel, BuildReport), BuildError> {
    params.validate().map_err(BuildError::Params)?;
    let mut report = BuildReport {
        segments_in: segments.len(),
        points_in: points.len(),
        ..BuildReport::default()
    };
    let map = &params.scene_map;
    let mut mapped = Vec::with_capacity(segments.len());
    for (i, s) in segments.iter().enumerate() {
        let reason = |p: &[f64; 3]| {
            if p.iter().all(|c| c.is_finite()) {
                RejectReason::BehindCamera
            } else {
                RejectReason::NotFinite
            }
        };
        let (pa, pb) = match (camera.project(&s.a_m), camera.project(&s.b_m)) {
            (Some(pa), Some(pb)) => (pa, pb),
            (None, _) => {
                report.rejections.push(Rejection {
                    item: InputItem::Segment(i),
                    reason: reason(&s.a_m),
                });
                continue;
            }
            (_, None) => {
                report.rejections.push(Rejection {
                    item: InputItem::Segment(i),
                    reason: reason(&s.b_m),
                });
                continue;
            }
        };
        mapped.push(MappedSegment {
            a: map.image_to_workspace(pa.0[0], pa.0[1]),
            b: map.image_to_workspace(pb.0[0], pb.0[1]),
            law: DepthLaw::Scene([pa.1, pb.1]),
            source: i,
        });
    }
    let mut mapped_points = Vec::with_capacity(points.len());
    for (i, p) in points.iter().enumerate() {
        match camera.project(p) {
            Some(([u, v], z)) => {
                let [x, y] = map.image_to_workspace(u, v);
                mapped_points.push(([x, y, map.scene_depth_to_relief_z(z)], i));
            }
            None => report.rejections.push(Rejection {
                item: InputItem::Point(i),
                reason: if p.iter().all(|c| c.is_finite()) {
                    RejectReason::BehindCamera
                } else {
                    RejectReason::NotFinite
                },
            }),
        }
    }
    build_mapped(mapped, mapped_points, params, report)
}

/// Build the relief from segments and points already in device coordinates (`x`, `y` on the
/// area, `z` the relief height, metres).
pub fn build_from_device(
    segments: &[DeviceSegment],
    points: &[[f64; 3]],
    params: &ReliefParams,
) -> Result<(ReliefModel, BuildReport), BuildError> {
    params.validate().map_err(BuildError::Params)?;
    let mut report = BuildReport {
        segments_in: segments.len(),
        points_in: points.len(),
        ..BuildReport::default()
    };
    let mut mapped = Vec::with_capacity(segments.len());
    for (i, s) in segments.iter().enumerate() {
        if !(s.a_m.iter().chain(s.b_m.iter()).all(|c| c.is_finite())) {
            report.rejections.push(Rejection {
                item: InputItem::Segment(i),
                reason: RejectReason::NotFinite,
            });
            continue;
        }
        mapped.push(MappedSegment {
            a: [s.a_m[0], s.a_m[1]],
            b: [s.b_m[0], s.b_m[1]],
            law: DepthLaw::Relief([s.a_m[2], s.b_m[2]]),
            source: i,
        });
    }
    let mut mapped_points = Vec::with_capacity(points.len());
    for (i, p) in points.iter().enumerate() {
        if p.iter().all(|c| c.is_finite()) {
            mapped_points.push((*p, i));
        } else {
            report.rejections.push(Rejection {
                item: InputItem::Point(i),
                reason: RejectReason::NotFinite,
            });
        }
    }
    build_mapped(mapped, mapped_points, params, report)
}

/// A constraint candidate between two table vertices.
#[derive(Debug, Clone)]
struct Edge {
    va: u32,
    vb: u32,
    law: DepthLaw,
    source: usize,
    /// Split points `(s, vertex)` along the edge.
    splits: Vec<(f64, u32)>,
}

fn build_mapped(
    segments: Vec<MappedSegment>,
    points: Vec<([f64; 3], usize)>,
    params: &ReliefParams,
    mut report: BuildReport,
) -> Result<(ReliefModel, BuildReport), BuildError> {
    let t_start = std::time::Instant::now();
    let area = params.area_m();
    let back_z = params.scene_map.back_plane_z_m();
    let nearest_z = back_z - params.scene_map.relief_depth_m();
    let clamp_z = |z: f64| z.clamp(nearest_z, back_z);
    let fw = params.frame_width_m.max(params.merge_distance_m);
    let inner = [area[0] + fw, area[1] + fw, area[2] - fw, area[3] - fw];
    // A stepped relief's frame has an inner border of its own (a constraint ring at `inner`):
    // the geometry stays clear of it.
    let inner_border = params.shape == ReliefShape::Stepped
        && params.frame_width_m > 4.0 * params.merge_distance_m;
    let clear = if inner_border {
        2.0 * params.merge_distance_m
    } else {
        0.0
    };
    let inside = [
        inner[0] + clear,
        inner[1] + clear,
        inner[2] - clear,
        inner[3] - clear,
    ];
    let mut table = VertexTable::new(params.merge_distance_m);

    // The frame: the area's border at the back plane.
    for [x, y] in border_points(area, params.border_spacing_m) {
        table.insert(x, y, back_z, true);
    }
    let frame_vertices = table.vertices.len();

    // Segments: clip to the inner area, insert their endpoints.
    let mut edges: Vec<Edge> = Vec::with_capacity(segments.len());
    let mut seen: CellMap<(u32, u32), usize> =
        CellMap::with_capacity_and_hasher(segments.len(), Default::default());
    for seg in &segments {
        let Some((s0, s1)) = clip_to_rect(seg.a, seg.b, inside) else {
            report.rejections.push(Rejection {
                item: InputItem::Segment(seg.source),
                reason: RejectReason::OutsideArea,
            });
            continue;
        };
        let at = |s: f64| {
            [
                seg.a[0] + (seg.b[0] - seg.a[0]) * s,
                seg.a[1] + (seg.b[1] - seg.a[1]) * s,
            ]
        };
        let law = seg.law.piece(s0, s1);
        let (a, b) = (at(s0), at(s1));
        let za = clamp_z(law.relief_z(0.0, params));
        let zb = clamp_z(law.relief_z(1.0, params));
        if !(za.is_finite() && zb.is_finite()) {
            report.rejections.push(Rejection {
                item: InputItem::Segment(seg.source),
                reason: RejectReason::NotFinite,
            });
            continue;
        }
        let va = table.insert(a[0], a[1], za, false);
        let vb = table.insert(b[0], b[1], zb, false);
        if va == vb {
            report.rejections.push(Rejection {
                item: InputItem::Segment(seg.source),
                reason: RejectReason::Degenerate,
            });
            continue;
        }
        let key = (va.min(vb), va.max(vb));
        if seen.insert(key, edges.len()).is_some() {
            report.rejections.push(Rejection {
                item: InputItem::Segment(seg.source),
                reason: RejectReason::Duplicate,
            });
            continue;
        }
        edges.push(Edge {
            va,
            vb,
            law,
            source: seg.source,
            splits: Vec::new(),
        });
    }
    for (p, i) in &points {
        if !in_rect([p[0], p[1]], inside) {
            report.rejections.push(Rejection {
                item: InputItem::Point(*i),
                reason: RejectReason::OutsideArea,
            });
            continue;
        }
        table.insert(p[0], p[1], clamp_z(p[2]), false);
    }
    if table.vertices.len() == frame_vertices {
        return Err(BuildError::NoUsableInput(Box::new(report)));
    }

    let t_cleaned = std::time::Instant::now();
    report.timings.cleaning = t_cleaned - t_start;
    let accepted = resolve_crossings(&mut edges, &mut table, params, &mut report);
    let t_crossings = std::time::Instant::now();
    report.timings.crossings = t_crossings - t_cleaned;

    // Constraint pieces between consecutive vertices along each kept edge.
    let mut constraint_pieces: Vec<([usize; 2], usize)> = Vec::new();
    for &e in &accepted {
        let edge = &mut edges[e];
        edge.splits
            .sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap_or(core::cmp::Ordering::Equal));
        let mut prev = edge.va;
        for &(_, v) in edge.splits.iter().chain(core::iter::once(&(1.0, edge.vb))) {
            if v != prev {
                constraint_pieces.push(([prev as usize, v as usize], edge.source));
                prev = v;
            }
        }
    }
    report.constraints_kept = accepted.len();
    report.points_merged = table.merged;
    if inner_border {
        add_inner_border(
            &mut table,
            frame_vertices,
            inner,
            params,
            &mut constraint_pieces,
        );
    }

    let vertices = table.vertices.clone();
    let edge_list: Vec<[usize; 2]> = constraint_pieces.iter().map(|p| p.0).collect();
    let mut conflicts: Vec<[usize; 2]> = Vec::new();
    let cdt = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        ConstrainedDelaunayTriangulation::<ReliefVertex>::try_bulk_load_cdt(
            vertices,
            edge_list,
            |e| conflicts.push(e),
        )
    }));
    let cdt = match cdt {
        Ok(Ok(cdt)) => cdt,
        Ok(Err(e)) => return Err(BuildError::Triangulation(format!("{e:?}"))),
        Err(_) => {
            return Err(BuildError::Triangulation(
                "the constrained triangulation aborted on this input".into(),
            ))
        }
    };
    for c in &conflicts {
        if let Some(piece) = constraint_pieces
            .iter()
            .find(|p| p.0 == *c && p.1 != INNER_BORDER)
        {
            report.rejections.push(Rejection {
                item: InputItem::Segment(piece.1),
                reason: RejectReason::TriangulationConflict,
            });
        }
    }
    let border_pieces = constraint_pieces
        .iter()
        .filter(|p| p.1 == INNER_BORDER)
        .count();
    report.constraint_edges = cdt.num_constraints().saturating_sub(border_pieces);

    let mut mesh_vertices: Vec<[f64; 3]> = cdt
        .vertices()
        .map(|v| [v.data().x, v.data().y, v.data().z])
        .collect();
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(cdt.num_inner_faces());
    let mut triangle_edges: Vec<[u32; 3]> = Vec::with_capacity(cdt.num_inner_faces());
    for f in cdt.inner_faces() {
        triangles.push(f.vertices().map(|v| v.fix().index() as u32));
        // The edges v0 v1, v1 v2, v2 v0, as the vertices are listed.
        triangle_edges.push(
            f.adjacent_edges()
                .map(|e| e.as_undirected().fix().index() as u32),
        );
    }
    if params.shape == ReliefShape::Stepped {
        let mut constraint = vec![false; cdt.num_undirected_edges()];
        for e in cdt.undirected_edges() {
            constraint[e.fix().index()] = e.is_constraint_edge();
        }
        // The bulk load keeps the vertices' order: the frame's come first.
        let topology = MeshTopology {
            constraint: &constraint,
            triangle_edges: &triangle_edges,
            frame_vertices: frame_vertices as u32,
        };
        report.depth_steps = cut_steps(&mut mesh_vertices, &mut triangles, &topology, params).steps;
    }
    report.vertices = mesh_vertices.len();
    report.triangles = triangles.len();
    let t_triangulated = std::time::Instant::now();
    report.timings.triangulation = t_triangulated - t_crossings;
    let model = ReliefModel::from_mesh(mesh_vertices, triangles, area, back_z, params);
    report.timings.model = t_triangulated.elapsed();
    Ok((model, report))
}

/// Points along the border of `rect = [x0, y0, x1, y1]`, counter-clockwise from its corner
/// `(x0, y0)`, every `spacing_m` or a little less (each side in equal steps, corners included).
fn border_points(rect: [f64; 4], spacing_m: f64) -> impl Iterator<Item = [f64; 2]> {
    let [x0, y0, x1, y1] = rect;
    [
        ([x0, y0], [x1, y0]),
        ([x1, y0], [x1, y1]),
        ([x1, y1], [x0, y1]),
        ([x0, y1], [x0, y0]),
    ]
    .into_iter()
    .flat_map(move |(a, b)| {
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        let n = ((len / spacing_m).ceil() as usize).clamp(1, 1000);
        (0..n).map(move |k| {
            let s = k as f64 / n as f64;
            [a[0] + (b[0] - a[0]) * s, a[1] + (b[1] - a[1]) * s]
        })
    })
}

/// The `source` of the inner border's constraint pieces (not an input segment).
const INNER_BORDER: usize = usize::MAX;

/// The frame's inner border ([`ReliefShape::Stepped`], `super::border`): a ring of vertices
/// along `inner`, as many per side as the frame has, each at the height of the nearest vertex
/// of the geometry, joined by constraint pieces.
fn add_inner_border(
    table: &mut VertexTable,
    frame_vertices: usize,
    inner: [f64; 4],
    params: &ReliefParams,
    pieces: &mut Vec<([usize; 2], usize)>,
) {
    let geometry: Vec<[f64; 3]> = table.vertices[frame_vertices..]
        .iter()
        .map(|v| [v.x, v.y, v.z])
        .collect();
    let nearest = NearestHeight::new(&geometry, inner);
    let mut ring: Vec<u32> = Vec::with_capacity(64);
    for [x, y] in border_points(inner, params.border_spacing_m) {
        let Some(z) = nearest.at(x, y) else {
            return;
        };
        ring.push(table.insert(x, y, z, true));
    }
    for k in 0..ring.len() {
        let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
        if a != b {
            pieces.push(([a as usize, b as usize], INNER_BORDER));
        }
    }
}

/// Keep the nearest segments as constraints; split crossings at a shared vertex when heights
/// agree, otherwise drop the farther segment's constraint. Returns the kept edges.
fn resolve_crossings(
    edges: &mut [Edge],
    table: &mut VertexTable,
    params: &ReliefParams,
    report: &mut BuildReport,
) -> Vec<usize> {
    let z_of = |table: &VertexTable, v: u32| table.vertices[v as usize].z;
    let mut order: Vec<usize> = (0..edges.len()).collect();
    order.sort_by(|&i, &j| {
        let zi = z_of(table, edges[i].va).min(z_of(table, edges[i].vb));
        let zj = z_of(table, edges[j].va).min(z_of(table, edges[j].vb));
        zi.partial_cmp(&zj).unwrap_or(core::cmp::Ordering::Equal)
    });
    let mut accepted: Vec<usize> = Vec::with_capacity(edges.len());
    let mut boxes: Vec<[f64; 4]> = Vec::with_capacity(edges.len());
    let merge = params.merge_distance_m;
    let mut pending: Vec<(usize, f64, f64)> = Vec::with_capacity(16); // (edge, s on e, t on f)
    for &e in &order {
        let (a, b) = (table.xy(edges[e].va), table.xy(edges[e].vb));
        let bbox = [
            a[0].min(b[0]) - merge,
            a[1].min(b[1]) - merge,
            a[0].max(b[0]) + merge,
            a[1].max(b[1]) + merge,
        ];
        let de = sub(b, a);
        let len_e = de[0].hypot(de[1]);
        pending.clear();
        let mut rejected = None;
        for (k, &f) in accepted.iter().enumerate() {
            let fb = boxes[k];
            if fb[0] > bbox[2] || fb[2] < bbox[0] || fb[1] > bbox[3] || fb[3] < bbox[1] {
                continue;
            }
            let (c, d) = (table.xy(edges[f].va), table.xy(edges[f].vb));
            let df = sub(d, c);
            let len_f = df[0].hypot(df[1]);
            let denom = cross(de, df);
            let shared = [edges[e].va, edges[e].vb]
                .iter()
                .any(|v| *v == edges[f].va || *v == edges[f].vb);
            if denom.abs() <= 1e-12 * len_e * len_f {
                // Parallel: overlapping when collinear and the parameter ranges meet.
                if cross(sub(c, a), de).abs() <= merge * len_e {
                    let t0 = ((c[0] - a[0]) * de[0] + (c[1] - a[1]) * de[1]) / (len_e * len_e);
                    let t1 = ((d[0] - a[0]) * de[0] + (d[1] - a[1]) * de[1]) / (len_e * len_e);
                    let (lo, hi) = (t0.min(t1), t0.max(t1));
                    let eps = merge / len_e;
                    if hi > eps && lo < 1.0 - eps {
                        rejected = Some(RejectReason::OverlapsSegment {
                            other: edges[f].source,
                        });
                        break;
                    }
                }
                continue;
            }
            let ac = sub(c, a);
            let s = cross(ac, df) / denom;
            let t = cross(ac, de) / denom;
            let (eps_s, eps_t) = (merge / len_e, merge / len_f);
            if s < -eps_s || s > 1.0 + eps_s || t < -eps_t || t > 1.0 + eps_t {
                continue;
            }
            if shared {
                // Touching at the shared vertex; collinear overlap was handled above.
                continue;
            }
            let ze = edges[e].law.relief_z(s.clamp(0.0, 1.0), params);
            let zf = edges[f].law.relief_z(t.clamp(0.0, 1.0), params);
            let gap = (ze - zf).abs();
            if gap.is_nan() || gap > params.crossing_tolerance_m {
                rejected = Some(RejectReason::CrossesNearerSegment {
                    other: edges[f].source,
                    height_gap_m: if gap.is_finite() { gap } else { f64::INFINITY },
                });
                break;
            }
            pending.push((f, s, t));
        }
        if let Some(reason) = rejected {
            report.rejections.push(Rejection {
                item: InputItem::Segment(edges[e].source),
                reason,
            });
            continue;
        }
        for &(f, s, t) in &pending {
            let (c, d) = (table.xy(edges[f].va), table.xy(edges[f].vb));
            let eps_s = merge / len_e;
            let len_f = (d[0] - c[0]).hypot(d[1] - c[1]);
            let eps_t = merge / len_f;
            let ze = edges[e].law.relief_z(s.clamp(0.0, 1.0), params);
            let zf = edges[f].law.relief_z(t.clamp(0.0, 1.0), params);
            // The crossing vertex: an endpoint when the crossing is at one, else a new vertex.
            let v = if s <= eps_s {
                edges[e].va
            } else if s >= 1.0 - eps_s {
                edges[e].vb
            } else if t <= eps_t {
                edges[f].va
            } else if t >= 1.0 - eps_t {
                edges[f].vb
            } else {
                report.crossings_split += 1;
                table.insert(
                    c[0] + (d[0] - c[0]) * t,
                    c[1] + (d[1] - c[1]) * t,
                    ze.min(zf),
                    false,
                )
            };
            if v != edges[e].va && v != edges[e].vb {
                edges[e].splits.push((s, v));
            }
            if v != edges[f].va && v != edges[f].vb {
                edges[f].splits.push((t, v));
            }
        }
        accepted.push(e);
        boxes.push(bbox);
    }
    accepted
}
