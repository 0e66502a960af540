//! Passive angle sensors of the one-wire device (paper section 4.4, eq. 7, Fig. 11).
//!
//! The one-wire device has a single actuated wire leaving a guide at the origin; where it points
//! is measured by two passive angle sensors on the guide, moved by the operator's hand through
//! the wire:
//!
//! - azimuth `alpha`: in the x-y plane, from +x towards +y;
//! - elevation `beta`: from the x-y plane towards +z.
//!
//! With the wire length `l` from the drive's encoder, eq. 7 gives the thimble position
//! `x = l cos(beta) cos(alpha)`, `y = l cos(beta) sin(alpha)`, `z = l sin(beta)`; inversely
//! `alpha = atan2(y, x)` and `beta = atan2(z, sqrt(x² + y²))`, the convention of
//! `videt_control::polar`.

use crate::ErrorType;

/// Which of the two angle sensors: the index into [`AngleSensors::read_angles`]'s output, and
/// the name an error uses for the sensor that failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AngleAxis {
    /// Azimuth `alpha`, in the x-y plane from +x towards +y (index 0).
    Azimuth = 0,
    /// Elevation `beta`, from the x-y plane towards +z (index 1).
    Elevation = 1,
}

impl AngleAxis {
    /// Both axes, in output order.
    pub const ALL: [AngleAxis; 2] = [AngleAxis::Azimuth, AngleAxis::Elevation];

    /// Position of this axis in the `[f64; 2]` of [`AngleSensors::read_angles`].
    pub const fn index(self) -> usize {
        self as usize
    }

    /// A short, stable, lower-case name for logs and the control socket.
    pub const fn as_str(self) -> &'static str {
        match self {
            AngleAxis::Azimuth => "azimuth",
            AngleAxis::Elevation => "elevation",
        }
    }
}

impl core::fmt::Display for AngleAxis {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The two passive angle sensors of the one-wire device's wire guide.
pub trait AngleSensors: ErrorType {
    /// The latest calibrated angles, radians: `out_rad[0]` the azimuth `alpha`, `out_rad[1]`
    /// the elevation `beta` (see [`AngleAxis`]). Calibrated means the zero offset and the sense
    /// of rotation are applied, so the angles follow eq. 7's convention; each lies in
    /// `(-pi, pi]`. **RT**: never waits for a measurement and never allocates (bus I/O
    /// excepted). On an error `out_rad` may be partly written and means nothing: the thimble
    /// position is unknown for this period.
    fn read_angles(&mut self, out_rad: &mut [f64; 2]) -> Result<(), Self::Error>;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_index_the_output_in_order_and_have_stable_names() {
        assert_eq!(AngleAxis::ALL.map(AngleAxis::index), [0, 1]);
        assert_eq!(
            AngleAxis::ALL.map(AngleAxis::as_str),
            ["azimuth", "elevation"]
        );
    }
}
