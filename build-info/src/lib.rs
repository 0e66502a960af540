//! What a build of VIDET's binaries was made from: its commit ([`COMMIT`], from `build.rs`),
//! and the `--version` text `videtd` and `videt` print.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

/// The commit the build was made from: `VIDET_BUILD_COMMIT` when set (a build from a source
/// tarball that knows its commit), else the checkout's (`git rev-parse --short=12 HEAD`), else
/// `unknown`.
pub const COMMIT: &str = env!("VIDET_COMMIT");

/// The text `--version` prints after the program's name: the version, the commit and
/// `features` (the optional capabilities the binary was built with, for a technician to tell
/// one build from another). Made once per process (a program's start), never on a real-time
/// path.
pub fn version(features: &str) -> &'static str {
    let text = format!(
        "{} (commit {COMMIT}, features: {features})",
        env!("CARGO_PKG_VERSION")
    );
    Box::leak(text.into_boxed_str())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_version_names_the_commit_and_the_features() {
        let v = version("v4l; with V4L2 capture");
        assert!(v.starts_with(env!("CARGO_PKG_VERSION")), "{v}");
        assert!(v.contains(&format!(
            "(commit {COMMIT}, features: v4l; with V4L2 capture)"
        )));
        assert!(!COMMIT.is_empty());
    }
}
