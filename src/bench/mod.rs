//! `robotd bench`: measurements of robotd's own machinery, each beside its raw baseline
//! measured in the same run (these machines are noisy; only same-run ratios mean much).
//!
//! Two-process measurements re-run this binary as a peer (`robotd bench-peer <role>`), so
//! everything crosses a real process boundary. The bus benchmark (raw iceoryx2 beside
//! robotd's bus) and the statistics live in the `bench/` crate (robotd-bench).

pub mod jpeg;
pub mod mcp;
pub mod niryo;
pub mod perception;
pub mod ping;
pub mod redis;
pub mod safety;
pub mod sim;
pub mod soak;
pub mod widowx;

pub use robotd_bench::bus;
pub use robotd_bench::stats::Latency;
