//! "Let the LLM see and name" (issue 44), end to end on the simulator:
//!
//! - the Python `fastmcp` clients labs use (2.x from `.venv`, 4.x from `.venv-fastmcp4`, both
//!   installed by ./scripts/test.sh) get a decodable JPEG with the overlay from
//!   `get_camera_image` over legacy SSE and streamable HTTP, within the size bound, and the
//!   text item beside it;
//! - an object the label table does not know (`unknown object`) is seen in the picture, named
//!   by `label_object`, keeps its name in the detection tools, and is moved by
//!   `pick_place_object` under that name — checked against the simulator's ground truth;
//! - the camera is a resource too (`camera://niryo_ws/latest`).

mod common;
#[path = "common/lab.rs"]
mod lab;

use base64::Engine;
use rmcp::model::{CallToolRequestParams, ReadResourceRequestParams, ResourceContents};
use serde_json::{json, Value};

/// The default byte bound of a picture.
const MAX_BYTES: usize = 150_000;

fn fastmcp4_python() -> String {
    let venv = concat!(env!("CARGO_MANIFEST_DIR"), "/.venv-fastmcp4/bin/python");
    assert!(
        std::path::Path::new(venv).exists(),
        "the fastmcp 4.x venv is missing: ./scripts/test.sh installs \
         tests/python/requirements-fastmcp4.txt into .venv-fastmcp4"
    );
    venv.to_owned()
}

/// Pixels that differ strongly between two pictures of the same size.
fn strongly_different(a: &[u8], b: &[u8]) -> usize {
    a.chunks_exact(3)
        .zip(b.chunks_exact(3))
        .filter(|(p, q)| p.iter().zip(q.iter()).any(|(x, y)| x.abs_diff(*y) > 90))
        .count()
}

#[test]
fn fastmcp_2_and_4_receive_an_annotated_jpeg_within_the_bound_over_sse_and_streamable_http() {
    let namespace = common::fresh_namespace("img");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=0.05"]);
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/python/mcp_camera_image.py"
    );
    for python in [common::python(), fastmcp4_python()] {
        for path in ["/sse", "/mcp"] {
            let out = tempfile::tempdir().unwrap();
            let args = [
                script.to_owned(),
                format!("http://127.0.0.1:{port}{path}"),
                out.path().display().to_string(),
                "3".to_owned(),
            ];
            let output = std::process::Command::new(&python)
                .args(&args)
                .output()
                .unwrap();
            let stderr = String::from_utf8_lossy(&output.stderr);
            assert!(output.status.success(), "{python} {path}: {stderr}");
            let report: Value = serde_json::from_slice(&output.stdout).unwrap();
            let version = report["fastmcp"].as_str().unwrap().to_owned();
            let is_4 = python.contains("fastmcp4");
            assert!(
                version.starts_with(if is_4 { "4." } else { "2." }),
                "{version}"
            );
            assert!(
                report["tools"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .any(|t| t == "get_camera_image"),
                "{report}"
            );
            assert_eq!(
                report["content_types"],
                json!(["text", "image"]),
                "{report}"
            );
            assert_eq!(report["mime_type"], "image/jpeg");
            let text = report["text"].as_str().unwrap();
            assert!(
                text.starts_with("✓ Camera image of workspace 'niryo_ws' (640×480 JPEG"),
                "{text}"
            );
            assert!(text.contains("'pencil' at ["), "{text}");
            // fastmcp's `result.data` is the text, as for every tool.
            assert_eq!(report["data"], report["text"]);
            let data = &report["structured"]["data"];
            assert_eq!(data["mime_type"], "image/jpeg");
            assert!(data["objects"].as_array().unwrap().len() >= 3, "{data}");
            let bytes = report["jpeg_bytes"].as_u64().unwrap() as usize;
            assert!(bytes <= MAX_BYTES, "{bytes} bytes");
            assert!(
                report["max_jpeg_bytes"].as_u64().unwrap() as usize <= MAX_BYTES,
                "{report}"
            );
            let invalid = report["invalid_text"].as_str().unwrap();
            assert!(
                invalid.starts_with("❌ Validation Error in get_camera_image:")
                    && invalid.contains("annotated: Input should be a valid boolean")
                    && invalid.contains("max_width: Input should be greater than or equal to 64"),
                "{invalid}"
            );
            // The JPEG decodes, and the overlay is on it: the annotated and the plain picture
            // of the same view differ where the boxes and tags are drawn.
            let jpeg = std::fs::read(out.path().join("camera.jpg")).unwrap();
            let plain = std::fs::read(out.path().join("plain.jpg")).unwrap();
            let (drawn, w, h) = robotd_render::decode_jpeg(&jpeg).unwrap();
            let (bare, ..) = robotd_render::decode_jpeg(&plain).unwrap();
            assert_eq!((w, h), (640, 480));
            let overlay = strongly_different(&drawn, &bare);
            assert!(
                overlay > 1_000,
                "{version} {path}: only {overlay} pixels of overlay"
            );
            eprintln!(
                "fastmcp {version} {path}: {bytes} bytes, get_camera_image p50 {:.1} ms, \
                 get_detected_objects p50 {:.1} ms",
                report["picture_ms"]["p50"].as_f64().unwrap(),
                report["baseline_ms"]["p50"].as_f64().unwrap()
            );
        }
    }
}

#[test]
fn an_unknown_object_is_seen_named_and_picked_by_its_new_name() {
    lab::runtime().block_on(async {
        let lab = lab::lab(Some(lab::scene("unknown.toml"))).await;
        // Look: the picture's text lists the unknown object with its id.
        let mut params = CallToolRequestParams::new("get_camera_image");
        params = params.with_arguments(json!({"max_width": 320}).as_object().unwrap().clone());
        let result = lab.client.call_tool(params).await.unwrap();
        let text = result.content[0].as_text().unwrap().text.clone();
        let image = result.content[1].as_image().expect("an image item");
        assert_eq!(image.mime_type, "image/jpeg");
        let jpeg = base64::engine::general_purpose::STANDARD
            .decode(&image.data)
            .unwrap();
        let (_, w, h) = robotd_render::decode_jpeg(&jpeg).unwrap();
        assert_eq!((w, h), (320, 240), "max_width is kept");
        let data = &result.structured_content.unwrap()["data"];
        let unknown = data["objects"]
            .as_array()
            .unwrap()
            .iter()
            .find(|o| o["label"] == "unknown object")
            .unwrap_or_else(|| panic!("no unknown object in {text}"))
            .clone();
        let id = unknown["id"].as_str().unwrap().to_owned();
        assert!(
            text.contains(&format!("- {id}: 'unknown object' at [")),
            "{text}"
        );
        // Name it; unknown ids and over-long names are refused with the reason.
        let (bad, _) = lab
            .call(
                "label_object",
                json!({"object_id": "obj-999", "label": "x"}),
            )
            .await;
        assert!(bad.contains("unknown object id 'obj-999'"), "{bad}");
        let (long, _) = lab
            .call(
                "label_object",
                json!({"object_id": id, "label": "y".repeat(101)}),
            )
            .await;
        // The tool's schema says the limit (workspace.max_label_chars, 100), and a longer
        // name is refused as an argument error before it reaches the workspace model.
        assert!(
            long.contains("Validation Error in label_object")
                && long.contains("at most 100 characters"),
            "{long}"
        );
        let named = lab
            .ok(
                "label_object",
                json!({"object_id": id, "label": "Screwdriver"}),
            )
            .await;
        assert_eq!(named["object"]["label"], "screwdriver");
        assert_eq!(named["detected_as"], "unknown object");
        assert_eq!(named["label_added"], true);
        let labels = lab.ok("get_object_labels_as_string", json!({})).await;
        assert!(labels.to_string().contains("screwdriver"), "{labels}");
        // The detection tools answer with the name, under the same id.
        let seen = lab
            .ok("get_detected_objects", json!({"label": "screwdriver"}))
            .await;
        assert_eq!(seen[0]["id"], id.as_str(), "{seen}");
        let from = [
            seen[0]["position"]["center_of_mass"]["x"].as_f64().unwrap(),
            seen[0]["position"]["center_of_mass"]["y"].as_f64().unwrap(),
        ];
        // Picked and placed by its new name: the simulator's block is where it was put.
        let to = [0.21, 0.04];
        lab.move_object("screwdriver", from, to).await;
        let truth = lab.truth_of("black block").await;
        let (x, y) = (truth.x_m, truth.y_m);
        assert!(
            (x - to[0]).abs() < 0.008 && (y - to[1]).abs() < 0.008,
            "the block is at ({x:.3}, {y:.3}), placed at {to:?}"
        );
        // Still the screwdriver, with its id, where it now lies.
        let after = lab
            .ok("get_detected_objects", json!({"label": "screwdriver"}))
            .await;
        assert_eq!(after[0]["id"], id.as_str(), "{after}");
        let p = &after[0]["position"]["center_of_mass"];
        assert!((p["x"].as_f64().unwrap() - to[0]).abs() < 0.008, "{after}");
        // The camera as a resource.
        let read = lab
            .client
            .peer()
            .read_resource(ReadResourceRequestParams::new("camera://niryo_ws/latest"))
            .await
            .unwrap();
        let ResourceContents::BlobResourceContents {
            blob, mime_type, ..
        } = &read.contents[0]
        else {
            panic!("not a blob: {read:?}")
        };
        assert_eq!(mime_type.as_deref(), Some("image/jpeg"));
        let jpeg = base64::engine::general_purpose::STANDARD
            .decode(blob)
            .unwrap();
        assert!(jpeg.len() <= MAX_BYTES);
        assert!(robotd_render::decode_jpeg(&jpeg).is_ok());
        let ResourceContents::TextResourceContents { text, .. } = &read.contents[1] else {
            panic!("not a text: {read:?}")
        };
        assert!(
            text.contains(&format!("- {id}: 'screwdriver' at [")),
            "{text}"
        );
        let missing = lab
            .client
            .peer()
            .read_resource(ReadResourceRequestParams::new("camera://moon/latest"))
            .await
            .unwrap_err();
        assert!(
            missing.to_string().contains("unknown workspace 'moon'"),
            "{missing}"
        );
    });
}
