//! What a scene and the hardware add to the service beyond the HAL: the scene's links (a second
//! reader of the thimble state, a status suffix, the twin's vision stall, the live image) and
//! the hardware's reports (why it went to its safe state, the drives' start-up report).

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use tracing::warn;

pub use videt_assembly::hardware::FaultCauses;
use videt_assembly::hardware::{drive_fault_causes, DriveReports};
use videt_runtime::snapshot::SnapshotReader;
use videt_runtime::thimble::ThimbleState;

/// What a scene adds to the service: a second reader of the thimble state (a vision thread that
/// looks where the finger is), a suffix for the status line, the twin's vision stall and the
/// live view's image.
#[derive(Default)]
pub struct SceneLinks {
    /// Publishes the thimble state every period to a reader the scene keeps.
    pub thimble: Option<videt_runtime::thimble::ThimblePublisher>,
    /// Text appended to each status line (called on the supervisor thread, once a second).
    pub status_suffix: Option<Box<dyn Fn() -> String + Send>>,
    /// On the twin: while set, the scene's vision thread publishes nothing (a stalled camera,
    /// for `sim-fault vision-stall`).
    pub vision_stall: Option<Arc<AtomicBool>>,
    /// The cameras' rectified left image for the live view (a camera scene sets it).
    pub live_image: Option<Arc<videt_viewers::live::ImageSlot>>,
}

/// What the hardware reports beside its HAL readings.
#[derive(Default)]
pub struct HardwareReports {
    /// The hardware's account of why it went to its safe state: each call returns one cause
    /// not yet told (already formatted, off the control thread), `None` when there is none.
    /// The supervisor logs each beside the safe state it explains.
    pub fault_causes: Option<FaultCauses>,
    /// The drives' start-up report (identities, missing optional objects): logged once per
    /// configuration and carried in the status reply.
    pub drives_report: Option<videt_drivers::cia402::SharedStartupReport>,
}

impl SceneLinks {
    /// The links of a vision thread that looks where the finger is: the thimble state the
    /// control thread publishes every period (the reader returned, for the thread), and
    /// `status` after each status line.
    pub fn following_the_finger(
        status: impl Fn() -> String + Send + 'static,
    ) -> (SceneLinks, SnapshotReader<ThimbleState>) {
        let (publisher, reader) = videt_runtime::thimble::thimble_channel();
        let links = SceneLinks {
            thimble: Some(publisher),
            status_suffix: Some(Box::new(status)),
            ..SceneLinks::default()
        };
        (links, reader)
    }
}

impl HardwareReports {
    /// What the CiA 402 drives of `hw` report: the cause of each safe state they enter, and their
    /// start-up report.
    pub fn of_drives<H: DriveReports>(hw: &mut H) -> HardwareReports {
        HardwareReports {
            fault_causes: Some(drive_fault_causes(hw.fault_reports())),
            drives_report: Some(hw.startup_report()),
        }
    }
}

/// Log each hardware fault cause not yet told ([`HardwareReports::fault_causes`]); the latest
/// one told, if any.
pub(super) fn tell_fault_causes(fault_causes: &mut Option<FaultCauses>) -> Option<String> {
    let mut latest = None;
    if let Some(next_cause) = fault_causes.as_mut() {
        while let Some(cause) = next_cause() {
            warn!(%cause, "hardware fault");
            latest = Some(cause);
        }
    }
    latest
}
