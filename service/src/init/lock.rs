//! One process at a time drives the motors: an exclusive, non-blocking `flock` on a lock file
//! (`files.motors_lock`, `/run/videt/motors.lock` on the device). `videtd` and the `videt` tool
//! both take it; the kernel releases it when the holder exits, however it exits.

use std::fs::{File, OpenOptions};
use std::io::{self, Read, Seek, Write};
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};

/// Why the lock was not taken.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// Another process holds it.
    #[error("the motors are in use by another process{holder} (lock {path}): stop it first (e.g. `systemctl stop videtd`)")]
    Busy {
        /// The lock file.
        path: String,
        /// `" (pid N)"` when the holder wrote its pid.
        holder: String,
    },
    /// The lock file could not be created or locked.
    #[error("cannot take the motors lock {path}: {source}")]
    Io {
        /// The lock file.
        path: String,
        /// The error.
        source: io::Error,
    },
}

/// The held lock; dropping it releases the motors.
#[derive(Debug)]
pub struct MotorsLock {
    file: File,
    path: PathBuf,
}

impl MotorsLock {
    /// Take the lock at `path` (its directory is created), or say who holds it.
    pub fn acquire(path: &Path) -> Result<MotorsLock, LockError> {
        let io_err = |source| LockError::Io {
            path: path.display().to_string(),
            source,
        };
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(io_err)?;
        }
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)
            .map_err(io_err)?;
        // SAFETY: flock on a file descriptor we own; no memory is passed.
        let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
        if rc != 0 {
            let e = io::Error::last_os_error();
            if e.raw_os_error() == Some(libc::EWOULDBLOCK) {
                let mut pid = String::new();
                let _ = file.read_to_string(&mut pid);
                let pid = pid.trim();
                return Err(LockError::Busy {
                    path: path.display().to_string(),
                    holder: if pid.is_empty() {
                        String::new()
                    } else {
                        format!(" (pid {pid})")
                    },
                });
            }
            return Err(io_err(e));
        }
        // Record the holder for the next one's error message.
        let _ = file.set_len(0);
        let _ = file.rewind();
        let _ = writeln!(file, "{}", std::process::id());
        let _ = file.flush();
        Ok(MotorsLock {
            file,
            path: path.to_path_buf(),
        })
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for MotorsLock {
    fn drop(&mut self) {
        let _ = self.file.set_len(0);
        // SAFETY: unlocking a descriptor we own (closing it would release the lock too).
        unsafe { libc::flock(self.file.as_raw_fd(), libc::LOCK_UN) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_holder_is_refused_until_the_first_lets_go() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run").join("motors.lock");
        let first = MotorsLock::acquire(&path).unwrap();
        let e = MotorsLock::acquire(&path).unwrap_err().to_string();
        assert!(
            e.contains("in use") && e.contains(&format!("pid {}", std::process::id())),
            "{e}"
        );
        drop(first);
        MotorsLock::acquire(&path).unwrap();
    }
}
