//! robotd's benchmark machinery, apart from the service: the bus benchmark (robotd's bus beside
//! raw iceoryx2, in two processes pinned to their own cores) and the latency statistics every
//! `robotd bench` uses. The `robotd bench …` commands call into it and write the figures to
//! BENCHMARKS.md.

pub mod bus;
pub mod stats;
