//! The gripper step of `robotd commission` on a Ned2: which tool the robot says is mounted,
//! and whether it opens and closes.
//!
//! The Ned2's TCP protocol reports no finger position and no grasp, so there is no range or
//! threshold to measure (the WidowX's are, in `gripper.rs`). What can go wrong on a real Ned2
//! is the tool itself: none mounted, another one than a gripper (a vacuum pump, an
//! electromagnet: robotd's pick and place skills drive a gripper), or a gripper that does not
//! answer. The robot names its tool (`GET_CURRENT_TOOL_ID`, after the `UPDATE_TOOL` the driver
//! sends on connecting); the step refuses anything but a gripper, then opens, closes on nothing
//! and opens again through `gripper/command` (origin `cli`, admitted by the motion policy),
//! and leaves the gripper open.

use super::session::Session;
use anyhow::{bail, Result};
use robotd_protocol::gripper::{GripperCommand, GripperReply};
use serde::Serialize;

/// What the step found.
#[derive(Debug, Clone, Serialize)]
pub struct Ned2Tool {
    /// The tool the robot names (`GRIPPER_1` … `GRIPPER_4`).
    pub tool: String,
    /// The commands the gripper carried out, in order.
    pub cycle: Vec<&'static str>,
    /// What the robot cannot tell.
    pub not_measured: &'static str,
}

/// Whether robotd can work with the tool named `tool`; `Err(why)` when not.
pub fn check_tool(tool: &str) -> Result<(), String> {
    match tool {
        "NONE" => Err(
            "the robot reports no tool mounted (NONE): mount the gripper; robotd \
                       asks the robot to detect its tool each time it connects"
                .into(),
        ),
        gripper if gripper.starts_with("GRIPPER_") => Ok(()),
        other => Err(format!(
            "the mounted tool is {other}, not a gripper: robotd's pick and place skills drive \
             a gripper; mount one"
        )),
    }
}

/// Runs the step on a Ned2.
pub async fn run(session: &Session) -> Result<Ned2Tool> {
    let info = session
        .hardware_info()
        .await
        .map_err(|e| anyhow::anyhow!("asking the robot for its tool: {e}"))?;
    let Some(tool) = info.tool else {
        bail!(
            "the robot did not say which tool is mounted ({}); nothing moved",
            info.not_reported.join("; ")
        );
    };
    if let Err(why) = check_tool(&tool) {
        bail!("{why}; nothing moved");
    }
    let mut cycle = Vec::new();
    for (command, what) in [
        (GripperCommand::Open, "opened"),
        (GripperCommand::Close, "closed on nothing"),
        (GripperCommand::Open, "opened again"),
    ] {
        match session.gripper(command).await? {
            GripperReply::State { .. } => cycle.push(what),
            GripperReply::Error { error } => bail!(
                "the {tool} did not carry out its commands: after {}, {error}",
                if cycle.is_empty() {
                    "nothing".to_owned()
                } else {
                    cycle.join(", ")
                }
            ),
        }
    }
    Ok(Ned2Tool {
        tool,
        cycle,
        not_measured: "finger positions and grasps: the Ned2's TCP protocol reports neither",
    })
}

#[cfg(test)]
mod tests {
    use super::check_tool;

    #[test]
    fn only_a_gripper_is_taken() {
        assert!(check_tool("GRIPPER_1").is_ok());
        assert!(check_tool("GRIPPER_4").is_ok());
        assert!(check_tool("NONE").unwrap_err().contains("no tool mounted"));
        assert!(check_tool("VACUUM_PUMP_1")
            .unwrap_err()
            .contains("not a gripper"));
    }
}
