//! A small file system for tests of a full disk: a tmpfs of a given size mounted on a fresh
//! directory (root only), unmounted when dropped.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};

/// A tmpfs of a set size, mounted for a test.
#[derive(Debug)]
pub struct SmallDisk {
    dir: PathBuf,
}

impl SmallDisk {
    /// Mount a tmpfs of `bytes` on a new directory under the temporary directory. `Err` says
    /// why it cannot (not root, no `mount`, a container that refuses it): the test then skips
    /// with that reason.
    pub fn mount(bytes: u64) -> Result<SmallDisk, String> {
        static NEXT: AtomicU32 = AtomicU32::new(0);
        let dir = std::env::temp_dir().join(format!(
            "videt-small-disk-{}-{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={bytes}"), "tmpfs"])
            .arg(&dir)
            .output()
            .map_err(|e| format!("cannot run mount: {e}"))?;
        if !out.status.success() {
            let _ = std::fs::remove_dir(&dir);
            return Err(format!(
                "cannot mount a {bytes}-byte tmpfs (root only): {}",
                String::from_utf8_lossy(&out.stderr).trim()
            ));
        }
        Ok(SmallDisk { dir })
    }

    /// [`SmallDisk::mount`], or `None` after printing why not (the test then skips).
    pub fn mount_or_skip(bytes: u64) -> Option<SmallDisk> {
        SmallDisk::mount(bytes)
            .map_err(|why| eprintln!("skipped: {why}"))
            .ok()
    }

    /// Where it is mounted.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    /// Fill the disk with a file until `free_bytes` are left (roughly: the file system's
    /// blocks); returns the file, whose removal frees the space again.
    pub fn fill_leaving(&self, free_bytes: u64) -> std::io::Result<PathBuf> {
        let path = self.dir.join("filler");
        let free = self.free_bytes()?;
        let size = free.saturating_sub(free_bytes);
        std::fs::write(&path, vec![0u8; size as usize])?;
        Ok(path)
    }

    /// Free bytes on the disk, as `df` says.
    pub fn free_bytes(&self) -> std::io::Result<u64> {
        let out = Command::new("df")
            .args(["--output=avail", "-B1"])
            .arg(&self.dir)
            .output()?;
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .nth(1)
            .and_then(|l| l.trim().parse().ok())
            .ok_or_else(|| std::io::Error::other("df gave no free space"))
    }
}

impl Drop for SmallDisk {
    fn drop(&mut self) {
        // Lazily: a file a test still holds open does not keep the mount.
        let _ = Command::new("umount").arg("-l").arg(&self.dir).status();
        let _ = std::fs::remove_dir(&self.dir);
    }
}
