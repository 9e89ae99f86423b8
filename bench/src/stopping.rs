//! Stopping time and distance per driver, the way ISO 10218 asks a robot's to be stated: from
//! the e-stop to standstill, at the tool and per joint, for a motion at full capped speed.
//!
//! Each driver runs behind the real actors and motion policy (`robotd_robot::Hardware`), as in
//! the service: the simulator itself; the Ned2 driver talking TCP to `robotd fake-niryo`; the
//! WidowX driver talking DYNAMIXEL Protocol 2.0 over a pseudo-terminal to `robotd
//! fake-widowx`. The fakes are backed by a simulated arm, which is the ground truth: its joints
//! are read every 0.5 ms, independently of what the driver reports.
//!
//! A trial swings the tool across the first workspace (operator caps: the origin is the CLI),
//! waits until it has covered 40 % of the way — near its peak speed — and publishes an e-stop
//! on `safety/estop`, the path of every entry point. Standstill is the last change of the
//! simulated joints; the figures are the time to it, the tool's travel after the e-stop, and
//! each joint's. The Ned2 has no stop command: the driver stops between segments of
//! `robot.niryo.segment_rad`, so its figures are the ones that choose that length; the fake
//! Ned2 is measured at three segment lengths, each with the time of one whole swing without
//! a stop (shorter segments stop sooner, and every segment starts and stops).

use anyhow::{bail, Context, Result};
use robotd_config::Config;
use robotd_driver::RobotDriver;
use robotd_driver_sim::SimRobot;
use robotd_kinematics::Kinematics;
use robotd_protocol::arm::ArmCommand;
use robotd_protocol::geometry::Pose;
use robotd_protocol::health::{EStopRelease, EmergencyStop};
use robotd_protocol::safety::{Origin, OriginKind};
use robotd_topics::{ARM_COMMAND, SAFETY_ESTOP, SAFETY_RELEASE};
use serde::Serialize;
use std::time::{Duration, Instant};

/// One driver's stopping figures.
#[derive(Debug, Clone, Serialize)]
pub struct Stopping {
    /// `sim`, `fake Ned2 (TCP)`, `fake WidowX (DYNAMIXEL)`.
    pub driver: String,
    /// Stops measured.
    pub trials: usize,
    /// Tool speed when the e-stop was published, m/s (p50 of the trials).
    pub speed_at_stop_m_s: f64,
    /// E-stop → standstill, ms (median).
    pub time_ms_p50: f64,
    /// Worst stopping time, ms.
    pub time_ms_max: f64,
    /// Tool travel after the e-stop, mm (p50).
    pub distance_mm_p50: f64,
    /// Worst tool travel, mm.
    pub distance_mm_max: f64,
    /// Worst travel of each joint after the e-stop, radians, base to wrist.
    pub joint_rad_max: Vec<f64>,
    /// The Ned2 driver's segment length, radians (other drivers: none).
    pub segment_rad: Option<f64>,
    /// One whole swing without a stop, seconds: what shorter segments cost in speed.
    pub swing_s: f64,
}

/// Segment lengths the fake Ned2 is measured with, radians: the default and one either side.
pub const NED2_SEGMENTS_RAD: [f64; 3] = [0.1, 0.2, 0.4];

/// The three drivers, `trials` stops each.
pub async fn measure_all(trials: usize) -> Result<Vec<Stopping>> {
    let mut out = Vec::new();
    out.push(measure_sim(trials).await.context("stopping: simulator")?);
    for segment_rad in NED2_SEGMENTS_RAD {
        out.push(
            measure_fake_ned2(trials, segment_rad)
                .await
                .context("stopping: fake Ned2")?,
        );
    }
    out.push(
        measure_fake_widowx(trials)
            .await
            .context("stopping: fake WidowX")?,
    );
    Ok(out)
}

fn base_config(namespace: &str) -> Config {
    let mut config = Config::default();
    config.bus.namespace = format!("bench-stop-{namespace}-{}", std::process::id());
    config.robot.time_scale = 1.0;
    config.safety.audit.enabled = false;
    config.safety.motions_per_minute = 0;
    config
}

async fn measure_sim(trials: usize) -> Result<Stopping> {
    let config = base_config("sim");
    run_trials("sim", &config, None, trials).await
}

async fn measure_fake_ned2(trials: usize, segment_rad: f64) -> Result<Stopping> {
    let mut config = base_config(&format!("ned2-{}", (segment_rad * 1000.0) as u32));
    config.robot.niryo.segment_rad = segment_rad;
    let sim = robotd_driver_sim::open(&config.robot)?;
    let fake = robotd_fake_niryo::FakeNiryo::new(
        sim.robot.clone(),
        robotd_fake_niryo::FakeFaults::default(),
    );
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
    config.robot.driver = RobotDriver::Niryo;
    config.robot.host = Some("127.0.0.1".into());
    config.robot.port = listener.local_addr()?.port();
    let served = tokio::spawn(fake.serve(listener));
    let result = run_trials("fake Ned2 (TCP)", &config, Some(sim.robot), trials).await;
    served.abort();
    let mut figures = result?;
    figures.segment_rad = Some(segment_rad);
    Ok(figures)
}

async fn measure_fake_widowx(trials: usize) -> Result<Stopping> {
    let mut config = base_config("widowx");
    config.robot.driver = RobotDriver::SimWidowx;
    let sim = robotd_driver_sim::open(&config.robot)?;
    let dir = tempfile::tempdir().context("a temporary folder for the pty")?;
    let link = dir.path().join("ttyDXL");
    let widowx = &config.robot.widowx;
    let _fake = robotd_fake_widowx::FakeServoBus::start(
        sim.robot.clone(),
        &link,
        (widowx.gripper_closed_ticks, widowx.gripper_open_ticks),
    )
    .context("starting the fake servo bus")?;
    config.robot.driver = RobotDriver::Widowx;
    config.robot.widowx.device = link;
    run_trials("fake WidowX (DYNAMIXEL)", &config, Some(sim.robot), trials).await
}

/// Starts the actors on `config`'s driver and stops `trials` swings; `truth` is the simulated
/// arm behind a fake (the simulator driver's own arm when `None`).
async fn run_trials(
    label: &str,
    config: &Config,
    truth: Option<SimRobot>,
    trials: usize,
) -> Result<Stopping> {
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
    let truth = match truth.or_else(|| hardware.sim.clone()) {
        Some(truth) => truth,
        None => bail!("no simulated arm to measure against"),
    };
    let kinematics = Kinematics::new(config.robot.model());
    let workspace = config
        .robot
        .workspaces()
        .into_iter()
        .next()
        .context("no workspace configured")?;
    let [x, _] = workspace.centre();
    let (left, right) = (workspace.upper_left[1], workspace.lower_right[1]);
    let down = |y: f64| Pose::new(x, y, 0.10, 0.0, std::f64::consts::FRAC_PI_2, 0.0);
    let ends = [down(left), down(right)];
    let tool = |q: &[f64]| -> Result<[f64; 3]> {
        let p = kinematics.tool_pose(q)?.translation.vector;
        Ok([p.x, p.y, p.z])
    };
    let estop = bus.publisher(&SAFETY_ESTOP)?;
    let release = bus.client(&SAFETY_RELEASE)?;
    let origin = Origin::new(OriginKind::Cli).session("robotd bench safety");
    let go = |target: Pose| -> Result<_> {
        let arm = bus.client(&ARM_COMMAND)?;
        let origin = origin.clone();
        Ok(tokio::spawn(robotd_runtime::origin::with_origin(
            origin,
            async move {
                arm.request(&ArmCommand::move_to(target), Duration::from_secs(30))
                    .await
            },
        )))
    };
    // To the first end, then one whole swing there and back, timed one way.
    go(ends[0])?
        .await?
        .context("moving to the start of the swing")?;
    let started = Instant::now();
    go(ends[1])?.await?.context("a whole swing")?;
    let swing_s = started.elapsed().as_secs_f64();
    go(ends[0])?.await?.context("a whole swing back")?;
    let (mut times, mut distances, mut speeds) = (Vec::new(), Vec::new(), Vec::new());
    let mut joint_max = vec![0.0_f64; kinematics.joint_count()];
    for i in 0..trials {
        let target = ends[(i + 1) % 2];
        let from = tool(&truth.joints())?;
        let goal = tool(&kinematics.inverse(&robotd_kinematics::pose_to_isometry(&target), None)?)?;
        let motion = go(target)?;
        // Sampled every 0.5 ms: the way covered, and the recent speed.
        let mut history: Vec<(Instant, [f64; 3])> = Vec::new();
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            let p = tool(&truth.joints())?;
            history.push((Instant::now(), p));
            if distance(p, from) >= 0.4 * distance(goal, from) {
                break;
            }
            if Instant::now() > deadline {
                bail!("{label}: the arm did not get going within 10 s");
            }
            std::thread::sleep(Duration::from_micros(500));
        }
        let q_at_stop = truth.joints();
        let sent = Instant::now();
        estop.publish(&EmergencyStop {
            engaged: true,
            reason: "robotd bench safety: stopping distance".into(),
            source: "bench".into(),
        })?;
        let p_at_stop = tool(&q_at_stop)?;
        let speed = history
            .iter()
            .rev()
            .find(|(t, _)| sent.duration_since(*t) >= Duration::from_millis(20))
            .map(|(t, p)| distance(p_at_stop, *p) / sent.duration_since(*t).as_secs_f64())
            .unwrap_or(f64::NAN);
        let (mut last, mut last_change) = (q_at_stop.clone(), sent);
        // Standstill: no change for 600 ms (longer than any Ned2 segment at the caps).
        while last_change.elapsed() < Duration::from_millis(600)
            && sent.elapsed() < Duration::from_secs(5)
        {
            let now = truth.joints();
            if now != last {
                last_change = Instant::now();
                last = now;
            }
            std::thread::sleep(Duration::from_micros(500));
        }
        if sent.elapsed() >= Duration::from_secs(5) {
            bail!("{label}: the arm was still moving 5 s after the e-stop");
        }
        times.push(last_change - sent);
        distances.push(distance(tool(&last)?, p_at_stop));
        speeds.push(speed);
        for (max, (a, b)) in joint_max.iter_mut().zip(q_at_stop.iter().zip(&last)) {
            *max = max.max((a - b).abs());
        }
        let _ = motion.await;
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
        // Finish the swing, so that the next trial starts from an end.
        go(target)?.await?.context("finishing the swing")?;
    }
    hardware.shutdown().await;
    let median = |values: &mut Vec<f64>| -> f64 {
        values.sort_by(f64::total_cmp);
        values.get(values.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let mut times_ms: Vec<f64> = times.iter().map(|d| d.as_secs_f64() * 1e3).collect();
    let mut distances_mm: Vec<f64> = distances.iter().map(|d| d * 1e3).collect();
    let time_ms_max = times_ms.iter().copied().fold(0.0, f64::max);
    let distance_mm_max = distances_mm.iter().copied().fold(0.0, f64::max);
    Ok(Stopping {
        driver: label.into(),
        trials,
        speed_at_stop_m_s: median(&mut speeds),
        time_ms_p50: median(&mut times_ms),
        time_ms_max,
        distance_mm_p50: median(&mut distances_mm),
        distance_mm_max,
        joint_rad_max: joint_max,
        segment_rad: None,
        swing_s,
    })
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    a.iter()
        .zip(&b)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        .sqrt()
}

/// The rows of the stopping table.
pub fn table(stops: &[Stopping]) -> String {
    let mut out = format!(
        "\n{:<26}{:>7} {:>9} {:>16} {:>18} {:>8}   {}\n",
        "stopping (e-stop → still)",
        "trials",
        "speed m/s",
        "time ms p50/max",
        "tool mm p50/max",
        "swing s",
        "worst joint travel, rad (base → wrist)"
    );
    for s in stops {
        let joints: Vec<String> = s.joint_rad_max.iter().map(|j| format!("{j:.3}")).collect();
        out += &format!(
            "{:<26}{:>7} {:>9.2} {:>7.0} / {:>6.0} {:>8.1} / {:>7.1} {:>8.2}   [{}]{}\n",
            s.driver,
            s.trials,
            s.speed_at_stop_m_s,
            s.time_ms_p50,
            s.time_ms_max,
            s.distance_mm_p50,
            s.distance_mm_max,
            s.swing_s,
            joints.join(", "),
            s.segment_rad
                .map(|r| format!(" (segments of {r} rad)"))
                .unwrap_or_default()
        );
    }
    out
}
