//! The bas-relief from vision, rendered through a god-object proxy with blended swaps.
//!
//! The vision thread publishes each new [`ReliefModel`] through a wait-free snapshot; the control
//! thread renders the newest one through [`SwapRenderer`]: the proxy stays outside the solid
//! (no pop-through), and when a new model comes in the force goes over from the last rendered
//! force to the new model's with a bounded step per period. Staleness is the cycle's business
//! (it fades the forces out when the version stops changing).

use std::cell::Cell;
use std::sync::Arc;

use videt_control::blend::{BlendParams, SwapRenderer, SwapRendererError};
use videt_control::proxy::{ProxyContact, ProxyParams};
use videt_control::{Contact, Surface, Vec3};
use videt_relief::ReliefModel;

use videt_runtime::snapshot::{
    snapshot_channel, SnapshotReader, SnapshotWriter, SurfaceFeed, SurfaceView,
};
use videt_runtime::telemetry::{FeedRecording, RecordedSurface, SurfaceTap};

/// The control thread's end: the newest relief, rendered through the proxy.
pub struct ReliefFeed {
    tap: Arc<SurfaceTap>,
    reader: SnapshotReader<ReliefModel>,
    renderer: Cell<SwapRenderer>,
    rendered_version: Cell<u64>,
    /// The version the last [`SurfaceFeed::current`] gave.
    current_version: u64,
    period_s: f64,
}

/// Creates the relief channel: the vision thread's writer and the control thread's feed,
/// starting with `initial` (version 0). `stiffness_n_per_m` is the control step's `K`;
/// `period_s` the control period.
pub fn relief_channel(
    initial: ReliefModel,
    proxy: ProxyParams,
    blend: BlendParams,
    stiffness_n_per_m: f64,
    period_s: f64,
) -> Result<(SnapshotWriter<ReliefModel>, ReliefFeed), SwapRendererError> {
    let renderer = SwapRenderer::new(proxy, blend, stiffness_n_per_m)?;
    let (mut writer, reader) = snapshot_channel(initial);
    // Every published relief goes to the session log too (cloned on the vision thread).
    let tap = Arc::new(SurfaceTap::default());
    let writer_tap = Arc::clone(&tap);
    writer.set_tap(Box::new(move |version, model: &ReliefModel| {
        writer_tap.published(version, RecordedSurface::Relief(model.clone()))
    }));
    Ok((
        writer,
        ReliefFeed {
            tap,
            reader,
            renderer: Cell::new(renderer),
            rendered_version: Cell::new(0),
            current_version: 0,
            period_s,
        },
    ))
}

impl ReliefFeed {
    /// The last proxy update (where the proxy is, the spring it rendered).
    pub fn last_proxy(&self) -> Option<ProxyContact> {
        self.renderer.get().last()
    }

    /// The model being rendered.
    pub fn model(&self) -> &ReliefModel {
        &self.reader.peek().value
    }
}

impl Surface for ReliefFeed {
    fn contact(&self, position_m: &Vec3) -> Option<Contact> {
        let snapshot = self.reader.peek();
        let mut renderer = self.renderer.get();
        if snapshot.version != self.rendered_version.get() {
            renderer.swap();
            self.rendered_version.set(snapshot.version);
        }
        let c = renderer.render(&snapshot.value, None, position_m, self.period_s, 0.0);
        self.renderer.set(renderer);
        c
    }
}

impl SurfaceFeed for ReliefFeed {
    type Surface = ReliefFeed;
    fn current(&mut self) -> SurfaceView<'_, ReliefFeed> {
        let latest = self.reader.latest();
        let (version, captured) = (latest.version, latest.captured);
        // The first period to take a version made from a camera frame measures how old the
        // frame is (CLOCK_MONOTONIC, as the capture stamp; a vDSO read, no system call).
        let frame_age_ns = match captured {
            Some(at) if version != self.current_version => {
                Some(videt_hal::Clock::now(&videt_runtime::rt::SystemClock).nanos_since(at))
            }
            _ => None,
        };
        self.current_version = version;
        SurfaceView {
            surface: self,
            version,
            live: true,
            frame_age_ns,
        }
    }
    fn recording(&self) -> FeedRecording {
        FeedRecording {
            initial: Some(RecordedSurface::Relief(self.reader.peek().value.clone())),
            tap: Some(Arc::clone(&self.tap)),
        }
    }
}

/// Whether the relief's proxy, blend and stiffness in `config` make a renderer (the plan
/// checks it before any relief is built).
pub fn check_relief_settings(config: &videt_config::Config) -> Result<(), SwapRendererError> {
    use crate::relief_scene::{blend_params, proxy_params};
    SwapRenderer::new(
        proxy_params(),
        blend_params(config),
        config.control.stiffness_n_per_m,
    )
    .map(|_| ())
}

/// The relief channel with the proxy, the blend and the stiffness of `config`: how the service
/// renders every relief (and how a replay renders the recorded ones again).
pub fn relief_channel_for(
    config: &videt_config::Config,
    initial: ReliefModel,
) -> Result<(SnapshotWriter<ReliefModel>, ReliefFeed), SwapRendererError> {
    use crate::relief_scene::{blend_params, proxy_params};
    relief_channel(
        initial,
        proxy_params(),
        blend_params(config),
        config.control.stiffness_n_per_m,
        1.0 / f64::from(config.control.rate_hz),
    )
}
