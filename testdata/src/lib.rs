//! Locates the shared test data (`../shared/data` beside the repository) for tests and
//! benchmarks.
//!
//! The data sits beside the repository in development and CI but not on a user's machine. A test
//! that needs it calls [`data_dir`] and returns early when it gets `None` (the reason is printed);
//! with `VIDET_REQUIRE_DATA=1` a missing data set fails the test instead. `VIDET_DATA_DIR`
//! overrides the location.
#![forbid(unsafe_code)]

use std::path::{Path, PathBuf};

/// The workspace root (this crate lives one level below it).
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("testdata crate sits inside the workspace")
        .to_path_buf()
}

/// Where the data set is expected: `$VIDET_DATA_DIR`, else `<workspace>/../shared/data`.
pub fn expected_location() -> PathBuf {
    match std::env::var_os("VIDET_DATA_DIR") {
        Some(dir) => PathBuf::from(dir),
        None => workspace_root().join("..").join("shared").join("data"),
    }
}

/// Whether a missing data set must fail the test (`VIDET_REQUIRE_DATA=1`).
pub fn data_required() -> bool {
    std::env::var("VIDET_REQUIRE_DATA").is_ok_and(|v| v == "1")
}

/// The path of `relative` inside the shared data set, or `None` (with the reason printed) when
/// it is absent. Panics instead of skipping when `VIDET_REQUIRE_DATA=1`.
pub fn data_dir(relative: &str) -> Option<PathBuf> {
    let path = expected_location().join(relative);
    if path.exists() {
        return Some(path);
    }
    let reason = format!(
        "test data {} not found (set VIDET_DATA_DIR or place the shared data beside the repository)",
        path.display()
    );
    if data_required() {
        panic!("{reason}; VIDET_REQUIRE_DATA=1 makes this a failure");
    }
    eprintln!("skipping: {reason}");
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_data_is_skipped_unless_required() {
        if data_required() {
            let r = std::panic::catch_unwind(|| data_dir("no/such/set"));
            assert!(r.is_err(), "a missing set must fail when data is required");
        } else {
            assert!(data_dir("no/such/set").is_none());
        }
    }
}
