//! `robotd bench safety`: what the motion policy adds to every motion command, beside the
//! planning the arm actor does for the same command anyway.
//!
//! For random tool-down targets over the workspace, timed in the same loop: planning
//! (inverse kinematics, and for straight paths the dense waypoints) — the bare command's own
//! cost — then the policy's admission (e-stop, rate limit, audit record) with the audit log
//! off and on (writing to a temporary file), and the plan check (geofence at every sampled
//! tool position and every link's box, joint margins, speed caps). Nothing moves: the
//! simulated arm stays at rest. Then e-stops: how fast the halt reaches the simulated arm's
//! driver, and the stopping time and distance of each driver ([`super::stopping`]).

use super::Latency;
use anyhow::{Context, Result};
use robotd_arm::{plan, ArmContext};
use robotd_driver::MotionControl;
use robotd_kinematics::Kinematics;
use robotd_protocol::arm::PathKind;
use robotd_protocol::geometry::{Pose, RobotModel};
use robotd_protocol::safety::{Origin, OriginKind};
use robotd_safety::{Safety, SafetyConfig};
use serde::Serialize;
use std::time::{Duration, Instant};

/// Everything `robotd bench safety` measures (µs per motion command).
#[derive(Debug, Clone, Serialize)]
pub struct SafetyFigures {
    /// Planning a joint move (IK), the bare cost.
    pub plan_joint: Latency,
    /// Planning a straight-line move (dense waypoints).
    pub plan_linear: Latency,
    /// Admission with the audit log off.
    pub admit: Latency,
    /// Admission with the audit log writing to a file.
    pub admit_audited: Latency,
    /// Plan check of a joint move.
    pub check_joint: Latency,
    /// Plan check of a straight-line move.
    pub check_linear: Latency,
    /// Motion commands per variant.
    pub commands: usize,
    /// E-stop published on `safety/estop` (the path of every entry point) until the simulated
    /// arm's joints last changed, over `estop_trials` stops of a running motion.
    pub estop_to_standstill: Latency,
    /// Worst of the same, µs.
    pub estop_to_standstill_max_us: f64,
    /// E-stop published until the arm's driver was told to halt (bus delivery and the
    /// e-stop watcher), over the same stops.
    pub estop_to_halt: Latency,
    /// Worst of the same, µs.
    pub estop_to_halt_max_us: f64,
    /// One control tick of the simulated arm, µs (the target).
    pub control_tick_us: f64,
    /// E-stops measured.
    pub estop_trials: usize,
    /// Stopping time and distance per driver (see [`super::stopping`]).
    pub stopping: Vec<super::stopping::Stopping>,
}

impl SafetyFigures {
    /// The human-readable table.
    pub fn table(&self) -> String {
        let row =
            |name: &str, l: &Latency| format!("{name:<44}{:>8.1} {:>8.1}\n", l.p50_us, l.p99_us);
        let mut out = format!(
            "{:<44}{:>8} {:>8}   ({} commands each; target: policy ≤ 50 µs added)\n",
            "per motion command", "p50 µs", "p99 µs", self.commands
        );
        out += &row("bare: plan a joint move (IK)", &self.plan_joint);
        out += &row("bare: plan a straight move (waypoints)", &self.plan_linear);
        out += &row("policy: admission, audit off", &self.admit);
        out += &row("policy: admission, audit to a file", &self.admit_audited);
        out += &row("policy: check a joint move", &self.check_joint);
        out += &row("policy: check a straight move", &self.check_linear);
        out += &format!(
            "\n{:<44}{:>8.0} {:>8.0}   (max {:.0} µs; {} stops of a moving arm)\n",
            "e-stop on the bus → driver told to halt",
            self.estop_to_halt.p50_us,
            self.estop_to_halt.p99_us,
            self.estop_to_halt_max_us,
            self.estop_trials
        );
        out += &format!(
            "{:<44}{:>8.0} {:>8.0}   (max {:.0} µs; one control tick = {:.0} µs)\n",
            "e-stop on the bus → last joint change",
            self.estop_to_standstill.p50_us,
            self.estop_to_standstill.p99_us,
            self.estop_to_standstill_max_us,
            self.control_tick_us
        );
        out += &super::stopping::table(&self.stopping);
        out
    }
}

/// Runs the measurement over `commands` random targets, and `stops` stops per driver for the
/// stopping figures.
pub fn run(commands: usize, stops: usize) -> Result<SafetyFigures> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    let robot = robotd_config::Config::default().robot;
    let sim = robotd_driver_sim::open(&robot).context("the simulator")?;
    let kinematics = Kinematics::new(RobotModel::Ned2);
    let control = MotionControl::default();
    let config = SafetyConfig {
        motions_per_minute: 0,
        llm_motions_per_minute: 0,
        ..SafetyConfig::default()
    };
    let dir = tempfile::tempdir().context("a temporary directory for the audit log")?;
    let mut audited = config.clone();
    audited.audit.path = dir.path().join("audit.jsonl").display().to_string();
    let workspaces = robot.workspaces();
    let make = |config: &SafetyConfig| -> Result<Safety> {
        let audit = Safety::open_audit(config, dir.path())?;
        Ok(Safety::new(
            config.clone(),
            kinematics.clone(),
            control.clone(),
            &workspaces,
            audit,
        ))
    };
    let mut quiet = config;
    quiet.audit.enabled = false;
    let safety = make(&quiet)?;
    let safety_audited = make(&audited)?;
    let context = ArmContext {
        driver: sim.drivers.arm.clone(),
        kinematics: kinematics.clone(),
        control: control.clone(),
        observation_poses: Vec::new(),
        safety: safety.clone(),
        shared: Default::default(),
    };
    let start = sim.robot.joints();
    let origin = Origin::new(OriginKind::Mcp).session("bench");
    let mut seed: u64 = 0x0BE7_C4AF;
    let mut unit = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut samples: [Vec<Duration>; 6] = Default::default();
    let mut done = 0;
    let mut tries = 0;
    while done < commands && tries < commands * 20 {
        tries += 1;
        let target = Pose::new(
            0.17 + 0.16 * unit(),
            -0.08 + 0.16 * unit(),
            0.03 + 0.15 * unit(),
            0.0,
            std::f64::consts::FRAC_PI_2,
            0.0,
        );
        let t = Instant::now();
        let Ok(joint) = plan(&context, target, PathKind::Joint) else {
            continue;
        };
        let plan_joint = t.elapsed();
        let t = Instant::now();
        let Ok(linear) = plan(&context, target, PathKind::Linear) else {
            continue;
        };
        let plan_linear = t.elapsed();
        let arguments = serde_json::json!({"kind": "move_to_pose", "target": target});
        let t = Instant::now();
        let admission = runtime
            .block_on(safety.admit(&origin, "arm", "move_to_pose", arguments.clone()))
            .map_err(|v| anyhow::anyhow!("{v}"))?;
        let admit = t.elapsed();
        let t = Instant::now();
        let audited_admission = runtime
            .block_on(safety_audited.admit(&origin, "arm", "move_to_pose", arguments))
            .map_err(|v| anyhow::anyhow!("{v}"))?;
        let admit_audited = t.elapsed();
        let t = Instant::now();
        let check_joint = safety.check_arm_motion(&admission, &start, &joint);
        let check_joint_time = t.elapsed();
        let t = Instant::now();
        let check_linear = safety.check_arm_motion(&admission, &start, &linear);
        let check_linear_time = t.elapsed();
        if check_joint.is_err() || check_linear.is_err() {
            continue;
        }
        safety_audited.finish(&audited_admission, robotd_safety::Outcome::Done);
        for (i, d) in [
            plan_joint,
            plan_linear,
            admit,
            admit_audited,
            check_joint_time,
            check_linear_time,
        ]
        .into_iter()
        .enumerate()
        {
            samples[i].push(d);
        }
        done += 1;
    }
    if done == 0 {
        anyhow::bail!("no target inside the workspace could be planned and checked");
    }
    safety_audited
        .audit()
        .flush(Duration::from_secs(10))
        .context("flushing the benchmark's audit log")?;
    // The e-stop measurement polls the simulator from one worker while the arm runs on the
    // others.
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(3)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    let (estops, control_tick) = runtime.block_on(estop_latencies(30))?;
    let stopping = runtime.block_on(super::stopping::measure_all(stops))?;
    let (mut standstill, mut halt): (Vec<Duration>, Vec<Duration>) = estops.into_iter().unzip();
    let max_us = |d: &[Duration]| d.iter().map(|d| d.as_secs_f64() * 1e6).fold(0.0, f64::max);
    let estop_to_standstill_max_us = max_us(&standstill);
    let estop_to_halt_max_us = max_us(&halt);
    let [a, b, c, d, e, f] = &mut samples;
    Ok(SafetyFigures {
        estop_trials: standstill.len(),
        estop_to_standstill: Latency::of(&mut standstill),
        estop_to_standstill_max_us,
        estop_to_halt: Latency::of(&mut halt),
        estop_to_halt_max_us,
        control_tick_us: control_tick.as_secs_f64() * 1e6,
        plan_joint: Latency::of(a),
        plan_linear: Latency::of(b),
        admit: Latency::of(c),
        admit_audited: Latency::of(d),
        check_joint: Latency::of(e),
        check_linear: Latency::of(f),
        commands: done,
        stopping,
    })
}

/// Stops up to `trials` running motions of the simulated arm with an e-stop on the bus; for
/// each, the time from the publish to the joints' last change and to the driver's halt. Also
/// returns the control tick.
async fn estop_latencies(trials: usize) -> Result<(Vec<(Duration, Duration)>, Duration)> {
    use robotd_protocol::arm::ArmCommand;
    use robotd_protocol::health::{EStopRelease, EmergencyStop};
    use robotd_topics::{ARM_COMMAND, SAFETY_ESTOP, SAFETY_RELEASE};
    let mut config = robotd_config::Config::default();
    config.bus.namespace = format!("bench-estop-{}", std::process::id());
    config.robot.time_scale = 1.0;
    config.safety.audit.enabled = false;
    let bus = robotd_runtime::bus::Bus::open(robotd_runtime::bus::BusOptions::new(
        &config.bus.namespace,
        "robotd-bench",
    ))?;
    let hardware = robotd_robot::Hardware::start(&bus, &config.robot_sections(), |_| {
        robotd_runtime::supervision::observer_fn(
            |_: &robotd_runtime::supervision::SupervisionEvent| {},
        )
    })
    .await?;
    let sim = hardware
        .sim
        .clone()
        .context("the benchmark needs the simulated arm")?;
    let estop = bus.publisher(&SAFETY_ESTOP)?;
    let release = bus.client(&SAFETY_RELEASE)?;
    let down = |x, y| Pose::new(x, y, 0.05, 0.0, std::f64::consts::FRAC_PI_2, 0.0);
    let targets = [down(0.33, 0.08), down(0.18, -0.08)];
    let mut out = Vec::with_capacity(trials);
    for i in 0..trials {
        let arm = bus.client(&ARM_COMMAND)?;
        let target = targets[i % 2];
        let motion = tokio::spawn(async move {
            arm.request(&ArmCommand::move_to(target), Duration::from_secs(30))
                .await
        });
        // Let it get going: stop it somewhere along the way.
        let before = sim.joints();
        let deadline = Instant::now() + Duration::from_secs(10);
        while sim.joints() == before && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
        tokio::time::sleep(Duration::from_millis(100 + 13 * (i as u64 % 7))).await;
        // Only a stop of an arm in motion counts: it must have moved within the last 2 ticks.
        let probe = sim.joints();
        tokio::time::sleep(2 * config.robot.control_period()).await;
        if sim.joints() == probe {
            let _ = motion.await;
            continue;
        }
        let sent = Instant::now();
        estop.publish(&EmergencyStop {
            engaged: true,
            reason: "robotd bench safety".into(),
            source: "bench".into(),
        })?;
        let mut last = sim.joints();
        let mut last_change = sent;
        let mut halted = None;
        while sent.elapsed() < Duration::from_millis(300) {
            let now = sim.joints();
            if now != last {
                last_change = Instant::now();
                last = now;
            }
            if halted.is_none() && !hardware.arm_context.driver.flags().moving {
                halted = Some(sent.elapsed());
            }
            std::thread::sleep(Duration::from_micros(100));
        }
        out.push((last_change - sent, halted.unwrap_or(Duration::MAX)));
        let _ = motion.await;
        // Released the deliberate way, by a request to the policy (an `engaged: false` on
        // `safety/estop` releases nothing); it answers once released.
        release
            .request(
                &EStopRelease {
                    confirm: "release".into(),
                    by: "robotd bench safety: next trial".into(),
                    only_if_reason: None,
                },
                Duration::from_secs(5),
            )
            .await?;
    }
    let tick = config.robot.control_period();
    hardware.shutdown().await;
    Ok((out, tick))
}
