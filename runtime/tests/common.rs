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
