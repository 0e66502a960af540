//! Lock-free, wait-free snapshots between threads (triple buffering, `triple_buffer` crate).
//!
//! The writer rebuilds a back buffer **in place** (reusing its allocations) and publishes it; the
//! reader switches to the newest buffer without waiting. Buffers are never dropped while the
//! channel lives, so the control thread neither allocates nor frees when it takes a new
//! snapshot: the vision thread, which writes, owns all allocation.

use videt_control::Surface;
use videt_hal::MonoTime;

/// Sees every snapshot as it is published (on the writer's thread): the session log records
/// surfaces through one.
pub type PublishTap<T> = Box<dyn FnMut(u64, &T) + Send>;

/// Writes snapshots: rebuild the back buffer in place, then publish it.
pub struct SnapshotWriter<T: Send> {
    input: triple_buffer::Input<Versioned<T>>,
    version: u64,
    tap: Option<PublishTap<T>>,
}

/// Reads the newest published snapshot.
pub struct SnapshotReader<T: Send> {
    output: triple_buffer::Output<Versioned<T>>,
}

/// A value with the version it was published under (0 = the initial value).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Versioned<T> {
    /// Published version, counting from 1.
    pub version: u64,
    /// The value.
    pub value: T,
    /// When the data it was made from was captured (a camera frame's exposure), on
    /// `CLOCK_MONOTONIC`; `None` when it was not made from a capture.
    pub captured: Option<MonoTime>,
}

/// A connected writer/reader pair, every buffer starting as a clone of `initial`.
pub fn snapshot_channel<T: Clone + Send>(initial: T) -> (SnapshotWriter<T>, SnapshotReader<T>) {
    let (input, output) = triple_buffer::triple_buffer(&Versioned {
        version: 0,
        value: initial,
        captured: None,
    });
    (
        SnapshotWriter {
            input,
            version: 0,
            tap: None,
        },
        SnapshotReader { output },
    )
}

impl<T: Send> SnapshotWriter<T> {
    /// Rebuild the back buffer with `fill` (it sees an older value to overwrite, whose
    /// allocations it should reuse) and publish it. Returns the new version.
    pub fn publish_with(&mut self, fill: impl FnOnce(&mut T)) -> u64 {
        self.publish_captured_with(None, fill)
    }

    /// As [`SnapshotWriter::publish_with`], for a value made from data captured at `captured`
    /// (`CLOCK_MONOTONIC`): the reader can tell how old the capture is when it takes it.
    pub fn publish_captured_with(
        &mut self,
        captured: Option<MonoTime>,
        fill: impl FnOnce(&mut T),
    ) -> u64 {
        self.version += 1;
        let back = self.input.input_buffer_mut();
        fill(&mut back.value);
        back.version = self.version;
        back.captured = captured;
        if let Some(tap) = self.tap.as_mut() {
            tap(self.version, &back.value);
        }
        self.input.publish();
        self.version
    }

    /// Show every snapshot published from now on to `tap`, with its version, before the
    /// reader can see it.
    pub fn set_tap(&mut self, tap: PublishTap<T>) {
        self.tap = Some(tap);
    }

    /// Publish `value` under `version` (greater than the last one): a replay re-publishes
    /// recorded snapshots under the versions they had.
    pub fn publish_as(&mut self, version: u64, value: T) -> u64 {
        self.version = version.max(self.version + 1) - 1;
        self.publish(value)
    }

    /// Replace the back buffer with `value` and publish (drops the old buffer's value here, on
    /// the writer's thread).
    pub fn publish(&mut self, value: T) -> u64 {
        self.publish_with(|slot| *slot = value)
    }
}

impl<T: Send> SnapshotReader<T> {
    /// The newest snapshot (wait-free; allocation-free).
    pub fn latest(&mut self) -> &Versioned<T> {
        self.output.update();
        self.output.output_buffer()
    }

    /// The snapshot taken by the last [`SnapshotReader::latest`], without looking for a newer
    /// one (wait-free; allocation-free).
    pub fn peek(&self) -> &Versioned<T> {
        self.output.output_buffer()
    }
}

/// The surface the control cycle renders this period.
pub struct SurfaceView<'a, S: ?Sized> {
    /// The surface.
    pub surface: &'a S,
    /// Its version (changes when a new model is published).
    pub version: u64,
    /// Whether the surface comes from a live source that can go stale (vision); a fixed
    /// surface never does.
    pub live: bool,
    /// On the first period that renders a version made from a camera frame: how long ago that
    /// frame was captured, nanoseconds (the frame-to-force latency); `None` otherwise.
    pub frame_age_ns: Option<u64>,
}

/// Where the control cycle gets its surface from each period. Called on the control thread:
/// wait-free and allocation-free.
pub trait SurfaceFeed {
    /// The surface type.
    type Surface: Surface + ?Sized;
    /// The surface to render now.
    fn current(&mut self) -> SurfaceView<'_, Self::Surface>;
    /// How the session log records this feed's surfaces (not called on the control thread).
    /// The default records nothing: a session on such a feed cannot be replayed.
    fn recording(&self) -> crate::telemetry::surfaces::FeedRecording {
        crate::telemetry::surfaces::FeedRecording::default()
    }
}

/// A fixed surface (a virtual wall, a stored model): never stale.
#[derive(Debug, Clone)]
pub struct FixedSurface<S>(pub S);

impl<S: Surface + crate::telemetry::surfaces::RecordSurface> SurfaceFeed for FixedSurface<S> {
    type Surface = S;
    fn current(&mut self) -> SurfaceView<'_, S> {
        SurfaceView {
            surface: &self.0,
            version: 0,
            live: false,
            frame_age_ns: None,
        }
    }
    fn recording(&self) -> crate::telemetry::surfaces::FeedRecording {
        crate::telemetry::surfaces::FeedRecording {
            initial: self.0.recorded(),
            tap: None,
        }
    }
}

impl<T: Surface + Send> SurfaceFeed for SnapshotReader<T> {
    type Surface = T;
    fn current(&mut self) -> SurfaceView<'_, T> {
        let latest = self.latest();
        SurfaceView {
            surface: &latest.value,
            version: latest.version,
            live: true,
            frame_age_ns: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reader_sees_the_newest_version_and_buffers_are_reused() {
        let (mut w, mut r) = snapshot_channel(Vec::<u32>::new());
        assert_eq!(r.latest().version, 0);
        let mut buffers_seen = std::collections::HashSet::new();
        for v in 1..=30u32 {
            w.publish_with(|buf| {
                buf.clear();
                buf.extend(v..v + 10);
            });
            let latest = r.latest();
            assert_eq!(latest.version, u64::from(v));
            assert_eq!(latest.value[0], v);
            if v > 3 {
                buffers_seen.insert(latest.value.as_ptr() as usize);
            }
        }
        assert!(
            buffers_seen.len() <= 3,
            "rebuilt in place: {} distinct buffers",
            buffers_seen.len()
        );
    }
}
