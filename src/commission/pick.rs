//! The supervised pick of `robotd commission`: the whole chain — camera, mount, perception,
//! kinematics, gripper — on one object, with the camera judging the result.
//!
//! The operator puts a small object (a cube of 2–4 cm) at the centre of the workspace sheet.
//! From the observation pose robotd finds it in a still frame (the perception pipeline, on the
//! configured intrinsics), picks it — above it, straight down to its centre's height, close,
//! up — puts it back where it found it, opens, rises and looks again. The report gives the
//! object's position before and after as the camera measured them, and the distance between:
//! what one pick-and-place moves an object that should not have moved at all. Every motion goes
//! through `arm/command` and `gripper/command` (origin `cli`) at the capped speed; the arm ends
//! at the observation pose.
//!
//! Refused, before anything moves: no object within [`CENTRE_RADIUS_M`] of the sheet's centre
//! (what the camera sees instead is listed), the sheet not in view. A grasp that catches
//! nothing fails the step after the arm has risen and returned to the observation pose.

use super::session::Session;
use anyhow::{bail, Context, Result};
use robotd_config::Config;
use robotd_protocol::geometry::Pose;
use robotd_protocol::gripper::{GripperCommand, GripperReply};
use robotd_protocol::objects::DetectedObject;
use robotd_vision::detector::{ColourDetector, ColourDetectorSettings, FrameView};
use robotd_vision::labels::LabelTable;
use robotd_vision::Pipeline;
use serde::Serialize;
use std::f64::consts::FRAC_PI_2;
use std::time::Duration;

/// The object must lie this close to the sheet's centre, metres.
pub const CENTRE_RADIUS_M: f64 = 0.04;

/// Height above the object's centre the gripper approaches from, metres.
const APPROACH_M: f64 = 0.08;

/// What the pick step measured.
#[derive(Debug, Clone, Serialize)]
pub struct PickReport {
    /// The object picked, as the detector named it.
    pub label: String,
    /// Where the camera saw it before, `[x, y]` metres.
    pub before_m: [f64; 2],
    /// Where the camera saw it after it was put back, `[x, y]` metres.
    pub after_m: [f64; 2],
    /// The distance between, millimetres.
    pub error_mm: f64,
    /// Whether the gripper reported holding it.
    pub held: bool,
}

fn down(x: f64, y: f64, z: f64, yaw: f64) -> Pose {
    Pose::new(x, y, z, 0.0, FRAC_PI_2, yaw)
}

/// The objects the camera sees from the observation pose.
async fn look(
    session: &mut Session,
    pipeline: &mut Pipeline,
    observation: Pose,
) -> Result<Vec<DetectedObject>> {
    session
        .move_to(observation)
        .await
        .map_err(|e| anyhow::anyhow!("going to the observation pose: {e}"))?;
    let frame = session.still_frame(Duration::from_secs(10)).await?;
    let view = FrameView {
        rgb: &frame.rgb,
        width: frame.width as usize,
        height: frame.height as usize,
        frame_id: frame.frame_id,
        timestamp_unix_ns: 0,
    };
    let (detections, status) = pipeline
        .process(&view, Some(&observation), true)
        .context("the detector failed on the frame")?;
    if status != robotd_vision::SheetStatus::Found {
        bail!("{status}");
    }
    Ok(detections.objects)
}

async fn gripper(session: &Session, command: GripperCommand) -> Result<bool> {
    match session.gripper(command.clone()).await? {
        GripperReply::State { holding, .. } => Ok(holding),
        GripperReply::Error { error } => bail!("gripper {command:?}: {error}"),
    }
}

/// Runs the step on `session`.
pub async fn run(
    session: &mut Session,
    config: &Config,
    workspace_id: Option<&str>,
) -> Result<PickReport> {
    let model = config.robot.model();
    let workspaces = config.robot.workspaces();
    let Some(spec) = (match workspace_id {
        Some(id) => workspaces.iter().find(|w| w.id == id),
        None => workspaces.first(),
    }) else {
        bail!("no such workspace configured: the pick uses the workspace sheet");
    };
    let detector = ColourDetector::new(LabelTable::builtin(), ColourDetectorSettings::default());
    let mut pipeline = Pipeline::new(
        &session.intrinsics(),
        vec![spec.to_info(model)],
        Box::new(detector),
    )?;
    let observation = Pose::from_array(spec.observation_pose);
    let [cx, cy] = spec.centre();
    let seen = look(session, &mut pipeline, observation).await?;
    let Some(object) = seen
        .iter()
        .filter(|o| (o.xy().x_m - cx).hypot(o.xy().y_m - cy) <= CENTRE_RADIUS_M)
        .min_by(|a, b| {
            let d = |o: &DetectedObject| (o.xy().x_m - cx).hypot(o.xy().y_m - cy);
            d(a).total_cmp(&d(b))
        })
        .cloned()
    else {
        let listed: Vec<String> = seen
            .iter()
            .map(|o| format!("{} at ({:.3}, {:.3})", o.label, o.xy().x_m, o.xy().y_m))
            .collect();
        bail!(
            "no object within {:.0} cm of the sheet's centre ({cx:.3}, {cy:.3}): put a small \
             cube there; the camera sees {}",
            CENTRE_RADIUS_M * 100.0,
            if listed.is_empty() {
                "nothing".to_owned()
            } else {
                listed.join(", ")
            }
        );
    };
    let (x, y) = (object.xy().x_m, object.xy().y_m);
    let z = object.position.center_of_mass.z_m.max(0.005);
    let yaw = object.gripper_rotation_rad;
    let step = |what: &'static str| move |e: String| anyhow::anyhow!("{what}: {e}");
    gripper(session, GripperCommand::Open).await?;
    session
        .move_to(down(x, y, z + APPROACH_M, yaw))
        .await
        .map_err(step("above the object"))?;
    session
        .move_to(down(x, y, z, yaw))
        .await
        .map_err(step("down to the object"))?;
    let held = gripper(session, GripperCommand::Close).await?;
    session
        .move_to(down(x, y, z + APPROACH_M, yaw))
        .await
        .map_err(step("lifting the object"))?;
    session
        .move_to(down(x, y, z + 0.002, yaw))
        .await
        .map_err(step("putting the object back"))?;
    gripper(session, GripperCommand::Open).await?;
    session
        .move_to(down(x, y, z + APPROACH_M, yaw))
        .await
        .map_err(step("rising from the object"))?;
    let after = look(session, &mut pipeline, observation).await?;
    let Some(back) = after
        .iter()
        .filter(|o| o.label == object.label)
        .min_by(|a, b| {
            let d = |o: &DetectedObject| (o.xy().x_m - x).hypot(o.xy().y_m - y);
            d(a).total_cmp(&d(b))
        })
    else {
        bail!(
            "the {} is no longer seen after the pick: it may have fallen off the sheet",
            object.label
        );
    };
    if !held {
        bail!(
            "the gripper closed on nothing: the {} was not caught (seen at ({x:.3}, {y:.3}))",
            object.label
        );
    }
    let after_m = [back.xy().x_m, back.xy().y_m];
    Ok(PickReport {
        label: object.label.clone(),
        before_m: [x, y],
        after_m,
        error_mm: (after_m[0] - x).hypot(after_m[1] - y) * 1000.0,
        held,
    })
}
