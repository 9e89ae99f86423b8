//! robotd's scene memory: the workspace model actor.
//!
//! The detection and workspace tools (`get_detected_objects`, `get_largest_free_space_with_center`,
//! `get_workspace_coordinate_from_point`, …) are answered from here, instantly, instead of moving
//! the arm and waiting for a detector on every call as the Python server does. The actor:
//!
//! - subscribes to `perception/detections` and keeps, per workspace, the objects on the table
//!   with ids that stay stable while they are tracked ([`memory`]);
//! - serves `workspace/query` ([`WorkspaceQuery`]): each [`WorkspaceRequest`] of the tools,
//!   optionally "from a view taken after time t", in which case the answer waits (bounded) for
//!   such a view while other queries are answered meanwhile;
//! - publishes the remembered objects on `workspace/objects` after every applied view, and the
//!   detectable labels on `workspace/labels` at start and whenever one is added;
//! - follows what the skills do (`ObjectPicked`, `ObjectPlaced`).
//!
//! Workspaces come from configuration (the simulator's scene files), never from code.

pub mod free_space;
pub mod memory;

pub use memory::{MemorySettings, SceneMemory};

use robotd_protocol::objects::Detections;
use robotd_protocol::validate::Validate;
use robotd_protocol::workspace::{
    DetectableLabels, WorkspaceError, WorkspaceInfo, WorkspaceQuery, WorkspaceReply,
    WorkspaceRequest, MAX_FRESH_WAIT_MS,
};
use robotd_runtime::bus::{Bus, BusError, PendingReply, Publisher, Server, Subscriber};
use robotd_runtime::catalog::{
    PERCEPTION_DETECTIONS, WORKSPACE_LABELS, WORKSPACE_OBJECTS, WORKSPACE_QUERY,
};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Notify;
use tokio::time::Instant;

/// How the workspace model starts.
#[derive(Debug, Clone)]
pub struct WorkspaceModelSettings {
    /// The configured workspaces (at least one).
    pub workspaces: Vec<WorkspaceInfo>,
    /// Labels detectable at start (any detector).
    pub labels: Vec<String>,
    /// Labels the built-in detector can see.
    pub builtin_labels: Vec<String>,
    /// Tracking and free-space settings.
    pub memory: MemorySettings,
    /// How long a fresh-view query waits when it names no limit.
    pub default_fresh_wait: Duration,
}

/// The workspace model could not start.
#[derive(Debug, thiserror::Error)]
pub enum WorkspaceStartError {
    /// A bus port could not be opened.
    #[error("workspace model: cannot open its bus ports: {0}")]
    Bus(#[from] BusError),
    /// No workspace to remember.
    #[error("workspace model: no workspace is configured")]
    NoWorkspace,
}

/// The running workspace model.
#[derive(Debug)]
pub struct WorkspaceModel {
    stop: Arc<Notify>,
    task: tokio::task::JoinHandle<()>,
}

impl WorkspaceModel {
    /// Starts the actor on `bus` (inside a tokio runtime). Its ports are open on return.
    pub fn start(
        bus: &Bus,
        settings: WorkspaceModelSettings,
    ) -> Result<WorkspaceModel, WorkspaceStartError> {
        if settings.workspaces.is_empty() {
            return Err(WorkspaceStartError::NoWorkspace);
        }
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
        let stop = Arc::new(Notify::new());
        let task = tokio::spawn(run(
            ports,
            memory,
            settings.default_fresh_wait,
            stop.clone(),
        ));
        Ok(WorkspaceModel { stop, task })
    }

    /// Stops the actor.
    pub async fn shutdown(self) {
        self.stop.notify_one();
        let _ = self.task.await;
    }
}

struct Ports {
    detections: Subscriber<Detections>,
    server: Server<WorkspaceQuery, WorkspaceReply>,
    objects: Publisher<robotd_protocol::workspace::TrackedObjects>,
    labels: Publisher<DetectableLabels>,
}

/// A query waiting for a view newer than `after_ns`.
struct Waiter {
    after_ns: u64,
    deadline: Instant,
    request: WorkspaceRequest,
    pending: PendingReply,
}

async fn run(mut ports: Ports, mut memory: SceneMemory, default_wait: Duration, stop: Arc<Notify>) {
    publish_labels(&ports.labels, &memory, None);
    let mut waiters: Vec<Waiter> = Vec::new();
    loop {
        let next_deadline = waiters.iter().map(|w| w.deadline).min();
        tokio::select! {
            _ = stop.notified() => break,
            received = ports.detections.recv() => match received {
                Ok(message) => {
                    if let Some(tracked) = memory.apply(&message.body) {
                        if let Err(error) = ports.objects.publish(&tracked) {
                            tracing::debug!(%error, "workspace model: publishing objects failed");
                        }
                        // Answer the queries this view was waited for.
                        let view = memory.last_view_ns();
                        let (ready, waiting): (Vec<Waiter>, Vec<Waiter>) =
                            waiters.drain(..).partition(|w| view > w.after_ns);
                        waiters = waiting;
                        for w in ready {
                            let reply = memory.answer(&w.request);
                            respond(&mut ports.server, w.pending, reply);
                        }
                    }
                }
                Err(error) => {
                    tracing::warn!(%error, "workspace model: a detection could not be read");
                }
            },
            incoming = ports.server.next() => match incoming {
                Ok(incoming) => {
                    let (envelope, pending) = incoming.split();
                    let query = envelope.body;
                    if let Err(e) = query.validate() {
                        respond(&mut ports.server, pending, WorkspaceError::from(e).into());
                        continue;
                    }
                    match query.fresh_after_unix_ns {
                        Some(after) if memory.last_view_ns() <= after => {
                            let wait = if query.max_wait_ms == 0 {
                                default_wait
                            } else {
                                Duration::from_millis(query.max_wait_ms.min(MAX_FRESH_WAIT_MS))
                            };
                            waiters.push(Waiter {
                                after_ns: after,
                                deadline: Instant::now() + wait,
                                request: query.request,
                                pending,
                            });
                        }
                        _ => {
                            let added = match &query.request {
                                WorkspaceRequest::AddLabel { .. } => Some(()),
                                _ => None,
                            };
                            let reply = memory.answer(&query.request);
                            if let (Some(()), WorkspaceReply::LabelAdded { label, already_known: false }) =
                                (added, &reply)
                            {
                                publish_labels(&ports.labels, &memory, Some(label.clone()));
                            }
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
                    let error = WorkspaceError::NoFreshDetection {
                        reason: "the camera gave no steady view of the workspace in time \
                                 (is the arm at the observation pose and the camera running?)"
                            .into(),
                    };
                    respond(&mut ports.server, w.pending, error.into());
                }
            }
        }
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

fn publish_labels(
    publisher: &Publisher<DetectableLabels>,
    memory: &SceneMemory,
    added: Option<String>,
) {
    let message = DetectableLabels {
        labels: memory.labels().to_vec(),
        added,
    };
    if let Err(error) = publisher.publish(&message) {
        tracing::debug!(%error, "workspace model: publishing labels failed");
    }
}
