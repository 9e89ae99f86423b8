//! `widowx`: with `robot.driver = "widowx"`, is the servo bus there and does every servo answer?
//!
//! The row opens `robot.widowx.device` as the driver does (so a missing adapter and a missing
//! permission get their own fix), pings the nine servos, checks each one's model and reads its
//! Hardware Error Status. It writes nothing and moves nothing. A robotd that is running on the
//! same bus loses a few of its replies meanwhile, which it tolerates.
//!
//! Without the widowx driver there is nothing to check (`ok`).

use super::Check;
use robotd_driver_widowx::control_table::{hardware_error_reasons, servo_name};
use robotd_driver_widowx::startup::survey;
use robotd_driver_widowx::DxlBus;
use std::path::PathBuf;

const NAME: &str = "widowx";

/// The serial device and baud rate of the servo bus (`None`: another driver is configured).
pub(super) fn check_widowx(bus: Option<(PathBuf, u32)>) -> Check {
    let Some((device, baud_rate)) = bus else {
        return Check::ok(
            NAME,
            "robot.driver is not \"widowx\"; no servo bus to check",
        );
    };
    let shown = device.display();
    let mut bus =
        match DxlBus::open_with_buffers(&device, baud_rate, vec![0; 1024], vec![0; 1024]) {
            Ok(bus) => bus,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Check::problem(
                NAME,
                format!("{shown} does not exist"),
                "plug in the U2D2 adapter and power the arm; install the udev rule of the README \
                 (\"Running a real WidowX\") so it appears as /dev/ttyDXL, or set \
                 robot.widowx.device to its /dev/ttyUSB* name",
            ),
            Err(e) if e.kind() == std::io::ErrorKind::PermissionDenied => return Check::problem(
                NAME,
                format!("no permission to open {shown}"),
                "add your user to the dialout group (sudo usermod -aG dialout $USER) and log in \
                 again, or give the udev rule MODE=\"0666\"",
            ),
            Err(e) => {
                return Check::problem(
                    NAME,
                    format!("cannot open {shown}: {e}"),
                    "check that no other program (another robotd, the Interbotix ROS driver, the \
                 Dynamixel Wizard) holds the port",
                )
            }
        };
    // dynamixel2 0.9 panics on a status packet whose length field is below 4 (a corrupt
    // reply): report it as a bus problem instead of ending the doctor.
    let surveyed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| survey(&mut bus)));
    let Ok(servos) = surveyed else {
        return Check::problem(
            NAME,
            format!("a servo on {shown} sent a malformed status packet"),
            "check the cabling and that every servo runs DYNAMIXEL Protocol 2.0 at the configured \
             baud rate; power-cycle the arm",
        );
    };
    let missing: Vec<String> = servos
        .iter()
        .filter_map(|s| s.model.as_ref().err().map(|e| e.to_string()))
        .collect();
    if !missing.is_empty() {
        return Check::problem(
            NAME,
            missing.join("; "),
            "power the arm (12 V), check the cable chain from the U2D2 to that servo, and that \
             robot.widowx.baud_rate matches the servos (1000000 on a WidowX)",
        );
    }
    let faulted: Vec<String> = servos
        .iter()
        .filter(|s| s.hardware_error.unwrap_or(0) != 0)
        .map(|s| {
            format!(
                "servo {} ({}): {}",
                s.id,
                servo_name(s.id),
                hardware_error_reasons(s.hardware_error.unwrap_or(0)).join(", ")
            )
        })
        .collect();
    if !faulted.is_empty() {
        return Check::warn(
            NAME,
            format!("hardware errors latched: {}", faulted.join("; ")),
            "robotd reboots a faulted servo when it starts; if the error comes back, let the \
             servo cool down, check the load and the supply voltage",
        );
    }
    Check::ok(
        NAME,
        format!("9 servos answer on {shown} at {baud_rate} baud"),
    )
}
