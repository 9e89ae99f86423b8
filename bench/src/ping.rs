//! `robotd bench ping`: round trips of a Rust client to a *running* robotd's `system/ping`.
//!
//! The Rust side of comparisons made from other languages: `scripts/bench/python_bus.py`
//! calls the same service of the same robotd from Python and runs this beside it, so the
//! figures show what the Python client adds.

use super::Latency;
use anyhow::{bail, Context, Result};
use robotd_protocol::diagnostics::Ping;
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::SYSTEM_PING;
use serde::Serialize;
use std::time::{Duration, Instant};

/// What `robotd bench ping` measures.
#[derive(Debug, Clone, Serialize)]
pub struct PingFigures {
    /// Median round trip, µs.
    pub round_trip_us_p50: f64,
    /// 99th percentile, µs.
    pub round_trip_us_p99: f64,
    /// Round trips measured (after 200 unmeasured ones).
    pub round_trips: usize,
    /// The namespace of the robotd pinged.
    pub namespace: String,
}

impl PingFigures {
    /// The human-readable table.
    pub fn table(&self) -> String {
        format!(
            "robotd bench ping: {} round trips to system/ping of the robotd in '{}'\n\
             Rust client round trip p50 / p99  {:>8.1} / {:>8.1} µs\n",
            self.round_trips, self.namespace, self.round_trip_us_p50, self.round_trip_us_p99
        )
    }
}

/// Pings the robotd serving `namespace` `round_trips` times.
pub fn run(namespace: &str, round_trips: usize) -> Result<PingFigures> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()?;
    runtime.block_on(async {
        let bus = Bus::open(BusOptions::new(namespace, "bench-ping"))?;
        let client = bus.client(&SYSTEM_PING)?;
        if !client.wait_for_server(Duration::from_secs(5)).await {
            bail!("no robotd serves system/ping in namespace '{namespace}' (is it running?)");
        }
        let mut samples = Vec::with_capacity(round_trips);
        for seq in 0..(round_trips + 200) as u64 {
            let ping = Ping {
                seq,
                payload: Vec::new(),
            };
            let started = Instant::now();
            let pong = client
                .request(&ping, Duration::from_secs(5))
                .await
                .context("pinging robotd")?;
            if pong.seq != seq {
                bail!("ping {seq} was answered as {}", pong.seq);
            }
            if seq >= 200 {
                samples.push(started.elapsed());
            }
        }
        let latency = Latency::of(&mut samples);
        Ok(PingFigures {
            round_trip_us_p50: latency.p50_us,
            round_trip_us_p99: latency.p99_us,
            round_trips,
            namespace: namespace.to_owned(),
        })
    })
}
