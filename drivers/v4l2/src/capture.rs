//! One capture session on a V4L2 device: open, check it captures video, negotiate the format
//! and size, stream buffers into the feed until something fails, and say what failed.

use crate::convert::{Decoder, PREFERRED_FORMATS};
use linuxvideo::format::{PixFormat, PixelFormat};
use linuxvideo::{BufType, CapabilityFlags, Device};
use std::io;
use std::os::fd::AsFd;
use std::path::Path;
use std::time::Duration;

/// A camera that sends nothing for this long counts as stalled (the session is restarted).
pub const STALL_TIMEOUT: Duration = Duration::from_secs(2);

/// What a session needs from its camera: the size to ask for, whether to go on, and where
/// decoded frames go.
pub trait FrameSink {
    /// The frame size the intrinsics are for.
    fn size(&self) -> (u32, u32);
    /// Whether anyone still wants frames (the camera was not dropped).
    fn wanted(&self) -> bool;
    /// One decoded RGB8 frame.
    fn frame(&self, rgb: Vec<u8>);
    /// One frame could not be used (the session goes on).
    fn bad_frame(&self, reason: String);
}

/// Streams from `path` into `sink` until an error; returns the reason the session ended.
pub fn run_session(path: &Path, sink: &dyn FrameSink) -> String {
    let shown = path.display();
    let (device, decoder, (width, height)) = match open(path, sink.size()) {
        Ok(opened) => opened,
        Err(reason) => return reason,
    };
    let mut stream = match device.into_stream() {
        Ok(stream) => stream,
        Err(e) => return format!("camera {shown}: cannot start streaming: {e}"),
    };
    tracing::info!(device = %shown, ?decoder, width, height, "camera streaming");
    while sink.wanted() {
        match wait_readable(&stream, STALL_TIMEOUT) {
            Ok(true) => {}
            Ok(false) => {
                return format!(
                    "camera {shown} sent no frame for {} s",
                    STALL_TIMEOUT.as_secs()
                )
            }
            Err(e) => return format!("camera {shown}: {e}"),
        }
        let decoded = stream.dequeue(|buffer| {
            if buffer.is_error() {
                return Ok(Err("the device flagged a frame as corrupt".to_owned()));
            }
            Ok(decoder.decode(&buffer, width, height))
        });
        match decoded {
            Ok(Ok(rgb)) => sink.frame(rgb),
            Ok(Err(reason)) => sink.bad_frame(format!("a frame of camera {shown}: {reason}")),
            Err(e) => return format!("camera {shown} stopped delivering frames: {e}"),
        }
    }
    format!("camera {shown} closed")
}

/// Opens `path` and negotiates a format at `size` as a capture session would, then closes it:
/// what the camera will give ("MJPG 640×480"), or why it cannot be used (for `robotd doctor`).
pub fn probe(path: &Path, size: (u32, u32)) -> Result<String, String> {
    let (capture, _, (width, height)) = open(path, size)?;
    Ok(format!(
        "{} {width}×{height}",
        capture.format().pixel_format()
    ))
}

/// Opens `path` as a capture device and negotiates a format robotd reads at `size`.
fn open(
    path: &Path,
    size: (u32, u32),
) -> Result<(linuxvideo::VideoCaptureDevice, Decoder, (u32, u32)), String> {
    let shown = path.display();
    let device = Device::open(path).map_err(|e| open_error(path, &e))?;
    let capabilities = device
        .capabilities()
        .map_err(|e| format!("camera {shown}: cannot read its capabilities: {e}"))?
        .device_capabilities();
    if !capabilities.contains(CapabilityFlags::VIDEO_CAPTURE) {
        return Err(format!(
            "{shown} is a V4L2 device that does not capture video (a UVC camera has a second, \
             metadata-only node: use the other /dev/video* of the camera)"
        ));
    }
    if !capabilities.contains(CapabilityFlags::STREAMING) {
        return Err(format!(
            "camera {shown} does not support streaming I/O, which robotd needs"
        ));
    }
    let offered = device
        .formats(BufType::VIDEO_CAPTURE)
        .map(|f| f.map(|f| f.pixel_format()))
        .collect::<io::Result<Vec<PixelFormat>>>()
        .map_err(|e| format!("camera {shown}: cannot list its formats: {e}"))?;
    let Some(format) = PREFERRED_FORMATS.into_iter().find(|f| offered.contains(f)) else {
        return Err(format!(
            "camera {shown} offers {offered:?}; robotd reads MJPG, JPEG or YUYV"
        ));
    };
    let (width, height) = size;
    let capture = device
        .video_capture(PixFormat::new(width, height, format))
        .map_err(|e| format!("camera {shown}: cannot set {format} at {width}×{height}: {e}"))?;
    let negotiated = capture.format();
    let got = (negotiated.width(), negotiated.height());
    if got != size {
        return Err(format!(
            "camera {shown} gives {}×{} {format} frames, not the {width}×{height} of its \
             intrinsics: set robot.widowx.camera_intrinsics for a size it offers (`v4l2-ctl \
             --list-formats-ext -d {shown}` lists them)",
            got.0, got.1
        ));
    }
    let Some(decoder) = Decoder::for_format(negotiated.pixel_format(), negotiated.bytes_per_line())
    else {
        return Err(format!(
            "camera {shown} switched to {} frames, which robotd does not read",
            negotiated.pixel_format()
        ));
    };
    Ok((capture, decoder, got))
}

/// A clear reason for a device that cannot be opened.
fn open_error(path: &Path, error: &io::Error) -> String {
    let shown = path.display();
    match error.kind() {
        io::ErrorKind::NotFound => {
            format!("camera {shown} not found (unplugged? `ls /dev/video*` lists the cameras)")
        }
        io::ErrorKind::PermissionDenied => format!(
            "no permission to open camera {shown}: add the user running robotd to the \
             'video' group"
        ),
        _ if error.raw_os_error() == Some(rustix::io::Errno::NOTTY.raw_os_error()) => {
            format!("{shown} is not a V4L2 device")
        }
        _ => format!("camera {shown} cannot be opened: {error}"),
    }
}

/// Waits until the stream has a frame to dequeue; false after `timeout` without one.
fn wait_readable(stream: &impl AsFd, timeout: Duration) -> io::Result<bool> {
    use rustix::event::{poll, PollFd, PollFlags, Timespec};
    let mut fds = [PollFd::new(stream, PollFlags::IN)];
    let timeout = Timespec {
        tv_sec: timeout.as_secs() as i64,
        tv_nsec: i64::from(timeout.subsec_nanos()),
    };
    loop {
        match poll(&mut fds, Some(&timeout)) {
            Ok(0) => return Ok(false),
            Ok(_) => {
                let revents = fds[0].revents();
                if revents.intersects(PollFlags::ERR | PollFlags::HUP | PollFlags::NVAL) {
                    return Err(io::Error::other(
                        "the device reported an error (unplugged?)",
                    ));
                }
                return Ok(true);
            }
            Err(rustix::io::Errno::INTR) => continue,
            Err(e) => return Err(e.into()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_that_is_not_a_camera_is_named_as_such() {
        let error = probe(Path::new("/dev/null"), (640, 480)).unwrap_err();
        assert!(error.contains("/dev/null is not a V4L2 device"), "{error}");
    }

    #[test]
    fn a_missing_device_says_it_is_not_found() {
        let error = probe(Path::new("/dev/video-robotd-missing"), (640, 480)).unwrap_err();
        assert!(error.contains("not found"), "{error}");
    }
}
