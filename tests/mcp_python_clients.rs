//! The clients that exist in the field: Python `fastmcp` (installed into .venv by
//! ./scripts/test.sh from tests/python/requirements.txt) lists robotd's tools and calls them
//! over legacy SSE and over streamable HTTP, including a pick-and-place with progress.

mod common;

use serde_json::Value;
use std::process::Command;

fn run_client(url: &str) -> Value {
    common::run_python_json("mcp_fastmcp_client.py", &[url.to_owned()])
}

#[test]
fn fastmcp_drives_robotd_over_sse_and_streamable_http() {
    let namespace = common::fresh_namespace("py");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=0.05"]);
    for (path, transport, place) in [
        ("/sse", "SSETransport", [0.27, -0.01]),
        ("/mcp", "StreamableHttpTransport", [0.27, -0.01]),
    ] {
        let report = run_client(&format!("http://127.0.0.1:{port}{path}"));
        assert_eq!(report["transport"], transport);
        assert_eq!(report["tools"].as_array().unwrap().len(), 24, "{report}");
        assert_eq!(report["output_schemas"], 24);
        assert_eq!(
            report["coordinate_text"],
            "✓ Coordinate of 'lower right corner' in workspace 'niryo_ws': [0.163, -0.087]"
        );
        assert_eq!(
            report["coordinate_structured"]["data"]["coordinate"],
            serde_json::json!([0.163, -0.087])
        );
        // fastmcp's `result.data` is the reply text, as the Python server gives it.
        assert_eq!(
            report["coordinate_data"], report["coordinate_text"],
            "{report}"
        );
        assert_eq!(
            report["pick_place_data"], report["pick_place_text"],
            "{report}"
        );
        assert!(
            report["objects_text"]
                .as_str()
                .unwrap()
                .starts_with("✓ Found 1 object(s):"),
            "{report}"
        );
        assert_eq!(
            report["invalid_text"],
            "❌ Validation Error in pick_object:\n  \
             • object_name: String should have at least 1 character\n  \
             • pick_coordinate: List should have at least 2 items after validation, not 1"
        );
        let text = report["pick_place_text"].as_str().unwrap();
        assert!(
            text.starts_with("✓ Successfully picked 'pencil' from [")
                && text.ends_with(&format!(
                    " and placed it at [{:.3}, {:.3}]",
                    place[0], place[1]
                )),
            "{text}"
        );
        let progress = report["progress"].as_array().unwrap();
        assert!(progress.len() >= 4, "progress notifications: {report}");
        assert!(progress.iter().all(|p| p["message"].is_string()));
        // The camera sees the pencil where it was put.
        let after = &report["pencil_after"][0]["position"]["center_of_mass"];
        let (x, y) = (after["x"].as_f64().unwrap(), after["y"].as_f64().unwrap());
        assert!(
            (x - place[0]).abs() < 0.006 && (y - place[1]).abs() < 0.006,
            "pencil seen at ({x:.4}, {y:.4}), placed at {place:?}"
        );
        // Put it back for the next transport.
        let pencil = &report["pencil_after"][0]["position"]["center_of_mass"];
        let status = Command::new(env!("CARGO_BIN_EXE_robotd"))
            .args(["call", "pick_place_object", "--url"])
            .arg(format!("http://127.0.0.1:{port}/mcp"))
            .args(["--arg", "object_name=pencil"])
            .arg("--arg")
            .arg(format!(
                "pick_coordinate=[{}, {}]",
                pencil["x"], pencil["y"]
            ))
            .args(["--arg", "place_coordinate=[0.22, -0.05]"])
            .status()
            .unwrap();
        assert!(status.success(), "robotd call put the pencil back");
    }
}
