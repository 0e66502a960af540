//! Live surface updates without force jumps.
//!
//! When the vision thread publishes a new surface, the rendered force goes over from the old
//! surface's force to the new one's over a configurable time ([`ForceBlender`]); the blend slows
//! down where needed so that a swap never changes the force by more than a configured step per
//! period. A surface that is not refreshed for longer than a configured age is stale: its force
//! fades out, with the same step bound, to free space (the control step's free-space field).
//!
//! [`SwapRenderer`] puts the pieces together for a relief: one god-object per surface (the
//! outgoing one keeps rendering the old surface during the blend) and the blender.

use crate::proxy::{GodObject, ProxyContact, ProxyParams, ProxyParamsError};
use crate::relief::ReliefSurface;
use crate::surface::Contact;
use crate::Vec3;

/// Settings of the blending.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlendParams {
    /// Shortest time over which a swap blends the old force into the new, seconds (> 0).
    pub blend_time_s: f64,
    /// Largest force change per period that a swap or a fade may cause, newtons (> 0).
    pub max_step_n: f64,
    /// A surface older than this is stale and fades out, seconds (> 0).
    pub stale_after_s: f64,
    /// Shortest time of the fade out (and back in), seconds (> 0).
    pub fade_time_s: f64,
}

impl Default for BlendParams {
    fn default() -> Self {
        BlendParams {
            blend_time_s: 0.1,
            max_step_n: 0.05,
            stale_after_s: 5.0,
            fade_time_s: 0.5,
        }
    }
}

/// A rejected blending setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlendParamsError {
    /// The offending field.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
}

impl core::fmt::Display for BlendParamsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "blend: {} = {} must be finite and > 0",
            self.field, self.value
        )
    }
}

impl BlendParams {
    /// Check every field (all must be finite and > 0).
    pub fn validate(&self) -> Result<(), BlendParamsError> {
        for (field, value) in [
            ("blend_time_s", self.blend_time_s),
            ("max_step_n", self.max_step_n),
            ("stale_after_s", self.stale_after_s),
            ("fade_time_s", self.fade_time_s),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(BlendParamsError { field, value });
            }
        }
        Ok(())
    }
}

/// Blends the force of an outgoing surface into the incoming one, and fades a stale surface
/// out. Pure; time comes in as the period.
///
/// Two ways to blend: *live*, from the outgoing surface's force (still evaluated every period)
/// to the incoming one's; or *frozen*, when the outgoing surface is no longer available (or a
/// second swap arrives during a blend): the gap between the last rendered force and the
/// incoming surface's force at the swap is carried and shrunk to zero. Either way the output
/// starts where it was, so a swap causes no step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceBlender {
    params: BlendParams,
    /// Weight of the incoming surface, `[0, 1]`.
    weight: f64,
    blending: bool,
    /// Gap `last output - incoming force` at the swap, newtons (frozen blending).
    frozen_gap_n: Vec3,
    /// Blend from `frozen_gap_n` rather than from a live outgoing force.
    frozen: bool,
    /// Overall scale, `[0, 1]` (0 = faded out to free space).
    fade: f64,
    /// The last output, newtons.
    last_n: Vec3,
}

impl ForceBlender {
    /// A blender with the given settings, fully on the current surface.
    pub fn new(params: BlendParams) -> Result<ForceBlender, BlendParamsError> {
        params.validate()?;
        Ok(ForceBlender {
            params,
            weight: 1.0,
            blending: false,
            frozen_gap_n: Vec3::zeros(),
            frozen: false,
            fade: 1.0,
            last_n: Vec3::zeros(),
        })
    }

    /// The settings.
    pub fn params(&self) -> &BlendParams {
        &self.params
    }

    /// A swap is being blended.
    pub fn is_blending(&self) -> bool {
        self.blending
    }

    /// The current blend carries a frozen gap (no live outgoing force is needed).
    pub fn is_frozen(&self) -> bool {
        self.frozen
    }

    /// Weight of the incoming surface, `[0, 1]`.
    pub fn weight(&self) -> f64 {
        self.weight
    }

    /// Overall fade, `[0, 1]` (0 = free space).
    pub fn fade(&self) -> f64 {
        self.fade
    }

    /// The last output force, newtons.
    pub fn last_force_n(&self) -> Vec3 {
        self.last_n
    }

    /// A new surface came in and its force is known only from now on: blend live from the
    /// outgoing surface's force (pass it to [`ForceBlender::update`] as `old_force_n`). During a
    /// blend this falls back to [`ForceBlender::start_swap_frozen`] semantics at the next
    /// update (the gap is taken from the last output).
    pub fn start_swap(&mut self) {
        if self.blending {
            self.frozen = true;
            self.frozen_gap_n = Vec3::from_element(f64::NAN); // taken at the next update
        } else {
            self.frozen = false;
        }
        self.weight = 0.0;
        self.blending = true;
    }

    /// A new surface came in and the outgoing one is gone: carry the gap between the last
    /// output and the incoming force (taken at the next update) and shrink it.
    pub fn start_swap_frozen(&mut self) {
        self.frozen = true;
        self.frozen_gap_n = Vec3::from_element(f64::NAN);
        self.weight = 0.0;
        self.blending = true;
    }

    /// One period of `dt_s` seconds: the force to render from the outgoing surface's force
    /// `old_force_n` (used while blending live; `None` otherwise) and the current one's
    /// `new_force_n`, for a current surface `surface_age_s` seconds old. Coefficient changes
    /// never move the output by more than `max_step_n` in one period.
    pub fn update(
        &mut self,
        dt_s: f64,
        surface_age_s: f64,
        old_force_n: Option<&Vec3>,
        new_force_n: &Vec3,
    ) -> Vec3 {
        let dt = if dt_s.is_finite() && dt_s > 0.0 {
            dt_s
        } else {
            0.0
        };
        let half_step = 0.5 * self.params.max_step_n;
        let new = finite_or_zero(new_force_n);
        if self.blending && !self.frozen && old_force_n.is_none() {
            // The outgoing force is gone mid-blend: freeze the current gap.
            self.frozen = true;
            self.frozen_gap_n = Vec3::from_element(f64::NAN);
        }
        let blended = if self.blending {
            // Gap between where the output starts and the incoming force.
            let gap = if self.frozen {
                if self.frozen_gap_n.iter().any(|c| c.is_nan()) {
                    let unfaded = if self.fade > 0.0 {
                        self.last_n / self.fade
                    } else {
                        new
                    };
                    // The output so far, expressed as `new + gap (1 - w)` with w = 0.
                    self.frozen_gap_n = finite_or_zero(&(unfaded - new));
                }
                self.frozen_gap_n
            } else {
                finite_or_zero(old_force_n.unwrap_or(&new)) - new
            };
            let size = gap.norm() * self.fade;
            let mut dw = dt / self.params.blend_time_s;
            if size > 0.0 {
                dw = dw.min(half_step / size);
            }
            self.weight = (self.weight + dw).min(1.0);
            if self.weight >= 1.0 {
                self.blending = false;
                self.frozen = false;
            }
            new + gap * (1.0 - self.weight)
        } else {
            new
        };
        // Fade towards free space when stale, back in when fresh.
        let stale = surface_age_s.is_nan() || surface_age_s > self.params.stale_after_s;
        let target = if stale { 0.0 } else { 1.0 };
        let size = blended.norm();
        let mut dg = dt / self.params.fade_time_s;
        if size > 0.0 {
            dg = dg.min(half_step / size);
        }
        self.fade = if self.fade < target {
            (self.fade + dg).min(target)
        } else {
            (self.fade - dg).max(target)
        };
        self.last_n = blended * self.fade;
        self.last_n
    }
}

fn finite_or_zero(v: &Vec3) -> Vec3 {
    if v.iter().all(|c| c.is_finite()) {
        *v
    } else {
        Vec3::zeros()
    }
}

/// Proxy rendering of a relief that is replaced now and then: a god-object on the current
/// surface, one on the outgoing surface while a swap is blended, and the blender. Forces are
/// the springs `K (proxy - finger)` of the two proxies; the result is a [`Contact`] for the
/// control step (`K depth n` equals the blended spring force).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwapRenderer {
    current: GodObject,
    outgoing: GodObject,
    blender: ForceBlender,
    stiffness_n_per_m: f64,
    last: Option<ProxyContact>,
}

/// A rejected renderer setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SwapRendererError {
    /// A proxy setting.
    Proxy(ProxyParamsError),
    /// A blend setting.
    Blend(BlendParamsError),
    /// The stiffness (N/m) is not finite and > 0.
    Stiffness(f64),
}

impl core::fmt::Display for SwapRendererError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SwapRendererError::Proxy(e) => e.fmt(f),
            SwapRendererError::Blend(e) => e.fmt(f),
            SwapRendererError::Stiffness(k) => {
                write!(
                    f,
                    "renderer: stiffness_n_per_m = {k} must be finite and > 0"
                )
            }
        }
    }
}

impl SwapRenderer {
    /// A renderer with the given settings; `stiffness_n_per_m` is the control step's `K` (it
    /// turns the blender's newton bound into displacements).
    pub fn new(
        proxy: ProxyParams,
        blend: BlendParams,
        stiffness_n_per_m: f64,
    ) -> Result<SwapRenderer, SwapRendererError> {
        if !(stiffness_n_per_m.is_finite() && stiffness_n_per_m > 0.0) {
            return Err(SwapRendererError::Stiffness(stiffness_n_per_m));
        }
        let current = GodObject::new(proxy).map_err(SwapRendererError::Proxy)?;
        Ok(SwapRenderer {
            current,
            outgoing: current,
            blender: ForceBlender::new(blend).map_err(SwapRendererError::Blend)?,
            stiffness_n_per_m,
            last: None,
        })
    }

    /// The blender (weights, fade).
    pub fn blender(&self) -> &ForceBlender {
        &self.blender
    }

    /// The last proxy update on the current surface.
    pub fn last(&self) -> Option<ProxyContact> {
        self.last
    }

    /// The current surface became the outgoing one and a new surface is current. The current
    /// proxy carries over (lifted out of the new solid at the next update); a copy keeps
    /// rendering the outgoing surface while the caller still passes it to
    /// [`SwapRenderer::render`]. Without it (or on a swap during a blend) the blend carries the
    /// gap from the last rendered force instead. Any number of swaps is fine.
    pub fn swap(&mut self) {
        self.blender.start_swap();
        self.outgoing = self.current;
    }

    /// One period: update the proxies against `current` (and `outgoing` while blending) for the
    /// finger at `finger_m`, blend, and return the contact for the control step.
    pub fn render<S: ReliefSurface + ?Sized>(
        &mut self,
        current: &S,
        outgoing: Option<&S>,
        finger_m: &Vec3,
        dt_s: f64,
        surface_age_s: f64,
    ) -> Option<Contact> {
        let k = self.stiffness_n_per_m;
        let now = self.current.update(current, finger_m);
        self.last = Some(now);
        let new_force = now.offset_m * k;
        let old_force = match (
            self.blender.is_blending() && !self.blender.is_frozen(),
            outgoing,
        ) {
            (true, Some(old)) => Some(self.outgoing.update(old, finger_m).offset_m * k),
            _ => None,
        };
        let force = self
            .blender
            .update(dt_s, surface_age_s, old_force.as_ref(), &new_force);
        let depth_m = force.norm() / k;
        (depth_m > 0.0 && depth_m.is_finite()).then(|| Contact {
            depth_m,
            normal: force / (depth_m * k),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::Plane;

    /// A proxy whose spring may change by any amount per period (isolates the blender).
    fn unlimited_proxy() -> ProxyParams {
        ProxyParams {
            max_offset_step_m: 1.0,
            ..ProxyParams::default()
        }
    }

    fn wall(z: f64) -> Plane {
        Plane::new(Vec3::new(0.0, 0.0, z), -Vec3::z()).unwrap()
    }

    #[test]
    fn swap_blends_with_a_bounded_step() {
        let blend = BlendParams {
            blend_time_s: 0.05,
            max_step_n: 0.02,
            ..BlendParams::default()
        };
        let k = 800.0;
        let mut r = SwapRenderer::new(unlimited_proxy(), blend, k).unwrap();
        let (old, new) = (wall(0.30), wall(0.29));
        let finger = Vec3::new(0.1, 0.1, 0.305);
        let dt = 1e-3;
        let mut prev = Vec3::zeros();
        for _ in 0..10 {
            let c = r.render(&old, None, &finger, dt, 0.0).unwrap();
            prev = c.normal * c.depth_m * k;
        }
        assert!((prev.norm() - 4.0).abs() < 1e-2);
        r.swap();
        let mut max_step: f64 = 0.0;
        let mut periods = 0;
        while r.blender().is_blending() {
            let c = r.render(&new, Some(&old), &finger, dt, 0.0).unwrap();
            let f = c.normal * c.depth_m * k;
            max_step = max_step.max((f - prev).norm());
            prev = f;
            periods += 1;
            assert!(periods < 10_000);
        }
        // 4 N -> 12 N with half the 0.02 N bound for the blend (the other half is the fade's)
        // takes 800 periods, more than the 50 of blend_time.
        std::eprintln!("4 N -> 12 N swap: {periods} periods, max step {max_step:.4} N");
        assert!(max_step <= 0.02 + 1e-9, "max step {max_step}");
        assert!((prev.norm() - 12.0).abs() < 1e-2);
        assert!((800..=802).contains(&periods), "{periods}");
    }

    #[test]
    fn swaps_without_the_old_surface_and_during_a_blend_stay_bounded() {
        let blend = BlendParams {
            blend_time_s: 0.02,
            max_step_n: 0.05,
            ..BlendParams::default()
        };
        let k = 800.0;
        let mut r = SwapRenderer::new(unlimited_proxy(), blend, k).unwrap();
        let walls = [wall(0.30), wall(0.29), wall(0.305), wall(0.28)];
        let finger = Vec3::new(0.1, 0.1, 0.307);
        let force = |c: Option<Contact>| c.map_or(Vec3::zeros(), |c| c.normal * c.depth_m * k);
        let mut prev = force(r.render(&walls[0], None, &finger, 1e-3, 0.0));
        let mut max_step: f64 = 0.0;
        for period in 1..3000 {
            // A new surface every 150 periods, never waiting for the blend to end.
            let w = (period / 150) % walls.len();
            if period % 150 == 0 {
                r.swap();
            }
            let f = force(r.render(&walls[w], None, &finger, 1e-3, 0.0));
            max_step = max_step.max((f - prev).norm());
            prev = f;
        }
        std::eprintln!("a swap every 150 periods: max step {max_step:.4} N");
        assert!(max_step <= 0.05 + 1e-9, "max step {max_step}");
    }

    #[test]
    fn stale_surface_fades_to_free_space_and_back() {
        let blend = BlendParams {
            max_step_n: 0.1,
            stale_after_s: 1.0,
            fade_time_s: 0.2,
            ..BlendParams::default()
        };
        let mut b = ForceBlender::new(blend).unwrap();
        let f = Vec3::new(0.0, 0.0, -5.0);
        let mut prev = b.update(1e-3, 0.0, None, &f);
        assert_eq!(prev, f);
        let mut max_step: f64 = 0.0;
        for i in 0..400 {
            let out = b.update(1e-3, 1.0 + i as f64 * 1e-3, None, &f);
            max_step = max_step.max((out - prev).norm());
            prev = out;
        }
        assert!(max_step <= 0.1 + 1e-12);
        assert_eq!(b.fade(), 0.0);
        assert_eq!(prev, Vec3::zeros());
        for _ in 0..400 {
            prev = b.update(1e-3, 0.0, None, &f);
        }
        assert_eq!(prev, f);
        assert!(ForceBlender::new(BlendParams {
            blend_time_s: f64::NAN,
            ..BlendParams::default()
        })
        .is_err());
    }
}
