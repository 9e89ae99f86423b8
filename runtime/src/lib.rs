//! robotd runtime: everything actors need to live together, and nothing about robots.
//!
//! - [`bus`]: typed messages over iceoryx2 shared memory — topics with a declared overflow
//!   policy, camera frames read in place, request-response that always answers. The same code
//!   works whether the peer is in this process or another one.
//! - [`supervision`]: restart policy, restart budget, exponential backoff, a safe-state hook
//!   before every restart, for in-process (kameo) actors and for actor processes alike.
//! - [`host`]: serves a bus service with a supervised in-process actor.
//! - [`config`]: layered configuration (defaults → file → `ROBOTD_*` environment → flags),
//!   refusing unknown keys and bad values with the place and the reason.
//! - [`telemetry`]: logs, daily log files, OpenTelemetry export, trace context for envelopes.
//! - [`metrics`]: the Prometheus metrics behind `GET /metrics`.
//! - [`heap`]: gives memory freed by a burst of work back to the system.
//! - [`backoff`]: the waits between attempts of every reconnect and retry loop.
//!
//! The robot's own topics and services (their names, message types and policies) are not
//! here: they are the catalogue of `robotd-topics` (`libs/topics`), built on [`bus`].
//!
//! A request across the bus, in one process (two processes work the same way):
//!
//! ```
//! use robotd_protocol::diagnostics::{Ping, Pong};
//! use robotd_runtime::bus::{Bus, BusOptions, Service};
//! use std::time::Duration;
//!
//! const ECHO: Service<Ping, Pong> = Service::new("doc/echo");
//!
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let namespace = format!("doc-{}", std::process::id());
//! let bus = Bus::open(BusOptions::new(&namespace, "doc"))?;
//! let mut server = bus.server(&ECHO)?;
//! tokio::spawn(async move {
//!     server
//!         .serve(|ping| async move {
//!             Ok(Pong { seq: ping.seq, payload: ping.payload, served_by_pid: std::process::id() })
//!         })
//!         .await
//! });
//! let client = bus.client(&ECHO)?;
//! let pong = client.request(&Ping { seq: 7, payload: vec![] }, Duration::from_secs(1)).await?;
//! assert_eq!(pong.seq, 7);
//! # Ok(()) }
//! ```
pub mod backoff;
pub mod bus;
pub mod config;
pub mod heap;
pub mod host;
pub mod limits;
pub mod metrics;
pub mod origin;
pub mod supervision;
pub mod telemetry;
