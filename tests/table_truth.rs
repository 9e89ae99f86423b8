//! Issue 43, "tools that tell the truth about the table": scenarios on the default simulated
//! scene where the workspace model's picture and the simulator's ground truth must agree —
//! a stack built and taken apart, an object near the sheet's edge, the free-space centre.

mod common;
#[path = "common/lab.rs"]
mod lab;

use lab::{assert_near, lab, lab_with, runtime, seen_in, Lab};
use serde_json::{json, Value};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// The detected objects' data, after a fresh view.
async fn detected(lab: &Lab) -> Vec<Value> {
    let data = lab.ok("get_detected_objects", json!({})).await;
    data.as_array().cloned().unwrap_or_default()
}

fn xy(o: &Value) -> [f64; 2] {
    let c = &o["position"]["center_of_mass"];
    [c["x"].as_f64().unwrap(), c["y"].as_f64().unwrap()]
}

fn z(o: &Value) -> f64 {
    o["position"]["center_of_mass"]["z"].as_f64().unwrap()
}

/// The one detected object called `label`, asserting there is exactly one.
fn one<'a>(objects: &'a [Value], label: &str) -> &'a Value {
    let found: Vec<&Value> = objects.iter().filter(|o| o["label"] == label).collect();
    assert_eq!(found.len(), 1, "one '{label}' in {objects:#?}");
    found[0]
}

/// The labels detected, sorted.
fn labels(objects: &[Value]) -> Vec<String> {
    let mut l: Vec<String> = seen_in(&Value::Array(objects.to_vec()))
        .into_iter()
        .map(|s| s.0)
        .collect();
    l.sort();
    l
}

/// `(id, label)` of each object, sorted.
fn names(objects: &[Value]) -> Vec<(String, String)> {
    let mut v: Vec<(String, String)> = objects
        .iter()
        .map(|o| {
            let text = |key: &str| o[key].as_str().unwrap_or_default().to_owned();
            (text("id"), text("label"))
        })
        .collect();
    v.sort();
    v
}

/// The objects of the newest `detected_objects` entry robotd wrote to Redis after `since_s`
/// (Unix seconds), waiting for one.
fn redis_objects(conn: &mut redis::Connection, since_s: f64) -> Vec<Value> {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let newest: Vec<(String, Vec<String>)> = redis::cmd("XREVRANGE")
            .arg("detected_objects")
            .arg("+")
            .arg("-")
            .arg("COUNT")
            .arg(1)
            .query(conn)
            .expect("XREVRANGE detected_objects");
        if let Some((_, fields)) = newest.first() {
            let field = |name: &str| {
                let at = fields.iter().position(|f| f == name)?;
                fields.get(at + 1).cloned()
            };
            let time: f64 = field("timestamp")
                .and_then(|t| t.parse().ok())
                .unwrap_or(0.0);
            if time > since_s {
                let objects = field("objects").expect("an objects field");
                return serde_json::from_str(&objects).expect("objects JSON");
            }
        }
        assert!(
            Instant::now() < deadline,
            "no detected_objects entry after {since_s}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn now_s() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
}

/// A `redis-server` of its own (stopped when dropped), the `redis.url` robotd is given, and a
/// connection to read its streams.
fn redis_for_the_lab() -> (common::Running, String, redis::Connection) {
    let port = common::free_port();
    let server = common::start_redis(port);
    let url = format!("redis://127.0.0.1:{port}/0");
    let conn = redis::Client::open(url.as_str())
        .and_then(|c| c.get_connection())
        .expect("connect to the test redis-server");
    (server, url, conn)
}

const DEFAULT_LABELS: [&str; 4] = ["blue square", "green cylinder", "pencil", "red cube"];

#[test]
fn a_stack_is_one_object_on_another_and_comes_apart_again() {
    let (_redis, url, mut conn) = redis_for_the_lab();
    runtime().block_on(async {
        let lab = lab_with(0.05, &[format!("redis.url={url}")]).await;
        let objects = detected(&lab).await;
        assert_eq!(labels(&objects), DEFAULT_LABELS);
        let cylinder_at = xy(one(&objects, "green cylinder"));
        let cube_at = xy(one(&objects, "red cube"));

        lab.ok(
            "pick_place_object",
            json!({"object_name": "green cylinder", "pick_coordinate": cylinder_at,
                   "place_coordinate": cube_at, "location": "on top of"}),
        )
        .await;
        let truth_cube = lab.truth_of("red cube").await;
        let truth_cyl = lab.truth_of("green cylinder").await;
        assert!((truth_cyl.bottom_z_m - truth_cube.top_z_m).abs() < 0.003);

        // Several views: the stack is two objects, named as before, the top one at its height.
        let mut ids = None;
        for _ in 0..6 {
            let objects = detected(&lab).await;
            assert_eq!(labels(&objects), DEFAULT_LABELS, "{objects:#?}");
            let cyl = one(&objects, "green cylinder");
            let cube = one(&objects, "red cube");
            assert!(
                (z(cyl) - (truth_cube.top_z_m + 0.020)).abs() < 0.004,
                "the cylinder's centre at z {:.4}, on a cube whose top is at {:.4}",
                z(cyl),
                truth_cube.top_z_m
            );
            assert!((z(cube) - 0.015).abs() < 0.004, "cube z {:.4}", z(cube));
            let these = (cyl["id"].clone(), cube["id"].clone());
            assert_eq!(*ids.get_or_insert(these.clone()), these, "ids kept");
        }
        // Redis: the stack's top as the tools have it (at its height); what shows of the cube
        // around it, if anything, is the cube; nothing else.
        let tools = detected(&lab).await;
        let from_redis = redis_objects(&mut conn, now_s());
        let tool_names = names(&tools);
        for name in names(&from_redis) {
            assert!(tool_names.contains(&name), "{name:?} not in {tool_names:?}");
        }
        let top = one(&from_redis, "green cylinder");
        assert!(
            (z(top) - z(one(&tools, "green cylinder"))).abs() < 1e-9,
            "{top:#}"
        );

        // Take the stack apart: the cylinder first, then the cube.
        let objects = detected(&lab).await;
        let cyl_at = xy(one(&objects, "green cylinder"));
        lab.ok(
            "pick_place_object",
            json!({"object_name": "green cylinder", "pick_coordinate": cyl_at,
                   "place_coordinate": [0.30, -0.06]}),
        )
        .await;
        assert_near(&lab.truth_of("green cylinder").await, [0.30, -0.06], 0.006);
        let objects = detected(&lab).await;
        assert_eq!(labels(&objects), DEFAULT_LABELS, "{objects:#?}");
        let cube_at = xy(one(&objects, "red cube"));
        lab.ok(
            "pick_place_object",
            json!({"object_name": "red cube", "pick_coordinate": cube_at,
                   "place_coordinate": [0.28, -0.01]}),
        )
        .await;
        assert_near(&lab.truth_of("red cube").await, [0.28, -0.01], 0.006);
        let objects = detected(&lab).await;
        assert_eq!(labels(&objects), DEFAULT_LABELS, "{objects:#?}");
    });
}

#[test]
fn a_cylinder_at_the_sheets_lower_edge_has_no_phantom_neighbour() {
    let (_redis, url, mut conn) = redis_for_the_lab();
    runtime().block_on(async {
        let lab = lab_with(0.05, &[format!("redis.url={url}")]).await;
        let objects = detected(&lab).await;
        let cylinder_at = xy(one(&objects, "green cylinder"));
        // Issue 43 saw a phantom "green box" beside it at [0.185, 0.013] (here 5 mm further
        // from the blue square, whose measured edge is 0.5 mm from that footprint), and
        // `robotd bench table` saw the cylinder itself become a "green box" at [0.186, -0.024].
        let mut from = cylinder_at;
        for edge in [[0.185, 0.008], [0.186, -0.024]] {
            lab.move_object("green cylinder", from, edge).await;
            let mut ids = None;
            for view in 0..8 {
                let objects = detected(&lab).await;
                assert_eq!(
                    labels(&objects),
                    DEFAULT_LABELS,
                    "at {edge:?}, view {view}: {objects:#?}"
                );
                let mut these: Vec<String> = objects
                    .iter()
                    .map(|o| o["id"].as_str().unwrap().to_owned())
                    .collect();
                these.sort();
                assert_eq!(*ids.get_or_insert(these.clone()), these, "view {view}");
            }
            // The Redis stream names every object as the tools do, and shows nothing else.
            let since = now_s();
            let tools = names(&detected(&lab).await);
            assert_eq!(
                names(&redis_objects(&mut conn, since)),
                tools,
                "at {edge:?}"
            );
            from = xy(one(&detected(&lab).await, "green cylinder"));
        }
        // Nothing the camera made up stands in the way of taking it back.
        lab.move_object("green cylinder", from, cylinder_at).await;
        assert_near(&lab.truth_of("green cylinder").await, cylinder_at, 0.006);
    });
}

/// The names quoted ('…') in a tool's text.
fn quoted(text: &str) -> Vec<String> {
    text.split('\'')
        .skip(1)
        .step_by(2)
        .map(str::to_owned)
        .collect()
}

#[test]
fn failure_texts_name_objects_as_the_detection_tools_do() {
    runtime().block_on(async {
        let lab = lab(None).await;
        // With a stack on the table: what shows of the cube under the cylinder is no new name.
        let objects = detected(&lab).await;
        lab.ok(
            "pick_place_object",
            json!({"object_name": "green cylinder",
                   "pick_coordinate": xy(one(&objects, "green cylinder")),
                   "place_coordinate": xy(one(&objects, "red cube")), "location": "on top of"}),
        )
        .await;
        let objects = detected(&lab).await;
        let names = labels(&objects);
        let mut truth: Vec<String> = lab.truth().await.into_iter().map(|o| o.label).collect();
        truth.sort();
        assert_eq!(names, truth, "{objects:#?}");
        let mut texts = Vec::new();
        for o in &objects {
            let at = xy(o);
            let label = o["label"].as_str().unwrap();
            // Placing onto each object, pushing each into its neighbours, picking the wrong
            // name there: every refusal names what the detection tools name.
            for (tool, args) in [
                (
                    "pick_object",
                    json!({"object_name": "unicorn", "pick_coordinate": at}),
                ),
                (
                    "pick_place_object",
                    json!({"object_name": label, "pick_coordinate": at,
                           "place_coordinate": [0.25, 0.0], "location": "on top of"}),
                ),
                (
                    "push_object",
                    json!({"object_name": label, "push_coordinate": at,
                           "direction": "left", "distance": 0.15}),
                ),
            ] {
                let (text, _) = lab.call(tool, args).await;
                texts.push(text);
            }
        }
        let mut refusals = 0;
        for text in texts.iter().filter(|t| t.starts_with('❌')) {
            refusals += 1;
            for name in quoted(text) {
                if name == "unicorn" {
                    continue;
                }
                assert!(
                    names.contains(&name),
                    "'{name}' in \"{text}\" is none of {names:?}"
                );
            }
            if let Some(seen) = text.split("seen there: ").nth(1) {
                for name in seen.split(", ") {
                    assert!(names.contains(&name.to_owned()), "{name} in {text}");
                }
            }
        }
        assert!(refusals >= 4, "{texts:#?}");
    });
}

#[test]
fn robotd_bench_table_checks_a_short_session_against_the_ground_truth() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["bench", "table", "--calls", "6", "--seed", "1", "--json"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let figures: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(figures["calls"], 6, "{figures}");
    assert!(figures["views"].as_u64().unwrap() >= 6, "{figures}");
    for zero in ["phantoms", "misnamed", "wrong_heights", "stuck_stacks"] {
        assert_eq!(figures[zero], 0, "{zero}: {figures}");
    }
}
