//! The camera step of `robotd commission`: whether the images come already rectified, where
//! the camera sits on the arm (hand-eye calibration) and how high the table is.
//!
//! The arm visits up to 10 views of the workspace sheet: its observation pose, then that
//! pose's joints turned by small steps (each joint by −1, 0 or +1 step: base ±0.15 rad,
//! shoulder and elbow ±0.12, forearm and wrist ±0.3, tool ±0.4) — only the combinations in which the camera, where robotd believes
//! it is, sees all four markers well inside the picture, picked so that their viewing
//! directions differ most. Each view is a motion like any other (the motion policy admits it,
//! the fence and the speed cap apply, the e-stop stops it); a view the policy refuses or that
//! does not show the four markers is skipped with its reason. The arm ends back at the
//! observation pose.
//!
//! In each still frame the sheet's four markers are found as perception finds them. Their raw
//! pixels are then read twice: undistorted with the lens's model (the images are raw), and as
//! they are (the robot rectified them already). [`super::handeye::solve`] fits the mount and
//! the table height under each reading; the reading that explains the views better says
//! whether the images are rectified — with a lens as strong as the Ned2's (k1 ≈ −0.41), the
//! wrong one leaves millimetres where the right one leaves tenths. A result whose worst
//! marker is off by more than [`MAX_RESIDUAL_MM`] is refused: the views disagree.

use super::handeye::{self, Pinhole, View};
use super::session::Session;
use anyhow::{bail, Result};
use nalgebra::Isometry3;
use robotd_config::Config;
use robotd_kinematics::{pose_to_isometry, CameraMount, Kinematics};
use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::geometry::{Pose, RobotModel};
use robotd_protocol::location::WorkspacePoint;
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_vision::detector::{ColourDetector, ColourDetectorSettings, FrameView};
use robotd_vision::labels::LabelTable;
use robotd_vision::markers::MarkerObservation;
use robotd_vision::Pipeline;
use serde::Serialize;
use std::time::Duration;

/// The worst marker of an accepted calibration may be off by this much, mm on the table.
pub const MAX_RESIDUAL_MM: f64 = 2.5;

/// Fewest good views the step needs.
pub const MIN_GOOD_VIEWS: usize = 6;

/// What the camera step measured.
#[derive(Debug, Clone, Serialize)]
pub struct CameraReport {
    /// Workspace whose sheet was used.
    pub workspace: String,
    /// Views planned, and those that showed the sheet.
    pub views_planned: usize,
    /// Views used.
    pub views_used: usize,
    /// Views skipped and why.
    pub skipped: Vec<String>,
    /// The measured mount: `[x_m, y_m, z_m, roll_deg, pitch_deg, yaw_deg]`.
    pub mount: [f64; 6],
    /// The configured mount, the same way.
    pub configured_mount: [f64; 6],
    /// How far the measured mount is from the configured one, mm.
    pub mount_change_mm: f64,
    /// How far it is turned from the configured one, degrees.
    pub mount_change_deg: f64,
    /// The table's height (the sheet's surface), metres, base frame, fitted together with the
    /// mount as a check: robotd's model puts it at 0, and the mount is fitted with it there
    /// (see `handeye`); a few millimetres off means the robot stands lower or higher than
    /// the table.
    pub table_z_m: f64,
    /// RMS of the markers' disagreement, mm.
    pub residual_mm_rms: f64,
    /// The worst marker's disagreement, mm.
    pub residual_mm_max: f64,
    /// Whether the robot sends images already rectified; `None` when the lens has no
    /// distortion to tell by.
    pub images_rectified: Option<bool>,
    /// Worst residual reading the images as raw (undistorted with the lens model), mm.
    pub residual_mm_max_as_raw: Option<f64>,
    /// Worst residual reading the images as rectified, mm.
    pub residual_mm_max_as_rectified: Option<f64>,
}

/// How far inside the image every marker must be predicted for a view to be planned, pixels
/// (room for a mount a few degrees off what robotd believes).
const PLAN_MARGIN_PX: f64 = 45.0;

/// Most views visited.
pub const MAX_VIEWS: usize = 10;

/// The step each joint is turned by from the observation pose, radians, base to tool: the
/// shoulder and elbow move the camera, the wrist tilts it back towards the sheet.
const JOINT_STEPS_RAD: [f64; 6] = [0.15, 0.12, 0.12, 0.3, 0.3, 0.4];

/// The views to visit, as joints: the observation pose's joints each turned by -1, 0 or +1
/// of [`JOINT_STEPS_RAD`], kept when the believed camera would see all four
/// markers well inside the picture, then picked greedily so that their viewing directions
/// differ most (the first is the observation pose itself).
pub fn plan_views(
    kinematics: &Kinematics,
    observation: &[f64],
    markers: &[[f64; 2]; 4],
    table_z_m: f64,
    pin: &Pinhole,
    size: (u32, u32),
) -> Vec<Vec<f64>> {
    let mut candidates: Vec<(Vec<f64>, Isometry3<f64>)> = Vec::new();
    // Every joint by -1, 0 or +1 step: 729 postures, each a forward kinematics away.
    for code in 0..3usize.pow(JOINT_STEPS_RAD.len() as u32) {
        let mut q = observation.to_vec();
        let mut rest = code;
        for (joint, step) in JOINT_STEPS_RAD.iter().enumerate() {
            q[joint] += step * ((rest % 3) as f64 - 1.0);
            rest /= 3;
        }
        if kinematics.check_joints(&q).is_err() {
            continue;
        }
        let Some(camera) = kinematics.camera_pose(&q) else {
            continue;
        };
        let inside = markers.iter().all(|m| {
            let p = camera.inverse_transform_point(&nalgebra::Point3::new(m[0], m[1], table_z_m));
            let (u, v) = (pin.fx * p.x / p.z + pin.cx, pin.fy * p.y / p.z + pin.cy);
            p.z > 0.05
                && (PLAN_MARGIN_PX..=size.0 as f64 - PLAN_MARGIN_PX).contains(&u)
                && (PLAN_MARGIN_PX..=size.1 as f64 - PLAN_MARGIN_PX).contains(&v)
        });
        if inside {
            candidates.push((q, camera));
        }
    }
    // The observation pose first, then each time the candidate whose camera differs most
    // (angle plus distance) from those already chosen.
    let mut chosen: Vec<(Vec<f64>, Isometry3<f64>)> = Vec::new();
    if let Some(camera) = kinematics.camera_pose(observation) {
        chosen.push((observation.to_vec(), camera));
    }
    while chosen.len() < MAX_VIEWS && !candidates.is_empty() {
        let gap = |camera: &Isometry3<f64>| {
            chosen
                .iter()
                .map(|(_, other)| {
                    camera.rotation.angle_to(&other.rotation)
                        + (camera.translation.vector - other.translation.vector).norm() * 5.0
                })
                .fold(f64::INFINITY, f64::min)
        };
        let (best, _) = candidates
            .iter()
            .enumerate()
            .map(|(i, (_, camera))| (i, gap(camera)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .expect("not empty");
        chosen.push(candidates.swap_remove(best));
    }
    chosen.into_iter().map(|(q, _)| q).collect()
}

/// The four marker centres of `workspace` on the table, in the order
/// `plane_from_markers` returns its markers (upper-left, upper-right, lower-left, lower-right).
fn marker_points(workspace: &WorkspaceInfo) -> [[f64; 2]; 4] {
    [
        WorkspacePoint::UpperLeftCorner,
        WorkspacePoint::UpperRightCorner,
        WorkspacePoint::LowerLeftCorner,
        WorkspacePoint::LowerRightCorner,
    ]
    .map(|p| {
        let q = workspace.point(p);
        [q.x_m, q.y_m]
    })
}

/// The lens model to undo on raw images: the driver's, or for a driver that reports none
/// (the images are rectified, or it was told so) the Ned2's own.
fn lens(model: RobotModel, reported: &CameraIntrinsics) -> CameraIntrinsics {
    if reported.distortion.iter().any(|k| *k != 0.0) || model != RobotModel::Ned2 {
        return reported.clone();
    }
    let mut ned2 = robotd_driver::hardware::ned2_camera_intrinsics();
    ned2.fx = reported.fx;
    ned2.fy = reported.fy;
    ned2.cx = reported.cx;
    ned2.cy = reported.cy;
    ned2
}

/// One view's parent pose and raw marker pixels.
struct RawView {
    parent: Isometry3<f64>,
    markers: Vec<([f64; 2], [f64; 2])>,
}

/// Two frames in a row must put every marker within this many pixels of each other for a
/// view to count: a frame from while the arm still moved (a camera's latency is an estimate)
/// does not.
const STEADY_PX: f64 = 0.35;

/// The four markers of the sheet in a steady picture, with the joints the arm rests at;
/// `Ok(Err(reason))` when the picture shows no sheet or does not settle.
async fn steady_markers(
    session: &mut Session,
    pipeline: &mut Pipeline,
    workspace: &WorkspaceInfo,
) -> Result<Result<(Vec<f64>, [MarkerObservation; 4]), String>> {
    let mut previous: Option<[MarkerObservation; 4]> = None;
    for _ in 0..8 {
        let frame = session.still_frame(Duration::from_secs(10)).await?;
        let view = FrameView {
            rgb: &frame.rgb,
            width: frame.width as usize,
            height: frame.height as usize,
            frame_id: frame.frame_id,
            timestamp_unix_ns: 0,
        };
        let markers = pipeline.find_markers(&view);
        let four = match pipeline.plane_from_markers(&view, &markers, workspace) {
            Ok((_, four)) => four,
            Err(status) => return Ok(Err(status.to_string())),
        };
        if let Some(before) = previous {
            let moved = before
                .iter()
                .zip(&four)
                .map(|(a, b)| {
                    (a.centre_px[0] - b.centre_px[0]).hypot(a.centre_px[1] - b.centre_px[1])
                })
                .fold(0.0, f64::max);
            if moved < STEADY_PX {
                return Ok(Ok((frame.joints, four)));
            }
        }
        previous = Some(four);
    }
    Ok(Err(
        "the picture did not settle: 8 frames in a row moved by more than a third of a pixel"
            .into(),
    ))
}

/// Runs the step on `session`. Leaves the arm at the workspace's observation pose.
pub async fn run(
    session: &mut Session,
    config: &Config,
    workspace_id: Option<&str>,
) -> Result<CameraReport> {
    let model = config.robot.model();
    let workspaces = config.robot.workspaces();
    let spec = match workspace_id {
        Some(id) => workspaces.iter().find(|w| w.id == id).cloned(),
        None => workspaces.first().cloned(),
    };
    let Some(spec) = spec else {
        bail!(
            "no workspace {} is configured; the camera step needs the workspace sheet on the \
             table and its corners in [[robot.workspaces]]",
            workspace_id.unwrap_or("at all")
        );
    };
    let workspace = spec.to_info(model);
    let believed = config.robot.camera_mount()?;
    let kinematics = Kinematics::new(model).with_camera_mount(believed);
    let reported = session.intrinsics();
    let lens = lens(model, &reported);
    let detector = ColourDetector::new(LabelTable::builtin(), ColourDetectorSettings::default());
    let mut pipeline = Pipeline::new(&reported, vec![workspace.clone()], Box::new(detector))?;
    let observation = Pose::from_array(spec.observation_pose);
    let points = marker_points(&workspace);
    let pin = Pinhole {
        fx: reported.fx,
        fy: reported.fy,
        cx: reported.cx,
        cy: reported.cy,
    };
    let start = kinematics
        .inverse(&pose_to_isometry(&observation), None)
        .map_err(|e| anyhow::anyhow!("the observation pose of '{}': {e}", workspace.id))?;
    let plan = plan_views(
        &kinematics,
        &start,
        &points,
        0.0,
        &pin,
        (reported.width, reported.height),
    );
    let mut raw_views = Vec::new();
    let mut skipped = Vec::new();
    for (i, target) in plan.iter().enumerate() {
        if let Err(reason) = session.move_joints(target.clone()).await {
            if reason.contains("emergency stop") || reason.contains("not connected") {
                bail!("view {i}: {reason}");
            }
            skipped.push(format!("view {i} at joints {target:.3?}: {reason}"));
            continue;
        }
        let (joints, four) = match steady_markers(session, &mut pipeline, &workspace).await? {
            Ok(found) => found,
            Err(reason) => {
                skipped.push(format!("view {i}: {reason}"));
                continue;
            }
        };
        let Some(parent) = kinematics.camera_parent_pose(&joints) else {
            skipped.push(format!(
                "view {i}: the arm reports joints outside its limits"
            ));
            continue;
        };
        raw_views.push(RawView {
            parent,
            markers: points
                .iter()
                .zip(four.iter())
                .map(|(p, m)| (*p, m.centre_px))
                .collect(),
        });
    }
    // Back where perception expects the arm, whatever came out.
    let back = session.move_to(observation).await;
    if raw_views.len() < MIN_GOOD_VIEWS {
        bail!(
            "only {} of {} views showed the workspace sheet '{}' with its four markers (at \
             least {MIN_GOOD_VIEWS} are needed): is the sheet on the table where \
             [[robot.workspaces]] says, and in view at its observation pose? {}",
            raw_views.len(),
            plan.len(),
            workspace.id,
            skipped.join("; ")
        );
    }
    if let Err(reason) = back {
        bail!("returning to the observation pose: {reason}");
    }
    let lens_camera = robotd_vision::camera::Camera::new(&lens);
    let as_raw: Vec<View> = raw_views
        .iter()
        .map(|v| View {
            parent: v.parent,
            markers: v
                .markers
                .iter()
                .map(|(p, px)| (*p, lens_camera.ideal_of(*px)))
                .collect(),
        })
        .collect();
    let as_rectified: Vec<View> = raw_views
        .iter()
        .map(|v| View {
            parent: v.parent,
            markers: v.markers.clone(),
        })
        .collect();
    let has_lens = lens.distortion.iter().any(|k| *k != 0.0);
    let raw = handeye::solve(&pin, &as_raw, &believed.transform, 0.0, false);
    let rectified = if has_lens {
        Some(handeye::solve(
            &pin,
            &as_rectified,
            &believed.transform,
            0.0,
            false,
        ))
    } else {
        None
    };
    let worst = |s: &Result<handeye::Solution, _>| s.as_ref().ok().map(|s| s.residual_mm_max);
    let (chosen, images_rectified) = match &rectified {
        Some(Ok(r)) if worst(&raw).is_none_or(|w| r.residual_mm_max < w) => (r.clone(), Some(true)),
        Some(_) => (raw.clone()?, Some(false)),
        None => (raw.clone()?, None),
    };
    if chosen.residual_mm_max > MAX_RESIDUAL_MM {
        bail!(
            "the views disagree: after the best fit a marker is still {:.1} mm off (view {}), \
             more than the {MAX_RESIDUAL_MM} mm accepted; did the sheet move, or the arm not \
             stand where it reports? Nothing was measured.",
            chosen.residual_mm_max,
            chosen.worst_view
        );
    }
    let measured = CameraMount {
        transform: chosen.mount,
    };
    // The table's height, fitted with the mount free too: a check of robotd's table at z = 0.
    let views_chosen = if images_rectified == Some(true) {
        &as_rectified
    } else {
        &as_raw
    };
    let table_z_m = handeye::solve(&pin, views_chosen, &chosen.mount, 0.0, true)
        .map(|s| s.table_z_m)
        .unwrap_or(f64::NAN);
    let (change_m, change_deg) = believed.difference(&measured);
    Ok(CameraReport {
        workspace: workspace.id,
        views_planned: plan.len(),
        views_used: raw_views.len(),
        skipped,
        mount: measured.to_xyz_rpy_deg(),
        configured_mount: believed.to_xyz_rpy_deg(),
        mount_change_mm: change_m * 1000.0,
        mount_change_deg: change_deg,
        table_z_m,
        residual_mm_rms: chosen.residual_mm_rms,
        residual_mm_max: chosen.residual_mm_max,
        images_rectified: if model == RobotModel::Ned2 {
            images_rectified
        } else {
            None
        },
        residual_mm_max_as_raw: worst(&raw),
        residual_mm_max_as_rectified: rectified.as_ref().and_then(worst),
    })
}
