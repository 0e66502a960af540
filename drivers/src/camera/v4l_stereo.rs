//! V4L2 stereo capture (`v4l` feature): two devices, each negotiated to GREY or YUYV at the
//! requested size and frame rate, streamed through mmap buffers; frames are paired by their
//! driver timestamps within a tolerance (the older frame of an unmatched pair is dropped), and an
//! unplugged camera is reported as [`CameraError::Disconnected`].
//!
//! Both cameras start streaming back to back: two free-running cameras keep the phase they
//! start with, so starting one only after the other's first frame (a frame period later) would
//! leave their frames up to half a period apart for good.

use std::io;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use v4l::buffer::Type;
use v4l::io::mmap::Stream;
use v4l::io::traits::CaptureStream;
use v4l::video::Capture;
use v4l::{Device, Format, FourCC};
use videt_hal::{GrayFrame, MonoTime, RgbFrame, StereoCamera, StereoFrame};

use super::pairing::{decide, PairDecision};
use super::pixel::{from_yuyv, grey_from_y8};
use super::CameraError;

/// Requested capture settings.
#[derive(Debug, Clone, PartialEq)]
pub struct V4lStereoConfig {
    /// Left camera device (`/dev/video0`).
    pub left: PathBuf,
    /// Right camera device.
    pub right: PathBuf,
    /// Requested width, px.
    pub width: u32,
    /// Requested height, px.
    pub height: u32,
    /// Largest timestamp difference of a pair.
    pub pair_tolerance: Duration,
    /// Longest wait for a pair.
    pub timeout: Duration,
    /// mmap buffers per camera.
    pub buffers: u32,
    /// Requested frame rate, frames per second (the camera may choose the nearest it has).
    pub frame_rate_hz: u32,
    /// Ask for colour (YUYV) before grey: a camera that offers both then delivers colour for
    /// the colour under the finger. Otherwise grey (GREY) is asked first: less to copy.
    pub prefer_colour: bool,
}

/// Pixel format a camera was negotiated to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelFormat {
    /// 8-bit grey.
    Grey,
    /// YUV 4:2:2 (grey from Y, colour converted).
    Yuyv,
}

struct Camera {
    path: PathBuf,
    stream: Stream<'static>,
    format: PixelFormat,
    width: u32,
    height: u32,
    stride: usize,
    // Staging for the newest frame (reused).
    grey: GrayFrame,
    rgb: RgbFrame,
    stamp_ns: u64,
    // The newest frame's bytes as the driver delivered them (reused).
    raw: Vec<u8>,
    buffers: u32,
    // The device must outlive the stream's buffers.
    _device: Device,
}

impl core::fmt::Debug for Camera {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Camera")
            .field("path", &self.path)
            .field("format", &self.format)
            .field("width", &self.width)
            .field("height", &self.height)
            .finish()
    }
}

/// ENODEV, ENXIO, EIO: what a V4L2 device returns once it was unplugged.
fn is_unplug(e: &io::Error) -> bool {
    const EIO: i32 = 5;
    const ENXIO: i32 = 6;
    const ENODEV: i32 = 19;
    matches!(e.raw_os_error(), Some(ENODEV | ENXIO | EIO))
}

fn io_err(path: &Path, e: io::Error) -> CameraError {
    if is_unplug(&e) {
        CameraError::Disconnected {
            device: path.to_path_buf(),
        }
    } else {
        CameraError::Io {
            path: path.to_path_buf(),
            source: e,
        }
    }
}

impl Camera {
    fn open(path: &Path, cfg: &V4lStereoConfig) -> Result<Camera, CameraError> {
        let dev = Device::with_path(path).map_err(|e| io_err(path, e))?;
        let mut negotiated = None;
        let grey = (b"GREY", PixelFormat::Grey);
        let colour = (b"YUYV", PixelFormat::Yuyv);
        let order = if cfg.prefer_colour {
            [colour, grey]
        } else {
            [grey, colour]
        };
        for (fourcc, pf) in order {
            let want = Format::new(cfg.width, cfg.height, FourCC::new(fourcc));
            let got = dev.set_format(&want).map_err(|e| io_err(path, e))?;
            if got.fourcc == FourCC::new(fourcc) {
                negotiated = Some((got, pf));
                break;
            }
        }
        let Some((fmt, format)) = negotiated else {
            let offered = dev
                .enum_formats()
                .map(|v| {
                    v.iter()
                        .map(|d| d.fourcc.to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                })
                .unwrap_or_else(|e| format!("unknown ({e})"));
            return Err(CameraError::Format {
                device: path.to_path_buf(),
                offered,
            });
        };
        // A camera without frame-interval control keeps its own rate.
        let _ = dev.set_params(&v4l::video::capture::Parameters::with_fps(
            cfg.frame_rate_hz.max(1),
        ));
        let buffers = cfg.buffers.max(2);
        let mut stream =
            Stream::with_buffers(&dev, Type::VideoCapture, buffers).map_err(|e| io_err(path, e))?;
        stream.set_timeout(cfg.timeout);
        Ok(Camera {
            path: path.to_path_buf(),
            stream,
            format,
            width: fmt.width,
            height: fmt.height,
            stride: fmt.stride as usize,
            grey: GrayFrame::default(),
            rgb: RgbFrame::default(),
            stamp_ns: 0,
            raw: Vec::new(),
            buffers,
            _device: dev,
        })
    }

    /// Queue every buffer and start streaming (`VIDIOC_STREAMON`), without waiting for a frame.
    fn start(&mut self) -> Result<(), CameraError> {
        use v4l::io::traits::Stream as _;
        for index in 0..self.buffers as usize {
            CaptureStream::queue(&mut self.stream, index).map_err(|e| io_err(&self.path, e))?;
        }
        self.stream.start().map_err(|e| io_err(&self.path, e))
    }

    /// Wait for (and drop) the first frame of a started stream; later frames come from
    /// [`Camera::next`], which hands this buffer back to the driver first.
    fn skip_first(&mut self) -> Result<(), CameraError> {
        CaptureStream::dequeue(&mut self.stream)
            .map(|_| ())
            .map_err(|e| io_err(&self.path, e))
    }

    /// Dequeue the next frame: its bytes into the raw staging buffer (a copy, cheap next to
    /// a conversion: frames dropped while pairing are never converted) and its timestamp.
    fn next(&mut self) -> Result<(), CameraError> {
        let (buf, meta) = self.stream.next().map_err(|e| {
            if e.kind() == io::ErrorKind::TimedOut {
                CameraError::Disconnected {
                    device: self.path.clone(),
                }
            } else {
                io_err(&self.path, e)
            }
        })?;
        let used = (meta.bytesused as usize).min(buf.len());
        self.raw.clear();
        self.raw.extend_from_slice(&buf[..used]);
        let ts = meta.timestamp;
        self.stamp_ns = (ts.sec as u64).saturating_mul(1_000_000_000) + (ts.usec as u64) * 1_000;
        Ok(())
    }

    /// Convert the staged frame into the grey (and, from YUYV, colour) staging images.
    fn convert(&mut self, colour: bool) -> Result<(), CameraError> {
        let data = &self.raw;
        let r = match self.format {
            PixelFormat::Grey => {
                grey_from_y8(data, self.width, self.height, self.stride, &mut self.grey)
            }
            PixelFormat::Yuyv => from_yuyv(
                data,
                self.width,
                self.height,
                self.stride,
                &mut self.grey,
                colour.then_some(&mut self.rgb),
            ),
        };
        r.map_err(|e| CameraError::Io {
            path: self.path.clone(),
            source: io::Error::new(
                io::ErrorKind::InvalidData,
                format!("frame of {} bytes, {} needed", e.got, e.needed),
            ),
        })
    }
}

/// Two V4L2 cameras as a [`StereoCamera`].
#[derive(Debug)]
pub struct V4lStereo {
    left: Camera,
    right: Camera,
    tolerance_ns: u64,
    timeout: Duration,
}

impl V4lStereo {
    /// Open and negotiate both cameras. **non-RT**.
    pub fn open(cfg: &V4lStereoConfig) -> Result<V4lStereo, CameraError> {
        let mut left = Camera::open(&cfg.left, cfg)?;
        let mut right = Camera::open(&cfg.right, cfg)?;
        if (left.width, left.height) != (right.width, right.height) {
            return Err(CameraError::SizeMismatch {
                left_w: left.width,
                left_h: left.height,
                right_w: right.width,
                right_h: right.height,
            });
        }
        // Start both before waiting for either (see the module's documentation).
        left.start()?;
        right.start()?;
        left.skip_first()?;
        right.skip_first()?;
        Ok(V4lStereo {
            left,
            right,
            tolerance_ns: cfg.pair_tolerance.as_nanos() as u64,
            timeout: cfg.timeout,
        })
    }

    /// The negotiated formats (left, right).
    pub fn formats(&self) -> (PixelFormat, PixelFormat) {
        (self.left.format, self.right.format)
    }
}

impl videt_hal::ErrorType for V4lStereo {
    type Error = CameraError;
}

impl StereoCamera for V4lStereo {
    fn capture(&mut self, out: &mut StereoFrame) -> Result<(), CameraError> {
        let start = Instant::now();
        self.left.next()?;
        self.right.next()?;
        loop {
            match decide(self.left.stamp_ns, self.right.stamp_ns, self.tolerance_ns) {
                PairDecision::Pair => break,
                PairDecision::DropLeft => self.left.next()?,
                PairDecision::DropRight => self.right.next()?,
            }
            if start.elapsed() > self.timeout {
                return Err(CameraError::Timeout {
                    tolerance_ms: self.tolerance_ns / 1_000_000,
                    waited_ms: start.elapsed().as_millis() as u64,
                });
            }
        }
        self.left.convert(true)?;
        self.right.convert(false)?;
        core::mem::swap(&mut out.left, &mut self.left.grey);
        core::mem::swap(&mut out.right, &mut self.right.grey);
        if self.left.format == PixelFormat::Yuyv {
            let rgb = out.left_rgb.get_or_insert_with(Default::default);
            core::mem::swap(rgb, &mut self.left.rgb);
        } else {
            out.left_rgb = None;
        }
        out.left_stamp = MonoTime(self.left.stamp_ns);
        out.right_stamp = MonoTime(self.right.stamp_ns);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_device_is_reported_with_its_path() {
        let cfg = V4lStereoConfig {
            left: "/dev/no-such-video".into(),
            right: "/dev/no-such-video2".into(),
            width: 640,
            height: 480,
            pair_tolerance: Duration::from_millis(5),
            timeout: Duration::from_millis(500),
            buffers: 4,
            frame_rate_hz: 30,
            prefer_colour: false,
        };
        let e = V4lStereo::open(&cfg).unwrap_err();
        assert!(e.to_string().contains("/dev/no-such-video"), "{e}");
    }

    #[test]
    #[ignore = "needs two V4L2 cameras (VIDET_KIL_CAMERAS=LEFT,RIGHT, default /dev/video0,/dev/video2): runs in the kernel-in-the-loop guest"]
    fn captures_paired_frames_from_two_cameras() {
        let list = std::env::var("VIDET_KIL_CAMERAS").unwrap_or("/dev/video0,/dev/video2".into());
        let (left, right) = list.split_once(',').expect("LEFT,RIGHT");
        let cfg = V4lStereoConfig {
            left: left.into(),
            right: right.into(),
            width: 640,
            height: 480,
            // Two free-running cameras: more than half their frame period (30 fps).
            pair_tolerance: Duration::from_millis(20),
            timeout: Duration::from_secs(2),
            buffers: 4,
            frame_rate_hz: 30,
            prefer_colour: true,
        };
        let mut cam = V4lStereo::open(&cfg).unwrap();
        let mut f = StereoFrame::default();
        let mut last = 0;
        for _ in 0..5 {
            cam.capture(&mut f).unwrap();
            let offset_ns = f.left_stamp.0.abs_diff(f.right_stamp.0);
            eprintln!("pair offset {:.2} ms", offset_ns as f64 / 1e6);
            assert!(offset_ns <= 20_000_000);
            assert!(f.left_stamp.0 > last, "a new pair each time");
            last = f.left_stamp.0;
            for frame in [&f.left, &f.right] {
                assert_eq!((frame.width, frame.height), (640, 480));
                assert_eq!(frame.data.len(), 640 * 480);
            }
            let rgb = f.left_rgb.as_ref().expect("colour from a YUYV camera");
            assert_eq!(rgb.data.len(), 3 * 640 * 480);
        }
    }
}
