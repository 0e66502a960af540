//! The surface the finger touches, as the control step needs it.
//!
//! The surface model (built from vision) implements [`Surface`]; the control step only asks for
//! the penetration depth and the outward normal at the thimble.

use crate::Vec3;

/// Contact with a surface at a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// How far the point is inside the surface, metres (> 0).
    pub depth_m: f64,
    /// Outward unit normal of the surface at the contact (points out of the solid).
    pub normal: Vec3,
}

/// A touchable surface. Implementations must answer without allocating, in bounded time: the
/// control thread calls `contact` every cycle.
pub trait Surface {
    /// The contact at `position_m`, or `None` when the point is outside the solid.
    fn contact(&self, position_m: &Vec3) -> Option<Contact>;
}

/// A half-space: the solid is on the side opposite to `normal` of the plane through `point_m`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    point_m: Vec3,
    normal: Vec3,
}

impl Plane {
    /// A plane through `point_m` with outward normal `normal` (normalised here). `None` when the
    /// normal is zero or not finite.
    pub fn new(point_m: Vec3, normal: Vec3) -> Option<Plane> {
        let n = normal.norm();
        if !(n.is_finite() && n > 1e-12 && point_m.iter().all(|c| c.is_finite())) {
            return None;
        }
        Some(Plane {
            point_m,
            normal: normal / n,
        })
    }

    /// The point the plane was given through, metres.
    pub fn point_m(&self) -> Vec3 {
        self.point_m
    }

    /// Outward unit normal.
    pub fn normal(&self) -> Vec3 {
        self.normal
    }

    /// Signed distance of a point from the plane, positive outside the solid.
    pub fn signed_distance_m(&self, position_m: &Vec3) -> f64 {
        (position_m - self.point_m).dot(&self.normal)
    }
}

impl Surface for Plane {
    fn contact(&self, position_m: &Vec3) -> Option<Contact> {
        let d = self.signed_distance_m(position_m);
        (d < 0.0).then_some(Contact {
            depth_m: -d,
            normal: self.normal,
        })
    }
}

/// No surface at all (free space everywhere).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FreeSpace;

impl Surface for FreeSpace {
    fn contact(&self, _position_m: &Vec3) -> Option<Contact> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_contact_depth_and_normal() {
        let wall = Plane::new(Vec3::new(0.0, 0.0, 0.3), Vec3::new(0.0, 0.0, -2.0)).unwrap();
        assert!(wall.contact(&Vec3::new(0.1, 0.1, 0.29)).is_none());
        let c = wall.contact(&Vec3::new(0.1, 0.1, 0.305)).unwrap();
        assert!((c.depth_m - 0.005).abs() < 1e-12);
        assert_eq!(c.normal, Vec3::new(0.0, 0.0, -1.0));
        assert!(Plane::new(Vec3::zeros(), Vec3::zeros()).is_none());
    }
}
