//! `robotd estop [REASON]` and `robotd estop --release`: the emergency stop from a terminal.
//!
//! Sends on the running robotd's bus topic `safety/estop`, the same path as the MCP tools
//! and `POST /estop`; the arm halts within one control tick. Releasing is its own flag, never
//! a side effect. Fails (exit 2) when no arm listens on the configured bus namespace.

use anyhow::{bail, Context, Result};
use robotd_config::Config;
use robotd_protocol::health::EmergencyStop;
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_runtime::catalog::SAFETY_ESTOP;
use std::time::{Duration, Instant};

/// How long to wait for robotd's arm to be connected to the new publisher.
const CONNECT_WAIT: Duration = Duration::from_secs(2);

/// Engages (or, with `release`, releases) the e-stop of the robotd on `config`'s bus.
pub fn run(config: &Config, reason: Option<&str>, release: bool) -> Result<String> {
    let bus = Bus::open(BusOptions::new(&config.bus.namespace, "robotd-estop"))
        .with_context(|| format!("joining the bus '{}'", config.bus.namespace))?;
    let publisher = bus
        .publisher(&SAFETY_ESTOP)
        .context("opening safety/estop")?;
    let user = std::env::var("USER").unwrap_or_else(|_| "a terminal user".into());
    let reason: String = match (release, reason) {
        (true, _) => format!("released by {user} (robotd estop --release)"),
        (false, Some(text)) if !text.trim().is_empty() => text.to_owned(),
        (false, _) => format!("engaged by {user} (robotd estop)"),
    }
    .chars()
    .filter(|c| !c.is_control())
    .take(500)
    .collect();
    let estop = EmergencyStop {
        engaged: !release,
        reason: reason.clone(),
        source: "cli".into(),
    };
    // A new publisher may need a moment to see the running service's subscriber.
    let started = Instant::now();
    loop {
        let delivered = publisher.publish(&estop).context("sending the e-stop")?;
        if delivered > 0 {
            let what = if release { "released" } else { "engaged" };
            return Ok(format!(
                "emergency stop {what} on bus '{}': {reason}",
                config.bus.namespace
            ));
        }
        if started.elapsed() > CONNECT_WAIT {
            bail!(
                "no robotd arm listens on bus namespace '{}' (is robotd serve running with this namespace?)",
                config.bus.namespace
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}
