//! `robotd fake-widowx`: the simulator behind the WidowX's servo bus (DYNAMIXEL Protocol 2.0 on
//! a pseudo-terminal) and its camera (an MJPEG stream), for trying the `widowx` driver (and
//! dynamixel-sdk scripts) without an arm. The scene and the motion come from the usual
//! `[robot]` settings (`--set robot.scene=…`); the gripper's tick range from `[robot.widowx]`.
//! The fake servo bus itself is the `robotd-fake-widowx` crate (`fakes/widowx/`); the camera
//! stream is `robotd-driver-mjpeg`'s server.

use anyhow::{bail, Context, Result};
use clap::Args;
use robotd_config::{Config, RobotDriver};
use robotd_driver_sim::faults::FaultInjector;
use robotd_fake_widowx::FakeServoBus;
use robotd_runtime::bus::{Bus, BusOptions};
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

/// Options of `robotd fake-widowx`.
#[derive(Debug, Args)]
pub struct FakeWidowxArgs {
    /// Where to put the servo bus's device (a symlink to the pseudo-terminal), for
    /// `robot.widowx.device`.
    #[arg(long, default_value = "/tmp/robotd-fake-widowx/ttyDXL")]
    pub device: PathBuf,
    /// Address of the camera's MJPEG stream (IP:port; port 0 picks a free one).
    #[arg(long, default_value = "127.0.0.1:8090")]
    pub camera_listen: String,
    /// Also serve the simulator's ground truth (`sim/world`) on the bus namespace, so tests
    /// can check where every object really is.
    #[arg(long)]
    pub ground_truth: bool,
    /// Wrong on purpose: the camera sits this far from the configured mount, in its own
    /// optical frame: DX_MM,DY_MM,DZ_MM,DROLL_DEG,DPITCH_DEG,DYAW_DEG (`robotd commission`
    /// measures it).
    #[arg(long, value_name = "OFFSET")]
    pub mount_offset: Option<String>,
    /// Wrong on purpose: the gripper's real CLOSED,OPEN ticks, instead of the configured
    /// `robot.widowx.gripper_closed_ticks` and `gripper_open_ticks`.
    #[arg(long, value_name = "CLOSED,OPEN")]
    pub gripper_ticks: Option<String>,
    /// Wrong on purpose: the joints obey every goal this many milliseconds late, a stop
    /// included (an arm that keeps going after the e-stop).
    #[arg(long, value_name = "MS", default_value_t = 0)]
    pub stopping_lag_ms: u64,
}

/// Serves until Ctrl-C.
pub fn run(mut config: Config, args: FakeWidowxArgs) -> Result<()> {
    match config.robot.driver {
        RobotDriver::SimWidowx | RobotDriver::Widowx => {
            config.robot.driver = RobotDriver::SimWidowx
        }
        RobotDriver::SimNed2 if config.robot.scene.is_none() => {
            config.robot.driver = RobotDriver::SimWidowx
        }
        other => bail!("fake-widowx simulates a WidowX; robot.driver = {other:?} is another robot"),
    }
    if let Some(offset) = &args.mount_offset {
        let offset = crate::fake_wrong::parse_mount_offset(offset)?;
        crate::fake_wrong::apply_mount_offset(&mut config, &offset)?;
    }
    if let Some(ticks) = &args.gripper_ticks {
        let (closed, open) = crate::fake_wrong::parse_ticks(ticks)?;
        config.robot.widowx.gripper_closed_ticks = closed;
        config.robot.widowx.gripper_open_ticks = open;
    }
    if let Some(dir) = args.device.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    runtime.block_on(async move {
        let sim = robotd_driver_sim::open(&config.robot)?;
        let _ground_truth = if args.ground_truth {
            let bus = Bus::open(BusOptions::new(&config.bus.namespace, "fake-widowx"))?;
            let task = robotd_driver_sim::serve_ground_truth(&bus, sim.robot.clone())?;
            Some((bus, task))
        } else {
            None
        };
        let widowx = &config.robot.widowx;
        let fake = FakeServoBus::start(
            sim.robot.clone(),
            &args.device,
            (widowx.gripper_closed_ticks, widowx.gripper_open_ticks),
        )
        .with_context(|| format!("serving the servo bus at {}", args.device.display()))?;
        fake.set_stopping_lag(std::time::Duration::from_millis(args.stopping_lag_ms));
        let listen = args
            .camera_listen
            .parse()
            .with_context(|| format!("--camera-listen {}: not an IP:port", args.camera_listen))?;
        let camera = robotd_driver_mjpeg::serve(
            listen,
            Arc::new(
                sim.robot
                    .camera(FaultInjector::new("fake-widowx", Default::default())),
            ),
            config.robot.camera.fps,
        )
        .await
        .with_context(|| format!("serving the camera on {}", args.camera_listen))?;
        println!(
            "fake-widowx servos on {} camera {}",
            fake.path().display(),
            camera.url()
        );
        std::io::stdout().flush()?;
        tokio::signal::ctrl_c().await?;
        drop(fake);
        Ok(())
    })
}
