//! `robotd commission`: first contact with a real arm. It measures, on the robot itself, what
//! no simulator and no fake can tell robotd — and writes the measured values as a config
//! file — before the arm works unattended, the way industrial robots are commissioned.
//!
//! The steps, each in its own module, in order:
//!
//! 1. **connect** ([`connect`]): the driver reaches the robot, which reports its joints,
//!    whether it is calibrated and whether the e-stop is engaged.
//! 2. **camera** ([`camera`]): whether the images come already rectified, where the camera
//!    sits on the arm and how high the table is (hand-eye calibration on the workspace sheet,
//!    [`handeye`]).
//!
//! 3. **stopping** ([`stopping`]): time and tool travel from an e-stop to standstill, at the
//!    capped speed, from the arm's own reports.
//!
//! 4. **gripper** ([`gripper`]): the WidowX gripper's closed and open ticks at its mechanical
//!    stops and the load that counts as holding; on a Ned2, which reports no finger position,
//!    the tool it names and whether it opens and closes ([`ned2_tool`]).
//!
//! 5. **pick** ([`pick`]): the object at the sheet's centre picked, put back and seen again;
//!    how far it moved, as the camera measures it.
//!
//! Every motion is a request on `arm/command` from the origin `cli`, so the motion policy
//! admits it (fence, joint margins, the speed cap this command lowers to `--speed`), audits
//! it, and the e-stop stops it ([`session`]). When a robotd already drives the arm on the
//! configured bus namespace, commissioning works through it (attached) instead of connecting
//! to the robot itself. Each moving step says what it will do and, unless
//! `--yes`, waits for the operator's go. A step that cannot run says why and leaves the arm at
//! rest. The report is printed (`--json` for machines); `--write FILE` writes the config file
//! commissioning ran with plus the measured values ([`config_file`]) — a new file, never over
//! an existing one.

mod camera;
mod config_file;
mod connect;
mod gripper;
pub mod handeye;
mod ned2_tool;
mod pick;
mod session;
mod stopping;
mod write;

use anyhow::{bail, Context, Result};
use clap::Args;
use robotd_config::Config;
use robotd_driver::RobotDriver;
use robotd_protocol::geometry::RobotModel;
use serde::Serialize;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

/// The steps, in the order they run.
pub const STEPS: [&str; 5] = ["connect", "camera", "gripper", "stopping", "pick"];

/// Options of `robotd commission`.
#[derive(Debug, Args)]
pub struct CommissionArgs {
    /// Run unattended: do not wait for the operator's go before a step moves the arm.
    #[arg(long)]
    pub yes: bool,
    /// Run only this step (connect, camera, gripper, stopping, pick).
    #[arg(long, value_name = "STEP")]
    pub only: Option<String>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write the config file this ran with (--config), plus the measured values, to this new
    /// file (never over an existing file): run robotd with it.
    #[arg(long, value_name = "FILE")]
    pub write: Option<PathBuf>,
    /// The workspace whose sheet the camera step uses (default: the first configured).
    #[arg(long, value_name = "ID")]
    pub workspace: Option<String>,
    /// Calibrate the robot when it is not calibrated (the connect step; each joint moves to
    /// its limits, after the operator's go unless --yes).
    #[arg(long)]
    pub calibrate: bool,
    /// Speed cap of every commissioning motion, m/s at the tool (never above the configured
    /// `safety.max_tcp_speed_m_s`).
    #[arg(long, default_value_t = 0.1, value_name = "M_S")]
    pub speed: f64,
}

/// One step's outcome in the report.
#[derive(Debug, Clone, Serialize)]
pub struct StepOutcome {
    /// The step's name.
    pub step: String,
    /// `ok`, `failed` or `skipped`.
    pub status: String,
    /// Why it failed or was skipped.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// What it measured.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub measured: Option<serde_json::Value>,
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// The robot model.
    pub robot: String,
    /// The configured driver.
    pub driver: String,
    /// Whether commissioning worked through a robotd that was already running (see
    /// `session.rs`).
    pub attached: bool,
    /// Each step run or asked for.
    pub steps: Vec<StepOutcome>,
    /// The file written, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub written: Option<PathBuf>,
}

fn outcome(step: &str, result: Result<serde_json::Value>) -> StepOutcome {
    match result {
        Ok(measured) => StepOutcome {
            step: step.into(),
            status: "ok".into(),
            reason: None,
            measured: Some(measured),
        },
        Err(error) => StepOutcome {
            step: step.into(),
            status: "failed".into(),
            reason: Some(format!("{error:#}")),
            measured: None,
        },
    }
}

/// Asks the operator before a step that moves the arm; `Ok(false)`: they declined.
fn operator_agrees(args: &CommissionArgs, what: &str) -> Result<bool> {
    eprintln!("robotd commission: {what}");
    if args.yes {
        return Ok(true);
    }
    if !std::io::stdin().is_terminal() {
        bail!(
            "this step moves the arm and nobody is at the terminal to agree: run with --yes to \
             commission unattended"
        );
    }
    eprint!("Keep the e-stop at hand. Go ahead? [y/N] ");
    let mut answer = String::new();
    std::io::stdin().read_line(&mut answer)?;
    Ok(matches!(answer.trim(), "y" | "Y" | "yes"))
}

/// Runs `robotd commission` on `config`, loaded from the file `config_path` (if any); the
/// exit code is 0 when every step run succeeded.
pub fn run(config: &Config, config_path: Option<&Path>, args: &CommissionArgs) -> Result<ExitCode> {
    if let Some(only) = &args.only {
        if !STEPS.contains(&only.as_str()) {
            bail!(
                "--only {only}: no such step; the steps are {}",
                STEPS.join(", ")
            );
        }
    }
    if !(args.speed.is_finite() && args.speed > 0.0 && args.speed <= 0.5) {
        bail!("--speed {}: give a cap from 0.01 to 0.5 m/s", args.speed);
    }
    if let Some(path) = &args.write {
        if path.exists() {
            bail!(
                "--write {}: the file exists; commissioning writes a new file and never \
                 overwrites one (your config stays yours): give a new path",
                path.display()
            );
        }
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    let report = runtime.block_on(run_steps(config, config_path, args))?;
    let failed = report.steps.iter().any(|s| s.status == "failed");
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", write::render(&report));
    }
    Ok(if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}

/// With `--calibrate`, calibrates a robot that says it is not calibrated (after the
/// operator's go), through the motion policy like every motion.
async fn calibrate_if_asked(session: &mut session::Session, args: &CommissionArgs) -> Result<()> {
    if !args.calibrate {
        return Ok(());
    }
    let state = session.state(connect::CONNECT_WAIT).await?;
    if state.calibrated {
        return Ok(());
    }
    if !operator_agrees(
        args,
        "connect: the robot is not calibrated; calibrating moves each joint to its limits and \
         back (keep the space around the arm clear)",
    )? {
        bail!(
            "the robot is not calibrated and the operator declined its calibration; nothing moved"
        );
    }
    // A Ned2's calibration takes up to a minute or two; the driver allows it 120 s.
    let motion_timeout = std::mem::replace(&mut session.motion_timeout, Duration::from_secs(150));
    let calibrated = session
        .command(robotd_protocol::arm::ArmCommand::Calibrate)
        .await;
    session.motion_timeout = motion_timeout;
    calibrated.map_err(|e| anyhow::anyhow!("calibrating: {e}"))?;
    // The next state says whether it took.
    let deadline = std::time::Instant::now() + connect::CONNECT_WAIT;
    while std::time::Instant::now() < deadline {
        if let Some(state) = session.next_state(Duration::from_millis(500)).await? {
            if state.calibrated {
                return Ok(());
            }
        }
    }
    bail!("the robot accepted the calibration but still reports itself not calibrated")
}

async fn run_steps(
    config: &Config,
    config_path: Option<&Path>,
    args: &CommissionArgs,
) -> Result<Report> {
    let wanted = |step: &str| args.only.as_deref().is_none_or(|only| only == step);
    let mut report = Report {
        robot: format!("{:?}", config.robot.model()),
        driver: format!("{:?}", config.robot.driver),
        attached: false,
        steps: Vec::new(),
        written: None,
    };
    let mut session = match session::Session::start(config, args.speed).await {
        Ok(session) => session,
        Err(error) => {
            report.steps.push(outcome("connect", Err(error)));
            return Ok(report);
        }
    };
    report.attached = session.attached();
    let connected = match calibrate_if_asked(&mut session, args).await {
        Ok(()) => connect::run(&mut session, config).await,
        Err(error) => Err(error),
    };
    let connected_ok = connected.is_ok();
    if wanted("connect") || !connected_ok {
        report.steps.push(outcome(
            "connect",
            connected.and_then(|c| Ok(serde_json::to_value(c)?)),
        ));
    }
    if !connected_ok {
        return Ok(report);
    }
    let mut camera_report = None;
    if wanted("camera") {
        let result = if operator_agrees(
            args,
            "camera: the arm visits up to 10 views of the workspace sheet around its observation \
             pose, slowly, and ends at the observation pose",
        )? {
            camera::run(&mut session, config, args.workspace.as_deref()).await
        } else {
            Err(anyhow::anyhow!("the operator declined; nothing moved"))
        };
        if let Ok(measured) = &result {
            camera_report = Some(measured.clone());
        }
        report.steps.push(outcome(
            "camera",
            result.and_then(|c| Ok(serde_json::to_value(c)?)),
        ));
    }
    if wanted("stopping") {
        let result = if operator_agrees(
            args,
            "stopping: the arm swings the tool across the workspace 10 cm above the sheet and \
             robotd engages the e-stop mid-swing, 3 times (it releases only its own e-stop)",
        )? {
            stopping::run(&mut session, config, args.workspace.as_deref(), args.speed).await
        } else {
            Err(anyhow::anyhow!("the operator declined; nothing moved"))
        };
        report.steps.push(outcome(
            "stopping",
            result.and_then(|c| Ok(serde_json::to_value(c)?)),
        ));
    }
    let mut gripper_report = None;
    if wanted("gripper") {
        let no_tool = (config.robot.model() == RobotModel::Ned2
            && config.robot.driver != RobotDriver::Niryo)
            .then(|| {
                format!(
                    "the {} driver has no tool to identify: a real Ned2 (driver niryo) names \
                     its tool",
                    config.robot.driver.name()
                )
            });
        if let Some(reason) = no_tool {
            report.steps.push(StepOutcome {
                step: "gripper".into(),
                status: "skipped".into(),
                reason: Some(reason),
                measured: None,
            });
        } else {
            let result = if operator_agrees(
                args,
                "gripper: the fingers open, close on nothing and open again, slowly (the \
                 fingers must be empty); a WidowX's are driven past the configured ends until \
                 they stall",
            )? {
                match config.robot.model() {
                    RobotModel::Ned2 => ned2_tool::run(&session)
                        .await
                        .and_then(|t| Ok(serde_json::to_value(t)?)),
                    RobotModel::WidowX250 => gripper::run(&session, config).await.and_then(|g| {
                        gripper_report = Some(g.clone());
                        Ok(serde_json::to_value(g)?)
                    }),
                }
            } else {
                Err(anyhow::anyhow!("the operator declined; nothing moved"))
            };
            report.steps.push(outcome("gripper", result));
        }
    }
    if wanted("pick") {
        let result = if operator_agrees(
            args,
            "pick: robotd picks the object at the sheet's centre, puts it back where it found \
             it and looks again (put a small cube at the sheet's centre first)",
        )? {
            pick::run(&mut session, config, args.workspace.as_deref()).await
        } else {
            Err(anyhow::anyhow!("the operator declined; nothing moved"))
        };
        report.steps.push(outcome(
            "pick",
            result.and_then(|c| Ok(serde_json::to_value(c)?)),
        ));
    }
    if let Some(path) = &args.write {
        config_file::write(
            path,
            config_path,
            config,
            camera_report.as_ref(),
            gripper_report.as_ref(),
        )?;
        report.written = Some(path.clone());
    }
    Ok(report)
}
