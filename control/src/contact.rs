//! The contact model: a spring along the surface normal (paper section 5,
//! `f_e = -K dx n`), with optional damping, frictionless along the surface.

use crate::surface::Contact;
use crate::Vec3;

/// Spring-damper contact along the normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactModel {
    /// Stiffness `K`, N/m.
    pub stiffness_n_per_m: f64,
    /// Damping along the normal, N·s/m (0 = none).
    pub damping_n_s_per_m: f64,
}

/// The reaction force of the surface on the thimble, newtons: `(K depth - B v_n) n` with the
/// damping's push at most the spring's (`K depth`), never pulling the thimble into the surface
/// (unilateral), zero along the surface so the finger slides
/// freely (the paper's Figs. 13-14). `velocity_m_s` is the thimble velocity; non-finite inputs
/// give no force.
pub fn contact_force(model: &ContactModel, contact: &Contact, velocity_m_s: &Vec3) -> Vec3 {
    let normal_speed = velocity_m_s.dot(&contact.normal);
    let normal_speed = if normal_speed.is_finite() {
        normal_speed
    } else {
        0.0
    };
    // The damper pushes back at most as hard as the spring: the force grows from zero as the
    // finger enters the surface (no step of `B v` at the onset of a touch) and at most doubles
    // the spring's while it goes in.
    let spring = model.stiffness_n_per_m * contact.depth_m;
    let damper = (-model.damping_n_s_per_m * normal_speed).min(spring.abs());
    let magnitude = spring + damper;
    if magnitude.is_finite() && magnitude > 0.0 {
        contact.normal * magnitude
    } else {
        Vec3::zeros()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spring_damper_is_normal_and_unilateral() {
        let model = ContactModel {
            stiffness_n_per_m: 400.0,
            damping_n_s_per_m: 2.0,
        };
        let c = Contact {
            depth_m: 0.005,
            normal: Vec3::new(0.0, 0.0, -1.0),
        };
        // Penetrating (moving against the normal): spring plus damping.
        let f = contact_force(&model, &c, &Vec3::new(0.3, 0.0, 0.1));
        assert!((f - Vec3::new(0.0, 0.0, -2.2)).norm() < 1e-12);
        // Entering fast at the surface: the damper gives at most the spring's force, so the
        // touch starts at zero force, not with a step of B v.
        let fast = contact_force(&model, &c, &Vec3::new(0.0, 0.0, 2.0));
        assert!((fast - Vec3::new(0.0, 0.0, -4.0)).norm() < 1e-12);
        let onset = Contact { depth_m: 0.0, ..c };
        assert_eq!(
            contact_force(&model, &onset, &Vec3::new(0.0, 0.0, 2.0)),
            Vec3::zeros()
        );
        // Sliding along the surface adds nothing.
        let f = contact_force(&model, &c, &Vec3::new(0.3, -0.2, 0.0));
        assert!((f - Vec3::new(0.0, 0.0, -2.0)).norm() < 1e-12);
        // Leaving fast: never sticky.
        let f = contact_force(&model, &c, &Vec3::new(0.0, 0.0, -5.0));
        assert_eq!(f, Vec3::zeros());
    }
}
