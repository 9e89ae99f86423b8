//! Event-driven wake-ups: an iceoryx2 event listener registered with tokio.
//!
//! iceoryx2's event listener on Linux is a Unix datagram socket. Registering its file
//! descriptor with tokio's reactor lets a task sleep until a notifier in any process fires,
//! with no polling thread and no sleep loop.

use super::{Bus, BusError, Ipc};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use std::os::fd::{AsRawFd, RawFd};
use std::sync::Arc;
use std::time::Duration;
use tokio::io::unix::AsyncFd;

/// The raw descriptor of a listener; owned by the listener, only borrowed for readiness.
struct ListenerFd(RawFd);

impl AsRawFd for ListenerFd {
    fn as_raw_fd(&self) -> RawFd {
        self.0
    }
}

/// An event service's handle, shared by this process's notifiers and listeners on it.
pub(crate) type EventFactory = iceoryx2::service::port_factory::event::PortFactory<Ipc>;

/// Wakes a task when the paired [`Notify`] fires.
pub(crate) struct Wake {
    // Field order matters: the registration must be dropped before the listener closes the fd.
    fd: AsyncFd<ListenerFd>,
    listener: PlainListener,
    name: String,
}

/// Fires the paired [`Wake`]s.
pub(crate) struct Notify {
    notifier: Notifier<Ipc>,
    _service: Arc<EventFactory>,
}

/// A listener for blocking waits outside tokio, with its service's shared handle.
pub(crate) struct PlainListener {
    listener: Listener<Ipc>,
    _service: Arc<EventFactory>,
}

impl std::ops::Deref for PlainListener {
    type Target = Listener<Ipc>;
    fn deref(&self) -> &Listener<Ipc> {
        &self.listener
    }
}

/// Name of the event that tells a topic's subscribers that data is waiting.
pub(crate) fn data_event(topic: &str) -> String {
    format!("{topic}/ready")
}

/// Name of the event that tells back-pressured publishers that a subscriber made room.
pub(crate) fn consumed_event(topic: &str) -> String {
    format!("{topic}/consumed")
}

/// Name of the event a new subscriber raises (a server attaching to its requests topic, say).
pub(crate) fn subscribed_event(topic: &str) -> String {
    format!("{topic}/subscribed")
}

/// Name of the event a new publisher raises so that subscribers connect to it.
pub(crate) fn joined_event(topic: &str) -> String {
    format!("{topic}/joined")
}

/// Limits of every event service robotd opens.
#[derive(Debug, Clone, Copy)]
pub(crate) struct EventLimits {
    pub(crate) max_notifiers: usize,
    pub(crate) max_listeners: usize,
    pub(crate) max_nodes: usize,
    pub(crate) event_id_max_value: usize,
}

pub(crate) const EVENT_LIMITS: EventLimits = EventLimits {
    max_notifiers: 256,
    max_listeners: 64,
    max_nodes: 256,
    // robotd only ever raises event id 0; a small id space keeps each drain cheap.
    event_id_max_value: 1,
};

/// The event service `name`: the handle this process already holds, or a new one.
pub(crate) fn event_service(bus: &Bus, name: &str) -> Result<Arc<EventFactory>, BusError> {
    bus.inner
        .events
        .get_or_open(name, || open_event_service(bus, name))
}

fn open_event_service(bus: &Bus, name: &str) -> Result<EventFactory, BusError> {
    bus.node()
        .service_builder(&bus.service_name(name)?)
        .event()
        .max_notifiers(EVENT_LIMITS.max_notifiers)
        .max_listeners(EVENT_LIMITS.max_listeners)
        .max_nodes(EVENT_LIMITS.max_nodes)
        .event_id_max_value(EVENT_LIMITS.event_id_max_value)
        .disable_notifier_created_event()
        .disable_notifier_dropped_event()
        .disable_notifier_dead_event()
        .open_or_create()
        .map_err(|e| BusError::Setup {
            what: format!("event service '{name}'"),
            reason: format!("{e:?}"),
        })
}

impl Wake {
    /// Creates a listener on event service `name`. Must be called inside a tokio runtime.
    pub(crate) fn new(bus: &Bus, name: &str) -> Result<Self, BusError> {
        let listener = listener(bus, name)?;
        if tokio::runtime::Handle::try_current().is_err() {
            return Err(BusError::Setup {
                what: format!("listener on '{name}'"),
                reason: "bus receivers must be created inside a tokio runtime".into(),
            });
        }
        // SAFETY: the descriptor is valid and stays open as long as `listener` lives; `fd` is
        // dropped first (field order), so the registration never outlives the descriptor.
        let fd = unsafe {
            let raw = listener.file_descriptor().native_handle();
            AsyncFd::register_with_interest(ListenerFd(raw), tokio::io::Interest::READABLE)
        }
        .map_err(|e| BusError::Wait {
            topic: name.to_owned(),
            source: e.into_parts().1,
        })?;
        Ok(Self {
            fd,
            listener,
            name: name.to_owned(),
        })
    }

    /// Makes the next notification wake [`sleep`](Self::sleep): consumes the notifications
    /// pending now. Call it after a check for data found nothing, then check again before
    /// sleeping; every waiting loop here is *check, rearm, check, sleep*.
    ///
    /// Why the second check and why here: iceoryx2 sends a notification's datagram only when
    /// the listener is not already marked notified, and only consuming resets that mark. A
    /// notifier that completes while a listener consumes leaves the mark set and its datagram
    /// read, perhaps before tokio's reactor saw it: no edge, and no later notifier sends one.
    /// A listener that then slept without consuming again slept until its timeout, and every
    /// wait after that did too (a busy RPC client fell to one reply per 250 ms liveness check).
    /// Consuming right before the last check clears that state, and whatever its notifiers
    /// announced is found by that check.
    ///
    /// A notifier racing the consume marks the listener again; so consuming repeats until a
    /// round finds no notification (bounded: under a flood the notifiers' data is there to
    /// be read anyway).
    pub(crate) fn rearm(&self) {
        for _ in 0..8 {
            discard_datagrams(self.fd.get_ref().0);
            match self.listener.try_wait(|_| {}) {
                Ok(0) => return,
                Ok(_) => {}
                Err(e) => {
                    tracing::warn!(event = %self.name, error = ?e, "consuming bus notifications failed");
                    return;
                }
            }
        }
    }

    /// Sleeps until a notification arrived since the last [`rearm`](Self::rearm) (or one
    /// before it that tokio already saw: a needless wake, never a missed one).
    pub(crate) async fn sleep(&self) -> Result<(), BusError> {
        let mut guard = self.fd.readable().await.map_err(|source| BusError::Wait {
            topic: self.name.clone(),
            source,
        })?;
        // Cleared now; a datagram that lands later raises a fresh edge.
        guard.clear_ready();
        Ok(())
    }

    /// Like [`sleep`](Self::sleep) with a deadline; `Ok(false)` when it passed.
    pub(crate) async fn sleep_timeout(&self, timeout: Duration) -> Result<bool, BusError> {
        match tokio::time::timeout(timeout, self.sleep()).await {
            Ok(result) => result.map(|()| true),
            Err(_) => Ok(false),
        }
    }
}

#[cfg(test)]
impl Wake {
    /// Reads the notification datagrams waiting now, as a racing consume can, without telling
    /// iceoryx2; returns how many there were.
    pub(crate) fn swallow_datagrams(&self) -> usize {
        let fd = self.fd.get_ref().0;
        let mut buffer = [0u8; 64];
        // SAFETY: `fd` is the listener's open socket and `buffer` is writable for its length.
        let mut read_one =
            || unsafe { libc::recv(fd, buffer.as_mut_ptr().cast(), 64, libc::MSG_DONTWAIT) >= 0 };
        (0..100).take_while(|_| read_one()).count()
    }
}

/// Reads and drops every datagram waiting on `fd`, without blocking. Notification datagrams
/// carry no data (iceoryx2 keeps the events in shared memory); a flood stops at 4,096.
///
/// iceoryx2 0.10 reads a single datagram per consume when the listener is not marked
/// notified, however many wait. The rest would pile up to the kernel's queue limit
/// (`net.unix.max_dgram_qlen`, 10 by default); then a notifier's send fails, iceoryx2 still
/// marks the listener notified, and no datagram raises an edge: a busy server went deaf that
/// way. So [`Wake::rearm`] empties the socket itself first.
fn discard_datagrams(fd: RawFd) {
    let mut buffer = [0u8; 64];
    for _ in 0..4_096 {
        // SAFETY: `fd` is the listener's open socket and `buffer` is writable for its length.
        let read = unsafe {
            libc::recv(
                fd,
                buffer.as_mut_ptr().cast(),
                buffer.len(),
                libc::MSG_DONTWAIT,
            )
        };
        if read < 0 && std::io::Error::last_os_error().kind() != std::io::ErrorKind::Interrupted {
            return; // empty (EAGAIN), or an error the next wait reports
        }
    }
}

/// A plain listener on event service `name`, for blocking waits outside tokio.
pub(crate) fn listener(bus: &Bus, name: &str) -> Result<PlainListener, BusError> {
    let service = event_service(bus, name)?;
    let listener = service
        .listener_builder()
        .create()
        .map_err(|e| BusError::Setup {
            what: format!("listener on '{name}'"),
            reason: format!("{e:?}"),
        })?;
    Ok(PlainListener {
        listener,
        _service: service,
    })
}

impl Notify {
    /// Creates a notifier on event service `name`.
    pub(crate) fn new(bus: &Bus, name: &str) -> Result<Self, BusError> {
        let service = event_service(bus, name)?;
        let notifier = service
            .notifier_builder()
            .create()
            .map_err(|e| BusError::Setup {
                what: format!("notifier on '{name}'"),
                reason: format!("{e:?}"),
            })?;
        Ok(Self {
            notifier,
            _service: service,
        })
    }

    /// Wakes every listener of the event service.
    pub(crate) fn notify(&self) {
        if let Err(e) = self.notifier.notify() {
            tracing::warn!(error = ?e, "bus notification failed");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::BusOptions;
    use std::os::unix::net::UnixDatagram;

    /// The filesystem path the socket `fd` is bound to.
    fn bound_path(fd: RawFd) -> std::path::PathBuf {
        // SAFETY: `address` is a zeroed sockaddr_un of the size passed; getsockname fills it.
        let mut address: libc::sockaddr_un = unsafe { std::mem::zeroed() };
        let mut length = std::mem::size_of::<libc::sockaddr_un>() as libc::socklen_t;
        let result = unsafe { libc::getsockname(fd, (&raw mut address).cast(), &raw mut length) };
        assert_eq!(
            result,
            0,
            "getsockname: {}",
            std::io::Error::last_os_error()
        );
        let path: Vec<u8> = address
            .sun_path
            .iter()
            .take_while(|c| **c != 0)
            .map(|c| *c as u8)
            .collect();
        std::path::PathBuf::from(
            <std::ffi::OsString as std::os::unix::ffi::OsStringExt>::from_vec(path),
        )
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_wake_up_leaves_no_notification_behind_and_the_next_one_still_wakes() {
        let namespace = format!("test-wake-{}", std::process::id());
        let bus = Bus::open(BusOptions::new(&namespace, "wake")).unwrap();
        let wake = Wake::new(&bus, "topic/ready").unwrap();
        let notify = Notify::new(&bus, "topic/ready").unwrap();
        // Leftover datagrams, as several notifiers racing one drain leave them.
        let fd = wake.fd.get_ref().0;
        let sender = UnixDatagram::unbound().unwrap();
        let path = bound_path(fd);
        for _ in 0..5 {
            sender.send_to(&[0], &path).unwrap();
        }
        notify.notify();
        tokio::time::timeout(Duration::from_secs(1), wake.sleep())
            .await
            .expect("woken")
            .unwrap();
        wake.rearm();
        assert_eq!(wake.swallow_datagrams(), 0, "left in the listener's socket");
        for round in 0..20 {
            notify.notify();
            tokio::time::timeout(Duration::from_secs(1), wake.sleep())
                .await
                .unwrap_or_else(|_| panic!("notification {round} did not wake the listener"))
                .unwrap();
            wake.rearm();
        }
    }

    /// The lost wake-up [`Wake::rearm`] prevents: a notification whose datagram another
    /// consume read before tokio's reactor saw it leaves the listener marked notified, so no
    /// later notifier sends a datagram. A current-thread runtime keeps the reactor from
    /// running in between, as a busy runtime does.
    #[tokio::test(flavor = "current_thread")]
    async fn a_notification_read_before_the_reactor_saw_it_does_not_silence_the_listener() {
        let namespace = format!("test-wake-lost-{}", std::process::id());
        let bus = Bus::open(BusOptions::new(&namespace, "wake")).unwrap();
        let wake = Wake::new(&bus, "topic/ready").unwrap();
        let notify = Notify::new(&bus, "topic/ready").unwrap();
        notify.notify();
        assert_eq!(wake.swallow_datagrams(), 1);
        // A waiting loop found no data: it rearms, checks again, sleeps.
        wake.rearm();
        notify.notify();
        tokio::time::timeout(Duration::from_secs(2), wake.sleep())
            .await
            .expect("the notification after the rearm wakes the listener")
            .unwrap();
    }
}
