//! A `videtd` child process for the whole-stack tests: started on a socket, queried for its
//! status, and killed when dropped, so that a failed assertion never leaves it running.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use videt_service::socket::{request, Request, StatusReport};

pub struct Daemon {
    child: Child,
    socket: PathBuf,
}

impl Daemon {
    /// Starts `videtd` on the twin of the rig with `guides` (the `--sim-guides` text), with the
    /// configuration file `config` and the calibration file `calibration` but not calibrated
    /// (no force rendered until a procedure calibrates it), without telemetry, for
    /// `duration_s` seconds.
    pub fn start_uncalibrated_twin(
        config: &str,
        guides: &str,
        calibration: &str,
        duration_s: u32,
        socket: &Path,
        telemetry_dir: Option<&Path>,
    ) -> Daemon {
        let duration = duration_s.to_string();
        let mut args = vec![
            "--sim",
            "--sim-calibration",
            "none",
            "--config",
            config,
            "--sim-guides",
            guides,
            "--duration",
            &duration,
            "--calibration",
            calibration,
        ];
        match telemetry_dir.and_then(|d| d.to_str()) {
            Some(dir) => args.extend(["--telemetry-dir", dir]),
            None => args.push("--no-telemetry"),
        }
        Daemon::start(&args, socket)
    }

    /// Starts `videtd` with `args` and `--socket socket` (quiet, its output discarded) and waits
    /// until the socket exists.
    pub fn start(args: &[&str], socket: &Path) -> Daemon {
        let child = Command::new(videt_testkit::videtd_bin())
            .args(args)
            .arg("--socket")
            .arg(socket)
            .env("RUST_LOG", "warn")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let daemon = Daemon {
            child,
            socket: socket.to_path_buf(),
        };
        let deadline = Instant::now() + Duration::from_secs(20);
        while !socket.exists() {
            assert!(Instant::now() < deadline, "videtd did not start");
            std::thread::sleep(Duration::from_millis(20));
        }
        daemon
    }

    /// The service's status.
    pub fn status(&self) -> StatusReport {
        request(&self.socket, &Request::Status, Duration::from_secs(2))
            .expect("videtd answers")
            .status
            .expect("a status")
    }

    /// Wait until `check` holds for the status (or fail after `secs`).
    pub fn wait_for(
        &self,
        secs: f64,
        what: &str,
        check: impl Fn(&StatusReport) -> bool,
    ) -> StatusReport {
        let deadline = Instant::now() + Duration::from_secs_f64(secs);
        loop {
            let s = self.status();
            if check(&s) {
                return s;
            }
            assert!(Instant::now() < deadline, "{what}: {s:?}");
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Waits for the process to end (after a stop request) and returns how it ended.
    pub fn wait(&mut self) -> ExitStatus {
        self.child.wait().unwrap()
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
