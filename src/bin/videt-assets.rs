//! `videt-assets DIR` — writes the manual pages (`DIR/man/manN/`) and the shell completions
//! (`DIR/completions/SHELL/`) of `videtd` and `videt`, generated from their command-line
//! definitions (`videt_tools::manual`). Not installed: `scripts/build-deb.sh` runs it to put
//! them in the Debian package.

use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let mut args = std::env::args_os().skip(1);
    let (Some(dir), None) = (args.next(), args.next()) else {
        eprintln!("usage: videt-assets DIR");
        return ExitCode::from(2);
    };
    match videt_tools::manual::write_all(&PathBuf::from(dir)) {
        Ok(files) => {
            for f in files {
                println!("{}", f.display());
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("videt-assets: {e}");
            ExitCode::FAILURE
        }
    }
}
