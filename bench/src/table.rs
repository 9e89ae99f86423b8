//! `robotd bench table`: a long, seeded random session of skill calls on the simulator, with
//! what the tools say about the table checked against the simulator's ground truth (issue 43).
//!
//! Starts `robotd serve` (this binary, the default simulated scene) on a free port, connects
//! an MCP client over streamable HTTP and a bus client of the simulator's ground truth
//! (`sim/world`), then makes `--calls` skill calls drawn from a seeded generator:
//!
//! - **free space** (40 %): an object the gripper can hold, moved with `pick_place_object` to
//!   the centre `get_largest_free_space_with_center` answers, when the object fits a square of
//!   the answered area (its longest side at most the area's square root: the tool's promise);
//!   the objects that do not are counted, not moved (a refusal of the pick itself, which does
//!   not name the centre, is not a placement);
//! - **stack** (20 %): an object put `on top of` a larger one; the next call takes the stack
//!   apart again (its top moved to the free-space centre);
//! - **push** (20 %): an object pushed 1–3 cm in a random direction;
//! - **edge** (20 %): an object moved to a random spot 15–30 mm inside a random edge of the
//!   sheet (a refusal is an answer here, not a failure).
//!
//! Before every call `get_detected_objects` is compared with the ground truth: a **phantom**
//! is a detection with no object within [`MATCH_M`] of it; a **misnamed** detection has
//! objects near it but none of its label; a **wrong height** is a detection of a stacked
//! object whose centre is more than [`HEIGHT_TOLERANCE_M`] off its true height. A **stuck
//! stack** is one whose top could not be picked off, three times in a row. The share of
//! free-space placements accepted is the figure `get_largest_free_space_with_center`
//! promises: a centre where the skills put the object down.

use super::Served;
use anyhow::{Context, Result};
use rmcp::model::CallToolRequestParams;
use robotd_mcp::client::{connect, McpClient};
use robotd_protocol::diagnostics::{SimObjectState, SimWorldRequest};
use robotd_runtime::bus::{Bus, BusOptions};
use serde::Serialize;
use serde_json::{json, Value};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A detection this close (table plane) to an object of the ground truth is of that object,
/// metres.
pub const MATCH_M: f64 = 0.025;

/// A stacked object's detected centre of mass may be this far off its true height, metres.
pub const HEIGHT_TOLERANCE_M: f64 = 0.006;

/// The default scene's sheet (niryo_ws), metres: x near … far, y right … left.
const SHEET: [f64; 4] = [0.163, 0.337, -0.087, 0.087];

/// Widest object the Ned2's gripper takes, metres (the skills refuse wider ones).
const GRIPPABLE_M: f64 = 0.036;

/// What `robotd bench table` measured.
#[derive(Debug, Default, Serialize)]
pub struct TableFigures {
    /// The generator's seed.
    pub seed: u64,
    /// Skill calls made.
    pub calls: usize,
    /// Views compared with the ground truth.
    pub views: usize,
    /// Detections with no object there.
    pub phantoms: usize,
    /// Detections of an object under another label.
    pub misnamed: usize,
    /// Detections of a stacked object more than 6 mm off its true height.
    pub wrong_heights: usize,
    /// Objects on the table no detection named (a view missing one).
    pub missed: usize,
    /// Stacks built (the upper object resting on the lower in the ground truth).
    pub stacks_built: usize,
    /// Stacks taken apart again.
    pub stacks_taken_apart: usize,
    /// Stacks whose top could not be picked off.
    pub stuck_stacks: usize,
    /// Placements at the answered free-space centre tried.
    pub free_space_places: usize,
    /// Of those, accepted and done.
    pub free_space_accepted: usize,
    /// Objects drawn for a free-space placement that did not fit the answered square (not
    /// moved).
    pub free_space_too_large: usize,
    /// Places near an edge tried, and accepted.
    pub edge_places: usize,
    /// Places near an edge accepted.
    pub edge_accepted: usize,
    /// Pushes tried.
    pub pushes: usize,
    /// Pushes done.
    pub pushes_done: usize,
    /// The first phantoms, misnamed and misplaced detections, for the report.
    pub wrong_views: Vec<String>,
    /// The first refusals of each kind of call, for the report.
    pub refusals: Vec<String>,
    /// Wall time, seconds.
    pub seconds: f64,
}

impl TableFigures {
    /// The share of free-space placements accepted, percent.
    pub fn free_space_share(&self) -> f64 {
        100.0 * self.free_space_accepted as f64 / self.free_space_places.max(1) as f64
    }

    /// The figures as a table.
    pub fn table(&self) -> String {
        let mut out = format!(
            "robotd bench table --calls {} --seed {} ({:.0} s)\n",
            self.calls, self.seed, self.seconds
        );
        let rows = [
            ("views checked", self.views.to_string()),
            ("phantoms", self.phantoms.to_string()),
            ("misnamed objects", self.misnamed.to_string()),
            (
                "stacked objects off their height",
                self.wrong_heights.to_string(),
            ),
            ("objects missed in a view", self.missed.to_string()),
            (
                "stacks built / taken apart / stuck",
                format!(
                    "{} / {} / {}",
                    self.stacks_built, self.stacks_taken_apart, self.stuck_stacks
                ),
            ),
            (
                "free-space places accepted",
                format!(
                    "{} of {} ({:.1} %)",
                    self.free_space_accepted,
                    self.free_space_places,
                    self.free_space_share()
                ),
            ),
            (
                "free-space objects larger than the answered square (not moved)",
                self.free_space_too_large.to_string(),
            ),
            (
                "edge places accepted",
                format!("{} of {}", self.edge_accepted, self.edge_places),
            ),
            (
                "pushes done",
                format!("{} of {}", self.pushes_done, self.pushes),
            ),
        ];
        for (what, value) in rows {
            out.push_str(&format!("  {what:<36} {value}\n"));
        }
        for wrong in &self.wrong_views {
            out.push_str(&format!("  seen, {wrong}\n"));
        }
        for refusal in &self.refusals {
            out.push_str(&format!("  refused, {refusal}\n"));
        }
        out
    }
}

/// A seeded xorshift generator.
struct Random(u64);

impl Random {
    fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> Option<&'a T> {
        if items.is_empty() {
            return None;
        }
        let i = ((self.unit() * items.len() as f64) as usize).min(items.len() - 1);
        items.get(i)
    }
}

/// One detection, as `get_detected_objects` gives it.
#[derive(Debug, Clone)]
struct Seen {
    label: String,
    at: [f64; 2],
    z: f64,
    /// Its footprint's sides, metres (along y, along x).
    sides: [f64; 2],
}

impl Seen {
    fn of(o: &Value) -> Option<Seen> {
        let c = &o["position"]["center_of_mass"];
        Some(Seen {
            label: o["label"].as_str()?.to_owned(),
            at: [c["x"].as_f64()?, c["y"].as_f64()?],
            z: c["z"].as_f64()?,
            sides: [
                o["dimensions"]["width_m"].as_f64()?,
                o["dimensions"]["height_m"].as_f64()?,
            ],
        })
    }

    fn grippable(&self) -> bool {
        self.sides[0].min(self.sides[1]) <= GRIPPABLE_M
    }

    /// Its footprint's longest side, metres.
    fn longest(&self) -> f64 {
        self.sides[0].max(self.sides[1])
    }
}

fn distance(a: [f64; 2], o: &SimObjectState) -> f64 {
    (a[0] - o.x_m).hypot(a[1] - o.y_m)
}

/// The session: the MCP client, the ground truth and the figures.
struct Session {
    client: McpClient,
    bus: Bus,
    figures: TableFigures,
    random: Random,
    /// The label of a stack's top waiting to be taken off, and attempts so far.
    stack_top: Option<(String, u32)>,
}

impl Session {
    async fn call(&self, tool: &str, args: Value) -> Result<(String, Value)> {
        let mut params = CallToolRequestParams::new(tool.to_owned());
        if let Value::Object(map) = args {
            params = params.with_arguments(map);
        }
        let result = self.client.call_tool(params).await?;
        let text = result
            .content
            .first()
            .and_then(|c| c.as_text())
            .map(|t| t.text.clone())
            .unwrap_or_default();
        let data = result
            .structured_content
            .map(|s| s["data"].clone())
            .unwrap_or(Value::Null);
        Ok((text, data))
    }

    async fn truth(&self) -> Result<Vec<SimObjectState>> {
        let client = self.bus.client(&robotd_topics::SIM_WORLD)?;
        Ok(client
            .request(&SimWorldRequest {}, Duration::from_secs(5))
            .await?
            .objects)
    }

    /// A fresh view, compared with the ground truth.
    async fn look(&mut self) -> Result<Vec<Seen>> {
        let (_, data) = self.call("get_detected_objects", json!({})).await?;
        let seen: Vec<Seen> = data
            .as_array()
            .map(Vec::as_slice)
            .unwrap_or_default()
            .iter()
            .filter_map(Seen::of)
            .collect();
        let truth: Vec<SimObjectState> = self
            .truth()
            .await?
            .into_iter()
            .filter(|o| !o.held)
            .collect();
        let figures = &mut self.figures;
        figures.views += 1;
        for s in &seen {
            let near: Vec<&SimObjectState> = truth
                .iter()
                .filter(|o| distance(s.at, o) <= MATCH_M)
                .collect();
            let wrong = match near.iter().find(|o| o.label == s.label) {
                Some(o) => {
                    let off = o.bottom_z_m > 0.005
                        && (s.z - (o.bottom_z_m + o.top_z_m) / 2.0).abs() > HEIGHT_TOLERANCE_M;
                    figures.wrong_heights += usize::from(off);
                    off.then_some("off its height")
                }
                None if near.is_empty() => {
                    figures.phantoms += 1;
                    Some("phantom")
                }
                None => {
                    figures.misnamed += 1;
                    Some("misnamed")
                }
            };
            if let (Some(what), true) = (wrong, figures.wrong_views.len() < 6) {
                let there: Vec<String> = near
                    .iter()
                    .map(|o| format!("{} (z {:.3})", o.label, (o.bottom_z_m + o.top_z_m) / 2.0))
                    .collect();
                figures.wrong_views.push(format!(
                    "{what}: '{}' at [{:.3}, {:.3}] z {:.3} after call {}; there: {}",
                    s.label,
                    s.at[0],
                    s.at[1],
                    s.z,
                    figures.calls,
                    there.join(", ")
                ));
            }
        }
        for o in &truth {
            if !seen
                .iter()
                .any(|s| s.label == o.label && distance(s.at, o) <= MATCH_M)
            {
                figures.missed += 1;
            }
        }
        Ok(seen)
    }

    /// Keeps the first refusals of each kind (`what`) for the report.
    fn note_refusal(&mut self, what: &str, text: &str) {
        let kind = format!("{what}: ");
        let known = self
            .figures
            .refusals
            .iter()
            .filter(|r| r.starts_with(&kind))
            .count();
        if known < 3 {
            self.figures.refusals.push(format!("{kind}{text}"));
        }
    }

    async fn free_space(&self) -> Result<(f64, [f64; 2])> {
        let (_, data) = self
            .call("get_largest_free_space_with_center", json!({}))
            .await?;
        let c = &data["center"];
        Ok((
            data["area_m2"].as_f64().unwrap_or(0.0),
            [c[0].as_f64().unwrap_or(0.25), c[1].as_f64().unwrap_or(0.0)],
        ))
    }

    async fn move_object(&self, what: &Seen, to: [f64; 2], location: &str) -> Result<String> {
        let mut args = json!({"object_name": what.label, "pick_coordinate": what.at,
                              "place_coordinate": to});
        if !location.is_empty() {
            args["location"] = json!(location);
        }
        let (text, _) = self.call("pick_place_object", args).await?;
        if text.contains("collision") {
            self.call("clear_collision_detected", json!({})).await?;
        }
        Ok(text)
    }

    /// One skill call.
    async fn step(&mut self) -> Result<()> {
        let seen = self.look().await?;
        let truth = self.truth().await?;
        // Objects in a stack (resting on another, or carrying one) in the ground truth.
        let up = |o: &SimObjectState| o.bottom_z_m > 0.005 && !o.held;
        let stacked = |s: &Seen| {
            truth.iter().any(|o| {
                distance(s.at, o) <= MATCH_M
                    && (up(o)
                        || truth.iter().any(|p| {
                            p.label != o.label && up(p) && distance([p.x_m, p.y_m], o) <= MATCH_M
                        }))
            })
        };
        if let Some((top, tries)) = self.stack_top.clone() {
            let found = seen.iter().find(|s| s.label == top).cloned();
            let (_, center) = self.free_space().await?;
            let done = match &found {
                Some(s) => {
                    let text = self.move_object(s, center, "").await?;
                    if !text.starts_with('✓') {
                        self.note_refusal("unstack", &text);
                    }
                    text.starts_with('✓')
                }
                None => false,
            };
            self.figures.calls += 1;
            if done {
                self.figures.stacks_taken_apart += 1;
                self.stack_top = None;
            } else if tries >= 2 {
                self.figures.stuck_stacks += 1;
                self.stack_top = None;
            } else {
                self.stack_top = Some((top, tries + 1));
            }
            return Ok(());
        }
        let free: Vec<Seen> = seen.iter().filter(|s| !stacked(s)).cloned().collect();
        let grippable: Vec<Seen> = free.iter().filter(|s| s.grippable()).cloned().collect();
        let roll = self.random.unit();
        if roll < 0.4 {
            let Some(what) = self.random.pick(&grippable).cloned() else {
                return Ok(());
            };
            let (area, center) = self.free_space().await?;
            if what.longest() > area.sqrt() {
                self.figures.free_space_too_large += 1;
                return Ok(());
            }
            let text = self.move_object(&what, center, "").await?;
            // A refusal of the pick (the fingers would hit a neighbour where the object lies)
            // says nothing about the place: the place's refusals name its coordinate.
            let at = format!("[{:.3}, {:.3}]", center[0], center[1]);
            if text.starts_with('✓') {
                self.figures.free_space_places += 1;
                self.figures.free_space_accepted += 1;
            } else if text.contains(&at) {
                self.figures.free_space_places += 1;
                self.note_refusal("free space", &text);
            } else {
                self.note_refusal("free space pick", &text);
            }
        } else if roll < 0.6 {
            // A smaller object onto a larger one.
            let pairs: Vec<(Seen, Seen)> = grippable
                .iter()
                .flat_map(|upper| {
                    free.iter()
                        .filter(|lower| {
                            lower.label != upper.label
                                && upper.sides[0].max(upper.sides[1])
                                    <= lower.sides[0].min(lower.sides[1]) + 0.004
                        })
                        .map(|lower| (upper.clone(), lower.clone()))
                        .collect::<Vec<_>>()
                })
                .collect();
            let Some((upper, lower)) = self.random.pick(&pairs).cloned() else {
                return Ok(());
            };
            let text = self.move_object(&upper, lower.at, "on top of").await?;
            let truth = self.truth().await?;
            let on = truth
                .iter()
                .any(|o| o.label == upper.label && o.bottom_z_m > 0.005 && !o.held);
            if text.starts_with('✓') && on {
                self.figures.stacks_built += 1;
                self.stack_top = Some((upper.label, 0));
            }
        } else if roll < 0.8 {
            let Some(what) = self.random.pick(&free).cloned() else {
                return Ok(());
            };
            let direction = *self
                .random
                .pick(&["left", "right", "up", "down"])
                .unwrap_or(&"left");
            let distance = self.random.range(0.01, 0.03);
            self.figures.pushes += 1;
            let (text, _) = self
                .call(
                    "push_object",
                    json!({"object_name": what.label, "push_coordinate": what.at,
                           "direction": direction, "distance": distance}),
                )
                .await?;
            if text.starts_with('✓') {
                self.figures.pushes_done += 1;
            } else {
                self.note_refusal("push", &text);
            }
        } else {
            let Some(what) = self.random.pick(&grippable).cloned() else {
                return Ok(());
            };
            let inset = self.random.range(0.015, 0.03);
            // Along the middle 70 % of the edge: its ends are the markers'.
            let along = self.random.range(0.15, 0.85);
            let [x_lo, x_hi, y_lo, y_hi] = SHEET;
            let to = match (self.random.unit() * 4.0) as usize {
                0 => [x_lo + inset, y_lo + along * (y_hi - y_lo)],
                1 => [x_hi - inset, y_lo + along * (y_hi - y_lo)],
                2 => [x_lo + along * (x_hi - x_lo), y_lo + inset],
                _ => [x_lo + along * (x_hi - x_lo), y_hi - inset],
            };
            self.figures.edge_places += 1;
            let text = self.move_object(&what, to, "").await?;
            if text.starts_with('✓') {
                self.figures.edge_accepted += 1;
            } else {
                self.note_refusal("edge", &text);
            }
        }
        self.figures.calls += 1;
        Ok(())
    }
}

fn free_port() -> Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// Runs the session: `calls` skill calls from `seed`, motions at `time_scale`.
pub fn run(exe: &Path, calls: usize, seed: u64, time_scale: f64) -> Result<TableFigures> {
    let namespace = format!("bench-table-{}", std::process::id());
    let port = free_port()?;
    let logs = tempfile::Builder::new()
        .prefix("robotd-bench-table-")
        .tempdir()
        .context("a temporary directory for the service's logs")?;
    let child = Command::new(exe)
        .args(["serve", "--namespace", &namespace, "--http"])
        .arg(format!("127.0.0.1:{port}"))
        .arg("--set")
        .arg(format!("robot.time_scale={time_scale}"))
        .args(["--set", "robot.camera.fps=15"])
        // The arm runs `time_scale` times real time: the per-minute motion limits of the
        // safety policy (meant for real time) would throttle the session.
        .args(["--set", "safety.motions_per_minute=0"])
        .args(["--set", "safety.llm_motions_per_minute=0"])
        .arg("--set")
        .arg(format!("telemetry.log_dir={}", logs.path().display()))
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .context("starting robotd serve")?;
    let mut served = Served(child);
    super::wait_until_serving(&mut served)?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    let started = Instant::now();
    let mut figures = runtime.block_on(async {
        let client = connect(&format!("http://127.0.0.1:{port}/mcp"), None).await?;
        let bus = Bus::open(BusOptions::new(&namespace, "bench-table"))?;
        let mut session = Session {
            client,
            bus,
            figures: TableFigures {
                seed,
                ..Default::default()
            },
            random: Random::new(seed),
            stack_top: None,
        };
        let mut steps = 0;
        while session.figures.calls < calls && steps < calls * 3 {
            steps += 1;
            let before = session.figures.calls;
            session.step().await?;
            if session.figures.calls != before && session.figures.calls.is_multiple_of(100) {
                eprint!("{}", session.figures.table());
            }
        }
        session.look().await?;
        anyhow::Ok(session.figures)
    })?;
    figures.seconds = started.elapsed().as_secs_f64();
    drop(served);
    Ok(figures)
}
