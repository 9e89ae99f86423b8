//! `robotd commission` on a robotd that is already running: it does not connect to the robot
//! (which answers one client) but works through that robotd — its motions on `arm/command`
//! at commissioning's own low speed cap (the origin's cap, lower than the running robotd's),
//! what the robot is from `system/hardware`. The running robotd here is the simulated Ned2
//! with its camera where the defaults say; commissioning is given a configuration whose
//! camera mount is 8 mm and 3° off, and must find the true one through the running robotd.
//! Also here, being cheap on the simulator: the refusals of an engaged e-stop (through the
//! running robotd) and of a fence that refuses every view (on its own).

#[path = "common/commissioning.rs"]
mod commissioning;
mod common;

use commissioning::{commission, error_of, step};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use robotd_kinematics::{CameraMount, RobotModel};
use std::process::Command;

/// `--set` arguments putting the camera mount at `mount`.
fn mount_settings(mount: &CameraMount) -> Vec<String> {
    let keys = ["x_m", "y_m", "z_m", "roll_deg", "pitch_deg", "yaw_deg"];
    keys.iter()
        .zip(mount.to_xyz_rpy_deg())
        .flat_map(|(key, value)| ["--set".into(), format!("robot.camera.mount.{key}={value}")])
        .collect()
}

#[test]
fn commissioning_works_through_the_running_robotd_at_its_own_speed_cap() {
    let namespace = common::fresh_namespace("commission-attached");
    let _robotd = common::start_robotd(&namespace, common::free_port(), &[]);

    // A configuration that names another driver is refused before anything moves.
    let (code, report, _) = commission(
        &[
            "--namespace",
            &namespace,
            "--set",
            "robot.driver=niryo",
            "--set",
            "robot.host=127.0.0.1",
        ],
        &["--only", "connect"],
    );
    assert_eq!(code, Some(1), "{report:#}");
    let reason = step(&report, "connect")["reason"].as_str().unwrap();
    assert!(
        reason.contains("drives 'sim-ned2'") && reason.contains("robot.driver = \"niryo\""),
        "{reason}"
    );

    // The whole camera step through the running robotd, with a configured mount that is off.
    let truth = CameraMount::default_for(RobotModel::Ned2);
    let believed = truth.offset_by(&Isometry3::from_parts(
        Translation3::new(0.008, 0.0, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 3f64.to_radians(), 0.0),
    ));
    let mut settings = vec!["--namespace".to_owned(), namespace.clone()];
    settings.extend(mount_settings(&believed));
    let settings: Vec<&str> = settings.iter().map(String::as_str).collect();
    // At commissioning's highest cap: the views take less time, and the speed does not change
    // what is measured.
    let (code, report, stderr) = commission(&settings, &["--only", "camera", "--speed", "0.5"]);
    assert_eq!(code, Some(0), "{report:#}\n{stderr}");
    assert_eq!(report["attached"], true, "{report:#}");
    let camera = step(&report, "camera");
    let (mm, degrees) = error_of(camera, &truth);
    eprintln!("attached: mount error {mm:.2} mm {degrees:.3}°");
    assert!(
        mm < 2.0 && degrees < 0.5,
        "{mm:.2} mm {degrees:.3}° off: {camera:#}"
    );

    // The stopping step at 10 cm/s: the running robotd's own cap is 1 m/s, so the speed the
    // swings ran at is the origin's cap at work. Its e-stops are released again.
    let (code, report, stderr) = commission(
        &["--namespace", &namespace],
        &["--only", "stopping", "--speed", "0.1"],
    );
    assert_eq!(code, Some(0), "{report:#}\n{stderr}");
    let stopping = &step(&report, "stopping")["measured"];
    let speed = stopping["mean_speed_m_s"].as_f64().unwrap();
    eprintln!("attached: swings at {speed:.4} m/s under a 0.1 m/s cap");
    assert!(speed > 0.02 && speed <= 0.1 * 1.05, "{stopping:#}");
}

#[test]
fn the_gripper_step_is_refused_on_a_running_widowx_robotd_before_anything_moves() {
    let namespace = common::fresh_namespace("commission-attached-widowx");
    let _robotd = common::start_robotd(
        &namespace,
        common::free_port(),
        &["--set", "robot.driver=sim-widowx"],
    );
    let (code, report, _) = commission(
        &[
            "--namespace",
            &namespace,
            "--set",
            "robot.driver=sim-widowx",
        ],
        &["--only", "gripper"],
    );
    assert_eq!(code, Some(1), "{report:#}");
    assert_eq!(report["attached"], true, "{report:#}");
    let gripper = step(&report, "gripper");
    assert_eq!(gripper["status"], "failed", "{report:#}");
    let reason = gripper["reason"].as_str().unwrap();
    assert!(
        reason.contains("stop robotd") && reason.contains("nothing moved"),
        "{reason}"
    );
}

#[test]
fn an_engaged_e_stop_and_a_fence_that_refuses_every_view_are_reported_and_nothing_moves() {
    let namespace = common::fresh_namespace("commission-refusals");
    let _robotd = common::start_robotd(&namespace, common::free_port(), &[]);
    let estop = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["--namespace", &namespace, "estop", "commissioning test"])
        .output()
        .unwrap();
    assert!(estop.status.success(), "{estop:?}");
    let (code, report, _) = commission(&["--namespace", &namespace], &["--only", "camera"]);
    assert_eq!(code, Some(1), "{report:#}");
    let connect = step(&report, "connect");
    let reason = connect["reason"].as_str().unwrap();
    assert!(reason.contains("emergency stop is engaged"), "{reason}");
    assert_eq!(report["steps"].as_array().unwrap().len(), 1, "{report:#}");

    // On its own (no robotd on this namespace), under a ceiling below the observation pose:
    // the policy refuses every view, and the step says so with the policy's reasons.
    let (code, report, _) = commission(
        &[
            "--namespace",
            &common::fresh_namespace("commission-fence"),
            "--set",
            "safety.ceiling_z_m=0.2",
        ],
        &["--only", "camera"],
    );
    assert_eq!(code, Some(1), "{report:#}");
    assert_eq!(report["attached"], false, "{report:#}");
    let reason = step(&report, "camera")["reason"].as_str().unwrap();
    eprintln!("{reason}");
    assert!(reason.contains("ceiling"), "{reason}");
}
