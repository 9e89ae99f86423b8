//! Event-driven wake-ups: an iceoryx2 event listener registered with tokio.
//!
//! iceoryx2's event listener on Linux is a Unix datagram socket. Registering its file
//! descriptor with tokio's reactor lets a task sleep until a notifier in any process fires,
//! with no polling thread and no sleep loop.
//!
//! A notifier in the *same* process wakes that process's sleepers directly, through a
//! `tokio::sync::Notify` its ports on the event service share, and sends datagrams only when
//! a listener elsewhere (another process, or a blocking listener here) needs one. A sleeper in
//! this process then does not wait for the kernel: on a multi-threaded runtime the woken task
//! runs next on the notifier's own worker thread, where the datagram would have woken the
//! reactor on another CPU first, and no other worker is woken for nothing. An in-process tool
//! call's round trip to an actor (MCP call → workspace model → reply) stays on one CPU.

use super::{Bus, BusError, Ipc};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use std::os::fd::{AsRawFd, RawFd};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll, Waker};
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
pub(crate) struct EventService {
    factory: iceoryx2::service::port_factory::event::PortFactory<Ipc>,
    /// Wakes this process's [`Wake`]s on the service that are asleep, without the kernel.
    in_process: tokio::sync::Notify,
    /// In-process notifications so far, counted before each wakes anyone: a [`Wake`] that
    /// saw the count change since its rearm does not sleep.
    notifications: AtomicU64,
    /// This process's [`Wake`]s on the service. When they are all of its listeners, a
    /// notifier sends no datagram.
    wakes: AtomicUsize,
}

impl EventService {
    /// Whether some listener of the service is not one of this process's [`Wake`]s (it is in
    /// another process, or a blocking listener here) and so needs the datagram.
    fn has_listeners_elsewhere(&self) -> bool {
        let wakes = self.wakes.load(Ordering::SeqCst);
        wakes == 0 || self.factory.dynamic_config().number_of_listeners() > wakes
    }
}

impl std::ops::Deref for EventService {
    type Target = iceoryx2::service::port_factory::event::PortFactory<Ipc>;
    fn deref(&self) -> &Self::Target {
        &self.factory
    }
}

/// Wakes a task when the paired [`Notify`] fires.
pub(crate) struct Wake {
    // Field order matters: the registration must be dropped before the listener closes the fd.
    fd: AsyncFd<ListenerFd>,
    listener: PlainListener,
    name: String,
    /// The service's in-process notification count at the last rearm.
    seen: AtomicU64,
}

/// Fires the paired [`Wake`]s.
pub(crate) struct Notify {
    notifier: Notifier<Ipc>,
    service: Arc<EventService>,
}

/// A listener for blocking waits outside tokio, with its service's shared handle.
pub(crate) struct PlainListener {
    listener: Listener<Ipc>,
    service: Arc<EventService>,
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
pub(crate) fn event_service(bus: &Bus, name: &str) -> Result<Arc<EventService>, BusError> {
    bus.inner
        .events
        .get_or_open(name, || open_event_service(bus, name))
}

fn open_event_service(bus: &Bus, name: &str) -> Result<EventService, BusError> {
    let factory = bus
        .node()
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
        })?;
    Ok(EventService {
        factory,
        in_process: tokio::sync::Notify::new(),
        notifications: AtomicU64::new(0),
        wakes: AtomicUsize::new(0),
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
        // Counted once its listener exists (uncounted, a listener only costs a datagram).
        listener.service.wakes.fetch_add(1, Ordering::SeqCst);
        Ok(Self {
            fd,
            listener,
            name: name.to_owned(),
            seen: AtomicU64::new(0),
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
    ///
    /// Rearming also forgets a readiness tokio's reactor recorded for a datagram that the
    /// in-process wake-up made needless, so the next sleep does not return at once for it.
    pub(crate) fn rearm(&self) {
        let service = &self.listener.service;
        self.seen.store(
            service.notifications.load(Ordering::SeqCst),
            Ordering::SeqCst,
        );
        self.forget_readiness();
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

    /// Clears the readiness tokio holds for the listener's socket, if any. Called before the
    /// socket is emptied, so a datagram landing after this raises a fresh edge.
    fn forget_readiness(&self) {
        let mut context = Context::from_waker(Waker::noop());
        if let Poll::Ready(Ok(mut guard)) = self.fd.poll_read_ready(&mut context) {
            guard.clear_ready();
        }
    }

    /// Sleeps until a notification arrived since the last [`rearm`](Self::rearm) (or one
    /// before it that tokio already saw: a needless wake, never a missed one). A notifier in
    /// this process wakes it directly; one elsewhere through the listener's socket.
    pub(crate) async fn sleep(&self) -> Result<(), BusError> {
        let service = &self.listener.service;
        let in_process = service.in_process.notified();
        tokio::pin!(in_process);
        // Listening before looking: a notifier that counts after this look wakes `in_process`.
        in_process.as_mut().enable();
        let notifications = service.notifications.load(Ordering::SeqCst);
        if notifications != self.seen.swap(notifications, Ordering::SeqCst) {
            return Ok(()); // notified in this process since the rearm
        }
        tokio::select! {
            biased;
            readable = self.fd.readable() => {
                let mut guard = readable.map_err(|source| BusError::Wait {
                    topic: self.name.clone(),
                    source,
                })?;
                // Cleared now; a datagram that lands later raises a fresh edge.
                guard.clear_ready();
            }
            // The datagram of this notification is read by the next rearm.
            () = in_process => {}
        }
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

impl Drop for Wake {
    fn drop(&mut self) {
        // Uncounted before its listener goes (see `Wake::new`).
        self.listener.service.wakes.fetch_sub(1, Ordering::SeqCst);
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
    Ok(PlainListener { listener, service })
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
        Ok(Self { notifier, service })
    }

    /// Wakes every listener of the event service: those of other processes through their
    /// sockets, this process's sleeping [`Wake`]s directly as well.
    pub(crate) fn notify(&self) {
        self.service.notifications.fetch_add(1, Ordering::SeqCst);
        if self.service.has_listeners_elsewhere() {
            if let Err(e) = self.notifier.notify() {
                tracing::warn!(error = ?e, "bus notification failed");
            }
        }
        self.service.in_process.notify_waiters();
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
        // Another node, as another process is: it wakes the listener through its socket only.
        let other = Bus::open(BusOptions::new(&namespace, "notifier")).unwrap();
        let notify = Notify::new(&other, "topic/ready").unwrap();
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
        let other = Bus::open(BusOptions::new(&namespace, "notifier")).unwrap();
        let notify = Notify::new(&other, "topic/ready").unwrap();
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

    /// A sleeper in a task woken by a notifier in the same process: `sleeper` runs the
    /// rearm-then-sleep of a waiting loop on `wake`.
    async fn sleeping(wake: &Arc<Wake>) -> tokio::task::JoinHandle<Result<(), BusError>> {
        wake.rearm();
        let sleeper = tokio::spawn({
            let wake = Arc::clone(wake);
            async move { wake.sleep().await }
        });
        // Let the sleeper start sleeping.
        tokio::task::yield_now().await;
        assert!(!sleeper.is_finished());
        sleeper
    }

    /// When every listener of the event service is a [`Wake`] of this process, a notifier
    /// wakes them directly and sends no datagram at all.
    #[tokio::test(flavor = "current_thread")]
    async fn a_notifier_in_the_same_process_wakes_the_sleeper_without_a_datagram() {
        let namespace = format!("test-wake-local-{}", std::process::id());
        let bus = Bus::open(BusOptions::new(&namespace, "wake")).unwrap();
        let wake = Arc::new(Wake::new(&bus, "topic/ready").unwrap());
        let notify = Notify::new(&bus, "topic/ready").unwrap();
        let sleeper = sleeping(&wake).await;
        notify.notify();
        assert_eq!(wake.swallow_datagrams(), 0, "a datagram nobody needed");
        tokio::time::timeout(Duration::from_secs(2), sleeper)
            .await
            .expect("woken in-process")
            .unwrap()
            .unwrap();
    }

    /// A notification that comes after the waiting loop's last check but before its sleep
    /// starts listening is not lost: the sleep sees the count moved and returns at once.
    #[tokio::test(flavor = "current_thread")]
    async fn an_in_process_notification_between_rearm_and_sleep_is_not_lost() {
        let namespace = format!("test-wake-gap-{}", std::process::id());
        let bus = Bus::open(BusOptions::new(&namespace, "wake")).unwrap();
        let wake = Wake::new(&bus, "topic/ready").unwrap();
        let notify = Notify::new(&bus, "topic/ready").unwrap();
        wake.rearm();
        notify.notify();
        tokio::time::timeout(Duration::from_secs(2), wake.sleep())
            .await
            .expect("the notification before the sleep wakes it")
            .unwrap();
    }

    /// With a listener in another node (as in another process) beside this process's own, a
    /// notifier here still sends the datagrams, and both are woken.
    #[tokio::test(flavor = "current_thread")]
    async fn a_listener_elsewhere_still_gets_its_datagram() {
        let namespace = format!("test-wake-mixed-{}", std::process::id());
        let bus = Bus::open(BusOptions::new(&namespace, "wake")).unwrap();
        let other = Bus::open(BusOptions::new(&namespace, "elsewhere")).unwrap();
        let local = Arc::new(Wake::new(&bus, "topic/ready").unwrap());
        let remote = Arc::new(Wake::new(&other, "topic/ready").unwrap());
        let notify = Notify::new(&bus, "topic/ready").unwrap();
        let local_sleeper = sleeping(&local).await;
        let remote_sleeper = sleeping(&remote).await;
        notify.notify();
        for sleeper in [local_sleeper, remote_sleeper] {
            tokio::time::timeout(Duration::from_secs(2), sleeper)
                .await
                .expect("both listeners woken")
                .unwrap()
                .unwrap();
        }
    }

    /// After an in-process wake-up, the datagram the same notification sent to a listener
    /// elsewhere is also in this listener's socket; the next rearm reads it and forgets the
    /// readiness tokio recorded for it, so the next sleep sleeps instead of returning at once.
    /// (Paused clock: the timeout fires only once the runtime has nothing else to do, its
    /// reactor polled.)
    #[tokio::test(flavor = "current_thread", start_paused = true)]
    async fn a_rearm_after_an_in_process_wake_up_leaves_no_stale_readiness() {
        let namespace = format!("test-wake-stale-{}", std::process::id());
        let bus = Bus::open(BusOptions::new(&namespace, "wake")).unwrap();
        let other = Bus::open(BusOptions::new(&namespace, "elsewhere")).unwrap();
        let _elsewhere = Wake::new(&other, "topic/ready").unwrap();
        let wake = Arc::new(Wake::new(&bus, "topic/ready").unwrap());
        let notify = Notify::new(&bus, "topic/ready").unwrap();
        let sleeper = sleeping(&wake).await;
        notify.notify();
        sleeper.await.unwrap().unwrap();
        // The reactor sees the datagram's edge before the rearm.
        tokio::task::yield_now().await;
        wake.rearm();
        assert_eq!(wake.swallow_datagrams(), 0);
        let slept = tokio::time::timeout(Duration::from_secs(1), wake.sleep()).await;
        assert!(
            slept.is_err(),
            "the sleep returned for a notification already read"
        );
    }
}
