//! A buffered file that remembers its first error: the MCAP sink reports a failed write only
//! to the tracing log, so the export asks the file.

use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::sync::{Arc, Mutex, PoisonError};

/// The first write error, kept: the MCAP sink reports a failed message write only to the
/// tracing log, so the file writer remembers it for the export to report.
pub(crate) type SharedError = Arc<Mutex<Option<io::Error>>>;

pub(crate) fn take_error(e: &SharedError) -> Option<io::Error> {
    e.lock().unwrap_or_else(PoisonError::into_inner).take()
}

/// A buffered file that remembers its first error.
pub(crate) struct CheckedWriter<W: Write> {
    inner: BufWriter<W>,
    pub(crate) error: SharedError,
}

impl<W: Write> CheckedWriter<W> {
    pub(crate) fn new(file: W) -> CheckedWriter<W> {
        CheckedWriter {
            inner: BufWriter::with_capacity(1 << 20, file),
            error: Arc::default(),
        }
    }

    fn keep<T>(&self, r: io::Result<T>) -> io::Result<T> {
        if let Err(e) = &r {
            let mut slot = self.error.lock().unwrap_or_else(PoisonError::into_inner);
            if slot.is_none() {
                *slot = Some(io::Error::new(e.kind(), e.to_string()));
            }
        }
        r
    }

    /// Flush, and the file back.
    pub(crate) fn finish(self) -> io::Result<W> {
        self.inner.into_inner().map_err(|e| e.into_error())
    }
}

impl<W: Write> Write for CheckedWriter<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let r = self.inner.write(buf);
        self.keep(r)
    }
    fn flush(&mut self) -> io::Result<()> {
        let r = self.inner.flush();
        self.keep(r)
    }
}

impl<W: Write + Seek> Seek for CheckedWriter<W> {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        let r = self.inner.seek(pos);
        self.keep(r)
    }
}
