//! Helpers shared by the bus tests.
#![allow(dead_code)]

use robotd_runtime::bus::{Bus, BusOptions};
use std::sync::atomic::{AtomicU32, Ordering};

/// A bus in a namespace no other test (or test run) uses.
pub fn fresh_bus(node: &str) -> Bus {
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    let namespace = format!(
        "test-{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    );
    Bus::open(BusOptions::new(&namespace, node)).expect("open bus")
}

/// The sum of `metric`'s series for bus topic `topic` in this process's metrics
/// (`robotd_bus_dropped_total` adds up its reasons).
pub fn metric_sum(metric: &str, topic: &str) -> f64 {
    let text = robotd_runtime::metrics::Metrics::global().render();
    text.lines()
        .filter(|line| line.starts_with(metric) && line.contains(&format!("topic=\"{topic}\"")))
        .filter_map(|line| line.rsplit(' ').next()?.parse::<f64>().ok())
        .sum()
}
