//! The report of `robotd commission` for people, and the config file of measured values it
//! writes with `--write FILE`.
//!
//! The file holds only what was measured — `[robot.camera.mount]` (with `measured_for`, the
//! fingerprint of the robot it was measured on, which `robotd doctor` compares), and for a
//! Ned2 `[robot.niryo] images_rectified`, for a WidowX `[robot.widowx]` gripper ticks and
//! `gripper_holding_load` — with a comment saying how well. Use it as the
//! config (`--config FILE`) or copy its tables into yours; commissioning never edits a file
//! that exists.

use super::camera::CameraReport;
use super::gripper::GripperReport;
use super::Report;
use anyhow::{Context, Result};
use robotd_config::Config;
use std::fmt::Write as _;
use std::path::Path;

/// The report as lines for a terminal.
pub fn render(report: &Report) -> String {
    let mut out = format!("robotd commission: {} ({})", report.robot, report.driver);
    if report.attached {
        out.push_str(", through the robotd already running");
    }
    out.push('\n');
    for step in &report.steps {
        let mark = match step.status.as_str() {
            "ok" => "✓",
            "failed" => "❌",
            _ => "·",
        };
        let _ = write!(out, "{mark} {:<9} {}", step.step, step.status);
        if let Some(reason) = &step.reason {
            let _ = write!(out, ": {reason}");
        }
        out.push('\n');
        if let Some(measured) = &step.measured {
            if let Some(map) = measured.as_object() {
                for (key, value) in map {
                    let _ = writeln!(out, "    {key}: {value}");
                }
            }
        }
    }
    if let Some(path) = &report.written {
        let _ = writeln!(out, "measured values written to {}", path.display());
    }
    out
}

/// Writes the measured values to `path`, a new file.
pub fn write_config(
    path: &Path,
    config: &Config,
    camera: Option<&CameraReport>,
    gripper: Option<&GripperReport>,
) -> Result<()> {
    let mut text = String::from(
        "# Measured by `robotd commission`. Use this file as the config (--config), or copy its\n\
         # tables into yours.\n",
    );
    match camera {
        Some(camera) => {
            let [x, y, z, roll, pitch, yaw] = camera.mount;
            let _ = write!(
                text,
                "\n# Hand-eye calibration on the sheet '{}': {} views, markers within {:.2} mm \
                 (rms {:.2} mm); table at z = {:.4} m.\n[robot.camera.mount]\nx_m = {x:.5}\n\
                 y_m = {y:.5}\nz_m = {z:.5}\nroll_deg = {roll:.3}\npitch_deg = {pitch:.3}\n\
                 yaw_deg = {yaw:.3}\nmeasured_for = \"{}\"\n",
                camera.workspace,
                camera.views_used,
                camera.residual_mm_max,
                camera.residual_mm_rms,
                camera.table_z_m,
                config.robot.commissioning_fingerprint(),
            );
            if let Some(rectified) = camera.images_rectified {
                let _ = write!(
                    text,
                    "\n# The robot's images are {}rectified (worst marker {:.2} mm read as raw, \
                     {:.2} mm read as rectified).\n[robot.niryo]\nimages_rectified = {rectified}\n",
                    if rectified { "" } else { "not " },
                    camera.residual_mm_max_as_raw.unwrap_or(f64::NAN),
                    camera.residual_mm_max_as_rectified.unwrap_or(f64::NAN),
                );
            }
        }
        None => text.push_str("\n# The camera step did not run or failed: nothing measured.\n"),
    }
    if let Some(gripper) = gripper {
        let _ = write!(
            text,
            "\n# The gripper's mechanical stops (configured: {} closed, {} open), and the load \
             that counts as holding: half the stall load at the closed stop ({} at PWM {}), \
             scaled to gripper_pwm (configured: {}).\n[robot.widowx]\n\
             gripper_closed_ticks = {}\ngripper_open_ticks = {}\ngripper_holding_load = {}\n",
            gripper.configured_closed_ticks,
            gripper.configured_open_ticks,
            gripper.empty_close_load,
            gripper.empty_close_pwm,
            gripper.configured_holding_load,
            gripper.closed_ticks,
            gripper.open_ticks,
            gripper.holding_load,
        );
    }
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .with_context(|| format!("creating {} (it must not exist)", path.display()))?;
    std::io::Write::write_all(&mut file, text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))
}
