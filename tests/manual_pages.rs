//! The manual pages and shell completions the Debian package installs, as `videt-assets` writes
//! them: every page renders without a warning (groff, through `man -l` where man-db is
//! installed), and every completion script parses in its shell (bash always; zsh and fish where
//! installed).

use std::path::{Path, PathBuf};
use std::process::Command;

fn generate() -> (tempfile::TempDir, Vec<PathBuf>) {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_videt-assets"))
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let files = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(PathBuf::from)
        .collect();
    (dir, files)
}

fn have(tool: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {tool}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Renders a page with groff's man macros, warnings on; returns the text and the warnings.
fn render(page: &Path) -> (String, String) {
    let out = Command::new("groff")
        .args(["-man", "-Tutf8", "-P-bcou", "-ww", "-rLL=80n"])
        .arg(page)
        .output()
        .unwrap();
    assert!(out.status.success(), "groff {}", page.display());
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn pages_render_without_warnings() {
    if !have("groff") {
        eprintln!("skipped: no groff (apt-get install groff-base)");
        return;
    }
    let (_dir, files) = generate();
    let pages: Vec<_> = files
        .iter()
        .filter(|f| f.to_string_lossy().contains("/man/man"))
        .collect();
    assert!(pages.len() >= 20, "{pages:?}");
    for page in &pages {
        let (text, warnings) = render(page);
        assert!(warnings.trim().is_empty(), "{}: {warnings}", page.display());
        assert!(text.contains("NAME"), "{}", page.display());
    }
    let dir = files[0].ancestors().nth(2).unwrap().to_owned();
    let (videtd, _) = render(&dir.join("man8/videtd.8"));
    for heading in [
        "SYNOPSIS",
        "OPTIONS",
        "EXIT STATUS",
        "FILES",
        "SIGNALS",
        "SEE ALSO",
    ] {
        assert!(
            videtd.contains(heading),
            "videtd(8) lacks {heading}:\n{videtd}"
        );
    }
    let (init, _) = render(&dir.join("man1/videt-init.1"));
    assert!(init.contains("videt init"), "{init}");
    assert!(init.contains("/var/lib/videt/calibration.toml"), "{init}");
    let (config, _) = render(&dir.join("man5/videt.toml.5"));
    assert!(
        config.contains("[control]") && config.contains("t_max_n"),
        "{config}"
    );
    // man-db reads them as the package installs them.
    if have("man") {
        let out = Command::new("man")
            .env("MANWIDTH", "80")
            .args(["--warnings", "-l"])
            .arg(dir.join("man8/videtd.8"))
            .output()
            .unwrap();
        assert!(out.status.success());
        assert!(String::from_utf8_lossy(&out.stdout).contains("SIGNALS"));
        assert!(
            out.stderr.is_empty(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

#[test]
fn completions_parse_in_their_shells() {
    let (_dir, files) = generate();
    let of = |shell: &str| -> Vec<&PathBuf> {
        files
            .iter()
            .filter(|f| {
                f.to_string_lossy()
                    .contains(&format!("/completions/{shell}/"))
            })
            .collect()
    };
    for (shell, check) in [("bash", "-n"), ("zsh", "-n"), ("fish", "--no-execute")] {
        let scripts = of(shell);
        assert_eq!(scripts.len(), 2, "{shell}: {scripts:?}");
        if !have(shell) {
            eprintln!("{shell} not installed: its completions are not parsed");
            continue;
        }
        for script in scripts {
            let out = Command::new(shell).arg(check).arg(script).output().unwrap();
            assert!(
                out.status.success(),
                "{shell} {}: {}",
                script.display(),
                String::from_utf8_lossy(&out.stderr)
            );
        }
    }
    // Bash completes a subcommand from its prefix.
    let bash = of("bash")
        .into_iter()
        .find(|f| f.ends_with("videt"))
        .unwrap();
    let script = format!(
        ". '{}'; COMP_WORDS=(videt tension-c); COMP_CWORD=1; COMP_LINE='videt tension-c'; \
         COMP_POINT=15; _videt videt tension-c videt; printf '%s\\n' \"${{COMPREPLY[@]}}\"",
        bash.display()
    );
    let out = Command::new("bash").args(["-c", &script]).output().unwrap();
    let replies = String::from_utf8_lossy(&out.stdout);
    assert!(
        replies.lines().any(|l| l == "tension-calibrate"),
        "{replies}"
    );
}
