//! robotd's scene memory: the workspace model actor.
//!
//! The detection and workspace tools (`get_detected_objects`, `get_largest_free_space_with_center`,
//! `get_workspace_coordinate_from_point`, …) are answered from here, at once, instead of moving
//! the arm and waiting for a detector on every call as the Python server does. The actor:
//!
//! - subscribes to `perception/detections` and keeps, per workspace, the objects on the table
//!   with ids that stay stable while they are tracked ([`tracker`]); only steady views (the arm
//!   stood still) of a configured workspace count. An object keeps one name however the
//!   detector relabels it between views (the label most of its recent views gave), and a new
//!   object of the built-in detector is reported only once [`CONFIRM_VIEWS`] views agree (or a
//!   skill placed it), so a one-view phantom never reaches a reply;
//! - serves `workspace/query` ([`WorkspaceQuery`]): each [`WorkspaceRequest`] of the tools
//!   ([`queries`], [`free_space`], [`labels`]), optionally "from a view taken after time t" —
//!   such a query waits (bounded) for that view while other queries are answered meanwhile
//!   (when that view left new objects unconfirmed, for the next one too, so a look-then-pick
//!   finds an object the camera has just seen; at the time limit it is answered from the view
//!   it has), and fails with [`WorkspaceError::NoFreshDetection`] when no view comes;
//! - follows what the skills do: [`WorkspaceRequest::ObjectPicked`] (the object is held, off
//!   the table) and [`WorkspaceRequest::ObjectPlaced`] (back on the table where it was put,
//!   until the camera confirms it or, not finding it, forgets it);
//! - keeps the names `label_object` gives ([`WorkspaceRequest::LabelObject`]): the named
//!   object answers to its name in every reply, in `workspace/objects` and when the skills
//!   pick by name, until it is forgotten or named again; the name joins the detectable labels;
//! - publishes the remembered objects of the workspace in view on `workspace/objects`
//!   ([`TrackedObjects`]) after every applied view, with the object each of the view's boxes
//!   was taken for (`detection_ids`: how the dashboard and the Redis stream name a view's
//!   boxes, one name per object everywhere), and the detectable labels on
//!   `workspace/labels` ([`DetectableLabels`]) at start and whenever one is added.
//!
//! Workspaces come from configuration (the simulator's scene files), never from code.
//!
//! ```no_run
//! # async fn demo(
//! #     workspaces: Vec<robotd_protocol::workspace::WorkspaceInfo>,
//! # ) -> Result<(), Box<dyn std::error::Error>> {
//! use robotd_protocol::envelope::unix_now_ns;
//! use robotd_protocol::workspace::{WorkspaceQuery, WorkspaceRequest};
//! use robotd_runtime::bus::{Bus, BusOptions};
//! use robotd_topics::WORKSPACE_QUERY;
//! use robotd_workspace_model::{WorkspaceModel, WorkspaceModelSettings};
//! use std::time::Duration;
//!
//! let bus = Bus::open(BusOptions::new("lab", "example"))?;
//! let model = WorkspaceModel::start(&bus, WorkspaceModelSettings::new(workspaces))?;
//!
//! // "What is on the table now?": wait up to 2 s for a view taken after this moment.
//! let client = bus.client(&WORKSPACE_QUERY)?;
//! let query = WorkspaceQuery {
//!     request: WorkspaceRequest::GetObjectsSorted { ascending: true },
//!     fresh_after_unix_ns: Some(unix_now_ns()),
//!     max_wait_ms: 2000,
//! };
//! let reply = client.request(&query, Duration::from_secs(3)).await?;
//! println!("{reply:?}");
//! model.shutdown().await;
//! # Ok(())
//! # }
//! ```

pub mod config;
pub use config::WorkspaceConfig;

pub mod free_space;
pub mod labels;
pub mod memory;
pub mod queries;
pub mod tracker;

pub use memory::{MemorySettings, SceneMemory};
pub use tracker::{IgnoredView, ASSOCIATION_GATE_M, CONFIRM_VIEWS};

use robotd_protocol::objects::Detections;
use robotd_protocol::validate::Validate;
use robotd_protocol::workspace::{
    DetectableLabels, TrackedObjects, WorkspaceError, WorkspaceInfo, WorkspaceQuery,
    WorkspaceReply, WorkspaceRequest, MAX_FRESH_WAIT_MS,
};
use robotd_runtime::bus::{Bus, BusError, PendingReply, Publisher, Server, Subscriber};
use robotd_topics::{PERCEPTION_DETECTIONS, WORKSPACE_LABELS, WORKSPACE_OBJECTS, WORKSPACE_QUERY};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Notify;
use tokio::time::Instant;

/// How long a fresh-view query waits when it names no limit, unless configured (config
/// `workspace.fresh_wait_ms`).
pub const DEFAULT_FRESH_WAIT: Duration = Duration::from_millis(3000);

/// How the workspace model starts.
#[derive(Debug, Clone)]
pub struct WorkspaceModelSettings {
    /// The configured workspaces (at least one; ids unique).
    pub workspaces: Vec<WorkspaceInfo>,
    /// Labels detectable at start (any detector).
    pub labels: Vec<String>,
    /// Labels the built-in detector can see (added to `labels` when missing there).
    pub builtin_labels: Vec<String>,
    /// Tracking and free-space settings.
    pub memory: MemorySettings,
    /// How long a fresh-view query waits when it names no limit (`max_wait_ms` = 0); at most
    /// [`MAX_FRESH_WAIT_MS`].
    pub default_fresh_wait: Duration,
}

impl WorkspaceModelSettings {
    /// Settings for `workspaces` with no labels and the defaults: free-space margin 0.01 m,
    /// objects forgotten after 3 missed views, fresh-view wait 3 s.
    pub fn new(workspaces: Vec<WorkspaceInfo>) -> Self {
        Self {
            workspaces,
            labels: Vec::new(),
            builtin_labels: Vec::new(),
            memory: MemorySettings::default(),
            default_fresh_wait: DEFAULT_FRESH_WAIT,
        }
    }

    /// Settings for `workspaces` from the `[workspace]` section, with `labels` the built-in
    /// detector can see (they are also the labels known at start).
    pub fn from_config(
        workspaces: Vec<WorkspaceInfo>,
        labels: Vec<String>,
        config: &WorkspaceConfig,
    ) -> Self {
        Self {
            workspaces,
            labels: labels.clone(),
            builtin_labels: labels,
            memory: MemorySettings {
                free_space_margin_m: config.free_space_margin_m,
                expire_after_frames: config.expire_after_frames,
                label_limits: labels::LabelLimits {
                    max_labels: config.max_labels as usize,
                    max_chars: config.max_label_chars as usize,
                },
            },
            default_fresh_wait: Duration::from_millis(config.fresh_wait_ms),
        }
    }
}

/// The workspace model could not start.
#[derive(Debug, thiserror::Error)]
pub enum WorkspaceStartError {
    /// A bus port could not be opened.
    #[error("workspace model: cannot open its bus ports: {0}")]
    Bus(#[from] BusError),
    /// No workspace to remember.
    #[error("workspace model: no workspace is configured (add one to the scene file)")]
    NoWorkspace,
    /// A workspace is malformed or its id is taken twice.
    #[error("workspace model: workspace '{workspace_id}' is invalid: {reason}")]
    BadWorkspace {
        /// The workspace.
        workspace_id: String,
        /// What is wrong.
        reason: String,
    },
}

/// The running workspace model.
#[derive(Debug)]
pub struct WorkspaceModel {
    stop: Arc<Notify>,
    task: tokio::task::JoinHandle<()>,
}

impl WorkspaceModel {
    /// Starts the actor on `bus` (inside a tokio runtime). Its ports are open on return, and
    /// the label list has been published.
    pub fn start(
        bus: &Bus,
        settings: WorkspaceModelSettings,
    ) -> Result<WorkspaceModel, WorkspaceStartError> {
        check_workspaces(&settings.workspaces)?;
        let ports = Ports {
            detections: bus.subscriber(&PERCEPTION_DETECTIONS)?,
            server: bus.server(&WORKSPACE_QUERY)?,
            objects: bus.publisher(&WORKSPACE_OBJECTS)?,
            labels: bus.publisher(&WORKSPACE_LABELS)?,
        };
        let memory = SceneMemory::new(
            settings.workspaces.clone(),
            &settings.labels,
            &settings.builtin_labels,
            settings.memory.clone(),
        );
        publish_labels(&ports.labels, memory.labels_message(None));
        let default_wait = settings
            .default_fresh_wait
            .min(Duration::from_millis(MAX_FRESH_WAIT_MS));
        let stop = Arc::new(Notify::new());
        let task = tokio::spawn(run(ports, memory, default_wait, stop.clone()));
        Ok(WorkspaceModel { stop, task })
    }

    /// Stops the actor. Queries still waiting for a fresh view are answered with
    /// [`WorkspaceError::Unavailable`].
    pub async fn shutdown(self) {
        self.stop.notify_one();
        let _ = self.task.await;
    }
}

fn check_workspaces(workspaces: &[WorkspaceInfo]) -> Result<(), WorkspaceStartError> {
    if workspaces.is_empty() {
        return Err(WorkspaceStartError::NoWorkspace);
    }
    for (i, ws) in workspaces.iter().enumerate() {
        if let Err(e) = ws.validate() {
            return Err(WorkspaceStartError::BadWorkspace {
                workspace_id: ws.id.clone(),
                reason: e.to_string(),
            });
        }
        if workspaces[..i].iter().any(|w| w.id == ws.id) {
            return Err(WorkspaceStartError::BadWorkspace {
                workspace_id: ws.id.clone(),
                reason: "the id is used by two workspaces".into(),
            });
        }
    }
    Ok(())
}

struct Ports {
    detections: Subscriber<Detections>,
    server: Server<WorkspaceQuery, WorkspaceReply>,
    objects: Publisher<TrackedObjects>,
    labels: Publisher<DetectableLabels>,
}

/// A query waiting for a view newer than `after_ns`.
struct Waiter {
    after_ns: u64,
    /// Views newer than `after_ns` applied so far (0 or 1: at the second it is answered).
    views: u32,
    deadline: Instant,
    request: WorkspaceRequest,
    pending: PendingReply,
}

async fn run(mut ports: Ports, mut memory: SceneMemory, default_wait: Duration, stop: Arc<Notify>) {
    let mut waiters: Vec<Waiter> = Vec::new();
    let mut last_warning = String::new();
    // Capture time of the view applied before the newest one.
    let mut previous_view_ns = 0u64;
    loop {
        let next_deadline = waiters.iter().map(|w| w.deadline).min();
        tokio::select! {
            _ = stop.notified() => break,
            received = ports.detections.recv() => match received {
                Ok(message) => match apply(&mut memory, &message.body, &mut previous_view_ns) {
                    Ok(tracked) => {
                        if let Err(error) = ports.objects.publish(&tracked) {
                            tracing::debug!(%error, "workspace model: publishing objects failed");
                        }
                        // Answer the queries this view was waited for: at the first view after
                        // their time, or the second when the first left candidates.
                        let view = memory.last_view_ns();
                        let settling = memory.has_candidates();
                        for w in waiters.iter_mut().filter(|w| view > w.after_ns) {
                            w.views += 1;
                        }
                        let (ready, waiting): (Vec<Waiter>, Vec<Waiter>) = waiters
                            .drain(..)
                            .partition(|w| w.views >= if settling { 2 } else { 1 });
                        waiters = waiting;
                        for w in ready {
                            let reply = serve(&mut memory, &ports.labels, &w.request);
                            respond(&mut ports.server, w.pending, reply);
                        }
                    }
                    Err(ignored) => report_ignored(&ignored, &mut last_warning),
                },
                Err(error) => {
                    tracing::warn!(%error, "workspace model: a detection could not be read");
                }
            },
            incoming = ports.server.next() => match incoming {
                Ok(incoming) => {
                    let (envelope, pending) = incoming.split();
                    let query = envelope.body;
                    if let Err(error) = check_query(&query) {
                        respond(&mut ports.server, pending, error.into());
                        continue;
                    }
                    let views_after = |after: u64| {
                        u32::from(memory.last_view_ns() > after) + u32::from(previous_view_ns > after)
                    };
                    match query.fresh_after_unix_ns {
                        Some(after)
                            if views_after(after) == 0
                                || (views_after(after) == 1 && memory.has_candidates()) =>
                        {
                            let wait = if query.max_wait_ms == 0 {
                                default_wait
                            } else {
                                Duration::from_millis(query.max_wait_ms)
                            };
                            waiters.push(Waiter {
                                after_ns: after,
                                views: views_after(after),
                                deadline: Instant::now() + wait,
                                request: query.request,
                                pending,
                            });
                        }
                        _ => {
                            let reply = serve(&mut memory, &ports.labels, &query.request);
                            respond(&mut ports.server, pending, reply);
                        }
                    }
                }
                Err(error) => {
                    tracing::warn!(%error, "workspace model: receiving a query failed");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
            },
            _ = sleep_until(next_deadline), if next_deadline.is_some() => {
                let now = Instant::now();
                let (expired, waiting): (Vec<Waiter>, Vec<Waiter>) =
                    waiters.drain(..).partition(|w| w.deadline <= now);
                waiters = waiting;
                for w in expired {
                    if w.views > 0 {
                        // A fresh view came but did not settle: answer from it.
                        let reply = serve(&mut memory, &ports.labels, &w.request);
                        respond(&mut ports.server, w.pending, reply);
                        continue;
                    }
                    let error = WorkspaceError::NoFreshDetection {
                        reason: no_fresh_view_reason(&memory, w.after_ns),
                    };
                    respond(&mut ports.server, w.pending, error.into());
                }
            }
        }
    }
    if !waiters.is_empty() {
        for w in waiters {
            let error = WorkspaceError::Unavailable {
                reason: "the workspace model is shutting down".into(),
            };
            respond(&mut ports.server, w.pending, error.into());
        }
        // A reply whose publisher closes at once can be lost before the client reads it:
        // keep the ports open a moment for the clients to collect these last answers.
        tokio::time::sleep(SHUTDOWN_GRACE).await;
    }
}

/// Applies one view, remembering the capture time of the view before it.
fn apply(
    memory: &mut SceneMemory,
    detections: &Detections,
    previous_view_ns: &mut u64,
) -> Result<TrackedObjects, IgnoredView> {
    let before = memory.last_view_ns();
    let tracked = memory.apply(detections)?;
    if memory.last_view_ns() > before {
        *previous_view_ns = before;
    }
    Ok(tracked)
}

/// How long the actor keeps its ports open after answering waiting queries at shutdown.
const SHUTDOWN_GRACE: Duration = Duration::from_millis(100);

/// The query's own checks: the request's fields (a location filter without a coordinate is
/// the tools' `CoordinateRequired`), and the wait limit.
fn check_query(query: &WorkspaceQuery) -> Result<(), WorkspaceError> {
    memory::check_request(&query.request)?;
    query.validate().map_err(WorkspaceError::from)
}

fn no_fresh_view_reason(memory: &SceneMemory, after_ns: u64) -> String {
    let last = memory.last_view_ns();
    let age = if last == 0 {
        "no steady view of a workspace has arrived yet".to_owned()
    } else {
        format!(
            "the newest steady view was taken {:.1} s before the time asked for",
            after_ns.saturating_sub(last) as f64 / 1e9
        )
    };
    format!(
        "the camera gave no steady view of the workspace in time ({age}); is the arm at the \
         observation pose and the camera running?"
    )
}

/// Answers `request`, publishing the label list when it changed.
fn serve(
    memory: &mut SceneMemory,
    labels: &Publisher<DetectableLabels>,
    request: &WorkspaceRequest,
) -> WorkspaceReply {
    let reply = memory.answer(request);
    let added = match &reply {
        WorkspaceReply::LabelAdded {
            label,
            already_known: false,
        } => Some(label.clone()),
        WorkspaceReply::ObjectLabelled {
            object,
            label_added: true,
            ..
        } => Some(object.label.clone()),
        _ => None,
    };
    if let Some(label) = added {
        publish_labels(labels, memory.labels_message(Some(label)));
    }
    reply
}

/// Logs why a frame changed nothing: frames during motion or without a sheet are routine; a
/// misconfigured or misbehaving detector is warned about once per distinct problem in a row.
fn report_ignored(ignored: &IgnoredView, last_warning: &mut String) {
    match ignored {
        IgnoredView::Moving { .. } | IgnoredView::NoWorkspace { .. } => {
            tracing::trace!(%ignored, "workspace model: view ignored");
        }
        IgnoredView::UnknownWorkspace { workspace_id, .. } => {
            warn_once(last_warning, &format!("unknown:{workspace_id}"), ignored);
        }
        IgnoredView::Stale { source_id, .. } | IgnoredView::Invalid { source_id, .. } => {
            warn_once(last_warning, &format!("source:{source_id}"), ignored);
        }
    }
}

fn warn_once(last_warning: &mut String, key: &str, ignored: &IgnoredView) {
    if last_warning != key {
        tracing::warn!(%ignored, "workspace model: view ignored");
        *last_warning = key.to_owned();
    } else {
        tracing::debug!(%ignored, "workspace model: view ignored");
    }
}

async fn sleep_until(deadline: Option<Instant>) {
    match deadline {
        Some(d) => tokio::time::sleep_until(d).await,
        None => std::future::pending().await,
    }
}

fn respond(
    server: &mut Server<WorkspaceQuery, WorkspaceReply>,
    pending: PendingReply,
    reply: WorkspaceReply,
) {
    if let Err(error) = server.respond(pending, Ok(reply)) {
        tracing::warn!(%error, "workspace model: could not send a reply");
    }
}

fn publish_labels(publisher: &Publisher<DetectableLabels>, message: DetectableLabels) {
    if let Err(error) = publisher.publish(&message) {
        tracing::debug!(%error, "workspace model: publishing labels failed");
    }
}
