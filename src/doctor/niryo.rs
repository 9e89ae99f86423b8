//! `niryo`: with `robot.driver = "niryo"`, can this machine reach the Ned2 and is it ready?
//!
//! The row asks the robot exactly what the driver asks first on every connection
//! ([`robotd_driver_niryo::link::greet`]): a TCP connect to `robot.host:robot.port`, the
//! handshake and `GET_HARDWARE_STATUS`. It sends nothing that moves the robot. Each way of
//! failing gets its own fix: no connection (robot off, wrong address, network), no answer to
//! the handshake (the robot is serving another client: it serves one at a time), an unreadable
//! status; a robot that needs calibration, reports motor errors or an error message is a
//! warning or a problem with what to do.
//!
//! Without the niryo driver there is nothing to check (`ok`).

use super::Check;
use robotd_driver_niryo::link::{greet, GreetError, LinkSettings};
use std::time::Duration;

const NAME: &str = "niryo";

/// The Ned2 of `settings` (`None`: another driver is configured).
pub(super) fn check_niryo(settings: Option<LinkSettings>) -> Check {
    let Some(mut settings) = settings else {
        return Check::ok(NAME, "robot.driver is not \"niryo\"; no Ned2 to check");
    };
    // The doctor is quick: at most 2 s per step, whatever the configuration says.
    settings.connect_timeout = settings.connect_timeout.min(Duration::from_secs(2));
    settings.query_timeout = settings.query_timeout.min(Duration::from_secs(2));
    let robot = format!("{}:{}", settings.host, settings.port);
    let runtime = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(runtime) => runtime,
        Err(e) => return Check::problem(NAME, format!("cannot start a runtime: {e}"), "retry"),
    };
    let greeted = runtime.block_on(async {
        let (stream, hardware) = greet(&settings).await?;
        drop(stream);
        Ok::<_, GreetError>(hardware)
    });
    let hardware =
        match greeted {
            Ok(hardware) => hardware,
            Err(GreetError::Connect(reason)) => {
                return Check::problem(
                    NAME,
                    reason,
                    format!(
                    "switch the robot on and wait for its LED to turn green or blue; check that \
                     this machine reaches it (ping {}); set robot.host / robot.port (the Ned2's \
                     own Wi-Fi hotspot is 10.10.10.10, port 40001)",
                    settings.host
                ),
                )
            }
            Err(GreetError::Handshake(reason)) => return Check::problem(
                NAME,
                reason,
                "close Niryo Studio and any pyniryo script, or stop the robotd that is connected \
                 (its /health says robot.connected); then run the doctor again",
            ),
            Err(GreetError::Status(reason)) => {
                return Check::problem(
                    NAME,
                    format!("{robot} answered the handshake but not its hardware status: {reason}"),
                    "update the robot's software (Niryo Studio) or restart the robot",
                )
            }
        };
    let summary = format!(
        "{} at {robot}: Raspberry Pi {:.0} °C",
        if hardware.hardware_version.is_empty() {
            "robot"
        } else {
            hardware.hardware_version.as_str()
        },
        hardware.rpi_temperature_c
    );
    if !hardware.motor_errors.is_empty() {
        let motors: Vec<String> = hardware
            .motor_errors
            .iter()
            .map(|(name, code)| format!("{name} (error {code})"))
            .collect();
        return Check::problem(
            NAME,
            format!("{summary}; motor hardware errors: {}", motors.join(", ")),
            "look at the motors named (cables, overheating, overload) and reboot the robot",
        );
    }
    if !hardware.error_message.is_empty() {
        return Check::warn(
            NAME,
            format!("{summary}; the robot reports: {}", hardware.error_message),
            "read the message in Niryo Studio; restart the robot if it persists",
        );
    }
    if hardware.calibration_needed {
        return Check::warn(
            NAME,
            format!("{summary}; needs calibration"),
            "robotd calibrates it on connecting (robot.niryo.auto_calibrate = true, the \
             default); with auto_calibrate = false call the calibrate tool first",
        );
    }
    Check::ok(NAME, format!("{summary}; calibrated"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_fake_niryo::{FakeFaults, FakeNiryo};
    use std::time::Instant;

    /// A fake Ned2 on a loopback port, served by its own thread's runtime.
    fn fake(faults: FakeFaults) -> (std::sync::Arc<FakeNiryo>, u16) {
        let mut robot = robotd_config::Config::default().robot;
        robot.time_scale = 0.05;
        let sim = robotd_driver_sim::open(&robot).unwrap();
        let fake = FakeNiryo::new(sim.robot, faults);
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        listener.set_nonblocking(true).unwrap();
        let serving = fake.clone();
        std::thread::spawn(move || {
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap();
            runtime.block_on(async move {
                let listener = tokio::net::TcpListener::from_std(listener).unwrap();
                serving.serve(listener).await;
            });
        });
        (fake, port)
    }

    fn settings(port: u16) -> LinkSettings {
        let mut robot = robotd_config::Config::default().robot;
        robot.host = Some("127.0.0.1".into());
        robot.port = port;
        robotd_driver_niryo::link_settings(&robot)
    }

    #[test]
    fn other_drivers_have_nothing_to_check() {
        assert_eq!(check_niryo(None).status, super::super::Status::Ok);
    }

    #[test]
    fn a_ready_robot_is_ok_and_one_needing_calibration_a_warning() {
        let (_fake, port) = fake(FakeFaults::default());
        let row = check_niryo(Some(settings(port)));
        assert_eq!(row.status, super::super::Status::Ok, "{row:?}");
        assert!(row.found.starts_with("ned2 at 127.0.0.1:"), "{row:?}");

        let (_fake, port) = fake(FakeFaults {
            needs_calibration: true,
            ..Default::default()
        });
        let row = check_niryo(Some(settings(port)));
        assert_eq!(row.status, super::super::Status::Warn, "{row:?}");
        assert!(row.found.ends_with("needs calibration"), "{row:?}");
        assert!(row.fix.unwrap().contains("auto_calibrate"));
    }

    #[test]
    fn no_robot_and_a_busy_robot_are_problems_with_their_own_fix() {
        let closed = {
            let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
            probe.local_addr().unwrap().port()
        };
        let started = Instant::now();
        let row = check_niryo(Some(settings(closed)));
        assert!(started.elapsed() < Duration::from_secs(3));
        assert_eq!(row.status, super::super::Status::Problem, "{row:?}");
        assert!(row.found.contains("cannot connect"), "{row:?}");
        assert!(row.fix.unwrap().contains("ping 127.0.0.1"));

        // A robot that never answers the handshake (as when it serves another client).
        let (_fake, port) = fake(FakeFaults {
            silent_at: Some(1),
            ..Default::default()
        });
        let row = check_niryo(Some(settings(port)));
        assert_eq!(row.status, super::super::Status::Problem, "{row:?}");
        assert!(
            row.found.contains("did not answer the handshake"),
            "{row:?}"
        );
        assert!(row.fix.unwrap().contains("Niryo Studio"));
    }
}
