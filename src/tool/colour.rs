//! `videt colour`: the trainer's aid for colour-to-touch.
//!
//! - `videt colour --image IMG --at X,Y [--window N] [--json]`: the colour and the level triple
//!   the wearer feels at image pixel (X, Y);
//! - `videt colour --image IMG --out PNG`: the image rendered in the 27 level colours.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{ArgGroup, Args, ValueEnum};
use videt_colour::training::{
    load_rgb, quantize_image, reading_at, reading_json, reading_text, write_png,
};
use videt_colour::{QuantizerConfig, SamplerConfig, WindowStatistic};

use super::ToolResult;

/// Arguments of `videt colour`.
#[derive(Debug, Args)]
#[command(group(ArgGroup::new("what").required(true).multiple(true).args(["at", "out"])))]
pub struct ColourArgs {
    /// The image (PNG, JPEG or PPM).
    #[arg(long, value_name = "IMG")]
    pub image: PathBuf,
    /// Image pixel to read, as column,row (e.g. `140,175`).
    #[arg(long, value_name = "X,Y", value_parser = parse_point)]
    pub at: Option<(u32, u32)>,
    /// Side of the square sampling window in pixels (odd, 1..=31).
    #[arg(long, value_name = "N", default_value_t = 7)]
    pub window: u32,
    /// How the window is combined.
    #[arg(long, value_enum, default_value_t = Statistic::Median)]
    pub statistic: Statistic,
    /// The space the Low/Mid/High thresholds apply in.
    #[arg(long, value_enum, default_value_t = Space::Chromaticity)]
    pub space: Space,
    /// With --at: print `{"rgb": [r, g, b], "levels": [..]}` instead of text.
    #[arg(long, requires = "at")]
    pub json: bool,
    /// Write the image quantized to the 27 level colours to this PNG.
    #[arg(long, value_name = "PNG")]
    pub out: Option<PathBuf>,
}

/// Window statistic.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Statistic {
    /// Rounded mean.
    Mean,
    /// Median (ignores speckle, keeps the majority colour at an edge).
    Median,
}

/// Quantization space.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Space {
    /// Chromaticity scaled by stretched brightness (the device default).
    Chromaticity,
    /// Plain camera RGB.
    Rgb,
}

fn parse_point(text: &str) -> Result<(u32, u32), String> {
    let bad =
        || format!("--at must be X,Y in image pixels (two non-negative integers), got '{text}'");
    let (x, y) = text.split_once(',').ok_or_else(bad)?;
    let x = x.trim().parse().map_err(|_| bad())?;
    let y = y.trim().parse().map_err(|_| bad())?;
    Ok((x, y))
}

/// Run `videt colour`.
pub fn run(args: &ColourArgs) -> ToolResult {
    let frame = load_rgb(&args.image)?;
    let sampler = SamplerConfig {
        window_px: args.window,
        statistic: match args.statistic {
            Statistic::Mean => WindowStatistic::Mean,
            Statistic::Median => WindowStatistic::Median,
        },
    };
    let quantizer = match args.space {
        Space::Chromaticity => QuantizerConfig::default(),
        Space::Rgb => QuantizerConfig::plain_rgb(),
    };
    if let Some((x, y)) = args.at {
        if x >= frame.width || y >= frame.height {
            return Err(format!(
                "--at {x},{y} is outside {} ({}x{}); allowed: x 0..={}, y 0..={}",
                args.image.display(),
                frame.width,
                frame.height,
                frame.width - 1,
                frame.height - 1
            )
            .into());
        }
        let reading = reading_at(
            &frame,
            f64::from(x) + 0.5,
            f64::from(y) + 0.5,
            sampler,
            quantizer,
        )
        .map_err(|e| format!("{}: {e}", args.image.display()))?;
        if args.json {
            println!("{}", reading_json(&reading));
        } else {
            println!("{}", reading_text(&reading));
        }
    }
    if let Some(out) = &args.out {
        let levels = quantize_image(&frame, sampler, quantizer)?;
        write_png(&levels, out)?;
        if !args.json {
            println!(
                "wrote {} ({}x{}, 27 level colours)",
                out.display(),
                levels.width,
                levels.height
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
