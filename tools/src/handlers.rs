//! What each tool does and says: read the arguments, ask the actors over the bus, and word
//! the outcome exactly as `spec/mcp-tools.md` does.
//!
//! Motion tools run one skill on the skills actor and follow its progress; cancelling the
//! call (or dropping it) cancels the skill, which stops the arm. Detection tools answer from
//! a view the camera took with the arm resting at the workspace's observation pose: if the
//! arm rests there already they are answered from the workspace model at once, otherwise the
//! arm goes there first and the answer waits for the first steady frame.

use crate::args::{validation_text, Args, FieldError};
use crate::{CallHooks, Progress, Registry, ToolOutput};
use nalgebra::UnitQuaternion;
use robotd_protocol::arm::{ArmCommand, ArmReply};
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::skills::{Skill, SkillCancel, SkillReply, SkillRequest, DEFAULT_Z_OFFSET_M};
use robotd_protocol::speech::{OverlayKind, SpeakRequest, TextOverlay, MAX_SPEECH_CHARS};
use robotd_protocol::workspace::{WorkspaceQuery, WorkspaceReply, WorkspaceRequest};
use robotd_protocol::{Direction, Location, Point2, Pose, WorkspacePoint};
use serde_json::{json, Map, Value};
use std::sync::atomic::Ordering;
use tokio::sync::mpsc;

type Arguments = Map<String, Value>;

/// `[x.xxx, y.yyy]`, the contract's coordinate format.
fn pt(p: Point2) -> String {
    format!("[{:.3}, {:.3}]", p.x_m, p.y_m)
}

fn pt_json(p: Point2) -> Value {
    json!([p.x_m, p.y_m])
}

fn pretty<T: serde::Serialize>(value: &T) -> String {
    serde_json::to_string_pretty(value).unwrap_or_else(|e| format!("<unprintable: {e}>"))
}

fn invalid(tool: &str, errors: Vec<FieldError>) -> ToolOutput {
    ToolOutput::failed(validation_text(tool, &errors))
}

/// Reads the arguments with `read`; any problem becomes the validation error text.
fn parse<T>(
    tool: &str,
    args: &Arguments,
    read: impl FnOnce(&mut Args) -> Option<T>,
) -> Result<T, ToolOutput> {
    let mut a = Args::new(args);
    let value = read(&mut a);
    match (a.finish(), value) {
        (Ok(()), Some(v)) => Ok(v),
        (Err(errors), _) => Err(invalid(tool, errors)),
        (Ok(()), None) => Err(invalid(
            tool,
            vec![FieldError {
                field: "arguments".into(),
                message: "could not be read".into(),
            }],
        )),
    }
}

pub(crate) async fn call(
    registry: &Registry,
    tool: &'static str,
    args: &Arguments,
    hooks: CallHooks,
) -> ToolOutput {
    let outcome = match tool {
        "pick_place_object" => pick_place_object(registry, args, hooks).await,
        "pick_object" => pick_object(registry, args, hooks).await,
        "place_object" => place_object(registry, args, hooks).await,
        "push_object" => push_object(registry, args, hooks).await,
        "move2by" => move2by(registry, args, hooks).await,
        "move2observation_pose" => move2observation_pose(registry, args, hooks).await,
        "clear_collision_detected" => {
            simple_skill(
                registry,
                tool,
                args,
                hooks,
                Skill::ClearCollision,
                "✓ Collision detection flag cleared",
                "❌ Error clearing collision flag: ",
            )
            .await
        }
        "calibrate" => {
            simple_skill(
                registry,
                tool,
                args,
                hooks,
                Skill::Calibrate,
                "✓ Robot calibration completed successfully",
                "❌ Robot calibration failed: ",
            )
            .await
        }
        "get_detected_objects" => get_detected_objects(registry, args, hooks).await,
        "get_detected_object" => get_detected_object(registry, args, hooks).await,
        "get_largest_detected_object" => extreme_object(registry, args, hooks, true).await,
        "get_smallest_detected_object" => extreme_object(registry, args, hooks, false).await,
        "get_detected_objects_sorted" => sorted_objects(registry, args, hooks).await,
        "get_largest_free_space_with_center" => free_space(registry, args, hooks).await,
        "get_workspace_coordinate_from_point" => workspace_coordinate(registry, args).await,
        "get_object_labels_as_string" => labels(registry, args).await,
        "add_object_name2object_labels" => add_label(registry, args).await,
        "get_system_status" => system_status(registry, args).await,
        "speak" => speak(registry, args),
        "set_user_task" => set_user_task(registry, args),
        other => Err(ToolOutput::failed(format!(
            "❌ Error: tool '{other}' has no handler"
        ))),
    };
    outcome.unwrap_or_else(|failure| failure)
}

// ---------------------------------------------------------------------------------------
// Skills

/// How a skill call ended, other than success.
enum SkillFailure {
    /// The skill ran and failed; the reason a user can act on.
    Failed(String),
    /// The skills actor could not be asked at all.
    Unavailable(String),
}

impl SkillFailure {
    fn reason(&self) -> &str {
        match self {
            SkillFailure::Failed(r) | SkillFailure::Unavailable(r) => r,
        }
    }
}

struct Done {
    object: Option<DetectedObject>,
    from: Option<Point2>,
    to: Option<Point2>,
}

impl Done {
    fn data(&self) -> Value {
        json!({
            "object": self.object,
            "from": self.from.map(pt_json),
            "to": self.to.map(pt_json),
        })
    }
}

/// Publishes a cancel for the run when dropped before it finished (a client that went away
/// mid-motion stops the arm).
struct CancelOnDrop<'a> {
    registry: &'a Registry,
    run_id: u64,
    armed: bool,
}

impl CancelOnDrop<'_> {
    fn cancel(&mut self) {
        if !self.armed {
            return;
        }
        self.armed = false;
        let publisher = self
            .registry
            .inner
            .cancel
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        if let Err(error) = publisher.publish(&SkillCancel {
            run_id: self.run_id,
        }) {
            tracing::error!(%error, run_id = self.run_id, "could not send a skill cancel");
        }
    }
}

impl Drop for CancelOnDrop<'_> {
    fn drop(&mut self) {
        self.registry
            .inner
            .progress_routes
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&self.run_id);
        self.cancel();
    }
}

async fn run_skill(
    registry: &Registry,
    skill: Skill,
    hooks: &CallHooks,
) -> Result<Done, SkillFailure> {
    let inner = &registry.inner;
    let run_id = inner.next_run.fetch_add(1, Ordering::Relaxed);
    let (tx, mut progress) = mpsc::unbounded_channel();
    inner
        .progress_routes
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert(run_id, tx);
    let mut guard = CancelOnDrop {
        registry,
        run_id,
        armed: true,
    };
    let request = SkillRequest { run_id, skill };
    let reply = inner.skills.request(&request, inner.settings.skill_timeout);
    tokio::pin!(reply);
    let mut cancel_sent = false;
    let reply = loop {
        tokio::select! {
            reply = &mut reply => break reply,
            Some(p) = progress.recv() => {
                if let Some(report) = &hooks.progress {
                    report(Progress { step: p.step, total: p.total, message: p.message });
                }
            }
            _ = hooks.cancel.cancelled(), if !cancel_sent => {
                cancel_sent = true;
                tracing::info!(run_id, "tool call cancelled; stopping the skill");
                guard.cancel();
            }
        }
    };
    guard.armed = false;
    match reply {
        Ok(SkillReply::Done { object, from, to }) => Ok(Done {
            object: object.map(|o| *o),
            from,
            to,
        }),
        Ok(SkillReply::Failed { error }) => Err(SkillFailure::Failed(error.to_string())),
        Err(error) => Err(SkillFailure::Unavailable(format!(
            "the skills actor did not answer: {error}"
        ))),
    }
}

fn location_text(location: Location) -> String {
    match location {
        Location::None => " at".to_owned(),
        other => format!(" {other} coordinate"),
    }
}

async fn pick_place_object(
    registry: &Registry,
    args: &Arguments,
    hooks: CallHooks,
) -> Result<ToolOutput, ToolOutput> {
    let tool = "pick_place_object";
    let (name, pick, place, location, z) = parse(tool, args, |a| {
        let name = a.text("object_name");
        let pick = a.point("pick_coordinate");
        let place = a.point("place_coordinate");
        let location = a.word::<Location>("location", Some(Location::None));
        let z = a.number_in("z_offset", DEFAULT_Z_OFFSET_M, 0.0, 0.1);
        Some((name?, pick?, place?, location?, z?))
    })?;
    let skill = Skill::PickPlace {
        object_name: name.clone(),
        pick_at: pick,
        place_at: place,
        location,
        z_offset_m: z,
    };
    match run_skill(registry, skill, &hooks).await {
        Ok(done) => {
            let z_text = if (z - DEFAULT_Z_OFFSET_M).abs() > 1e-12 {
                format!(" (z_offset: {z:.3}m)")
            } else {
                String::new()
            };
            Ok(ToolOutput::ok(
                format!(
                    "✓ Successfully picked '{name}' from {}{z_text} and placed it{} {}",
                    pt(pick),
                    location_text(location),
                    pt(place)
                ),
                done.data(),
            ))
        }
        Err(SkillFailure::Unavailable(reason)) => Err(ToolOutput::failed(format!(
            "❌ Error during {tool}: {reason}"
        ))),
        Err(failure) => Err(ToolOutput::failed(format!(
            "❌ Failed to pick and place '{name}': {}",
            failure.reason()
        ))),
    }
}

async fn pick_object(
    registry: &Registry,
    args: &Arguments,
    hooks: CallHooks,
) -> Result<ToolOutput, ToolOutput> {
    let (name, pick, z) = parse("pick_object", args, |a| {
        let name = a.text("object_name");
        let pick = a.point("pick_coordinate");
        let z = a.number_in("z_offset", DEFAULT_Z_OFFSET_M, 0.0, 0.1);
        Some((name?, pick?, z?))
    })?;
    let skill = Skill::Pick {
        object_name: name.clone(),
        pick_at: pick,
        z_offset_m: z,
    };
    match run_skill(registry, skill, &hooks).await {
        Ok(done) => {
            let z_text = if (z - DEFAULT_Z_OFFSET_M).abs() > 1e-12 {
                format!(" with z_offset {z:.3}m")
            } else {
                String::new()
            };
            Ok(ToolOutput::ok(
                format!("✓ Successfully picked '{name}' from {}{z_text}", pt(pick)),
                done.data(),
            ))
        }
        Err(failure) => Err(ToolOutput::failed(format!(
            "❌ Failed to pick '{name}': {}",
            failure.reason()
        ))),
    }
}

async fn place_object(
    registry: &Registry,
    args: &Arguments,
    hooks: CallHooks,
) -> Result<ToolOutput, ToolOutput> {
    let (place, location) = parse("place_object", args, |a| {
        let place = a.point("place_coordinate");
        let location = a.word::<Location>("location", Some(Location::None));
        Some((place?, location?))
    })?;
    let skill = Skill::Place {
        place_at: place,
        location,
    };
    match run_skill(registry, skill, &hooks).await {
        Ok(done) => Ok(ToolOutput::ok(
            format!(
                "✓ Successfully placed object{} {}",
                location_text(location),
                pt(place)
            ),
            done.data(),
        )),
        Err(failure) => Err(ToolOutput::failed(format!(
            "❌ Failed to place object: {}",
            failure.reason()
        ))),
    }
}

/// Longest push, millimetres (the workspaces are about 20 cm across).
const MAX_PUSH_MM: f64 = 500.0;
/// Longest move2by, metres.
const MAX_MOVE_M: f64 = 0.5;

async fn push_object(
    registry: &Registry,
    args: &Arguments,
    hooks: CallHooks,
) -> Result<ToolOutput, ToolOutput> {
    let (name, at, direction, distance_mm) = parse("push_object", args, |a| {
        let name = a.text("object_name");
        let at = a.point("push_coordinate");
        let direction = a.word::<Direction>("direction", None);
        let distance = a.positive("distance", MAX_PUSH_MM);
        Some((name?, at?, direction?, distance?))
    })?;
    let skill = Skill::Push {
        object_name: name.clone(),
        push_at: at,
        direction,
        distance_m: distance_mm / 1000.0,
    };
    match run_skill(registry, skill, &hooks).await {
        Ok(done) => Ok(ToolOutput::ok(
            format!(
                "✓ Successfully pushed '{name}' from {} {direction} by {distance_mm:.1}mm",
                pt(at)
            ),
            done.data(),
        )),
        Err(failure) => Err(ToolOutput::failed(format!(
            "❌ Failed to push '{name}': {}",
            failure.reason()
        ))),
    }
}

async fn move2by(
    registry: &Registry,
    args: &Arguments,
    hooks: CallHooks,
) -> Result<ToolOutput, ToolOutput> {
    let tool = "move2by";
    let (name, pick, direction_word, distance, z) = parse(tool, args, |a| {
        let name = a.text("object_name");
        let pick = a.point("pick_coordinate");
        let direction = a.raw_word("direction");
        let distance = a.positive("distance", MAX_MOVE_M);
        let z = a.number_in("z_offset", DEFAULT_Z_OFFSET_M, 0.0, 0.1);
        Some((name?, pick?, direction?, distance?, z?))
    })?;
    let Ok(direction) = direction_word.parse::<Direction>() else {
        return Err(ToolOutput::failed(format!(
            "❌ Error during {tool}: Invalid direction '{direction_word}'"
        )));
    };
    let target = direction.offset(pick, distance);
    let skill = Skill::MoveBy {
        object_name: name.clone(),
        pick_at: pick,
        direction,
        distance_m: distance,
        z_offset_m: z,
    };
    match run_skill(registry, skill, &hooks).await {
        Ok(done) => Ok(ToolOutput::ok(
            format!(
                "✓ Successfully picked '{name}' from {} and placed it {:.1} centimeters {direction}wards at {}",
                pt(pick),
                distance * 100.0,
                pt(target)
            ),
            done.data(),
        )),
        Err(failure) => Err(ToolOutput::failed(format!(
            "❌ Failed to pick and move '{name}': {}",
            failure.reason()
        ))),
    }
}

async fn move2observation_pose(
    registry: &Registry,
    args: &Arguments,
    hooks: CallHooks,
) -> Result<ToolOutput, ToolOutput> {
    let ws = parse("move2observation_pose", args, |a| a.text("workspace_id"))?;
    let skill = Skill::GoToObservationPose {
        workspace_id: ws.clone(),
    };
    match run_skill(registry, skill, &hooks).await {
        Ok(_) => Ok(ToolOutput::ok(
            format!("✓ Moved to observation pose for workspace '{ws}'"),
            json!({"workspace_id": ws}),
        )),
        Err(failure) => Err(ToolOutput::failed(format!(
            "❌ Error moving to observation pose: {}",
            failure.reason()
        ))),
    }
}

async fn simple_skill(
    registry: &Registry,
    tool: &str,
    args: &Arguments,
    hooks: CallHooks,
    skill: Skill,
    success: &str,
    failure_prefix: &str,
) -> Result<ToolOutput, ToolOutput> {
    parse(tool, args, |_| Some(()))?;
    match run_skill(registry, skill, &hooks).await {
        Ok(_) => Ok(ToolOutput::ok(success.to_owned(), json!({}))),
        Err(failure) => Err(ToolOutput::failed(format!(
            "{failure_prefix}{}",
            failure.reason()
        ))),
    }
}

// ---------------------------------------------------------------------------------------
// Detection

/// Position within which the arm counts as at the observation pose, metres.
const AT_POSE_M: f64 = 0.005;
/// Orientation within which the arm counts as at the observation pose, radians.
const AT_POSE_RAD: f64 = 0.05;

fn same_pose(a: &Pose, b: &Pose) -> bool {
    let dp = ((a.x_m - b.x_m).powi(2) + (a.y_m - b.y_m).powi(2) + (a.z_m - b.z_m).powi(2)).sqrt();
    let qa = UnitQuaternion::from_euler_angles(a.roll_rad, a.pitch_rad, a.yaw_rad);
    let qb = UnitQuaternion::from_euler_angles(b.roll_rad, b.pitch_rad, b.yaw_rad);
    dp <= AT_POSE_M && qa.angle_to(&qb) <= AT_POSE_RAD
}

/// The time after which a camera view counts as fresh: when the arm came to rest at the
/// observation pose, moving it there first if needed.
async fn fresh_view(registry: &Registry, hooks: &CallHooks) -> Result<u64, String> {
    let ws = &registry.settings().workspaces[0];
    let rest = *registry.inner.arm_rest.borrow();
    if let Some(rest) = rest {
        if !rest.moving && same_pose(&rest.pose, &ws.observation_pose) {
            return Ok(rest.rested_since_unix_ns);
        }
    }
    let skill = Skill::GoToObservationPose {
        workspace_id: ws.id.clone(),
    };
    match run_skill(registry, skill, hooks).await {
        Ok(_) => Ok(robotd_protocol::envelope::unix_now_ns()),
        Err(failure) => Err(format!(
            "could not move to the observation pose of '{}': {}",
            ws.id,
            failure.reason()
        )),
    }
}

async fn ask(
    registry: &Registry,
    request: WorkspaceRequest,
    fresh_after_unix_ns: Option<u64>,
) -> Result<WorkspaceReply, String> {
    let query = WorkspaceQuery {
        request,
        fresh_after_unix_ns,
        max_wait_ms: 0,
    };
    match registry
        .query_client()
        .request(&query, registry.settings().query_timeout)
        .await
    {
        Ok(reply) => reply.into_result().map_err(|e| e.to_string()),
        Err(error) => Err(format!("the workspace model did not answer: {error}")),
    }
}

/// Asks `request` from a fresh view.
async fn ask_fresh(
    registry: &Registry,
    request: WorkspaceRequest,
    hooks: &CallHooks,
) -> Result<WorkspaceReply, String> {
    let fresh = fresh_view(registry, hooks).await?;
    ask(registry, request, Some(fresh)).await
}

fn unexpected(reply: &WorkspaceReply) -> String {
    format!("unexpected answer from the workspace model: {reply:?}")
}

async fn get_detected_objects(
    registry: &Registry,
    args: &Arguments,
    hooks: CallHooks,
) -> Result<ToolOutput, ToolOutput> {
    let (location, coordinate, label) = parse("get_detected_objects", args, |a| {
        let location = a.word::<Location>("location", Some(Location::None));
        let coordinate = a.opt_point("coordinate");
        let label = a.opt_text("label");
        Some((location?, coordinate, label))
    })?;
    let fail =
        |reason: String| ToolOutput::failed(format!("❌ Error getting detected objects: {reason}"));
    if location.needs_coordinate() && coordinate.is_none() {
        return Err(fail(format!(
            "Coordinate must be provided for location filter: {location}"
        )));
    }
    let request = WorkspaceRequest::GetObjects {
        location,
        coordinate,
        label,
    };
    match ask_fresh(registry, request, &hooks).await.map_err(fail)? {
        WorkspaceReply::Objects { objects } if objects.is_empty() => Ok(ToolOutput::ok(
            "✓ No objects detected matching the criteria".into(),
            json!([]),
        )),
        WorkspaceReply::Objects { objects } => Ok(ToolOutput::ok(
            format!("✓ Found {} object(s):\n{}", objects.len(), pretty(&objects)),
            json!(objects),
        )),
        other => Err(fail(unexpected(&other))),
    }
}

async fn get_detected_object(
    registry: &Registry,
    args: &Arguments,
    hooks: CallHooks,
) -> Result<ToolOutput, ToolOutput> {
    let (coordinate, label) = parse("get_detected_object", args, |a| {
        let coordinate = a.point("coordinate");
        let label = a.opt_text("label");
        Some((coordinate?, label))
    })?;
    let fail =
        |reason: String| ToolOutput::failed(format!("❌ Error getting detected object: {reason}"));
    let request = WorkspaceRequest::GetObjectNear { coordinate, label };
    match ask_fresh(registry, request, &hooks).await.map_err(fail)? {
        WorkspaceReply::Object { object: None } => Ok(ToolOutput::ok(
            format!("✓ No object found near {}", pt(coordinate)),
            Value::Null,
        )),
        WorkspaceReply::Object {
            object: Some(object),
        } => Ok(ToolOutput::ok(
            format!(
                "✓ Found object near {}:\n{}",
                pt(coordinate),
                pretty(&object)
            ),
            json!(object),
        )),
        other => Err(fail(unexpected(&other))),
    }
}

async fn extreme_object(
    registry: &Registry,
    args: &Arguments,
    hooks: CallHooks,
    largest: bool,
) -> Result<ToolOutput, ToolOutput> {
    let (tool, word, request) = if largest {
        (
            "get_largest_detected_object",
            "largest",
            WorkspaceRequest::GetLargestObject,
        )
    } else {
        (
            "get_smallest_detected_object",
            "smallest",
            WorkspaceRequest::GetSmallestObject,
        )
    };
    parse(tool, args, |_| Some(()))?;
    let fail =
        |reason: String| ToolOutput::failed(format!("❌ Error getting {word} object: {reason}"));
    match ask_fresh(registry, request, &hooks).await.map_err(fail)? {
        WorkspaceReply::Object { object: None } => {
            Ok(ToolOutput::ok("✓ No objects detected".into(), Value::Null))
        }
        WorkspaceReply::Object {
            object: Some(object),
        } => {
            let title = if largest { "Largest" } else { "Smallest" };
            Ok(ToolOutput::ok(
                format!(
                    "✓ {title} object ({:.6} m²):\n{}",
                    object.dimensions.size_m2,
                    pretty(&object)
                ),
                json!(object),
            ))
        }
        other => Err(fail(unexpected(&other))),
    }
}

async fn sorted_objects(
    registry: &Registry,
    args: &Arguments,
    hooks: CallHooks,
) -> Result<ToolOutput, ToolOutput> {
    let ascending = parse("get_detected_objects_sorted", args, |a| {
        a.flag("ascending", true)
    })?;
    let fail =
        |reason: String| ToolOutput::failed(format!("❌ Error getting sorted objects: {reason}"));
    let request = WorkspaceRequest::GetObjectsSorted { ascending };
    match ask_fresh(registry, request, &hooks).await.map_err(fail)? {
        WorkspaceReply::Objects { objects } if objects.is_empty() => {
            Ok(ToolOutput::ok("✓ No objects detected".into(), json!([])))
        }
        WorkspaceReply::Objects { objects } => {
            let order = if ascending {
                "smallest to largest"
            } else {
                "largest to smallest"
            };
            Ok(ToolOutput::ok(
                format!(
                    "✓ Found {} object(s) sorted {order}:\n{}",
                    objects.len(),
                    pretty(&objects)
                ),
                json!(objects),
            ))
        }
        other => Err(fail(unexpected(&other))),
    }
}

async fn free_space(
    registry: &Registry,
    args: &Arguments,
    hooks: CallHooks,
) -> Result<ToolOutput, ToolOutput> {
    parse("get_largest_free_space_with_center", args, |_| Some(()))?;
    let fail = |reason: String| {
        ToolOutput::failed(format!("❌ Error getting largest free space: {reason}"))
    };
    match ask_fresh(registry, WorkspaceRequest::GetLargestFreeSpace, &hooks)
        .await
        .map_err(fail)?
    {
        WorkspaceReply::FreeSpace { area_m2, center } => Ok(ToolOutput::ok(
            format!(
                "✓ Largest free space: {area_m2:.4} m² at center coordinates {}",
                pt(center)
            ),
            json!({"area_m2": area_m2, "center": pt_json(center)}),
        )),
        other => Err(fail(unexpected(&other))),
    }
}

// ---------------------------------------------------------------------------------------
// Workspace and labels

async fn workspace_coordinate(
    registry: &Registry,
    args: &Arguments,
) -> Result<ToolOutput, ToolOutput> {
    let (ws, point_word) = parse("get_workspace_coordinate_from_point", args, |a| {
        let ws = a.text("workspace_id");
        let point = a.raw_word("point");
        Some((ws?, point?))
    })?;
    let Ok(point) = point_word.parse::<WorkspacePoint>() else {
        return Err(ToolOutput::failed(format!(
            "❌ Could not get coordinate for '{point_word}' in workspace '{ws}'"
        )));
    };
    let request = WorkspaceRequest::GetWorkspacePoint {
        workspace_id: ws.clone(),
        point,
    };
    match ask(registry, request, None).await {
        Ok(WorkspaceReply::Coordinate { coordinate }) => Ok(ToolOutput::ok(
            format!(
                "✓ Coordinate of '{point}' in workspace '{ws}': {}",
                pt(coordinate)
            ),
            json!({"workspace_id": ws, "point": point.as_str(), "coordinate": pt_json(coordinate)}),
        )),
        Ok(other) => Err(ToolOutput::failed(format!(
            "❌ Could not get coordinate for '{point}' in workspace '{ws}': {}",
            unexpected(&other)
        ))),
        Err(reason) => Err(ToolOutput::failed(format!(
            "❌ Error getting workspace coordinate: {reason}"
        ))),
    }
}

async fn labels(registry: &Registry, args: &Arguments) -> Result<ToolOutput, ToolOutput> {
    parse("get_object_labels_as_string", args, |_| Some(()))?;
    let fail =
        |reason: String| ToolOutput::failed(format!("❌ Error getting object labels: {reason}"));
    match ask(registry, WorkspaceRequest::GetLabels, None)
        .await
        .map_err(fail)?
    {
        WorkspaceReply::Labels { labels, .. } if labels.is_empty() => Ok(ToolOutput::ok(
            "✓ Detectable objects: No detectable objects configured.".into(),
            json!({"labels": labels}),
        )),
        WorkspaceReply::Labels { labels, .. } => Ok(ToolOutput::ok(
            format!(
                "✓ Detectable objects: I can recognize these objects: {}",
                labels.join(", ")
            ),
            json!({"labels": labels}),
        )),
        other => Err(fail(unexpected(&other))),
    }
}

async fn add_label(registry: &Registry, args: &Arguments) -> Result<ToolOutput, ToolOutput> {
    let mut a = Args::new(args);
    let name = a.text("object_name");
    let problems = a.finish();
    let name = match (name, problems) {
        (Some(name), Ok(())) => name,
        (_, Err(errors)) if errors.iter().all(|e| e.field == "object_name") => {
            return Err(ToolOutput::failed(
                "❌ Validation Error: object_name must be a non-empty string".into(),
            ))
        }
        (_, Err(errors)) => return Err(invalid("add_object_name2object_labels", errors)),
        (None, Ok(())) => unreachable!("a missing name is a problem"),
    };
    let fail =
        |reason: String| ToolOutput::failed(format!("❌ Error adding object label: {reason}"));
    match ask(
        registry,
        WorkspaceRequest::AddLabel {
            label: name.clone(),
        },
        None,
    )
    .await
    .map_err(fail)?
    {
        WorkspaceReply::LabelAdded {
            label,
            already_known,
        } => {
            let text = if already_known {
                format!("✓ {name} is already in the list of recognizable objects.")
            } else {
                format!("✓ Added {name} to the list of recognizable objects.")
            };
            Ok(ToolOutput::ok(
                text,
                json!({"label": label, "already_known": already_known}),
            ))
        }
        other => Err(fail(unexpected(&other))),
    }
}

fn round3(v: f64) -> f64 {
    // + 0.0 turns -0.0 into 0.0.
    (v * 1000.0).round() / 1000.0 + 0.0
}

async fn system_status(registry: &Registry, args: &Arguments) -> Result<ToolOutput, ToolOutput> {
    parse("get_system_status", args, |_| Some(()))?;
    let settings = registry.settings();
    let pose = match registry
        .inner
        .arm
        .request(&ArmCommand::GetPose, std::time::Duration::from_secs(5))
        .await
    {
        Ok(ArmReply::Ok { pose }) => pose,
        Ok(ArmReply::Error { error }) => {
            return Err(ToolOutput::failed(format!(
                "❌ Error getting system status: {error}"
            )))
        }
        Ok(other) => {
            return Err(ToolOutput::failed(format!(
                "❌ Error getting system status: unexpected arm reply {other:?}"
            )))
        }
        Err(error) => {
            return Err(ToolOutput::failed(format!(
                "❌ Error getting system status: the arm did not answer: {error}"
            )))
        }
    };
    let mut status = json!({
        "robot_id": settings.robot_id,
        "workspace_id": settings.workspaces[0].id,
        "pose": {
            "x": round3(pose.x_m), "y": round3(pose.y_m), "z": round3(pose.z_m),
            "roll": round3(pose.roll_rad), "pitch": round3(pose.pitch_rad), "yaw": round3(pose.yaw_rad),
        },
    });
    if let (Value::Object(extra), Some(map)) = ((settings.status)(), status.as_object_mut()) {
        for (k, v) in extra {
            map.entry(k).or_insert(v);
        }
    }
    Ok(ToolOutput::ok(pretty(&status), status))
}

// ---------------------------------------------------------------------------------------
// Feedback

fn speak(registry: &Registry, args: &Arguments) -> Result<ToolOutput, ToolOutput> {
    let mut a = Args::new(args);
    let text = a.text("text");
    let text = match (text, a.finish()) {
        (Some(text), Ok(())) => text,
        (_, Err(errors)) if errors.iter().all(|e| e.field == "text") => {
            return Err(ToolOutput::failed(
                "❌ Validation Error: text must be a non-empty string".into(),
            ))
        }
        (_, Err(errors)) => return Err(invalid("speak", errors)),
        (None, Ok(())) => unreachable!("a missing text is a problem"),
    };
    let chars = text.chars().count();
    if chars > MAX_SPEECH_CHARS {
        return Err(invalid(
            "speak",
            vec![FieldError {
                field: "text".into(),
                message: format!("must be at most {MAX_SPEECH_CHARS} characters, got {chars}"),
            }],
        ));
    }
    let publisher = registry
        .inner
        .speak
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    match publisher.publish(&SpeakRequest::new(text.clone(), "mcp")) {
        Ok(0) => Err(ToolOutput::failed(
            "❌ Error speaking: the text-to-speech actor is not running".into(),
        )),
        Ok(_) => Ok(ToolOutput::ok(
            format!("✓ Speaking: '{text}'"),
            json!({"text": text}),
        )),
        Err(error) => Err(ToolOutput::failed(format!("❌ Error speaking: {error}"))),
    }
}

fn set_user_task(registry: &Registry, args: &Arguments) -> Result<ToolOutput, ToolOutput> {
    let task = parse("set_user_task", args, |a| a.text("task"))?;
    let mut overlay = TextOverlay::new(task.clone(), OverlayKind::UserTask);
    overlay.tool_name = Some("set_user_task".into());
    let publisher = registry
        .inner
        .overlay
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    match publisher.publish(&overlay) {
        Ok(_) => Ok(ToolOutput::ok(
            format!("✓ User task set: {task}"),
            json!({"task": task}),
        )),
        Err(error) => Err(ToolOutput::failed(format!(
            "❌ Error setting the user task: {error}"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_compare_by_position_and_rotation() {
        let a = Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027);
        // The same rotation written with other Euler angles.
        let q = UnitQuaternion::from_euler_angles(a.roll_rad, a.pitch_rad, a.yaw_rad);
        let (r, p, y) = q.euler_angles();
        let b = Pose::new(0.174, -0.002, 0.277, r, p, y);
        assert!(same_pose(&a, &b));
        let c = Pose::new(0.173, -0.002, 0.277, -3.042, 1.2, -3.027);
        assert!(!same_pose(&a, &c));
        assert_eq!(pt(Point2::new(0.2, -0.0504)), "[0.200, -0.050]");
        assert_eq!(
            location_text(Location::RightNextTo),
            " right next to coordinate"
        );
    }
}
