//! The `robotd bench …` command line: one subcommand per benchmark and its options (the
//! benchmarks themselves are the sibling modules; `main.rs` only dispatches).

use clap::{Args, Subcommand};

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Round trips and frame throughput through the bus, beside raw iceoryx2.
    Bus(BenchBusArgs),
    /// The simulator: camera rendering, inverse kinematics, camera frame to the bus.
    Sim(BenchSimArgs),
    /// Perception: detector speed on one core, accuracy on random simulated scenes, and a
    /// camera frame to objects in the workspace model through the bus.
    Perception(BenchPerceptionArgs),
    /// MCP latency over SSE and streamable HTTP, calls/s with 8 and 64 clients, the
    /// service's memory (starts its own `robotd serve`).
    Mcp(BenchMcpArgs),
    /// Camera frames to Redis (JPEG q85, XADD) beside the bus's own frame rate, and the
    /// running Redis edge (starts its own redis-server unless --redis names one).
    Redis(BenchRedisArgs),
    /// What the motion policy adds to a motion command, beside planning the same command.
    Safety(BenchSafetyArgs),
    /// Round trips of a Rust client to a running robotd's system/ping (the Rust side of
    /// scripts/bench/python_bus.py).
    Ping(BenchPingArgs),
    /// The service for N minutes under a realistic mix (MCP clients coming and going, motions,
    /// the agent, Redis down and up, actor faults and kills), sampled every 5 s; exit 1 when
    /// memory, descriptors or threads grow, a fault is not recovered, a call is lost or runs
    /// twice, or the robot stays stuck.
    Soak(BenchSoakArgs),
    /// A long seeded random session of skill calls on the simulator (stacks, pushes, places
    /// near every edge and at the free-space centre), the tools' view of the table checked
    /// against the simulator's ground truth: phantoms, misnamed objects, stuck stacks, and the
    /// share of placements at the answered free-space centre accepted (issue 43).
    Table(BenchTableArgs),
    /// JPEG encoding of a 640×480 camera frame: robotd's encoder beside the `image` crate's,
    /// and a copy of the frame as the floor.
    Jpeg(BenchJpegArgs),
    /// The niryo driver against the fake Ned2 on loopback: a command round trip beside a raw
    /// TCP echo of the same bytes, camera images through TCP and decoding.
    Niryo(BenchNiryoArgs),
    /// The widowx driver against the fake servo bus on a pty: a sync read of the nine servos
    /// beside a raw pty echo of the same bytes, the 100 Hz control loop, a servo fault's
    /// recovery.
    Widowx(BenchWidowxArgs),
}

#[derive(Debug, Args)]
pub struct BenchWidowxArgs {
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Round trips per variant.
    #[arg(long, default_value_t = 2000)]
    pub round_trips: usize,
}

#[derive(Debug, Args)]
pub struct BenchNiryoArgs {
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Round trips per variant.
    #[arg(long, default_value_t = 2000)]
    pub round_trips: usize,
    /// Camera images fetched.
    #[arg(long, default_value_t = 100)]
    pub images: usize,
    /// Random scenes for perception through JPEG.
    #[arg(long, default_value_t = 60)]
    pub scenes: usize,
}

#[derive(Debug, Args)]
pub struct BenchJpegArgs {
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Frames encoded per variant.
    #[arg(long, default_value_t = 300)]
    pub frames: usize,
}

#[derive(Debug, Args)]
pub struct BenchSoakArgs {
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// How long to run, minutes (2 … 10080).
    #[arg(long, default_value_t = 3.0)]
    pub minutes: f64,
}

#[derive(Debug, Args)]
pub struct BenchTableArgs {
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Skill calls to make.
    #[arg(long, default_value_t = 1000)]
    pub calls: usize,
    /// Seed of the session's choices.
    #[arg(long, default_value_t = 43)]
    pub seed: u64,
    /// Motion time scale of the simulated arm (1 = real time).
    #[arg(long, default_value_t = 0.05)]
    pub time_scale: f64,
}

#[derive(Debug, Args)]
pub struct BenchPingArgs {
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// The running robotd's bus namespace.
    #[arg(long, default_value = "robotd")]
    pub namespace: String,
    /// Round trips measured.
    #[arg(long, default_value_t = 5_000)]
    pub round_trips: usize,
}

#[derive(Debug, Args)]
pub struct BenchSafetyArgs {
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Motion commands per variant.
    #[arg(long, default_value_t = 2000)]
    pub commands: usize,
    /// E-stops of a swinging arm per driver (simulator, fake Ned2, fake WidowX) for the
    /// stopping time and distance.
    #[arg(long, default_value_t = 10)]
    pub stops: usize,
}

#[derive(Debug, Args)]
pub struct BenchRedisArgs {
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Frames through the bus and to Redis.
    #[arg(long, default_value_t = 300)]
    pub frames: usize,
}

#[derive(Debug, Args)]
pub struct BenchMcpArgs {
    #[arg(long)]
    pub json: bool,
    /// Sequential calls per latency measurement.
    #[arg(long, default_value_t = 1000)]
    pub calls: usize,
    /// Seconds of each throughput run.
    #[arg(long, default_value_t = 3.0)]
    pub seconds: f64,
    /// Run the service and the benchmark pinned to CPU 0, without the cross-CPU wake-ups
    /// (slow on VMs) in every figure.
    #[arg(long)]
    pub one_core: bool,
}

#[derive(Debug, Args)]
pub struct BenchPerceptionArgs {
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Random scenes for speed and accuracy.
    #[arg(long, default_value_t = 60)]
    pub scenes: usize,
    /// Frames sent through the bus for the frame-to-objects latency.
    #[arg(long, default_value_t = 100)]
    pub bus_frames: usize,
    /// Instead: N randomized frames (sheet designs, light, lens, camera pose, distractors),
    /// scored against ground truth.
    #[arg(long, value_name = "N")]
    pub randomized: Option<usize>,
    /// Seed of the randomized frames.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// With --randomized: write the frames that went wrong to this folder as PNG files.
    #[arg(long, value_name = "DIR")]
    pub dump: Option<std::path::PathBuf>,
    /// With --randomized: run only this frame (a seed the report or a dumped file names);
    /// may be given several times.
    #[arg(long = "frame-seed", value_name = "SEED")]
    pub frame_seeds: Vec<u64>,
}

#[derive(Debug, Args)]
pub struct BenchSimArgs {
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Frames rendered per variant.
    #[arg(long, default_value_t = 300)]
    pub frames: usize,
}

#[derive(Debug, Args)]
pub struct BenchBusArgs {
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Measured round trips per variant.
    #[arg(long, default_value_t = 20_000)]
    pub round_trips: usize,
    /// Frames per variant.
    #[arg(long, default_value_t = 20_000)]
    pub frames: usize,
    /// Restarts measured.
    #[arg(long, default_value_t = 500)]
    pub restarts: usize,
}
