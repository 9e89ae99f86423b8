//! `robotd serve`: the long-running service.
//!
//! Joins the bus (cleaning up what crashed processes left behind), starts robotd's own
//! `system` service, the robot's hardware actors (arm, gripper, camera; the simulator unless a
//! real driver is configured), every actor configured to run as its own process, each under a
//! supervisor, and serves `/health` and `/metrics` on the HTTP port until SIGINT or SIGTERM.

use anyhow::{Context, Result};
use robotd_config::{ActorMode, Config, WorkspaceConfig};
use robotd_http::guard::HttpGuard;
use robotd_http::{HealthSource, HttpEdge};
use robotd_mcp::call_log::CallLog;
use robotd_mcp::McpService;
use robotd_perception::detector::{ColourDetector, ColourDetectorSettings};
use robotd_perception::labels::LabelTable;
use robotd_perception::{Perception, Pipeline};
use robotd_protocol::diagnostics::Pong;
use robotd_protocol::geometry::RobotModel;
use robotd_protocol::health::RestartEvent;
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_robot::Hardware;
use robotd_runtime::bus::stale::{
    remove_half_created_after, HALF_CREATED_SETTLE, SHARED_MEMORY_DIR,
};
use robotd_runtime::bus::{Bus, BusOptions, Publisher};
use robotd_runtime::supervision::{SupervisedProcess, SupervisionObserver, Supervisor};
use robotd_skills::{Skills, SkillsSettings};
use robotd_speech::{Speech, SpeechSettings};
use robotd_tools::{Registry, ToolSettings};
use robotd_topics::{HEALTH_RESTARTS, SYSTEM_PING};
use robotd_workspace_model::{WorkspaceModel, WorkspaceModelSettings};
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Instant;
use tokio_util::sync::CancellationToken;

use crate::health_board::{supervision_observer, HealthBoard, RobotInfo};
use crate::health_parts::{external_detections_report, safety_report, workspace_view_report};

/// Runs the service until a shutdown signal.
/// Everything `robotd serve` runs, started; [`Runtime::shutdown`] stops it in order.
pub struct Runtime {
    /// The bus this instance joined.
    pub bus: Bus,
    /// The configured workspaces (`[robot] workspaces`, or the model's built-in ones).
    pub workspaces: Vec<WorkspaceInfo>,
    /// The report behind `/health` and `get_system_status`.
    pub health_source: HealthSource,
    system: tokio::task::JoinHandle<()>,
    hardware: Hardware,
    workspace_model: WorkspaceModel,
    perception: Option<Perception>,
    redis: Option<robotd_redis::RedisEdge>,
    speech: Speech,
    skills: Skills,
    processes: Vec<SupervisedProcess>,
    stt: Arc<crate::stt_health::SttHealth>,
    /// The one tool registry of this instance (MCP and the agent share it: each registry's
    /// bus publishers cost megabytes of iceoryx2 bookkeeping, see BENCHMARKS.md).
    registry: Mutex<Option<Registry>>,
}

impl Runtime {
    /// Joins the bus and starts every actor.
    pub async fn start(config: &Config) -> Result<Runtime> {
        let started = Instant::now();
        let redis_target = robotd_redis::resolve_target(None, config.redis.url.as_deref(), &|k| {
            std::env::var(k).ok()
        })
        .map_err(anyhow::Error::msg)
        .context("the Redis settings")?;
        let trust = robotd_redis::Trust::parse(&config.redis.trust)
            .map_err(anyhow::Error::msg)
            .context("[redis] trust")?;
        // Without a Redis edge there is no external detector to trust.
        let trust = if redis_target.is_some() {
            trust
        } else {
            robotd_redis::Trust::Builtin
        };
        let bus = Bus::open(BusOptions::new(&config.bus.namespace, "robotd"))
            .context("joining the bus")?;
        tracing::info!(namespace = %config.bus.namespace, "joined the bus");

        // robotd's own service: any process on the bus can check that robotd is alive.
        let mut ping_server = bus.server(&SYSTEM_PING).context("serving system/ping")?;
        let pid = std::process::id();
        let system = tokio::spawn(async move {
            let served = ping_server
                .serve(move |ping| async move {
                    Ok(Pong {
                        seq: ping.seq,
                        payload: ping.payload,
                        served_by_pid: pid,
                    })
                })
                .await;
            if let Err(error) = served {
                tracing::error!(%error, "the system service stopped");
            }
        });

        let health = Arc::new(HealthBoard::default());
        let restarts: Arc<Mutex<Publisher<RestartEvent>>> =
            Arc::new(Mutex::new(bus.publisher(&HEALTH_RESTARTS)?));
        let hardware = Hardware::start(&bus, &config.robot_sections(), |_actor| {
            supervision_observer(health.clone(), restarts.clone())
        })
        .await
        .context("starting the robot's hardware actors")?;
        let robot_model = hardware.arm_context.kinematics.model();
        let robot = RobotInfo {
            model: robot_model.display_name().to_owned(),
            scene: hardware
                .sim
                .as_ref()
                .map(|sim| sim.with_world(|world| world.scene_name().to_owned()))
                .unwrap_or_default(),
        };
        tracing::info!(model = %robot.model, scene = %robot.scene, "robot ready");
        // From [robot] workspaces (or the model's built-in ones), whatever the driver.
        let workspaces = config.robot.workspace_infos();
        let labels = load_label_table(config)?;
        let workspace_model =
            start_workspace_model(&bus, workspaces.clone(), &labels, &config.workspace)?;
        let perception = if trust.runs_builtin() {
            Some(start_perception(
                &bus,
                &hardware,
                workspaces.clone(),
                labels.clone(),
                config.perception.detector_settings(),
            )?)
        } else {
            tracing::info!("[redis] trust = \"external\": the built-in detector does not run");
            None
        };
        let redis = match redis_target {
            Some(target) => Some(
                robotd_redis::RedisEdge::start(
                    &bus,
                    robotd_redis::RedisEdgeSettings {
                        target,
                        instance: instance_id(&config.service.name),
                        camera_fps: config.redis.camera_fps,
                        annotated_fps: config.redis.annotated_fps,
                        objects_fps: config.redis.objects_fps,
                        trust,
                        max_entry_bytes: config.redis.max_entry_bytes as usize,
                        intrinsics: hardware.camera_intrinsics.clone(),
                        workspaces: workspaces.clone(),
                        label_table: labels.clone(),
                    },
                )
                .context("starting the Redis edge")?,
            ),
            None => None,
        };
        let redis_status = redis.as_ref().map(|edge| edge.status());
        let speech = start_speech(
            &bus,
            config,
            supervision_observer(health.clone(), restarts.clone()),
        )
        .await?;
        let skills = start_skills(
            &bus,
            robot_model,
            workspaces.clone(),
            hardware.safety.clone(),
        )?;
        // Subscribed before the STT actor starts: its first status says its model loaded.
        let stt_configured = crate::doctor::stt_command(config).is_some();
        let stt = crate::stt_health::SttHealth::start(&bus, stt_configured)?;
        let processes = start_process_actors(config, &bus, &health, &restarts).await?;
        // Everything that consumes the robot's data is up: a replayed recording may begin.
        hardware.start_playback();

        let report_config = config.clone();
        let report_health = health.clone();
        let report_safety = hardware.safety.clone();
        let perception_stats = perception.as_ref().map(Perception::stats);
        let robot_link = hardware.arm_context.driver.clone();
        let disk_places = crate::disk::places(config);
        let stt_health = stt.clone();
        let health_source: HealthSource = Arc::new(move || {
            let mut report = report_health.report(&report_config, &robot, started);
            // A real robot can be down while its actors run: say why.
            match robot_link.connection() {
                Ok(()) => report["robot"]["connected"] = true.into(),
                Err(reason) => {
                    report["robot"]["connected"] = false.into();
                    report["robot"]["available"] = false.into();
                    report["robot"]["reason"] = format!("robot not connected: {reason}").into();
                    report["status"] = "degraded".into();
                }
            }
            report["safety"] = safety_report(&report_safety);
            let view = perception_stats.as_ref().and_then(|s| s.workspace_view());
            if view.as_ref().is_some_and(|v| !v.visible) {
                report["status"] = "degraded".into();
            }
            report["workspace_view"] = workspace_view_report(view.as_ref());
            if let Some(stats) = &perception_stats {
                report["external_detections"] = external_detections_report(&stats.external);
            }
            let disk = crate::disk::report(&disk_places);
            if disk["low"] == true {
                report["status"] = "degraded".into();
            }
            report["disk"] = disk;
            report["stt"] = stt_health.report();
            report["redis"] = match &redis_status {
                Some(status) => status.to_json(),
                None => serde_json::json!({"state": "off"}),
            };
            report
        });
        Ok(Runtime {
            bus,
            workspaces,
            health_source,
            system,
            hardware,
            workspace_model,
            perception,
            redis,
            speech,
            skills,
            processes,
            stt,
            registry: Mutex::new(None),
        })
    }

    /// The camera's intrinsics as its driver reports them.
    pub fn camera_intrinsics(&self) -> robotd_protocol::camera::CameraIntrinsics {
        self.hardware.camera_intrinsics.clone()
    }

    /// The safety routes' state: the policy, an e-stop publisher and a client of the policy's
    /// release service on this runtime's bus.
    pub fn safety_api(&self) -> Result<robotd_http::safety::SafetyApi> {
        Ok(robotd_http::safety::SafetyApi {
            safety: self.hardware.safety.clone(),
            estop: Arc::new(Mutex::new(
                self.bus.publisher(&robotd_topics::SAFETY_ESTOP)?,
            )),
            release: Arc::new(self.bus.client(&robotd_topics::SAFETY_RELEASE)?),
        })
    }

    /// The tool registry over this runtime's bus: created once, then shared by every caller.
    pub fn tool_registry(&self, config: &Config) -> Result<Registry> {
        let mut shared = self.registry.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(registry) = shared.as_ref() {
            return Ok(registry.clone());
        }
        let registry = self.new_tool_registry(config)?;
        *shared = Some(registry.clone());
        Ok(registry)
    }

    fn new_tool_registry(&self, config: &Config) -> Result<Registry> {
        // `robot_id` is the robot type, as the Python server answers (`niryo`, `widowx`).
        let robot_type = self.hardware.arm_context.kinematics.model().robot_type();
        let mut settings = ToolSettings::new(robot_type, self.workspaces.clone());
        settings.skill_timeout = std::time::Duration::from_secs(config.mcp.skill_timeout_s);
        settings.max_label_chars = config.workspace.max_label_chars as usize;
        let health = self.health_source.clone();
        let safety = self.hardware.safety.clone();
        settings.status = Arc::new(move || {
            let report = health();
            let estop = safety.estop();
            serde_json::json!({
                "status": report.get("status"),
                "actors": report.get("actors"),
                "estop_engaged": estop.is_some(),
                "estop_reason": estop,
                "redis": report.get("redis"),
                "workspace_view": report.get("workspace_view"),
                "uptime_ms": report.get("uptime_ms"),
            })
        });
        Ok(Registry::connect(&self.bus, settings)?)
    }

    /// Stops everything, actors first, hardware last.
    pub async fn shutdown(self) {
        for process in &self.processes {
            if let Err(error) = process.stop().await {
                tracing::warn!(%error, "stopping an actor process");
            }
        }
        self.stt.stop();
        self.skills.shutdown().await;
        if let Some(redis) = self.redis {
            redis.shutdown().await;
        }
        if let Some(perception) = self.perception {
            perception.shutdown();
        }
        self.speech.shutdown().await;
        self.workspace_model.shutdown().await;
        self.hardware.shutdown().await;
        self.system.abort();
    }
}

/// The MCP service over `registry`, with the call log in the configured log directory.
fn mcp_service(config: &Config, registry: Registry) -> McpService {
    let (log, error) = CallLog::open(&config.telemetry.log_dir, config.mcp.call_log_limits());
    match (error, log.path()) {
        (Some(error), _) => tracing::warn!(
            %error,
            dir = %config.telemetry.log_dir.display(),
            "the MCP call log cannot be written; calls are only traced"
        ),
        (None, Some(path)) => tracing::info!(path = %path.display(), "MCP call log"),
        (None, None) => {}
    }
    McpService::new(registry, config.mcp.strict_errors, Arc::new(log))
}

/// `robotd serve`: the runtime, with `/health`, `/metrics` and the MCP edge on the HTTP port,
/// until SIGINT or SIGTERM.
pub async fn run(config: Config, config_file: Option<&std::path::Path>) -> Result<()> {
    match robotd_runtime::limits::raise_open_files_limit() {
        Ok(limit) if limit.before != limit.after => tracing::info!(
            before = limit.before,
            after = limit.after,
            "open-files limit raised to the hard limit"
        ),
        Ok(_) => {}
        Err(error) => tracing::warn!(%error, "the open-files limit could not be raised"),
    }
    // Before the first supervisor starts: each one joins the watchdog as it starts.
    crate::notify::install_watchdog();
    let runtime = Runtime::start(&config).await?;
    let agent = start_agent(&config, config_file, &runtime)?;
    let edge = HttpEdge::bind(config.http.bind, runtime.health_source.clone()).await?;
    let address = edge.local_addr()?;
    let guard = HttpGuard {
        token: config.mcp.token.clone().filter(|t| !t.trim().is_empty()),
        max_body_bytes: config.mcp.max_body_bytes,
        allowed_origins: config.mcp.allowed_origins.clone(),
        allowed_hosts: config.http.allowed_hosts.clone(),
        loopback: address.ip().is_loopback(),
    };
    robotd_http::guard::check_bind(address, &guard)?;
    let mut edge = edge.with_guard(guard).with_limits(config.http.limits());
    let stop_sessions = CancellationToken::new();
    if config.mcp.enabled {
        let service = mcp_service(&config, runtime.tool_registry(&config)?);
        edge = edge.with_routes(robotd_mcp::http::router(
            service,
            config.mcp.router_options(),
            stop_sessions.clone(),
        ));
    }
    edge = edge.with_routes(robotd_http::safety::router(runtime.safety_api()?));
    let dashboard = if config.dashboard.enabled {
        let (routes, live) = crate::dashboard::routes(&config, &runtime, &agent)?;
        edge = edge.with_routes(routes);
        Some(live)
    } else {
        None
    };
    let viewers = crate::foxglove::start(&config, &runtime).await?;
    tracing::info!("HTTP edge on http://{address} (/health, /metrics, MCP /sse and /mcp)");
    eprintln!(
        "robotd: serving on http://{address} ({}/health, /metrics{}); bus namespace '{}'",
        if config.dashboard.enabled {
            "dashboard: /, "
        } else {
            ""
        },
        if config.mcp.enabled {
            ", MCP: /sse and /mcp"
        } else {
            ""
        },
        config.bus.namespace
    );
    // The edge is bound and the hardware actors have said whether the robot is there.
    let status = crate::notify::status_line(&(runtime.health_source)(), &address.to_string());
    crate::notify::ready(&status);
    let status_updates = crate::notify::spawn_status_updates(
        runtime.health_source.clone(),
        address.to_string(),
        status,
    );
    let sessions = stop_sessions.clone();
    edge.serve(async move {
        shutdown_signal().await;
        crate::notify::stopping();
        sessions.cancel();
    })
    .await?;
    if let Some(updates) = status_updates {
        updates.abort();
    }
    tracing::info!("shutting down");
    if let Some(live) = dashboard {
        live.stop();
    }
    drop(viewers);
    drop(agent);
    runtime.shutdown().await;
    Ok(())
}

/// The LLM agent on the bus (`agent/request` → `agent/events`), when `[agent] serve` is on and
/// a provider is usable; otherwise why it is off (the robot runs either way).
fn start_agent(
    config: &Config,
    config_file: Option<&std::path::Path>,
    runtime: &Runtime,
) -> Result<Result<robotd_agent::actor::AgentActor, String>> {
    if !config.agent.serve {
        return Ok(Err(
            "the agent is switched off ([agent] serve = false)".to_owned()
        ));
    }
    let env = crate::chat::provider_env(config, config_file)?;
    let settings = match robotd_agent::providers::resolve(
        &config.agent.api,
        config.agent.model.as_deref(),
        &env,
    ) {
        Ok(settings) => settings,
        Err(reason) => {
            tracing::info!(%reason, "the LLM agent is off (robotd chat --mcp still works)");
            return Ok(Err(format!("no LLM provider is configured: {reason}")));
        }
    };
    let hints: Vec<robotd_agent::WorkspaceHint> = runtime
        .workspaces
        .iter()
        .map(robotd_agent::WorkspaceHint::from)
        .collect();
    let tools = robotd_agent::RegistryTools::new(runtime.tool_registry(config)?);
    let agent = robotd_agent::Agent::new(
        settings.clone(),
        Arc::new(tools),
        &hints,
        config.agent.agent_config(),
    )?;
    let actor = robotd_agent::actor::spawn(&runtime.bus, agent)?;
    tracing::info!(provider = %settings.provider, model = %settings.model, "LLM agent on the bus");
    Ok(Ok(actor))
}

/// `robotd mcp-stdio`: the runtime, serving MCP on stdin/stdout until the client closes it
/// (or SIGINT/SIGTERM). No HTTP port is opened, so it can run beside nothing else.
pub async fn run_stdio(config: Config) -> Result<()> {
    let runtime = Runtime::start(&config).await?;
    let service = mcp_service(&config, runtime.tool_registry(&config)?);
    tracing::info!("serving MCP on stdio");
    let served = tokio::select! {
        served = robotd_mcp::serve_stdio(service) => served,
        _ = shutdown_signal() => Ok(()),
    };
    runtime.shutdown().await;
    served
}

/// The in-process actors of this build (an `[actors.<name>]` table tunes their supervision).
const BUILT_IN_ACTORS: [&str; 4] = ["arm", "gripper", "camera", "tts"];

async fn start_process_actors(
    config: &Config,
    bus: &Bus,
    health: &Arc<HealthBoard>,
    restarts: &Arc<Mutex<Publisher<RestartEvent>>>,
) -> Result<Vec<SupervisedProcess>> {
    let mut processes = Vec::new();
    for (name, actor) in &config.actors {
        if actor.mode != ActorMode::Process {
            if BUILT_IN_ACTORS.contains(&name.as_str()) {
                continue; // its [actors.<name>] table only tunes its supervision
            }
            tracing::warn!(
                actor = %name,
                "no built-in actor of this name in this build; its [actors] entry is ignored"
            );
            continue;
        }
        let command = actor.command.clone();
        let namespace = config.bus.namespace.clone();
        let observer = supervision_observer(health.clone(), restarts.clone());
        let cleanup_bus = bus.clone();
        let process = Supervisor::new(name.clone())
            .policy(config.supervision_for(name).policy())
            .observer(observer)
            .on_restart_cleanup(move |_context| {
                // The process just died: segments it left half-created are too young for the
                // clean-up's own sweep, and iceoryx2 would wait on them forever.
                remove_half_created_after(Path::new(SHARED_MEMORY_DIR), || {
                    std::thread::sleep(HALF_CREATED_SETTLE)
                });
                let report = cleanup_bus.cleanup_dead_nodes_after_sweep();
                if report.failed > 0 {
                    return Err(format!(
                        "{} dead bus node(s) could not be removed",
                        report.failed
                    ));
                }
                Ok(())
            })
            .spawn_process(move || {
                let mut child = tokio::process::Command::new(&command[0]);
                child
                    .args(&command[1..])
                    .env("ROBOTD_BUS__NAMESPACE", &namespace);
                // systemd's notification socket is robotd's, not its children's.
                for var in crate::notify::NOTIFY_VARS {
                    child.env_remove(var);
                }
                #[cfg(target_os = "linux")]
                // SAFETY: prctl is async-signal-safe; the closure only calls it.
                unsafe {
                    // If robotd itself dies (even by SIGKILL), its actor processes get SIGTERM
                    // instead of running on as orphans.
                    child.pre_exec(|| {
                        libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
                        Ok(())
                    });
                }
                child
            })
            .await
            .with_context(|| format!("starting actor process '{name}'"))?;
        processes.push(process);
    }
    Ok(processes)
}

async fn shutdown_signal() {
    let interrupt = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        let mut terminate =
            match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
                Ok(signal) => signal,
                Err(error) => {
                    tracing::warn!(%error, "cannot listen for SIGTERM; use Ctrl-C");
                    let _ = interrupt.await;
                    return;
                }
            };
        tokio::select! {
            _ = interrupt => {}
            _ = terminate.recv() => {}
        }
    }
    #[cfg(not(unix))]
    {
        let _ = interrupt.await;
    }
}

/// Names this robotd in the Redis entries it writes: `<service>@<host>#<pid>`.
fn instance_id(service: &str) -> String {
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_owned())
        .unwrap_or_else(|_| "host".into());
    format!("{service}@{host}#{}", std::process::id())
}

/// The label table of the built-in detector: `[perception] labels` when set, else the
/// built-in `config/labels.toml`.
fn load_label_table(config: &Config) -> Result<LabelTable> {
    match &config.perception.labels {
        Some(path) => LabelTable::load(path).context("loading [perception] labels"),
        None => Ok(LabelTable::builtin()),
    }
}

/// Starts the workspace model (scene memory) for `workspaces`, with the built-in detector's
/// labels as the detectable ones.
pub fn start_workspace_model(
    bus: &Bus,
    workspaces: Vec<WorkspaceInfo>,
    labels: &LabelTable,
    config: &WorkspaceConfig,
) -> Result<WorkspaceModel> {
    Ok(WorkspaceModel::start(
        bus,
        WorkspaceModelSettings::from_config(workspaces, labels.labels(), config),
    )?)
}

/// Starts the skills actor (pick, place, push …) for the robot's workspaces.
fn start_skills(
    bus: &Bus,
    robot: RobotModel,
    workspaces: Vec<WorkspaceInfo>,
    safety: robotd_safety::Safety,
) -> Result<Skills> {
    let mut settings = SkillsSettings::new(robot, workspaces);
    settings.safety = Some(safety);
    Ok(Skills::start(bus, settings)?)
}

/// Starts the perception actor on the camera's frames.
fn start_perception(
    bus: &Bus,
    hardware: &Hardware,
    workspaces: Vec<WorkspaceInfo>,
    labels: LabelTable,
    settings: ColourDetectorSettings,
) -> Result<Perception> {
    let detector = ColourDetector::new(labels.clone(), settings);
    let pipeline = Pipeline::new(&hardware.camera_intrinsics, workspaces, Box::new(detector))
        .context("setting up perception")?;
    Ok(Perception::start(bus, pipeline, labels)?)
}

/// Starts the text-to-speech actor with the configured engine and output (falling back to the
/// `none` engine, with one warning, when no engine is available).
async fn start_speech(
    bus: &Bus,
    config: &Config,
    observer: impl SupervisionObserver,
) -> Result<Speech> {
    let key = std::env::var(robotd_speech::ELEVENLABS_KEY_VAR).ok();
    let (engine, warning) =
        robotd_speech::choose_engine(&config.tts, key.as_deref()).context("[tts] engine")?;
    if let Some(warning) = warning {
        tracing::warn!("{warning}");
    }
    let output = robotd_speech::choose_output(&config.tts).context("[tts] output")?;
    tracing::info!(engine = engine.name(), output = ?output, "speech engine chosen");
    Ok(Speech::start(
        bus,
        SpeechSettings {
            engine,
            output,
            scratch_dir: config.tts.spool_dir.clone(),
            queue_capacity: config.tts.queue_capacity,
            duplicate_window: std::time::Duration::from_millis(config.tts.duplicate_window_ms),
            policy: config.supervision_for("tts").policy(),
        },
        observer,
    )
    .await?)
}
