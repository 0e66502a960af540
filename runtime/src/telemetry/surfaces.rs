//! The surfaces a session log records: every surface the control thread could have rendered,
//! once per published version, and the taps through which a vision thread's publications reach
//! the telemetry writer.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, PoisonError};

use videt_control::surface::Plane;
use videt_control::Vec3;
use videt_relief::ReliefModel;

/// A surface as recorded.
#[derive(Debug, Clone, PartialEq)]
pub enum RecordedSurface {
    /// A flat wall (the twin's wall, the check wall).
    Plane(Plane),
    /// A bas-relief, rendered through the proxy with blended swaps.
    Relief(ReliefModel),
}

impl RecordedSurface {
    /// Append the encoded surface to `out` (see `docs/telemetry.md`).
    pub fn encode(&self, out: &mut Vec<u8>) {
        let put_f64 = |out: &mut Vec<u8>, v: f64| out.extend_from_slice(&v.to_le_bytes());
        match self {
            RecordedSurface::Plane(p) => {
                out.push(SURFACE_PLANE);
                out.extend_from_slice(&[0; 7]);
                for v in p.point_m().iter().chain(p.normal().iter()) {
                    put_f64(out, *v);
                }
            }
            RecordedSurface::Relief(m) => {
                out.push(SURFACE_RELIEF);
                out.extend_from_slice(&[0; 7]);
                for v in m.area_m() {
                    put_f64(out, v);
                }
                put_f64(out, m.back_plane_z_m());
                put_f64(out, m.grid_cells_per_triangle());
                out.extend_from_slice(&(m.vertices().len() as u32).to_le_bytes());
                out.extend_from_slice(&(m.triangles().len() as u32).to_le_bytes());
                for v in m.vertices().iter().flatten() {
                    put_f64(out, *v);
                }
                for i in m.triangles().iter().flatten() {
                    out.extend_from_slice(&i.to_le_bytes());
                }
            }
        }
    }

    /// Decode a surface encoded by [`RecordedSurface::encode`]; a malformed one is an error,
    /// never a panic.
    pub fn decode(bytes: &[u8]) -> Result<RecordedSurface, String> {
        let mut r = Reader { bytes, at: 0 };
        let kind = r.take(8)?[0];
        match kind {
            SURFACE_PLANE => {
                let v: [f64; 6] = core::array::from_fn(|_| 0.0);
                let mut v = v;
                for x in &mut v {
                    *x = r.f64()?;
                }
                let plane = Plane::new(Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]))
                    .ok_or("a plane with a zero or non-finite normal")?;
                Ok(RecordedSurface::Plane(plane))
            }
            SURFACE_RELIEF => {
                let area = [r.f64()?, r.f64()?, r.f64()?, r.f64()?];
                let back_z = r.f64()?;
                let cells = r.f64()?;
                let nv = r.u32()? as usize;
                let nt = r.u32()? as usize;
                if !(area.iter().all(|a| a.is_finite())
                    && area[2] > area[0]
                    && area[3] > area[1]
                    && back_z.is_finite())
                {
                    return Err(format!("relief area {area:?} / back plane {back_z}"));
                }
                if !(cells.is_finite() && cells > 0.0 && cells <= 64.0) {
                    return Err(format!("relief grid cells per triangle {cells}"));
                }
                if r.remaining() != nv * 24 + nt * 12 {
                    return Err(format!(
                        "relief of {nv} vertices and {nt} triangles in {} bytes",
                        r.remaining()
                    ));
                }
                let mut vertices = Vec::with_capacity(nv);
                for _ in 0..nv {
                    let v = [r.f64()?, r.f64()?, r.f64()?];
                    if !v.iter().all(|c| c.is_finite()) {
                        return Err("a relief vertex is not finite".into());
                    }
                    vertices.push(v);
                }
                let mut triangles = Vec::with_capacity(nt);
                for _ in 0..nt {
                    let t = [r.u32()?, r.u32()?, r.u32()?];
                    if t.iter().any(|&i| i as usize >= nv) {
                        return Err(format!("relief triangle {t:?} indexes past {nv} vertices"));
                    }
                    triangles.push(t);
                }
                Ok(RecordedSurface::Relief(ReliefModel::from_mesh_with_grid(
                    vertices, triangles, area, back_z, cells,
                )))
            }
            other => Err(format!("unknown surface kind {other}")),
        }
    }
}

const SURFACE_PLANE: u8 = 0;
const SURFACE_RELIEF: u8 = 1;

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or("surface record ends early")?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_le_bytes(self.take(8)?.try_into().expect("8")))
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4")))
    }
    fn remaining(&self) -> usize {
        self.bytes.len() - self.at
    }
}

/// A surface the session log records: the feeds' surfaces say what they are.
pub trait RecordSurface {
    /// The surface as recorded (`None`: this kind of surface is not recorded).
    fn recorded(&self) -> Option<RecordedSurface>;
}

impl RecordSurface for Plane {
    fn recorded(&self) -> Option<RecordedSurface> {
        Some(RecordedSurface::Plane(*self))
    }
}

impl RecordSurface for ReliefModel {
    fn recorded(&self) -> Option<RecordedSurface> {
        Some(RecordedSurface::Relief(self.clone()))
    }
}

/// A polygonal profile (the paper's experiments) is not recorded: a session on one is not
/// replayed.
impl<const CAP: usize> RecordSurface for videt_control::profile::Profile<CAP> {
    fn recorded(&self) -> Option<RecordedSurface> {
        None
    }
}

/// How a surface feed's surfaces reach the session log.
#[derive(Default, Clone)]
pub struct FeedRecording {
    /// The surface before any publication (version 0).
    pub initial: Option<RecordedSurface>,
    /// Where later versions are published (`None`: the surface never changes).
    pub tap: Option<Arc<SurfaceTap>>,
}

/// What a surface tap holds: versions published while recording (bounded), and before the
/// recording starts only the newest one.
#[derive(Default)]
struct TapState {
    recording: bool,
    newest_before: Option<(u64, Arc<RecordedSurface>)>,
    queue: VecDeque<(u64, Arc<RecordedSurface>)>,
    lost: Vec<u64>,
    /// The newest version published, recording or not (for a live view).
    newest: Option<(u64, Arc<RecordedSurface>)>,
}

/// Surfaces published by a vision thread, waiting for the telemetry writer. The vision thread
/// clones each published surface into it (on its own thread; the control thread never sees
/// it); the writer drains it. A writer that falls [`SurfaceTap::CAPACITY`] surfaces behind
/// loses the versions that do not fit, and the log says which.
#[derive(Default)]
pub struct SurfaceTap {
    state: Mutex<TapState>,
}

/// What the writer takes from a tap.
#[derive(Debug, Default)]
pub struct TapDrain {
    /// Published surfaces, in order of version.
    pub surfaces: Vec<(u64, Arc<RecordedSurface>)>,
    /// Versions that could not be kept.
    pub lost: Vec<u64>,
}

impl SurfaceTap {
    /// Surfaces kept waiting for the writer.
    pub const CAPACITY: usize = 64;

    /// A version was published (called on the publishing thread).
    pub fn published(&self, version: u64, surface: RecordedSurface) {
        let surface = Arc::new(surface);
        let mut s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        s.newest = Some((version, Arc::clone(&surface)));
        if !s.recording {
            s.newest_before = Some((version, surface));
        } else if s.queue.len() < Self::CAPACITY {
            s.queue.push_back((version, surface));
        } else {
            s.lost.push(version);
        }
    }

    /// The newest version published and its surface (shared, not copied), whether or not a
    /// log records it; `None` before the first publication.
    pub fn newest(&self) -> Option<(u64, Arc<RecordedSurface>)> {
        let s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        s.newest.clone()
    }

    /// Start recording: from now on every version is kept; the newest one published before
    /// is the first to be drained.
    pub fn start_recording(&self) {
        let mut s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        s.recording = true;
        if let Some(first) = s.newest_before.take() {
            s.queue.push_front(first);
        }
    }

    /// Take what is waiting.
    pub fn drain(&self) -> TapDrain {
        let mut s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        TapDrain {
            surfaces: s.queue.drain(..).collect(),
            lost: std::mem::take(&mut s.lost),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn relief() -> ReliefModel {
        let vertices = vec![
            [0.0, 0.0, 0.40],
            [0.2, 0.0, 0.41],
            [0.2, 0.1, 0.38],
            [0.0, 0.1, 0.4000000000000001],
            [0.1, 0.05, 0.36],
        ];
        let triangles = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
        ReliefModel::from_mesh_with_grid(vertices, triangles, [0.0, 0.0, 0.2, 0.1], 0.45, 1.7)
    }

    #[test]
    fn surfaces_round_trip_exactly_and_bad_bytes_are_errors() {
        let plane = Plane::new(Vec3::new(0.0, 0.1, 0.33), Vec3::new(0.0, 0.0, -1.0)).unwrap();
        for s in [
            RecordedSurface::Plane(plane),
            RecordedSurface::Relief(relief()),
        ] {
            let mut bytes = Vec::new();
            s.encode(&mut bytes);
            assert_eq!(RecordedSurface::decode(&bytes).unwrap(), s);
            for cut in [0, 7, 8, bytes.len() / 2, bytes.len() - 1] {
                assert!(
                    RecordedSurface::decode(&bytes[..cut]).is_err(),
                    "cut at {cut}"
                );
            }
        }
        let mut bytes = Vec::new();
        RecordedSurface::Relief(relief()).encode(&mut bytes);
        // A triangle index past the vertices.
        let last = bytes.len() - 4;
        bytes[last..].copy_from_slice(&99u32.to_le_bytes());
        let e = RecordedSurface::decode(&bytes).unwrap_err();
        assert!(e.contains("indexes past"), "{e}");
        bytes[0] = 7;
        assert!(RecordedSurface::decode(&bytes)
            .unwrap_err()
            .contains("kind 7"));
    }

    #[test]
    fn a_tap_keeps_the_newest_before_recording_then_every_version_up_to_its_capacity() {
        let tap = SurfaceTap::default();
        let plane =
            |z: f64| RecordedSurface::Plane(Plane::new(Vec3::new(0.0, 0.0, z), Vec3::z()).unwrap());
        assert!(tap.newest().is_none());
        tap.published(1, plane(1.0));
        tap.published(2, plane(2.0));
        assert!(tap.drain().surfaces.is_empty());
        assert_eq!(tap.newest().map(|n| n.0), Some(2));
        tap.start_recording();
        for v in 3..3 + SurfaceTap::CAPACITY as u64 + 2 {
            tap.published(v, plane(v as f64));
        }
        let d = tap.drain();
        let versions: Vec<u64> = d.surfaces.iter().map(|s| s.0).collect();
        assert_eq!(versions.first(), Some(&2));
        assert_eq!(versions.len(), SurfaceTap::CAPACITY);
        assert_eq!(d.lost, vec![66, 67, 68]);
        let (version, newest) = tap.newest().unwrap();
        assert_eq!(version, 68);
        assert_eq!(*newest, plane(68.0));
    }
}
