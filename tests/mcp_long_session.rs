//! A long randomized session on the simulator, as an LLM drives robotd for hours (issue 17):
//! seeded tool calls drawn from what an LLM does (detect, pick and place, relative places,
//! pushes, move2by, invalid arguments, recoveries), and after every call the reply checked
//! against the simulator's ground truth:
//!
//! - a success claims what the world shows (the object where the reply says, held or not);
//! - nothing is held that no reply announced ("silent holds", target 0), and no reply claims a
//!   hold the world does not show;
//! - invalid arguments move nothing;
//! - after any failure the documented recovery (`clear_collision_detected` after a collision,
//!   then `get_detected_objects`, then `place_object` for an object still held) works: a robot
//!   it does not bring back counts as stuck (target 0).
//!
//! `LONG_SESSION_CALLS` (default 500) and `LONG_SESSION_SEED` (default 17) choose the
//! session; the report (calls, failures by kind, collisions) is printed at the end.

mod common;
#[path = "common/lab.rs"]
mod lab;

use lab::{lab_with, runtime, seen_in, Lab};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use robotd_protocol::diagnostics::SimObjectState;
use robotd_protocol::{Direction, Location};
use serde_json::{json, Value};
use std::collections::BTreeMap;

/// The relative locations (`Location::STRINGS` starts with the six of `pick_place_object`,
/// then `close to`, then `none`).
const RELATIVE: usize = 6;
const DIRECTIONS: &[&str] = Direction::STRINGS;

/// What the session saw and counted.
#[derive(Default)]
struct Tally {
    calls: usize,
    succeeded: usize,
    failures: BTreeMap<String, usize>,
    collisions: usize,
    /// Collisions the skills should have foreseen: the camera's last list named every object
    /// on the table, and nothing else.
    unforeseen: Vec<String>,
    silent_holds: Vec<String>,
    false_claims: Vec<String>,
    stuck: Vec<String>,
}

/// A session: the robot, the random source, what the replies said.
struct Session {
    lab: Lab,
    rng: SmallRng,
    tally: Tally,
    /// The last objects a detection tool listed.
    seen: Vec<(String, [f64; 2], f64)>,
    /// The object the replies said is in the gripper.
    holding: Option<String>,
    /// Where the last pick took its object from.
    picked_from: Option<[f64; 2]>,
    /// Where the last reply that said an object is still held suggested to put it down.
    put_down_at: Option<[f64; 2]>,
}

/// A random point on the sheet, away from its edges.
fn random_point(rng: &mut SmallRng) -> [f64; 2] {
    let x = rng.random_range(0.185..0.315);
    let y = rng.random_range(-0.065..0.065);
    [
        (x * 1000.0_f64).round() / 1000.0,
        (y * 1000.0_f64).round() / 1000.0,
    ]
}

/// The kind of a failure reply, for the report.
fn failure_kind(tool: &str, text: &str) -> String {
    let kind = if text.starts_with("❌ Validation Error") {
        "invalid arguments"
    } else if text.contains("collision detected") {
        "collision"
    } else if text.contains("would not fit")
        || text.contains("would cover the marker")
        || text.contains("fingers would hit")
        || text.contains("no room")
        || text.contains("no object near")
        || text.contains("would stick out")
        || text.contains("would shove")
    {
        "placement refused"
    } else if text.contains("within 5 cm") {
        "object not found"
    } else if text.contains("holds nothing") {
        "nothing held"
    } else if text.contains("already holds") || text.contains("holds '") {
        "gripper busy"
    } else if text.contains("mm wide across the grasp") {
        "too wide"
    } else if text.contains("outside workspace") {
        "outside workspace"
    } else if text.contains("out of the arm's reach") {
        "unreachable"
    } else if text.contains("closed on nothing") {
        "grasp missed"
    } else if text.contains("refused by the safety policy") {
        "refused by the safety policy"
    } else if text.contains("unknown workspace") {
        "unknown workspace"
    } else if text.contains("moved") && tool == "push_object" {
        "push not as expected"
    } else {
        "other"
    };
    kind.to_owned()
}

fn snapshot(truth: &[SimObjectState]) -> Vec<(String, f64, f64, bool)> {
    truth
        .iter()
        .map(|o| (o.label.clone(), o.x_m, o.y_m, o.held))
        .collect()
}

fn moved(before: &[(String, f64, f64, bool)], after: &[(String, f64, f64, bool)]) -> bool {
    before
        .iter()
        .zip(after)
        .any(|(a, b)| a.3 != b.3 || (a.1 - b.1).abs() > 0.0005 || (a.2 - b.2).abs() > 0.0005)
}

impl Session {
    fn pick_seen(&mut self) -> Option<(String, [f64; 2])> {
        if self.seen.is_empty() {
            return None;
        }
        let i = self.rng.random_range(0..self.seen.len());
        Some((self.seen[i].0.clone(), self.seen[i].1))
    }

    fn place_args(&mut self, allow_close_to: bool) -> (Value, Option<[f64; 2]>) {
        if self.rng.random_bool(0.5) || self.seen.is_empty() {
            let p = random_point(&mut self.rng);
            (json!(p), Some(p))
        } else {
            let (_, at) = self.pick_seen().unwrap();
            let n = if allow_close_to {
                RELATIVE + 1
            } else {
                RELATIVE
            };
            let location = Location::STRINGS[self.rng.random_range(0..n)];
            (json!({"coordinate": at, "location": location}), None)
        }
    }

    /// One call of the grammar; returns the tool, its arguments and, for motions that claim
    /// a resting place, where the named object should end.
    fn next_call(&mut self) -> (String, Value, Option<(String, [f64; 2])>) {
        let roll = self.rng.random_range(0..100);
        let seen = self.pick_seen();
        match (roll, seen) {
            (0..=14, _) | (_, None) => ("get_detected_objects".into(), json!({}), None),
            (15..=39, Some((label, at))) => {
                let (place, end) = self.place_args(false);
                let mut args = json!({"object_name": label, "pick_coordinate": at});
                match place {
                    Value::Array(_) => args["place_coordinate"] = place,
                    Value::Object(o) => {
                        args["place_coordinate"] = o["coordinate"].clone();
                        args["location"] = o["location"].clone();
                    }
                    _ => {}
                }
                (
                    "pick_place_object".into(),
                    args,
                    end.map(|e| (label.clone(), e)),
                )
            }
            (40..=47, Some((label, at))) => (
                "pick_object".into(),
                json!({"object_name": label, "pick_coordinate": at}),
                None,
            ),
            (48..=57, _) => {
                let (place, end) = self.place_args(true);
                let args = match place {
                    Value::Array(_) => json!({"place_coordinate": place}),
                    Value::Object(o) => {
                        json!({"place_coordinate": o["coordinate"], "location": o["location"]})
                    }
                    _ => json!({}),
                };
                let claim = match (&self.holding, end) {
                    (Some(label), Some(e)) => Some((label.clone(), e)),
                    _ => None,
                };
                ("place_object".into(), args, claim)
            }
            (58..=69, Some((label, at))) => {
                let direction = DIRECTIONS[self.rng.random_range(0..4)];
                let distance = self.rng.random_range(10..=40) as f64;
                (
                    "push_object".into(),
                    json!({"object_name": label, "push_coordinate": at,
                           "direction": direction, "distance": distance}),
                    None,
                )
            }
            (70..=77, Some((label, at))) => {
                let direction = DIRECTIONS[self.rng.random_range(0..4)];
                let distance = self.rng.random_range(1..=5) as f64 / 100.0;
                let end = match direction {
                    "up" => [at[0] + distance, at[1]],
                    "down" => [at[0] - distance, at[1]],
                    "left" => [at[0], at[1] + distance],
                    _ => [at[0], at[1] - distance],
                };
                (
                    "move2by".into(),
                    json!({"object_name": label, "pick_coordinate": at,
                           "direction": direction, "distance": distance}),
                    Some((label, end)),
                )
            }
            (78..=89, Some((label, at))) => {
                let bad = [
                    (
                        "pick_object",
                        json!({"object_name": "", "pick_coordinate": at}),
                    ),
                    (
                        "pick_place_object",
                        json!({"object_name": label, "pick_coordinate": [at[0]],
                               "place_coordinate": [0.25, 0.0]}),
                    ),
                    (
                        "pick_place_object",
                        json!({"object_name": label, "pick_coordinate": at,
                               "place_coordinate": [0.25, 0.0], "z_offset": 0.5}),
                    ),
                    (
                        "push_object",
                        json!({"object_name": label, "push_coordinate": at,
                               "direction": "sideways", "distance": 20.0}),
                    ),
                    (
                        "place_object",
                        json!({"place_coordinate": [0.25, 0.0], "location": "sideways"}),
                    ),
                    (
                        "pick_object",
                        json!({"object_name": "unicorn", "pick_coordinate": at}),
                    ),
                    (
                        "pick_place_object",
                        json!({"object_name": label, "pick_coordinate": at,
                               "place_coordinate": [99.9, 99.9]}),
                    ),
                    ("move2observation_pose", json!({"workspace_id": "nope_ws"})),
                ];
                let (tool, args) = bad[self.rng.random_range(0..bad.len())].clone();
                (tool.into(), args, None)
            }
            (90..=94, _) => {
                let tool = [
                    "clear_collision_detected",
                    "move2observation_pose",
                    "calibrate",
                ][self.rng.random_range(0..3)];
                let args = if tool == "move2observation_pose" {
                    json!({"workspace_id": "niryo_ws"})
                } else {
                    json!({})
                };
                (tool.into(), args, None)
            }
            _ => {
                let tool = [
                    "get_largest_free_space_with_center",
                    "get_object_labels_as_string",
                    "get_system_status",
                    "get_detected_objects_sorted",
                ][self.rng.random_range(0..4)];
                (tool.into(), json!({}), None)
            }
        }
    }

    async fn call(&mut self, tool: &str, args: Value) -> (String, Value) {
        self.tally.calls += 1;
        let (text, data) = self.lab.call(tool, args).await;
        if text.starts_with('✓') {
            self.tally.succeeded += 1;
        } else {
            *self
                .tally
                .failures
                .entry(failure_kind(tool, &text))
                .or_default() += 1;
            if text.contains("collision detected") {
                self.tally.collisions += 1;
                let mut real: Vec<String> = self
                    .lab
                    .truth()
                    .await
                    .into_iter()
                    .filter(|o| !o.held)
                    .map(|o| o.label)
                    .collect();
                let mut seen: Vec<String> = self.seen.iter().map(|s| s.0.clone()).collect();
                real.sort();
                seen.sort();
                real.retain(|l| Some(l) != self.holding.as_ref());
                seen.retain(|l| Some(l) != self.holding.as_ref());
                if real == seen {
                    self.tally
                        .unforeseen
                        .push(format!("{tool}: {text} (seen: {seen:?})"));
                }
            }
        }
        if tool.starts_with("get_detected_objects") && text.starts_with('✓') {
            self.seen = seen_in(&data);
        }
        (text, data)
    }

    /// Updates what the replies say is held.
    fn follow_holding(&mut self, tool: &str, args: &Value, text: &str) {
        if let Some(from) = args["pick_coordinate"].as_array() {
            if let (Some(x), Some(y)) = (
                from.first().and_then(Value::as_f64),
                from.get(1).and_then(Value::as_f64),
            ) {
                self.picked_from = Some([x, y]);
            }
        }
        if text.starts_with('✓') {
            match tool {
                "pick_object" => self.holding = args["object_name"].as_str().map(str::to_owned),
                "place_object" | "pick_place_object" | "move2by" => self.holding = None,
                _ => {}
            }
        } else if let Some(start) = text.rfind("; '") {
            let rest = &text[start + 3..];
            if let Some(end) = rest.find("' is still held: put it down with place_object") {
                self.holding = Some(rest[..end].to_owned());
                self.put_down_at = rest
                    .rsplit_once("e.g. at [")
                    .and_then(|(_, p)| p.strip_suffix(']'))
                    .and_then(|p| p.split_once(", "))
                    .and_then(|(x, y)| Some([x.parse().ok()?, y.parse().ok()?]));
            }
        }
    }

    /// Checks the world against what the reply claimed.
    async fn check(
        &mut self,
        step: usize,
        tool: &str,
        text: &str,
        claim: Option<(String, [f64; 2])>,
        before: &[(String, f64, f64, bool)],
    ) {
        let truth = self.lab.truth().await;
        let held: Vec<&SimObjectState> = truth.iter().filter(|o| o.held).collect();
        let world_holds = held.first().map(|o| o.label.clone());
        if world_holds != self.holding {
            let what = format!(
                "step {step} {tool}: the world holds {world_holds:?}, the replies said {:?} ({text})",
                self.holding
            );
            if world_holds.is_some() && self.holding.is_none() {
                self.tally.silent_holds.push(what);
            } else {
                self.tally.false_claims.push(what);
            }
            self.holding = world_holds.clone();
        }
        if text.starts_with('✓') {
            if let Some((label, end)) = claim {
                if let Some(o) = truth.iter().find(|o| o.label == label) {
                    let d = (o.x_m - end[0]).hypot(o.y_m - end[1]);
                    if d > 0.01 || o.held {
                        self.tally.false_claims.push(format!(
                            "step {step} {tool}: '{label}' is at ({:.3}, {:.3}) held {}, the \
                             reply put it at {end:?}: {text}",
                            o.x_m, o.y_m, o.held
                        ));
                    }
                }
            }
        }
        if text.starts_with("❌ Validation Error") && moved(before, &snapshot(&truth)) {
            self.tally.false_claims.push(format!(
                "step {step} {tool}: invalid arguments moved something"
            ));
        }
    }

    /// The documented recovery after a failure; counts the robot as stuck when it fails.
    async fn recover(&mut self, step: usize, text: &str) {
        if text.contains("collision detected") {
            let (t, _) = self.call("clear_collision_detected", json!({})).await;
            if !t.starts_with('✓') {
                self.tally
                    .stuck
                    .push(format!("step {step}: clear failed: {t}"));
            }
        }
        let (t, _) = self.call("get_detected_objects", json!({})).await;
        if !t.starts_with('✓') {
            self.tally
                .stuck
                .push(format!("step {step}: detection after a failure: {t}"));
            return;
        }
        if let Some(label) = self.holding.clone() {
            // Where to put it down: where the reply suggested, the largest free space, where
            // it came from.
            let (_, data) = self
                .call("get_largest_free_space_with_center", json!({}))
                .await;
            let spots: Vec<[f64; 2]> = self
                .put_down_at
                .into_iter()
                .chain(
                    data["center"]
                        .as_array()
                        .and_then(|c| Some([c.first()?.as_f64()?, c.get(1)?.as_f64()?])),
                )
                .chain(self.picked_from)
                .collect();
            let mut last = String::new();
            for to in spots {
                let (t, _) = self
                    .call("place_object", json!({"place_coordinate": to}))
                    .await;
                self.follow_holding("place_object", &json!({}), &t);
                if t.starts_with('✓') || self.holding.is_none() {
                    return;
                }
                // A place that collided leaves the flag set: clear it before the next spot, or
                // the arm refuses that one before the planner sees it.
                if t.contains("collision detected") {
                    self.call("clear_collision_detected", json!({})).await;
                }
                last = t;
            }
            self.tally.stuck.push(format!(
                "step {step}: '{label}' could not be put down anywhere: {last}"
            ));
        }
    }
}

#[test]
fn a_long_random_session_never_strands_the_robot_and_every_reply_tells_the_truth() {
    let calls: usize = std::env::var("LONG_SESSION_CALLS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(500);
    let seed: u64 = std::env::var("LONG_SESSION_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(17);
    runtime().block_on(async {
        // Motions run 50 times faster than real ones: the per-minute rate limit (made for real
        // time, tested in safety_service) would refuse what the session is about.
        let lab = lab_with(0.02, &["safety.llm_motions_per_minute=0".to_owned()]).await;
        let mut session = Session {
            lab,
            rng: SmallRng::seed_from_u64(seed),
            tally: Tally::default(),
            seen: Vec::new(),
            holding: None,
            picked_from: None,
            put_down_at: None,
        };
        let started = std::time::Instant::now();
        let mut step = 0;
        while session.tally.calls < calls {
            step += 1;
            let (tool, args, claim) = session.next_call();
            let before = snapshot(&session.lab.truth().await);
            let (text, _) = session.call(&tool, args.clone()).await;
            session.follow_holding(&tool, &args, &text);
            session.check(step, &tool, &text, claim, &before).await;
            if !text.starts_with('✓') && !text.starts_with("❌ Validation Error") {
                session.recover(step, &text).await;
            }
        }
        let t = &session.tally;
        eprintln!(
            "\nlong session (seed {seed}): {} calls in {:.0} s, {} succeeded, {} collisions \
             ({} with every object seen as it is), {} silent holds, {} false claims, {} stuck",
            t.calls,
            started.elapsed().as_secs_f64(),
            t.succeeded,
            t.collisions,
            t.unforeseen.len(),
            t.silent_holds.len(),
            t.false_claims.len(),
            t.stuck.len()
        );
        for (kind, n) in &t.failures {
            eprintln!("  failures: {kind}: {n}");
        }
        for line in t
            .silent_holds
            .iter()
            .chain(&t.false_claims)
            .chain(&t.stuck)
            .chain(&t.unforeseen)
        {
            eprintln!("  ! {line}");
        }
        assert!(t.calls >= calls);
        assert!(t.succeeded > t.calls / 3, "most calls should work");
        assert!(
            t.silent_holds.is_empty(),
            "silent holds: {:#?}",
            t.silent_holds
        );
        assert!(
            t.false_claims.is_empty(),
            "false claims: {:#?}",
            t.false_claims
        );
        assert!(t.stuck.is_empty(), "stuck: {:#?}", t.stuck);
        // A collision the camera could not foresee (an object hidden behind another, two
        // seen as one) is recovered from like any other; one the skills could have foreseen
        // is a planning miss.
        assert!(
            t.unforeseen.is_empty(),
            "collisions with every object seen: {:#?}",
            t.unforeseen
        );
    });
}
