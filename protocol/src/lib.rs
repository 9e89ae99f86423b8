//! robotd protocol: the typed messages actors exchange. No I/O.
pub mod envelope;
