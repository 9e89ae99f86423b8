//! `commissioning`: with a real robot (`niryo` or `widowx` driver), was it commissioned, and
//! is that still this robot?
//!
//! `robotd commission --write FILE` writes the measured camera mount with `measured_for`, a
//! fingerprint of the robot it was measured on (model, driver, address or servo device, camera
//! source: [`robotd_driver::RobotConfig::commissioning_fingerprint`]). This row compares it
//! with the configuration in use. Nothing is measured here and nothing moves.
//!
//! - no `[robot.camera.mount]`: a warning — the mount is the model's nominal guess;
//! - a mount without `measured_for`: ok, set by hand;
//! - a fingerprint that differs: a warning — the robot, its address or its camera changed since
//!   the mount was measured (stale);
//! - the same fingerprint: ok.
//!
//! Simulated and replayed robots have nothing to commission (`ok`).

use super::Check;
use robotd_driver::{RobotConfig, RobotDriver};

const NAME: &str = "commissioning";

/// The row for `[robot]`.
pub(super) fn check_commissioning(robot: &RobotConfig) -> Check {
    if !matches!(robot.driver, RobotDriver::Niryo | RobotDriver::Widowx) {
        return Check::ok(NAME, "not a real robot; nothing to commission");
    }
    let fix = "run `robotd commission --write commissioned.toml` with this config and use the \
               file (docs/commissioning.md)";
    let Some(mount) = &robot.camera.mount else {
        return Check::warn(
            NAME,
            "not commissioned: the camera mount is the model's nominal guess, never measured on \
             this robot",
            fix,
        );
    };
    let now = robot.commissioning_fingerprint();
    match &mount.measured_for {
        None => Check::ok(
            NAME,
            "[robot.camera.mount] is set by hand (not measured by robotd commission)",
        ),
        Some(measured) if *measured == now => Check::ok(
            NAME,
            format!("commissioned: the camera mount was measured on this robot ({now})"),
        ),
        Some(measured) => Check::warn(
            NAME,
            format!(
                "stale: the camera mount was measured on another robot or connection ({measured}; \
                 now {now}): the model, driver, address, servo device or camera changed since"
            ),
            fix,
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::super::Status;
    use super::*;

    fn niryo() -> RobotConfig {
        toml::from_str("driver = \"niryo\"\nhost = \"10.0.0.5\"").unwrap()
    }

    #[test]
    fn missing_current_and_stale_commissioning() {
        let sim: RobotConfig = toml::from_str("driver = \"sim-ned2\"").unwrap();
        assert_eq!(check_commissioning(&sim).status, Status::Ok);

        let mut robot = niryo();
        let missing = check_commissioning(&robot);
        assert_eq!(missing.status, Status::Warn);
        assert!(
            missing.found.contains("not commissioned"),
            "{}",
            missing.found
        );

        let mut mount = robotd_driver::config::CameraMountConfig::from_array([
            0.0385, 0.0, 0.0, 100.0, -90.0, 0.0,
        ]);
        mount.measured_for = Some(robot.commissioning_fingerprint());
        robot.camera.mount = Some(mount);
        assert_eq!(check_commissioning(&robot).status, Status::Ok);

        robot.host = Some("10.0.0.6".into());
        let stale = check_commissioning(&robot);
        assert_eq!(stale.status, Status::Warn);
        assert!(stale.found.contains("stale"), "{}", stale.found);
    }
}
