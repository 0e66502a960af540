//! The session log file as the writer appends to it, and its surface frames.

use std::fs::File;
use std::io::{self, Seek, SeekFrom, Write};
use std::path::Path;

use super::format::{frame, FrameKind};
use super::surfaces::RecordedSurface;

/// A batch is written once it holds this many bytes, or whenever the ring is empty.
pub(super) const BATCH_BYTES: usize = 256 * 1024;

/// The session log file as the writer appends to it: frames are gathered in `batch` (its
/// `Write` implementation) and appended by [`LogSink::commit`], which takes a refused batch back
/// to the last whole frame.
pub(super) struct LogSink {
    pub(super) file: File,
    /// Bytes of the file known written: it ends on a frame boundary.
    good_len: u64,
    pub(super) batch: Vec<u8>,
}

impl LogSink {
    pub(super) fn create(path: &Path) -> io::Result<LogSink> {
        Ok(LogSink {
            file: File::create(path)?,
            good_len: 0,
            batch: Vec::with_capacity(2 * BATCH_BYTES),
        })
    }

    /// Append the batch to the file. On an error the file is cut back to where the batch
    /// began and the batch is dropped.
    pub(super) fn commit(&mut self) -> io::Result<()> {
        if self.batch.is_empty() {
            return Ok(());
        }
        let written = self.file.write_all(&self.batch);
        let taken = self.batch.len() as u64;
        self.batch.clear();
        match written {
            Ok(()) => {
                self.good_len += taken;
                Ok(())
            }
            Err(e) => {
                // A part of the batch may be in the file: take it back.
                let _ = self.file.set_len(self.good_len);
                let _ = self.file.seek(SeekFrom::Start(self.good_len));
                Err(e)
            }
        }
    }
}

impl Write for LogSink {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        self.batch.extend_from_slice(bytes);
        Ok(bytes.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// Writes surface frames, a surface equal to the previous one as a short repeat.
#[derive(Default)]
pub(super) struct SurfaceFrames {
    pub(super) last: Option<RecordedSurface>,
    buf: Vec<u8>,
}

impl SurfaceFrames {
    pub(super) fn write(
        &mut self,
        version: u64,
        surface: &RecordedSurface,
        out: &mut impl Write,
    ) -> io::Result<()> {
        self.buf.clear();
        self.buf.extend_from_slice(&version.to_le_bytes());
        if self.last.as_ref() == Some(surface) {
            self.buf.push(0);
        } else {
            self.buf.push(1);
            surface.encode(&mut self.buf);
            self.last = Some(surface.clone());
        }
        frame(FrameKind::Surface, &self.buf, out)
    }
}
