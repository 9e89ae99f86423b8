//! Session places: how many MCP sessions may be open, who holds them, and when each one ends
//! by itself.
//!
//! One [`SessionPlaces`] counts the sessions of both transports (legacy SSE and streamable
//! HTTP) against three rules:
//!
//! - **The cap** ([`PlaceLimits::max_sessions`]): a new session beyond it is refused (503).
//! - **A client's share** ([`PlaceLimits::per_client`]): one client (its address and token,
//!   [`SessionOwner`]) holds at most this many places, so one client cannot take them all. A
//!   client at its share that opens another session gives up its oldest session that never
//!   made a call (a handshake it abandoned); one whose sessions all made calls is refused.
//! - **Expiry**: a session that made no call (no request after `initialize`) ends
//!   [`PlaceLimits::unused_timeout`] after it opened, and a streamable-HTTP session ends
//!   [`PlaceLimits::idle_timeout`] after its last request. An SSE session that made a call
//!   ends when its stream closes.
//!
//! Expiry falls on whole seconds of one clock (a session ends between N and N + 1 s after
//! its last activity): sessions that went quiet within the same second end together, which
//! frees their places at once and wakes the server once for all of them. A refusal knows
//! when the next place frees by itself ([`Refusal::retry_after`]): the earliest expiry among
//! the sessions that could make room, or none when no session expires by itself (the 503
//! then carries no `Retry-After`).
//!
//! A place is taken in two steps: [`SessionPlaces::admit`] reserves it (so a burst of new
//! sessions cannot pass the cap), [`Ticket::open`] names it once the transport made the
//! session. The transport closes a session when [`SessionPlaces::closed`] resolves (it expired
//! or was given up) and gives the place back with [`SessionPlaces::release`] when it closed.
//! Times are tokio's, so the rules can be tested on a paused clock.

use crate::owner::SessionOwner;
use std::collections::HashMap;
use std::future::Future;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use tokio::time::Instant;
use tokio_util::sync::CancellationToken;

/// The rules of [`SessionPlaces`] (from `[mcp]`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct PlaceLimits {
    /// Most sessions open at once (`mcp.max_sessions`).
    pub(crate) max_sessions: usize,
    /// Most sessions of one client (`mcp.max_sessions_per_client`).
    pub(crate) per_client: usize,
    /// A session that made no call ends this long after it opened.
    pub(crate) unused_timeout: Duration,
    /// A streamable-HTTP session ends this long after its last request.
    pub(crate) idle_timeout: Duration,
}

/// Which transport a session is served by.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Transport {
    /// Legacy HTTP+SSE: lives while its stream is open.
    Sse,
    /// Streamable HTTP: lives until `DELETE /mcp` or its idle timeout.
    Streamable,
}

/// One open session.
struct Place {
    owner: SessionOwner,
    transport: Transport,
    opened: Instant,
    last_active: Instant,
    /// It made a request after `initialize`.
    used: bool,
    /// Fired when the session must close (expired or given up) or closed.
    closing: CancellationToken,
}

#[derive(Default)]
struct State {
    places: HashMap<String, Place>,
    /// Places admitted but not yet opened, by client.
    reserved: HashMap<SessionOwner, usize>,
}

impl State {
    fn reserved_total(&self) -> usize {
        self.reserved.values().sum()
    }

    fn held_by(&self, owner: &SessionOwner) -> usize {
        let open = self.places.values().filter(|p| &p.owner == owner).count();
        open + self.reserved.get(owner).copied().unwrap_or(0)
    }
}

/// Why a new session was refused, and when a place frees by itself.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Refusal {
    /// The setting whose limit was reached (`mcp.max_sessions` or
    /// `mcp.max_sessions_per_client`).
    pub(crate) setting: &'static str,
    /// Sessions held (all, or the client's).
    pub(crate) held: usize,
    /// The limit.
    pub(crate) limit: usize,
    /// Time until the first of those sessions ends by itself; `None` when none will.
    pub(crate) retry_after: Option<Duration>,
}

impl Refusal {
    /// `Retry-After` in whole seconds, rounded up (never 0: a place is not free yet).
    pub(crate) fn retry_after_s(&self) -> Option<u64> {
        self.retry_after
            .map(|d| d.as_secs() + u64::from(d.subsec_nanos() > 0))
            .map(|s| s.max(1))
    }
}

/// The session places of both transports (see the module documentation).
pub(crate) struct SessionPlaces {
    limits: PlaceLimits,
    state: Mutex<State>,
    /// The origin of the whole seconds expiry falls on.
    epoch: Instant,
}

impl std::fmt::Debug for SessionPlaces {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SessionPlaces")
            .field("limits", &self.limits)
            .field("open", &self.lock().places.len())
            .finish()
    }
}

/// A place reserved for a session being opened; dropped unopened, it is given back.
pub(crate) struct Ticket {
    places: Arc<SessionPlaces>,
    owner: SessionOwner,
    pending: bool,
}

impl Ticket {
    /// The session `id` opened on `transport` takes the reserved place.
    pub(crate) fn open(mut self, id: &str, transport: Transport) {
        let now = Instant::now();
        let mut state = self.places.lock();
        unreserve(&mut state, &self.owner);
        self.pending = false;
        state.places.insert(
            id.to_owned(),
            Place {
                owner: self.owner,
                transport,
                opened: now,
                last_active: now,
                used: false,
                closing: CancellationToken::new(),
            },
        );
    }
}

impl Drop for Ticket {
    fn drop(&mut self) {
        if self.pending {
            unreserve(&mut self.places.lock(), &self.owner);
        }
    }
}

fn unreserve(state: &mut State, owner: &SessionOwner) {
    if let Some(n) = state.reserved.get_mut(owner) {
        *n -= 1;
        if *n == 0 {
            state.reserved.remove(owner);
        }
    }
}

impl SessionPlaces {
    /// Places under `limits`.
    pub(crate) fn new(limits: PlaceLimits) -> Arc<Self> {
        Arc::new(Self {
            limits,
            state: Mutex::default(),
            epoch: Instant::now(),
        })
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// When session `place` ends by itself, if it does: on the next whole second.
    fn deadline(&self, place: &Place) -> Option<Instant> {
        let unused = (!place.used).then(|| place.opened + self.limits.unused_timeout);
        let idle = (place.transport == Transport::Streamable)
            .then(|| place.last_active + self.limits.idle_timeout);
        let due = match (unused, idle) {
            (Some(a), Some(b)) => a.min(b),
            (a, b) => a.or(b)?,
        };
        let nanos = due.saturating_duration_since(self.epoch).as_nanos();
        let seconds = u64::try_from(nanos.div_ceil(1_000_000_000)).unwrap_or(u64::MAX / 2);
        Some(self.epoch + Duration::from_secs(seconds))
    }

    /// Time from `now` until the first of `places` ends by itself.
    fn first_expiry<'a>(
        &self,
        places: impl Iterator<Item = &'a Place>,
        now: Instant,
    ) -> Option<Duration> {
        places
            .filter_map(|p| self.deadline(p))
            .min()
            .map(|d| d.saturating_duration_since(now))
    }

    /// Reserves a place for a new session of `owner`, or says why not. A client at its share
    /// gives up its oldest session that never made a call to make room.
    pub(crate) fn admit(self: &Arc<Self>, owner: SessionOwner) -> Result<Ticket, Refusal> {
        let now = Instant::now();
        let mut state = self.lock();
        let max = self.limits.max_sessions;
        let held = state.places.len() + state.reserved_total();
        if held >= max {
            return Err(Refusal {
                setting: "mcp.max_sessions",
                held,
                limit: max,
                retry_after: self.first_expiry(state.places.values(), now),
            });
        }
        let share = self.limits.per_client.min(max);
        let mine = state.held_by(&owner);
        if mine >= share {
            let oldest_unused = state
                .places
                .iter()
                .filter(|(_, p)| p.owner == owner && !p.used)
                .min_by_key(|(_, p)| p.opened)
                .map(|(id, _)| id.clone());
            let Some(id) = oldest_unused else {
                let own = state.places.values().filter(|p| p.owner == owner);
                return Err(Refusal {
                    setting: "mcp.max_sessions_per_client",
                    held: mine,
                    limit: share,
                    retry_after: self.first_expiry(own, now),
                });
            };
            if let Some(place) = state.places.remove(&id) {
                tracing::info!(session = %id, share, "MCP session that never made a call closed: its client opened another at its share");
                place.closing.cancel();
            }
        }
        *state.reserved.entry(owner).or_default() += 1;
        Ok(Ticket {
            places: self.clone(),
            owner,
            pending: true,
        })
    }

    /// A request of session `id` arrived; `call` when it is a request other than
    /// `initialize` (the session is in use from then on).
    pub(crate) fn touch(&self, id: &str, call: bool) {
        if let Some(place) = self.lock().places.get_mut(id) {
            place.last_active = Instant::now();
            place.used |= call;
        }
    }

    /// Whether session `id` holds a place.
    pub(crate) fn contains(&self, id: &str) -> bool {
        self.lock().places.contains_key(id)
    }

    /// Session `id` closed: its place is free.
    pub(crate) fn release(&self, id: &str) {
        if let Some(place) = self.lock().places.remove(id) {
            place.closing.cancel();
        }
    }

    /// Sessions holding a place (opened; admitted ones not yet opened are not counted).
    #[cfg(test)]
    pub(crate) fn open(&self) -> usize {
        self.lock().places.len()
    }

    /// Resolves when session `id` must close because it expired or was given up, or once it
    /// was released; at once for a session without a place.
    pub(crate) fn closed(self: &Arc<Self>, id: &str) -> impl Future<Output = ()> + Send + 'static {
        let places = self.clone();
        let id = id.to_owned();
        let closing = self.lock().places.get(&id).map(|p| p.closing.clone());
        async move {
            let Some(closing) = closing else { return };
            loop {
                let deadline = {
                    let state = places.lock();
                    match state.places.get(&id) {
                        Some(place) => places.deadline(place),
                        None => return,
                    }
                };
                let expires = async {
                    match deadline {
                        Some(deadline) => tokio::time::sleep_until(deadline).await,
                        None => std::future::pending().await,
                    }
                };
                tokio::select! {
                    () = closing.cancelled() => return,
                    () = expires => {
                        if places.expire_if_due(&id) {
                            return;
                        }
                    }
                }
            }
        }
    }

    /// Takes session `id`'s place away when its time is up; true when it did.
    fn expire_if_due(&self, id: &str) -> bool {
        let now = Instant::now();
        let mut state = self.lock();
        let due = state
            .places
            .get(id)
            .and_then(|p| self.deadline(p))
            .is_some_and(|d| d <= now);
        if !due {
            return false;
        }
        if let Some(place) = state.places.remove(id) {
            let why = if place.used {
                "idle"
            } else {
                "no call since it opened"
            };
            tracing::info!(session = %id, why, "MCP session expired: closing it");
            place.closing.cancel();
        }
        true
    }
}

#[cfg(test)]
mod tests;
