//! The simulated robot: one kinematic arm, its gripper and its wrist camera in one simulated
//! world, behind the same driver traits a real robot implements.
//!
//! [`SimRobot`] owns the shared state (joints, the [`World`] with its objects, the flags) and
//! hands out three drivers, [`SimArm`], [`SimGripper`] and [`SimCamera`], which the arm,
//! gripper and camera actors use exactly as they would use a real robot's drivers. Motions run
//! in time: a joint motion takes as long as the joint velocity limits allow (times
//! `time_scale`), advancing once per control tick; at every tick the tool is moved through the
//! world, which stops it at a collision, lets it push objects, and carries what it holds.
//! The camera renders what the world looks like from where the arm holds it.
//!
//! The world's ground truth is for the simulator and the tests only: perception sees pixels.

use crate::faults::FaultInjector;
use nalgebra::{Isometry3, Point3, Vector3};
use robotd_driver::{
    ArmDriver, ArmFlags, ArmMotion, Calibration, CameraDriver, CaptureInfo, ClearCollision, Close,
    DriverError, DriverFuture, GripperDriver, GripperStatus, Motion, MotionControl, Open, Permit,
    SetWidth,
};
use robotd_kinematics::Kinematics;
use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::envelope::unix_now_ns;
use robotd_protocol::geometry::RobotModel;
use robotd_render::{Disc, Intrinsics, RenderOptions, RenderScene, Renderer, Shape, Solid};
use robotd_sim::{GraspOutcome, ObjectShape, Scene, ToolState, World};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

/// Settings of a simulated robot.
#[derive(Debug, Clone)]
pub struct SimSettings {
    /// Simulated motion time relative to the real robot (1.0 = realistic).
    pub time_scale: f64,
    /// Length of one control tick in the robot's time: a motion is advanced once per tick of
    /// `control_period × time_scale` of real time (at least 1 ms), so a sped-up simulation
    /// takes the same steps through the world as a real-time one, only sooner.
    pub control_period: Duration,
    /// Camera sensor noise (0–255 units).
    pub noise_stddev: f64,
    /// Whether the camera applies lens distortion.
    pub lens_distortion: bool,
}

impl Default for SimSettings {
    fn default() -> Self {
        Self {
            time_scale: 1.0,
            control_period: Duration::from_millis(20),
            noise_stddev: 2.0,
            lens_distortion: false,
        }
    }
}

/// The shortest control tick of a sped-up simulation, real time.
const MIN_TICK: Duration = Duration::from_millis(1);

/// Time a simulated gripper takes to open or close fully, at time scale 1.
const GRIPPER_TRAVEL_TIME: Duration = Duration::from_millis(500);

/// The whole simulated robot state, behind one lock held only for short steps.
struct SimState {
    joints: Vec<f64>,
    world: World,
    collision: Option<String>,
    calibrated: bool,
    moving: bool,
}

/// A simulated arm with gripper and wrist camera in a simulated world.
#[derive(Clone)]
pub struct SimRobot {
    state: Arc<Mutex<SimState>>,
    kinematics: Kinematics,
    settings: SimSettings,
    /// Bumped by every halt; a running motion stops when it changes.
    halts: Arc<AtomicU64>,
}

impl std::fmt::Debug for SimRobot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimRobot")
            .field("model", &self.kinematics.model())
            .finish_non_exhaustive()
    }
}

impl SimRobot {
    /// A robot of `scene.robot` at its home posture in `scene`, gripper open.
    pub fn new(scene: &Scene, settings: SimSettings) -> Self {
        let kinematics = Kinematics::new(scene.robot);
        let joints = kinematics.home_joints();
        let mut world = World::new(scene);
        let opening = gripper_max_width(scene.robot);
        if let Ok(tcp) = kinematics.tool_pose(&joints) {
            world.set_tool(ToolState {
                tcp,
                opening_m: opening,
            });
        }
        Self {
            state: Arc::new(Mutex::new(SimState {
                joints,
                world,
                collision: None,
                calibrated: true,
                moving: false,
            })),
            kinematics,
            settings,
            halts: Arc::new(AtomicU64::new(0)),
        }
    }

    /// This robot with its wrist camera at `mount` (`[robot.camera.mount]`): the camera
    /// renders from there and reports that pose.
    pub fn with_camera_mount(mut self, mount: robotd_kinematics::CameraMount) -> Self {
        self.kinematics = self.kinematics.with_camera_mount(mount);
        self
    }

    /// The robot's kinematics.
    pub fn kinematics(&self) -> &Kinematics {
        &self.kinematics
    }

    /// Runs `f` on the world (ground truth: tests and benchmarks only).
    pub fn with_world<R>(&self, f: impl FnOnce(&mut World) -> R) -> R {
        f(&mut self.lock().world)
    }

    /// Current joint positions.
    pub fn joints(&self) -> Vec<f64> {
        self.lock().joints.clone()
    }

    /// Puts the arm at `joints` instantly (no motion, no physics): initialisation and tests.
    pub fn teleport(&self, joints: &[f64]) -> Result<(), DriverError> {
        self.kinematics
            .check_joints(joints)
            .map_err(|e| DriverError::OutOfRange(e.to_string()))?;
        let tcp = self
            .kinematics
            .tool_pose(joints)
            .map_err(|e| DriverError::OutOfRange(e.to_string()))?;
        let mut state = self.lock();
        state.joints = joints.to_vec();
        let opening = state.world.tool().opening_m;
        state.world.set_tool(ToolState {
            tcp,
            opening_m: opening,
        });
        Ok(())
    }

    /// Moves the arm to `q` in one step through the world, as a real arm's servos would
    /// (what holds is carried): `Err(Collision)` and nothing moved when the step runs into
    /// an object or the table. For fakes that serve the simulator behind a real robot's
    /// protocol, which move the arm as their servos report it (`robotd fake-widowx`).
    pub fn step_arm(&self, q: &[f64]) -> Result<(), DriverError> {
        self.step_to(q)
    }

    /// The arm driver of this robot.
    pub fn arm(&self, faults: FaultInjector) -> SimArm {
        SimArm {
            robot: self.clone(),
            faults: Arc::new(faults),
        }
    }

    /// The gripper driver of this robot.
    pub fn gripper(&self, faults: FaultInjector) -> SimGripper {
        SimGripper {
            robot: self.clone(),
            faults: Arc::new(faults),
        }
    }

    /// The wrist camera driver of this robot.
    pub fn camera(&self, faults: FaultInjector) -> SimCamera {
        let intrinsics = Intrinsics::ned2();
        let renderer = Renderer::new(
            intrinsics,
            RenderOptions {
                noise_stddev: self.settings.noise_stddev,
                lens_distortion: self.settings.lens_distortion,
                seed: 1,
                shading: true,
            },
        );
        SimCamera {
            robot: self.clone(),
            renderer: Mutex::new(renderer),
            faults: Arc::new(faults),
        }
    }

    fn lock(&self) -> MutexGuard<'_, SimState> {
        // A panic while holding the lock (an injected fault) leaves consistent data: every
        // step writes whole values. Keep going with it.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Scaled real duration of a nominal motion time.
    fn scaled(&self, nominal_s: f64) -> Duration {
        Duration::from_secs_f64((nominal_s * self.settings.time_scale).max(0.0))
    }

    /// Each joint's velocity limit, rad/s.
    fn joint_velocity_limits(&self) -> Vec<f64> {
        self.kinematics
            .joint_limits()
            .iter()
            .map(|l| l.max_velocity_rad_s)
            .collect()
    }

    /// Moves the arm to `q` for one control tick: the tool goes through the world.
    fn step_to(&self, q: &[f64]) -> Result<(), DriverError> {
        let tcp = self
            .kinematics
            .tool_pose(q)
            .map_err(|e| DriverError::OutOfRange(e.to_string()))?;
        let mut state = self.lock();
        let opening = state.world.tool().opening_m;
        let (_reached, outcome) = state.world.move_tool(&ToolState {
            tcp,
            opening_m: opening,
        });
        if let Some(what) = outcome.collision {
            tracing::warn!(with = %what, tcp = ?tcp.translation.vector, "simulated collision: the arm stopped");
            state.collision = Some(what.clone());
            state.moving = false;
            return Err(DriverError::Collision { what });
        }
        state.joints = q.to_vec();
        Ok(())
    }

    /// Runs a path of joint waypoints in time, checking `control` and halts every tick.
    async fn run_path(
        &self,
        waypoints: Vec<Vec<f64>>,
        smooth: bool,
        speed_scale: f64,
        control: &MotionControl,
    ) -> Result<(), DriverError> {
        robotd_driver::check_speed_scale(speed_scale)?;
        let halts_at_start = self.halts.load(Ordering::SeqCst);
        {
            let mut state = self.lock();
            if let Some(what) = &state.collision {
                let _ = what;
                return Err(DriverError::CollisionPending);
            }
            if !state.calibrated {
                return Err(DriverError::NotCalibrated);
            }
            state.moving = true;
        }
        let result = self
            .run_path_inner(waypoints, smooth, speed_scale, control, halts_at_start)
            .await;
        self.lock().moving = false;
        result
    }

    /// Follows `waypoints` in time ([`robotd_driver::TimedPath`]): each tick the tool moves
    /// through every waypoint passed since the last tick (the world sees it at each), then to
    /// where the path is now.
    async fn run_path_inner(
        &self,
        waypoints: Vec<Vec<f64>>,
        smooth: bool,
        speed_scale: f64,
        control: &MotionControl,
        halts_at_start: u64,
    ) -> Result<(), DriverError> {
        let tick = self
            .scaled(self.settings.control_period.as_secs_f64())
            .max(MIN_TICK);
        let mut ticker = tokio::time::interval(tick);
        ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let velocities = self.joint_velocity_limits();
        let time_scale = self.settings.time_scale;
        let mut path =
            robotd_driver::TimedPath::new(self.joints(), waypoints, smooth, move |a, b| {
                robotd_driver::nominal_travel_time_s(a, b, &velocities) / speed_scale * time_scale
            });
        let started = tokio::time::Instant::now();
        loop {
            ticker.tick().await;
            control.check()?;
            if self.halts.load(Ordering::SeqCst) != halts_at_start {
                return Err(DriverError::Stopped {
                    reason: "the arm was halted".into(),
                });
            }
            let sample = path.sample(started.elapsed().as_secs_f64());
            for waypoint in &sample.passed {
                self.step_to(waypoint)?;
            }
            if sample.finished {
                return Ok(());
            }
            self.step_to(&sample.now)?;
        }
    }
}

/// Widest opening of the simulated gripper of `model`, metres: the real gripper's
/// (`robotd_driver::hardware`, where the real drivers read it).
pub use robotd_driver::hardware::gripper_max_width;

/// The simulated arm driver.
#[derive(Debug, Clone)]
pub struct SimArm {
    robot: SimRobot,
    faults: Arc<FaultInjector>,
}

impl SimArm {
    /// The robot this arm belongs to.
    pub fn robot(&self) -> &SimRobot {
        &self.robot
    }

    /// The simulated robot's own controller running `motion` at `speed_scale`: what a fake
    /// robot does with a motion command it received over its wire (`fakes/`). robotd's actors
    /// never call it: they hold the arm as an `ArmDriver`, whose
    /// [`execute`](ArmDriver::execute) needs the policy's permit. Like
    /// [`SimRobot::teleport`], this is the simulated world's side, not a driver's.
    pub async fn controller_move(
        &self,
        motion: Motion,
        speed_scale: f64,
        control: &MotionControl,
    ) -> Result<(), DriverError> {
        self.faults.maybe_fail("move").await;
        match motion {
            Motion::Joints(target) => {
                self.robot
                    .run_path(vec![target], true, speed_scale, control)
                    .await
            }
            Motion::JointPath(path) => self.robot.run_path(path, false, speed_scale, control).await,
        }
    }

    /// The simulated robot's own calibration (see [`SimArm::controller_move`]).
    pub async fn controller_calibrate(&self) -> Result<(), DriverError> {
        self.faults.maybe_fail("calibrate").await;
        tokio::time::sleep(self.robot.scaled(0.5)).await;
        self.robot.lock().calibrated = true;
        Ok(())
    }

    /// The simulated robot clearing its collision flag (see [`SimArm::controller_move`]).
    pub fn controller_clear_collision(&self) {
        self.robot.lock().collision = None;
    }
}

impl ArmDriver for SimArm {
    fn model(&self) -> RobotModel {
        self.robot.kinematics.model()
    }

    fn joints(&self) -> Result<Vec<f64>, DriverError> {
        Ok(self.robot.joints())
    }

    fn flags(&self) -> ArmFlags {
        let state = self.robot.lock();
        ArmFlags {
            moving: state.moving,
            collision_detected: state.collision.is_some(),
            calibrated: state.calibrated,
        }
    }

    fn execute<'a>(
        &'a self,
        permit: Permit<ArmMotion>,
        control: &'a MotionControl,
    ) -> DriverFuture<'a, ()> {
        let ArmMotion {
            motion,
            speed_scale,
        } = permit.into_act();
        Box::pin(async move { self.controller_move(motion, speed_scale, control).await })
    }

    fn calibrate(&self, _permit: Permit<Calibration>) -> DriverFuture<'_, ()> {
        Box::pin(self.controller_calibrate())
    }

    fn clear_collision(&self, _permit: Permit<ClearCollision>) -> DriverFuture<'_, ()> {
        self.controller_clear_collision();
        Box::pin(async { Ok(()) })
    }

    fn halt(&self) -> Result<(), DriverError> {
        self.robot.halts.fetch_add(1, Ordering::SeqCst);
        self.robot.lock().moving = false;
        Ok(())
    }
}

/// The simulated gripper driver.
#[derive(Debug, Clone)]
pub struct SimGripper {
    robot: SimRobot,
    faults: Arc<FaultInjector>,
}

impl SimGripper {
    fn status_now(&self) -> GripperStatus {
        let state = self.robot.lock();
        GripperStatus {
            holding: state.world.held().is_some(),
            width_m: state.world.gripper_width_m(),
        }
    }

    /// The simulated gripper opening fully by itself: what a fake robot does with the command
    /// it received (see [`SimArm::controller_move`]); robotd's actors use
    /// [`GripperDriver::open`], which needs the policy's permit.
    pub async fn controller_open(&self) -> Result<GripperStatus, DriverError> {
        self.faults.maybe_fail("open").await;
        let max = self.max_width_m();
        let from = self.status_now().width_m;
        self.travel(from, max).await;
        self.robot.lock().world.open_gripper(max);
        Ok(self.status_now())
    }

    /// The simulated gripper closing by itself (see [`SimGripper::controller_open`]).
    pub async fn controller_close(&self) -> Result<GripperStatus, DriverError> {
        self.faults.maybe_fail("close").await;
        let from = self.status_now().width_m;
        let outcome = self.robot.lock().world.close_gripper();
        let to = self.status_now().width_m;
        self.travel(from, to).await;
        if let GraspOutcome::Empty { reason } = &outcome {
            tracing::debug!(%reason, "the simulated gripper closed on nothing");
        }
        Ok(self.status_now())
    }

    /// The simulated gripper moving to `width_m` by itself (see
    /// [`SimGripper::controller_open`]).
    pub async fn controller_set_width(&self, width_m: f64) -> Result<GripperStatus, DriverError> {
        self.faults.maybe_fail("set_width").await;
        let max = self.max_width_m();
        if !(0.0..=max).contains(&width_m) {
            return Err(DriverError::OutOfRange(format!(
                "gripper width {width_m:.3} m is outside 0 … {max:.3} m"
            )));
        }
        let from = self.status_now().width_m;
        self.travel(from, width_m).await;
        let mut state = self.robot.lock();
        if width_m >= state.world.gripper_width_m() {
            state.world.open_gripper(width_m);
        } else {
            // Closing part-way: a close that stops at the object (or fully closed) is the
            // only closing motion the simulator models.
            let _ = state.world.close_gripper();
        }
        drop(state);
        Ok(self.status_now())
    }

    async fn travel(&self, from_m: f64, to_m: f64) {
        let max = gripper_max_width(self.robot.kinematics.model());
        let fraction = ((to_m - from_m).abs() / max).clamp(0.0, 1.0);
        let nominal = GRIPPER_TRAVEL_TIME.as_secs_f64() * fraction;
        tokio::time::sleep(self.robot.scaled(nominal)).await;
    }
}

impl GripperDriver for SimGripper {
    fn max_width_m(&self) -> f64 {
        gripper_max_width(self.robot.kinematics.model())
    }

    fn open(&self, _permit: Permit<Open>) -> DriverFuture<'_, GripperStatus> {
        Box::pin(self.controller_open())
    }

    fn close(&self, _permit: Permit<Close>) -> DriverFuture<'_, GripperStatus> {
        Box::pin(self.controller_close())
    }

    fn set_width(&self, permit: Permit<SetWidth>) -> DriverFuture<'_, GripperStatus> {
        Box::pin(self.controller_set_width(permit.act().width_m))
    }

    fn status(&self) -> Result<GripperStatus, DriverError> {
        Ok(self.status_now())
    }
}

/// The simulated wrist camera: renders the world from the camera's real pose.
pub struct SimCamera {
    robot: SimRobot,
    renderer: Mutex<Renderer>,
    faults: Arc<FaultInjector>,
}

impl std::fmt::Debug for SimCamera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimCamera").finish_non_exhaustive()
    }
}

impl SimCamera {
    /// Where the camera is for joints `q` (the model's wrist camera, see
    /// [`Kinematics::camera_pose`]).
    fn camera_pose(&self, q: &[f64]) -> Result<Isometry3<f64>, DriverError> {
        self.robot
            .kinematics
            .camera_pose(q)
            .ok_or_else(|| DriverError::Hardware(format!("no camera pose for joints {q:?}")))
    }

    /// What the camera can see: sheets, markers and objects of the world.
    fn render_scene(world: &World) -> RenderScene {
        let quads = world
            .sheet_quads()
            .into_iter()
            .map(|quad| (quad, [245, 245, 242]))
            .collect();
        let mut discs = Vec::new();
        for marker in world.markers() {
            // Concentric rings: black, white, black, and a white or black centre.
            let r = marker.outer_radius_m;
            let lift = |z: f64| Point3::new(marker.center.x, marker.center.y, z);
            let z = marker.center.z;
            discs.push(Disc {
                center: lift(z),
                radius_m: r,
                color: [20, 20, 20],
            });
            discs.push(Disc {
                center: lift(z),
                radius_m: r * 0.7,
                color: [245, 245, 242],
            });
            discs.push(Disc {
                center: lift(z),
                radius_m: r * 0.45,
                color: [20, 20, 20],
            });
            if marker.white_centre {
                discs.push(Disc {
                    center: lift(z),
                    radius_m: r * 0.2,
                    color: [245, 245, 242],
                });
            }
        }
        let solids = world.objects().iter().map(solid_of).collect();
        RenderScene {
            background: [118, 96, 72],
            table_z_m: 0.0,
            quads,
            discs,
            solids,
        }
    }
}

impl CameraDriver for SimCamera {
    fn size(&self) -> (u32, u32) {
        let renderer = self.renderer.lock().unwrap_or_else(|p| p.into_inner());
        (renderer.intrinsics().width, renderer.intrinsics().height)
    }

    fn intrinsics(&self) -> CameraIntrinsics {
        let renderer = self.renderer.lock().unwrap_or_else(|p| p.into_inner());
        let mut intrinsics = CameraIntrinsics::from(*renderer.intrinsics());
        // Without simulated lens distortion the image is an ideal pinhole image: say so, so a
        // detector does not undistort what was never distorted.
        if !renderer.options().lens_distortion {
            intrinsics.distortion = [0.0; 5];
        }
        intrinsics
    }

    fn capture_into(&self, out: &mut [u8]) -> Result<CaptureInfo, DriverError> {
        self.faults.maybe_fail_blocking("capture");
        // The capture time is taken before the world is read, never after: a thread preempted
        // between the two would otherwise stamp a picture of an arm still moving with a time
        // after it stopped, and that frame would pass for a steady view.
        let timestamp_unix_ns = unix_now_ns();
        let (scene, q) = {
            let state = self.robot.lock();
            (Self::render_scene(&state.world), state.joints.clone())
        };
        let camera_pose = self.camera_pose(&q)?;
        let mut renderer = self.renderer.lock().unwrap_or_else(|p| p.into_inner());
        renderer
            .render_into(&scene, &camera_pose, out)
            .map_err(|e| DriverError::Hardware(format!("rendering the simulated camera: {e}")))?;
        Ok(CaptureInfo {
            camera_pose,
            timestamp_unix_ns,
        })
    }
}

/// How the camera draws a simulated object: a box or an upright cylinder where it stands.
pub fn solid_of(object: &robotd_sim::SimObject) -> Solid {
    Solid {
        shape: match object.spec.shape {
            ObjectShape::Box {
                length_x_m,
                width_y_m,
                height_z_m,
            } => Shape::Box {
                size_m: Vector3::new(length_x_m, width_y_m, height_z_m),
            },
            ObjectShape::Cylinder {
                diameter_m,
                height_m,
            } => Shape::Cylinder {
                radius_m: diameter_m / 2.0,
                height_m,
            },
        },
        pose: object.pose,
        color: object.spec.color,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_simulated_camera_is_the_ned2_camera_the_real_drivers_assume() {
        assert_eq!(
            CameraIntrinsics::from(Intrinsics::ned2()),
            robotd_driver::hardware::ned2_camera_intrinsics()
        );
    }
}
