//! A served robotd on the simulator, an MCP client of it and a bus client of the simulator's
//! ground truth (`sim/world`): the harness of the scenario tests and the long session.
//! Include it with `mod common; #[path = "common/lab.rs"] mod lab;`.

#![allow(dead_code)]

use crate::common;
use rmcp::model::CallToolRequestParams;
use robotd_mcp::client::{connect, McpClient};
use robotd_protocol::diagnostics::{SimObjectState, SimWorldRequest};
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::SIM_WORLD;
use serde_json::Value;
use std::time::Duration;

/// A two-thread runtime, as the tests' MCP clients need.
pub fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

/// The setting that loads `tests/scenes/{name}`.
pub fn scene(name: &str) -> String {
    format!(
        "robot.scene={}/tests/scenes/{name}",
        env!("CARGO_MANIFEST_DIR")
    )
}

/// Which driver the lab's robotd runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Driver {
    /// The built-in simulator (`sim-ned2`).
    Sim,
    /// The `niryo` driver over TCP against `robotd fake-niryo` (the same simulator behind the
    /// Ned2's protocol; camera frames cross TCP as JPEGs).
    Niryo,
    /// The `widowx` driver over its DYNAMIXEL servo bus against `robotd fake-widowx` (the same
    /// simulator behind nine servos on a pseudo-terminal; camera frames cross HTTP as MJPEG).
    /// The sheet is the Ned2's (`niryo_ws`, seen from the WidowX's observation pose), so every
    /// scenario's coordinates mean the same on both arms.
    Widowx,
}

/// A served robotd, an MCP client of it and a bus client of its ground truth.
pub struct Lab {
    _robotd: common::Running,
    _fake: Option<common::Running>,
    _files: Option<tempfile::TempDir>,
    /// The MCP client (SSE).
    pub client: McpClient,
    /// `http://127.0.0.1:PORT` of the served robotd.
    pub url: String,
    bus: Bus,
}

/// Starts robotd on the simulator (motions at `time_scale`, the camera at 15 fps) with
/// `extra` settings, and connects to it over SSE.
pub async fn lab_with(time_scale: f64, extra: &[String]) -> Lab {
    lab_on(Driver::Sim, time_scale, extra).await
}

/// [`lab_with`] on `driver`. With [`Driver::Niryo`] the simulator runs in `robotd
/// fake-niryo` (with `extra` and the time scale) and robotd drives it with
/// `config/niryo.toml`; the ground truth comes from the fake.
pub async fn lab_on(driver: Driver, time_scale: f64, extra: &[String]) -> Lab {
    let namespace = common::fresh_namespace("scn");
    let port = common::free_port();
    let mut settings = vec![
        "--set".to_owned(),
        format!("robot.time_scale={time_scale}"),
        "--set".to_owned(),
        "robot.camera.fps=15".to_owned(),
    ];
    for setting in extra {
        settings.push("--set".into());
        settings.push(setting.clone());
    }
    let settings: Vec<&str> = settings.iter().map(String::as_str).collect();
    let mut files = None;
    let (robotd, fake) = match driver {
        Driver::Sim => (common::start_robotd(&namespace, port, &settings), None),
        Driver::Widowx => {
            let dir = tempfile::tempdir().unwrap();
            let config = widowx_lab_config(dir.path(), extra);
            let config = config.to_str().unwrap();
            let device = dir.path().join("ttyDXL");
            let (fake, camera_url) = common::start_fake_widowx(
                &["--namespace", namespace.as_str(), "--config", config],
                &device,
                &["--ground-truth"],
            );
            let camera_url = format!("robot.widowx.camera_url={camera_url}");
            let robotd = common::start_robotd(
                &namespace,
                port,
                &["--config", config, "--set", &camera_url],
            );
            files = Some(dir);
            (robotd, Some(fake))
        }
        Driver::Niryo => {
            let mut fake_settings = vec!["--namespace", namespace.as_str()];
            fake_settings.extend(&settings);
            let (fake, robot_port) = common::start_fake_niryo(&fake_settings, &["--ground-truth"]);
            let config = concat!(env!("CARGO_MANIFEST_DIR"), "/config/niryo.toml");
            let robotd = start_robotd_on_fake_niryo(&namespace, port, robot_port, config, &[]);
            (robotd, Some(fake))
        }
    };
    let client = connect(&format!("http://127.0.0.1:{port}/sse"), None)
        .await
        .unwrap();
    let bus = Bus::open(BusOptions::new(&namespace, "scenario-test")).unwrap();
    Lab {
        _robotd: robotd,
        _fake: fake,
        _files: files,
        client,
        url: format!("http://127.0.0.1:{port}"),
        bus,
    }
}

/// A robotd with the config file `config` driving the `robotd fake-niryo` already listening on
/// `robot_port` (its ground truth served on `namespace`, which robotd joins too), and an MCP
/// client of it.
pub async fn lab_on_running_fake_niryo(
    namespace: &str,
    robot_port: u16,
    config: &str,
    time_scale: f64,
) -> Lab {
    let port = common::free_port();
    let time_scale = format!("robot.time_scale={time_scale}");
    let robotd =
        start_robotd_on_fake_niryo(namespace, port, robot_port, config, &["--set", &time_scale]);
    let client = connect(&format!("http://127.0.0.1:{port}/sse"), None)
        .await
        .unwrap();
    Lab {
        _robotd: robotd,
        _fake: None,
        _files: None,
        client,
        url: format!("http://127.0.0.1:{port}"),
        bus: Bus::open(BusOptions::new(namespace, "scenario-test")).unwrap(),
    }
}

/// `robotd serve` on HTTP `port` with the config file `config` and `extra` settings, driving
/// the fake Ned2 on `robot_port` through the niryo driver.
fn start_robotd_on_fake_niryo(
    namespace: &str,
    port: u16,
    robot_port: u16,
    config: &str,
    extra: &[&str],
) -> common::Running {
    let robot_port = format!("robot.port={robot_port}");
    let mut settings = vec![
        "--config",
        config,
        "--set",
        "robot.host=127.0.0.1",
        "--set",
        &robot_port,
        "--set",
        "robot.camera.fps=15",
    ];
    settings.extend(extra);
    common::start_robotd(namespace, port, &settings)
}

/// The config of a WidowX lab in `dir`: the scene of `extra`'s `robot.scene=…` (or the Ned2's
/// default scene) moved to the WidowX, on the Ned2's sheet seen from the WidowX's observation
/// pose, the servo bus at `dir/ttyDXL`.
fn widowx_lab_config(dir: &std::path::Path, extra: &[String]) -> std::path::PathBuf {
    let scene_path = extra
        .iter()
        .find_map(|s| s.strip_prefix("robot.scene="))
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/scenes/default.toml")
        });
    let scene = std::fs::read_to_string(&scene_path).unwrap();
    assert!(
        scene.contains("robot = \"ned2\""),
        "{}: a Ned2 scene",
        scene_path.display()
    );
    let scene = scene.replace("robot = \"ned2\"", "robot = \"widowx250\"");
    let scene_file = dir.join("scene.toml");
    std::fs::write(&scene_file, scene).unwrap();
    let config = format!(
        r#"[robot]
driver = "widowx"
control_rate_hz = 100
scene = "{scene}"

[robot.camera]
fps = 15.0

[[robot.workspaces]]
id = "niryo_ws"
upper_left = [0.337, 0.087]
lower_right = [0.163, -0.087]
observation_pose = [0.30, 0.0, 0.25, 0.0, 0.0, 0.0]

[robot.widowx]
device = "{device}"
camera_latency_ms = 100
"#,
        scene = scene_file.display(),
        device = dir.join("ttyDXL").display(),
    );
    let path = dir.join("robot.toml");
    std::fs::write(&path, config).unwrap();
    path
}

/// [`lab_with`] at time scale 0.05, with an optional scene setting.
pub async fn lab(scene_setting: Option<String>) -> Lab {
    lab_with(0.05, &scene_setting.into_iter().collect::<Vec<_>>()).await
}

impl Lab {
    /// Calls `tool`; its reply text and `structuredContent.data` (`Null` when absent).
    pub async fn call(&self, tool: &str, args: Value) -> (String, Value) {
        let mut params = CallToolRequestParams::new(tool.to_owned());
        if let Value::Object(map) = args {
            params = params.with_arguments(map);
        }
        let result = self.client.call_tool(params).await.unwrap();
        let text = result.content[0].as_text().unwrap().text.clone();
        let data = result
            .structured_content
            .map(|s| s["data"].clone())
            .unwrap_or(Value::Null);
        eprintln!("{tool}: {}", text.lines().next().unwrap_or(""));
        (text, data)
    }

    /// Calls `tool` and asserts that it succeeded.
    pub async fn ok(&self, tool: &str, args: Value) -> Value {
        let (text, data) = self.call(tool, args).await;
        assert!(text.starts_with('✓'), "{tool}: {text}");
        data
    }

    /// What the camera sees: label, [x, y] (centre of mass) and area of each object.
    pub async fn seen(&self) -> Vec<(String, [f64; 2], f64)> {
        let data = self.ok("get_detected_objects", serde_json::json!({})).await;
        seen_in(&data)
    }

    /// The simulator's ground truth.
    pub async fn truth(&self) -> Vec<SimObjectState> {
        let client = self.bus.client(&SIM_WORLD).unwrap();
        client
            .request(&SimWorldRequest {}, Duration::from_secs(5))
            .await
            .unwrap()
            .objects
    }

    /// The ground truth of the object `label`.
    pub async fn truth_of(&self, label: &str) -> SimObjectState {
        self.truth()
            .await
            .into_iter()
            .find(|o| o.label == label)
            .unwrap_or_else(|| panic!("no {label} in the world"))
    }

    /// Moves `label` from `from` to `to` with `pick_place_object`, asserting success.
    pub async fn move_object(&self, label: &str, from: [f64; 2], to: [f64; 2]) {
        self.ok(
            "pick_place_object",
            serde_json::json!({"object_name": label, "pick_coordinate": from,
                               "place_coordinate": to}),
        )
        .await;
    }
}

/// Label, [x, y] and area of each object in a detection tool's data.
pub fn seen_in(data: &Value) -> Vec<(String, [f64; 2], f64)> {
    data.as_array()
        .map(Vec::as_slice)
        .unwrap_or_default()
        .iter()
        .map(|o| {
            let c = &o["position"]["center_of_mass"];
            (
                o["label"].as_str().unwrap_or_default().to_owned(),
                [
                    c["x"].as_f64().unwrap_or_default(),
                    c["y"].as_f64().unwrap_or_default(),
                ],
                o["dimensions"]["size_m2"].as_f64().unwrap_or_default(),
            )
        })
        .collect()
}

/// Asserts that `o` rests (not held) within `tol` metres of `at`.
pub fn assert_near(o: &SimObjectState, at: [f64; 2], tol: f64) {
    let d = ((o.x_m - at[0]).powi(2) + (o.y_m - at[1]).powi(2)).sqrt();
    assert!(
        d <= tol && !o.held,
        "{} at ({:.4}, {:.4}), wanted {at:?} (off by {:.1} mm, held {})",
        o.label,
        o.x_m,
        o.y_m,
        d * 1000.0,
        o.held
    );
}
