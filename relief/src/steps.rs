//! Depth steps kept as steps ([`ReliefShape::Stepped`](super::ReliefShape::Stepped)).
//!
//! The constrained Delaunay triangulation joins every vertex to its neighbours, so a triangle
//! between a near segment (an occluding edge) and a far one (the background behind it)
//! interpolates a ramp where the scene has a cliff. Here every such edge of the mesh gets a
//! **foot** vertex close to its nearer end, at its farther end's height: the triangles on the
//! edge are cut at their feet, so the surface holds the far height up to a wall beside the
//! near vertex: `step_width_m` wide across, wider where the rise would make it steeper than
//! `step_max_wall_slope` (the rendering's proxy holds the finger on such walls), the foot
//! placed further along an edge where a triangle's corner would thin the wall. The wall is
//! steep but not vertical (the surface stays a height field, its normals within 90 degrees of
//! the reference normal) and the cut keeps the mesh conforming: a foot belongs to its edge,
//! shared by the two triangles on it.
//!
//! An edge is a step when its ends' heights differ by more than `step_min_height_m` and a
//! triangle on it is steeper than `step_min_slope` (its height's gradient on the area); never
//! when it is a constraint (a matched segment follows the scene) or touches a vertex of the
//! frame, whose ramp to the back plane is the area's edge.

use crate::input::ReliefParams;

/// What the cut needs to know about the mesh.
pub(super) struct MeshTopology<'a> {
    /// Per undirected edge of the triangulation: a constraint edge (a matched segment).
    pub constraint: &'a [bool],
    /// Per triangle, the undirected edges `t0 t1`, `t1 t2`, `t2 t0` (indices into
    /// `constraint`).
    pub triangle_edges: &'a [[u32; 3]],
    /// Vertices `0..frame_vertices` are the frame's, at the back plane.
    pub frame_vertices: u32,
}

/// The feet of the edges that span a depth step, and the cut mesh.
pub(super) struct StepCut {
    /// Edges found to span a step.
    pub steps: usize,
}

/// An edge's foot not yet decided.
const UNDECIDED: u32 = u32::MAX;
/// An edge without a foot.
const NO_FOOT: u32 = u32::MAX - 1;

/// Cut every triangle at its edges' feet (see the module's documentation): new vertices are
/// appended to `vertices`, `triangles` is replaced by the cut mesh (counter-clockwise kept).
pub(super) fn cut_steps(
    vertices: &mut Vec<[f64; 3]>,
    triangles: &mut Vec<[u32; 3]>,
    topology: &MeshTopology<'_>,
    params: &ReliefParams,
) -> StepCut {
    let edges = topology.constraint.len();
    let corners = |t: [u32; 3]| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])];
    // Edges that may be steps: on a steep triangle, heights differing enough, not constraints
    // nor the frame's.
    let mut steep = vec![false; edges];
    for (t, e) in triangles.iter().zip(topology.triangle_edges) {
        if slope(vertices, *t).is_some_and(|g| g > params.step_min_slope) {
            for k in 0..3 {
                steep[e[k] as usize] = true;
            }
        }
    }
    let mut candidate = vec![false; edges];
    for (t, e) in triangles.iter().zip(topology.triangle_edges) {
        for (k, (a, b)) in corners(*t).into_iter().enumerate() {
            let i = e[k] as usize;
            candidate[i] = steep[i] && step_candidate(vertices, (a, b), i, topology, params);
        }
    }
    // How far along each step edge its foot must be, in walls: more than one where the
    // triangle's corner would make the wall narrower than `width` across (an obtuse near
    // corner's cone, a thin strip along a near edge).
    let mut stretch = vec![1.0f64; edges];
    for (&t, e) in triangles.iter().zip(topology.triangle_edges) {
        let c = [0, 1, 2].map(|k| candidate[e[k] as usize]);
        // Two step edges meeting at a corner: rotate it to t0 (edges t0 t1 and t2 t0).
        let Some(r) = (0..3).find(|&r| c[r] && c[(r + 2) % 3] && !c[(r + 1) % 3]) else {
            continue;
        };
        let ([t0, t1, t2], [e01, _, e20]) = (rotate(t, r), rotate(*e, r));
        let z = |i: u32| vertices[i as usize][2];
        let angle = |at: u32, a: u32, b: u32| {
            let [p, q, w] = [at, a, b].map(|i| vertices[i as usize]);
            let (u, v) = ([q[0] - p[0], q[1] - p[1]], [w[0] - p[0], w[1] - p[1]]);
            (u[0] * v[1] - u[1] * v[0])
                .abs()
                .atan2(u[0] * v[0] + u[1] * v[1])
        };
        let mut need = |edge: u32, factor: f64| {
            let s = &mut stretch[edge as usize];
            *s = s.max(1.0 / factor.max(MIN_WALL_FACTOR));
        };
        if z(t0) < z(t1) && z(t0) < z(t2) {
            // The near corner's cone: its far side is the line between the two feet.
            let g = (0.5 * angle(t0, t1, t2)).cos();
            need(e01, g);
            need(e20, g);
        } else if z(t0) > z(t1) && z(t0) > z(t2) {
            // The strip along the near edge t1 t2.
            need(e01, angle(t1, t2, t0).sin());
            need(e20, angle(t2, t0, t1).sin());
        }
    }
    let mut feet = vec![UNDECIDED; edges];
    let mut steps = 0;
    let mut cut: Vec<[u32; 3]> = Vec::with_capacity(triangles.len() * 2);
    for (&t, e) in triangles.iter().zip(topology.triangle_edges) {
        let mut f = [None; 3];
        for (k, (a, b)) in corners(t).into_iter().enumerate() {
            let i = e[k] as usize;
            if feet[i] == UNDECIDED {
                feet[i] = match candidate[i]
                    .then(|| step_foot(vertices, (a, b), stretch[i], params))
                    .flatten()
                {
                    Some(p) => {
                        vertices.push(p);
                        steps += 1;
                        (vertices.len() - 1) as u32
                    }
                    None => NO_FOOT,
                };
            }
            f[k] = (feet[i] != NO_FOOT).then_some(feet[i]);
        }
        cut_triangle(vertices, t, f, &mut cut);
    }
    *triangles = cut;
    StepCut { steps }
}

/// The steepness of triangle `t`: the norm of its height's gradient on the area (`None` when
/// it has no area).
fn slope(vertices: &[[f64; 3]], t: [u32; 3]) -> Option<f64> {
    let [p0, p1, p2] = t.map(|i| vertices[i as usize]);
    let e1 = [p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]];
    let e2 = [p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]];
    let det = e1[0] * e2[1] - e1[1] * e2[0];
    if det.abs() < 1e-18 {
        return None;
    }
    let gx = (e1[2] * e2[1] - e2[2] * e1[1]) / det;
    let gy = (e2[2] * e1[0] - e1[2] * e2[0]) / det;
    Some(gx.hypot(gy))
}

/// The smallest corner factor a wall's foot distance is stretched for (at most five times
/// `width`): beyond, the wall is let narrower.
const MIN_WALL_FACTOR: f64 = 0.2;

/// The edge `(a, b)` may span a step: not a constraint, not the frame's, and its ends'
/// heights differ by more than `step_min_height_m` (its triangles' steepness is checked apart).
fn step_candidate(
    vertices: &[[f64; 3]],
    (a, b): (u32, u32),
    edge: usize,
    topology: &MeshTopology<'_>,
    params: &ReliefParams,
) -> bool {
    if a < topology.frame_vertices || b < topology.frame_vertices || topology.constraint[edge] {
        return false;
    }
    (vertices[a as usize][2] - vertices[b as usize][2]).abs() > params.step_min_height_m
}

/// The foot of the step edge `(a, b)`: on the edge, `stretch` walls from its nearer end (the
/// smaller `z`), at the farther end's height; a wall is `step_width_m`, wider where the rise
/// would make it steeper than `step_max_wall_slope`. `None` when the edge is too short for it
/// (shorter than two walls): it stays a ramp.
fn step_foot(
    vertices: &[[f64; 3]],
    (a, b): (u32, u32),
    stretch: f64,
    params: &ReliefParams,
) -> Option<[f64; 3]> {
    let (pa, pb) = (vertices[a as usize], vertices[b as usize]);
    let (near, far) = if pa[2] <= pb[2] { (pa, pb) } else { (pb, pa) };
    let rise = far[2] - near[2];
    let length = (far[0] - near[0]).hypot(far[1] - near[1]);
    let width = params.step_width_m.max(rise / params.step_max_wall_slope) * stretch;
    (length > 2.0 * width).then(|| {
        let s = width / length;
        [
            near[0] + (far[0] - near[0]) * s,
            near[1] + (far[1] - near[1]) * s,
            far[2],
        ]
    })
}

/// The triangle `t` (counter-clockwise) cut at the feet `f` of its edges `t0 t1`, `t1 t2`,
/// `t2 t0`, appended to `out`, counter-clockwise.
fn cut_triangle(vertices: &[[f64; 3]], t: [u32; 3], f: [Option<u32>; 3], out: &mut Vec<[u32; 3]>) {
    match f {
        [None, None, None] => out.push(t),
        [Some(_), Some(_), Some(_)] => {
            let [f01, f12, f20] = f.map(|x| x.unwrap_or_default());
            out.extend([
                [t[0], f01, f20],
                [t[1], f12, f01],
                [t[2], f20, f12],
                [f01, f12, f20],
            ]);
        }
        _ => {
            // Rotate so that the cut edges come first: one foot on t0 t1, or two on t0 t1 and
            // t2 t0 (the edges at t0).
            let rotated = (0..3).find_map(|r| {
                let (tt, ff) = (rotate(t, r), rotate(f, r));
                let one = ff[0].is_some() && ff[1].is_none() && ff[2].is_none();
                let two = ff[0].is_some() && ff[1].is_none() && ff[2].is_some();
                (one || two).then_some((tt, ff))
            });
            let Some((t, f)) = rotated else {
                out.push(t);
                return;
            };
            match (f[0], f[2]) {
                (Some(f01), None) => out.extend([[t[0], f01, t[2]], [f01, t[1], t[2]]]),
                (Some(f01), Some(f20)) => {
                    // The corner, then the quad f01 t1 t2 f20 by its less steep diagonal.
                    out.push([t[0], f01, f20]);
                    let steepest = |a: [u32; 3], b: [u32; 3]| {
                        let s = |t| slope(vertices, t).unwrap_or(f64::INFINITY);
                        s(a).max(s(b))
                    };
                    let one = [[f01, t[1], t[2]], [f01, t[2], f20]];
                    let other = [[f01, t[1], f20], [t[1], t[2], f20]];
                    if steepest(one[0], one[1]) <= steepest(other[0], other[1]) {
                        out.extend(one);
                    } else {
                        out.extend(other);
                    }
                }
                _ => out.push(t),
            }
        }
    }
}

fn rotate<T: Copy>(a: [T; 3], r: usize) -> [T; 3] {
    [a[r % 3], a[(r + 1) % 3], a[(r + 2) % 3]]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn signed_area(v: &[[f64; 3]], t: [u32; 3]) -> f64 {
        let [a, b, c] = t.map(|i| v[i as usize]);
        0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
    }

    #[test]
    fn the_slope_is_the_gradient_on_the_area() {
        let v = vec![
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 1.0],
            [0.0, 1.0, 0.0],
            [0.0, 2.0, 0.0],
        ];
        assert!((slope(&v, [0, 1, 2]).unwrap() - 0.5).abs() < 1e-12);
        assert_eq!(slope(&v, [0, 2, 3]), None);
    }

    #[test]
    fn every_cut_keeps_the_area_and_the_orientation() {
        let v: Vec<[f64; 3]> = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.1, 0.0, 0.0],
            [0.9, 0.1, 0.0],
            [0.0, 0.1, 0.0],
        ];
        let whole = signed_area(&v, [0, 1, 2]);
        for mask in 0..8u32 {
            let f = [3, 4, 5].map(|i| (mask & (1 << (i - 3)) != 0).then_some(i));
            let mut out = Vec::new();
            cut_triangle(&v, [0, 1, 2], f, &mut out);
            let total: f64 = out.iter().map(|&t| signed_area(&v, t)).sum();
            assert!((total - whole).abs() < 1e-12, "mask {mask}: {total}");
            assert!(out.iter().all(|&t| signed_area(&v, t) > 0.0), "mask {mask}");
            let used = f.iter().flatten().count();
            assert!(
                f.iter()
                    .flatten()
                    .all(|i| out.iter().any(|t| t.contains(i))),
                "mask {mask}: {used} feet, not all used"
            );
        }
    }
}
