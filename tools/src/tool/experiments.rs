//! `videt experiments`: the paper's experiments (section 6, Figs. 18, 22 and 23) on the digital
//! twin, drawn as the paper draws them, with a summary of what each shows.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use super::ToolResult;

/// Arguments of `videt experiments`.
#[derive(Debug, Args)]
pub struct ExperimentsArgs {
    /// Directory the figures and `summary.txt` are written to (created if missing).
    #[arg(long, value_name = "DIR", default_value = "videt-experiments")]
    pub out: PathBuf,
}

/// Run the three experiments, write their figures and summary, print the summary.
pub fn run(args: &ExperimentsArgs) -> ToolResult {
    let f18 = videt_experiments::fig18()?;
    let f22 = videt_experiments::fig22()?;
    let f23 = videt_experiments::fig23()?;
    let written = videt_experiments::write_figures_of(&args.out, &f18, &f22, &f23)?;
    print!(
        "{}",
        videt_experiments::figures::summary_text(&f18.summary, &f22.summary, &f23.summary)
    );
    for path in written {
        println!("wrote {}", path.display());
    }
    Ok(ExitCode::SUCCESS)
}
