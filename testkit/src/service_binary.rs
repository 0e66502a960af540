//! The service's binary for the whole-stack tests: `videtd` is a package of its own, so the
//! tests of another package get no `CARGO_BIN_EXE_videtd`. [`videtd_bin`] builds it (once per
//! test process, with the profile the tests were built with) into the tests' target directory
//! and gives its path.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The `videtd` binary, built fresh: `cargo build -p videtd` (release when the tests are
/// optimized), into the target directory the running test binary sits in. Panics with cargo's
/// message when the build fails.
pub fn videtd_bin() -> PathBuf {
    static BUILT: OnceLock<PathBuf> = OnceLock::new();
    BUILT
        .get_or_init(|| {
            let exe = std::env::current_exe().expect("the test binary's path");
            // target/<profile>/deps/<test> -> target/<profile>
            let profile_dir = exe
                .parent()
                .and_then(Path::parent)
                .expect("a test binary in target/<profile>/deps");
            let target_dir = profile_dir.parent().expect("target/<profile>");
            let mut build = Command::new(env!("CARGO"));
            build
                .args(["build", "--quiet", "-p", "videtd", "--bin", "videtd"])
                .arg("--target-dir")
                .arg(target_dir)
                .current_dir(env!("CARGO_MANIFEST_DIR"));
            if !cfg!(debug_assertions) {
                build.arg("--release");
            }
            let out = build.output().expect("cargo runs");
            assert!(
                out.status.success(),
                "cargo build -p videtd: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            profile_dir.join("videtd")
        })
        .clone()
}
