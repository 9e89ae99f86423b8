//! A thread of its own for an edge that follows the bus.
//!
//! Bus ports are bound to the thread and runtime that opened them, and an edge that encodes
//! camera frames (Redis, dashboard, Foxglove) must not take CPU time from the service's
//! runtime. [`spawn_reader_thread`] starts a named thread with a current-thread tokio runtime
//! and runs the edge's loop on it; the loop opens its ports there.

use std::future::Future;

/// Runs `work()` on a new thread named `name`, inside a current-thread tokio runtime. A runtime
/// that cannot start is logged with the thread's name and the thread ends.
pub fn spawn_reader_thread<F, Fut>(
    name: &str,
    work: F,
) -> std::io::Result<std::thread::JoinHandle<()>>
where
    F: FnOnce() -> Fut + Send + 'static,
    Fut: Future<Output = ()>,
{
    let label = name.to_owned();
    std::thread::Builder::new().name(label.clone()).spawn(move || {
        match tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
        {
            Ok(runtime) => runtime.block_on(work()),
            Err(error) => {
                tracing::error!(%error, thread = %label, "the thread cannot start its tokio runtime")
            }
        }
    })
}
