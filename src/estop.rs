//! `robotd estop [REASON]` and `robotd estop --release`: the emergency stop from a terminal.
//!
//! Engaging sends on the running robotd's bus topic `safety/estop`, the same path as the MCP
//! tool and `POST /estop`; the arm halts within one control tick. Returns once the arm reports
//! the new state on `arm/state`. Fails when no arm listens on the configured bus namespace or
//! none confirms.
//!
//! Releasing is its own flag, never a side effect: a request to the safety policy's service
//! `safety/release` (origin `cli`), like the MCP tool's and `POST /estop/release`; the policy
//! answers once it is released.
//!
//! Engaging never fails on the command line's form: `main` drops what clap cannot read after
//! `estop` (an unknown option, a stray value) and passes it here as notes, which the reply
//! prints. A release with such notes is refused instead: nothing changes.

use anyhow::{bail, Context, Result};
use robotd_config::Config;
use robotd_protocol::health::{EStopRelease, EmergencyStop};
use robotd_protocol::safety::{printable, Origin, OriginKind};
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_runtime::origin::with_origin;
use robotd_topics::{ARM_STATE, SAFETY_ESTOP, SAFETY_RELEASE};
use std::time::{Duration, Instant};

/// How long to wait for robotd's arm to confirm the new e-stop state on `arm/state`.
const CONFIRM_WAIT: Duration = Duration::from_secs(5);

/// Engages (or, with `release`, releases) the e-stop of the robotd on `config`'s bus.
/// `notes` say what was wrong with the command line (and was ignored): an engage goes ahead
/// and reports them; a release is refused, since releasing must be deliberate.
pub fn run(
    config: &Config,
    reason: Option<&str>,
    release: bool,
    notes: &[String],
) -> Result<String> {
    if release && !notes.is_empty() {
        bail!(
            "nothing was released: releasing the emergency stop is a deliberate act, and this \
             command line had problems ({}); run exactly `robotd estop --release`",
            notes.join("; ")
        );
    }
    let done = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the tokio runtime")?
        .block_on(send(config, reason, release))?;
    Ok(match notes {
        [] => done,
        notes => format!(
            "{done}; note: the command line was not well formed, and this was ignored: {}",
            notes.join("; ")
        ),
    })
}

async fn send(config: &Config, reason: Option<&str>, release: bool) -> Result<String> {
    let bus = Bus::open(BusOptions::new(&config.bus.namespace, "robotd-estop"))
        .with_context(|| format!("joining the bus '{}'", config.bus.namespace))?;
    if release {
        return send_release(config, &bus).await;
    }
    let publisher = bus
        .publisher(&SAFETY_ESTOP)
        .context("opening safety/estop")?;
    let mut states = bus.subscriber(&ARM_STATE).context("opening arm/state")?;
    let user = std::env::var("USER").unwrap_or_else(|_| "a terminal user".into());
    let reason = printable(
        &match reason {
            Some(text) if !text.trim().is_empty() => text.to_owned(),
            _ => format!("engaged by {user} (robotd estop)"),
        },
        500,
    );
    let estop = EmergencyStop {
        engaged: true,
        reason: reason.clone(),
        source: "cli".into(),
    };
    // A new publisher may need a moment to see the running service's subscriber, and a sample
    // lives in this process's shared memory: send until the arm reports the new state.
    let started = Instant::now();
    let mut delivered_once = false;
    while started.elapsed() < CONFIRM_WAIT {
        if publisher.publish(&estop).context("sending the e-stop")? > 0 {
            delivered_once = true;
        }
        let until = tokio::time::Instant::now() + Duration::from_millis(500);
        loop {
            match tokio::time::timeout_at(until, states.recv()).await {
                Ok(Ok(state)) if state.body.estop_engaged => {
                    return Ok(format!(
                        "emergency stop engaged on bus '{}': {reason}",
                        config.bus.namespace
                    ));
                }
                Ok(Ok(_)) => {}
                Ok(Err(error)) => bail!("reading arm/state: {error}"),
                Err(_) => break,
            }
        }
    }
    if delivered_once {
        bail!(
            "the e-stop was sent on bus '{}' but the arm did not confirm it within {} s; check /health",
            config.bus.namespace,
            CONFIRM_WAIT.as_secs()
        )
    }
    bail!(
        "no robotd arm listens on bus namespace '{}' (is robotd serve running with this namespace?)",
        config.bus.namespace
    )
}

/// Asks the safety policy to release the e-stop (`safety/release`, origin `cli`): the policy
/// records who released it and answers with the new state.
async fn send_release(config: &Config, bus: &Bus) -> Result<String> {
    let client = bus
        .client(&SAFETY_RELEASE)
        .context("opening safety/release")?;
    if !client.wait_for_server(CONFIRM_WAIT).await {
        bail!(
            "no robotd serves the e-stop on bus namespace '{}' (is robotd serve running with \
             this namespace?)",
            config.bus.namespace
        );
    }
    let user = std::env::var("USER").unwrap_or_else(|_| "a terminal user".into());
    let request = EStopRelease {
        confirm: "release".into(),
        by: printable(&format!("{user} (robotd estop --release)"), 200),
        only_if_reason: None,
    };
    let state = with_origin(
        Origin::new(OriginKind::Cli),
        client.request(&request, CONFIRM_WAIT),
    )
    .await
    .context("releasing the emergency stop")?;
    Ok(format!(
        "emergency stop released on bus '{}': {}",
        config.bus.namespace, state.reason
    ))
}
