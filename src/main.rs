//! `robotd`: the runtime for LLM-driven tabletop robots.
//!
//! This file is the command line and the wiring only; every piece lives in a crate of its own
//! (`protocol`, `runtime`, `actors/*`, `adapters`).

mod audit;
mod call;
mod catalog;
mod chat;
mod commission;
mod dashboard;
mod detect;
mod disk;
mod doctor;
mod estop;
mod fake_niryo;
mod fake_widowx;
mod fake_wrong;
mod foxglove;
mod health_board;
mod health_parts;
mod listen;
mod notify;
mod recording;
mod say;
mod serve;
mod stt_health;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
#[cfg(feature = "bench")]
use robotd_bench::cli::BenchCommand;
use robotd_config::{Config, LoadOptions};
use robotd_runtime::telemetry::{self, Mode};
use std::path::PathBuf;

/// robotd: supervised actors on an iceoryx2 bus, driving a tabletop robot arm.
#[derive(Debug, Parser)]
#[command(name = "robotd", version, about)]
struct Cli {
    #[command(flatten)]
    config: ConfigArgs,
    #[command(subcommand)]
    command: Option<Command>,
}

/// Where the configuration comes from (file → environment → these flags).
#[derive(Debug, Args, Clone)]
struct ConfigArgs {
    /// A TOML file layered over the built-in defaults (config/default.toml).
    #[arg(long, global = true, env = "ROBOTD_CONFIG", value_name = "FILE")]
    config: Option<PathBuf>,
    /// Override one configuration key, e.g. `--set http.bind=0.0.0.0:8000` (repeatable).
    #[arg(long = "set", global = true, value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Shorthand for `--set bus.namespace=NAME`.
    #[arg(long, global = true, value_name = "NAME")]
    namespace: Option<String>,
    /// Shorthand for `--set http.bind=ADDR`.
    #[arg(long, global = true, value_name = "IP:PORT")]
    http: Option<String>,
    /// Shorthand for `--set redis.url=URL`: the Redis of the Python tools
    /// (`redis://[:password@]host:port/db`, `rediss://` for TLS); turns the Redis edge on.
    #[arg(long, global = true, value_name = "URL")]
    redis: Option<String>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the service (the default).
    Serve,
    /// Check this machine: shared memory, stale bus resources, Redis, espeak-ng, audio, LLM keys,
    /// and with the niryo or widowx driver the robot (connect and status, or the nine servos).
    Doctor(DoctorArgs),
    /// Measure robotd's machinery beside its raw baseline.
    #[cfg(feature = "bench")]
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
    /// Measure robotd's machinery (not in this build: `cargo build --release --features bench`).
    #[cfg(not(feature = "bench"))]
    Bench {
        #[arg(trailing_var_arg = true, allow_hyphen_values = true, hide = true)]
        args: Vec<String>,
    },
    /// Commission a real arm: measure what no simulator can (the camera's mount on the arm,
    /// rectified images, …) slowly and under the motion policy, and write it as config
    /// (docs/commissioning.md).
    Commission(commission::CommissionArgs),
    /// Run the built-in perception on one image file: markers, workspace, objects (check a
    /// camera or the lighting; `--out annotated.png` draws what was found).
    Detect(detect::DetectArgs),
    /// Say one text with the configured speech engine: play it, or write it with --out.
    Say(SayArgs),
    /// Serve the MCP tools on stdin/stdout (for desktop LLM apps that spawn their server).
    /// Starts the whole runtime; logs go to stderr and the log file, never to stdout.
    McpStdio,
    /// Call one tool of a running robotd (or any MCP server) and print its reply.
    ///
    /// Example: `robotd call pick_object --arg object_name=pencil --arg
    /// 'pick_coordinate=[0.22,-0.05]'`. Exits 0 on a ✓ reply, 1 on a ❌ reply, 2 when the
    /// call could not be made.
    Call(CallArgs),
    /// Talk to the robot in plain words through an LLM (in process, or `--mcp URL`).
    Chat(chat::ChatArgs),
    /// Say a command: record the microphone until silence, transcribe it with the running
    /// robotd's STT actor and hand it to its agent (`--print-only`: just print it).
    Listen(listen::ListenArgs),
    /// Engage the emergency stop of the running robotd (or release it with --release).
    Estop(EstopArgs),
    /// Record the running robotd's bus (camera, arm, objects, every topic) into an MCAP file
    /// that Foxglove opens; until Ctrl-C or --duration.
    Record(RecordArgs),
    /// Publish an MCAP recording onto a bus without a robot (camera frames, arm and gripper
    /// state by default), for your own subscribers. To run robotd's perception, workspace
    /// model, dashboard and tools on a recording, serve it as the robot instead: robotd serve
    /// --set robot.driver=replay --set robot.replay.file=FILE.mcap.
    Replay(ReplayArgs),
    /// Serve the simulator behind the Niryo Ned2's TCP protocol: a fake robot for the niryo
    /// driver and pyniryo scripts (`--set robot.scene=…`, `--set robot.time_scale=…`).
    FakeNiryo(fake_niryo::FakeNiryoArgs),
    /// Serve the simulator behind the WidowX's servo bus (DYNAMIXEL Protocol 2.0 on a
    /// pseudo-terminal) and its camera (MJPEG over HTTP): a fake arm for the widowx driver and
    /// dynamixel-sdk scripts.
    FakeWidowx(fake_widowx::FakeWidowxArgs),
    /// Print the bus catalogue: every topic, frame topic and service with its message types,
    /// schema versions and the exact iceoryx2 settings an actor in another language must use
    /// (`--json`: the file the Python package in python/ ships).
    Catalog {
        /// JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// The motion audit log.
    Audit {
        #[command(subcommand)]
        what: AuditCommand,
    },
    /// The other process of a two-process benchmark (started by `robotd bench`).
    #[cfg(feature = "bench")]
    #[command(hide = true)]
    BenchPeer {
        role: String,
        #[arg(long = "peer-namespace")]
        peer_namespace: String,
        #[arg(long)]
        count: usize,
        #[arg(long)]
        cpu: Option<usize>,
    },
}

#[derive(Debug, Args)]
struct CallArgs {
    /// The tool's name, e.g. `get_detected_objects`; `list` lists the tools.
    tool: String,
    /// An argument as key=value; the value is read as JSON when it parses (numbers, lists,
    /// true/false, null), otherwise as a string.
    #[arg(long = "arg", value_name = "KEY=VALUE")]
    args: Vec<String>,
    /// The server's MCP URL (`…/sse` for legacy SSE, `…/mcp` for streamable HTTP). Default:
    /// the configured `http.bind`, `/mcp`.
    #[arg(long, value_name = "URL")]
    url: Option<String>,
    /// Bearer token (default: `[mcp] token` of the configuration, e.g. ROBOTD_MCP__TOKEN).
    #[arg(long, env = "ROBOTD_MCP_TOKEN", hide_env_values = true)]
    token: Option<String>,
    /// Print `structuredContent` (JSON) instead of the text.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Args)]
struct EstopArgs {
    /// Why (shown in every refusal until release; several words are joined). A mistyped
    /// option is ignored with a note: the e-stop engages whatever the command line.
    reason: Vec<String>,
    /// Release the emergency stop instead (a deliberate act: only after the cause was dealt
    /// with).
    #[arg(long)]
    release: bool,
}

#[derive(Debug, Subcommand)]
enum AuditCommand {
    /// Check the keyed chain of audit files (oldest first, e.g. audit.jsonl.1 audit.jsonl);
    /// exit 1 names the first broken line, exit 2 when a file or the key cannot be read.
    Verify {
        /// The key file of the chain (default: audit.key beside the last file).
        #[arg(long)]
        key: Option<PathBuf>,
        /// The files, oldest first.
        #[arg(required = true)]
        files: Vec<PathBuf>,
    },
}

#[derive(Debug, Args)]
struct SayArgs {
    /// What to say.
    text: String,
    /// Write the audio to this WAV file instead of playing it.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
}

#[derive(Debug, Args)]
struct DoctorArgs {
    /// Print the report as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Remove the resources of dead bus nodes.
    #[arg(long)]
    clean: bool,
}

#[derive(Debug, Args)]
struct RecordArgs {
    /// The file to write (never overwritten).
    file: std::path::PathBuf,
    /// Comma-separated topics to record (camera/frames and bus topics); default all.
    #[arg(long)]
    topics: Option<String>,
    /// How long to record, e.g. 30s, 2m, 1h; default until Ctrl-C.
    #[arg(long, value_parser = recording::parse_duration)]
    duration: Option<std::time::Duration>,
}

#[derive(Debug, Args)]
struct ReplayArgs {
    /// The MCAP file to replay.
    file: std::path::PathBuf,
    /// Comma-separated topics to publish; default camera/frames, arm/state, gripper/state.
    /// Safety topics (safety/estop) are never replayed.
    #[arg(long)]
    topics: Option<String>,
    /// Pace relative to the recording: 1 = as recorded, 2 = twice as fast, 0 = as fast as
    /// possible.
    #[arg(long, default_value_t = 1.0)]
    speed: f64,
}

fn load_config(args: &ConfigArgs) -> Result<Config> {
    let mut overrides = Vec::new();
    for pair in &args.set {
        overrides.push(LoadOptions::parse_override(pair)?);
    }
    if let Some(namespace) = &args.namespace {
        overrides.push(("bus.namespace".into(), namespace.clone()));
    }
    if let Some(http) = &args.http {
        overrides.push(("http.bind".into(), http.clone()));
    }
    if let Some(redis) = &args.redis {
        overrides.push(("redis.url".into(), redis.clone()));
    }
    Ok(Config::load(LoadOptions {
        file: args.config.clone(),
        overrides,
    })?)
}

fn main() -> std::process::ExitCode {
    match run() {
        Ok(code) => code,
        Err(error) => {
            eprintln!("robotd: {error:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// The global options that take a value (`--namespace NAME`), for finding the subcommand.
const GLOBAL_VALUE_OPTIONS: [&str; 5] = ["--config", "--set", "--namespace", "--http", "--redis"];

/// Where the subcommand is in `argv`, and its name.
fn subcommand_of(argv: &[std::ffi::OsString]) -> Option<(usize, String)> {
    let mut i = 1;
    while i < argv.len() {
        let word = argv[i].to_string_lossy();
        if GLOBAL_VALUE_OPTIONS.contains(&word.as_ref()) {
            i += 2;
        } else if word.starts_with('-') {
            i += 1;
        } else {
            return Some((i, word.into_owned()));
        }
    }
    None
}

/// Parses the command line. `robotd estop` engages whatever follows it: an argument clap
/// does not know is dropped and named in a note (and a command line it still cannot read is
/// cut after `estop`), so a mistyped e-stop still stops. The notes say what was ignored.
fn parse_cli() -> (Cli, Vec<String>) {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    let mut argv: Vec<std::ffi::OsString> = std::env::args_os().collect();
    let mut notes = Vec::new();
    loop {
        let error = match Cli::try_parse_from(&argv) {
            Ok(cli) => return (cli, notes),
            Err(error) => error,
        };
        let estop = subcommand_of(&argv).filter(|(_, name)| name == "estop");
        let (Some((at, _)), false) = (
            estop,
            matches!(
                error.kind(),
                ErrorKind::DisplayHelp
                    | ErrorKind::DisplayVersion
                    | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            ),
        ) else {
            error.exit()
        };
        let bad = match error.get(ContextKind::InvalidArg) {
            Some(ContextValue::String(bad)) => Some(bad.clone()),
            _ => None,
        };
        let position = bad.as_ref().and_then(|bad| {
            let option = bad.split([' ', '=']).next().unwrap_or(bad);
            (at + 1..argv.len()).find(|&i| {
                let word = argv[i].to_string_lossy();
                word == *bad || word == option || word.starts_with(&format!("{option}="))
            })
        });
        match position {
            Some(i) => {
                let word = argv.remove(i).to_string_lossy().into_owned();
                notes.push(format!("unknown argument '{word}' ignored"));
            }
            None if at + 1 >= argv.len() => error.exit(),
            None => {
                let ignored: Vec<String> = argv
                    .drain(at + 1..)
                    .map(|w| w.to_string_lossy().into_owned())
                    .collect();
                let first_line = error.to_string();
                let first_line = first_line.lines().next().unwrap_or_default().to_owned();
                notes.push(format!(
                    "the arguments '{}' were not understood ({}) and were ignored",
                    ignored.join(" "),
                    first_line.trim_start_matches("error: ")
                ));
            }
        }
    }
}

fn run() -> Result<std::process::ExitCode> {
    let (cli, notes) = parse_cli();
    // iceoryx2 logs to stderr on its own; keep it to warnings about real problems.
    iceoryx2::prelude::set_log_level(iceoryx2::prelude::LogLevel::Error);
    match cli.command.unwrap_or(Command::Serve) {
        Command::Serve => {
            let config = load_config(&cli.config)?;
            let _telemetry = telemetry::init(&config.telemetry, Mode::Service)?;
            let runtime = tokio::runtime::Builder::new_multi_thread()
                .worker_threads(config.service.worker_threads)
                .enable_all()
                .build()
                .context("starting the tokio runtime")?;
            runtime.block_on(serve::run(config, cli.config.config.as_deref()))?;
            Ok(std::process::ExitCode::SUCCESS)
        }
        Command::McpStdio => {
            let config = load_config(&cli.config)?;
            let _telemetry = telemetry::init(&config.telemetry, Mode::Stdio)?;
            let runtime = tokio::runtime::Builder::new_multi_thread()
                .worker_threads(config.service.worker_threads)
                .enable_all()
                .build()
                .context("starting the tokio runtime")?;
            runtime.block_on(serve::run_stdio(config))?;
            Ok(std::process::ExitCode::SUCCESS)
        }
        Command::Call(args) => {
            let config = load_config(&cli.config)?;
            let runtime = tokio::runtime::Builder::new_multi_thread()
                .worker_threads(2)
                .enable_all()
                .build()
                .context("starting the tokio runtime")?;
            let url = args
                .url
                .clone()
                .unwrap_or_else(|| format!("http://{}/mcp", config.http.bind));
            let token = args.token.clone().or(config.mcp.token.clone());
            runtime.block_on(call::run(call::CallOptions {
                url,
                token,
                tool: args.tool,
                args: args.args,
                json: args.json,
            }))
        }
        Command::Chat(args) => {
            let config = load_config(&cli.config)?;
            chat::run(config, cli.config.config.as_deref(), args)
        }
        Command::FakeNiryo(args) => {
            let config = load_config(&cli.config)?;
            let _telemetry = telemetry::init(&config.telemetry, Mode::Command)?;
            fake_niryo::run(config, args)?;
            Ok(std::process::ExitCode::SUCCESS)
        }
        Command::FakeWidowx(args) => {
            let config = load_config(&cli.config)?;
            let _telemetry = telemetry::init(&config.telemetry, Mode::Command)?;
            fake_widowx::run(config, args)?;
            Ok(std::process::ExitCode::SUCCESS)
        }
        Command::Record(args) => {
            let config = load_config(&cli.config)?;
            let done =
                recording::record(&config, &args.file, args.topics.as_deref(), args.duration)?;
            eprintln!("robotd: {done}");
            Ok(std::process::ExitCode::SUCCESS)
        }
        Command::Replay(args) => {
            let config = load_config(&cli.config)?;
            let done = recording::replay(&config, &args.file, args.topics.as_deref(), args.speed)?;
            eprintln!("robotd: {done}");
            Ok(std::process::ExitCode::SUCCESS)
        }
        Command::Listen(args) => listen::run(&load_config(&cli.config)?, &args),
        Command::Estop(args) => {
            let config = load_config(&cli.config)?;
            let reason = args.reason.join(" ");
            let done = estop::run(&config, Some(reason.as_str()), args.release, &notes)?;
            eprintln!("robotd: {done}");
            Ok(std::process::ExitCode::SUCCESS)
        }
        Command::Catalog { json } => {
            print!("{}", catalog::render(json));
            Ok(std::process::ExitCode::SUCCESS)
        }
        Command::Audit {
            what: AuditCommand::Verify { files, key },
        } => match audit::run(&files, key.as_deref()) {
            Err(unreadable) => {
                eprintln!("robotd: {unreadable:#}");
                Ok(std::process::ExitCode::from(2))
            }
            Ok(audit::Verdict::Intact(report)) => {
                println!("{report}");
                Ok(std::process::ExitCode::SUCCESS)
            }
            Ok(audit::Verdict::Broken(broken)) => {
                println!("broken: {broken}");
                Ok(std::process::ExitCode::from(1))
            }
        },
        Command::Say(args) => {
            let config = load_config(&cli.config)?;
            let said = say::run(&config, &args.text, args.out.as_deref())?;
            eprintln!("robotd: {said}");
            Ok(std::process::ExitCode::SUCCESS)
        }
        Command::Detect(args) => detect::run(&args, &load_config(&cli.config)?),
        Command::Commission(args) => commission::run(
            &load_config(&cli.config)?,
            cli.config.config.as_deref(),
            &args,
        ),
        Command::Doctor(args) => {
            let config = load_config(&cli.config)?;
            let config_dir = cli
                .config
                .config
                .as_deref()
                .and_then(|p| p.parent())
                .map(PathBuf::from)
                .unwrap_or_else(|| PathBuf::from("."));
            let report = doctor::run(&doctor::DoctorOptions {
                disk_places: disk::places(&config),
                redis_url: config.redis.url.clone(),
                http_bind: Some(config.http.bind.to_string()),
                bus_namespace: config.bus.namespace.clone(),
                config_dir,
                clean: args.clean,
                niryo: (config.robot.driver == robotd_config::RobotDriver::Niryo)
                    .then(|| robotd_driver_niryo::link_settings(&config.robot)),
                widowx: (config.robot.driver == robotd_config::RobotDriver::Widowx).then(|| {
                    (
                        config.robot.widowx.device.clone(),
                        config.robot.widowx.baud_rate,
                    )
                }),
                camera: (config.robot.driver == robotd_config::RobotDriver::Widowx)
                    .then(|| config.robot.widowx.camera_url.clone())
                    .flatten()
                    .map(|source| {
                        let intrinsics =
                            robotd_driver_widowx::camera_intrinsics(&config.robot.widowx);
                        (source, (intrinsics.width, intrinsics.height))
                    }),
                replay: (config.robot.driver == robotd_config::RobotDriver::Replay)
                    .then(|| config.robot.replay.clone()),
                stt: doctor::stt_command(&config),
                robot: Some(config.robot.clone()),
            })?;
            if args.json {
                println!("{}", serde_json::to_string_pretty(&report.to_json())?);
            } else {
                print!("{}", report.render_table());
            }
            Ok(if report.has_problems() {
                std::process::ExitCode::FAILURE
            } else {
                std::process::ExitCode::SUCCESS
            })
        }
        #[cfg(feature = "bench")]
        Command::Bench { what } => {
            robotd_bench::run(what, || Ok(load_config(&cli.config)?.redis.url))
        }
        #[cfg(not(feature = "bench"))]
        Command::Bench { .. } => anyhow::bail!(
            "this robotd was built without its benchmarks (the `bench` feature); build them with \
             `cargo build --release --features bench` (BENCHMARKS.md)"
        ),
        #[cfg(feature = "bench")]
        Command::BenchPeer {
            role,
            peer_namespace,
            count,
            cpu,
        } => robotd_bench::run_peer(&role, &peer_namespace, count, cpu),
    }
}
