//! Camera frames in shared memory, written once and read in place.
//!
//! A frame is a fixed-size [`FrameSlot`] (header + 640×480×3 pixels, 921,600 bytes) that lives
//! in an iceoryx2 shared-memory segment. The producer loans a slot, renders or copies the image
//! straight into it and sends it; subscribers in any process get a [`FrameSample`] that points
//! at the same memory. No byte of the image is copied by the bus.
//!
//! ```no_run
//! use robotd_runtime::bus::{Bus, BusOptions, FrameTopic, Overflow};
//! const CAMERA: FrameTopic = FrameTopic::new("camera/frames", Overflow::latest_wins(2));
//! # async fn demo() -> Result<(), robotd_runtime::bus::BusError> {
//! let bus = Bus::open(BusOptions::new("demo", "camera"))?;
//! let publisher = bus.frame_publisher(&CAMERA)?;
//! let mut frame = publisher.loan()?;
//! frame.header_mut().frame_id = 1;
//! frame.pixels_mut().fill(128); // render into shared memory
//! frame.send()?;
//! # Ok(()) }
//! ```

use super::consumed::ConsumedWaiter;
use super::pubsub::Overflow;
use super::wake::{consumed_event, data_event, Notify, Wake};
use super::{Bus, BusError, Ipc};
use crate::metrics::{Direction, Metrics};
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::port::BackpressureInfo;
use iceoryx2::prelude::*;
use robotd_protocol::envelope::{unix_now_ns, TraceContext};
use std::collections::HashMap;

/// Frame width in pixels (the Ned2 wrist camera).
pub const FRAME_WIDTH: usize = 640;
/// Frame height in pixels.
pub const FRAME_HEIGHT: usize = 480;
/// Bytes per pixel (RGB8).
pub const FRAME_CHANNELS: usize = 3;
/// Bytes of pixel data in one frame.
pub const FRAME_BYTES: usize = FRAME_WIDTH * FRAME_HEIGHT * FRAME_CHANNELS;

const TRACEPARENT_BYTES: usize = 64;

/// Fixed-layout frame header stored in shared memory next to the pixels.
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("robotd.FrameHeader.v1")]
pub struct FrameHeader {
    /// Camera's frame counter.
    pub frame_id: u64,
    /// Capture time, nanoseconds since the Unix epoch.
    pub timestamp_unix_ns: u64,
    /// Image width in pixels (≤ [`FRAME_WIDTH`]).
    pub width: u32,
    /// Image height in pixels (≤ [`FRAME_HEIGHT`]).
    pub height: u32,
    /// Bytes per pixel (≤ [`FRAME_CHANNELS`]).
    pub channels: u32,
    /// 0 = RGB8, 1 = BGR8.
    pub encoding: u32,
    /// Camera pose at capture: x, y, z (m), roll, pitch, yaw (rad), robot base frame.
    pub camera_pose: [f64; 6],
    /// Publisher sequence number (set by the bus; gaps reveal replaced frames).
    pub seq: u64,
    traceparent_len: u32,
    traceparent: [u8; TRACEPARENT_BYTES],
}

impl Default for FrameHeader {
    fn default() -> Self {
        Self {
            frame_id: 0,
            timestamp_unix_ns: 0,
            width: FRAME_WIDTH as u32,
            height: FRAME_HEIGHT as u32,
            channels: FRAME_CHANNELS as u32,
            encoding: 0,
            camera_pose: [0.0; 6],
            seq: 0,
            traceparent_len: 0,
            traceparent: [0; TRACEPARENT_BYTES],
        }
    }
}

impl FrameHeader {
    /// The trace context of the span that published the frame.
    pub fn trace_context(&self) -> TraceContext {
        let len = (self.traceparent_len as usize).min(TRACEPARENT_BYTES);
        let traceparent = std::str::from_utf8(&self.traceparent[..len])
            .ok()
            .filter(|s| !s.is_empty())
            .map(str::to_owned);
        TraceContext {
            traceparent,
            tracestate: None,
        }
    }

    fn set_trace_context(&mut self, trace: &TraceContext) {
        let bytes = trace.traceparent.as_deref().unwrap_or("").as_bytes();
        if bytes.len() <= TRACEPARENT_BYTES {
            self.traceparent[..bytes.len()].copy_from_slice(bytes);
            self.traceparent_len = bytes.len() as u32;
        } else {
            self.traceparent_len = 0;
        }
    }
}

/// Type name of [`FrameSlot`] (the `type_name` attribute below; a test keeps them equal).
pub(crate) const FRAME_SLOT_TYPE: &str = "robotd.FrameSlot.v1";

/// Port and node limits of every frame topic.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FrameLimits {
    pub(crate) max_borrowed_samples: usize,
    pub(crate) max_publishers: usize,
    pub(crate) max_subscribers: usize,
    pub(crate) max_nodes: usize,
}

pub(crate) const FRAME_LIMITS: FrameLimits = FrameLimits {
    max_borrowed_samples: 2,
    max_publishers: 2,
    max_subscribers: 8,
    max_nodes: 16,
};

/// One frame in shared memory: header and pixels.
#[derive(ZeroCopySend)]
#[repr(C)]
#[type_name("robotd.FrameSlot.v1")]
pub struct FrameSlot {
    /// Metadata.
    pub header: FrameHeader,
    /// Row-major pixels, `height × width × channels` bytes used.
    pub pixels: [u8; FRAME_BYTES],
}

impl std::fmt::Debug for FrameSlot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrameSlot")
            .field("header", &self.header)
            .finish_non_exhaustive()
    }
}

/// A named stream of frames and its overflow policy (normally latest wins).
#[derive(Debug, Clone, Copy)]
pub struct FrameTopic {
    name: &'static str,
    overflow: Overflow,
}

impl FrameTopic {
    /// A frame topic called `name`.
    pub const fn new(name: &'static str, overflow: Overflow) -> Self {
        Self { name, overflow }
    }

    /// The topic's name.
    pub const fn name(&self) -> &'static str {
        self.name
    }

    /// The topic's overflow policy.
    pub const fn overflow(&self) -> Overflow {
        self.overflow
    }
}

type FrameFactory =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<Ipc, FrameSlot, ()>;

fn open_frames(bus: &Bus, topic: &FrameTopic) -> Result<FrameFactory, BusError> {
    bus.node()
        .service_builder(&bus.service_name(topic.name)?)
        .publish_subscribe::<FrameSlot>()
        .enable_safe_overflow(topic.overflow.is_latest_wins())
        .subscriber_max_buffer_size(topic.overflow.depth())
        .subscriber_max_borrowed_samples(FRAME_LIMITS.max_borrowed_samples)
        .history_size(0)
        .max_publishers(FRAME_LIMITS.max_publishers)
        .max_subscribers(FRAME_LIMITS.max_subscribers)
        .max_nodes(FRAME_LIMITS.max_nodes)
        .open_or_create()
        .map_err(|e| BusError::Setup {
            what: format!("frame topic '{}'", topic.name),
            reason: format!("{e:?} (overflow policy and depth must match in every process)"),
        })
}

/// Publishes frames into shared memory.
pub struct FramePublisher {
    port: iceoryx2::port::publisher::Publisher<Ipc, FrameSlot, ()>,
    notify: Notify,
    topic: FrameTopic,
    seq: std::sync::atomic::AtomicU64,
}

impl std::fmt::Debug for FramePublisher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FramePublisher")
            .field("topic", &self.topic.name)
            .finish()
    }
}

/// A frame slot loaned from shared memory; fill it, then [`send`](FrameLoan::send) it.
pub struct FrameLoan<'a> {
    sample: iceoryx2::sample_mut::SampleMut<Ipc, FrameSlot, ()>,
    publisher: &'a FramePublisher,
}

/// A received frame, read in place from shared memory.
pub struct FrameSample {
    sample: iceoryx2::sample::Sample<Ipc, FrameSlot, ()>,
}

impl std::fmt::Debug for FrameSample {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrameSample")
            .field("header", self.header())
            .finish()
    }
}

/// Receives frames.
pub struct FrameSubscriber {
    port: iceoryx2::port::subscriber::Subscriber<Ipc, FrameSlot, ()>,
    wake: Wake,
    consumed: Option<Notify>,
    topic: FrameTopic,
    last_seq: HashMap<u128, u64>,
}

impl std::fmt::Debug for FrameSubscriber {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrameSubscriber")
            .field("topic", &self.topic.name)
            .finish()
    }
}

impl Bus {
    /// Creates a frame publisher on `topic`.
    pub fn frame_publisher(&self, topic: &FrameTopic) -> Result<FramePublisher, BusError> {
        let service = open_frames(self, topic)?;
        let mut builder = service.publisher_builder().max_loaned_samples(2);
        if let Overflow::BackPressure { max_wait, .. } = topic.overflow {
            let waiter = ConsumedWaiter::new(self, &consumed_event(topic.name));
            builder = builder
                .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
                .set_backpressure_handler(move |info: &BackpressureInfo| {
                    waiter.on_full(info, max_wait)
                });
        }
        let port = builder.create().map_err(|e| BusError::Setup {
            what: format!("frame publisher on '{}'", topic.name),
            reason: format!("{e:?}"),
        })?;
        Ok(FramePublisher {
            port,
            notify: Notify::new(self, &data_event(topic.name))?,
            topic: *topic,
            seq: std::sync::atomic::AtomicU64::new(0),
        })
    }

    /// Creates a frame subscriber on `topic`. Must be called inside a tokio runtime.
    pub fn frame_subscriber(&self, topic: &FrameTopic) -> Result<FrameSubscriber, BusError> {
        let service = open_frames(self, topic)?;
        let port = service
            .subscriber_builder()
            .buffer_size(topic.overflow.depth())
            .create()
            .map_err(|e| BusError::Setup {
                what: format!("frame subscriber on '{}'", topic.name),
                reason: format!("{e:?}"),
            })?;
        // Connect to the publishers that exist now, so frames sent before our first receive
        // are delivered rather than refused (a later publisher connects at our next receive).
        port.update_connections().map_err(|e| BusError::Setup {
            what: format!("frame subscriber on '{}'", topic.name),
            reason: format!("cannot connect to the publishers: {e:?}"),
        })?;
        let consumed = match topic.overflow {
            Overflow::BackPressure { .. } => Some(Notify::new(self, &consumed_event(topic.name))?),
            Overflow::LatestWins { .. } => None,
        };
        Ok(FrameSubscriber {
            port,
            wake: Wake::new(self, &data_event(topic.name))?,
            consumed,
            topic: *topic,
            last_seq: HashMap::new(),
        })
    }
}

impl FramePublisher {
    /// Loans a frame slot in shared memory. Its header is reset; its pixels hold whatever the
    /// slot held before (write all of them).
    pub fn loan(&self) -> Result<FrameLoan<'_>, BusError> {
        let mut sample = self.port.loan_uninit().map_err(|e| BusError::Transfer {
            topic: self.topic.name.to_owned(),
            reason: format!(
                "cannot loan a frame slot: {e:?} (subscribers holding too many frames?)"
            ),
        })?;
        let slot = sample.payload_mut().as_mut_ptr();
        // SAFETY: `slot` points at a live, exclusively loaned `FrameSlot` in shared memory. The
        // header is written here; the pixel bytes live in an mmap'd segment that the kernel
        // zero-fills and that earlier frames wrote, so every byte is an initialised `u8` (which
        // has no invalid values).
        let sample = unsafe {
            std::ptr::addr_of_mut!((*slot).header).write(FrameHeader::default());
            sample.assume_init()
        };
        Ok(FrameLoan {
            sample,
            publisher: self,
        })
    }
}

impl FrameLoan<'_> {
    /// The frame's header, to fill in.
    pub fn header_mut(&mut self) -> &mut FrameHeader {
        &mut self.sample.payload_mut().header
    }

    /// The pixel buffer in shared memory, to render into.
    pub fn pixels_mut(&mut self) -> &mut [u8; FRAME_BYTES] {
        &mut self.sample.payload_mut().pixels
    }

    /// Publishes the frame; returns how many subscribers received it.
    pub fn send(mut self) -> Result<usize, BusError> {
        let publisher = self.publisher;
        let name = publisher.topic.name;
        let trace = crate::telemetry::current_trace_context();
        {
            let header = &mut self.sample.payload_mut().header;
            header.seq = publisher
                .seq
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            if header.timestamp_unix_ns == 0 {
                header.timestamp_unix_ns = unix_now_ns();
            }
            header.set_trace_context(&trace);
        }
        let started = std::time::Instant::now();
        let delivered = self.sample.send();
        // Wake the subscribers even when one of them was full: the others got the frame.
        publisher.notify.notify();
        let delivered = delivered.map_err(|e| match e {
            iceoryx2::port::SendError::UnableToDeliver => {
                Metrics::global().bus_dropped(name, "subscriber_full");
                BusError::Full {
                    topic: name.to_owned(),
                    waited_ms: started.elapsed().as_millis() as u64,
                }
            }
            other => BusError::Transfer {
                topic: name.to_owned(),
                reason: format!("{other:?}"),
            },
        })?;
        Metrics::global().bus_message(name, Direction::Sent);
        Ok(delivered)
    }
}

impl FrameSample {
    /// The frame's header.
    pub fn header(&self) -> &FrameHeader {
        &self.sample.payload().header
    }

    /// The used pixel bytes (`height × width × channels`), read in place.
    pub fn pixels(&self) -> &[u8] {
        let h = self.header();
        let used = (h.width as usize)
            .saturating_mul(h.height as usize)
            .saturating_mul(h.channels as usize)
            .min(FRAME_BYTES);
        &self.sample.payload().pixels[..used]
    }

    /// Address of the pixel memory (to show that readers share the producer's memory).
    pub fn pixels_ptr(&self) -> *const u8 {
        self.sample.payload().pixels.as_ptr()
    }
}

impl FrameSubscriber {
    /// Waits for the next frame.
    pub async fn recv(&mut self) -> Result<FrameSample, BusError> {
        loop {
            if let Some(frame) = self.try_recv()? {
                return Ok(frame);
            }
            self.wake.rearm();
            if let Some(frame) = self.try_recv()? {
                return Ok(frame);
            }
            self.wake.sleep().await?;
        }
    }

    /// Returns the next frame if one is waiting.
    pub fn try_recv(&mut self) -> Result<Option<FrameSample>, BusError> {
        let name = self.topic.name;
        let sample = self.port.receive().map_err(|e| BusError::Transfer {
            topic: name.to_owned(),
            reason: format!("{e:?}"),
        })?;
        let Some(sample) = sample else {
            return Ok(None);
        };
        if let Some(consumed) = &self.consumed {
            consumed.notify();
        }
        let metrics = Metrics::global();
        let header = &sample.payload().header;
        let publisher = sample.header().publisher_id().value();
        if let Some(previous) = self.last_seq.insert(publisher, header.seq) {
            let missed = header.seq.saturating_sub(previous.saturating_add(1));
            for _ in 0..missed.min(1_000) {
                metrics.bus_dropped(name, "overwritten_latest_wins");
            }
        }
        metrics.bus_message(name, Direction::Received);
        let latency_ns = unix_now_ns().saturating_sub(header.timestamp_unix_ns);
        metrics.bus_latency(name, latency_ns as f64 / 1e9);
        Ok(Some(FrameSample { sample }))
    }
}
