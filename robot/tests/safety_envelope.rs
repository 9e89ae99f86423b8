//! The motion policy against the simulator's ground truth.
//!
//! Thousands of random arm commands — inside the workspace, on the fence's edge, far outside,
//! NaN and infinite, huge — from every origin go through the same path as a bus request
//! (`admit_and_run`: admission, planning, the plan check) to the arm actor on the simulated
//! Ned2. A recording driver keeps every motion that reached it; each is then followed through
//! the simulator's own kinematics at a finer step than the policy samples, and every tool
//! position must lie inside the envelope. Every refusal must say why.

mod common;

use robotd_arm::{admit_and_run, ArmActor, ArmContext, ObservationPose};
use robotd_driver::{
    ArmDriver, ArmFlags, ArmMotion, Calibration, ClearCollision, DriverError, DriverFuture, Motion,
    MotionControl, Permit,
};
use robotd_kinematics::Kinematics;
use robotd_protocol::arm::{ArmCommand, ArmError, ArmReply, PathKind};
use robotd_protocol::geometry::{Pose, PoseDelta, RobotModel};
use robotd_protocol::safety::{Origin, OriginKind};
use robotd_runtime::supervision::Supervisor;
use robotd_safety::config::KeepOutBox;
use robotd_safety::{AuditLog, BodyDepth, Fence, Safety, SafetyConfig};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

/// An arm driver that records every motion it is asked to execute, then runs it on `inner`.
struct Recording {
    inner: Arc<dyn ArmDriver>,
    executed: Mutex<Vec<(Vec<f64>, Motion, f64)>>,
}

impl ArmDriver for Recording {
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
        let start = self.inner.joints().unwrap_or_default();
        let act = permit.act();
        self.executed
            .lock()
            .unwrap()
            .push((start, act.motion.clone(), act.speed_scale));
        self.inner.execute(permit, control)
    }
    fn calibrate(&self, permit: Permit<Calibration>) -> DriverFuture<'_, ()> {
        self.inner.calibrate(permit)
    }
    fn clear_collision(&self, permit: Permit<ClearCollision>) -> DriverFuture<'_, ()> {
        self.inner.clear_collision(permit)
    }
    fn halt(&self) -> Result<(), DriverError> {
        self.inner.halt()
    }
}

/// A small deterministic generator (xorshift64*), so a failure can be replayed from its seed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * self.unit()
    }
    fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[(self.next() % items.len() as u64) as usize]
    }
}

/// A value that is NaN, infinite or huge.
fn wild(rng: &mut Rng) -> f64 {
    rng.pick(&[
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        1e300,
        -1e12,
        5.0e3,
    ])
}

fn random_command(rng: &mut Rng, fence: &Fence) -> ArmCommand {
    let path = if rng.unit() < 0.5 {
        PathKind::Joint
    } else {
        PathKind::Linear
    };
    let down = |x, y, z, yaw| Pose::new(x, y, z, 0.0, std::f64::consts::FRAC_PI_2, yaw);
    match rng.next() % 100 {
        // Inside the fence or just around its edges.
        0..=34 => {
            let x = rng.range(fence.min.x - 0.03, fence.max.x + 0.03);
            let y = rng.range(fence.min.y - 0.03, fence.max.y + 0.03);
            let z = rng.range(fence.min.z - 0.03, 0.30);
            let yaw = rng.range(-1.5, 1.5);
            ArmCommand::MoveToPose {
                target: down(x, y, z, yaw),
                path,
            }
        }
        // Far outside.
        35..=49 => ArmCommand::MoveToPose {
            target: down(
                rng.range(-2.0, 2.0),
                rng.range(-2.0, 2.0),
                rng.range(-1.0, 2.0),
                0.0,
            ),
            path,
        },
        // NaN, infinite, huge.
        50..=54 => {
            let mut v = [0.25, 0.0, 0.1, 0.0, 1.57, 0.0];
            let i = (rng.next() % 6) as usize;
            v[i] = wild(rng);
            ArmCommand::MoveToPose {
                target: Pose::from_array(v),
                path,
            }
        }
        // Joint targets, within and beyond the limits.
        55..=74 => {
            let n = if rng.unit() < 0.95 {
                6
            } else {
                1 + (rng.next() % 8) as usize
            };
            let mut q: Vec<f64> = (0..n).map(|_| rng.range(-3.5, 3.5)).collect();
            if rng.unit() < 0.05 {
                q[0] = wild(rng);
            }
            ArmCommand::MoveJoints { positions_rad: q }
        }
        // Relative moves.
        75..=89 => {
            let mut d = PoseDelta::translation(
                rng.range(-0.2, 0.2),
                rng.range(-0.2, 0.2),
                rng.range(-0.2, 0.2),
            );
            if rng.unit() < 0.05 {
                d.dz_m = wild(rng);
            }
            ArmCommand::ShiftPose { delta: d }
        }
        90..=96 => ArmCommand::GoToObservationPose {
            workspace_id: rng.pick(&["niryo_ws", "gazebo_1", "nowhere"]).into(),
        },
        _ => ArmCommand::Calibrate,
    }
}

/// `fence` grown by `by` metres (the tolerance between the policy's samples).
fn grown(fence: &Fence, by: f64) -> Fence {
    let mut wide = fence.clone();
    wide.min.x -= by;
    wide.min.y -= by;
    wide.min.z -= by;
    wide.max.x += by;
    wide.max.y += by;
    wide.max.z += by;
    wide.max_reach_m += by;
    wide
}

/// Every joint position of `motion` from `start`, the driver's way (joint interpolation),
/// sampled every 0.004 rad of the fastest joint.
fn joint_samples(start: &[f64], motion: &Motion) -> Vec<Vec<f64>> {
    let targets: Vec<Vec<f64>> = match motion {
        Motion::Joints(q) => vec![q.clone()],
        Motion::JointPath(path) => path.clone(),
    };
    let mut out = Vec::new();
    let mut from = start.to_vec();
    for to in targets {
        let step = from
            .iter()
            .zip(&to)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let n = ((step / 0.004).ceil() as usize).max(1);
        for i in 0..=n {
            let t = i as f64 / n as f64;
            let q: Vec<f64> = from.iter().zip(&to).map(|(a, b)| a + (b - a) * t).collect();
            out.push(q);
        }
        from = to;
    }
    out
}

fn empty_scene() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("empty.toml"),
        "name = \"empty\"\nrobot = \"ned2\"\n",
    )
    .unwrap();
    dir
}

#[tokio::test(start_paused = true)]
async fn random_motions_from_every_origin_never_leave_the_envelope() {
    let per_origin: usize = std::env::var("ROBOTD_SAFETY_COMMANDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000 / OriginKind::ALL.len() + 1);
    let scene = empty_scene();
    let mut robot = common::default_sections().robot;
    robot.scene = Some(scene.path().join("empty.toml"));
    robot.control_rate_hz = 50;
    let sim = robotd_driver_sim::open(&robot).expect("the simulator");
    let kinematics = Kinematics::new(RobotModel::Ned2);
    let recording = Arc::new(Recording {
        inner: sim.drivers.arm.clone(),
        executed: Mutex::default(),
    });
    // A mast beside the base, over the way to the workspace's left side: the tool centre
    // never goes there (it is outside the fence), the elbow and forearm would.
    let config = SafetyConfig {
        motions_per_minute: 0,
        llm_motions_per_minute: 0,
        keep_out: vec![KeepOutBox {
            name: "mast".into(),
            min: [0.07, 0.07, 0.20],
            max: [0.11, 0.11, 0.50],
        }],
        ..SafetyConfig::default()
    };
    let control = MotionControl::default();
    let safety = Safety::new(
        config,
        kinematics.clone(),
        control.clone(),
        &robot.workspaces(),
        AuditLog::disabled(),
    );
    let context = ArmContext {
        driver: recording.clone(),
        kinematics: kinematics.clone(),
        control,
        observation_poses: robot
            .workspaces()
            .iter()
            .map(|w| ObservationPose {
                workspace_id: w.id.clone(),
                pose: Pose::from_array(w.observation_pose),
            })
            .collect(),
        safety: safety.clone(),
        shared: Default::default(),
    };
    let actor = Supervisor::new("arm")
        .spawn_actor::<ArmActor>(move || ArmActor::new(context.clone()))
        .await
        .unwrap();
    let fence = safety.fence().clone();
    let tolerance = grown(&fence, 0.002);
    let mut rng = Rng(0x5AFE_7E57_0000_0001);
    let mut outcomes: BTreeMap<String, usize> = BTreeMap::new();
    let mut ground_truth_outside = 0;
    for kind in OriginKind::ALL {
        let origin = Origin::new(kind).session("property");
        for _ in 0..per_origin {
            let command = random_command(&mut rng, &fence);
            let reply = admit_and_run(&actor, &safety, command.clone(), &origin)
                .await
                .expect("the arm actor answers");
            let key = match &reply {
                ArmReply::Error { error } => {
                    let text = error.to_string();
                    assert!(
                        text.len() > 20,
                        "a refusal without a reason: {error:?} for {command:?}"
                    );
                    match error {
                        ArmError::Refused { limit, .. } => format!("refused: {limit}"),
                        other => format!("error: {}", serde_json::to_value(other).unwrap()["kind"]),
                    }
                }
                _ => "done".to_owned(),
            };
            *outcomes.entry(key).or_default() += 1;
            // The simulator's own tool position, wherever the command left the arm.
            let q = sim.robot.joints();
            let p = kinematics.tool_pose(&q).unwrap().translation.vector;
            if tolerance.check(&p).is_err() {
                ground_truth_outside += 1;
            }
            if recording.flags().collision_detected {
                let cleared = admit_and_run(&actor, &safety, ArmCommand::ClearCollision, &origin)
                    .await
                    .expect("the arm actor answers");
                assert!(matches!(cleared, ArmReply::Ok { .. }), "{cleared:?}");
            }
        }
    }
    let executed = recording.executed.lock().unwrap().clone();
    let mut outside = Vec::new();
    let mut link_samples = 0;
    for (start, motion, scale) in &executed {
        assert!(*scale > 0.0 && *scale <= 1.0, "speed scale {scale}");
        for q in joint_samples(start, motion) {
            let p = kinematics.tool_pose(&q).unwrap().translation.vector;
            let body = kinematics.body(&q).unwrap();
            if let Err(v) = tolerance
                .check(&p)
                .and_then(|()| tolerance.check_body(&body, BodyDepth::default()))
            {
                outside.push(v.reason);
                break;
            }
            link_samples += body.len();
        }
    }
    let total = per_origin * OriginKind::ALL.len();
    eprintln!(
        "{total} commands, {} reached the driver ({link_samples} link boxes checked); outcomes: {outcomes:?}",
        executed.len()
    );
    assert_eq!(
        outside,
        Vec::<String>::new(),
        "motions that left the envelope"
    );
    assert_eq!(
        ground_truth_outside, 0,
        "the simulated tool ended outside the envelope"
    );
    // The test means something only if both kinds of outcome happened often.
    assert!(
        executed.len() > total / 10,
        "too few motions ran: {}",
        executed.len()
    );
    for limit in [
        "refused: fence",
        "refused: floor",
        "refused: joint_limit",
        "refused: keep_out",
    ] {
        assert!(
            outcomes.get(limit).copied().unwrap_or(0) > 0,
            "no '{limit}' in {outcomes:?}"
        );
    }
    actor.shutdown().await.unwrap();
}
