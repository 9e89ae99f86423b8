//! The camera's newest frame, for `get_camera_image`.
//!
//! Camera frames travel on the bus in shared memory (`camera/frames`), and a frame port lives
//! on the thread that opened it. [`Grabber`] is that thread: started by the first picture a
//! registry is asked for, it sleeps until a call asks for "a frame taken after time t", then
//! takes the newest frame waiting on its port (the topic keeps only the latest), or waits for
//! the next one until the call's deadline, and copies its pixels out as RGB8. Between calls
//! it reads nothing: frames nobody asked for are overwritten on the bus, never copied. The
//! last frame copied is kept: when nothing newer waits on the port, it is still the newest
//! frame, and a call it is new enough for is answered with it at once rather than waiting up
//! to a frame period for the next.

use robotd_runtime::bus::{Bus, FrameSample, FrameSubscriber};
use robotd_topics::CAMERA_FRAMES;
use std::time::Duration;
use tokio::sync::{mpsc, oneshot};
use tokio::time::Instant;

/// How long the last frame copied may answer a call when nothing newer arrived (a camera
/// that stopped gives no picture rather than an old one), ns.
const LAST_FRAME_KEPT_NS: u64 = 1_000_000_000;
/// Calls waiting for a frame at once; one more is refused rather than queued without bound.
const WAITING_CALLS: usize = 16;

/// One frame, copied out of shared memory, RGB8.
#[derive(Clone)]
pub(crate) struct Frame {
    /// `width × height × 3` bytes, rows top to bottom.
    pub(crate) rgb: Vec<u8>,
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) frame_id: u64,
    /// Capture time, ns since the Unix epoch.
    pub(crate) timestamp_unix_ns: u64,
}

struct Ask {
    after_unix_ns: u64,
    deadline: Instant,
    reply: oneshot::Sender<Result<Frame, String>>,
}

/// The camera thread's door. Cheap to clone; the thread ends when the last clone is dropped.
#[derive(Clone)]
pub(crate) struct Grabber {
    asks: mpsc::Sender<Ask>,
}

impl Grabber {
    /// Starts the thread; its frame port opens there.
    pub(crate) fn start(bus: Bus) -> std::io::Result<Self> {
        let (asks, receiver) = mpsc::channel(WAITING_CALLS);
        robotd_runtime::bus::spawn_reader_thread("tools-camera", move || serve(bus, receiver))?;
        Ok(Self { asks })
    }

    /// Whether the thread still listens (it stops if its port cannot be opened).
    pub(crate) fn is_running(&self) -> bool {
        !self.asks.is_closed()
    }

    /// The newest frame captured after `after_unix_ns`, waiting up to `wait` for one.
    pub(crate) async fn frame_after(
        &self,
        after_unix_ns: u64,
        wait: Duration,
    ) -> Result<Frame, String> {
        let (reply, answer) = oneshot::channel();
        let ask = Ask {
            after_unix_ns,
            deadline: Instant::now() + wait,
            reply,
        };
        self.asks.try_send(ask).map_err(|e| match e {
            mpsc::error::TrySendError::Full(_) => format!(
                "{WAITING_CALLS} calls already wait for a camera frame; try again in a moment"
            ),
            mpsc::error::TrySendError::Closed(_) => "the camera reader has stopped".to_owned(),
        })?;
        answer
            .await
            .unwrap_or_else(|_| Err("the camera reader stopped before answering".to_owned()))
    }
}

async fn serve(bus: Bus, mut asks: mpsc::Receiver<Ask>) {
    let mut frames = match bus.frame_subscriber(&CAMERA_FRAMES) {
        Ok(frames) => frames,
        Err(error) => {
            let reason = format!("the camera topic could not be opened: {error}");
            tracing::warn!(%reason, "tools: no camera pictures");
            asks.close();
            while let Some(ask) = asks.recv().await {
                let _ = ask.reply.send(Err(reason.clone()));
            }
            return;
        }
    };
    let mut last: Option<Frame> = None;
    while let Some(ask) = asks.recv().await {
        if ask.reply.is_closed() {
            continue; // the call went away while it waited its turn
        }
        let result = grab(&mut frames, &mut last, ask.after_unix_ns, ask.deadline).await;
        let _ = ask.reply.send(result);
    }
}

/// The newest frame after `after`: what waits on the port, else the last one copied (`last`)
/// if it is new enough, else the next to arrive.
async fn grab(
    frames: &mut FrameSubscriber,
    last: &mut Option<Frame>,
    after_unix_ns: u64,
    deadline: Instant,
) -> Result<Frame, String> {
    let frame = grab_new(frames, last, after_unix_ns, deadline).await?;
    *last = Some(frame.clone());
    Ok(frame)
}

async fn grab_new(
    frames: &mut FrameSubscriber,
    last: &Option<Frame>,
    after_unix_ns: u64,
    deadline: Instant,
) -> Result<Frame, String> {
    let now = robotd_protocol::envelope::unix_now_ns();
    let mut newest: Option<Frame> = last
        .as_ref()
        .filter(|f| f.timestamp_unix_ns > after_unix_ns)
        .filter(|f| now.saturating_sub(f.timestamp_unix_ns) < LAST_FRAME_KEPT_NS)
        .cloned();
    let mut last_problem: Option<String> = None;
    loop {
        loop {
            match frames.try_recv() {
                Ok(Some(sample)) if sample.header().timestamp_unix_ns > after_unix_ns => {
                    match copy(&sample) {
                        Ok(frame) => newest = Some(frame),
                        Err(problem) => last_problem = Some(problem),
                    }
                }
                Ok(Some(_)) => {} // taken before the view asked for
                Ok(None) => break,
                Err(error) => return Err(format!("reading the camera failed: {error}")),
            }
        }
        if let Some(frame) = newest {
            return Ok(frame);
        }
        let next = tokio::time::timeout_at(deadline, frames.recv()).await;
        match next {
            Err(_) => {
                return Err(match last_problem {
                    Some(problem) => problem,
                    None => "no camera frame arrived in time; is the camera running?".to_owned(),
                })
            }
            Ok(Err(error)) => return Err(format!("reading the camera failed: {error}")),
            Ok(Ok(sample)) if sample.header().timestamp_unix_ns > after_unix_ns => {
                match copy(&sample) {
                    Ok(frame) => newest = Some(frame),
                    Err(problem) => last_problem = Some(problem),
                }
            }
            Ok(Ok(_)) => {}
        }
    }
}

/// The sample's pixels as RGB8 (BGR8 is swapped), or why they cannot be shown.
fn copy(sample: &FrameSample) -> Result<Frame, String> {
    let header = *sample.header();
    let (width, height) = (header.width as usize, header.height as usize);
    let bytes = width * height * 3;
    if width == 0 || height == 0 || header.channels != 3 || header.encoding > 1 {
        return Err(format!(
            "the camera sends frames this tool cannot show ({width}×{height}, {} channels, \
             encoding {})",
            header.channels, header.encoding
        ));
    }
    let pixels = sample.pixels();
    if pixels.len() < bytes {
        return Err(format!(
            "a camera frame is short: {} bytes for {width}×{height}",
            pixels.len()
        ));
    }
    let mut rgb = pixels[..bytes].to_vec();
    if header.encoding == 1 {
        for px in rgb.chunks_exact_mut(3) {
            px.swap(0, 2);
        }
    }
    Ok(Frame {
        rgb,
        width,
        height,
        frame_id: header.frame_id,
        timestamp_unix_ns: header.timestamp_unix_ns,
    })
}
