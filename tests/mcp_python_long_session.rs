//! The long randomized session of `tests/mcp_long_session.rs`, driven by the Python `fastmcp`
//! client over SSE (tests/python/mcp_long_session.py), twice in a row on one running robotd:
//! the second session starts from the world the first left. After each, the simulator's ground
//! truth must agree with what the replies said (what is held, where the last detection put
//! each object), and no recovery may have failed.
//!
//! `LONG_SESSION_CALLS` (default 200 per session here) sets the length.

mod common;
#[path = "common/lab.rs"]
mod lab;

use lab::{lab_with, runtime};
use serde_json::Value;

fn run_session(url: &str, calls: usize, seed: u64) -> Value {
    common::run_python_json(
        "mcp_long_session.py",
        &[url.to_owned(), calls.to_string(), seed.to_string()],
    )
}

#[test]
fn a_fastmcp_long_session_twice_on_one_service_agrees_with_the_world() {
    let calls: usize = std::env::var("LONG_SESSION_CALLS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(200);
    runtime().block_on(async {
        // Motions run 50 times faster than real ones: the per-minute rate limit (made for real
        // time, tested in safety_service) would refuse what the session is about.
        let lab = lab_with(0.02, &["safety.llm_motions_per_minute=0".to_owned()]).await;
        let url = format!("{}/sse", lab.url);
        for seed in [1, 2] {
            let report = tokio::task::spawn_blocking({
                let url = url.clone();
                move || run_session(&url, calls, seed)
            })
            .await
            .unwrap();
            eprintln!("fastmcp session (seed {seed}): {report}");
            assert!(report["calls"].as_u64().unwrap() >= calls as u64);
            assert!(
                report["succeeded"].as_u64().unwrap() > calls as u64 / 3,
                "{report}"
            );
            assert_eq!(report["stuck"], serde_json::json!([]), "{report}");
            let truth = lab.truth().await;
            let held: Vec<&str> = truth
                .iter()
                .filter(|o| o.held)
                .map(|o| o.label.as_str())
                .collect();
            match report["holding"].as_str() {
                Some(label) => assert_eq!(held, [label], "{report}"),
                None => assert!(held.is_empty(), "held {held:?}, the replies said nothing"),
            }
            // Every object the last detection named by its real label is where it said.
            for seen in report["seen"].as_array().unwrap() {
                let label = seen["label"].as_str().unwrap();
                let at = [
                    seen["at"][0].as_f64().unwrap(),
                    seen["at"][1].as_f64().unwrap(),
                ];
                if let Some(o) = truth.iter().find(|o| o.label == label) {
                    let d = (o.x_m - at[0]).hypot(o.y_m - at[1]);
                    assert!(
                        d < 0.015 || o.held,
                        "{label} seen at {at:?}, is at ({:.3}, {:.3})",
                        o.x_m,
                        o.y_m
                    );
                }
            }
        }
    });
}
