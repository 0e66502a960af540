//! The recorded surfaces, rendered as the service rendered them, from a log read as a stream.

use std::collections::BTreeMap;
use std::sync::Arc;

use videt_control::surface::Plane;
use videt_control::WireDevice;
use videt_rt_config::Config;
use videt_runtime::cycle::{ControlCycle, CycleRecord};
use videt_runtime::snapshot::{FixedSurface, SnapshotWriter, SurfaceFeed, SurfaceView};
use videt_runtime::telemetry::{RecordedSurface, SurfaceEntry};
use videt_service::relief_feed::ReliefFeed;
use videt_vision::surface::ReliefModel;

use super::devices::RecordedDevices;

/// How the session's surfaces were rendered: a fixed plane, or the relief feed.
enum Render {
    Plane(FixedSurface<Plane>),
    Relief {
        writer: SnapshotWriter<ReliefModel>,
        feed: Box<ReliefFeed>,
        published: u64,
    },
}

/// The recorded surfaces as the control thread found them. A version is held from the moment
/// the log gives it (before the first period that renders it) until a period renders a later
/// one, so the memory held does not grow with the session's length.
pub(super) struct ReplayFeed {
    config: Config,
    held: BTreeMap<u64, SurfaceEntry>,
    render: Option<Render>,
}

impl ReplayFeed {
    /// A feed rendering as `config` says, holding no surface yet.
    pub(super) fn new(config: &Config) -> ReplayFeed {
        ReplayFeed {
            config: config.clone(),
            held: BTreeMap::new(),
            render: None,
        }
    }

    /// The log gave surface `version`.
    pub(super) fn hold(&mut self, version: u64, entry: SurfaceEntry) {
        self.held.insert(version, entry);
    }

    fn surface(&self, version: u64) -> Result<&Arc<RecordedSurface>, String> {
        match self.held.get(&version) {
            Some(SurfaceEntry::Recorded(s)) => Ok(s),
            Some(SurfaceEntry::Lost) => Err(format!(
                "surface version {version} was published but not recorded (the log writer fell behind)"
            )),
            None => Err(format!("surface version {version} is not in the log")),
        }
    }

    /// Start rendering the session's first surface (version 0), as the service started.
    pub(super) fn start(&mut self) -> Result<(), String> {
        if self.render.is_some() {
            return Ok(());
        }
        self.render = Some(match self.surface(0)?.as_ref() {
            RecordedSurface::Plane(p) => Render::Plane(FixedSurface(*p)),
            RecordedSurface::Relief(m) => {
                let (writer, feed) =
                    videt_service::relief_feed::relief_channel_for(&self.config, m.clone())
                        .map_err(|e| format!("relief rendering settings: {e}"))?;
                Render::Relief {
                    writer,
                    feed: Box::new(feed),
                    published: 0,
                }
            }
        });
        Ok(())
    }

    /// Make `version` the newest surface, as the control thread found it.
    pub(super) fn show(&mut self, version: u64) -> Result<(), String> {
        self.start()?;
        let model = match &self.render {
            Some(Render::Relief { published, .. }) if version != *published => {
                let RecordedSurface::Relief(m) = self.surface(version)?.as_ref() else {
                    return Err(format!("surface version {version} is not a relief"));
                };
                if version < *published {
                    return Err(format!(
                        "surface version {version} after version {published} (a corrupt record)"
                    ));
                }
                Some(m.clone())
            }
            Some(Render::Plane(_)) if version != 0 => {
                return Err(format!(
                    "surface version {version} on a fixed surface (a corrupt record)"
                ))
            }
            _ => None,
        };
        if let (
            Some(model),
            Some(Render::Relief {
                writer, published, ..
            }),
        ) = (model, &mut self.render)
        {
            writer.publish_as(version, model);
            *published = version;
        }
        // The versions before it are never rendered again.
        self.held = self.held.split_off(&version);
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
        match &mut self.render {
            Some(Render::Plane(f)) => {
                cycle.run(devices, with_age(f.current(), age), now, overrun, out)
            }
            Some(Render::Relief { feed, .. }) => {
                cycle.run(devices, with_age(feed.current(), age), now, overrun, out)
            }
            // `show` starts the rendering before any period runs.
            None => {}
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
