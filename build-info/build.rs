//! Names the build in `videt --version` and `videtd --version`: the commit the binaries were
//! built from (`VIDET_COMMIT`). From `VIDET_BUILD_COMMIT` when set (a build from a source tarball
//! that knows its commit), else from `git rev-parse`, else `unknown` (no git, or not a checkout).

use std::path::PathBuf;
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    if !out.status.success() {
        return None;
    }
    let text = String::from_utf8(out.stdout).ok()?.trim().to_owned();
    (!text.is_empty()).then_some(text)
}

fn main() {
    println!("cargo:rerun-if-env-changed=VIDET_BUILD_COMMIT");
    let commit = match std::env::var("VIDET_BUILD_COMMIT") {
        Ok(c) if !c.trim().is_empty() => c.trim().to_owned(),
        _ => from_git().unwrap_or_else(|| "unknown".to_owned()),
    };
    println!("cargo:rustc-env=VIDET_COMMIT={commit}");
}

/// The commit of the checkout, and a rebuild whenever HEAD moves (a commit, a checkout).
fn from_git() -> Option<String> {
    let commit = git(&["rev-parse", "--short=12", "HEAD"])?;
    // HEAD and the branch it names live in the git directory (a worktree's own, and the
    // common one for the refs): rebuild when either changes.
    for dir in ["--git-dir", "--git-common-dir"] {
        if let Some(d) = git(&["rev-parse", dir]) {
            let d = PathBuf::from(d);
            watch(&d.join("HEAD"));
            watch(&d.join("packed-refs"));
        }
    }
    if let Some(r) = git(&["rev-parse", "--symbolic-full-name", "HEAD"]) {
        if let Some(common) = git(&["rev-parse", "--git-common-dir"]) {
            watch(&PathBuf::from(common).join(r));
        }
    }
    Some(commit)
}

/// Rerun when `path` changes; only for a file that exists (cargo reruns a build script that
/// watches a missing file at every build, which would relink the binaries every time).
fn watch(path: &std::path::Path) {
    if path.is_file() {
        println!("cargo:rerun-if-changed={}", path.display());
    }
}
