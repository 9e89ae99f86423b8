//! `robotd fake-niryo`: the simulator behind the Niryo Ned2's TCP protocol, for trying the
//! `niryo` driver (and pyniryo scripts) without a robot. The scene and the motion time come
//! from the usual `[robot]` settings (`--set robot.scene=…`, `--set robot.time_scale=…`). The
//! fake itself is the `robotd-fake-niryo` crate (`fakes/niryo/`); this is its command.

use anyhow::{bail, Context, Result};
use clap::Args;
use robotd_config::{Config, RobotDriver};
use robotd_fake_niryo::{FakeFaults, FakeNiryo};
use robotd_runtime::bus::{Bus, BusOptions};
use std::io::Write;

/// Options of `robotd fake-niryo`.
#[derive(Debug, Args)]
pub struct FakeNiryoArgs {
    /// Address to listen on (IP:port; port 0 picks a free one, printed on stdout).
    #[arg(long, default_value = "127.0.0.1:40001")]
    pub listen: String,
    /// Start uncalibrated, as a robot just switched on (moves are ignored until CALIBRATE).
    #[arg(long)]
    pub needs_calibration: bool,
    /// Fault: close the connection when the N-th command arrives (the command still runs).
    #[arg(long, value_name = "N")]
    pub drop_at: Option<u64>,
    /// Fault: answer the N-th command with garbage.
    #[arg(long, value_name = "N")]
    pub garbage_at: Option<u64>,
    /// Fault: never answer the N-th command.
    #[arg(long, value_name = "N")]
    pub silent_at: Option<u64>,
    /// Count only commands of this name for --drop-at, --garbage-at and --silent-at (e.g.
    /// MOVE_JOINTS).
    #[arg(long, value_name = "COMMAND")]
    pub only: Option<String>,
    /// Also serve the simulator's ground truth (`sim/world`) on the bus namespace, so tests
    /// can check where every object really is.
    #[arg(long)]
    pub ground_truth: bool,
    /// Fault: close every connection at once.
    #[arg(long)]
    pub refuse_connections: bool,
    /// Wrong on purpose: the camera sits this far from the configured mount, in its own
    /// optical frame: DX_MM,DY_MM,DZ_MM,DROLL_DEG,DPITCH_DEG,DYAW_DEG (`robotd commission`
    /// measures it).
    #[arg(long, value_name = "OFFSET")]
    pub mount_offset: Option<String>,
    /// Send images already undistorted, as Ned2 software from 5.8.0 does (the intrinsics still
    /// report the lens's distortion).
    #[arg(long)]
    pub rectified: bool,
    /// Wrong on purpose: every motion starts this many milliseconds after its command arrived,
    /// so a motion sent just before the e-stop still runs (the Ned2 has no stop command).
    #[arg(long, value_name = "MS", default_value_t = 0)]
    pub stopping_lag_ms: u64,
    /// The tool the robot says is mounted (GET_CURRENT_TOOL_ID): NONE, GRIPPER_1 … GRIPPER_4,
    /// ELECTROMAGNET_1, VACUUM_PUMP_1, VACUUM_PUMP_2. The simulated gripper still grips.
    #[arg(long, value_name = "TOOL", default_value = "GRIPPER_1")]
    pub tool: String,
}

/// Serves until Ctrl-C.
pub fn run(mut config: Config, args: FakeNiryoArgs) -> Result<()> {
    match config.robot.driver {
        RobotDriver::SimNed2 | RobotDriver::Niryo => config.robot.driver = RobotDriver::SimNed2,
        other => bail!("fake-niryo simulates a Ned2; robot.driver = {other:?} is another robot"),
    }
    // A real lens: the images carry the Ned2's distortion, as GET_CAMERA_INTRINSICS says,
    // unless the robot rectifies them.
    config.robot.camera.lens_distortion = !args.rectified;
    if let Some(offset) = &args.mount_offset {
        let offset = crate::fake_wrong::parse_mount_offset(offset)?;
        crate::fake_wrong::apply_mount_offset(&mut config, &offset)?;
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    runtime.block_on(async move {
        let sim = robotd_driver_sim::open(&config.robot)?;
        let _ground_truth = if args.ground_truth {
            let bus = Bus::open(BusOptions::new(&config.bus.namespace, "fake-niryo"))?;
            let task = robotd_driver_sim::serve_ground_truth(&bus, sim.robot.clone())?;
            Some((bus, task))
        } else {
            None
        };
        let fake = FakeNiryo::new(
            sim.robot,
            FakeFaults {
                refuse_connections: args.refuse_connections,
                drop_at: args.drop_at,
                garbage_at: args.garbage_at,
                silent_at: args.silent_at,
                needs_calibration: args.needs_calibration,
                ignore_moves: false,
                only: args.only.clone(),
            },
        );
        fake.set_stopping_lag(std::time::Duration::from_millis(args.stopping_lag_ms));
        fake.set_tool(&args.tool).map_err(anyhow::Error::msg)?;
        let listener = tokio::net::TcpListener::bind(&args.listen)
            .await
            .with_context(|| format!("listening on {}", args.listen))?;
        let address = listener.local_addr()?;
        println!("fake-niryo listening on {address}");
        std::io::stdout().flush()?;
        tokio::select! {
            () = fake.serve(listener) => {}
            _ = tokio::signal::ctrl_c() => {}
        }
        Ok(())
    })
}
