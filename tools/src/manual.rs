//! The manual pages and shell completions of `videtd` and `videt`, generated from their clap
//! definitions ([`videt_service::cli::Args`], [`crate::cli::Cli`]) so that they cannot drift from
//! `--help`: `videtd(8)`, `videt(1)` and a page per subcommand (`videt-init(1)`,
//! `videt-config-check(1)`, ...), each with its exit status, files and signals; `videt.toml(5)`
//! from the example configuration's comments; the completions for bash, zsh and fish. The
//! `videt-assets` binary writes them for the Debian package (`scripts/build-deb.sh`).

use std::io;
use std::path::{Path, PathBuf};

use clap::{Command, CommandFactory};
use clap_complete::Shell;
use clap_mangen::roff::{bold, italic, roman, Inline, Roff};
use clap_mangen::Man;

use crate::cli::Cli;
use crate::tool::device::{EXIT_CALIBRATION_WRITE, EXIT_MOTORS_BUSY, EXIT_NO_BACKEND, EXIT_USAGE};
use crate::tool::replay::EXIT_DIVERGED;
use crate::tool::through_service::EXIT_SERVICE_LOST;

/// The example configuration, the source of `videt.toml(5)`.
pub const EXAMPLE_CONFIG: &str = include_str!("../../config/videt.example.toml");

/// The name of the manual the pages belong to (the centre of their header line).
const MANUAL: &str = "VIDET";

/// One manual page: `name(section)` and its roff text.
#[derive(Debug, Clone)]
pub struct Page {
    /// The page's name, e.g. `videt-init`.
    pub name: String,
    /// Its section: "1", "5" or "8".
    pub section: &'static str,
    /// The page in roff (man macros).
    pub text: String,
}

impl Page {
    /// Its file name, e.g. `videt-init.1`.
    pub fn file_name(&self) -> String {
        format!("{}.{}", self.name, self.section)
    }
}

/// A section of our own: a heading and its paragraphs (each a list of inline runs).
struct Section {
    heading: &'static str,
    /// Tagged paragraphs: a tag (bold) and its text; an empty tag is a plain paragraph.
    items: Vec<(String, String)>,
}

impl Section {
    fn new(heading: &'static str) -> Section {
        Section {
            heading,
            items: Vec::new(),
        }
    }
    fn item(mut self, tag: impl Into<String>, text: impl Into<String>) -> Section {
        self.items.push((tag.into(), text.into()));
        self
    }
    fn para(self, text: impl Into<String>) -> Section {
        self.item("", text)
    }
    fn render(&self, roff: &mut Roff) {
        roff.control("SH", [self.heading]);
        for (tag, text) in &self.items {
            if tag.is_empty() {
                roff.control("PP", []);
            } else {
                roff.control("TP", []);
                roff.text([bold(tag.as_str())]);
            }
            roff.text([roman(text.as_str())]);
        }
    }
}

/// The package's version, in every page's header.
fn source() -> String {
    format!("videt {}", env!("CARGO_PKG_VERSION"))
}

/// Renders `cmd` as a page: clap_mangen's sections (name, synopsis, description, options,
/// subcommands, the text after `--help`), then `extra`.
fn page(cmd: Command, name: &str, section: &'static str, extra: &[Section]) -> io::Result<Page> {
    let has_options = cmd.get_arguments().any(|a| !a.is_hide_set());
    let has_subcommands = cmd.get_subcommands().any(|s| !s.is_hide_set());
    let has_after_help = cmd.get_after_long_help().or(cmd.get_after_help()).is_some();
    let has_version = cmd.get_version().or(cmd.get_long_version()).is_some();
    let exit_codes = lists_exit_codes(&cmd).then(|| {
        let help = cmd.get_after_long_help().or(cmd.get_after_help());
        help.map(|h| h.to_string()).unwrap_or_default()
    });
    let man = Man::new(cmd)
        .title(name.to_uppercase())
        .section(section)
        .source(source())
        .manual(MANUAL);
    let mut out = Vec::new();
    man.render_title(&mut out)?;
    man.render_name_section(&mut out)?;
    man.render_synopsis_section(&mut out)?;
    man.render_description_section(&mut out)?;
    if has_options {
        man.render_options_section(&mut out)?;
    }
    if has_subcommands {
        man.render_subcommands_section(&mut out)?;
    }
    let mut roff = Roff::new();
    match exit_codes {
        // A list of exit codes after `--help` is the page's exit status.
        Some(text) => Section::new("EXIT STATUS").para(text).render(&mut roff),
        None if has_after_help => man.render_extra_section(&mut out)?,
        None => {}
    }
    for s in extra {
        s.render(&mut roff);
    }
    out.extend_from_slice(roff.to_roff().as_bytes());
    if has_version {
        man.render_version_section(&mut out)?;
    }
    let text = String::from_utf8(out).map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e))?;
    Ok(Page {
        name: name.to_owned(),
        section,
        text,
    })
}

/// The files both programs use (the defaults of the example configuration).
fn files() -> Section {
    Section::new("FILES")
        .item(
            "/etc/videt/videt.toml",
            "The configuration (a conffile of the package); see videt.toml(5). Check it with \
             `videt config check /etc/videt/videt.toml`.",
        )
        .item(
            "/var/lib/videt/calibration.toml",
            "The rig's calibration (files.calibration): written by `videt init` and \
             `videt wire replace`, read by videtd. Without a valid one no force is rendered.",
        )
        .item(
            "/etc/videt/stereo.json",
            "The stereo calibration of the cameras (vision.stereo_calibration), written by \
             `videt calibrate-stereo`.",
        )
        .item(
            "/run/videt/videtd.sock",
            "videtd's control socket (socket.path), mode 0660, group videt: `videt service`, \
             `videt status` and the procedures talk to the running service through it.",
        )
        .item(
            "/run/videt/motors.lock",
            "Held by the one process that drives the motors (files.motors_lock).",
        )
        .item(
            "/var/log/videt/",
            "One session log per run of videtd (telemetry.directory), read by `videt log` and \
             `videt replay`. The service's own messages go to the journal: \
             `journalctl -u videtd`.",
        )
}

/// See also: the other pages of the package.
fn see_also(pages: &[&str]) -> Section {
    Section::new("SEE ALSO").para(pages.join(", "))
}

/// The service's page.
fn videtd_page() -> io::Result<Page> {
    let mut cmd = videt_service::cli::Args::command();
    cmd.build();
    let exit = Section::new("EXIT STATUS")
        .item(
            "0",
            "Stopped cleanly (SIGTERM, SIGINT or --duration): forces ramped out, drives off.",
        )
        .item(
            "1",
            "Stopped by a failure while running (the journal says which).",
        )
        .item(
            EXIT_USAGE.to_string(),
            "The command line or the configuration was refused; nothing was started.",
        )
        .item(
            videt_service::run::EXIT_PANIC.to_string(),
            "A thread panicked: the control loop stopped in the safe state (every wire at \
             minimum tension, drives off). systemd restarts the service (Restart=on-failure).",
        );
    let signals = Section::new("SIGNALS")
        .item(
            "SIGTERM, SIGINT",
            "Ramp the tensions to minimum over control.ramp_down_s, power the drives off, close \
             the session log and exit 0 (`systemctl stop videtd`, Ctrl-C).",
        )
        .item(
            "SIGHUP",
            "Ignored, with a warning: the configuration is read at start; restart videtd to \
             apply a new one.",
        );
    let systemd = Section::new("SYSTEMD").para(
        "As the unit videtd.service (Type=notify) videtd reports READY=1 once the drives are \
         enabled and pets the watchdog while the control loop runs, in its safe states too. \
         The package installs the unit disabled: edit and check /etc/videt/videt.toml, then \
         `systemctl enable --now videtd`.",
    );
    page(
        cmd,
        "videtd",
        "8",
        &[
            exit,
            files(),
            signals,
            systemd,
            see_also(&["videt(1)", "videt.toml(5)", "systemctl(1)", "journalctl(1)"]),
        ],
    )
}

/// The exit status of a `videt` subcommand whose `--help` has no list of its own.
fn tool_exit_status(name: &str) -> Section {
    let mut s = Section::new("EXIT STATUS")
        .item("0", "Done.")
        .item(
            "1",
            "Failed; the reason is printed as `videt: MESSAGE` on standard error.",
        )
        .item(
            EXIT_USAGE.to_string(),
            "Bad arguments (the usage is printed) or a refused configuration.",
        );
    match name {
        "videt-replay" => {
            s = s.item(
                EXIT_DIVERGED.to_string(),
                "The replay diverged: an output differs from the recorded one.",
            )
        }
        "videt-status" => s = s.item("4", "There is no valid calibration."),
        "videt-tension-calibrate" => {
            s = s
                .item(
                    EXIT_NO_BACKEND.to_string(),
                    "No device backend on this system (use --sim).",
                )
                .item(
                    EXIT_MOTORS_BUSY.to_string(),
                    "The motors are in use by another process.",
                )
                .item(
                    EXIT_CALIBRATION_WRITE.to_string(),
                    "The calibration could not be written.",
                )
        }
        "videt-service" => {
            s = s.item(
                EXIT_SERVICE_LOST.to_string(),
                "The connection to videtd broke before the request ended.",
            )
        }
        _ => {}
    }
    s
}

/// Whether `cmd`'s `--help` ends with its own list of exit codes (then it is the page's).
fn lists_exit_codes(cmd: &Command) -> bool {
    cmd.get_after_long_help()
        .or(cmd.get_after_help())
        .is_some_and(|h| h.to_string().starts_with("Exit codes:"))
}

/// The tool's page and one per subcommand, nested ones too (`videt-config-check`).
fn videt_pages() -> io::Result<Vec<Page>> {
    let mut cmd = Cli::command();
    cmd.build();
    let mut subpages = Vec::new();
    collect_subcommands(&cmd, "videt", &mut subpages);
    let mut see: Vec<String> = subpages.iter().map(|(n, _)| format!("{n}(1)")).collect();
    see.extend(["videtd(8)".to_owned(), "videt.toml(5)".to_owned()]);
    let see: Vec<&str> = see.iter().map(String::as_str).collect();
    let mut pages = vec![page(
        cmd.clone(),
        "videt",
        "1",
        &[tool_exit_status("videt"), files(), see_also(&see)],
    )?];
    for (name, sub) in subpages {
        let mut extra = Vec::new();
        if !lists_exit_codes(&sub) {
            extra.push(tool_exit_status(&name));
        }
        extra.push(files());
        extra.push(see_also(&["videt(1)", "videtd(8)", "videt.toml(5)"]));
        pages.push(page(sub, &name, "1", &extra)?);
    }
    Ok(pages)
}

/// The subcommands of `cmd` (named `PARENT-SUB`), depth first, without clap's `help`.
fn collect_subcommands(cmd: &Command, parent: &str, out: &mut Vec<(String, Command)>) {
    for sub in cmd.get_subcommands() {
        if sub.is_hide_set() || sub.get_name() == "help" {
            continue;
        }
        let name = format!("{parent}-{}", sub.get_name());
        out.push((name.clone(), sub.clone().display_name(&name)));
        collect_subcommands(sub, &name, out);
    }
}

/// `videt.toml(5)`: the example configuration's comments, section by section, each setting with
/// its example value.
pub fn config_page() -> Page {
    let mut roff = Roff::new();
    roff.control("TH", ["VIDET.TOML", "5", "", &source(), MANUAL]);
    roff.control("SH", ["NAME"]);
    roff.text([roman(
        "videt.toml - configuration of the VIDET service and tool",
    )]);
    roff.control("SH", ["SYNOPSIS"]);
    roff.text([bold("/etc/videt/videt.toml")]);
    roff.control("SH", ["DESCRIPTION"]);
    let mut pending: Vec<String> = Vec::new();
    let mut in_sections = false;
    let mut last_was_setting = false;
    // Comments right under a section's header describe the section.
    let mut after_header = false;
    for line in EXAMPLE_CONFIG.lines() {
        let trimmed = line.trim();
        if let Some(comment) = trimmed.strip_prefix('#') {
            let text = comment.trim().to_owned();
            if line.starts_with(' ') && last_was_setting {
                // The continuation of a setting's trailing comment.
                roff.text([roman(format!(" {text}"))]);
            } else {
                pending.push(text);
            }
            continue;
        }
        if trimmed.is_empty() {
            if !pending.is_empty() {
                roff.control("PP", []);
                roff.text([roman(pending.join(" "))]);
                pending.clear();
            }
            last_was_setting = false;
            continue;
        }
        if let Some(name) = trimmed.strip_prefix('[') {
            if !in_sections {
                flush(&mut roff, &mut pending);
                roff.control("SH", ["SETTINGS"]);
                roff.text([roman(
                    "Every value is validated on load; an error names the field and the allowed \
                     range. Settings left out take the values shown here.",
                )]);
                in_sections = true;
            }
            flush(&mut roff, &mut pending);
            roff.control("SS", [format!("[{}", name).as_str()]);
            last_was_setting = false;
            after_header = true;
            continue;
        }
        // A setting: `key = value   # comment`.
        if after_header {
            flush(&mut roff, &mut pending);
            after_header = false;
        }
        let (setting, comment) = split_comment(trimmed);
        let (key, value) = setting.split_once('=').unwrap_or((setting, ""));
        roff.control("TP", []);
        let tag: Vec<Inline> = vec![bold(key.trim()), roman(" = "), italic(value.trim())];
        roff.text(tag);
        let mut text = std::mem::take(&mut pending).join(" ");
        if let Some(c) = comment {
            if !text.is_empty() {
                text.push(' ');
            }
            text.push_str(c);
        }
        roff.text([roman(text)]);
        last_was_setting = true;
    }
    flush(&mut roff, &mut pending);
    for s in [
        files(),
        see_also(&["videt(1)", "videt-config-check(1)", "videtd(8)"]),
    ] {
        s.render(&mut roff);
    }
    Page {
        name: "videt.toml".to_owned(),
        section: "5",
        text: roff.to_roff(),
    }
}

fn flush(roff: &mut Roff, pending: &mut Vec<String>) {
    if !pending.is_empty() {
        roff.control("PP", []);
        roff.text([roman(pending.join(" "))]);
        pending.clear();
    }
}

/// `key = value  # comment` into the setting and the comment; a `#` inside a string is kept.
fn split_comment(line: &str) -> (&str, Option<&str>) {
    let mut in_string = false;
    for (i, c) in line.char_indices() {
        match c {
            '"' => in_string = !in_string,
            '#' if !in_string => return (line[..i].trim_end(), Some(line[i + 1..].trim())),
            _ => {}
        }
    }
    (line, None)
}

/// Every page: videtd(8), videt(1) and its subcommands' pages, videt.toml(5).
pub fn pages() -> io::Result<Vec<Page>> {
    let mut pages = vec![videtd_page()?];
    pages.extend(videt_pages()?);
    pages.push(config_page());
    Ok(pages)
}

/// The shells completed, and where each looks for a completion file (relative to /).
pub const COMPLETIONS: [(Shell, &str); 3] = [
    (Shell::Bash, "usr/share/bash-completion/completions"),
    (Shell::Zsh, "usr/share/zsh/vendor-completions"),
    (Shell::Fish, "usr/share/fish/vendor_completions.d"),
];

/// The completion script of `bin` ("videt" or "videtd") for `shell`: its file name and text.
pub fn completion(shell: Shell, bin: &str) -> (String, Vec<u8>) {
    let mut cmd = match bin {
        "videtd" => videt_service::cli::Args::command(),
        _ => Cli::command(),
    };
    let file = match shell {
        Shell::Zsh => format!("_{bin}"),
        Shell::Fish => format!("{bin}.fish"),
        _ => bin.to_owned(),
    };
    let mut out = Vec::new();
    clap_complete::generate(shell, &mut cmd, bin, &mut out);
    (file, out)
}

/// Writes the pages to `out/man/manN/NAME.N` and the completions to `out/completions/SHELL/FILE`;
/// returns the files written.
pub fn write_all(out: &Path) -> io::Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for p in pages()? {
        let dir = out.join("man").join(format!("man{}", p.section));
        std::fs::create_dir_all(&dir)?;
        let path = dir.join(p.file_name());
        std::fs::write(&path, &p.text)?;
        written.push(path);
    }
    for (shell, _) in COMPLETIONS {
        let dir = out.join("completions").join(shell.to_string());
        std::fs::create_dir_all(&dir)?;
        for bin in ["videt", "videtd"] {
            let (file, text) = completion(shell, bin);
            let path = dir.join(file);
            std::fs::write(&path, text)?;
            written.push(path);
        }
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn find<'a>(pages: &'a [Page], name: &str) -> &'a Page {
        pages
            .iter()
            .find(|p| p.name == name)
            .unwrap_or_else(|| panic!("no page {name}"))
    }

    #[test]
    fn a_page_per_program_and_subcommand() {
        let pages = pages().unwrap();
        let videtd = find(&pages, "videtd");
        assert_eq!(videtd.section, "8");
        for sub in Cli::command().get_subcommands() {
            if sub.get_name() != "help" {
                find(&pages, &format!("videt-{}", sub.get_name()));
            }
        }
        find(&pages, "videt-config-check");
        find(&pages, "videt.toml");
        let mut names: Vec<_> = pages.iter().map(Page::file_name).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), pages.len(), "two pages of one name");
    }

    #[test]
    fn pages_carry_exit_status_files_and_signals() {
        let pages = pages().unwrap();
        let videtd = &find(&pages, "videtd").text;
        for heading in [
            "SH \"EXIT STATUS\"",
            "SH FILES",
            "SH SIGNALS",
            "SH OPTIONS",
            "SH VERSION",
        ] {
            assert!(videtd.contains(heading), "videtd(8) lacks {heading}");
        }
        for option in ["\\-\\-sim", "\\-\\-config", "\\-\\-no\\-socket"] {
            assert!(videtd.contains(option), "videtd(8) lacks {option}");
        }
        assert!(videtd.contains("/run/videt/videtd.sock"));
        let init = &find(&pages, "videt-init").text;
        assert!(init.contains(".TH VIDET-INIT 1"), "{}", &init[..200]);
        // The synopsis names the command as it is typed.
        assert!(init.contains("videt init"), "{init}");
        // Its own list of exit codes (its --help's), not the generic one.
        assert!(init.contains("10 e\\-stop pressed"), "{init}");
        assert_eq!(init.matches("EXIT STATUS").count(), 1, "{init}");
        assert!(!init.contains("EXTRA"));
        let replay = &find(&pages, "videt-replay").text;
        assert!(replay.contains("EXIT STATUS") && replay.contains("diverged"));
    }

    #[test]
    fn config_page_has_every_section_and_setting_of_the_example() {
        let page = config_page();
        let example: toml::Table = toml::from_str(EXAMPLE_CONFIG).unwrap();
        for (section, settings) in &example {
            assert!(
                page.text.contains(&format!(".SS [{section}]")),
                "no [{section}]"
            );
            for key in settings.as_table().unwrap().keys() {
                assert!(
                    page.text
                        .contains(&format!("\\fB{}\\fR = ", key.replace('-', "\\-"))),
                    "no {section}.{key}"
                );
            }
        }
        // A trailing comment and its continuation lines are the setting's text.
        assert!(page.text.contains("the Z\\-width"), "{}", page.text);
    }

    #[test]
    fn completions_name_the_subcommands() {
        for (shell, _) in COMPLETIONS {
            let (file, text) = completion(shell, "videt");
            let text = String::from_utf8(text).unwrap();
            assert!(text.contains("tension-calibrate"), "{shell}: {file}");
            assert!(text.contains("calibrate-stereo"), "{shell}: {file}");
            let (_, text) = completion(shell, "videtd");
            assert!(String::from_utf8(text).unwrap().contains("sim-calibration"));
        }
        assert_eq!(completion(Shell::Zsh, "videt").0, "_videt");
        assert_eq!(completion(Shell::Fish, "videt").0, "videt.fish");
        assert_eq!(completion(Shell::Bash, "videt").0, "videt");
    }

    #[test]
    fn comments_split_outside_strings() {
        assert_eq!(split_comment("a = 1  # one"), ("a = 1", Some("one")));
        assert_eq!(split_comment("a = \"#x\" # y"), ("a = \"#x\"", Some("y")));
        assert_eq!(split_comment("a = 1"), ("a = 1", None));
    }
}
