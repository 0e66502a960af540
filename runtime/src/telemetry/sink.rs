//! The session log file as the writer appends to it, block by compressed block, and its
//! surface frames.

use std::fs::File;
use std::io::{self, Seek, SeekFrom, Write};
use std::path::Path;
use std::time::{Duration, Instant};

use super::block::BlockBuilder;
use super::format::{
    encode_calibration, encode_end, encode_header, encode_period, frame, FrameKind, LogHeader,
    BATCH_BYTES, FORMAT_VERSION_3, PERIOD_BYTES,
};
use super::read::{LogItem, SurfaceEntry};
use super::surfaces::RecordedSurface;

/// The oldest a batch gets before it is written, when the periods come slower than
/// [`BATCH_BYTES`] fills: what a session killed or cut off loses at most, besides the ring.
pub(super) const BATCH_AGE: Duration = Duration::from_millis(500);

/// The session log file as the writer appends to it: the frames of a batch are gathered in a
/// compressed block ([`LogSink::frame`]) and appended by [`LogSink::commit`], which takes a
/// refused batch back to the last whole block.
pub(super) struct LogSink {
    pub(super) file: File,
    /// Bytes of the file known written: it ends on a frame boundary.
    good_len: u64,
    /// The frames of the batch.
    block: BlockBuilder,
    /// When the batch's first frame came.
    block_since: Option<Instant>,
    /// The bytes to append: the header, or the sealed block.
    out: Vec<u8>,
}

impl LogSink {
    pub(super) fn create(path: &Path) -> io::Result<LogSink> {
        Ok(LogSink {
            file: File::create(path)?,
            good_len: 0,
            block: BlockBuilder::with_capacity(2 * BATCH_BYTES)?,
            block_since: None,
            out: Vec::with_capacity(BATCH_BYTES),
        })
    }

    /// Bytes of the file known written.
    pub(super) fn written_bytes(&self) -> u64 {
        self.good_len
    }

    /// The file's header, before any frame.
    pub(super) fn header(&mut self, header: &[u8]) {
        self.out.extend_from_slice(header);
    }

    /// Add a frame to the batch.
    pub(super) fn frame(&mut self, kind: FrameKind, payload: &[u8]) {
        self.block_since.get_or_insert_with(Instant::now);
        self.block.push(kind, payload);
    }

    /// The batch's bytes before compression.
    pub(super) fn batch_bytes(&self) -> usize {
        self.block.len()
    }

    /// Whether the batch is [`BATCH_AGE`] old.
    pub(super) fn batch_due(&self) -> bool {
        self.block_since
            .is_some_and(|since| since.elapsed() >= BATCH_AGE)
    }

    /// Seal the batch into a block and append it to the file. On an error the file is cut
    /// back to where the batch began and the batch is dropped.
    pub(super) fn commit(&mut self) -> io::Result<()> {
        self.block_since = None;
        if !self.block.is_empty() {
            match self.block.seal() {
                Ok(payload) => frame(FrameKind::Block, &payload, &mut self.out)?,
                Err(e) => {
                    self.block.clear();
                    self.out.clear();
                    return Err(e);
                }
            }
        }
        if self.out.is_empty() {
            return Ok(());
        }
        let written = self.file.write_all(&self.out);
        let taken = self.out.len() as u64;
        self.out.clear();
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

/// Where frames go: the writer's compressed blocks, or version 3's frames.
pub(super) trait FrameOut {
    /// Add a frame.
    fn frame(&mut self, kind: FrameKind, payload: &[u8]);
}

impl FrameOut for LogSink {
    fn frame(&mut self, kind: FrameKind, payload: &[u8]) {
        LogSink::frame(self, kind, payload);
    }
}

/// A version 3 log's bytes: frames one after the other, each with its CRC.
struct Version3(Vec<u8>);

impl FrameOut for Version3 {
    fn frame(&mut self, kind: FrameKind, payload: &[u8]) {
        frame(kind, payload, &mut self.0).expect("writing to memory");
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
        out: &mut impl FrameOut,
    ) {
        self.buf.clear();
        self.buf.extend_from_slice(&version.to_le_bytes());
        if self.last.as_ref() == Some(surface) {
            self.buf.push(0);
        } else {
            self.buf.push(1);
            surface.encode(&mut self.buf);
            self.last = Some(surface.clone());
        }
        out.frame(FrameKind::Surface, &self.buf);
    }
}

/// Turns a log's items back into its frames.
#[derive(Default)]
struct ItemFrames {
    surfaces: SurfaceFrames,
}

impl ItemFrames {
    /// The frame of `item` into `out`; a session that could not be read is left out.
    fn put(&mut self, item: LogItem, out: &mut impl FrameOut) -> io::Result<()> {
        match item {
            LogItem::Session(session) => {
                if let Ok(session) = *session {
                    let text = session.to_toml().map_err(io::Error::other)?;
                    out.frame(FrameKind::Session, text.as_bytes());
                }
            }
            LogItem::Calibration {
                from_cycle,
                calibration,
            } => out.frame(
                FrameKind::Calibration,
                &encode_calibration(from_cycle, &calibration),
            ),
            LogItem::Surface(version, SurfaceEntry::Recorded(surface)) => {
                self.surfaces.write(version, &surface, out);
            }
            LogItem::Surface(version, SurfaceEntry::Lost) => {
                out.frame(FrameKind::SurfaceLost, &version.to_le_bytes());
            }
            LogItem::Period(record) => {
                let mut period = [0u8; PERIOD_BYTES];
                encode_period(&record, &mut period);
                out.frame(FrameKind::Period, &period);
            }
            LogItem::End(end) => out.frame(FrameKind::End, &encode_end(&end)),
        }
        Ok(())
    }
}

/// Write a whole session log of `items` to `path` at once, as the writer thread writes one
/// (the same blocks), for tools and tests that make a log from another: an older version's,
/// or a long one made of a short one. A session frame that could not be read is left out.
/// Returns the file's size.
pub fn write_log(
    path: &Path,
    header: &LogHeader,
    items: impl IntoIterator<Item = LogItem>,
) -> io::Result<u64> {
    let mut sink = LogSink::create(path)?;
    sink.header(&encode_header(header));
    let mut frames = ItemFrames::default();
    for item in items {
        frames.put(item, &mut sink)?;
        if sink.batch_bytes() >= BATCH_BYTES {
            sink.commit()?;
        }
    }
    sink.commit()?;
    sink.file.sync_all()?;
    Ok(sink.written_bytes())
}

/// The bytes of a version 3 log of `items` (uncompressed frames, each with its CRC), as this
/// service wrote before version 4: for a reader of that version, and for tests of what a
/// reader does with a log cut between or inside two frames.
pub fn version_3_bytes(
    header: &LogHeader,
    items: impl IntoIterator<Item = LogItem>,
) -> io::Result<Vec<u8>> {
    let mut out = Version3(encode_header(header).to_vec());
    out.0[8..12].copy_from_slice(&FORMAT_VERSION_3.to_le_bytes());
    let mut frames = ItemFrames::default();
    for item in items {
        frames.put(item, &mut out)?;
    }
    Ok(out.0)
}
