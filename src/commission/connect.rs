//! The connect step of `robotd commission`: the driver reaches the robot and the robot tells
//! where its joints are, whether it is calibrated and whether the e-stop is engaged, and what it
//! reports of its versions: a Ned2 its hardware version and motor types (`GET_HARDWARE_STATUS`;
//! its TCP protocol reports no software or firmware version), a WidowX each servo's model number
//! and firmware version (control table addresses 0 and 6). A driver that reports none (the
//! simulator) leaves `versions` empty and says why in `versions_not_reported`.
//!
//! Nothing moves here. The niryo driver calibrates a robot that needs it on connecting when
//! `robot.niryo.auto_calibrate` is true (a motion the policy admits like any other); with
//! `false`, a robot that needs calibration is reported and the moving steps are refused.
//! An engaged e-stop refuses the moving steps too: release it (`robotd estop --release`)
//! once the arm's surroundings are clear.

use super::session::Session;
use anyhow::{bail, Result};
use robotd_config::Config;
use serde::Serialize;
use std::time::Duration;

/// How long the robot has to answer a joints query before it counts as not connected.
const ANSWER_WAIT: Duration = Duration::from_secs(10);

/// How long the arm has to publish its state: a Ned2 that calibrates on connecting takes
/// ~30 s.
pub(super) const CONNECT_WAIT: Duration = Duration::from_secs(60);

/// What the connect step found.
#[derive(Debug, Clone, Serialize)]
pub struct Connected {
    /// The robot's joints, radians, base to wrist.
    pub joints_rad: Vec<f64>,
    /// Whether the robot is calibrated.
    pub calibrated: bool,
    /// The camera's image size, pixels.
    pub image_size: [u32; 2],
    /// The camera's lens distortion as the driver reports it (all zero: rectified images).
    pub distortion: [f64; 5],
    /// What the robot reports of its versions; `None` when the driver reports none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub versions: Option<Versions>,
    /// What the robot does not report of its versions, and why.
    pub versions_not_reported: Vec<String>,
}

/// The robot's versions as its driver reads them.
#[derive(Debug, Clone, Serialize)]
pub struct Versions {
    /// The robot's hardware version (a Ned2: `ned2`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hardware: Option<String>,
    /// The robot's software version.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub software: Option<String>,
    /// Each motor, base to tool.
    pub motors: Vec<Motor>,
    /// The tool the robot reports mounted (a Ned2: `GRIPPER_1`, `NONE`, …).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tool: Option<String>,
}

/// One motor's model and firmware.
#[derive(Debug, Clone, Serialize)]
pub struct Motor {
    /// What it moves.
    pub name: String,
    /// Its model or type.
    pub model: String,
    /// Its firmware version.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub firmware: Option<String>,
}

/// Runs the step: an error when the robot is not connected, not calibrated or e-stopped.
pub async fn run(session: &mut Session, config: &Config) -> Result<Connected> {
    // A robot that is not there says so at once; one still connecting gets a few seconds.
    let asked = std::time::Instant::now();
    loop {
        match session
            .command(robotd_protocol::arm::ArmCommand::GetJoints)
            .await
        {
            Ok(_) => break,
            Err(reason) if asked.elapsed() < ANSWER_WAIT => {
                tracing::debug!(%reason, "the robot does not answer yet");
                tokio::time::sleep(Duration::from_millis(500)).await;
            }
            Err(reason) => bail!(
                "the robot does not answer ({:?} driver, after {ANSWER_WAIT:?}): {reason}",
                config.robot.driver
            ),
        }
    }
    let state = session.state(CONNECT_WAIT).await?;
    if state.estop_engaged {
        bail!(
            "the emergency stop is engaged: nothing may move. Clear the arm's surroundings, \
             release it (`robotd estop --release`) and run robotd commission again"
        );
    }
    if !state.calibrated {
        bail!(
            "the robot is not calibrated: run robotd commission --calibrate (or calibrate it \
             another way: robot.niryo.auto_calibrate = true does it on connecting)"
        );
    }
    let intrinsics = session.intrinsics();
    let (versions, versions_not_reported) = match session.hardware_info().await {
        Ok(info) => (
            Some(Versions {
                hardware: info.hardware_version,
                software: info.software_version,
                motors: info
                    .motors
                    .into_iter()
                    .map(|m| Motor {
                        name: m.name,
                        model: m.model,
                        firmware: m.firmware,
                    })
                    .collect(),
                tool: info.tool,
            }),
            info.not_reported,
        ),
        Err(reason) => (None, vec![reason.to_string()]),
    };
    Ok(Connected {
        joints_rad: state.joints.positions_rad,
        calibrated: state.calibrated,
        image_size: [intrinsics.width, intrinsics.height],
        distortion: intrinsics.distortion,
        versions,
        versions_not_reported,
    })
}
