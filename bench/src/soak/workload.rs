//! What the soak does to the service: MCP clients coming and going on both transports, a
//! long-lived session, detection and motion tools, agent requests to the mock LLM; and the
//! faults from outside: Redis stopped and started again, the external actor killed.

use super::sampler::{CallLog, MotionLog, Outcome};
use super::service::{self, Served, EXTERNAL_ACTOR};
use anyhow::Result;
use rmcp::model::CallToolRequestParams;
use robotd_agent::mock::{MockLlm, MockReply};
use robotd_mcp::client::{connect, McpClient};
use robotd_protocol::agent::AgentRequest;
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::{AGENT_EVENTS, AGENT_REQUEST};
use serde_json::{json, Map, Value};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Pause between two visiting clients.
const VISITOR_INTERVAL: Duration = Duration::from_secs(1);

/// Longest a tool call may take before it counts as lost.
const CALL_TIMEOUT: Duration = Duration::from_secs(60);

/// Where the pencil started and was last seen, and how its last moves went. Visits move it
/// 1 cm left of where it started and back; one that ended up elsewhere (a failed move, a
/// recovery) is put back where it started, which was free when the scene was made.
#[derive(Debug, Clone)]
struct PencilTrack {
    home: Option<(f64, f64)>,
    last_seen: (f64, f64),
    /// Moves in a row that failed for another reason than an injected fault.
    failures: u32,
}

/// What a visit does with the pencil.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum PencilMove {
    /// `move2by` 1 cm this way.
    By(&'static str),
    /// `pick_place_object` back where it started.
    Home,
    /// `push_object` 2 cm this way, toward where it started: picking it was refused too
    /// (another object next to it, as the refusal says: "move one of them apart first").
    Push(&'static str),
}

/// Farthest from where it started that the pencil is still moved 1 cm at a time, metres.
const NEAR_HOME_M: f64 = 0.015;

impl PencilTrack {
    fn new() -> Self {
        Self {
            home: None,
            last_seen: (0.22, -0.05),
            failures: 0,
        }
    }

    /// The next move of the pencil seen at `at`.
    fn next_move(&mut self, at: (f64, f64)) -> PencilMove {
        let home = *self.home.get_or_insert(at);
        let (dx, dy) = (at.0 - home.0, at.1 - home.1);
        let near_home = dx.abs().max(dy.abs()) <= NEAR_HOME_M;
        match self.failures {
            0 if near_home && dy > 0.005 => PencilMove::By("right"),
            0 if near_home => PencilMove::By("left"),
            0 | 1 => PencilMove::Home,
            _ if dy.abs() >= dx.abs() && dy > 0.0 => PencilMove::Push("right"),
            _ if dy.abs() >= dx.abs() => PencilMove::Push("left"),
            _ if dx > 0.0 => PencilMove::Push("down"),
            _ => PencilMove::Push("up"),
        }
    }

    /// Records how `attempted` went.
    fn moved(&mut self, attempted: PencilMove, outcome: Option<Outcome>) {
        self.failures = match (outcome, attempted) {
            // Pushed closer: try picking it up again.
            (Some(Outcome::Ok), PencilMove::Push(_)) => 1,
            (Some(Outcome::Ok), _) => 0,
            // The injected gripper fault says nothing about where the pencil lies.
            (Some(Outcome::InjectedFault), _) => self.failures,
            // Picking it up was refused or failed: push it next.
            (_, PencilMove::Home) => self.failures.max(1) + 1,
            _ => self.failures + 1,
        };
    }
}

/// How often a visitor sends a request again that a restarting actor did not receive.
const READY_TRIES: usize = 10;
/// How long it waits before sending it again.
const READY_WAIT: Duration = Duration::from_millis(500);

/// Shared by the workload's tasks.
pub struct Workload {
    pub start: Instant,
    pub end: Instant,
    pub port: u16,
    pub calls: CallLog,
    /// Tool calls sent by the MCP clients (each counted before it is sent).
    pub tool_calls_sent: AtomicU64,
    pub sessions: AtomicU64,
    pub motions: MotionLog,
}

fn arguments(v: Value) -> Map<String, Value> {
    v.as_object().cloned().unwrap_or_default()
}

impl Workload {
    fn running(&self) -> bool {
        Instant::now() < self.end
    }

    /// One tool call, timed and classified; the reply's text and structured content, or None
    /// when no answer came.
    async fn call_full(
        &self,
        client: &McpClient,
        tool: &str,
        args: Value,
    ) -> Option<(String, Value)> {
        let started = Instant::now();
        let since = started - self.start;
        let params = CallToolRequestParams::new(tool.to_owned()).with_arguments(arguments(args));
        self.tool_calls_sent.fetch_add(1, Ordering::Relaxed);
        match tokio::time::timeout(CALL_TIMEOUT, client.call_tool(params)).await {
            Ok(Ok(result)) => {
                let text = result
                    .content
                    .first()
                    .and_then(|c| c.as_text())
                    .map(|t| t.text.clone())
                    .unwrap_or_default();
                let outcome = Outcome::of_reply(&text);
                self.calls.example(outcome, tool, &text);
                self.calls.record(since, started.elapsed(), outcome);
                Some((text, result.structured_content.unwrap_or(Value::Null)))
            }
            Ok(Err(error)) => {
                self.calls.example(Outcome::Lost, tool, &error.to_string());
                self.calls.record(since, started.elapsed(), Outcome::Lost);
                None
            }
            Err(_) => {
                let text = format!("no answer within {} s", CALL_TIMEOUT.as_secs());
                self.calls.example(Outcome::Lost, tool, &text);
                self.calls.record(since, started.elapsed(), Outcome::Lost);
                None
            }
        }
    }

    /// [`Self::call_full`] for its text only.
    async fn call(&self, client: &McpClient, tool: &str, args: Value) -> Option<String> {
        self.call_full(client, tool, args)
            .await
            .map(|(text, _)| text)
    }

    /// What a user does when a motion left the arm stuck: clears the collision flag, and puts
    /// down an object the gripper still holds where the pencil was last seen, or, when that is
    /// refused, where the reply suggests (`… put it down with place_object, e.g. at [x, y]`).
    /// Returns whether the object was put down somewhere else.
    async fn recover_like_a_user(
        &self,
        client: &McpClient,
        reply: Option<&str>,
        at: (f64, f64),
    ) -> bool {
        let Some(reply) = reply else {
            return false;
        };
        if reply.contains("clear_collision_detected") {
            self.call(client, "clear_collision_detected", json!({}))
                .await;
        }
        if reply.contains("still held") {
            // Where it was first; if that is refused too, where the reply suggests.
            let placed = self.place_when_ready(client, at).await;
            let still_held = placed.as_deref().is_some_and(|r| r.contains("still held"));
            if let Some((x, y)) = placed
                .as_deref()
                .and_then(suggested_place)
                .or_else(|| suggested_place(reply))
                .filter(|_| still_held)
            {
                self.place_when_ready(client, (x, y)).await;
                return true;
            }
        }
        false
    }

    /// `place_object` at `at`, sent again (as its reply asks) while the gripper actor is
    /// restarting after an injected fault and did not receive it; at most [`READY_TRIES`]
    /// times, [`READY_WAIT`] apart.
    async fn place_when_ready(&self, client: &McpClient, at: (f64, f64)) -> Option<String> {
        let mut placed = None;
        for _ in 0..READY_TRIES {
            placed = self
                .call(
                    client,
                    "place_object",
                    json!({"place_coordinate": [at.0, at.1]}),
                )
                .await;
            let not_received = placed
                .as_deref()
                .is_some_and(|r| r.contains("restarting") && r.contains("did not receive"));
            if !not_received {
                break;
            }
            tokio::time::sleep(READY_WAIT).await;
        }
        placed
    }

    /// Clients that come and go: each connects (SSE and streamable HTTP in turn), looks at the
    /// workspace, moves the pencil 1 cm and back toward where it started, asks cheap questions,
    /// and leaves.
    pub async fn visiting_clients(self: Arc<Self>) {
        let mut n = 0u64;
        let mut pencil = PencilTrack::new();
        while self.running() {
            n += 1;
            let url = if n.is_multiple_of(2) {
                format!("http://127.0.0.1:{}/sse", self.port)
            } else {
                format!("http://127.0.0.1:{}/mcp", self.port)
            };
            if n.is_multiple_of(10) {
                // One client in ten vanishes without a goodbye, like a client process that
                // crashed: it runs on a runtime of its own that is then dropped, closing its
                // connections; robotd must notice and forget its session.
                let work = self.clone();
                let mut track = pencil.clone();
                let joined = tokio::task::spawn_blocking(move || {
                    let runtime = tokio::runtime::Builder::new_current_thread()
                        .enable_all()
                        .build()
                        .ok()?;
                    runtime.block_on(async {
                        let client = work.connect(&url).await?;
                        work.visit(&client, &mut track).await;
                        Some(())
                    })?;
                    drop(runtime);
                    Some(track)
                })
                .await;
                if let Ok(Some(track)) = joined {
                    pencil = track;
                }
            } else if let Some(client) = self.connect(&url).await {
                self.visit(&client, &mut pencil).await;
                let _ = client.cancel().await;
            }
            tokio::time::sleep(VISITOR_INTERVAL).await;
        }
    }

    async fn connect(&self, url: &str) -> Option<McpClient> {
        match connect(url, None).await {
            Ok(client) => {
                self.sessions.fetch_add(1, Ordering::Relaxed);
                Some(client)
            }
            Err(error) => {
                self.calls
                    .example(Outcome::Lost, "connect", &error.to_string());
                self.calls
                    .record(self.start.elapsed(), Duration::ZERO, Outcome::Lost);
                None
            }
        }
    }

    /// One visit: find the pencil, move it 1 cm toward where it started, ask cheap questions.
    async fn visit(&self, client: &McpClient, pencil: &mut PencilTrack) {
        let found = self
            .call_full(client, "get_detected_objects", json!({"label": "pencil"}))
            .await;
        let at = found.as_ref().and_then(|(_, v)| {
            let at = &v["data"][0]["position"]["center_of_mass"];
            Some((at["x"].as_f64()?, at["y"].as_f64()?))
        });
        if let Some((x, y)) = at {
            pencil.last_seen = (x, y);
            let started_s = self.start.elapsed().as_secs_f64();
            let attempted = pencil.next_move((x, y));
            let (tool, args) = match attempted {
                PencilMove::By(direction) => (
                    "move2by",
                    json!({"object_name": "pencil", "pick_coordinate": [x, y],
                           "direction": direction, "distance": 0.01}),
                ),
                PencilMove::Home => {
                    let home = pencil.home.unwrap_or((x, y));
                    (
                        "pick_place_object",
                        json!({"object_name": "pencil", "pick_coordinate": [x, y],
                               "place_coordinate": [home.0, home.1]}),
                    )
                }
                PencilMove::Push(direction) => (
                    "push_object",
                    json!({"object_name": "pencil", "push_coordinate": [x, y],
                           "direction": direction, "distance": 20}),
                ),
            };
            let moved = self.call(client, tool, args).await;
            let outcome = moved.as_deref().map(Outcome::of_reply);
            self.motions.record(started_s, outcome == Some(Outcome::Ok));
            self.recover_like_a_user(client, moved.as_deref(), (x, y))
                .await;
            pencil.moved(attempted, outcome);
        } else {
            let text = found.map(|(text, _)| text);
            self.recover_like_a_user(client, text.as_deref(), pencil.last_seen)
                .await;
        }
        for _ in 0..5 {
            self.call(
                client,
                "get_workspace_coordinate_from_point",
                json!({"workspace_id": "niryo_ws", "point": "center point"}),
            )
            .await;
        }
        self.call(client, "get_system_status", json!({})).await;
    }

    /// One session for the whole soak, asking a cheap question ten times a second.
    pub async fn resident_client(self: Arc<Self>) {
        let url = format!("http://127.0.0.1:{}/mcp", self.port);
        let Ok(client) = connect(&url, None).await else {
            self.calls
                .record(self.start.elapsed(), Duration::ZERO, Outcome::Lost);
            return;
        };
        while self.running() {
            self.call(
                &client,
                "get_workspace_coordinate_from_point",
                json!({"workspace_id": "niryo_ws", "point": "upper left corner"}),
            )
            .await;
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        let _ = client.cancel().await;
    }
}

/// Agent requests answered / failed.
#[derive(Debug, Default)]
pub struct AgentTally {
    pub sent: AtomicU64,
    pub answered: AtomicU64,
    pub failed: AtomicU64,
    /// Requests that got a final event after their first one.
    pub answered_twice: AtomicU64,
}

/// Every 15 s, a request to the agent (the mock LLM plans, calls `get_detected_objects`,
/// answers); waits for its terminal event.
pub async fn agent_requests(
    work: Arc<Workload>,
    namespace: String,
    mock: Arc<MockLlm>,
    tally: Arc<AgentTally>,
) -> Result<()> {
    let bus = Bus::open(BusOptions::new(&namespace, "soak-agent-client"))?;
    let requests = bus.publisher(&AGENT_REQUEST)?;
    let mut events = bus.subscriber(&AGENT_EVENTS)?;
    let mut n = 0u64;
    let mut finished = std::collections::HashSet::new();
    while work.running() {
        n += 1;
        mock.push(MockReply::plan_and_call(
            "I look at the table first.",
            "get_detected_objects",
            json!({}),
        ));
        mock.push(MockReply::text("I see the objects on the table."));
        let request_id = format!("soak-{n}");
        tally.sent.fetch_add(1, Ordering::Relaxed);
        if requests
            .publish(&AgentRequest {
                request_id: request_id.clone(),
                text: "What is on the table?".into(),
            })
            .is_err()
        {
            tally.failed.fetch_add(1, Ordering::Relaxed);
            continue;
        }
        let deadline = Instant::now() + Duration::from_secs(60);
        let outcome = loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match tokio::time::timeout(left, events.recv()).await {
                Ok(Ok(event)) if event.body.request_id == request_id => {
                    if event.body.event.is_terminal() {
                        break Some(matches!(
                            event.body.event,
                            robotd_protocol::agent::AgentEventKind::Answer { .. }
                        ));
                    }
                }
                Ok(Ok(event)) => {
                    // An earlier request's final event: its second if one was seen already (a
                    // request given up on may still get its first, late).
                    if event.body.event.is_terminal()
                        && !finished.insert(event.body.request_id.clone())
                    {
                        tally.answered_twice.fetch_add(1, Ordering::Relaxed);
                    }
                }
                _ => break None,
            }
        };
        if outcome.is_some() {
            finished.insert(request_id);
        }
        let counter = if outcome == Some(true) {
            &tally.answered
        } else {
            &tally.failed
        };
        counter.fetch_add(1, Ordering::Relaxed);
        tokio::time::sleep(Duration::from_secs(15)).await;
    }
    Ok(())
}

/// The free spot a tool's reply suggests for an object still held: `e.g. at [x, y]`.
fn suggested_place(reply: &str) -> Option<(f64, f64)> {
    let rest = &reply[reply.find("e.g. at [")? + "e.g. at [".len()..];
    let (x, rest) = rest.split_once(',')?;
    let y = rest.split_once(']')?.0;
    Some((x.trim().parse().ok()?, y.trim().parse().ok()?))
}

/// One injected fault and whether (and how fast) the service recovered.
#[derive(Debug, Clone, serde::Serialize)]
pub struct InjectedFault {
    /// Seconds into the soak.
    pub at_s: f64,
    /// What was done.
    pub what: String,
    /// Seconds until the service was whole again; None = it never was.
    pub recovered_after_s: Option<f64>,
}

/// Kills the external actor every 40 s and stops Redis for 5 s every 60 s; records whether
/// the service recovered from each.
pub async fn inject_faults(
    work: Arc<Workload>,
    robotd_pid: u32,
    redis_port: u16,
    redis: Arc<Mutex<Option<Served>>>,
    faults: Arc<Mutex<Vec<InjectedFault>>>,
) {
    let mut next_kill = work.start + Duration::from_secs(40);
    let mut next_redis = work.start + Duration::from_secs(60);
    while work.running() {
        tokio::time::sleep(Duration::from_millis(500)).await;
        let now = Instant::now();
        if now >= next_kill {
            next_kill = now + Duration::from_secs(40);
            let Some(pid) = service::child_with(robotd_pid, "bench-peer") else {
                continue;
            };
            let _ = std::process::Command::new("kill")
                .args(["-KILL", &pid.to_string()])
                .status();
            let killed = Instant::now();
            let mut recovered = None;
            while killed.elapsed() < Duration::from_secs(10) {
                if service::child_with(robotd_pid, "bench-peer").is_some_and(|p| p != pid)
                    && actor_running(work.port, EXTERNAL_ACTOR).await
                {
                    recovered = Some(killed.elapsed().as_secs_f64());
                    break;
                }
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
            push(
                &faults,
                &work,
                killed,
                "external actor killed (SIGKILL)",
                recovered,
            );
        }
        if now >= next_redis {
            next_redis = now + Duration::from_secs(60);
            let stopped = Instant::now();
            redis.lock().unwrap_or_else(|e| e.into_inner()).take();
            tokio::time::sleep(Duration::from_secs(5)).await;
            let restarted = service::start_redis(redis_port).ok();
            let ok = restarted.is_some();
            *redis.lock().unwrap_or_else(|e| e.into_inner()) = restarted;
            let mut recovered = None;
            while ok && stopped.elapsed() < Duration::from_secs(30) {
                if redis_connected(work.port).await {
                    recovered = Some(stopped.elapsed().as_secs_f64());
                    break;
                }
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
            push(
                &faults,
                &work,
                stopped,
                "redis-server stopped for 5 s",
                recovered,
            );
        }
    }
}

fn push(
    faults: &Mutex<Vec<InjectedFault>>,
    work: &Workload,
    at: Instant,
    what: &str,
    recovered_after_s: Option<f64>,
) {
    faults
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(InjectedFault {
            at_s: (at - work.start).as_secs_f64(),
            what: what.into(),
            recovered_after_s,
        });
}

/// robotd's `/health`, if it answers within 5 s.
pub async fn health(port: u16) -> Option<Value> {
    static CLIENT: std::sync::OnceLock<reqwest::Client> = std::sync::OnceLock::new();
    let response = CLIENT
        .get_or_init(reqwest::Client::new)
        .get(format!("http://127.0.0.1:{port}/health"))
        .timeout(Duration::from_secs(5))
        .send()
        .await
        .ok()?;
    response.json().await.ok()
}

/// The service's count of tool calls answered to MCP clients over SSE and streamable HTTP
/// (`robotd_tool_calls_total` on `/metrics`), or None when it cannot be read.
pub async fn tool_calls_served(port: u16) -> Option<u64> {
    let text = reqwest::Client::new()
        .get(format!("http://127.0.0.1:{port}/metrics"))
        .timeout(Duration::from_secs(5))
        .send()
        .await
        .ok()?
        .text()
        .await
        .ok()?;
    Some(
        text.lines()
            .filter(|line| line.starts_with("robotd_tool_calls_total{"))
            .filter(|line| {
                line.contains(r#"transport="sse""#)
                    || line.contains(r#"transport="streamable_http""#)
            })
            .filter_map(|line| line.rsplit(' ').next()?.parse::<f64>().ok())
            .map(|n| n as u64)
            .sum(),
    )
}

async fn actor_running(port: u16, name: &str) -> bool {
    health(port).await.is_some_and(|h| {
        h["actors"].as_array().is_some_and(|actors| {
            actors
                .iter()
                .any(|a| a["actor"] == name && a["state"] == "running")
        })
    })
}

async fn redis_connected(port: u16) -> bool {
    health(port)
        .await
        .is_some_and(|h| h["redis"]["state"] == "connected")
}

#[cfg(test)]
mod tests {
    use super::{suggested_place, PencilMove, PencilTrack};

    use crate::soak::sampler::Outcome;

    #[test]
    fn the_pencil_goes_left_and_back_and_home_after_a_failure() {
        let mut pencil = PencilTrack::new();
        let home = (0.22, -0.05);
        assert_eq!(pencil.next_move(home), PencilMove::By("left"));
        pencil.moved(PencilMove::By("left"), Some(Outcome::Ok));
        assert_eq!(pencil.next_move((0.22, -0.04)), PencilMove::By("right"));
        // The injected gripper fault changes nothing.
        pencil.moved(PencilMove::By("right"), Some(Outcome::InjectedFault));
        assert_eq!(pencil.next_move((0.22, -0.04)), PencilMove::By("right"));
        // Put down elsewhere by a recovery: back home.
        assert_eq!(pencil.next_move((0.25, -0.002)), PencilMove::Home);
        pencil.moved(PencilMove::Home, Some(Outcome::Ok));
        assert_eq!(pencil.next_move(home), PencilMove::By("left"));
        // A refused move (another object in the way): back home, not the same move again.
        pencil.moved(PencilMove::By("left"), Some(Outcome::ToolError));
        assert_eq!(pencil.next_move(home), PencilMove::Home);
    }

    #[test]
    fn a_pencil_that_cannot_be_picked_is_pushed_toward_home() {
        let mut pencil = PencilTrack::new();
        assert_eq!(pencil.next_move((0.22, -0.05)), PencilMove::By("left"));
        pencil.moved(PencilMove::By("left"), Some(Outcome::Ok));
        // Left at [0.249, 0.001] next to the red cube; picking it is refused.
        let stuck = (0.249, 0.001);
        assert_eq!(pencil.next_move(stuck), PencilMove::Home);
        pencil.moved(PencilMove::Home, Some(Outcome::ToolError));
        assert_eq!(pencil.next_move(stuck), PencilMove::Push("right"));
        pencil.moved(PencilMove::Push("right"), Some(Outcome::ToolError));
        assert_eq!(pencil.next_move(stuck), PencilMove::Push("right"));
        pencil.moved(PencilMove::Push("right"), Some(Outcome::Ok));
        // Pushed closer: picked up and put home again.
        assert_eq!(pencil.next_move((0.249, -0.019)), PencilMove::Home);
        // Mostly off in x: pushed along x.
        pencil.moved(PencilMove::Home, Some(Outcome::ToolError));
        assert_eq!(pencil.next_move((0.30, -0.05)), PencilMove::Push("down"));
    }

    #[test]
    fn the_place_a_reply_suggests_is_read() {
        let reply = "❌ Failed to place object: 'pencil' would not fit at [0.226, -0.052]: 'green \
                     cylinder' is in the way; 'pencil' is still held: put it down with \
                     place_object, e.g. at [0.248, -0.002]";
        assert_eq!(suggested_place(reply), Some((0.248, -0.002)));
        assert_eq!(suggested_place("'pencil' is still held"), None);
        assert_eq!(suggested_place("e.g. at [x, 1]"), None);
    }
}
