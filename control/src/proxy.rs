//! Proxy (god-object) contact on a bas-relief.
//!
//! The rendered contact follows a proxy point that is constrained to stay outside the solid
//! (Zilles & Salisbury's god-object, CHAI3D's finger-proxy, HAPI's god-object renderer): each
//! period the proxy moves towards the finger along straight motions that stop at the surface and
//! then slide along the planes of the faces they met (at most [`MAX_CONSTRAINTS`] planes). The
//! force is the spring `K (proxy - finger)`: however fast the finger moves, and however thin a
//! feature is, the proxy cannot cross the surface, so the finger never pops through.
//!
//! Force shading: the component of `proxy - finger` along the face normal is turned onto the
//! normal interpolated across the faces, so the force direction does not jump at edges. Where
//! the proxy itself jumps (a finger several millimetres deep passing under a convex edge makes
//! it change faces) the rendered spring follows in steps of at most `max_offset_step_m` per
//! period, so the force never changes by more than `K max_offset_step_m` in one period from it.
//! Optional Coulomb friction (static / dynamic cone) holds the proxy where it is while the
//! finger's tangential pull stays inside the cone.
//!
//! Pure, allocation-free, bounded: every update does at most `max_iterations` surface queries.

use crate::relief::ReliefSurface;
use crate::surface::{Contact, Surface};
use crate::Vec3;
use core::cell::Cell;

/// Most constraint planes the proxy honours at once (a corner of three faces).
pub const MAX_CONSTRAINTS: usize = 3;

/// Settings of the proxy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProxyParams {
    /// Clearance kept between the proxy and the surface, metres (> 0, small: 1 µm).
    pub skin_m: f64,
    /// Static friction coefficient `μs` (0 = frictionless).
    pub static_friction: f64,
    /// Dynamic friction coefficient `μd` (`0 <= μd <= μs`).
    pub dynamic_friction: f64,
    /// Most straight moves per update (>= 1; 4 is plenty for three constraint planes).
    pub max_iterations: u32,
    /// Apply force shading (interpolated normals).
    pub force_shading: bool,
    /// Longest path the proxy slides along the surface in one update, metres (> 0). The default
    /// (0.1 m) does not limit it in practice; a small value makes the proxy itself lag behind a
    /// fast finger (force smoothing is `max_offset_step_m`'s job). Free-space motion is never
    /// limited.
    pub max_slide_m: f64,
    /// Largest change of the rendered spring displacement per update, metres (> 0): the force
    /// changes by at most `K max_offset_step_m` per period. The proxy itself always goes where
    /// the constraints take it; where it jumps (a finger a few millimetres deep passing under
    /// a convex edge makes it change faces) or the finger leaves the surface, the spring follows
    /// over a few periods instead of in one step. Limits only motions faster than
    /// `max_offset_step_m` per period.
    pub max_offset_step_m: f64,
}

impl Default for ProxyParams {
    fn default() -> Self {
        ProxyParams {
            skin_m: 1e-6,
            static_friction: 0.0,
            dynamic_friction: 0.0,
            max_iterations: 6,
            force_shading: true,
            max_slide_m: 0.1,
            max_offset_step_m: 5e-4,
        }
    }
}

/// A rejected proxy setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProxyParamsError {
    /// The offending field.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
    /// What is allowed.
    pub allowed: &'static str,
}

impl core::fmt::Display for ProxyParamsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "proxy: {} = {} must be {}",
            self.field, self.value, self.allowed
        )
    }
}

impl ProxyParams {
    /// Check every field.
    pub fn validate(&self) -> Result<(), ProxyParamsError> {
        let err = |field, value, allowed| {
            Err(ProxyParamsError {
                field,
                value,
                allowed,
            })
        };
        if !(self.skin_m > 0.0 && self.skin_m <= 1e-3) {
            return err("skin_m", self.skin_m, "in (0, 1e-3] m");
        }
        if !(self.static_friction >= 0.0 && self.static_friction <= 10.0) {
            return err("static_friction", self.static_friction, "in [0, 10]");
        }
        if !(self.dynamic_friction >= 0.0 && self.dynamic_friction <= self.static_friction) {
            return err(
                "dynamic_friction",
                self.dynamic_friction,
                "in [0, static_friction]",
            );
        }
        if !(self.max_slide_m > 0.0 && self.max_slide_m <= 0.1) {
            return err("max_slide_m", self.max_slide_m, "in (0, 0.1] m");
        }
        if !(self.max_offset_step_m > 0.0 && self.max_offset_step_m.is_finite()) {
            return err(
                "max_offset_step_m",
                self.max_offset_step_m,
                "finite and > 0 m",
            );
        }
        if !(1..=16).contains(&self.max_iterations) {
            return err("max_iterations", self.max_iterations as f64, "in [1, 16]");
        }
        Ok(())
    }
}

/// The outcome of one proxy update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProxyContact {
    /// The proxy, metres (outside the solid).
    pub proxy_m: Vec3,
    /// The spring displacement whose `K` multiple is the contact force, metres (zero in free
    /// space; force shading applied).
    pub offset_m: Vec3,
    /// Constraint planes met this period (0 = free space).
    pub constraints: u8,
    /// The proxy is held by static friction.
    pub sticking: bool,
}

impl ProxyContact {
    /// The contact as the control step takes it: depth `|offset|` along `offset / |offset|`, so
    /// that `K depth n = K offset`. `None` in free space.
    pub fn contact(&self) -> Option<Contact> {
        let depth_m = self.offset_m.norm();
        (depth_m > 0.0 && depth_m.is_finite()).then(|| Contact {
            depth_m,
            normal: self.offset_m / depth_m,
        })
    }
}

/// A constraint plane: `n · p >= c` outside (n the outward normal).
#[derive(Debug, Clone, Copy, PartialEq)]
struct ConstraintPlane {
    normal: Vec3,
    offset: f64,
}

impl ConstraintPlane {
    fn signed(&self, p: &Vec3) -> f64 {
        self.normal.dot(p) - self.offset
    }
}

/// The god-object: a proxy point that stays outside the relief. Plain `Copy` state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GodObject {
    params: ProxyParams,
    proxy_m: Vec3,
    placed: bool,
    sliding: bool,
    /// The spring displacement rendered at the last update.
    offset_m: Vec3,
}

impl GodObject {
    /// A proxy with the given (validated) settings; it is placed at the first update.
    pub fn new(params: ProxyParams) -> Result<GodObject, ProxyParamsError> {
        params.validate()?;
        Ok(GodObject {
            params,
            proxy_m: Vec3::zeros(),
            placed: false,
            sliding: false,
            offset_m: Vec3::zeros(),
        })
    }

    /// The settings.
    pub fn params(&self) -> &ProxyParams {
        &self.params
    }

    /// The proxy, metres (meaningful after the first update).
    pub fn proxy_m(&self) -> Vec3 {
        self.proxy_m
    }

    /// Forget the proxy: the next update places it at the finger (lifted out of the solid).
    pub fn reset(&mut self) {
        self.placed = false;
        self.sliding = false;
        self.offset_m = Vec3::zeros();
    }

    /// The displacement to render: `target`, approached by at most `max_offset_step_m`.
    fn limit_offset(&mut self, target: Vec3) -> Vec3 {
        let last = if self.offset_m.iter().all(|c| c.is_finite()) {
            self.offset_m
        } else {
            Vec3::zeros()
        };
        let change = target - last;
        let len = change.norm();
        let max = self.params.max_offset_step_m;
        self.offset_m = if len > max {
            last + change * (max / len)
        } else {
            target
        };
        self.offset_m
    }

    /// Lift a point out of the solid along `-z` (the height field's escape direction).
    fn lift_out<S: ReliefSurface + ?Sized>(&self, surface: &S, p: &mut Vec3) {
        if let Some(h) = surface.height(p.x, p.y) {
            let top = h.z_m - self.params.skin_m;
            if p.z > top && top.is_finite() {
                p.z = top;
            }
        }
    }

    /// Move the proxy towards `finger_m` without crossing the surface; return the contact.
    pub fn update<S: ReliefSurface + ?Sized>(
        &mut self,
        surface: &S,
        finger_m: &Vec3,
    ) -> ProxyContact {
        let free = ProxyContact {
            proxy_m: *finger_m,
            offset_m: Vec3::zeros(),
            constraints: 0,
            sticking: false,
        };
        if !finger_m.iter().all(|c| c.is_finite()) {
            return ProxyContact {
                proxy_m: self.proxy_m,
                ..free
            };
        }
        if !self.placed || !self.proxy_m.iter().all(|c| c.is_finite()) {
            self.proxy_m = *finger_m;
            self.placed = true;
            self.sliding = false;
        }
        let skin = self.params.skin_m;
        let previous = self.proxy_m;
        // The surface may have been replaced under the proxy: start from outside it.
        let mut p = previous;
        self.lift_out(surface, &mut p);
        let start = p;

        let mut planes = [ConstraintPlane {
            normal: Vec3::zeros(),
            offset: 0.0,
        }; MAX_CONSTRAINTS];
        let mut count = 0usize;
        let mut goal = *finger_m;
        // Sliding along the surface is limited per update; reaching it is not.
        let mut budget = self.params.max_slide_m;
        let mut constrained = false;
        // Constraint planes met at any time this update (for friction and shading).
        let mut met = 0usize;
        for _ in 0..self.params.max_iterations {
            let motion = goal - p;
            let length = motion.norm();
            if length <= 1e-12 {
                break;
            }
            let limited = constrained && length > budget;
            let target = if limited {
                p + motion * (budget / length)
            } else {
                goal
            };
            match surface.segment_hit(&p, &target) {
                None => {
                    if constrained {
                        budget -= (target - p).norm();
                    }
                    p = target;
                    if limited || count == 0 {
                        break;
                    }
                    // A constrained goal reached in the air (past a convex edge): head for the
                    // finger again from here.
                    count = 0;
                    goal = *finger_m;
                }
                Some(hit) => {
                    let reach = target - p;
                    let reach_len = reach.norm();
                    let t_back = if reach_len > 0.0 {
                        (hit.t - skin / reach_len).max(0.0)
                    } else {
                        0.0
                    };
                    if constrained {
                        budget = (budget - reach_len * t_back).max(0.0);
                    }
                    p += reach * t_back;
                    constrained = true;
                    let n = hit.face_normal;
                    let plane = ConstraintPlane {
                        normal: n,
                        offset: n.dot(&hit.point_m) + skin,
                    };
                    if count == MAX_CONSTRAINTS
                        || planes[..count].iter().any(|q| {
                            q.normal.dot(&n) > 1.0 - 1e-9 && (q.offset - plane.offset).abs() < skin
                        })
                    {
                        // A corner, or the same plane again: the proxy stays here.
                        break;
                    }
                    planes[count] = plane;
                    count += 1;
                    met = met.max(count);
                    goal = constrained_goal(finger_m, &planes[..count], &p);
                }
            }
        }
        self.lift_out(surface, &mut p);
        if !constrained || (p - finger_m).norm() <= 1e-12 {
            // The finger is outside: the proxy joins it (after the same lift, in case the finger
            // is numerically on the surface).
            self.proxy_m = p;
            self.sliding = false;
            let offset_m = self.limit_offset(p - finger_m);
            return ProxyContact {
                proxy_m: p,
                offset_m,
                constraints: 0,
                sticking: false,
            };
        }

        // Friction: keep the previous proxy while the finger's pull stays inside the cone.
        let mut sticking = false;
        let mu = if self.sliding {
            self.params.dynamic_friction
        } else {
            self.params.static_friction
        };
        let under = surface.height(p.x, p.y);
        let spring_dir = (p - finger_m).normalize();
        // The contact normal: the face's under the proxy, or in a crease the spring's direction.
        let n_contact = match under {
            Some(h) if count <= 1 => h.face_normal,
            _ => spring_dir,
        };
        if mu > 0.0 {
            let n = n_contact;
            let normal_depth = (p - finger_m).dot(&n).max(0.0);
            let slip = start - p;
            let tangential = slip - n * slip.dot(&n);
            let tangential_len = tangential.norm();
            let cone = mu * normal_depth;
            let mut candidate = if tangential_len <= cone {
                sticking = true;
                start
            } else {
                p + slip * (self.params.dynamic_friction * normal_depth / tangential_len)
            };
            // The candidate lies between two points outside the solid, a short way apart (this
            // period's slide); across a convex edge the chord dips into the solid: lift it out.
            self.lift_out(surface, &mut candidate);
            p = candidate;
            self.sliding = !sticking;
        } else {
            self.sliding = count > 0;
        }
        self.proxy_m = p;

        let raw = p - finger_m;
        let mut offset = raw;
        if self.params.force_shading && count <= 1 {
            if let Some(h) = surface.height(p.x, p.y) {
                let n_face = h.face_normal;
                let along = raw.dot(&n_face);
                if along > 0.0 && h.normal.iter().all(|c| c.is_finite()) {
                    offset = raw - n_face * along + h.normal * along;
                }
            }
        }
        ProxyContact {
            proxy_m: p,
            offset_m: self.limit_offset(offset),
            constraints: met as u8,
            sticking,
        }
    }
}

/// The point closest to `finger` that satisfies the constraint planes (as equalities for the
/// ones it violates): one plane, the line of two planes, or `stay` for three.
fn constrained_goal(finger: &Vec3, planes: &[ConstraintPlane], stay: &Vec3) -> Vec3 {
    let last = planes[planes.len() - 1];
    let on_last = finger - last.normal * last.signed(finger).min(0.0);
    let violated = planes[..planes.len() - 1]
        .iter()
        .find(|q| q.signed(&on_last) < -1e-12);
    let Some(other) = violated else {
        return on_last;
    };
    // Project onto the line where `last` and `other` meet.
    let (n1, n2) = (last.normal, other.normal);
    let g = n1.dot(&n2);
    let det = 1.0 - g * g;
    if det < 1e-9 {
        return *stay;
    }
    let r1 = last.offset - n1.dot(finger);
    let r2 = other.offset - n2.dot(finger);
    let a = (r1 - g * r2) / det;
    let b = (r2 - g * r1) / det;
    let on_line = finger + n1 * a + n2 * b;
    if planes.len() == 3 {
        let third = if core::ptr::eq(other, &planes[0]) {
            planes[1]
        } else {
            planes[0]
        };
        if third.signed(&on_line) < -1e-12 {
            return *stay;
        }
    }
    on_line
}

/// A relief rendered through a god-object, usable wherever a [`Surface`] is taken (the control
/// step calls `contact` once per period; each call advances the proxy).
#[derive(Debug)]
pub struct ProxySurface<'a, S: ReliefSurface + ?Sized> {
    surface: &'a S,
    proxy: Cell<GodObject>,
    last: Cell<Option<ProxyContact>>,
}

impl<'a, S: ReliefSurface + ?Sized> ProxySurface<'a, S> {
    /// Render `surface` through a proxy with the given (validated) settings.
    pub fn new(surface: &'a S, params: ProxyParams) -> Result<Self, ProxyParamsError> {
        Ok(ProxySurface {
            surface,
            proxy: Cell::new(GodObject::new(params)?),
            last: Cell::new(None),
        })
    }

    /// The last proxy update, if any.
    pub fn last(&self) -> Option<ProxyContact> {
        self.last.get()
    }
}

impl<S: ReliefSurface + ?Sized> Surface for ProxySurface<'_, S> {
    fn contact(&self, position_m: &Vec3) -> Option<Contact> {
        let mut proxy = self.proxy.get();
        let c = proxy.update(self.surface, position_m);
        self.proxy.set(proxy);
        self.last.set(Some(c));
        c.contact()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::relief::{height_field_contact, HeightSample, SegmentHit};
    use crate::surface::Plane;
    use proptest::prelude::*;

    /// A terrace: `z = low` for `x < edge`, `z = high` (nearer the user) beyond, joined by a
    /// vertical wall — the hardest case for a height field.
    struct Terrace {
        edge_x: f64,
        low_z: f64,
        high_z: f64,
    }

    impl Terrace {
        fn h(&self, x: f64) -> f64 {
            if x < self.edge_x {
                self.low_z
            } else {
                self.high_z
            }
        }
    }

    impl Surface for Terrace {
        fn contact(&self, p: &Vec3) -> Option<Contact> {
            height_field_contact(self, p)
        }
    }

    impl ReliefSurface for Terrace {
        fn height(&self, x: f64, _y: f64) -> Option<HeightSample> {
            Some(HeightSample {
                z_m: self.h(x),
                normal: -Vec3::z(),
                face_normal: -Vec3::z(),
            })
        }
        fn segment_hit(&self, a: &Vec3, b: &Vec3) -> Option<SegmentHit> {
            let inside = |p: &Vec3| p.z >= self.h(p.x);
            if inside(a) {
                return Some(SegmentHit {
                    t: 0.0,
                    point_m: *a,
                    face_normal: -Vec3::z(),
                });
            }
            let d = b - a;
            let mut best: Option<SegmentHit> = None;
            // Horizontal faces.
            for z in [self.low_z, self.high_z] {
                if d.z > 0.0 {
                    let t = (z - a.z) / d.z;
                    if (0.0..=1.0).contains(&t) {
                        let p = a + d * t;
                        if (self.h(p.x) - z).abs() < 1e-15 && best.is_none_or(|h| t < h.t) {
                            best = Some(SegmentHit {
                                t,
                                point_m: p,
                                face_normal: -Vec3::z(),
                            });
                        }
                    }
                }
            }
            // The wall at x = edge between high and low, facing -x.
            if d.x > 0.0 {
                let t = (self.edge_x - a.x) / d.x;
                if (0.0..=1.0).contains(&t) {
                    let p = a + d * t;
                    if p.z >= self.high_z && best.is_none_or(|h| t < h.t) {
                        best = Some(SegmentHit {
                            t,
                            point_m: p,
                            face_normal: -Vec3::x(),
                        });
                    }
                }
            }
            best
        }
    }

    fn wall() -> Plane {
        Plane::new(Vec3::new(0.0, 0.0, 0.3), -Vec3::z()).unwrap()
    }

    #[test]
    fn free_space_proxy_follows_the_finger() {
        let mut g = GodObject::new(ProxyParams::default()).unwrap();
        let c = g.update(&wall(), &Vec3::new(0.1, 0.1, 0.2));
        assert_eq!(c.constraints, 0);
        assert_eq!(c.offset_m, Vec3::zeros());
        assert!(c.contact().is_none());
    }

    #[test]
    fn pressing_the_wall_gives_the_spring_along_the_normal() {
        let mut g = GodObject::new(ProxyParams::default()).unwrap();
        g.update(&wall(), &Vec3::new(0.1, 0.1, 0.29));
        // A 2 cm jump of the finger: the spring grows by at most 0.5 mm per update.
        let first = g.update(&wall(), &Vec3::new(0.1, 0.1, 0.31));
        assert!((first.offset_m.norm() - 5e-4).abs() < 1e-12);
        let mut c = first;
        for _ in 0..30 {
            c = g.update(&wall(), &Vec3::new(0.1, 0.1, 0.31));
        }
        assert_eq!(c.constraints, 1);
        assert!((c.proxy_m.z - 0.3).abs() < 1e-5);
        let contact = c.contact().unwrap();
        assert!((contact.depth_m - 0.01).abs() < 1e-5);
        assert!((contact.normal + Vec3::z()).norm() < 1e-9);
    }

    #[test]
    fn fast_motion_never_pops_through() {
        // From above the wall straight to 20 cm behind it in one period.
        let unlimited = ProxyParams {
            max_slide_m: 0.1,
            max_offset_step_m: 1.0,
            ..ProxyParams::default()
        };
        let mut g = GodObject::new(unlimited).unwrap();
        g.update(&wall(), &Vec3::new(0.1, 0.1, 0.25));
        let c = g.update(&wall(), &Vec3::new(0.15, 0.1, 0.5));
        assert!(c.proxy_m.z <= 0.3);
        assert!(
            (c.proxy_m.x - 0.15).abs() < 1e-9,
            "slid along the plane to the finger's projection"
        );
        assert!((c.offset_m.z + 0.2).abs() < 1e-5);
        // With a 0.5 mm slide limit the proxy reaches the wall where the motion meets it and
        // slides at most 0.5 mm further.
        let mut g = GodObject::new(ProxyParams {
            max_slide_m: 5e-4,
            ..ProxyParams::default()
        })
        .unwrap();
        g.update(&wall(), &Vec3::new(0.1, 0.1, 0.25));
        let c = g.update(&wall(), &Vec3::new(0.15, 0.1, 0.5));
        let reached_x = 0.1 + 0.05 * (0.05 / 0.25);
        assert!(
            (c.proxy_m.x - (reached_x + 5e-4)).abs() < 1e-6,
            "{:?}",
            c.proxy_m
        );
        assert!(c.proxy_m.z <= 0.3);
    }

    #[test]
    fn the_proxy_stops_at_a_wall_the_finger_crosses_underneath() {
        let t = Terrace {
            edge_x: 0.2,
            low_z: 0.35,
            high_z: 0.32,
        };
        let mut g = GodObject::new(ProxyParams {
            max_slide_m: 0.1,
            max_offset_step_m: 1.0,
            ..ProxyParams::default()
        })
        .unwrap();
        // Resting on the low floor, pressing 1 cm.
        g.update(&t, &Vec3::new(0.1, 0.0, 0.34));
        let c = g.update(&t, &Vec3::new(0.1, 0.0, 0.36));
        assert!((c.proxy_m.z - 0.35).abs() < 1e-5);
        // The finger moves under the terrace: the proxy is stopped by the wall.
        let c = g.update(&t, &Vec3::new(0.25, 0.0, 0.36));
        assert!(c.proxy_m.x <= 0.2, "proxy {:?}", c.proxy_m);
        assert!(c.offset_m.x < -0.04, "pushed back out of the wall");
        assert_eq!(c.constraints, 2, "floor and wall");
    }

    #[test]
    fn static_friction_holds_and_dynamic_friction_slides() {
        let params = ProxyParams {
            static_friction: 0.5,
            dynamic_friction: 0.3,
            max_slide_m: 0.1,
            max_offset_step_m: 1.0,
            ..ProxyParams::default()
        };
        let mut g = GodObject::new(params).unwrap();
        g.update(&wall(), &Vec3::new(0.1, 0.0, 0.29));
        g.update(&wall(), &Vec3::new(0.1, 0.0, 0.31));
        // 1 cm deep, 4 mm sideways: inside the static cone (5 mm).
        let c = g.update(&wall(), &Vec3::new(0.104, 0.0, 0.31));
        assert!(c.sticking);
        assert!((c.proxy_m.x - 0.1).abs() < 1e-9);
        // 8 mm sideways: slides, and lags by the dynamic cone (3 mm).
        let c = g.update(&wall(), &Vec3::new(0.108, 0.0, 0.31));
        assert!(!c.sticking);
        assert!((c.proxy_m.x - 0.105).abs() < 1e-6, "{:?}", c.proxy_m);
    }

    #[test]
    fn the_spring_follows_a_proxy_jump_and_a_release_in_bounded_steps() {
        let t = Terrace {
            edge_x: 0.2,
            low_z: 0.35,
            high_z: 0.32,
        };
        let mut g = GodObject::new(ProxyParams::default()).unwrap();
        g.update(&t, &Vec3::new(0.25, 0.0, 0.31));
        let mut last = Vec3::zeros();
        let mut path = std::vec::Vec::new();
        // Press 5 mm into the terrace top, then lift off.
        for k in 0..40 {
            path.push(Vec3::new(0.25, 0.0, 0.32 + 0.000125 * k as f64));
        }
        for _ in 0..30 {
            path.push(Vec3::new(0.25, 0.0, 0.31));
        }
        for p in path {
            let c = g.update(&t, &p);
            assert!((c.offset_m - last).norm() <= 5e-4 + 1e-12);
            last = c.offset_m;
        }
        assert_eq!(last, Vec3::zeros(), "released after a few periods");
    }

    #[test]
    fn surface_adapter_feeds_the_spring() {
        let w = wall();
        let s = ProxySurface::new(&w, ProxyParams::default()).unwrap();
        assert!(s.contact(&Vec3::new(0.0, 0.0, 0.29)).is_none());
        assert!(s.contact(&Vec3::new(0.0, 0.0, 0.3001)).is_some());
        let c = s.contact(&Vec3::new(0.0, 0.0, 0.3003)).unwrap();
        assert!((c.depth_m - 0.0003).abs() < 1e-5);
        assert!(GodObject::new(ProxyParams {
            dynamic_friction: 1.0,
            ..ProxyParams::default()
        })
        .is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(11), ..ProptestConfig::default() })]

        /// Whatever the finger does, the proxy ends outside the terrace.
        #[test]
        fn the_proxy_never_ends_inside(path in prop::collection::vec((0.0..0.4f64, -0.1..0.1f64, 0.2..0.45f64), 1..60),
                                        mu in 0.0..0.8f64) {
            let t = Terrace { edge_x: 0.2, low_z: 0.35, high_z: 0.32 };
            let mut g = GodObject::new(ProxyParams { static_friction: mu, dynamic_friction: mu * 0.6, ..ProxyParams::default() }).unwrap();
            for (x, y, z) in path {
                let c = g.update(&t, &Vec3::new(x, y, z));
                prop_assert!(c.proxy_m.iter().all(|v| v.is_finite()));
                prop_assert!(c.offset_m.iter().all(|v| v.is_finite()));
                prop_assert!(c.proxy_m.z < t.h(c.proxy_m.x), "proxy {:?} inside", c.proxy_m);
            }
        }
    }
}
