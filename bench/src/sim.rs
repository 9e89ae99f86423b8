//! `robotd bench sim`: the simulator's costs — rendering the wrist camera, inverse
//! kinematics over the workspace, and a frame from the camera to a subscriber on the bus.
//!
//! Baselines in the same run: filling a frame buffer with one value (the floor of any
//! renderer writing 921,600 bytes) beside the render time, and the render time alone beside
//! the render-and-publish time.

use super::Latency;
use anyhow::{Context, Result};
use robotd_driver::CameraDriver;
use robotd_driver_sim::faults::FaultInjector;
use robotd_driver_sim::{SimCamera, SimRobot, SimSettings};
use robotd_kinematics::{pose_to_isometry, Kinematics};
use robotd_protocol::geometry::{Pose, RobotModel};
use robotd_runtime::bus::{Bus, BusOptions, FRAME_BYTES};
use robotd_sim::Scene;
use robotd_topics::CAMERA_FRAMES;
use serde::Serialize;
use std::time::{Duration, Instant};

/// Everything `robotd bench sim` measures.
#[derive(Debug, Clone, Serialize)]
pub struct SimFigures {
    /// Median time to render one 640×480 frame of the default scene, ms.
    pub render_ms_p50: f64,
    /// 99th percentile render time, ms.
    pub render_ms_p99: f64,
    /// Median time to fill a 921,600-byte buffer with one value (floor), ms.
    pub fill_ms_p50: f64,
    /// Share of tool-down targets over the workspaces that IK solved.
    pub ik_solve_rate: f64,
    /// IK targets tried.
    pub ik_targets: usize,
    /// Median IK solve time (unseeded), µs.
    pub ik_us_p50: f64,
    /// 99th percentile IK solve time, µs.
    pub ik_us_p99: f64,
    /// Median time from the start of a capture to the frame arriving at a subscriber, µs
    /// (render into shared memory + send + receive, one process).
    pub frame_to_bus_us_p50: f64,
    /// 99th percentile of the same, µs.
    pub frame_to_bus_us_p99: f64,
    /// Frames rendered per variant.
    pub frames: usize,
}

impl SimFigures {
    /// The human-readable table.
    pub fn table(&self) -> String {
        format!(
            "measure                              value            target\n\
             render 640x480 p50 / p99             {:>6.2} / {:>6.2} ms  p50 ≤ 10 ms\n\
             fill 921,600 B (floor) p50           {:>6.3} ms\n\
             IK solve rate ({} targets)          {:>6.1} %          ≥ 99 %\n\
             IK p50 / p99                         {:>6.1} / {:>6.1} µs  p50 ≤ 200 µs\n\
             frame → bus subscriber p50 / p99     {:>6.0} / {:>6.0} µs\n",
            self.render_ms_p50,
            self.render_ms_p99,
            self.fill_ms_p50,
            self.ik_targets,
            self.ik_solve_rate * 100.0,
            self.ik_us_p50,
            self.ik_us_p99,
            self.frame_to_bus_us_p50,
            self.frame_to_bus_us_p99,
        )
    }
}

fn ms(latency: Latency) -> (f64, f64) {
    (latency.p50_us / 1000.0, latency.p99_us / 1000.0)
}

/// The simulated Ned2's wrist camera at the default scene's observation pose (the robot
/// must outlive the camera's use).
pub(crate) fn observation_camera() -> Result<(SimRobot, SimCamera)> {
    let scene = Scene::default_ned2();
    let robot = SimRobot::new(
        &scene,
        SimSettings {
            time_scale: 0.0,
            ..SimSettings::default()
        },
    );
    let kinematics = Kinematics::new(RobotModel::Ned2);
    let observation = scene
        .workspaces
        .first()
        .context("the default scene has no workspace")?;
    let joints = kinematics
        .inverse(
            &pose_to_isometry(&Pose::from_array(observation.observation_pose)),
            None,
        )
        .map_err(|e| anyhow::anyhow!("observation pose: {e}"))?;
    robot
        .teleport(&joints)
        .map_err(|e| anyhow::anyhow!("observation pose: {e}"))?;
    let camera = robot.camera(FaultInjector::none("camera"));
    Ok((robot, camera))
}

/// Runs the measurements with `frames` frames per variant.
pub fn run(frames: usize) -> Result<SimFigures> {
    let (_robot, camera) = observation_camera()?;
    let scene = Scene::default_ned2();
    let kinematics = Kinematics::new(RobotModel::Ned2);

    // Render, interleaved with the fill floor.
    let mut buffer = vec![0u8; FRAME_BYTES];
    let mut render = Vec::with_capacity(frames);
    let mut fill = Vec::with_capacity(frames);
    for i in 0..frames + 10 {
        let t = Instant::now();
        buffer.fill((i % 251) as u8);
        let filled = t.elapsed();
        std::hint::black_box(&buffer);
        let t = Instant::now();
        camera
            .capture_into(&mut buffer)
            .map_err(|e| anyhow::anyhow!("render: {e}"))?;
        let rendered = t.elapsed();
        if i >= 10 {
            fill.push(filled);
            render.push(rendered);
        }
    }
    let (render_ms_p50, render_ms_p99) = ms(Latency::of(&mut render));
    let (fill_ms_p50, _) = ms(Latency::of(&mut fill));

    // IK over a grid of tool-down targets of every workspace of the scene.
    let mut ik_times = Vec::new();
    let mut solved = 0usize;
    let mut tried = 0usize;
    for workspace in &scene.workspaces {
        let [x_far, y_left] = workspace.upper_left;
        let [x_near, y_right] = workspace.lower_right;
        for ix in 0..8 {
            for iy in 0..8 {
                for iz in 0..4 {
                    for yaw in [0.0, 0.8, -0.8] {
                        let x = x_near + (x_far - x_near) * ix as f64 / 7.0;
                        let y = y_right + (y_left - y_right) * iy as f64 / 7.0;
                        let z = 0.01 + 0.03 * iz as f64;
                        let target = pose_to_isometry(&Pose::new(
                            x,
                            y,
                            z,
                            0.0,
                            std::f64::consts::FRAC_PI_2,
                            yaw,
                        ));
                        let t = Instant::now();
                        let result = kinematics.inverse(&target, None);
                        ik_times.push(t.elapsed());
                        tried += 1;
                        solved += usize::from(result.is_ok());
                    }
                }
            }
        }
    }
    let ik = Latency::of(&mut ik_times);

    // A frame from the camera to a subscriber through the bus (one process). Bus ports
    // register their wake-up events with tokio, so they live inside a runtime.
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let _in_runtime = runtime.enter();
    let namespace = format!("bench-sim-{}", std::process::id());
    let bus = Bus::open(BusOptions::new(&namespace, "bench-sim"))?;
    let publisher = bus.frame_publisher(&CAMERA_FRAMES)?;
    let mut subscriber = bus.frame_subscriber(&CAMERA_FRAMES)?;
    let mut to_bus: Vec<Duration> = Vec::with_capacity(frames);
    for i in 0..frames + 10 {
        let t = Instant::now();
        let mut frame = publisher.loan()?;
        camera
            .capture_into(&mut frame.pixels_mut()[..])
            .map_err(|e| anyhow::anyhow!("render: {e}"))?;
        frame.header_mut().frame_id = i as u64;
        frame.send()?;
        let received = loop {
            if let Some(sample) = subscriber.try_recv()? {
                break sample;
            }
            std::thread::yield_now();
        };
        let elapsed = t.elapsed();
        if received.header().frame_id != i as u64 {
            anyhow::bail!("frame {i} arrived as {}", received.header().frame_id);
        }
        if i >= 10 {
            to_bus.push(elapsed);
        }
    }
    let to_bus = Latency::of(&mut to_bus);

    Ok(SimFigures {
        render_ms_p50,
        render_ms_p99,
        fill_ms_p50,
        ik_solve_rate: solved as f64 / tried.max(1) as f64,
        ik_targets: tried,
        ik_us_p50: ik.p50_us,
        ik_us_p99: ik.p99_us,
        frame_to_bus_us_p50: to_bus.p50_us,
        frame_to_bus_us_p99: to_bus.p99_us,
        frames,
    })
}
