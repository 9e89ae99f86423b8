//! Issue 39, "one door": random command streams from every origin, over the real bus, to the
//! arm and gripper actors on the simulator behind drivers that record every actuator call
//! (motion, calibration, clear-collision, gripper open, close and width).
//!
//! The streams come in bursts, each from every origin kind at once (MCP, the agent, a bare bus
//! client, Redis, the CLI, HTTP, robotd itself), some while the e-stop is engaged — engaged
//! from a random source, with a replayed `engaged: false` (what `robotd replay` of an old
//! recording, or a mirroring client, would publish) thrown in that must release nothing —
//! and released only through the policy's `safety/release`. Then:
//!
//! - every call that reached a driver carries a permit whose motion number the audit log
//!   shows as admitted: 0 commands without admission;
//! - no motion reached a driver while the e-stop was engaged: 0 during an engaged e-stop
//!   (clearing the collision flag, which moves nothing, is allowed then);
//! - every motion command sent during an engaged burst was answered with the e-stop;
//! - every motion that reached the arm's driver, followed from where it started every 0.004
//!   rad, kept the tool centre in the fence and every link's box above the table, below the
//!   ceiling and out of the keep-out boxes: 0 link samples outside.

mod common;

use common::{audit_events, fresh_config, rig};
use robotd_protocol::arm::{ArmCommand, ArmError, ArmReply, PathKind};
use robotd_protocol::geometry::{Pose, PoseDelta};
use robotd_protocol::gripper::{GripperCommand, GripperError, GripperReply};
use robotd_protocol::health::{EStopRelease, EmergencyStop};
use robotd_protocol::safety::{Origin, OriginKind};
use robotd_runtime::origin::with_origin;
use robotd_topics::{ARM_COMMAND, GRIPPER_COMMAND, SAFETY_ESTOP, SAFETY_RELEASE};
use std::collections::BTreeMap;
use std::f64::consts::FRAC_PI_2;
use std::time::{Duration, Instant};

const TIMEOUT: Duration = Duration::from_secs(30);

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
}

/// One command of a stream: to the arm or to the gripper.
#[derive(Debug, Clone)]
enum Command {
    Arm(ArmCommand),
    Gripper(GripperCommand),
}

impl Command {
    fn moves(&self) -> bool {
        match self {
            Command::Arm(c) => c.moves_arm(),
            Command::Gripper(c) => !matches!(c, GripperCommand::GetState),
        }
    }
}

fn random_command(rng: &mut Rng) -> Command {
    let down = |x, y, z| Pose::new(x, y, z, 0.0, FRAC_PI_2, 0.0);
    match rng.next() % 12 {
        0..=2 => Command::Arm(ArmCommand::MoveToPose {
            target: down(
                rng.range(0.15, 0.32),
                rng.range(-0.12, 0.12),
                rng.range(-0.05, 0.25),
            ),
            path: if rng.unit() < 0.5 {
                PathKind::Joint
            } else {
                PathKind::Linear
            },
        }),
        3 => Command::Arm(ArmCommand::ShiftPose {
            delta: PoseDelta {
                dz_m: rng.range(-0.05, 0.05),
                ..PoseDelta::default()
            },
        }),
        4 => Command::Arm(ArmCommand::GoToObservationPose {
            workspace_id: "niryo_ws".into(),
        }),
        5 => Command::Arm(ArmCommand::Calibrate),
        6 => Command::Arm(ArmCommand::ClearCollision),
        7 => Command::Arm(ArmCommand::GetPose),
        8 => Command::Gripper(GripperCommand::Open),
        9 => Command::Gripper(GripperCommand::Close),
        10 => Command::Gripper(GripperCommand::SetWidth {
            width_m: rng.range(0.0, 0.04),
        }),
        _ => Command::Gripper(GripperCommand::GetState),
    }
}

/// Whether a reply says the e-stop refused it.
fn estopped(reply: &Result<Reply, String>) -> bool {
    matches!(
        reply,
        Ok(Reply::Arm(ArmReply::Error {
            error: ArmError::EStopped { .. },
        })) | Ok(Reply::Gripper(GripperReply::Error {
            error: GripperError::EStopped { .. },
        }))
    )
}

#[derive(Debug)]
enum Reply {
    Arm(ArmReply),
    Gripper(GripperReply),
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn random_streams_from_every_origin_reach_a_driver_only_admitted_and_never_during_an_estop() {
    let bursts: usize = std::env::var("ROBOTD_DOOR_BURSTS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(24);
    let dir = tempfile::tempdir().unwrap();
    let mut config = fresh_config(0.02);
    config.safety.audit.enabled = true;
    config.safety.audit.path = dir.path().join("audit.jsonl").display().to_string();
    config.safety.motions_per_minute = 0;
    config.safety.llm_motions_per_minute = 0;
    let rig = rig(&config).await;
    let control = rig.safety.control().clone();
    let estops = rig.bus.publisher(&SAFETY_ESTOP).unwrap();
    let release = rig.bus.client(&SAFETY_RELEASE).unwrap();
    let mut rng = Rng(0xD00_0039_5AFE);
    let mut outcomes: BTreeMap<&str, usize> = BTreeMap::new();
    let mut estopped_motions = 0;

    for burst in 0..bursts {
        let engaged = burst % 3 == 1 || rng.unit() < 0.25;
        if engaged {
            let sources = ["mcp", "http", "cli", "dashboard", "supervisor"];
            estops
                .publish(&EmergencyStop {
                    engaged: true,
                    reason: format!("burst {burst}"),
                    source: sources[(rng.next() % 5) as usize].into(),
                })
                .unwrap();
            let waited = Instant::now();
            while !control.estop_engaged() {
                assert!(waited.elapsed() < TIMEOUT, "the e-stop did not engage");
                tokio::task::yield_now().await;
            }
            // A replayed or mirrored release: ignored.
            estops
                .publish(&EmergencyStop {
                    engaged: false,
                    reason: "replayed from a recording".into(),
                    source: "replay".into(),
                })
                .unwrap();
        }
        let mut streams = Vec::new();
        for kind in OriginKind::ALL {
            let commands: Vec<Command> = (0..1 + rng.next() % 3)
                .map(|_| random_command(&mut rng))
                .collect();
            let origin = Origin::new(kind).session(format!("burst-{burst}"));
            let arm = rig.bus.client(&ARM_COMMAND).unwrap();
            let gripper = rig.bus.client(&GRIPPER_COMMAND).unwrap();
            streams.push(tokio::spawn(with_origin(origin, async move {
                let mut replies = Vec::new();
                for command in commands {
                    let reply = match &command {
                        Command::Arm(c) => arm
                            .request(c, TIMEOUT)
                            .await
                            .map(Reply::Arm)
                            .map_err(|e| e.to_string()),
                        Command::Gripper(c) => gripper
                            .request(c, TIMEOUT)
                            .await
                            .map(Reply::Gripper)
                            .map_err(|e| e.to_string()),
                    };
                    replies.push((command, reply));
                }
                replies
            })));
        }
        for stream in streams {
            for (command, reply) in stream.await.unwrap() {
                let key = match &reply {
                    Ok(Reply::Arm(ArmReply::Error { .. }))
                    | Ok(Reply::Gripper(GripperReply::Error { .. })) => "error",
                    Ok(_) => "ok",
                    Err(_) => "bus error",
                };
                *outcomes.entry(key).or_default() += 1;
                assert!(reply.is_ok(), "{command:?}: {reply:?}");
                let clear = matches!(command, Command::Arm(ArmCommand::ClearCollision));
                if engaged && command.moves() && !clear {
                    assert!(
                        estopped(&reply),
                        "a motion during the e-stop was not refused by it: {command:?} → {reply:?}"
                    );
                    estopped_motions += 1;
                }
            }
        }
        if engaged {
            assert!(control.estop_engaged(), "something released the e-stop");
            with_origin(Origin::new(OriginKind::Cli), async {
                release
                    .request(
                        &EStopRelease {
                            confirm: "release".into(),
                            by: "the test".into(),
                            only_if_reason: None,
                        },
                        TIMEOUT,
                    )
                    .await
                    .unwrap()
            })
            .await;
            assert!(!control.estop_engaged());
        }
    }

    rig.safety.audit().flush(Duration::from_secs(10)).unwrap();
    let events = audit_events(&config);
    let admitted: std::collections::HashSet<u64> = events
        .iter()
        .filter(|e| e["event"] == "admission" && e["decision"] == "admitted")
        .filter_map(|e| e["motion"].as_u64())
        .collect();
    let calls = rig.calls.all();
    let unadmitted: Vec<_> = calls
        .iter()
        .filter(|c| !admitted.contains(&c.motion_id))
        .collect();
    // Clearing the collision flag moves nothing and is allowed during an e-stop (admitted and
    // audited all the same); every other call is a motion.
    let during_estop: Vec<_> = calls
        .iter()
        .filter(|c| c.estop_engaged && c.method != "clear_collision")
        .collect();
    let mut per_method: BTreeMap<&str, usize> = BTreeMap::new();
    for call in &calls {
        *per_method.entry(call.method).or_default() += 1;
    }
    eprintln!(
        "{bursts} bursts; replies {outcomes:?}; {} driver calls {per_method:?}; {estopped_motions} motions refused by the e-stop",
        calls.len()
    );
    assert_eq!(
        unadmitted,
        Vec::<&common::Call>::new(),
        "calls without admission"
    );
    assert_eq!(
        during_estop,
        Vec::<&common::Call>::new(),
        "calls during an e-stop"
    );
    // The test means something only if the drivers were really called, every kind of call,
    // and the e-stop really refused motions.
    for method in [
        "execute",
        "calibrate",
        "clear_collision",
        "open",
        "close",
        "set_width",
    ] {
        assert!(
            per_method.get(method).copied().unwrap_or(0) > 0,
            "no '{method}' reached the driver: {per_method:?}"
        );
    }
    assert!(estopped_motions > 5, "{estopped_motions}");
    let (samples, outside) = link_samples_outside(&rig.safety, &calls);
    eprintln!("{samples} link boxes checked along the motions that ran");
    assert_eq!(
        outside,
        Vec::<String>::new(),
        "link samples outside the fence"
    );
    assert!(samples > 1000, "{samples}");
    rig.hardware.shutdown().await;
}

/// Every motion of `calls` followed every 0.004 rad of its fastest joint: how many link boxes
/// were checked, and what was outside the fence (2 mm tolerance between the policy's samples).
fn link_samples_outside(
    safety: &robotd_safety::Safety,
    calls: &[common::Call],
) -> (usize, Vec<String>) {
    let kinematics = safety.kinematics();
    let mut fence = safety.fence().clone();
    fence.min -= nalgebra::Vector3::repeat(0.002);
    fence.max += nalgebra::Vector3::repeat(0.002);
    fence.max_reach_m += 0.002;
    let (mut samples, mut outside) = (0, Vec::new());
    for (start, motion) in calls.iter().filter_map(|c| c.motion.as_ref()) {
        let targets = match motion {
            robotd_safety::Motion::Joints(q) => vec![q.clone()],
            robotd_safety::Motion::JointPath(path) => path.clone(),
        };
        let mut from = start.clone();
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
                let tcp = kinematics.tool_pose(&q).unwrap().translation.vector;
                let body = kinematics.body(&q).unwrap();
                samples += body.len();
                if let Err(v) = fence
                    .check(&tcp)
                    .and_then(|()| fence.check_body(&body, robotd_safety::BodyDepth::default()))
                {
                    outside.push(v.reason);
                }
            }
            from = to;
        }
    }
    (samples, outside)
}
