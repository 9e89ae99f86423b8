//! The Ned2's gripper over TCP: `OPEN_GRIPPER` / `CLOSE_GRIPPER` with the configured speed and
//! torques (integers, as the robot requires).
//!
//! The Ned2's TCP protocol reports no finger position and no load, so this driver cannot
//! sense a grasp: after a close it reports `holding = true` with the fingers' width unknown
//! (0), and after an open `holding = false` at the full width. A missed grasp is therefore
//! noticed by the camera (the object is still seen where it was), not by the gripper — the
//! README says so under "Running a real Ned2".

use crate::arm::link_error;
use crate::link::Link;
use crate::wire::Param;
use robotd_driver::{
    Close, DriverError, DriverFuture, GripperDriver, GripperStatus, NiryoConfig, Open, Permit,
    SetWidth,
};
use std::sync::{Arc, Mutex};

/// Widest opening of the Ned2's standard gripper, metres.
pub const MAX_WIDTH_M: f64 = 0.040;

/// The Ned2's gripper.
#[derive(Debug)]
pub struct NiryoGripper {
    link: Arc<Link>,
    params: [i64; 3],
    last: Mutex<GripperStatus>,
}

impl NiryoGripper {
    /// The gripper driver on `link` with the speed and torques of `settings`.
    pub fn new(link: Arc<Link>, settings: &NiryoConfig) -> Self {
        Self {
            link,
            params: [
                settings.gripper_speed.into(),
                settings.gripper_max_torque_percent.into(),
                settings.gripper_hold_torque_percent.into(),
            ],
            last: Mutex::new(GripperStatus {
                holding: false,
                width_m: MAX_WIDTH_M,
            }),
        }
    }

    async fn command(
        &self,
        name: &str,
        after: GripperStatus,
    ) -> Result<GripperStatus, DriverError> {
        let params: Vec<Param> = self.params.iter().map(|p| Param::Int(*p)).collect();
        // A full stroke takes about a second; three seconds more for a slow robot.
        let deadline = self.link.settings().query_timeout + std::time::Duration::from_secs(3);
        self.link
            .call(name, &params, deadline)
            .await
            .map_err(link_error)?;
        *self.last.lock().unwrap_or_else(|p| p.into_inner()) = after;
        Ok(after)
    }
}

impl GripperDriver for NiryoGripper {
    fn max_width_m(&self) -> f64 {
        MAX_WIDTH_M
    }

    fn open(&self, _permit: Permit<Open>) -> DriverFuture<'_, GripperStatus> {
        Box::pin(self.command(
            "OPEN_GRIPPER",
            GripperStatus {
                holding: false,
                width_m: MAX_WIDTH_M,
            },
        ))
    }

    fn close(&self, _permit: Permit<Close>) -> DriverFuture<'_, GripperStatus> {
        Box::pin(self.command(
            "CLOSE_GRIPPER",
            GripperStatus {
                holding: true,
                width_m: 0.0,
            },
        ))
    }

    fn set_width(&self, permit: Permit<SetWidth>) -> DriverFuture<'_, GripperStatus> {
        let width_m = permit.act().width_m;
        Box::pin(async move {
            Err(DriverError::Hardware(format!(
                "the Ned2's gripper only opens fully or closes (asked for {:.1} mm); use open or close",
                width_m * 1000.0
            )))
        })
    }

    fn status(&self) -> Result<GripperStatus, DriverError> {
        self.link
            .status()
            .map_err(|reason| DriverError::Hardware(format!("robot not connected: {reason}")))?;
        Ok(*self.last.lock().unwrap_or_else(|p| p.into_inner()))
    }
}
