//! Polygonal profiles: a polyline in the x-z plane, extruded along `y`, solid on one side — the
//! "surfaces" of the paper's experiments (section 6: "because of the planar nature of the device,
//! a surface is represented ... as its intersection with the plane of the wires"; Fig. 18's
//! polygonal profile, Fig. 23's polygonal contour).
//!
//! A profile is open (its two end segments continue as rays, so the solid never ends) or closed
//! (a simple polygon). The solid lies on the left or the right of the polyline walked from its
//! first vertex to its last (for a closed polygon walked counter-clockwise in the x-z plane, the
//! left is the inside). Queries are allocation-free and bounded by the vertex capacity `CAP`:
//! the control thread may call [`Surface::contact`] every period.
//!
//! The contact is the nearest point of the polyline: depth is the distance to it, the normal is
//! the face normal of the nearest segment (pointing out of the solid), or at a vertex the
//! direction from the point to the vertex. Inside/outside comes from the nearest feature (the
//! face normal, or at a vertex the sum of the two adjacent face normals — the 2D pseudo-normal),
//! which is exact for any simple polyline.

use crate::kinematics::libm_sqrt;
use crate::planar::Vec2;
use crate::surface::{Contact, Surface};
use crate::Vec3;

/// Default vertex capacity of a [`Profile`].
pub const PROFILE_CAPACITY: usize = 32;

/// On which side of the polyline (walked from the first vertex to the last) the solid lies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolidSide {
    /// On the left: for a segment along `+x`, the solid is at larger `z`.
    Left,
    /// On the right: for a segment along `+x`, the solid is at smaller `z`.
    Right,
}

/// Why a profile was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProfileError {
    /// Fewer vertices than the shape needs (2 for an open profile, 3 for a closed one).
    TooFewVertices {
        /// Vertices given.
        given: usize,
    },
    /// More vertices than the profile's capacity.
    TooManyVertices {
        /// Vertices given.
        given: usize,
        /// The capacity.
        capacity: usize,
    },
    /// A vertex coordinate is not finite.
    NotFinite,
    /// Two consecutive vertices coincide (a segment of zero length).
    DegenerateSegment {
        /// Index of the segment's first vertex.
        segment: usize,
    },
}

impl core::fmt::Display for ProfileError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ProfileError::TooFewVertices { given } => {
                write!(f, "a profile needs more vertices than {given}")
            }
            ProfileError::TooManyVertices { given, capacity } => {
                write!(f, "{given} vertices, more than the capacity {capacity}")
            }
            ProfileError::NotFinite => f.write_str("a vertex coordinate is not finite"),
            ProfileError::DegenerateSegment { segment } => {
                write!(f, "segment {segment} has zero length")
            }
        }
    }
}

/// The feature of the polyline nearest to a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Feature {
    /// The inside of segment `i` (from vertex `i` to vertex `i + 1`), or its ray on an open end.
    Segment(usize),
    /// Vertex `i`.
    Vertex(usize),
}

/// The nearest point of a profile to a query point, in the x-z plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nearest {
    /// The nearest point of the polyline, `[x, z]`, metres.
    pub point_m: Vec2,
    /// Which feature it lies on.
    pub feature: Feature,
    /// The segment it was found on (for a vertex, one of the two adjacent segments).
    pub segment: usize,
    /// Distance from the query point, metres, positive outside the solid, negative inside.
    pub signed_distance_m: f64,
    /// Unit normal pointing out of the solid at the nearest point, `[x, z]`.
    pub normal: Vec2,
}

/// A polygonal profile in the x-z plane (extruded along `y`) with at most `CAP` vertices.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile<const CAP: usize = PROFILE_CAPACITY> {
    vertices: [Vec2; CAP],
    len: usize,
    closed: bool,
    solid: SolidSide,
}

impl<const CAP: usize> Profile<CAP> {
    /// An open profile through `vertices_m` (`[x, z]`, metres; at least 2): its end segments
    /// continue as rays.
    pub fn open(vertices_m: &[Vec2], solid: SolidSide) -> Result<Profile<CAP>, ProfileError> {
        Profile::build(vertices_m, false, solid)
    }

    /// A closed polygon through `vertices_m` (`[x, z]`, metres; at least 3, the last joined to
    /// the first). It must be simple (no self-intersection).
    pub fn closed(vertices_m: &[Vec2], solid: SolidSide) -> Result<Profile<CAP>, ProfileError> {
        Profile::build(vertices_m, true, solid)
    }

    fn build(
        vertices_m: &[Vec2],
        closed: bool,
        solid: SolidSide,
    ) -> Result<Profile<CAP>, ProfileError> {
        let given = vertices_m.len();
        let needed = if closed { 3 } else { 2 };
        if given < needed {
            return Err(ProfileError::TooFewVertices { given });
        }
        if given > CAP {
            return Err(ProfileError::TooManyVertices {
                given,
                capacity: CAP,
            });
        }
        if !vertices_m.iter().all(|v| v.iter().all(|c| c.is_finite())) {
            return Err(ProfileError::NotFinite);
        }
        let mut vertices = [Vec2::zeros(); CAP];
        vertices[..given].copy_from_slice(vertices_m);
        let profile = Profile {
            vertices,
            len: given,
            closed,
            solid,
        };
        for i in 0..profile.segment_count() {
            let (a, b) = profile.segment(i);
            if (b - a).norm_squared() <= 1e-24 {
                return Err(ProfileError::DegenerateSegment { segment: i });
            }
        }
        Ok(profile)
    }

    /// The vertices, `[x, z]`, metres.
    pub fn vertices(&self) -> &[Vec2] {
        &self.vertices[..self.len]
    }

    /// Whether the last vertex joins the first.
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// The side the solid is on.
    pub fn solid_side(&self) -> SolidSide {
        self.solid
    }

    /// Number of segments (vertices - 1 when open, vertices when closed).
    pub fn segment_count(&self) -> usize {
        if self.closed {
            self.len
        } else {
            self.len - 1
        }
    }

    /// Segment `i`'s end points (from vertex `i` to the next). Panics when `i` is out of range.
    pub fn segment(&self, i: usize) -> (Vec2, Vec2) {
        assert!(i < self.segment_count(), "segment {i} out of range");
        (self.vertices[i], self.vertices[(i + 1) % self.len])
    }

    /// Length of segment `i`, metres.
    pub fn segment_length_m(&self, i: usize) -> f64 {
        let (a, b) = self.segment(i);
        (b - a).norm()
    }

    /// Unit face normal of segment `i`, pointing out of the solid, `[x, z]`.
    pub fn outward_normal(&self, i: usize) -> Vec2 {
        let (a, b) = self.segment(i);
        let d = (b - a) / (b - a).norm();
        // The right of the direction of travel is (dz, -dx).
        let right = Vec2::new(d.y, -d.x);
        match self.solid {
            SolidSide::Left => right,
            SolidSide::Right => -right,
        }
    }

    /// Whether segment `i` continues as a ray before its first vertex (open profiles' first
    /// segment) and after its last (open profiles' last segment).
    fn ray_ends(&self, i: usize) -> (bool, bool) {
        if self.closed {
            (false, false)
        } else {
            (i == 0, i + 1 == self.segment_count())
        }
    }

    /// The nearest point of the profile to `point_m` (`[x, z]`), with the signed distance and
    /// the outward normal there. `None` when the point is not finite.
    pub fn nearest(&self, point_m: &Vec2) -> Option<Nearest> {
        if !point_m.iter().all(|c| c.is_finite()) {
            return None;
        }
        let mut best: Option<(f64, Vec2, Feature, usize)> = None;
        for i in 0..self.segment_count() {
            let (a, b) = self.segment(i);
            let d = b - a;
            let t = (point_m - a).dot(&d) / d.norm_squared();
            let (ray_before, ray_after) = self.ray_ends(i);
            let (t, feature) = if t <= 0.0 && !ray_before {
                (0.0, Feature::Vertex(i))
            } else if t >= 1.0 && !ray_after {
                (1.0, Feature::Vertex((i + 1) % self.len))
            } else {
                (t, Feature::Segment(i))
            };
            let q = a + d * t;
            let dist_sq = (point_m - q).norm_squared();
            if best.is_none_or(|(b, ..)| dist_sq < b) {
                best = Some((dist_sq, q, feature, i));
            }
        }
        let (dist_sq, q, feature, segment) = best?;
        let distance = libm_sqrt(dist_sq);
        let (side_normal, face) = match feature {
            Feature::Segment(i) => (self.outward_normal(i), true),
            Feature::Vertex(k) => {
                // Vertex k joins segment k-1 (ending at k) and segment k; both exist here (an
                // open profile's end vertices lie on rays, never nearest as vertices).
                let prev = (k + self.segment_count() - 1) % self.segment_count();
                let pseudo = self.outward_normal(prev) + self.outward_normal(k);
                let n = pseudo.norm();
                let pseudo = if n > 1e-12 {
                    pseudo / n
                } else {
                    self.outward_normal(k)
                };
                (pseudo, false)
            }
        };
        let outside = (point_m - q).dot(&side_normal) >= 0.0;
        let signed_distance_m = if outside { distance } else { -distance };
        let normal = if face || distance <= 1e-12 {
            side_normal
        } else if outside {
            (point_m - q) / distance
        } else {
            (q - point_m) / distance
        };
        Some(Nearest {
            point_m: q,
            feature,
            segment,
            signed_distance_m,
            normal,
        })
    }

    /// Signed distance of `point_m` (`[x, z]`) from the profile, metres: positive outside the
    /// solid, negative inside; NaN for a non-finite point.
    pub fn signed_distance_m(&self, point_m: &Vec2) -> f64 {
        self.nearest(point_m)
            .map_or(f64::NAN, |n| n.signed_distance_m)
    }

    /// The point of segment `i` nearest to `point_m`, as the fraction `[0, 1]` of the way from
    /// its first vertex, and the distance, metres (rays ignored: the finite segment only).
    pub fn project_on_segment(&self, i: usize, point_m: &Vec2) -> (f64, f64) {
        let (a, b) = self.segment(i);
        let d = b - a;
        let t = ((point_m - a).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
        (t, (point_m - (a + d * t)).norm())
    }
}

impl<const CAP: usize> Surface for Profile<CAP> {
    fn contact(&self, position_m: &Vec3) -> Option<Contact> {
        let n = self.nearest(&Vec2::new(position_m.x, position_m.z))?;
        (n.signed_distance_m < 0.0).then_some(Contact {
            depth_m: -n.signed_distance_m,
            normal: Vec3::new(n.normal.x, 0.0, n.normal.y),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ceiling with a raised recess: solid above (towards +z), walked along +x.
    fn castellated() -> Profile {
        Profile::open(
            &[
                Vec2::new(0.0, 0.30),
                Vec2::new(0.2, 0.30),
                Vec2::new(0.2, 0.36),
                Vec2::new(0.3, 0.36),
                Vec2::new(0.3, 0.30),
                Vec2::new(0.5, 0.30),
            ],
            SolidSide::Left,
        )
        .unwrap()
    }

    fn contact_at(p: &Profile, x: f64, z: f64) -> Option<Contact> {
        p.contact(&Vec3::new(x, 0.7, z))
    }

    #[test]
    fn faces_give_their_depth_and_normal() {
        let p = castellated();
        // Under the low ceiling: free; above it: inside, normal -z.
        assert!(contact_at(&p, 0.1, 0.29).is_none());
        let c = contact_at(&p, 0.1, 0.305).unwrap();
        assert!((c.depth_m - 0.005).abs() < 1e-12);
        assert!((c.normal - Vec3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
        // Inside the recess (free), then pressed into its walls: normals along +-x.
        assert!(contact_at(&p, 0.25, 0.33).is_none());
        let c = contact_at(&p, 0.197, 0.33).unwrap();
        assert!((c.depth_m - 0.003).abs() < 1e-12);
        assert!((c.normal - Vec3::x()).norm() < 1e-12);
        let c = contact_at(&p, 0.304, 0.33).unwrap();
        assert!((c.normal + Vec3::x()).norm() < 1e-12);
    }

    #[test]
    fn corners_are_signed_right_both_ways() {
        let p = castellated();
        // The solid's convex corner (0.2, 0.30): the free space wraps around it.
        assert!(contact_at(&p, 0.21, 0.29).is_none());
        assert!(contact_at(&p, 0.2 + 1e-4, 0.31).is_none());
        let c = contact_at(&p, 0.19, 0.31).unwrap();
        assert!((c.depth_m - 0.01).abs() < 1e-12, "{c:?}");
        // The solid's concave corner (0.3, 0.36): inside, the vertex is nearest and the normal
        // points from the thimble to it.
        let c = contact_at(&p, 0.303, 0.364).unwrap();
        assert!((c.depth_m - 0.005).abs() < 1e-12, "{c:?}");
        assert!(
            (c.normal - Vec3::new(-0.6, 0.0, -0.8)).norm() < 1e-12,
            "{c:?}"
        );
        assert!(contact_at(&p, 0.299, 0.359).is_none());
    }

    #[test]
    fn open_ends_continue_as_rays() {
        let p = castellated();
        let c = contact_at(&p, -5.0, 0.31).unwrap();
        assert!((c.depth_m - 0.01).abs() < 1e-12);
        assert!(contact_at(&p, 9.0, 0.2).is_none());
        let n = p.nearest(&Vec2::new(-5.0, 0.31)).unwrap();
        assert_eq!(n.feature, Feature::Segment(0));
    }

    #[test]
    fn closed_polygons_have_an_inside() {
        // Counter-clockwise square in x-z: the inside is on the left.
        let square = [
            Vec2::new(0.1, 0.1),
            Vec2::new(0.3, 0.1),
            Vec2::new(0.3, 0.3),
            Vec2::new(0.1, 0.3),
        ];
        let solid = Profile::<4>::closed(&square, SolidSide::Left).unwrap();
        let c = solid.contact(&Vec3::new(0.2, 0.0, 0.12)).unwrap();
        assert!((c.depth_m - 0.02).abs() < 1e-12);
        assert!((c.normal + Vec3::z()).norm() < 1e-12);
        assert!(solid.contact(&Vec3::new(0.35, 0.0, 0.35)).is_none());
        assert!(solid.contact(&Vec3::new(0.0, 0.0, 0.2)).is_none());
        // The same polygon as a hole: solid outside.
        let hole = Profile::<4>::closed(&square, SolidSide::Right).unwrap();
        assert!(hole.contact(&Vec3::new(0.2, 0.0, 0.2)).is_none());
        let c = hole.contact(&Vec3::new(0.35, 0.0, 0.2)).unwrap();
        assert!((c.depth_m - 0.05).abs() < 1e-12);
        assert!((c.normal + Vec3::x()).norm() < 1e-12);
        // Outside a corner of the hole: the vertex is nearest, the normal points back to it.
        let c = hole.contact(&Vec3::new(0.33, 0.0, 0.34)).unwrap();
        assert!((c.depth_m - 0.05).abs() < 1e-12);
        assert!((c.normal - Vec3::new(-0.6, 0.0, -0.8)).norm() < 1e-12);
        assert_eq!(solid.segment_count(), 4);
        assert!((solid.outward_normal(0) - Vec2::new(0.0, -1.0)).norm() < 1e-12);
    }

    #[test]
    fn bad_input_is_refused_and_never_gives_nan() {
        let v = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
        ];
        assert_eq!(
            Profile::<2>::open(&v, SolidSide::Left),
            Err(ProfileError::TooManyVertices {
                given: 3,
                capacity: 2
            })
        );
        assert_eq!(
            Profile::<4>::closed(&v[..2], SolidSide::Left),
            Err(ProfileError::TooFewVertices { given: 2 })
        );
        assert_eq!(
            Profile::<4>::open(&[v[0], v[0]], SolidSide::Left),
            Err(ProfileError::DegenerateSegment { segment: 0 })
        );
        assert_eq!(
            Profile::<4>::open(&[v[0], Vec2::new(f64::NAN, 0.0)], SolidSide::Left),
            Err(ProfileError::NotFinite)
        );
        let p = castellated();
        assert!(p.contact(&Vec3::new(f64::NAN, 0.0, 0.3)).is_none());
        assert!(p.contact(&Vec3::new(f64::INFINITY, 0.0, 0.3)).is_none());
        assert!(p.signed_distance_m(&Vec2::new(0.1, f64::NAN)).is_nan());
        // On the boundary: touching is not contact.
        assert!(contact_at(&p, 0.1, 0.30).is_none());
    }

    #[test]
    fn every_point_agrees_with_a_brute_force_inside_test() {
        // Sample a grid around a closed, non-convex polygon and compare the sign with the
        // even-odd rule.
        let poly = [
            Vec2::new(0.0, 0.0),
            Vec2::new(0.4, 0.0),
            Vec2::new(0.4, 0.3),
            Vec2::new(0.25, 0.12),
            Vec2::new(0.1, 0.3),
        ];
        let p = Profile::<8>::closed(&poly, SolidSide::Left).unwrap();
        let even_odd = |q: Vec2| {
            let mut inside = false;
            for i in 0..poly.len() {
                let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
                if (a.y > q.y) != (b.y > q.y) {
                    let x = a.x + (q.y - a.y) / (b.y - a.y) * (b.x - a.x);
                    if q.x < x {
                        inside = !inside;
                    }
                }
            }
            inside
        };
        for i in 0..=60 {
            for j in 0..=50 {
                let q = Vec2::new(
                    -0.1 + 0.6 * i as f64 / 60.0 + 1e-4,
                    -0.1 + 0.5 * j as f64 / 50.0 + 1e-4,
                );
                let n = p.nearest(&q).unwrap();
                assert_eq!(n.signed_distance_m < 0.0, even_odd(q), "{q:?}");
                assert!((n.normal.norm() - 1.0).abs() < 1e-9);
            }
        }
    }
}
