//! The live updates around the finger: the region of interest under the thimble, its
//! re-matching and merge into the relief's segments ([`StereoRelief::update_around`]), and the
//! vision thread that runs them and publishes each rebuilt relief ([`spawn_live_updates`],
//! counted in [`LiveStats`]).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use videt_relief::region::merge_region;
use videt_relief::{build_from_scene, BuildReport, ReliefModel};
use videt_runtime::snapshot::{SnapshotReader, SnapshotWriter};
use videt_runtime::thimble::ThimbleState;
use videt_vision::{GrayView, LocalRegion};

use super::mapping::scene_segments;
use super::relief::{measure_patches, StereoRelief};

/// Whether the pixel nearest `(u, v)` lies in `rect = [x0, y0, x1, y1]` (`x0 <= x < x1`, the
/// same for `y`).
fn in_pixel_rect(u: f64, v: f64, rect: [f64; 4]) -> bool {
    let (x, y) = (u.round(), v.round());
    x >= rect[0] && x < rect[2] && y >= rect[1] && y < rect[3]
}

/// Pieces shorter than this in the image are dropped after a merge, pixels.
const MIN_PIECE_PX: f64 = 1.0;

/// What a live update did.
#[derive(Debug, Clone)]
pub struct RegionUpdate {
    /// The region re-matched, left image pixels `[u0, v0, u1, v1]`.
    pub roi_px: [f64; 4],
    /// Fresh 3D segments the local run gave.
    pub fresh_segments: usize,
    /// Segments the rebuild was given (old outside the region, fresh inside).
    pub merged_segments: usize,
    /// Time of the local pipeline run.
    pub match_time: Duration,
    /// Time of the merge of the fresh segments into the old ones.
    pub merge_time: Duration,
    /// Time of the rebuild.
    pub build_time: Duration,
    /// The builder's report.
    pub report: BuildReport,
}

impl RegionUpdate {
    /// Whole update time (match + merge + build).
    pub fn total_time(&self) -> Duration {
        self.match_time + self.merge_time + self.build_time
    }
}

impl StereoRelief {
    /// The left-image region of interest `(centre, velocity)` in pixels under a thimble at
    /// `position_m` moving at `velocity_m_s`, or `None` when the finger is not over the image.
    pub fn region_under(
        &self,
        position_m: [f64; 3],
        velocity_m_s: [f64; 3],
    ) -> Option<LocalRegion> {
        let map = &self.relief.scene_map;
        let [x, y, _] = position_m;
        let [u, v] = map.workspace_to_image(x, y);
        let [w, h] = map.image_size_px();
        if !(u.is_finite() && v.is_finite() && (0.0..w).contains(&u) && (0.0..h).contains(&v)) {
            return None;
        }
        // Pixels per metre along x and y (v grows with -y).
        let [u1, v1] = map.workspace_to_image(x + 1e-3, y + 1e-3);
        let (du, dv) = ((u1 - u) * 1e3, (v1 - v) * 1e3);
        let frame = self.live.update_period_s;
        let vel = [
            (velocity_m_s[0] * du * frame) as f32,
            (velocity_m_s[1] * dv * frame) as f32,
        ];
        Some(LocalRegion {
            centre_px: [u as f32, v as f32],
            size_px: self.live.roi_size_px,
            velocity_px_per_frame: if vel.iter().all(|c| c.is_finite()) {
                vel
            } else {
                [0.0, 0.0]
            },
        })
    }

    /// Re-matches the region under the thimble, merges it into the segments and rebuilds the
    /// relief. `Ok(None)` when the finger is not over the image (nothing to update).
    pub fn update_around(
        &mut self,
        position_m: [f64; 3],
        velocity_m_s: [f64; 3],
    ) -> Result<Option<(ReliefModel, RegionUpdate)>, String> {
        let Some(region) = self.region_under(position_m, velocity_m_s) else {
            return Ok(None);
        };
        let start = Instant::now();
        let roi = {
            let lv = GrayView::from_image(&self.pair.left).map_err(|e| e.to_string())?;
            let rv = GrayView::from_image(&self.pair.right).map_err(|e| e.to_string())?;
            let out = self
                .pipeline
                .run_local(&lv, &rv, Some(&self.geometry), &self.vision, &region)
                .map_err(|e| format!("local stereo pipeline: {e}"))?;
            let Some(windows) = out.local else {
                return Err("local stereo pipeline returned no region".into());
            };
            self.fresh.clear();
            scene_segments(&out.segments_3d, &mut self.fresh);
            measure_patches(
                self.patches.as_ref(),
                &mut self.patch_depth,
                (&lv, &rv),
                &self.geometry,
                out,
                &self.vision,
                Some(windows.roi),
            );
            scene_segments(&self.patch_depth.far_sides, &mut self.fresh);
            let r = windows.roi;
            [
                r.x as f64,
                r.y as f64,
                (r.x + r.width) as f64,
                (r.y + r.height) as f64,
            ]
        };
        let match_time = start.elapsed();
        let start = Instant::now();
        let mut merged = merge_region(&self.segments, &self.fresh, &self.camera, roi);
        let camera = self.camera;
        merged.retain(|s| match (camera.project(&s.a_m), camera.project(&s.b_m)) {
            (Some((a, _)), Some((b, _))) => (a[0] - b[0]).hypot(a[1] - b[1]) >= MIN_PIECE_PX,
            // Not projectable: the builder rejects it with its reason.
            _ => true,
        });
        // The support points: the old ones outside the region, the fresh ones inside.
        // (The points are grid nodes, whole pixels: rounded back, a node is in the region when
        // its column and row are.)
        self.points.retain(|p| {
            camera
                .project(p)
                .is_none_or(|([u, v], _)| !in_pixel_rect(u, v, roi))
        });
        self.points.extend_from_slice(&self.patch_depth.points);
        let merge_time = start.elapsed();
        let start = Instant::now();
        let (model, report) = build_from_scene(&merged, &self.points, &self.camera, &self.relief)
            .map_err(|e| e.to_string())?;
        let build_time = start.elapsed();
        let update = RegionUpdate {
            roi_px: roi,
            fresh_segments: self.fresh.len(),
            merged_segments: merged.len(),
            match_time,
            merge_time,
            build_time,
            report,
        };
        self.segments = merged;
        Ok(Some((model, update)))
    }
}

/// Counters of the live updates, shared between the vision thread and the status line.
#[derive(Debug, Default)]
pub struct LiveStats {
    updates: AtomicU64,
    failures: AtomicU64,
    keepalives: AtomicU64,
    full_refreshes: AtomicU64,
    last_update_us: AtomicU64,
    max_update_us: AtomicU64,
}

impl LiveStats {
    /// Live region updates published.
    pub fn updates(&self) -> u64 {
        self.updates.load(Ordering::Relaxed)
    }

    /// Updates that failed (the previous relief stays).
    pub fn failures(&self) -> u64 {
        self.failures.load(Ordering::Relaxed)
    }

    /// The unchanged relief re-published because the finger was away from the image.
    pub fn keepalives(&self) -> u64 {
        self.keepalives.load(Ordering::Relaxed)
    }

    /// Whole-image runs published.
    pub fn full_refreshes(&self) -> u64 {
        self.full_refreshes.load(Ordering::Relaxed)
    }

    /// Time of the last update and of the slowest one (match + rebuild), microseconds.
    pub fn update_time_us(&self) -> [u64; 2] {
        [
            self.last_update_us.load(Ordering::Relaxed),
            self.max_update_us.load(Ordering::Relaxed),
        ]
    }

    /// Records one published update that took `time`.
    pub fn record_update(&self, time: Duration) {
        let us = time.as_micros().min(u128::from(u64::MAX)) as u64;
        self.updates.fetch_add(1, Ordering::Relaxed);
        self.last_update_us.store(us, Ordering::Relaxed);
        self.max_update_us.fetch_max(us, Ordering::Relaxed);
    }

    /// For the status line: `relief: N live updates (last X ms, max Y ms)`.
    pub fn status_text(&self) -> String {
        let [last, max] = self.update_time_us();
        let failures = match self.failures() {
            0 => String::new(),
            n => format!(", {n} failed"),
        };
        format!(
            "  relief: {} live updates (last {:.1} ms, max {:.1} ms{failures}), {} whole-image",
            self.updates(),
            last as f64 * 1e-3,
            max as f64 * 1e-3,
            self.full_refreshes()
        )
    }
}

/// Start the vision thread (`videt-vision`) of a stereo relief: at the live update rate it
/// reads the newest thimble state, re-matches the region under the finger and publishes the
/// rebuilt relief (every `full_refresh_s` a whole-image run instead); when the finger is not
/// over the image it re-publishes the current relief every `keepalive_s` seconds (the relief
/// is not stale: vision is running). The thread runs SCHED_FIFO at `fifo_priority` when one is
/// given (`realtime.vision_priority`), else SCHED_OTHER. Runs until the process ends.
pub fn spawn_live_updates(
    mut relief: StereoRelief,
    initial: ReliefModel,
    mut writer: SnapshotWriter<ReliefModel>,
    mut thimble: SnapshotReader<ThimbleState>,
    stats: Arc<LiveStats>,
    keepalive_s: f64,
    fifo_priority: Option<u8>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    let period = Duration::from_secs_f64(relief.live.update_period_s);
    let keepalive = Duration::from_secs_f64(keepalive_s.clamp(1e-3, 3600.0));
    let full_refresh = Duration::from_secs_f64(relief.live.full_refresh_s.clamp(1e-3, 1e6));
    std::thread::Builder::new()
        .name("videt-vision".into())
        .spawn(move || {
            videt_runtime::rt::enter_vision_priority(fifo_priority);
            let mut current = initial;
            let mut next_tick = Instant::now() + period;
            let mut last_publish = Instant::now();
            let mut last_full = Instant::now();
            loop {
                let now = Instant::now();
                if next_tick > now {
                    std::thread::sleep(next_tick - now);
                }
                next_tick += period;
                if next_tick + period < Instant::now() {
                    // Fell behind (a slow update): do not try to catch up.
                    next_tick = Instant::now() + period;
                }
                if last_full.elapsed() >= full_refresh {
                    last_full = Instant::now();
                    match relief.refresh_full() {
                        Ok((model, _)) => {
                            current = model;
                            writer.publish_with(|slot| slot.clone_from(&current));
                            stats.full_refreshes.fetch_add(1, Ordering::Relaxed);
                            last_publish = Instant::now();
                        }
                        Err(e) => {
                            if stats.failures.fetch_add(1, Ordering::Relaxed) < 10 {
                                tracing::warn!("whole-image relief refresh failed (the previous relief stays): {e}");
                            }
                        }
                    }
                    continue;
                }
                let state = thimble.latest();
                let (version, position, velocity) = (
                    state.version,
                    state.value.position_m,
                    state.value.velocity_m_s,
                );
                // The stored pair stands for a frame captured as the update starts.
                let captured = videt_hal::Clock::now(&videt_runtime::rt::SystemClock);
                let update = if version == 0 {
                    Ok(None) // the control loop has not published a position yet
                } else {
                    relief.update_around(position, velocity)
                };
                match update {
                    Ok(Some((model, update))) => {
                        current = model;
                        writer.publish_captured_with(Some(captured), |slot| {
                            slot.clone_from(&current)
                        });
                        stats.record_update(update.total_time());
                        last_publish = Instant::now();
                    }
                    Ok(None) => {}
                    Err(e) => {
                        if stats.failures.fetch_add(1, Ordering::Relaxed) < 10 {
                            tracing::warn!(
                                "live relief update failed (the previous relief stays): {e}"
                            );
                        }
                    }
                }
                if last_publish.elapsed() >= keepalive {
                    writer.publish_with(|slot| slot.clone_from(&current));
                    stats.keepalives.fetch_add(1, Ordering::Relaxed);
                    last_publish = Instant::now();
                }
            }
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stereo_relief::relief::patch_params;
    use crate::stereo_relief::{LiveSettings, StereoPair};
    use videt_relief::SceneSegment3;

    #[test]
    fn patches_add_far_sides_and_points_and_an_update_renews_only_those_in_its_region() {
        let layout = videt_runtime::setup::relief_layout(&videt_config::Config::default());
        let (_, _, plain) = StereoRelief::build(
            StereoPair::demo().unwrap(),
            &layout,
            LiveSettings {
                patch_spacing_px: 0,
                ..LiveSettings::default()
            },
        )
        .unwrap();
        let (mut relief, model, initial) = StereoRelief::build(
            StereoPair::demo().unwrap(),
            &layout,
            LiveSettings {
                patch_spacing_px: 12,
                ..LiveSettings::default()
            },
        )
        .unwrap();
        assert!(relief.points().len() > 100, "{}", relief.points().len());
        // The far sides of occluding edges join the segments.
        assert!(
            initial.segments_3d > plain.segments_3d,
            "{} with patches, {} without",
            initial.segments_3d,
            plain.segments_3d
        );
        let before = relief.points().to_vec();
        let [cx, cy] = layout.centre_m;
        let (_, update) = relief
            .update_around([cx, cy, 0.3], [0.0; 3])
            .unwrap()
            .unwrap();
        let r = update.roi_px;
        let camera = relief.camera;
        let inside = |p: &[f64; 3]| {
            let ([u, v], _) = camera.project(p).unwrap();
            in_pixel_rect(u, v, r)
        };
        let split = |points: &[[f64; 3]]| {
            let (mut a, mut b): (Vec<_>, Vec<_>) = points.iter().copied().partition(inside);
            let key = |p: &[f64; 3]| p.map(f64::to_bits);
            a.sort_by_key(key);
            b.sort_by_key(key);
            (a, b)
        };
        let (in_before, out_before) = split(&before);
        let (in_after, out_after) = split(relief.points());
        assert!(
            !in_before.is_empty(),
            "no support point in the region {r:?}"
        );
        // Outside the region the points stay; inside, the same images give them again.
        assert_eq!(out_after, out_before);
        assert_eq!(in_after, in_before);
        // A whole-image run measures them all anew: the same relief.
        let (refreshed, _) = relief.refresh_full().unwrap();
        assert_eq!(refreshed, model);
        assert!(patch_params(&LiveSettings {
            patch_spacing_px: 3,
            ..LiveSettings::default()
        })
        .unwrap_err()
        .contains("[4, 64]"));
    }

    #[test]
    fn demo_pair_builds_a_relief_and_updates_it_around_the_finger() {
        let config = videt_config::Config::default();
        let layout = videt_runtime::setup::relief_layout(&config);
        let (mut relief, model, initial) = StereoRelief::build(
            StereoPair::demo().unwrap(),
            &layout,
            LiveSettings::default(),
        )
        .unwrap();
        assert!(initial.segments_3d > 50, "{}", initial.segments_3d);
        assert!(initial.report.constraints_kept > 30, "{:?}", initial.report);
        let back = model.back_plane_z_m();
        let front = back - layout.relief_depth_m;
        for v in model.vertices() {
            assert!(v[2] >= front - 1e-9 && v[2] <= back + 1e-9, "{v:?}");
        }
        let initial_segments = relief.segments().to_vec();
        // Over the centre of the area: an update; off the area: none.
        let [cx, cy] = layout.centre_m;
        let (updated, update) = relief
            .update_around([cx, cy, 0.3], [0.02, 0.0, 0.0])
            .unwrap()
            .unwrap();
        assert!(update.fresh_segments > 0, "{update:?}");
        assert!(update.roi_px[2] > update.roi_px[0] && update.roi_px[3] > update.roi_px[1]);
        // The region re-matched on the same images finds the whole-image run's segments there
        // again (same pixels, same depths), but for the few whose chains the local window cuts.
        let camera = relief.camera;
        let image_of = |s: &SceneSegment3| {
            let (a, za) = camera.project(&s.a_m).unwrap();
            let (b, zb) = camera.project(&s.b_m).unwrap();
            (a, b, za, zb)
        };
        let found_again = relief
            .fresh
            .iter()
            .filter(|f| {
                let (fa, fb, fza, fzb) = image_of(f);
                initial_segments.iter().any(|o| {
                    let (oa, ob, oza, ozb) = image_of(o);
                    let near = |p: [f64; 2], q: [f64; 2]| (p[0] - q[0]).hypot(p[1] - q[1]) < 1.0;
                    near(fa, oa)
                        && near(fb, ob)
                        && (fza / oza - 1.0).abs() < 0.02
                        && (fzb / ozb - 1.0).abs() < 0.02
                })
            })
            .count();
        assert!(
            found_again * 4 >= update.fresh_segments * 3,
            "{found_again} of {} fresh segments found again",
            update.fresh_segments
        );
        assert!(update.merged_segments >= initial_segments.len() - 5);
        assert_eq!(updated.back_plane_z_m(), model.back_plane_z_m());
        // Many updates along a sweep: pieces accumulate a little; a whole-image run resets them.
        for k in 0..40 {
            let x = cx - 0.07 + 0.0035 * k as f64;
            relief
                .update_around([x, cy + 0.03, 0.3], [0.05, 0.0, 0.0])
                .unwrap()
                .unwrap();
        }
        let (refreshed, _) = relief.refresh_full().unwrap();
        assert_eq!(relief.segments().len(), initial.segments_3d);
        assert_eq!(refreshed, model);
        assert!(relief
            .update_around([cx + 1.0, cy, 0.3], [0.0; 3])
            .unwrap()
            .is_none());
    }
}
