//! What the control loop renders, whichever scene it is: a fixed wall, or a relief kept up to
//! date by a vision thread. One feed type for every scene, so the service is started from one
//! place; the choice costs one branch per query on the control thread (no allocation, no
//! dynamic dispatch).

use videt_control::{Contact, Plane, Surface, Vec3};
use videt_runtime::snapshot::{FixedSurface, SurfaceFeed, SurfaceView};
use videt_runtime::telemetry::FeedRecording;

use crate::relief_feed::ReliefFeed;

/// The surface feed of a scene.
pub enum SceneFeed {
    /// A flat virtual wall (the check wall, a twin's wall scene): never stale.
    Wall(FixedSurface<Plane>),
    /// A relief published by a vision thread, rendered through the proxy with blended swaps.
    Relief(Box<ReliefFeed>),
}

impl Surface for SceneFeed {
    fn contact(&self, position_m: &Vec3) -> Option<Contact> {
        match self {
            SceneFeed::Wall(wall) => wall.0.contact(position_m),
            SceneFeed::Relief(relief) => relief.contact(position_m),
        }
    }
}

impl SurfaceFeed for SceneFeed {
    type Surface = SceneFeed;

    fn current(&mut self) -> SurfaceView<'_, SceneFeed> {
        let (version, live, frame_age_ns) = match self {
            SceneFeed::Wall(wall) => {
                let view = wall.current();
                (view.version, view.live, view.frame_age_ns)
            }
            SceneFeed::Relief(relief) => {
                let view = relief.current();
                (view.version, view.live, view.frame_age_ns)
            }
        };
        SurfaceView {
            surface: self,
            version,
            live,
            frame_age_ns,
        }
    }

    fn recording(&self) -> FeedRecording {
        match self {
            SceneFeed::Wall(wall) => wall.recording(),
            SceneFeed::Relief(relief) => relief.recording(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wall_feed_renders_the_wall_and_is_never_live() {
        let wall = Plane::new(Vec3::new(0.0, 0.0, 0.3), Vec3::new(0.0, 0.0, -1.0)).unwrap();
        let mut feed = SceneFeed::Wall(FixedSurface(wall));
        let inside = Vec3::new(0.1, 0.1, 0.31);
        let view = feed.current();
        assert!(!view.live);
        assert_eq!(view.version, 0);
        assert_eq!(
            view.surface.contact(&inside).map(|c| c.depth_m),
            wall.contact(&inside).map(|c| c.depth_m)
        );
        assert!(feed.recording().initial.is_some());
    }
}
