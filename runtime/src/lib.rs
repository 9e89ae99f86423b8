//! robotd runtime: the bus (iceoryx2), actor supervision, configuration, telemetry, metrics.
pub mod bus;
pub mod catalog;
pub mod config;
pub mod metrics;
pub mod supervision;
pub mod telemetry;
