//! The bus, logged onto Foxglove channels.
//!
//! One thread reads the bus (like every edge: its ports live on the thread that opened them)
//! and logs into a [`foxglove::Context`]; whatever sinks the context has receive it — the
//! WebSocket server of the live view, an MCAP file of `robotd record`, or both. Channels:
//!
//! | channel | message | from |
//! |---|---|---|
//! | `/camera` | `foxglove.CompressedImage` (JPEG) | `camera/frames`, at most `camera_fps` a second |
//! | `/camera/meta` | JSON [`FrameMeta`]: `frame_id`, `timestamp_unix_ns`, `width`, `height`, `camera_pose`, `intrinsics` (when known) | the same frames' headers (what replay needs to rebuild them) |
//! | `/tf` | `foxglove.FrameTransforms` | every link of the arm from its parent link (the URDF's tree, from `base_link`), by forward kinematics of `arm/state` |
//! | `/joint_states` | JSON: `name` (the URDF's joint names), `position` (rad) | `arm/state` |
//! | `/robot_description` | JSON `std_msgs/String`: the URDF, with simple visuals for the 3D panel | once a second (late viewers get it too) |
//! | `/scene/arm` | `foxglove.SceneUpdate` | the arm as a line through its link origins (without the URDF layer) |
//! | `/scene/objects` | `foxglove.SceneUpdate` | `workspace/objects`: a box and a label per object |
//! | `/scene/workspace` | `foxglove.SceneUpdate` | the workspaces' sheets, the geofence's edges and the keep-out zones, once a second |
//! | `/log` | `foxglove.Log` | overlays (speech, tasks, system messages), restarts, agent answers and errors |
//! | `/bus/<topic>` | JSON, schema named by the message type, with its JSON Schema (generated from the Rust type) | every message topic ([`crate::topics`]) |
//!
//! Log times are the bus's (a frame's capture time, a message's send time), so a recording
//! replays with the original timing. A channel nobody listens to costs nothing: the SDK drops
//! messages without sinks before encoding them.

use crate::topics::{self, JsonSubscriber};
use crate::{scene, urdf};
use foxglove::messages::log::Level;
use foxglove::messages::{CompressedImage, FrameTransforms, Log, SceneUpdate};
use foxglove::{Channel, ChannelBuilder, Context, PartialMetadata, RawChannel, Schema};
use robotd_kinematics::Kinematics;
use robotd_protocol::agent::AgentEventKind;
use robotd_protocol::geometry::RobotModel;
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_recording::camera::FrameMeta;
use robotd_runtime::bus::{Bus, BusError};
use robotd_topics::{
    AGENT_EVENTS, ARM_STATE, CAMERA_FRAMES, CAMERA_INTRINSICS, HEALTH_RESTARTS, OVERLAY_TEXT,
    WORKSPACE_OBJECTS,
};
use serde_json::json;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// What the bridge logs and how.
#[derive(Debug, Clone)]
pub struct BridgeSettings {
    /// Most camera frames per second logged.
    pub camera_fps: f64,
    /// JPEG quality of those frames.
    pub jpeg_quality: u8,
    /// The arm's model (for its links and URDF).
    pub model: RobotModel,
    /// The workspaces drawn.
    pub workspaces: Vec<WorkspaceInfo>,
    /// The motion policy's geofence and keep-out zones, drawn with the workspaces.
    pub geofence: Option<(scene::Box3, Vec<scene::Box3>)>,
    /// Bus topics logged under `/bus/…`: `None` = all.
    pub topics: Option<Vec<String>>,
    /// Log the camera.
    pub camera: bool,
    /// The camera's intrinsics, written into every frame's `/camera/meta` so a replay serves
    /// the frames with them (`None` when the recorder does not know them).
    pub camera_intrinsics: Option<robotd_protocol::camera::CameraIntrinsics>,
}

/// The running bridge; dropping it stops the thread.
#[derive(Debug)]
pub struct Bridge {
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Drop for Bridge {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// Starts the bridge from `bus` into `context`.
pub fn start(bus: Bus, context: Arc<Context>, settings: BridgeSettings) -> std::io::Result<Bridge> {
    let stop = Arc::new(AtomicBool::new(false));
    let stopping = stop.clone();
    let thread = robotd_runtime::bus::spawn_reader_thread("foxglove-bridge", move || async move {
        if let Err(error) = follow(&bus, &context, &settings, &stopping).await {
            tracing::error!(%error, "foxglove: the bridge stopped: its bus ports failed");
        }
    })?;
    Ok(Bridge {
        stop,
        thread: Some(thread),
    })
}

fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

fn at(ns: u64) -> PartialMetadata {
    PartialMetadata { log_time: Some(ns) }
}

/// A JSON channel, with a schema named `schema_name` that accepts any object.
fn json_channel(context: &Arc<Context>, topic: &str, schema_name: &str) -> Option<Arc<RawChannel>> {
    json_channel_with(
        context,
        topic,
        schema_name,
        br#"{"type":"object"}"#.to_vec(),
    )
}

/// A JSON channel whose schema is `schema_name` with the JSON Schema `schema`.
fn json_channel_with(
    context: &Arc<Context>,
    topic: &str,
    schema_name: &str,
    schema: Vec<u8>,
) -> Option<Arc<RawChannel>> {
    let schema = Schema::new(schema_name, "jsonschema", schema);
    match ChannelBuilder::new(topic)
        .message_encoding("json")
        .schema(schema)
        .context(context)
        .build_raw()
    {
        Ok(channel) => Some(channel),
        Err(error) => {
            tracing::warn!(%error, topic, "foxglove: channel not created");
            None
        }
    }
}

/// The typed channels of the bridge.
struct Channels {
    camera: Channel<CompressedImage>,
    camera_meta: Option<Arc<RawChannel>>,
    tf: Channel<FrameTransforms>,
    joints: Option<Arc<RawChannel>>,
    description: Option<Arc<RawChannel>>,
    arm: Channel<SceneUpdate>,
    objects: Channel<SceneUpdate>,
    workspace: Channel<SceneUpdate>,
    log: Channel<Log>,
}

impl Channels {
    fn new(context: &Arc<Context>) -> Self {
        Self {
            camera: ChannelBuilder::new(robotd_recording::CAMERA)
                .context(context)
                .build(),
            camera_meta: json_channel(
                context,
                robotd_recording::CAMERA_META,
                "robotd.CameraFrameMeta",
            ),
            tf: ChannelBuilder::new("/tf").context(context).build(),
            joints: json_channel(context, "/joint_states", "robotd.JointState"),
            description: json_channel(
                context,
                robotd_recording::ROBOT_DESCRIPTION,
                "std_msgs/String",
            ),
            arm: ChannelBuilder::new("/scene/arm").context(context).build(),
            objects: ChannelBuilder::new("/scene/objects")
                .context(context)
                .build(),
            workspace: ChannelBuilder::new("/scene/workspace")
                .context(context)
                .build(),
            log: ChannelBuilder::new("/log").context(context).build(),
        }
    }
}

/// The names of the arm's joints as its URDF has them (`joint_1` … on the Ned2, `waist`,
/// `shoulder` … on the WidowX), in the order of `arm/state`'s positions: the movable joints
/// along the kinematic chain from the base to the tool. `None` if the URDF and the kinematics
/// disagree (a build defect the tests catch).
pub fn joint_names(kinematics: &Kinematics) -> Option<Vec<String>> {
    let links = kinematics.link_poses(&kinematics.home_joints()).ok()?;
    let chain: Vec<&str> = links.iter().map(|(name, _)| name.as_str()).collect();
    let model = urdf::parse(kinematics.urdf());
    let names = model.movable_joints_along(&chain)?;
    (names.len() == kinematics.joint_count())
        .then(|| names.into_iter().map(str::to_owned).collect())
}

async fn follow(
    bus: &Bus,
    context: &Arc<Context>,
    settings: &BridgeSettings,
    stop: &AtomicBool,
) -> Result<(), BusError> {
    let channels = Channels::new(context);
    let kinematics = Kinematics::new(settings.model);
    let joint_names = joint_names(&kinematics);
    if joint_names.is_none() {
        tracing::warn!(model = ?settings.model, "foxglove: the URDF's joints do not match the kinematics; no /joint_states");
    }
    let mut frames = if settings.camera {
        Some(bus.frame_subscriber(&CAMERA_FRAMES)?)
    } else {
        None
    };
    let mut arm = bus.subscriber(&ARM_STATE)?;
    let mut objects = bus.subscriber(&WORKSPACE_OBJECTS)?;
    let mut overlays = bus.subscriber(&OVERLAY_TEXT)?;
    let mut restarts = bus.subscriber(&HEALTH_RESTARTS)?;
    let mut agent = bus.subscriber(&AGENT_EVENTS)?;
    // The intrinsics /camera/meta carries: the camera's as it knows them now (a Ned2 sends
    // its own when it connects), from robotd's at start until then.
    let mut intrinsics_now = bus.subscriber(&CAMERA_INTRINSICS)?;
    let mut intrinsics = settings.camera_intrinsics.clone();
    let mut raw: Vec<(Arc<RawChannel>, Box<dyn JsonSubscriber>)> = Vec::new();
    for topic in topics::all() {
        let wanted = settings
            .topics
            .as_ref()
            .is_none_or(|list| list.iter().any(|t| t == topic.name()));
        if !wanted {
            continue;
        }
        let Some(channel) = json_channel_with(
            context,
            &topics::channel_name(topic.name()),
            topic.type_name(),
            topic.schema(),
        ) else {
            continue;
        };
        raw.push((channel, topic.subscribe(bus)?));
    }
    let every = Duration::from_secs_f64(1.0 / settings.camera_fps.max(0.1));
    let mut last_frame: Option<Instant> = None;
    let mut last_slow: Option<Instant> = None;
    let mut drawn_objects: Vec<String> = Vec::new();
    let urdf = json!({ "data": kinematics.urdf() }).to_string();
    while !stop.load(Ordering::SeqCst) {
        if last_slow.is_none_or(|t| t.elapsed() >= Duration::from_secs(1)) {
            last_slow = Some(Instant::now());
            let ns = now_ns();
            if let Some(channel) = &channels.description {
                channel.log_with_meta(urdf.as_bytes(), at(ns));
            }
            channels.workspace.log_with_time(
                &scene::workspace_scene(&settings.workspaces, settings.geofence.as_ref(), ns),
                ns,
            );
        }
        while let Some(message) = arm.try_recv()? {
            let ns = message.sent_at_unix_ns;
            let q = &message.body.joints.positions_rad;
            if let (Some(channel), Some(names)) = (&channels.joints, &joint_names) {
                if names.len() == q.len() {
                    let body = json!({"name": names, "position": q}).to_string();
                    channel.log_with_meta(body.as_bytes(), at(ns));
                }
            }
            match kinematics.link_poses(q) {
                Ok(links) => {
                    channels
                        .tf
                        .log_with_time(&scene::link_transforms(&links, ns), ns);
                    channels
                        .arm
                        .log_with_time(&scene::arm_scene(&links, ns), ns);
                }
                Err(error) => tracing::debug!(%error, "foxglove: arm state without usable joints"),
            }
        }
        while let Some(message) = objects.try_recv()? {
            let ns = message.sent_at_unix_ns;
            let update = scene::objects_scene(&message.body.objects, &drawn_objects, ns);
            drawn_objects = update.entities.iter().map(|e| e.id.clone()).collect();
            channels.objects.log_with_time(&update, ns);
        }
        while let Some(message) = overlays.try_recv()? {
            let text = format!("{}: {}", message.body.kind.as_str(), message.body.text);
            let line = scene::log(Level::Info, "overlay", text, message.sent_at_unix_ns);
            channels.log.log_with_time(&line, message.sent_at_unix_ns);
        }
        while let Some(message) = restarts.try_recv()? {
            let r = &message.body;
            let text = format!(
                "{} restarted (attempt {}): {}",
                r.actor, r.attempt, r.reason
            );
            let line = scene::log(Level::Warning, &r.actor, text, message.sent_at_unix_ns);
            channels.log.log_with_time(&line, message.sent_at_unix_ns);
        }
        while let Some(message) = agent.try_recv()? {
            let (level, text) = match &message.body.event {
                AgentEventKind::Answer { text } => (Level::Info, format!("answer: {text}")),
                AgentEventKind::Error { message } => (Level::Error, format!("error: {message}")),
                _ => continue,
            };
            let line = scene::log(level, "agent", text, message.sent_at_unix_ns);
            channels.log.log_with_time(&line, message.sent_at_unix_ns);
        }
        while let Some(message) = intrinsics_now.try_recv()? {
            intrinsics = Some(message.body);
        }
        for (channel, subscriber) in &mut raw {
            while let Some((ns, json)) = subscriber.try_recv()? {
                channel.log_with_meta(&json, at(ns));
            }
        }
        let Some(frames) = frames.as_mut() else {
            tokio::time::sleep(Duration::from_millis(20)).await;
            continue;
        };
        let sample = match tokio::time::timeout(Duration::from_millis(20), frames.recv()).await {
            Err(_) => continue,
            Ok(Err(error)) => {
                tracing::debug!(%error, "foxglove: receiving a frame failed");
                tokio::time::sleep(Duration::from_millis(20)).await;
                continue;
            }
            Ok(Ok(sample)) => sample,
        };
        if last_frame.is_some_and(|t| t.elapsed() < every) || !channels.camera.has_sinks() {
            continue;
        }
        let header = *sample.header();
        let (w, h) = (header.width as usize, header.height as usize);
        if header.channels != 3 || header.encoding != 0 || sample.pixels().len() < w * h * 3 {
            continue;
        }
        last_frame = Some(Instant::now());
        let jpeg = robotd_render::encode_jpeg(
            &sample.pixels()[..w * h * 3],
            header.width,
            header.height,
            settings.jpeg_quality,
        );
        drop(sample);
        let ns = header.timestamp_unix_ns;
        match jpeg {
            Ok(jpeg) => {
                let image = CompressedImage {
                    timestamp: Some(scene::timestamp(ns)),
                    frame_id: "camera_link".to_owned(),
                    data: jpeg.into(),
                    format: "jpeg".to_owned(),
                };
                channels.camera.log_with_time(&image, ns);
                if let Some(channel) = &channels.camera_meta {
                    let meta = FrameMeta {
                        frame_id: header.frame_id,
                        timestamp_unix_ns: ns,
                        width: header.width,
                        height: header.height,
                        camera_pose: header.camera_pose,
                        intrinsics: intrinsics.clone(),
                    };
                    match serde_json::to_vec(&meta) {
                        Ok(bytes) => channel.log_with_meta(&bytes, at(ns)),
                        Err(error) => tracing::warn!(%error, "foxglove: a frame header"),
                    }
                }
            }
            Err(error) => tracing::warn!(%error, "foxglove: JPEG encoding failed"),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joint_states_name_the_urdf_joints_of_the_configured_robot() {
        let wx = joint_names(&Kinematics::new(RobotModel::WidowX250)).unwrap();
        assert_eq!(
            wx,
            [
                "waist",
                "shoulder",
                "elbow",
                "forearm_roll",
                "wrist_angle",
                "wrist_rotate"
            ]
        );
        let ned2 = joint_names(&Kinematics::new(RobotModel::Ned2)).unwrap();
        assert_eq!(
            ned2,
            ["joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6"]
        );
        // Each is a movable joint of that robot's URDF, one per position of `arm/state`.
        for model in [RobotModel::Ned2, RobotModel::WidowX250] {
            let kinematics = Kinematics::new(model);
            let names = joint_names(&kinematics).unwrap();
            assert_eq!(names.len(), kinematics.joint_count());
            let parsed = urdf::parse(kinematics.urdf());
            for name in &names {
                assert!(
                    parsed
                        .joints
                        .iter()
                        .any(|j| &j.name == name && j.is_movable()),
                    "{model:?}: {name}"
                );
            }
        }
    }

    /// The channels the bridge creates (besides `/bus/<topic>`).
    const CHANNELS: [&str; 9] = [
        "/camera",
        "/camera/meta",
        "/tf",
        "/joint_states",
        "/robot_description",
        "/scene/arm",
        "/scene/objects",
        "/scene/workspace",
        "/log",
    ];

    #[test]
    fn the_layout_names_only_channels_the_bridge_creates() {
        let layout: serde_json::Value =
            serde_json::from_str(include_str!("../../../config/foxglove-layout.json")).unwrap();
        let text = layout["configById"].to_string();
        let mentioned: Vec<&str> = text
            .split('"')
            .filter(|s| s.starts_with('/'))
            .map(|s| s.split('.').next().unwrap_or(s))
            .collect();
        assert!(!mentioned.is_empty());
        for topic in mentioned {
            let known = CHANNELS.contains(&topic)
                || topic
                    .strip_prefix("/bus/")
                    .is_some_and(|t| crate::topics::find(t).is_some());
            assert!(
                known,
                "the layout names {topic}, which the bridge does not create"
            );
        }
    }
}
