//! The bas-relief surface as the haptic rendering needs it (paper section 2).
//!
//! A bas-relief is a height field over the device's `x`-`y` plane: the surface is
//! `z = h(x, y)`, the solid lies on its `+z` side (away from the user) and the outward normal
//! always has a negative `z` component (it forms an angle within ±90° with the reference normal
//! `-z`). Besides the penetration query of [`Surface`], the proxy (god-object) contact needs the
//! height under a point and the first crossing of a straight motion into the solid.

use crate::surface::{Contact, Plane, Surface};
use crate::Vec3;

/// The surface under a point `(x, y)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeightSample {
    /// Device `z` of the surface, metres.
    pub z_m: f64,
    /// Interpolated (force-shading) outward unit normal.
    pub normal: Vec3,
    /// Outward unit normal of the flat face under the point.
    pub face_normal: Vec3,
}

/// Where a straight motion first enters the solid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentHit {
    /// Fraction of the motion, `[0, 1]`, at which the surface is reached.
    pub t: f64,
    /// The point where the surface is reached, metres.
    pub point_m: Vec3,
    /// Outward unit normal of the flat face that is reached.
    pub face_normal: Vec3,
}

/// A bas-relief surface (a height field along `-z`). Implementations answer without allocating
/// and in bounded time: the control thread calls these every period.
pub trait ReliefSurface: Surface {
    /// The surface under `(x_m, y_m)`, or `None` where it is undefined.
    fn height(&self, x_m: f64, y_m: f64) -> Option<HeightSample>;

    /// The first point of the straight motion from `from_m` to `to_m` that lies on or inside the
    /// solid (`t = 0` when `from_m` is already inside), or `None` when the motion stays outside.
    fn segment_hit(&self, from_m: &Vec3, to_m: &Vec3) -> Option<SegmentHit>;
}

/// Penetration of a point into a relief measured along `z` (the height-field convention):
/// `depth = z - h(x, y)` when positive, with the interpolated normal. Helper for implementations
/// of [`Surface::contact`].
pub fn height_field_contact<S: ReliefSurface + ?Sized>(
    surface: &S,
    position_m: &Vec3,
) -> Option<Contact> {
    if !position_m.iter().all(|c| c.is_finite()) {
        return None;
    }
    let h = surface.height(position_m.x, position_m.y)?;
    let depth_m = position_m.z - h.z_m;
    (depth_m > 0.0).then_some(Contact {
        depth_m,
        normal: h.normal,
    })
}

/// A plane whose outward normal points towards the user (`normal.z < 0`) is a relief.
impl ReliefSurface for Plane {
    fn height(&self, x_m: f64, y_m: f64) -> Option<HeightSample> {
        let n = self.normal();
        if n.z >= -1e-9 || !(x_m.is_finite() && y_m.is_finite()) {
            return None;
        }
        // On the plane: n·(p - q) = 0 with p = (x, y, z); signed distance is linear in z.
        let at_zero = self.signed_distance_m(&Vec3::new(x_m, y_m, 0.0));
        let z_m = -at_zero / n.z;
        Some(HeightSample {
            z_m,
            normal: n,
            face_normal: n,
        })
    }

    fn segment_hit(&self, from_m: &Vec3, to_m: &Vec3) -> Option<SegmentHit> {
        let d0 = self.signed_distance_m(from_m);
        let d1 = self.signed_distance_m(to_m);
        if !(d0.is_finite() && d1.is_finite()) {
            return None;
        }
        if d0 <= 0.0 {
            return Some(SegmentHit {
                t: 0.0,
                point_m: *from_m,
                face_normal: self.normal(),
            });
        }
        if d1 > 0.0 {
            return None;
        }
        let t = (d0 / (d0 - d1)).clamp(0.0, 1.0);
        Some(SegmentHit {
            t,
            point_m: from_m + (to_m - from_m) * t,
            face_normal: self.normal(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_as_relief() {
        let wall = Plane::new(Vec3::new(0.0, 0.0, 0.3), Vec3::new(0.0, 0.0, -1.0)).unwrap();
        let h = wall.height(0.1, 0.2).unwrap();
        assert!((h.z_m - 0.3).abs() < 1e-12);
        let c = height_field_contact(&wall, &Vec3::new(0.1, 0.2, 0.31)).unwrap();
        assert!((c.depth_m - 0.01).abs() < 1e-12);
        let hit = wall
            .segment_hit(&Vec3::new(0.0, 0.0, 0.2), &Vec3::new(0.0, 0.0, 0.4))
            .unwrap();
        assert!((hit.t - 0.5).abs() < 1e-12);
        assert!(wall
            .segment_hit(&Vec3::new(0.0, 0.0, 0.2), &Vec3::new(0.1, 0.0, 0.25))
            .is_none());
        let facing_away = Plane::new(Vec3::zeros(), Vec3::z()).unwrap();
        assert!(facing_away.height(0.0, 0.0).is_none());
    }
}
