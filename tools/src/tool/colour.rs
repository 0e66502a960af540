//! `videt colour`: the trainer's aid for colour-to-touch.
//!
//! - `videt colour --image IMG --at X,Y [--window N] [--json]`: the colour and the level triple
//!   the wearer feels at image pixel (X, Y);
//! - `videt colour --image IMG --out PNG`: the image rendered in the 27 level colours.
//!
//! The window, statistic, space and thresholds are the `[colour]` section of the wearer's
//! configuration (`--config FILE`, else `/etc/videt/videt.toml` when it exists, else the
//! defaults), so the levels shown are the ones `videtd` renders; `--window`, `--statistic` and
//! `--space` override them.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{ArgGroup, Args, ValueEnum};
use videt_colour::training::{
    load_rgb, quantize_image, reading_at, reading_json, reading_text, write_png,
};
use videt_config::{ColourSpaceName, ColourStatistic, Config};

use super::device::DEFAULT_CONFIG;
use super::ToolResult;
use videt_service::colour_thread::colour_levels;

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
    /// The configuration whose `[colour]` section sets the window, space and thresholds
    /// (default: /etc/videt/videt.toml when it exists, else the built-in defaults).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Side of the square sampling window in pixels (odd, 1..=31), instead of `colour.window_px`.
    #[arg(long, value_name = "N")]
    pub window: Option<u32>,
    /// How the window is combined, instead of `colour.statistic`.
    #[arg(long, value_enum)]
    pub statistic: Option<Statistic>,
    /// The space the Low/Mid/High thresholds apply in, instead of `colour.space`.
    #[arg(long, value_enum)]
    pub space: Option<Space>,
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
    let mut colour = match &args.config {
        Some(path) => Config::load(path)?,
        None if std::path::Path::new(DEFAULT_CONFIG).exists() => {
            Config::load(std::path::Path::new(DEFAULT_CONFIG))?
        }
        None => Config::default(),
    }
    .colour;
    if let Some(window) = args.window {
        colour.window_px = window;
    }
    if let Some(statistic) = args.statistic {
        colour.statistic = match statistic {
            Statistic::Mean => ColourStatistic::Mean,
            Statistic::Median => ColourStatistic::Median,
        };
    }
    if let Some(space) = args.space {
        colour.space = match space {
            Space::Chromaticity => ColourSpaceName::Chromaticity,
            Space::Rgb => ColourSpaceName::Rgb,
        };
    }
    let (sampler, quantizer) = colour_levels(&colour);
    quantizer.validate()?;
    let frame = load_rgb(&args.image)?;
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
