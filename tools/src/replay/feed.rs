//! The recorded surfaces, rendered as the service rendered them, from a log read as a stream.

use std::collections::BTreeMap;
use std::sync::Arc;

use videt_config::Config;
use videt_control::surface::Plane;
use videt_control::WireDevice;
use videt_relief::ReliefModel;
use videt_runtime::cycle::{ControlCycle, CycleRecord};
use videt_runtime::snapshot::{FixedSurface, SnapshotWriter, SurfaceFeed, SurfaceView};
use videt_runtime::telemetry::{RecordedSurface, SurfaceEntry};
use videt_service::relief_feed::ReliefFeed;

use super::devices::RecordedDevices;

/// The recorded surfaces the log has given and no period has yet passed: a version is held
/// from the moment the log gives it (before the first period that renders it) until a period
/// renders a later one, so the memory held does not grow with the session's length.
#[derive(Default)]
pub(super) struct HeldSurfaces(BTreeMap<u64, SurfaceEntry>);

impl HeldSurfaces {
    /// The log gave surface `version`.
    pub(super) fn hold(&mut self, version: u64, entry: SurfaceEntry) {
        self.0.insert(version, entry);
    }

    fn surface(&self, version: u64) -> Result<&Arc<RecordedSurface>, String> {
        match self.0.get(&version) {
            Some(SurfaceEntry::Recorded(s)) => Ok(s),
            Some(SurfaceEntry::Lost) => Err(format!(
                "surface version {version} was published but not recorded (the log writer fell behind)"
            )),
            None => Err(format!("surface version {version} is not in the log")),
        }
    }
}

/// The recorded surfaces as the control thread found them: a fixed plane, or the relief feed.
pub(super) enum ReplayFeed {
    Plane(FixedSurface<Plane>),
    Relief {
        writer: SnapshotWriter<ReliefModel>,
        feed: Box<ReliefFeed>,
        published: u64,
    },
}

impl ReplayFeed {
    /// Render the session's first surface (version 0), as the service started, with
    /// `config`'s settings.
    pub(super) fn start(held: &HeldSurfaces, config: &Config) -> Result<ReplayFeed, String> {
        Ok(match held.surface(0)?.as_ref() {
            RecordedSurface::Plane(p) => ReplayFeed::Plane(FixedSurface(*p)),
            RecordedSurface::Relief(m) => {
                let (writer, feed) =
                    videt_service::relief_feed::relief_channel_for(config, m.clone())
                        .map_err(|e| format!("relief rendering settings: {e}"))?;
                ReplayFeed::Relief {
                    writer,
                    feed: Box::new(feed),
                    published: 0,
                }
            }
        })
    }

    /// Make `version` the newest surface, as the control thread found it; the versions before
    /// it are let go.
    pub(super) fn show(&mut self, held: &mut HeldSurfaces, version: u64) -> Result<(), String> {
        match self {
            ReplayFeed::Plane(_) if version != 0 => {
                return Err(format!(
                    "surface version {version} on a fixed surface (a corrupt record)"
                ))
            }
            ReplayFeed::Plane(_) => {}
            ReplayFeed::Relief {
                writer, published, ..
            } => {
                if version != *published {
                    let RecordedSurface::Relief(m) = held.surface(version)?.as_ref() else {
                        return Err(format!("surface version {version} is not a relief"));
                    };
                    if version < *published {
                        return Err(format!(
                            "surface version {version} after version {published} (a corrupt record)"
                        ));
                    }
                    writer.publish_as(version, m.clone());
                    *published = version;
                }
            }
        }
        held.0 = held.0.split_off(&version);
        Ok(())
    }

    /// Run one period of `cycle` on the recorded inputs, rendering the surface shown.
    pub(super) fn run<const N: usize, D: WireDevice<N>>(
        &mut self,
        cycle: &mut ControlCycle<N, D>,
        devices: &mut RecordedDevices<'_>,
        record: &CycleRecord,
        out: &mut CycleRecord,
    ) {
        // The period's time and the frame age are measurements of the session, taken from the
        // clock when it ran: both come from the record, never from this machine's clock (the
        // replay publishes the recorded surfaces without a capture stamp, so the feed reads no
        // clock either).
        let (now, overrun) = (record.time, record.inputs.deadline_overrun);
        let age = record.inputs.surface_frame_age_ns;
        match self {
            ReplayFeed::Plane(f) => {
                cycle.run(devices, with_age(f.current(), age), now, overrun, out)
            }
            ReplayFeed::Relief { feed, .. } => {
                cycle.run(devices, with_age(feed.current(), age), now, overrun, out)
            }
        }
    }
}

/// `view` with the recorded frame age: how old the camera frame of a new surface was when the
/// service first rendered it. The outputs do not depend on it; the record keeps it as an input
/// (the frame-to-force latency), so a replay hands the recorded one back.
fn with_age<S: ?Sized>(
    mut view: SurfaceView<'_, S>,
    frame_age_ns: Option<u64>,
) -> SurfaceView<'_, S> {
    view.frame_age_ns = frame_age_ns;
    view
}
