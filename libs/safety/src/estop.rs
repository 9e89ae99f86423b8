//! The emergency stop's two doors: engaging is open to anyone, releasing only to a deliberate
//! request to the policy.
//!
//! - **Engage**: an [`EmergencyStop`] with `engaged: true` on `safety/estop`, from any process
//!   (the MCP tools, `POST /estop`, `robotd estop`, a bus client). The latch is set, the
//!   driver halted (the caller's `halt`), and the engagement recorded in the audit log.
//! - **Release**: only an [`EStopRelease`] request to the policy's own service
//!   `safety/release`, with `confirm: "release"`; the request's origin and `by` go into the
//!   audit log, and the policy answers with the new state ([`EStopState`]). The MCP tool
//!   `release_emergency_stop`, `POST /estop/release` and `robotd estop --release` all send it.
//! - A bare `engaged: false` on `safety/estop` (a client mirroring the state, a replayed
//!   recording, an old script) releases nothing: it is ignored, logged and audited.
//!
//! One task serves both ([`serve`]), and before it answers a release it takes every engage
//! already queued on `safety/estop`: a release never overtakes an e-stop sent before it.
//!
//! Like every bus request, the release's origin is what the sender claims (see
//! `robotd_protocol::safety`): the service makes releasing a deliberate, recorded act, not an
//! authenticated one. `POST /estop/release` is behind the HTTP port's token.

use crate::{Safety, Violation};
use robotd_protocol::health::{EStopRelease, EStopState, EmergencyStop};
use robotd_protocol::safety::{printable, Origin};
use robotd_runtime::bus::{BusError, Fault, FaultKind, Server, Subscriber};

/// The only word that releases.
pub const CONFIRM: &str = "release";

impl Safety {
    /// Engages the e-stop: sets the latch, calls `halt` (which halts the driver), and only
    /// then logs and records who engaged it and why.
    ///
    /// An e-stop engaged while one already is keeps the first reason and adds its own
    /// (`first; then second`), so nobody who releases "their own" stop (a release with
    /// `only_if_reason`) releases one somebody else engaged meanwhile.
    pub fn engage_estop(&self, reason: &str, source: &str, halt: impl FnOnce()) {
        let was_engaged = self.inner.control.estop_engaged();
        let mut reason = printable(reason, 500);
        if was_engaged {
            let before = self.inner.control.estop_reason();
            if before != reason && !before.ends_with(&format!("; then {reason}")) {
                reason = printable(&format!("{before}; then {reason}"), 2000);
            } else {
                reason = before;
            }
        }
        self.inner.control.set_estop(true, &reason);
        halt();
        let source = printable(source, 100);
        tracing::warn!(%reason, %source, "emergency stop engaged");
        self.record_estop(serde_json::json!({
            "event": "estop_engaged",
            "source": source,
            "reason": reason,
            "was_engaged": was_engaged,
        }));
    }

    /// Releases the e-stop, the only way it is released: `confirm` must be [`CONFIRM`].
    /// Records the release with `origin` and `by`; returns how it was released.
    /// With `only_if_reason`, releases only when the e-stop's reason is exactly that (a tool
    /// releasing the stop it engaged itself); refused otherwise, and it stays engaged.
    pub fn release_estop(
        &self,
        origin: &Origin,
        confirm: &str,
        by: &str,
        only_if_reason: Option<&str>,
    ) -> Result<String, Violation> {
        let by = printable(by.trim(), 200);
        let refused = |reason: String| {
            self.record_estop(serde_json::json!({
                "event": "estop_release_refused",
                "origin": origin,
                "by": by,
                "reason": reason,
            }));
            Err(Violation {
                limit: "estop",
                reason,
            })
        };
        if confirm != CONFIRM {
            return refused(format!(
                "releasing the emergency stop is a deliberate act: confirm must be '{CONFIRM}', got '{}'",
                printable(confirm, 40)
            ));
        }
        if let Some(expected) = only_if_reason {
            let now = self.inner.control.estop_reason();
            if !self.inner.control.estop_engaged() || now != expected {
                return refused(format!(
                    "the emergency stop is not the one expected (its reason is '{}', expected \
                     '{}'): somebody else engaged it or released it; it stays as it is",
                    printable(&now, 300),
                    printable(expected, 300)
                ));
            }
        }
        let was = self.estop();
        let reason = match by.as_str() {
            "" => format!("released by {origin}"),
            by => format!("released by {by} ({origin})"),
        };
        self.inner.control.set_estop(false, &reason);
        tracing::warn!(%origin, %by, was_engaged = was.is_some(), "emergency stop released");
        self.record_estop(serde_json::json!({
            "event": "estop_released",
            "origin": origin,
            "by": by,
            "was_engaged": was.is_some(),
            "engaged_reason": was,
        }));
        Ok(reason)
    }

    /// A bare `engaged: false` on `safety/estop`: releases nothing; logged and recorded.
    pub fn ignore_bus_release(&self, reason: &str, source: &str) {
        let reason = printable(reason, 500);
        let source = printable(source, 100);
        tracing::warn!(
            %reason,
            %source,
            "ignored engaged=false on safety/estop: only a release request to the safety policy \
             (safety/release) releases the e-stop"
        );
        self.record_estop(serde_json::json!({
            "event": "estop_release_ignored",
            "source": source,
            "reason": reason,
            "why": "a bare engaged=false on safety/estop releases nothing; release through safety/release",
        }));
    }

    /// The e-stop's state now.
    pub fn estop_state(&self) -> EStopState {
        let control = &self.inner.control;
        EStopState {
            engaged: control.estop_engaged(),
            reason: control.estop_reason(),
        }
    }

    fn record_estop(&self, record: serde_json::Value) {
        // An e-stop event that cannot be recorded still happens: engaging must never fail,
        // and motions after a release are refused anyway while the log cannot take them.
        if let Err(error) = self.inner.audit.record(record) {
            tracing::error!(%error, "could not record an e-stop event in the audit log");
        }
    }
}

/// Applies one message of `safety/estop`. One that cannot be read (another schema version,
/// corrupt bytes) is logged and skipped: it must not end the watch.
fn apply(
    safety: &Safety,
    received: Result<robotd_protocol::envelope::Envelope<EmergencyStop>, BusError>,
    halt: &(impl Fn() + ?Sized),
) -> Result<(), BusError> {
    let estop = match received {
        Ok(envelope) => envelope.body,
        Err(BusError::Decode(error)) => {
            tracing::warn!(%error, "an unreadable message on safety/estop, skipped");
            return Ok(());
        }
        Err(other) => return Err(other),
    };
    if estop.engaged {
        safety.engage_estop(&estop.reason, &estop.source, halt);
    } else {
        safety.ignore_bus_release(&estop.reason, &estop.source);
    }
    Ok(())
}

/// Serves the e-stop: engages from `estops` (`safety/estop`, halting through `halt`) and
/// answers release requests on `releases` (`safety/release`), in the order they were sent.
/// Runs until the bus fails.
pub async fn serve(
    mut estops: Subscriber<EmergencyStop>,
    mut releases: Server<EStopRelease, EStopState>,
    safety: Safety,
    halt: impl Fn() + Send + Sync + 'static,
) -> Result<(), BusError> {
    loop {
        tokio::select! {
            biased;
            estop = estops.recv() => apply(&safety, estop, &halt)?,
            incoming = releases.next() => {
                let incoming = incoming?;
                // An e-stop sent before this release is in the queue now: apply it first.
                loop {
                    match estops.try_recv() {
                        Ok(None) => break,
                        Ok(Some(estop)) => apply(&safety, Ok(estop), &halt)?,
                        Err(error) => apply(&safety, Err(error), &halt)?,
                    }
                }
                let origin = incoming.origin.clone();
                let (envelope, pending) = incoming.split();
                let request = envelope.body;
                let reply = safety
                    .release_estop(
                        &origin,
                        &request.confirm,
                        &request.by,
                        request.only_if_reason.as_deref(),
                    )
                    .map(|_| safety.estop_state())
                    .map_err(|violation| Fault::new(FaultKind::Refused, violation.reason));
                if let Err(error) = releases.respond(pending, reply) {
                    tracing::warn!(%error, "could not answer a release of the emergency stop");
                }
            }
        }
    }
}
