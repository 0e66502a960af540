//! `videt angle-sensors`: the one-wire device's two passive angle sensors (AS5048A absolute
//! encoders on SPI, `videt_drivers::angle`) read through the HAL's `AngleSensors`, for a
//! technician checking them: the magnetic field of each encoder, then raw counts, calibrated
//! angles and, given the wire length, the thimble position by eq. 7. The raw counts at the
//! reference pose (wire along +x, level) are the zeros to calibrate with. `--sim X,Y,Z` reads
//! simulated encoders (the twin's, at SPI level) with the thimble at that position instead.

use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

use clap::Args;
use embedded_hal::spi::SpiDevice;
use videt_control::polar::{polar_forward, PolarCoordinates};
use videt_drivers::angle::{AngleSensorPair, Calibration, Sense, RAD_PER_COUNT};
use videt_hal::{AngleAxis, AngleSensors};

use super::ToolResult;

/// Read the one-wire device's angle sensors.
#[derive(Debug, Args)]
pub struct AngleSensorsArgs {
    /// SPI device of the azimuth encoder (e.g. /dev/spidev1.0).
    #[arg(long, value_name = "DEV", required_unless_present = "sim")]
    pub azimuth: Option<String>,
    /// SPI device of the elevation encoder (e.g. /dev/spidev1.1).
    #[arg(long, value_name = "DEV", required_unless_present = "sim")]
    pub elevation: Option<String>,
    /// Raw counts of the azimuth and elevation encoders at angle zero (wire along +x, level).
    #[arg(long, value_name = "AZ,EL", default_value = "0,0", value_parser = parse_zero_counts)]
    pub zero_counts: [u16; 2],
    /// The azimuth encoder's counts run against the angle.
    #[arg(long)]
    pub reverse_azimuth: bool,
    /// The elevation encoder's counts run against the angle.
    #[arg(long)]
    pub reverse_elevation: bool,
    /// Wire length, metres: also print the thimble position by eq. 7.
    #[arg(long, value_name = "M", value_parser = parse_length)]
    pub length: Option<f64>,
    /// Readings to take (1..=100000).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub count: u32,
    /// Time between readings, milliseconds.
    #[arg(long, value_name = "MS", default_value_t = 100)]
    pub period_ms: u64,
    /// Read simulated encoders with the thimble at X,Y,Z metres (from the wire guide) instead
    /// of devices.
    #[arg(long, value_name = "X,Y,Z", conflicts_with_all = ["azimuth", "elevation"], value_parser = parse_position)]
    pub sim: Option<[f64; 3]>,
}

fn parse_zero_counts(text: &str) -> Result<[u16; 2], String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let count = |s: &str| -> Result<u16, String> {
        s.parse::<u16>()
            .ok()
            .filter(|c| *c < 16384)
            .ok_or_else(|| format!("{s:?} is not a count in 0..=16383"))
    };
    match parts.as_slice() {
        [az, el] => Ok([count(az)?, count(el)?]),
        _ => Err(format!(
            "{text:?}: expected AZ,EL (two counts in 0..=16383)"
        )),
    }
}

fn parse_length(text: &str) -> Result<f64, String> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|l| l.is_finite() && *l > 0.0 && *l <= 10.0)
        .ok_or_else(|| format!("{text:?} is not a wire length in (0, 10] m"))
}

fn parse_position(text: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{text:?}: {e} (expected X,Y,Z in metres)"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) && v.iter().any(|c| *c != 0.0) => {
            Ok([*x, *y, *z])
        }
        _ => Err(format!(
            "{text:?}: expected X,Y,Z in metres, finite and not all zero"
        )),
    }
}

impl AngleSensorsArgs {
    fn calibration(&self) -> [Calibration; 2] {
        let sense = |reversed: bool| {
            if reversed {
                Sense::Negative
            } else {
                Sense::Positive
            }
        };
        [
            Calibration {
                zero_counts: self.zero_counts[0],
                sense: sense(self.reverse_azimuth),
            },
            Calibration {
                zero_counts: self.zero_counts[1],
                sense: sense(self.reverse_elevation),
            },
        ]
    }
}

/// Run `videt angle-sensors`.
pub fn run(args: &AngleSensorsArgs) -> ToolResult {
    let calibration = args.calibration();
    if let Some([x, y, z]) = args.sim {
        use videt_sim::as5048a_encoder::{encoder_on_axis, Mounting};
        let position = Arc::new(videt_sim::SharedPosition::new(videt_sim::Vec3::new(
            x, y, z,
        )));
        let encoder = |axis| encoder_on_axis(Arc::clone(&position), axis, Mounting::ALIGNED);
        let pair = AngleSensorPair::new(
            encoder(AngleAxis::Azimuth),
            encoder(AngleAxis::Elevation),
            calibration,
        )?;
        println!("simulated encoders, thimble at ({x:+.4}, {y:+.4}, {z:+.4}) m");
        return report(pair, args);
    }
    #[cfg(target_os = "linux")]
    {
        let (Some(az), Some(el)) = (&args.azimuth, &args.elevation) else {
            return Err("--azimuth DEV and --elevation DEV are needed (or --sim X,Y,Z)".into());
        };
        let pair = videt_drivers::angle::linux::open_angle_pair(az, el, calibration)?;
        println!("azimuth encoder {az}, elevation encoder {el}");
        report(pair, args)
    }
    #[cfg(not(target_os = "linux"))]
    Err("reading SPI devices needs Linux (or --sim X,Y,Z)".into())
}

/// Print the encoders' field, then `args.count` readings: counts, angles, position.
fn report<S: SpiDevice>(mut pair: AngleSensorPair<S>, args: &AngleSensorsArgs) -> ToolResult
where
    S::Error: core::fmt::Debug + Send + Sync + 'static,
{
    let diagnostics = pair.check_diagnostics()?;
    for (axis, d) in AngleAxis::ALL.iter().zip(diagnostics) {
        println!(
            "{:>9}: magnetic field in range (automatic gain {} of 255)",
            axis.as_str(),
            d.agc()
        );
    }
    // The first read starts the encoders' pipeline (its answer is the previous command's).
    let calibration = pair.calibration();
    let mut angles = [0.0; 2];
    pair.read_angles(&mut angles)?;
    for k in 0..args.count {
        if k > 0 {
            std::thread::sleep(Duration::from_millis(args.period_ms));
        }
        pair.read_angles(&mut angles)?;
        let counts = [0, 1].map(|i| calibration[i].counts(angles[i]));
        let mut line = format!(
            "counts az {:5} el {:5}   alpha {:+9.3}°  beta {:+9.3}°",
            counts[0],
            counts[1],
            angles[0].to_degrees(),
            angles[1].to_degrees()
        );
        if let Some(length_m) = args.length {
            let p = polar_forward(&PolarCoordinates {
                length_m,
                azimuth_rad: angles[0],
                elevation_rad: angles[1],
            });
            line.push_str(&format!("   x ({:+.4}, {:+.4}, {:+.4}) m", p.x, p.y, p.z));
        }
        println!("{line}");
    }
    println!(
        "resolution {:.4}° per count; at the reference pose (wire along +x, level) the counts are the zeros (--zero-counts AZ,EL)",
        RAD_PER_COUNT.to_degrees()
    );
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arguments_are_checked_with_the_allowed_range() {
        assert_eq!(parse_zero_counts("5000, 12000").unwrap(), [5000, 12000]);
        assert!(parse_zero_counts("16384,0")
            .unwrap_err()
            .contains("0..=16383"));
        assert!(parse_zero_counts("1").unwrap_err().contains("AZ,EL"));
        assert!(parse_length("0").unwrap_err().contains("(0, 10]"));
        assert_eq!(parse_position("0.3,0.3,0.1").unwrap(), [0.3, 0.3, 0.1]);
        assert!(parse_position("0,0,0")
            .unwrap_err()
            .contains("not all zero"));
        assert!(parse_position("1,2").unwrap_err().contains("X,Y,Z"));
    }
}
