//! What the one-door tests share: drivers that record every actuator call (with its permit's
//! audit number and whether the e-stop was engaged at that moment) before passing it on to
//! the simulator, and the robot's actors started on them over a real bus.

#![allow(dead_code)]

use robotd_driver::{
    ArmDriver, ArmFlags, ArmMotion, Calibration, ClearCollision, Close, DriverError, DriverFuture,
    GripperDriver, GripperStatus, MotionControl, Open, Permit, RobotDrivers, SetWidth,
};
use robotd_protocol::geometry::RobotModel;
use robotd_robot::{Hardware, RobotSections};
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_runtime::supervision::{observer_fn, SupervisionEvent};
use robotd_safety::Safety;
use std::ops::{Deref, DerefMut};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};

/// One actuator call that reached a driver.
#[derive(Debug, Clone, PartialEq)]
pub struct Call {
    /// The trait method.
    pub method: &'static str,
    /// The permit's motion number in the audit log.
    pub motion_id: u64,
    /// Whether the e-stop was engaged when the call began.
    pub estop_engaged: bool,
    /// For a motion: the joints it started from and what it was to do.
    pub motion: Option<(Vec<f64>, robotd_safety::Motion)>,
}

/// The calls of one robot, shared by its recording drivers.
#[derive(Debug, Clone, Default)]
pub struct Calls(Arc<Mutex<Vec<Call>>>);

impl Calls {
    fn push<A>(&self, method: &'static str, permit: &Permit<A>, control: &MotionControl) {
        self.push_motion(method, permit, control, None);
    }

    fn push_motion<A>(
        &self,
        method: &'static str,
        permit: &Permit<A>,
        control: &MotionControl,
        motion: Option<(Vec<f64>, robotd_safety::Motion)>,
    ) {
        self.0.lock().unwrap().push(Call {
            method,
            motion_id: permit.motion_id(),
            estop_engaged: control.estop_engaged(),
            motion,
        });
    }

    /// Everything recorded so far.
    pub fn all(&self) -> Vec<Call> {
        self.0.lock().unwrap().clone()
    }

    /// How many calls of `method`.
    pub fn count(&self, method: &str) -> usize {
        self.all().iter().filter(|c| c.method == method).count()
    }
}

/// An arm driver that records every actuator call, then runs it on `inner`.
pub struct RecordingArm {
    pub inner: Arc<dyn ArmDriver>,
    pub calls: Calls,
    pub control: MotionControl,
}

impl ArmDriver for RecordingArm {
    fn model(&self) -> RobotModel {
        self.inner.model()
    }
    fn joints(&self) -> Result<Vec<f64>, DriverError> {
        self.inner.joints()
    }
    fn flags(&self) -> ArmFlags {
        self.inner.flags()
    }
    fn execute<'a>(
        &'a self,
        permit: Permit<ArmMotion>,
        control: &'a MotionControl,
    ) -> DriverFuture<'a, ()> {
        let start = self.inner.joints().ok();
        let motion = start.map(|start| (start, permit.act().motion.clone()));
        self.calls
            .push_motion("execute", &permit, &self.control, motion);
        self.inner.execute(permit, control)
    }
    fn calibrate(&self, permit: Permit<Calibration>) -> DriverFuture<'_, ()> {
        self.calls.push("calibrate", &permit, &self.control);
        self.inner.calibrate(permit)
    }
    fn clear_collision(&self, permit: Permit<ClearCollision>) -> DriverFuture<'_, ()> {
        self.calls.push("clear_collision", &permit, &self.control);
        self.inner.clear_collision(permit)
    }
    fn halt(&self) -> Result<(), DriverError> {
        self.inner.halt()
    }
}

/// A gripper driver that records every actuator call, then runs it on `inner`.
pub struct RecordingGripper {
    pub inner: Arc<dyn GripperDriver>,
    pub calls: Calls,
    pub control: MotionControl,
}

impl GripperDriver for RecordingGripper {
    fn max_width_m(&self) -> f64 {
        self.inner.max_width_m()
    }
    fn open(&self, permit: Permit<Open>) -> DriverFuture<'_, GripperStatus> {
        self.calls.push("open", &permit, &self.control);
        self.inner.open(permit)
    }
    fn close(&self, permit: Permit<Close>) -> DriverFuture<'_, GripperStatus> {
        self.calls.push("close", &permit, &self.control);
        self.inner.close(permit)
    }
    fn set_width(&self, permit: Permit<SetWidth>) -> DriverFuture<'_, GripperStatus> {
        self.calls.push("set_width", &permit, &self.control);
        self.inner.set_width(permit)
    }
    fn status(&self) -> Result<GripperStatus, DriverError> {
        self.inner.status()
    }
}

/// The robot's sections as `config/default.toml` documents them (what the binary hands over
/// when nothing is configured).
pub fn default_sections() -> RobotSections {
    let defaults: toml::Table = include_str!("../../../config/default.toml")
        .parse()
        .expect("config/default.toml");
    let section = |name: &str| {
        defaults
            .get(name)
            .cloned()
            .unwrap_or_else(|| panic!("[{name}] in config/default.toml"))
    };
    let telemetry = section("telemetry");
    RobotSections {
        robot: section("robot").try_into().expect("[robot]"),
        safety: section("safety").try_into().expect("[safety]"),
        log_dir: telemetry["log_dir"]
            .as_str()
            .expect("telemetry.log_dir")
            .into(),
        supervision: section("supervision").try_into().expect("[supervision]"),
        actor_supervision: Default::default(),
        commissioning: false,
    }
}

/// A test's configuration: the robot's sections (what this crate reads; `config.robot`,
/// `config.safety`, … through `Deref`) and a bus namespace of its own.
#[derive(Debug, Clone)]
pub struct TestConfig {
    /// The bus namespace (`[bus] namespace`).
    pub namespace: String,
    /// The robot's sections.
    pub sections: RobotSections,
}

impl Deref for TestConfig {
    type Target = RobotSections;
    fn deref(&self) -> &RobotSections {
        &self.sections
    }
}

impl DerefMut for TestConfig {
    fn deref_mut(&mut self) -> &mut RobotSections {
        &mut self.sections
    }
}

/// The default sections on a bus namespace of its own (`{prefix}-{pid}-{n}`), no audit log.
pub fn test_config(prefix: &str) -> TestConfig {
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    let mut config = TestConfig {
        namespace: format!(
            "{prefix}-{}-{}",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ),
        sections: default_sections(),
    };
    config.safety.audit.enabled = false;
    config
}

/// A configuration on a bus namespace of its own: the simulated Ned2 at `time_scale`, 100 Hz
/// control, no audit log (set one to read it back).
pub fn fresh_config(time_scale: f64) -> TestConfig {
    let mut config = test_config("door");
    config.robot.time_scale = time_scale;
    config.robot.control_rate_hz = 100;
    config.robot.camera.fps = 5.0;
    config.supervision.backoff_initial_ms = 5;
    config
}

/// The robot of `config` (the simulator) behind recording drivers, its actors on a bus.
pub struct Rig {
    pub bus: Bus,
    pub hardware: Hardware,
    pub safety: Safety,
    pub calls: Calls,
    pub sim: robotd_driver_sim::SimRobot,
}

pub async fn rig(config: &TestConfig) -> Rig {
    let bus = Bus::open(BusOptions::new(&config.namespace, "door-test")).expect("bus");
    let sim = robotd_driver_sim::open(&config.robot).expect("the simulator");
    let safety = Hardware::policy(config, sim.drivers.model).expect("the policy");
    let calls = Calls::default();
    let control = safety.control().clone();
    let drivers = RobotDrivers {
        model: sim.drivers.model,
        arm: Arc::new(RecordingArm {
            inner: sim.drivers.arm.clone(),
            calls: calls.clone(),
            control: control.clone(),
        }),
        gripper: Arc::new(RecordingGripper {
            inner: sim.drivers.gripper.clone(),
            calls: calls.clone(),
            control,
        }),
        camera: sim.drivers.camera.clone(),
    };
    let hardware = Hardware::start_on(&bus, config, drivers, safety.clone(), |_| {
        observer_fn(|_: &SupervisionEvent| {})
    })
    .await
    .expect("hardware");
    Rig {
        bus,
        hardware,
        safety,
        calls,
        sim: sim.robot,
    }
}

/// The audit log's events (the `event` object of each line) of `config`'s log.
pub fn audit_events(config: &TestConfig) -> Vec<serde_json::Value> {
    std::fs::read_to_string(&config.safety.audit.path)
        .unwrap_or_default()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["event"].take())
        .collect()
}
