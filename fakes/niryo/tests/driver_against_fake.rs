//! The niryo driver against the fake Ned2 over a real TCP socket on loopback: motions,
//! gripper, camera, collisions, and every fault a real robot's connection can produce.

use robotd_driver::{
    ArmDriver, Close, DriverError, Motion, MotionControl, Open, RobotConfig, SetWidth,
};
use robotd_driver_niryo::{NiryoArm, NiryoDrivers};
use robotd_fake_niryo::{FakeFaults, FakeNiryo};
use robotd_kinematics::{pose_to_isometry, Kinematics};
use robotd_protocol::geometry::{Pose, RobotModel};
use robotd_safety::{testing, AuditConfig, AuditLog, Safety};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::net::TcpListener;

/// A fake Ned2 on a free loopback port (or on `port`), motions at `time_scale`.
async fn fake_on(port: u16, time_scale: f64, faults: FakeFaults) -> (Arc<FakeNiryo>, SocketAddr) {
    let robot: RobotConfig = toml::from_str(&format!(
        "driver = \"sim-ned2\"\ntime_scale = {time_scale}\n[camera]\nlens_distortion = true\nnoise_stddev = 0.0\n"
    ))
    .unwrap();
    let sim = robotd_driver_sim::open(&robot).unwrap();
    let fake = FakeNiryo::new(sim.robot, faults);
    let listener = TcpListener::bind(("127.0.0.1", port)).await.unwrap();
    let address = listener.local_addr().unwrap();
    tokio::spawn(fake.clone().serve(listener));
    (fake, address)
}

async fn fake(faults: FakeFaults) -> (Arc<FakeNiryo>, SocketAddr) {
    fake_on(0, 0.05, faults).await
}

fn config(port: u16, extra: &str) -> RobotConfig {
    toml::from_str(&format!(
        "driver = \"niryo\"\nhost = \"127.0.0.1\"\nport = {port}\n[camera]\nfps = 30.0\n[niryo]\nconnect_timeout_ms = 500\nquery_timeout_ms = 1000\n{extra}"
    ))
    .unwrap()
}

async fn open(port: u16, extra: &str) -> NiryoDrivers {
    robotd_driver_niryo::open(
        &config(port, extra),
        Duration::from_secs(3),
        testing::wide_policy(RobotModel::Ned2),
    )
    .await
}

/// Runs `motion` on `arm` with a permit of a test policy (wide limits, full speed).
async fn execute(
    arm: &Arc<dyn ArmDriver>,
    motion: Motion,
    control: &MotionControl,
) -> Result<(), DriverError> {
    let policy = testing::wide_policy(RobotModel::Ned2);
    let start = arm.joints()?;
    arm.execute(testing::motion(&policy, &start, motion).await, control)
        .await
}

/// Waits (polling a condition, bounded) until `done` holds.
async fn until(what: &str, timeout: Duration, mut done: impl FnMut() -> bool) -> Duration {
    let started = Instant::now();
    while !done() {
        assert!(
            started.elapsed() < timeout,
            "{what}: not within {timeout:?}"
        );
        tokio::time::sleep(Duration::from_millis(2)).await;
    }
    started.elapsed()
}

fn joints_for(x: f64, y: f64, z: f64) -> Vec<f64> {
    let kin = Kinematics::new(RobotModel::Ned2);
    let pose = Pose::from_array([x, y, z, 0.0, 1.57, 0.0]);
    kin.inverse(&pose_to_isometry(&pose), Some(&kin.home_joints()))
        .unwrap()
}

fn close(a: &[f64], b: &[f64]) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-3)
}

fn count(log: &[String], command: &str) -> usize {
    log.iter().filter(|c| *c == command).count()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn moves_in_segments_grips_and_sees_through_the_real_protocol() {
    let (fake, address) = fake(FakeFaults::default()).await;
    let niryo = open(address.port(), "").await;
    assert_eq!(niryo.link.status(), Ok(()));
    let arm = niryo.drivers.arm.clone();
    let start = arm.joints().unwrap();
    assert!(
        close(&start, &fake.sim().joints()),
        "joints read at connect"
    );

    let target = joints_for(0.25, 0.05, 0.15);
    let before = fake.command_log();
    execute(
        &arm,
        Motion::Joints(target.clone()),
        &MotionControl::default(),
    )
    .await
    .unwrap();
    assert!(close(&fake.sim().joints(), &target));
    assert!(close(&arm.joints().unwrap(), &target));
    let sent = fake.command_log()[before.len()..].to_vec();
    let segments = count(&sent, "MOVE_JOINTS");
    assert!(
        segments >= 2,
        "a long joint move goes in segments: {sent:?}"
    );
    // Each segment is read back before the next one is sent (other readers of the joints,
    // such as the camera's pose, may add GET_JOINTS of their own in between).
    let mut read_back = 0;
    for (i, command) in sent.iter().enumerate() {
        if command == "MOVE_JOINTS" {
            let until_next = sent[i + 1..]
                .iter()
                .take_while(|c| *c != "MOVE_JOINTS")
                .any(|c| c == "GET_JOINTS");
            read_back += usize::from(until_next);
        }
    }
    assert_eq!(read_back, segments, "each segment read back: {sent:?}");

    let gripper = niryo.drivers.gripper.clone();
    let policy = testing::wide_policy(RobotModel::Ned2);
    let permit = testing::gripper(&policy, Close).await;
    assert!(gripper.close(permit).await.unwrap().holding);
    let permit = testing::gripper(&policy, Open).await;
    assert!(!gripper.open(permit).await.unwrap().holding);
    let permit = testing::gripper(&policy, SetWidth { width_m: 0.01 }).await;
    assert!(
        gripper.set_width(permit).await.is_err(),
        "the Ned2 gripper has no width control"
    );

    let camera = niryo.drivers.camera.clone();
    assert_eq!(
        camera.intrinsics().distortion[0],
        -0.4146402,
        "read from the robot"
    );
    tokio::time::timeout(Duration::from_secs(3), camera.frame_ready())
        .await
        .unwrap()
        .unwrap();
    let mut frame = vec![0u8; 640 * 480 * 3];
    let info = camera.capture_into(&mut frame).unwrap();
    let kin = Kinematics::new(RobotModel::Ned2);
    let expected = kin.camera_pose(&target).unwrap();
    assert!((info.camera_pose.translation.vector - expected.translation.vector).norm() < 1e-3);
    assert!(
        frame.iter().any(|p| *p > 200) && frame.iter().any(|p| *p < 60),
        "a real image"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_collision_stops_the_arm_and_clearing_lets_it_move_again() {
    let (_fake, address) = fake(FakeFaults::default()).await;
    let niryo = open(address.port(), "").await;
    let arm = niryo.drivers.arm.clone();
    let control = MotionControl::default();
    execute(&arm, Motion::Joints(joints_for(0.25, 0.0, 0.10)), &control)
        .await
        .unwrap();
    // Straight into the table.
    let error = execute(&arm, Motion::Joints(joints_for(0.25, 0.0, -0.02)), &control)
        .await
        .unwrap_err();
    assert!(matches!(error, DriverError::Collision { .. }), "{error}");
    assert!(arm.flags().collision_detected);
    let again = execute(&arm, Motion::Joints(joints_for(0.25, 0.0, 0.10)), &control)
        .await
        .unwrap_err();
    assert_eq!(again, DriverError::CollisionPending);
    let policy = testing::wide_policy(RobotModel::Ned2);
    arm.clear_collision(testing::clear_collision(&policy).await)
        .await
        .unwrap();
    assert!(!arm.flags().collision_detected);
    execute(&arm, Motion::Joints(joints_for(0.25, 0.0, 0.10)), &control)
        .await
        .unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_move_the_robot_answers_ok_but_ignores_is_an_error() {
    let (fake, address) = fake(FakeFaults::default()).await;
    let niryo = open(address.port(), "").await;
    fake.set_faults(|f| f.ignore_moves = true);
    let error = execute(
        &niryo.drivers.arm,
        Motion::Joints(joints_for(0.25, 0.05, 0.15)),
        &MotionControl::default(),
    )
    .await
    .unwrap_err();
    assert!(error.to_string().contains("did not arrive"), "{error}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_uncalibrated_robot_is_calibrated_on_connect_or_refuses_motions() {
    let (fake, address) = fake(FakeFaults {
        needs_calibration: true,
        ..Default::default()
    })
    .await;
    let niryo = open(address.port(), "auto_calibrate = false").await;
    let arm = niryo.drivers.arm.clone();
    assert!(!arm.flags().calibrated);
    let error = execute(
        &arm,
        Motion::Joints(joints_for(0.25, 0.05, 0.15)),
        &MotionControl::default(),
    )
    .await
    .unwrap_err();
    assert_eq!(error, DriverError::NotCalibrated);
    let policy = testing::wide_policy(RobotModel::Ned2);
    let start = arm.joints().unwrap();
    arm.calibrate(testing::calibration(&policy, &start).await)
        .await
        .unwrap();
    assert!(arm.flags().calibrated);
    drop(niryo);

    let (fake2, address) = fake_on(
        0,
        0.05,
        FakeFaults {
            needs_calibration: true,
            ..Default::default()
        },
    )
    .await;
    let niryo = open(address.port(), "").await;
    assert!(niryo.drivers.arm.flags().calibrated);
    assert_eq!(
        count(&fake2.command_log(), "CALIBRATE"),
        1,
        "auto_calibrate on connect"
    );
    let _ = fake;
}

/// Issue 39, door 1: the driver's own calibration on connecting asks the motion policy first.
/// While the e-stop is engaged it is refused (audited), the robot is not calibrated, and the
/// arm's connection status (what `/health` shows) says why; once the e-stop is released it is
/// admitted, sent once, and its outcome recorded. On the old code the driver sent `CALIBRATE
/// AUTO` at once, e-stop or not, with no audit line.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_automatic_calibration_waits_for_the_policy_and_an_engaged_estop() {
    let (fake, address) = fake(FakeFaults {
        needs_calibration: true,
        ..Default::default()
    })
    .await;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("audit.jsonl");
    let audit = AuditLog::start(&AuditConfig {
        path: path.clone(),
        max_file_bytes: 1 << 20,
        keep_files: 2,
        queue: 64,
        key: None,
    })
    .unwrap();
    let control = MotionControl::default();
    let policy = Safety::new(
        testing::wide_config(100.0),
        Kinematics::new(RobotModel::Ned2),
        control.clone(),
        &[],
        audit.clone(),
    );
    control.set_estop(true, "cable in the way");
    let niryo =
        robotd_driver_niryo::open(&config(address.port(), ""), Duration::ZERO, policy).await;
    let arm = niryo.drivers.arm.clone();
    until(
        "the held calibration reported",
        Duration::from_secs(5),
        || {
            arm.connection().is_err_and(|reason| {
                reason.contains("needs calibration")
                    && reason.contains("emergency stop engaged: cable in the way")
            })
        },
    )
    .await;
    assert_eq!(count(&fake.command_log(), "CALIBRATE"), 0);
    assert!(!arm.flags().calibrated);
    assert!(
        arm.joints().is_err(),
        "no command before the robot is ready"
    );

    control.set_estop(false, "");
    until(
        "calibrated after the release",
        Duration::from_secs(5),
        || arm.connection().is_ok(),
    )
    .await;
    assert_eq!(count(&fake.command_log(), "CALIBRATE"), 1);
    assert!(arm.flags().calibrated);

    audit.flush(Duration::from_secs(5)).unwrap();
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["event"].take())
        .collect();
    let calibrations: Vec<_> = lines
        .iter()
        .filter(|l| l["action"] == "calibrate_on_connect")
        .collect();
    assert_eq!(calibrations.len(), 2, "{lines:?}");
    assert_eq!(calibrations[0]["decision"], "refused");
    assert_eq!(calibrations[0]["limit"], "estop");
    assert_eq!(calibrations[1]["decision"], "admitted");
    assert_eq!(calibrations[1]["origin"]["kind"], "internal");
    let admitted = &calibrations[1]["motion"];
    assert!(
        lines
            .iter()
            .any(|l| l["event"] == "outcome" && &l["motion"] == admitted && l["outcome"] == "done"),
        "{lines:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_unreachable_robot_is_reported_and_becomes_available_by_itself() {
    // A port held by a bound socket that does not listen: connections to it are refused, and
    // no other test can take it meanwhile.
    let holder = tokio::net::TcpSocket::new_v4().unwrap();
    holder.bind("127.0.0.1:0".parse().unwrap()).unwrap();
    let port = holder.local_addr().unwrap().port();
    let niryo = robotd_driver_niryo::open(
        &config(port, ""),
        Duration::ZERO,
        testing::wide_policy(RobotModel::Ned2),
    )
    .await;
    let arm = niryo.drivers.arm.clone();
    // `open` did not wait: the first attempt may still be under way ("not connected yet").
    until(
        "the refused connection reported",
        Duration::from_secs(4),
        || {
            arm.connection()
                .is_err_and(|reason| reason.contains("cannot connect"))
        },
    )
    .await;
    let error = arm.joints().unwrap_err().to_string();
    assert!(error.starts_with("robot not connected: "), "{error}");
    // Let the reconnector back off to its longest wait before the robot appears.
    tokio::time::sleep(Duration::from_millis(2500)).await;
    drop(holder);
    let (_fake, _) = fake_on(port, 0.05, FakeFaults::default()).await;
    let back = until("reconnected", Duration::from_secs(4), || {
        arm.connection().is_ok()
    })
    .await;
    println!(
        "robot available again {:.0} ms after it started listening",
        back.as_secs_f64() * 1e3
    );
    assert!(back <= Duration::from_millis(2500), "{back:?}");
    assert!(arm.joints().is_ok());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_connection_lost_mid_motion_fails_it_at_once_and_never_resends_it() {
    let (fake, address) = fake_on(0, 0.5, FakeFaults::default()).await;
    let niryo = open(address.port(), "segment_rad = 3.0").await;
    let arm = niryo.drivers.arm.clone();
    let control = MotionControl::default();
    execute(&arm, Motion::Joints(joints_for(0.25, 0.0, 0.15)), &control)
        .await
        .unwrap();
    fake.set_faults(|f| {
        f.drop_at = Some(1);
        f.only = Some("MOVE_JOINTS".into());
    });
    let target = joints_for(0.2, 0.1, 0.2);
    let before = fake.command_log().len();
    let handshakes = count(&fake.command_log(), "HANDSHAKE");
    let started = Instant::now();
    let error = execute(&arm, Motion::Joints(target.clone()), &control)
        .await
        .unwrap_err();
    let failed_after = started.elapsed();
    assert!(
        error
            .to_string()
            .contains("connection to the robot lost during move"),
        "{error}"
    );
    assert!(
        failed_after < Duration::from_millis(500),
        "at once, not at the deadline: {failed_after:?}"
    );
    // Known again only through a new connection (the reconnector may already be back).
    assert!(
        arm.joints().is_err() || count(&fake.command_log(), "HANDSHAKE") > handshakes,
        "the position is unknown until reconnected"
    );
    until("reconnected", Duration::from_secs(10), || {
        arm.connection().is_ok()
    })
    .await;
    // The robot finished the move on its own; the driver read where the arm is before
    // accepting anything, and the move was sent exactly once.
    assert!(close(&arm.joints().unwrap(), &target));
    assert_eq!(count(&fake.command_log()[before..], "MOVE_JOINTS"), 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn garbage_and_silence_reset_the_connection_and_it_comes_back() {
    let (fake, address) = fake(FakeFaults::default()).await;
    let niryo = open(address.port(), "").await;
    let arm: Arc<NiryoArm> = Arc::new(NiryoArm::new(
        niryo.link.clone(),
        robotd_driver_niryo::arm::ArmSettings {
            max_velocity_rad_s: vec![1.0; 6],
            segment_rad: 0.2,
            arrival_tolerance_rad: 0.02,
        },
    ));
    // GET_HARDWARE_STATUS: only this test sends it after the connect.
    for fault in ["garbage", "silent"] {
        until("connected", Duration::from_secs(5), || {
            niryo.link.status().is_ok()
        })
        .await;
        fake.set_faults(|f| {
            *f = FakeFaults {
                only: Some("GET_HARDWARE_STATUS".into()),
                ..Default::default()
            };
            if fault == "garbage" {
                f.garbage_at = Some(1);
            } else {
                f.silent_at = Some(1);
            }
        });
        let handshakes = count(&fake.command_log(), "HANDSHAKE");
        let started = Instant::now();
        let error = niryo
            .link
            .call("GET_HARDWARE_STATUS", &[], Duration::from_secs(1))
            .await
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("connection to the robot lost during GET_HARDWARE_STATUS"),
            "{fault}: {error}"
        );
        if fault == "silent" {
            assert!(error.contains("no reply within 1.0 s"), "{error}");
            assert!(started.elapsed() < Duration::from_millis(1500));
        } else {
            assert!(error.contains("malformed"), "{error}");
        }
        // The connection was dropped and a new one greeted the robot (the reconnector may
        // already be back, so the status alone cannot tell).
        until("a new connection", Duration::from_secs(5), || {
            count(&fake.command_log(), "HANDSHAKE") > handshakes
        })
        .await;
    }
    until("reconnected", Duration::from_secs(5), || {
        niryo.link.status().is_ok()
    })
    .await;
    assert!(arm.read_joints().await.is_ok());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stop_takes_effect_at_the_end_of_the_current_segment() {
    // Real time; the wrist joint (2 rad/s) turns 1.5 rad in segments of 0.2 rad (~0.15 s).
    let (fake, address) = fake_on(0, 1.0, FakeFaults::default()).await;
    let niryo = open(address.port(), "segment_rad = 0.2").await;
    let arm = niryo.drivers.arm.clone();
    let mut target = arm.joints().unwrap();
    target[3] += 1.5;
    let control = MotionControl::default();
    let motion = {
        let (arm, control) = (arm.clone(), control.clone());
        tokio::spawn(async move { execute(&arm, Motion::Joints(target), &control).await })
    };
    let start = fake.sim().joints()[3];
    until("moving", Duration::from_secs(5), || {
        fake.sim().joints()[3] != start
    })
    .await;
    let stopped_at = Instant::now();
    control.set_estop(true, "test");
    let result = motion.await.unwrap();
    let latency = stopped_at.elapsed();
    assert!(
        matches!(result, Err(DriverError::Stopped { .. })),
        "{result:?}"
    );
    println!(
        "e-stop to motion ended: {:.0} ms (segments of 0.2 rad, ~150 ms each)",
        latency.as_secs_f64() * 1e3
    );
    assert!(latency < Duration::from_millis(400), "{latency:?}");
    let parked = fake.sim().joints()[3];
    assert!(parked - start < 0.5, "the arm stopped part-way ({parked})");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rectified_images_are_described_without_distortion() {
    let (_fake, address) = fake(FakeFaults::default()).await;
    let raw = open(address.port(), "").await;
    assert_eq!(raw.link.status(), Ok(()));
    assert_eq!(raw.drivers.camera.intrinsics().distortion[0], -0.4146402);
    // A second fake: the first one serves `raw` (one client at a time, as the robot).
    let (_fake2, address) = fake(FakeFaults::default()).await;
    let rectified = open(address.port(), "images_rectified = true").await;
    assert_eq!(rectified.link.status(), Ok(()));
    let intrinsics = rectified.drivers.camera.intrinsics();
    assert_eq!(intrinsics.distortion, [0.0; 5]);
    assert_eq!(
        intrinsics.fx, 508.069,
        "the camera matrix is still the robot's"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_a_stopping_lag_a_segment_sent_before_the_estop_still_runs() {
    // Real time, segments of 0.2 rad; every motion starts 300 ms after its command.
    let (fake, address) = fake_on(0, 1.0, FakeFaults::default()).await;
    fake.set_stopping_lag(Duration::from_millis(300));
    let niryo = open(address.port(), "segment_rad = 0.2").await;
    let arm = niryo.drivers.arm.clone();
    let mut target = arm.joints().unwrap();
    target[3] += 1.5;
    let start = fake.sim().joints()[3];
    let control = MotionControl::default();
    let before = count(&fake.command_log(), "MOVE_JOINTS");
    let motion = {
        let (arm, control) = (arm.clone(), control.clone());
        tokio::spawn(async move { execute(&arm, Motion::Joints(target), &control).await })
    };
    until("the first segment sent", Duration::from_secs(5), || {
        count(&fake.command_log(), "MOVE_JOINTS") > before
    })
    .await;
    control.set_estop(true, "test");
    let still_for = until(
        "the arm moving after the e-stop",
        Duration::from_secs(5),
        || fake.sim().joints()[3] != start,
    )
    .await;
    let result = motion.await.unwrap();
    assert!(
        matches!(result, Err(DriverError::Stopped { .. })),
        "{result:?}"
    );
    // The segment sent before the e-stop started late, then ran to its end; no other did.
    assert!(still_for >= Duration::from_millis(250), "{still_for:?}");
    let parked = fake.sim().joints()[3] - start;
    assert!((0.1..0.3).contains(&parked), "turned {parked} rad");
    assert_eq!(count(&fake.command_log(), "MOVE_JOINTS"), before + 1);
}
