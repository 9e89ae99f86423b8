//! # robotd-tools: the one tool registry
//!
//! robotd's robot tools (`docs/mcp-tools.md`: the Python server's 20 plus `emergency_stop`
//! and `release_emergency_stop`) are defined here once — name, description,
//! typed parameters with their JSON Schema, validation, reply texts, and a handler that sends
//! bus requests to the actors (skills, workspace model, arm, speech). The MCP edge serves this
//! registry over SSE, streamable HTTP and stdio; the LLM agent calls it in process. Nothing
//! here knows about MCP or HTTP.
//!
//! A call returns a [`ToolOutput`]: the contract's text (`✓ …` or `❌ …`), whether it is a
//! failure, and the typed `data` behind `structuredContent`. Failures are ordinary outputs;
//! only an unknown tool is an `Err`.
//!
//! ```no_run
//! # async fn demo(bus: robotd_runtime::bus::Bus, settings: robotd_tools::ToolSettings)
//! # -> Result<(), Box<dyn std::error::Error>> {
//! use robotd_tools::{CallHooks, Registry};
//! let registry = Registry::connect(&bus, settings)?;
//! let args = serde_json::json!({"workspace_id": "niryo_ws", "point": "center point"});
//! let out = registry
//!     .call("get_workspace_coordinate_from_point", args.as_object().cloned(), CallHooks::default())
//!     .await?;
//! assert_eq!(out.text, "✓ Coordinate of 'center point' in workspace 'niryo_ws': [0.250, 0.000]");
//! # Ok(()) }
//! ```
//!
//! ## Modules
//!
//! - `tools`: one module per tool — its name, argument struct, data type and handler — and
//!   the table that dispatches calls by name. Start here to read or add a tool.
//! - [`args`]: how a call's arguments are deserialized into a tool's argument struct, every
//!   problem listed in the contract's validation error text.
//! - [`schema`]: the JSON Schemas derived from those types, and shared schema pieces.
//! - [`definitions`]: the tools as clients see them (`tools/list`).
//! - [`limits`]: every string argument's `maxLength`, and the check of it.
//! - [`backend`]: the [`ToolBackend`](backend::ToolBackend) trait an LLM agent calls tools
//!   through, and its plain data (implemented by the agent for this registry and by the MCP
//!   edge for MCP servers).
//! - `skill`, `view`: what the tools share to ask the skills actor and the workspace model.

pub mod args;
pub mod backend;
mod camera;
pub mod definitions;
pub mod limits;
pub mod picture;
pub mod schema;
mod skill;
pub mod timings;
mod tools;
mod view;

pub use definitions::ToolInfo;

use robotd_protocol::arm::{ArmCommand, ArmReply, ArmState};
use robotd_protocol::health::{EStopRelease, EStopState, EmergencyStop};
use robotd_protocol::skills::{SkillCancel, SkillProgress, SkillReply, SkillRequest};
use robotd_protocol::speech::{SpeakRequest, TextOverlay};
use robotd_protocol::workspace::{WorkspaceInfo, WorkspaceQuery, WorkspaceReply};
use robotd_protocol::Pose;
use robotd_runtime::bus::{Bus, BusError, Client, Publisher};
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

/// The argument name under which an edge hands a tool that must act whatever it is sent
/// ([`ALWAYS_ACTS`]) arguments that were not a JSON object (`"arguments": 5`). No tool declares
/// it, so any other tool refuses it as an unknown argument.
pub const ARGUMENTS_NOT_AN_OBJECT: &str = "(arguments)";

/// The tools that act whatever their arguments: an edge passes them a call it would refuse
/// for its form (arguments that are not an object), wrapped under [`ARGUMENTS_NOT_AN_OBJECT`].
/// Only `emergency_stop`: a request to stop is never refused.
pub const ALWAYS_ACTS: &[&str] = &["emergency_stop"];

/// The workspace model's label limit by default (`workspace.max_label_chars`).
pub const DEFAULT_MAX_LABEL_CHARS: usize = 100;

/// Extra status for `get_system_status` (actor health, restarts, e-stop), as JSON.
pub type StatusSource = Arc<dyn Fn() -> serde_json::Value + Send + Sync>;

/// What the registry needs to know about this robotd.
#[derive(Clone)]
pub struct ToolSettings {
    /// The robot type (`robot_id` of `get_system_status`: `niryo`, `widowx`).
    pub robot_id: String,
    /// The configured workspaces; the first is the robot's current one.
    pub workspaces: Vec<WorkspaceInfo>,
    /// Actor health, restarts and e-stop for `get_system_status`.
    pub status: StatusSource,
    /// Longest a skill (pick, place, push, …) may take.
    pub skill_timeout: Duration,
    /// Longest a workspace-model query may take (including waiting for a fresh view).
    pub query_timeout: Duration,
    /// Parallel bus clients of the workspace model (concurrent detection calls).
    pub query_clients: usize,
    /// Largest JPEG `get_camera_image` returns, bytes: a bigger picture is re-encoded at a
    /// lower quality, then made smaller, until it fits.
    pub image_max_bytes: usize,
    /// Longest label, characters (`workspace.max_label_chars`): the `maxLength` of the
    /// arguments that name an object ([`limits::LABEL_FIELDS`]).
    pub max_label_chars: usize,
}

impl std::fmt::Debug for ToolSettings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ToolSettings")
            .field("robot_id", &self.robot_id)
            .field("workspaces", &self.workspaces.len())
            .finish()
    }
}

impl ToolSettings {
    /// Settings with the usual timeouts and no extra status.
    pub fn new(robot_id: impl Into<String>, workspaces: Vec<WorkspaceInfo>) -> Self {
        Self {
            robot_id: robot_id.into(),
            workspaces,
            status: Arc::new(|| serde_json::json!({})),
            skill_timeout: Duration::from_secs(180),
            query_timeout: Duration::from_secs(20),
            query_clients: 8,
            image_max_bytes: picture::DEFAULT_MAX_BYTES,
            max_label_chars: DEFAULT_MAX_LABEL_CHARS,
        }
    }
}

/// One step of a running tool, for MCP progress notifications.
#[derive(Debug, Clone, PartialEq)]
pub struct Progress {
    /// Steps done.
    pub step: u32,
    /// Steps in all.
    pub total: u32,
    /// What is being done.
    pub message: String,
}

/// How a caller follows and stops a call.
#[derive(Default)]
pub struct CallHooks {
    /// Called for each step of a motion tool.
    pub progress: Option<Box<dyn Fn(Progress) + Send + Sync>>,
    /// Cancelling it stops a running motion (the arm stops and holds) and ends the call.
    pub cancel: CancellationToken,
}

/// A picture a tool returns beside its text (MCP `ImageContent`): only `get_camera_image`
/// returns one.
#[derive(Clone, PartialEq, Eq)]
pub struct ToolImage {
    /// The file's media type, `image/jpeg`.
    pub mime_type: &'static str,
    /// The encoded file.
    pub data: Vec<u8>,
}

impl std::fmt::Debug for ToolImage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ToolImage")
            .field("mime_type", &self.mime_type)
            .field("bytes", &self.data.len())
            .finish()
    }
}

impl ToolImage {
    /// The file in standard base64, as MCP carries it.
    pub fn base64(&self) -> String {
        use base64::Engine;
        base64::engine::general_purpose::STANDARD.encode(&self.data)
    }
}

/// The result of one tool call.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolOutput {
    /// The contract's reply text.
    pub text: String,
    /// True for `❌` replies (validation errors and failures).
    pub is_failure: bool,
    /// The typed payload (`structuredContent.data`), `null` on failure.
    pub data: serde_json::Value,
    /// Pictures that go with the text (empty for every tool but `get_camera_image`).
    pub images: Vec<ToolImage>,
}

impl ToolOutput {
    fn ok(text: String, data: serde_json::Value, images: Vec<ToolImage>) -> Self {
        Self {
            text,
            is_failure: false,
            data,
            images,
        }
    }

    fn failed(text: String) -> Self {
        Self {
            text,
            is_failure: true,
            data: serde_json::Value::Null,
            images: Vec::new(),
        }
    }

    /// `structuredContent`: `{"result": text, "data": data}`.
    pub fn structured(&self) -> serde_json::Value {
        serde_json::json!({"result": self.text, "data": self.data})
    }
}

/// Why a call could not be made at all (a protocol error, not a tool failure).
#[derive(Debug, thiserror::Error)]
pub enum CallError {
    /// No tool has this name.
    #[error("unknown tool '{name}'")]
    UnknownTool {
        /// The name asked for.
        name: String,
    },
}

/// Why the registry could not connect to the bus.
#[derive(Debug, thiserror::Error)]
pub enum ConnectError {
    /// A bus port could not be created.
    #[error("tool registry: {0}")]
    Bus(#[from] BusError),
    /// No workspace is configured.
    #[error("tool registry: no workspace is configured; the robot's scene must define one")]
    NoWorkspace,
}

/// Where the arm is and when it last came to rest, from `arm/state`.
#[derive(Debug, Clone, Copy)]
struct ArmRest {
    pose: Pose,
    moving: bool,
    /// Wall-clock time the arm was last seen coming to rest (0 = never seen moving).
    rested_since_unix_ns: u64,
}

struct Inner {
    settings: ToolSettings,
    tools: Vec<ToolInfo>,
    queries: Vec<Client<WorkspaceQuery, WorkspaceReply>>,
    next_query: AtomicUsize,
    skills: Client<SkillRequest, SkillReply>,
    arm: Client<ArmCommand, ArmReply>,
    cancel: Mutex<Publisher<SkillCancel>>,
    estop: Mutex<Publisher<EmergencyStop>>,
    release: Client<EStopRelease, EStopState>,
    speak: Mutex<Publisher<SpeakRequest>>,
    overlay: Mutex<Publisher<TextOverlay>>,
    arm_rest: watch::Receiver<Option<ArmRest>>,
    progress_routes: Arc<Mutex<HashMap<u64, mpsc::UnboundedSender<SkillProgress>>>>,
    next_run: AtomicU64,
    /// The bus, for the camera thread opened by the first `get_camera_image`.
    bus: Bus,
    camera: Mutex<Option<camera::Grabber>>,
    background: Vec<tokio::task::JoinHandle<()>>,
}

impl Drop for Inner {
    fn drop(&mut self) {
        for task in &self.background {
            task.abort();
        }
    }
}

/// The tool registry, connected to the bus. Cheap to clone; share one per process.
#[derive(Clone)]
pub struct Registry {
    inner: Arc<Inner>,
}

impl std::fmt::Debug for Registry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Registry")
            .field("tools", &self.inner.tools.len())
            .finish()
    }
}

impl Registry {
    /// Connects the registry's bus clients. Must be called inside a tokio runtime.
    pub fn connect(bus: &Bus, settings: ToolSettings) -> Result<Self, ConnectError> {
        if settings.workspaces.is_empty() {
            return Err(ConnectError::NoWorkspace);
        }
        let queries = (0..settings.query_clients.max(1))
            .map(|_| bus.client(&robotd_topics::WORKSPACE_QUERY))
            .collect::<Result<Vec<_>, _>>()?;
        let (rest_tx, rest_rx) = watch::channel(None);
        let mut arm_states = bus.subscriber(&robotd_topics::ARM_STATE)?;
        let watcher = tokio::spawn(async move {
            let mut last: Option<ArmRest> = None;
            while let Ok(envelope) = arm_states.recv().await {
                let state: ArmState = envelope.body;
                // The arm says since when it stands still; older senders do not, and then
                // the first state of a rest counts.
                let rested_since_unix_ns = match last {
                    _ if !state.moving && state.still_since_unix_ns > 0 => {
                        state.still_since_unix_ns
                    }
                    Some(prev) if prev.moving && !state.moving => {
                        robotd_protocol::envelope::unix_now_ns()
                    }
                    Some(prev) => prev.rested_since_unix_ns,
                    None => 0,
                };
                let now = ArmRest {
                    pose: state.tool_pose,
                    moving: state.moving,
                    rested_since_unix_ns,
                };
                last = Some(now);
                if rest_tx.send(Some(now)).is_err() {
                    break;
                }
            }
        });
        let routes: Arc<Mutex<HashMap<u64, mpsc::UnboundedSender<SkillProgress>>>> = Arc::default();
        let mut progress = bus.subscriber(&robotd_topics::SKILLS_PROGRESS)?;
        let progress_routes = routes.clone();
        let router = tokio::spawn(async move {
            while let Ok(envelope) = progress.recv().await {
                let p = envelope.body;
                let routes = progress_routes.lock().unwrap_or_else(|e| e.into_inner());
                if let Some(tx) = routes.get(&p.run_id) {
                    let _ = tx.send(p);
                }
            }
        });
        // Run ids unique across processes sharing the skills actor.
        let run_base = (u64::from(std::process::id()) << 40)
            ^ (robotd_protocol::envelope::unix_now_ns() & 0xFF_FFFF_0000);
        let mut tools = definitions::all();
        for tool in &mut tools {
            limits::apply_label_limit(&mut tool.input_schema, settings.max_label_chars);
        }
        Ok(Self {
            inner: Arc::new(Inner {
                tools,
                queries,
                next_query: AtomicUsize::new(0),
                skills: bus.client(&robotd_topics::SKILLS_RUN)?,
                arm: bus.client(&robotd_topics::ARM_COMMAND)?,
                cancel: Mutex::new(bus.publisher(&robotd_topics::SKILLS_CANCEL)?),
                estop: Mutex::new(bus.publisher(&robotd_topics::SAFETY_ESTOP)?),
                release: bus.client(&robotd_topics::SAFETY_RELEASE)?,
                speak: Mutex::new(bus.publisher(&robotd_topics::SPEECH_SPEAK)?),
                overlay: Mutex::new(bus.publisher(&robotd_topics::OVERLAY_TEXT)?),
                arm_rest: rest_rx,
                progress_routes: routes,
                next_run: AtomicU64::new(run_base),
                bus: bus.clone(),
                camera: Mutex::new(None),
                background: vec![watcher, router],
                settings,
            }),
        })
    }

    /// Every tool, in the contract's order.
    pub fn tools(&self) -> &[ToolInfo] {
        &self.inner.tools
    }

    /// The ids of the configured workspaces, the robot's current one first.
    pub fn workspace_ids(&self) -> Vec<String> {
        let workspaces = &self.inner.settings.workspaces;
        workspaces.iter().map(|w| w.id.clone()).collect()
    }

    /// The tool called `name`, if there is one.
    pub fn tool(&self, name: &str) -> Option<&ToolInfo> {
        self.inner.tools.iter().find(|t| t.name == name)
    }

    /// Calls tool `name` with `arguments` (a JSON object; `None` = no arguments).
    pub async fn call(
        &self,
        name: &str,
        arguments: Option<serde_json::Map<String, serde_json::Value>>,
        hooks: CallHooks,
    ) -> Result<ToolOutput, CallError> {
        let tool = tools::find(name).ok_or_else(|| CallError::UnknownTool {
            name: name.to_owned(),
        })?;
        let args = arguments.unwrap_or_default();
        // Strings over their schema's maxLength; a request to stop acts whatever it is sent.
        let too_long = match self.tool(name) {
            Some(info) if !ALWAYS_ACTS.contains(&name) => {
                limits::too_long(&info.input_schema, &args)
            }
            _ => Vec::new(),
        };
        let started = std::time::Instant::now();
        let output = (tool.call)(self, &args, hooks, too_long).await;
        timings::record(name, started.elapsed(), !output.is_failure);
        Ok(output)
    }

    fn query_client(&self) -> &Client<WorkspaceQuery, WorkspaceReply> {
        let queries = &self.inner.queries;
        let i = self.inner.next_query.fetch_add(1, Ordering::Relaxed) % queries.len();
        &queries[i]
    }

    fn settings(&self) -> &ToolSettings {
        &self.inner.settings
    }

    /// The camera thread, started on first use (a registry that never shows a picture opens
    /// no camera port).
    fn camera(&self) -> Result<camera::Grabber, String> {
        let mut slot = self.inner.camera.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(grabber) = slot.as_ref() {
            if grabber.is_running() {
                return Ok(grabber.clone());
            }
        }
        let grabber = camera::Grabber::start(self.inner.bus.clone())
            .map_err(|e| format!("the camera reader could not start: {e}"))?;
        *slot = Some(grabber.clone());
        Ok(grabber)
    }
}
