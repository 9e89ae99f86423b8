//! `robotd commission` against the fakes made wrong on purpose: the fake robot's camera sits
//! 8 mm and 3° away from where robotd's config says, and (Ned2) its images come rectified.
//! Commissioning must find the true mount within 2 mm and 0.5°, say that the images are
//! rectified, and write both to a new config file; with that file, commissioning again finds
//! the mount where the file says. The whole run on the WidowX (whose fake gripper stops 100
//! ticks from the configured ones) also finds the gripper's stops within 20 ticks, reports the
//! stopping time and distance after an e-stop at the capped speed, and picks the cube near
//! the sheet's centre and puts it back within 3 mm as the camera sees it (the Ned2 too, with
//! the written config).

#[path = "common/commissioning.rs"]
mod commissioning;
mod common;

use commissioning::{commission, error_of, ned2_settings, run, step, strs};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use robotd_kinematics::{CameraMount, RobotModel};
use serde_json::Value;

/// The fakes' offset: 8 mm along the image's x, 3° about its y axis.
const OFFSET: &str = "8,0,0,0,3,0";

fn true_mount(model: RobotModel) -> CameraMount {
    CameraMount::default_for(model).offset_by(&Isometry3::from_parts(
        Translation3::new(0.008, 0.0, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 3f64.to_radians(), 0.0),
    ))
}

/// Writes `scene` into `dir` with its red cube's position `from` replaced by `to`; returns the
/// `robot.scene=…` setting that loads it.
fn scene_with_cube_moved(dir: &std::path::Path, scene: &str, from: &str, to: &str) -> String {
    assert!(
        scene.contains(from),
        "the scene no longer has its cube at {from:?}"
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, scene.replace(from, to)).unwrap();
    format!("robot.scene={}", path.display())
}

#[test]
fn commissioning_a_ned2_finds_its_camera_mount_and_rectified_images() {
    let namespace = common::fresh_namespace("commission-ned2");
    let dir = tempfile::tempdir().unwrap();
    // The default scene with its red cube at the sheet's centre, for the supervised pick.
    let scene = scene_with_cube_moved(
        dir.path(),
        include_str!("../config/scenes/default.toml"),
        "x_m = 0.28\ny_m = 0.04",
        "x_m = 0.25\ny_m = 0.0",
    );
    let (_fake, port) = common::start_fake_niryo(
        &[
            "--namespace",
            &format!("{namespace}-fake"),
            "--set",
            "robot.time_scale=0.2",
            "--set",
            &scene,
        ],
        &["--mount-offset", OFFSET, "--rectified"],
    );
    let written = dir.path().join("commissioned.toml");
    let port = format!("robot.port={port}");
    let robot = [
        "--namespace",
        namespace.as_str(),
        "--config",
        concat!(env!("CARGO_MANIFEST_DIR"), "/config/niryo.toml"),
        "--set",
        "robot.host=127.0.0.1",
        "--set",
        port.as_str(),
        "--set",
        "robot.time_scale=0.2",
    ];
    // The camera steps at commissioning's highest cap: the speed does not change what is
    // measured, and the views come sooner.
    let (code, report, _) = commission(
        &robot,
        &[
            "--only",
            "camera",
            "--speed",
            "0.5",
            "--write",
            written.to_str().unwrap(),
        ],
    );
    let camera = step(&report, "camera");
    assert_eq!(camera["status"], "ok", "{report:#}");
    assert_eq!(code, Some(0), "{report:#}");
    let (mm, deg) = error_of(camera, &true_mount(RobotModel::Ned2));
    eprintln!("Ned2 mount error {mm:.2} mm {deg:.3}°: {camera:#}");
    assert!(
        mm < 2.0 && deg < 0.5,
        "{mm:.2} mm {deg:.3}° off: {camera:#}"
    );
    let measured = &camera["measured"];
    assert!(
        measured["mount_change_mm"].as_f64().unwrap() > 6.0,
        "{camera:#}"
    );
    assert_eq!(measured["images_rectified"], true, "{camera:#}");
    let file = std::fs::read_to_string(&written).unwrap();
    assert!(file.contains("[robot.camera.mount]"), "{file}");
    assert!(file.contains("images_rectified = true"), "{file}");
    // It is the config file commissioning ran with, comments and settings kept, plus the
    // measured values: robotd runs from it alone.
    let niryo = include_str!("../config/niryo.toml");
    for kept in niryo
        .lines()
        .filter(|l| l.starts_with("segment_rad") || l.starts_with("# "))
    {
        assert!(file.contains(kept), "{kept:?} lost:\n{file}");
    }

    // Never over an existing file: refused before anything moves.
    let again = run(&robot, &["--write", written.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&again.stderr);
    assert_eq!(again.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("never overwrites"), "{stderr}");
    assert_eq!(std::fs::read_to_string(&written).unwrap(), file);

    // With the written values, the camera is where the config says.
    let with_written = [
        "--namespace",
        namespace.as_str(),
        "--config",
        written.to_str().unwrap(),
        "--set",
        "robot.host=127.0.0.1",
        "--set",
        port.as_str(),
        "--set",
        "robot.time_scale=0.2",
    ];
    let (code, report, _) = commission(&with_written, &["--only", "camera", "--speed", "0.5"]);
    let camera = step(&report, "camera");
    assert_eq!(code, Some(0), "{report:#}");
    let measured = &camera["measured"];
    assert!(
        measured["mount_change_mm"].as_f64().unwrap() < 1.0,
        "{camera:#}"
    );
    assert!(
        measured["mount_change_deg"].as_f64().unwrap() < 0.3,
        "{camera:#}"
    );
    assert_eq!(measured["images_rectified"], true, "{camera:#}");

    // The supervised pick with the written values: the cube at the centre is picked, put
    // back, and seen where it was.
    let (code, report, _) = commission(&with_written, &["--only", "pick"]);
    assert_eq!(code, Some(0), "{report:#}");
    let pick = &step(&report, "pick")["measured"];
    eprintln!("Ned2 supervised pick with the written config: {pick}");
    assert_eq!(pick["label"], "red cube", "{report:#}");
    assert_eq!(pick["held"], true, "{report:#}");
    assert!(pick["error_mm"].as_f64().unwrap() < 3.0, "{report:#}");
}

#[test]
fn an_unknown_step_is_refused_and_nothing_starts() {
    let output = run(
        &["--namespace", &common::fresh_namespace("commission-no")],
        &["--only", "grip"],
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("no such step"), "{stderr}");
}

#[test]
fn commissioning_a_widowx_measures_mount_gripper_stopping_and_a_pick() {
    let namespace = common::fresh_namespace("commission-widowx");
    let dir = tempfile::tempdir().unwrap();
    let device = dir.path().join("ttyDXL");
    let config = concat!(env!("CARGO_MANIFEST_DIR"), "/config/widowx.toml");
    // The WidowX scene with its red cube near the sheet's centre, for the supervised pick.
    let scene = scene_with_cube_moved(
        dir.path(),
        include_str!("../config/scenes/widowx.toml"),
        "x_m = 0.30\ny_m = 0.05",
        "x_m = 0.255\ny_m = 0.025",
    );
    let (_fake, camera_url) = common::start_fake_widowx(
        &[
            "--namespace",
            &format!("{namespace}-fake"),
            "--config",
            config,
            "--set",
            "robot.time_scale=0.2",
            "--set",
            &scene,
        ],
        &device,
        &["--mount-offset", OFFSET, "--gripper-ticks", "1700,2700"],
    );
    let device = format!("robot.widowx.device={}", device.display());
    let camera_url = format!("robot.widowx.camera_url={camera_url}");
    let written = dir.path().join("commissioned.toml");
    let (code, report, _) = commission(
        &[
            "--namespace",
            namespace.as_str(),
            "--config",
            config,
            "--set",
            device.as_str(),
            "--set",
            camera_url.as_str(),
            "--set",
            "robot.time_scale=0.2",
        ],
        &["--write", written.to_str().unwrap()],
    );
    let camera = step(&report, "camera");
    assert_eq!(code, Some(0), "{report:#}");
    let stopping = &step(&report, "stopping")["measured"];
    let distance = stopping["distance_mm_max"].as_f64().unwrap();
    assert!((0.0..30.0).contains(&distance), "{report:#}");
    assert!(
        stopping["time_ms_max"].as_f64().unwrap() < 1000.0,
        "{report:#}"
    );
    assert!(
        stopping["mean_speed_m_s"].as_f64().unwrap() <= 0.12,
        "{report:#}"
    );
    // The fake's gripper stops 100 ticks above the configured 1600..2600.
    let gripper = &step(&report, "gripper")["measured"];
    eprintln!("WidowX gripper: {gripper}");
    let ticks = |key: &str| gripper[key].as_i64().unwrap();
    assert!((ticks("closed_ticks") - 1700).abs() <= 20, "{report:#}");
    assert!((ticks("open_ticks") - 2700).abs() <= 20, "{report:#}");
    // The fake's stalled gripper reports a load of PWM × 1000 / 885: 282 at the commissioning
    // PWM 250, so 395 at the configured 350, and half of it counts as holding.
    assert_eq!(ticks("empty_close_pwm"), 250, "{report:#}");
    assert!((ticks("empty_close_load") - 282).abs() <= 2, "{report:#}");
    assert!((ticks("holding_load") - 197).abs() <= 2, "{report:#}");
    let file = std::fs::read_to_string(&written).unwrap();
    let table: toml::Value = toml::from_str(&file).unwrap();
    let written_load = table["robot"]["widowx"]["gripper_holding_load"].as_integer();
    assert_eq!(written_load, Some(ticks("holding_load")), "{file}");
    let pick = &step(&report, "pick")["measured"];
    eprintln!("WidowX supervised pick: {pick}");
    assert_eq!(pick["held"], true, "{report:#}");
    assert!(pick["error_mm"].as_f64().unwrap() < 3.0, "{report:#}");
    let (mm, deg) = error_of(camera, &true_mount(RobotModel::WidowX250));
    eprintln!("WidowX mount error {mm:.2} mm {deg:.3}°: {camera:#}");
    assert!(
        mm < 2.0 && deg < 0.5,
        "{mm:.2} mm {deg:.3}° off: {camera:#}"
    );
    assert_eq!(
        camera["measured"]["images_rectified"],
        Value::Null,
        "{camera:#}"
    );
}

#[test]
fn a_robot_that_is_not_there_is_reported_within_seconds() {
    // A port nobody listens on.
    let port = format!("robot.port={}", common::free_port());
    let started = std::time::Instant::now();
    let (code, report, _) = commission(
        &[
            "--namespace",
            &common::fresh_namespace("commission-absent"),
            "--config",
            concat!(env!("CARGO_MANIFEST_DIR"), "/config/niryo.toml"),
            "--set",
            "robot.host=127.0.0.1",
            "--set",
            &port,
        ],
        &["--only", "camera"],
    );
    assert_eq!(code, Some(1), "{report:#}");
    let connect = step(&report, "connect");
    assert_eq!(connect["status"], "failed", "{report:#}");
    let reason = connect["reason"].as_str().unwrap();
    assert!(reason.contains("does not answer"), "{reason}");
    assert!(reason.contains("not connected"), "{reason}");
    assert!(report["steps"].as_array().unwrap().len() == 1, "{report:#}");
    assert!(started.elapsed() < std::time::Duration::from_secs(40));
}

#[test]
fn a_sheet_out_of_view_is_refused_naming_why() {
    // The simulator puts the sheet where the workspace says; this observation pose looks
    // 25 cm to the side of it.
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("robot.toml");
    std::fs::write(
        &config,
        "[robot]\ndriver = \"sim-ned2\"\ntime_scale = 0.1\n\n[[robot.workspaces]]\nid = \
         \"niryo_ws\"\nupper_left = [0.337, 0.087]\nlower_right = [0.163, -0.087]\n\
         observation_pose = [0.173, 0.25, 0.277, -3.042, 1.327, -3.027]\n",
    )
    .unwrap();
    let (code, report, _) = commission(
        &[
            "--namespace",
            &common::fresh_namespace("commission-nosheet"),
            "--config",
            config.to_str().unwrap(),
        ],
        &["--only", "camera"],
    );
    assert_eq!(code, Some(1), "{report:#}");
    let camera = step(&report, "camera");
    assert_eq!(camera["status"], "failed", "{report:#}");
    let reason = camera["reason"].as_str().unwrap();
    assert!(reason.contains("showed the workspace sheet"), "{reason}");
    assert!(reason.contains("no workspace in view"), "{reason}");
}

#[test]
fn connecting_reports_what_each_robot_tells_of_its_versions() {
    // WidowX: every servo's model number and firmware, read from its control table.
    let namespace = common::fresh_namespace("commission-versions-widowx");
    let dir = tempfile::tempdir().unwrap();
    let device = dir.path().join("ttyDXL");
    let config = concat!(env!("CARGO_MANIFEST_DIR"), "/config/widowx.toml");
    let (_fake, camera_url) = common::start_fake_widowx(
        &[
            "--namespace",
            &format!("{namespace}-fake"),
            "--config",
            config,
        ],
        &device,
        &[],
    );
    let device = format!("robot.widowx.device={}", device.display());
    let camera_url = format!("robot.widowx.camera_url={camera_url}");
    let (code, report, _) = commission(
        &[
            "--namespace",
            namespace.as_str(),
            "--config",
            config,
            "--set",
            device.as_str(),
            "--set",
            camera_url.as_str(),
        ],
        &["--only", "connect"],
    );
    assert_eq!(code, Some(0), "{report:#}");
    let connect = &step(&report, "connect")["measured"];
    let motors = connect["versions"]["motors"].as_array().unwrap();
    assert_eq!(motors.len(), 9, "{connect:#}");
    assert_eq!(motors[0]["name"], "1 waist", "{connect:#}");
    assert_eq!(motors[0]["model"], "XM430-W350 (1020)", "{connect:#}");
    // The fake's servos answer firmware 52 at address 6.
    assert!(motors.iter().all(|m| m["firmware"] == "52"), "{connect:#}");

    // Ned2: the hardware version and motor types of GET_HARDWARE_STATUS; no software version.
    let namespace = common::fresh_namespace("commission-versions-ned2");
    let (_fake, port) =
        common::start_fake_niryo(&["--namespace", &format!("{namespace}-fake")], &[]);
    let port = format!("robot.port={port}");
    let (code, report, _) = commission(
        &[
            "--namespace",
            namespace.as_str(),
            "--config",
            concat!(env!("CARGO_MANIFEST_DIR"), "/config/niryo.toml"),
            "--set",
            "robot.host=127.0.0.1",
            "--set",
            port.as_str(),
        ],
        &["--only", "connect"],
    );
    assert_eq!(code, Some(0), "{report:#}");
    let connect = &step(&report, "connect")["measured"];
    let versions = &connect["versions"];
    assert_eq!(versions["hardware"], "ned2", "{connect:#}");
    assert_eq!(versions["software"], Value::Null, "{connect:#}");
    let motors = versions["motors"].as_array().unwrap();
    assert_eq!(motors.len(), 7, "{connect:#}");
    assert_eq!(motors[0]["name"], "Joint 1", "{connect:#}");
    assert_eq!(motors[0]["model"], "Stepper", "{connect:#}");
    let missing = connect["versions_not_reported"].to_string();
    assert!(missing.contains("software version"), "{connect:#}");
    // And the tool GET_CURRENT_TOOL_ID names: the fake's standard gripper.
    assert_eq!(versions["tool"], "GRIPPER_1", "{connect:#}");

    // The simulator reports none and says so.
    let (code, report, _) = commission(
        &[
            "--namespace",
            &common::fresh_namespace("commission-versions-sim"),
            "--set",
            "robot.driver=sim-ned2",
        ],
        &["--only", "connect"],
    );
    assert_eq!(code, Some(0), "{report:#}");
    let connect = &step(&report, "connect")["measured"];
    assert_eq!(connect["versions"], Value::Null, "{connect:#}");
    let missing = connect["versions_not_reported"].to_string();
    assert!(
        missing.contains("not reported by this driver"),
        "{connect:#}"
    );
}

#[test]
fn an_uncalibrated_ned2_is_refused_unless_commissioning_is_asked_to_calibrate_it() {
    let namespace = common::fresh_namespace("commission-calibrate");
    let (_fake, port) = common::start_fake_niryo(
        &[
            "--namespace",
            &format!("{namespace}-fake"),
            "--set",
            "robot.time_scale=0.05",
        ],
        &["--needs-calibration"],
    );
    let robot = ned2_settings(
        &namespace,
        port,
        &["--set", "robot.niryo.auto_calibrate=false"],
    );
    let robot = strs(&robot);
    let (code, report, _) = commission(&robot, &["--only", "connect"]);
    assert_eq!(code, Some(1), "{report:#}");
    let reason = step(&report, "connect")["reason"].as_str().unwrap();
    assert!(
        reason.contains("not calibrated") && reason.contains("--calibrate"),
        "{reason}"
    );

    let (code, report, _) = commission(&robot, &["--only", "connect", "--calibrate"]);
    assert_eq!(code, Some(0), "{report:#}");
    assert_eq!(step(&report, "connect")["measured"]["calibrated"], true);
}

#[test]
fn a_ned2s_gripper_step_names_its_tool_and_refuses_one_that_is_not_a_gripper() {
    let run_with_tool = |tool: &str| {
        let namespace = common::fresh_namespace("commission-ned2-tool");
        let (_fake, port) = common::start_fake_niryo(
            &["--namespace", &format!("{namespace}-fake")],
            &["--tool", tool],
        );
        let (code, report, _) = commission(
            &strs(&ned2_settings(&namespace, port, &[])),
            &["--only", "gripper"],
        );
        (code, report)
    };
    let (code, report) = run_with_tool("GRIPPER_2");
    assert_eq!(code, Some(0), "{report:#}");
    let gripper = &step(&report, "gripper")["measured"];
    assert_eq!(gripper["tool"], "GRIPPER_2", "{report:#}");
    assert_eq!(gripper["cycle"].as_array().unwrap().len(), 3, "{report:#}");

    for (tool, why) in [
        ("VACUUM_PUMP_1", "not a gripper"),
        ("NONE", "no tool mounted"),
    ] {
        let (code, report) = run_with_tool(tool);
        assert_eq!(code, Some(1), "{report:#}");
        let gripper = step(&report, "gripper");
        assert_eq!(gripper["status"], "failed", "{report:#}");
        let reason = gripper["reason"].as_str().unwrap();
        assert!(
            reason.contains(why) && reason.contains("nothing moved"),
            "{tool}: {reason}"
        );
    }
}

#[test]
fn a_ned2_that_starts_its_motions_late_is_still_until_its_last_segment_ran() {
    // Every motion of the fake Ned2 starts 1 s after its command: the segment under way at
    // the e-stop reports nothing for longer than the step's 600 ms quiet window, so the step
    // must wait for the arm to report its motion over before it calls it still.
    let namespace = common::fresh_namespace("commission-ned2-lag");
    let (_fake, port) = common::start_fake_niryo(
        &[
            "--namespace",
            &format!("{namespace}-fake"),
            "--set",
            "robot.time_scale=0.5",
        ],
        &["--stopping-lag-ms", "1000"],
    );
    let (code, report, _) = commission(
        &strs(&ned2_settings(
            &namespace,
            port,
            &["--set", "robot.time_scale=0.5"],
        )),
        &["--only", "stopping"],
    );
    assert_eq!(code, Some(0), "{report:#}");
    let stopping = &step(&report, "stopping")["measured"];
    eprintln!("Ned2 with 1 s of lag: {stopping}");
    let times: Vec<f64> = stopping["times_ms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t.as_f64().unwrap())
        .collect();
    assert_eq!(times.len(), 3, "{stopping:#}");
    // No stop is reported as instant: each waited for its segment's end.
    assert!(times.iter().all(|t| *t > 20.0), "{stopping:#}");
}
