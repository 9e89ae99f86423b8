//! The widowx driver against the fake servo bus on a real pseudo-terminal: bring-up, motions,
//! the gripper's grasp, a servo fault, corrupt and lost packets, the adapter unplugged.

use robotd_driver::{ArmDriver, Close, DriverError, Motion, MotionControl, Open, RobotConfig};
use robotd_driver_widowx::control_table::{address, GRIPPER_ID};
use robotd_driver_widowx::WidowxDrivers;
use robotd_fake_widowx::FakeServoBus;
use robotd_kinematics::Kinematics;
use robotd_protocol::RobotModel;
use robotd_safety::testing;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Tool speed caps of the test policy: one the arm never reaches (full speed), and one that
/// keeps a long motion going for a few seconds (to stop or fault it on the way).
const FULL: f64 = 100.0;
const SLOW: f64 = 0.1;

/// Runs `motion` on `arm` with a permit of a test policy (wide limits) capping the tool at
/// `speed_m_s`. A disconnected arm is planned from its rest pose (the driver refuses anyway).
async fn execute(
    arm: &Arc<dyn ArmDriver>,
    motion: Motion,
    speed_m_s: f64,
    control: &MotionControl,
) -> Result<(), DriverError> {
    let policy = testing::policy(
        RobotModel::WidowX250,
        testing::wide_config(speed_m_s),
        MotionControl::default(),
    );
    let start = arm
        .joints()
        .unwrap_or_else(|_| Kinematics::new(RobotModel::WidowX250).home_joints());
    arm.execute(testing::motion(&policy, &start, motion).await, control)
        .await
}

struct Rig {
    fake: FakeServoBus,
    widowx: WidowxDrivers,
    _dir: tempfile::TempDir,
}

fn config(device: &std::path::Path) -> RobotConfig {
    let mut config: RobotConfig =
        toml::from_str("driver = \"widowx\"\ncontrol_rate_hz = 100").unwrap();
    config.widowx.device = device.to_path_buf();
    config
}

async fn rig() -> Rig {
    let dir = tempfile::tempdir().unwrap();
    let sim_config: RobotConfig = toml::from_str("driver = \"sim-widowx\"").unwrap();
    let sim = robotd_driver_sim::open(&sim_config).unwrap().robot;
    let link = dir.path().join("ttyDXL");
    let defaults = robotd_driver::WidowxConfig::default();
    let fake = FakeServoBus::start(
        sim,
        &link,
        (defaults.gripper_closed_ticks, defaults.gripper_open_ticks),
    )
    .unwrap();
    let widowx = robotd_driver_widowx::open(&config(&link));
    wait_connected(&widowx, Duration::from_secs(5)).await;
    Rig {
        fake,
        widowx,
        _dir: dir,
    }
}

async fn wait_connected(widowx: &WidowxDrivers, within: Duration) {
    let deadline = Instant::now() + within;
    while widowx.bus.connection().is_err() || widowx.drivers.arm.joints().is_err() {
        assert!(
            Instant::now() < deadline,
            "not connected: {:?}",
            widowx.bus.connection()
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

/// Waits until the bus says it is not connected; its reason.
async fn wait_disconnected(widowx: &WidowxDrivers, what: &str) -> String {
    let deadline = Instant::now() + Duration::from_secs(3);
    loop {
        if let Err(reason) = widowx.bus.connection() {
            return reason;
        }
        assert!(Instant::now() < deadline, "still connected {what}");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

/// Waits until the simulated arm has moved from `from` (a motion is under way), instead of
/// guessing how long starting one takes.
async fn wait_moving(fake: &FakeServoBus, from: &[f64]) {
    let deadline = Instant::now() + Duration::from_secs(5);
    while max_diff(&fake.sim().joints(), from) < 0.01 {
        assert!(Instant::now() < deadline, "the arm never started moving");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn brings_up_the_bus_and_moves_the_simulated_arm() {
    let rig = rig().await;
    let sim = rig.fake.sim();
    let arm = &rig.widowx.drivers.arm;
    assert!(max_diff(&arm.joints().unwrap(), &sim.joints()) < 0.002);
    // Bring-up put the shadows on their masters and the gripper in PWM mode, torque on.
    assert_eq!(
        rig.fake.read_table(3, address::SECONDARY_ID, 1),
        Some(vec![2])
    );
    assert_eq!(
        rig.fake.read_table(5, address::DRIVE_MODE, 1),
        Some(vec![1])
    );
    assert_eq!(
        rig.fake.read_table(GRIPPER_ID, address::OPERATING_MODE, 1),
        Some(vec![16])
    );
    assert_eq!(
        rig.fake.read_table(4, address::TORQUE_ENABLE, 1),
        Some(vec![1])
    );

    let target = vec![0.3, -0.2, 0.3, 0.0, 0.4, 0.1];
    let control = MotionControl::default();
    execute(arm, Motion::Joints(target.clone()), FULL, &control)
        .await
        .unwrap();
    assert!(
        max_diff(&sim.joints(), &target) < 0.01,
        "sim at {:?}",
        sim.joints()
    );
    assert!(max_diff(&arm.joints().unwrap(), &target) < 0.01);
    // Every goal the bus wrote reached the servos once.
    assert_eq!(
        rig.fake.counters().goal_writes.load(Ordering::SeqCst),
        rig.widowx.bus.stats.goal_writes.load(Ordering::SeqCst) + 6,
        "6 goal writes of the bring-up plus one sync write per tick of the motion"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stop_holds_the_arm_within_a_tick_or_two() {
    let rig = rig().await;
    let arm = rig.widowx.drivers.arm.clone();
    let control = MotionControl::default();
    let motion_control = control.clone();
    let from = rig.fake.sim().joints();
    let motion = tokio::spawn(async move {
        execute(
            &arm,
            Motion::Joints(vec![1.2, -0.2, 0.3, 0.0, 0.4, 0.1]),
            SLOW,
            &motion_control,
        )
        .await
    });
    wait_moving(&rig.fake, &from).await;
    let stopped_at = Instant::now();
    control.request_stop();
    let result = motion.await.unwrap();
    assert!(
        matches!(result, Err(DriverError::Stopped { .. })),
        "{result:?}"
    );
    let latency = stopped_at.elapsed();
    assert!(
        latency < Duration::from_millis(100),
        "stop took {latency:?}"
    );
    // Held: the arm does not keep going toward the old target.
    let here = rig.fake.sim().joints();
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert!(max_diff(&rig.fake.sim().joints(), &here) < 0.02);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_gripper_closes_on_nothing_and_opens() {
    let rig = rig().await;
    let gripper = &rig.widowx.drivers.gripper;
    let policy = testing::wide_policy(RobotModel::WidowX250);
    let closed = gripper
        .close(testing::gripper(&policy, Close).await)
        .await
        .unwrap();
    assert!(!closed.holding, "nothing between the fingers: {closed:?}");
    assert!(closed.width_m < 0.003, "{closed:?}");
    let open = gripper
        .open(testing::gripper(&policy, Open).await)
        .await
        .unwrap();
    assert!(!open.holding);
    assert!(open.width_m > gripper.max_width_m() - 0.003, "{open:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_servo_fault_is_named_the_arm_held_and_the_servo_rebooted_within_a_second() {
    let rig = rig().await;
    let arm = rig.widowx.drivers.arm.clone();
    let control = MotionControl::default();
    let motion_control = control.clone();
    let from = rig.fake.sim().joints();
    let motion = tokio::spawn(async move {
        execute(
            &arm,
            Motion::Joints(vec![1.0, -0.2, 0.3, 0.0, 0.4, 0.1]),
            SLOW,
            &motion_control,
        )
        .await
    });
    wait_moving(&rig.fake, &from).await;
    rig.fake.latch_hardware_error(4, 0x20);
    let error = motion.await.unwrap().unwrap_err();
    let text = error.to_string();
    assert!(text.contains("servo 4 (elbow) reported overload"), "{text}");
    let fault = rig.widowx.bus.last_fault().unwrap();
    assert!(fault.recovered, "{fault}");
    assert!(fault.recovery_time < Duration::from_secs(1), "{fault}");
    assert_eq!(rig.fake.counters().reboots.load(Ordering::SeqCst), 1);
    assert_eq!(
        rig.fake.read_table(4, address::TORQUE_ENABLE, 1),
        Some(vec![1])
    );
    assert_eq!(
        rig.fake.read_table(4, address::HARDWARE_ERROR_STATUS, 1),
        Some(vec![0])
    );
    // And the arm moves again.
    let target = vec![0.2, -0.2, 0.3, 0.0, 0.4, 0.1];
    execute(
        &rig.widowx.drivers.arm,
        Motion::Joints(target.clone()),
        FULL,
        &control,
    )
    .await
    .unwrap();
    assert!(max_diff(&rig.fake.sim().joints(), &target) < 0.01);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn corrupt_and_lost_packets_are_errors_and_the_bus_carries_on() {
    let rig = rig().await;
    let faults = rig.fake.faults();
    faults.corrupt_next.store(3, Ordering::SeqCst);
    faults.drop_next.store(2, Ordering::SeqCst);
    // A few ticks pass with bad replies: no panic, and the bus stays up (one bad tick is not a
    // lost servo).
    let deadline = Instant::now() + Duration::from_secs(2);
    while faults.corrupt_next.load(Ordering::SeqCst) + faults.drop_next.load(Ordering::SeqCst) > 0 {
        assert!(Instant::now() < deadline, "the bus stopped asking");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let rejected_before = rig.fake.counters().rejected.load(Ordering::SeqCst);
    assert_eq!(
        rejected_before, 0,
        "the driver's own packets are always intact"
    );
    wait_connected(&rig.widowx, Duration::from_secs(3)).await;
    // A bus that stops answering makes the robot unavailable with the reason.
    faults.silent.store(true, Ordering::SeqCst);
    let reason = wait_disconnected(&rig.widowx, "while silent").await;
    assert!(
        reason.contains("stopped answering") || reason.contains("does not answer"),
        "{reason}"
    );
    let refused = execute(
        &rig.widowx.drivers.arm,
        Motion::Joints(vec![0.0; 6]),
        FULL,
        &MotionControl::default(),
    )
    .await
    .unwrap_err();
    assert!(
        refused.to_string().contains("robot not connected"),
        "{refused}"
    );
    faults.silent.store(false, Ordering::SeqCst);
    wait_connected(&rig.widowx, Duration::from_secs(5)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_unplugged_adapter_is_reported_and_found_again() {
    let rig = rig().await;
    rig.fake.unplug();
    let reason = wait_disconnected(&rig.widowx, "after unplugging").await;
    assert!(reason.contains("U2D2"), "{reason}");
    rig.fake.plug_in().unwrap();
    let replugged = Instant::now();
    wait_connected(&rig.widowx, Duration::from_secs(5)).await;
    assert!(
        replugged.elapsed() < Duration::from_millis(2500),
        "{:?}",
        replugged.elapsed()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_missing_servo_is_a_start_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("ttyDXL");
    let widowx = robotd_driver_widowx::open(&config(&link));
    let deadline = Instant::now() + Duration::from_secs(2);
    loop {
        if let Err(reason) = widowx.bus.connection() {
            if reason.contains("not found") {
                assert!(reason.contains("ttyDXL"), "{reason}");
                break;
            }
        }
        assert!(Instant::now() < deadline);
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    widowx.bus.shutdown();
}
