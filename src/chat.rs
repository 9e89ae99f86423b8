//! `robotd chat`: talk to the robot in plain words through an LLM.
//!
//! Two modes: in process (the runtime starts here, as `robotd serve` would, without its
//! network edges) or as an MCP client of a running server (`--mcp URL`: robotd's own edge or
//! any other MCP robot server). `--command "…"` runs one request and exits (0 on an answer,
//! 1 otherwise); without it the chat is interactive (`quit`/`exit`/`q`, `tools`, `clear`,
//! `switch <provider> [model]`). The plan, every tool call and its result are printed as they
//! happen; the session's log goes to `<log_dir>/mcp_client_YYYYmmdd_HHMMSS.log`.

use anyhow::{Context, Result};
use clap::Args;
use robotd_agent::agent::WorkspaceHint;
use robotd_agent::providers::{resolve, Env, ProviderSettings};
use robotd_agent::{Agent, RegistryTools, ToolBackend};
use robotd_config::Config;
use robotd_mcp::agent_tools::McpTools;
use robotd_protocol::agent::AgentEventKind;
use std::io::Write;
use std::path::Path;
use std::process::ExitCode;
use std::sync::Arc;
use tokio::io::AsyncBufReadExt;
use tokio_util::sync::CancellationToken;

/// Options of `robotd chat`.
#[derive(Debug, Args)]
pub struct ChatArgs {
    /// The LLM provider: openai, groq, gemini, ollama, openai-compatible, or auto (the first
    /// whose key is set, in that order). Default: `[agent] api` of the configuration (auto).
    #[arg(long, value_name = "PROVIDER")]
    pub api: Option<String>,
    /// The model (default: `[agent] model`, else the provider's, e.g. gpt-4o-mini).
    #[arg(long)]
    pub model: Option<String>,
    /// Run this one request, print what happens, and exit (0 on an answer, 1 otherwise).
    #[arg(long, short = 'c', value_name = "TEXT")]
    pub command: Option<String>,
    /// Drive the MCP server at this URL (`…/sse` or `…/mcp`) instead of starting the runtime.
    #[arg(long, value_name = "URL")]
    pub mcp: Option<String>,
    /// Bearer token of the MCP server (default: `[mcp] token` of the configuration).
    #[arg(long, env = "ROBOTD_MCP_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
}

/// Where the agent's variables come from: the environment, then `secrets.env` next to the
/// config file (or in the working directory), then the base URLs of `[agent]`.
pub fn provider_env(config: &Config, config_file: Option<&Path>) -> Result<Env> {
    let secrets = config_file
        .and_then(Path::parent)
        .map(|dir| dir.join("secrets.env"))
        .unwrap_or_else(|| Path::new("secrets.env").to_owned());
    Ok(Env::from_process(Some(&secrets))?.with_defaults(config.agent.base_url_variables()))
}

/// Runs `robotd chat`.
pub fn run(config: Config, config_file: Option<&Path>, args: ChatArgs) -> Result<ExitCode> {
    let env = provider_env(&config, config_file)?;
    // Fail fast, before starting anything, when no provider can be used.
    let api = args.api.as_deref().unwrap_or(&config.agent.api);
    let model = args.model.as_deref().or(config.agent.model.as_deref());
    let settings = resolve(api, model, &env)?;
    // robotd's telemetry in its chat mode: warnings on the terminal, the session's file, and
    // OTLP export when configured (the agent's llm.call spans reach the collector).
    let log =
        robotd_runtime::telemetry::init(&config.telemetry, robotd_runtime::telemetry::Mode::Chat)?;
    tracing::info!(provider = %settings.provider, model = %settings.model, "robotd chat starting");
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    let log_path = log
        .session_file()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let code = runtime.block_on(session(config, env, settings, args, &log_path))?;
    drop(runtime);
    drop(log);
    Ok(code)
}

async fn session(
    config: Config,
    env: Env,
    settings: ProviderSettings,
    args: ChatArgs,
    log_path: &Path,
) -> Result<ExitCode> {
    let (tools, workspaces, robot, source): (
        Arc<dyn ToolBackend>,
        Vec<WorkspaceHint>,
        // The in-process runtime, stopped at the end (None with --mcp).
        Option<crate::serve::Runtime>,
        String,
    ) = match &args.mcp {
        Some(url) => {
            let token = args.token.clone().or(config.mcp.token.clone());
            let tools = McpTools::connect(url, token.as_deref())
                .await
                .with_context(|| format!("connecting to the MCP server at {url}"))?;
            let tools: Arc<dyn ToolBackend> = Arc::new(tools);
            let workspaces = probe_workspaces(tools.as_ref()).await;
            (tools, workspaces, None, url.clone())
        }
        None => {
            let runtime = crate::serve::Runtime::start(&config).await?;
            let registry = runtime.tool_registry(&config)?;
            let workspaces = runtime.workspaces.iter().map(WorkspaceHint::from).collect();
            (
                Arc::new(RegistryTools::new(registry)),
                workspaces,
                Some(runtime),
                "the robot in this process".to_owned(),
            )
        }
    };
    let mut agent = Agent::new(settings, tools, &workspaces, config.agent.agent_config())?;
    let code = match &args.command {
        Some(text) => single_shot(&mut agent, text).await,
        None => {
            eprintln!(
                "robotd chat: {} {} driving {} ({} tools). Log: {}\n\
                 Type a request, or: tools, clear, switch <provider> [model], quit.",
                agent.provider().provider,
                agent.provider().model,
                source,
                agent.tools().len(),
                log_path.display()
            );
            interactive(&mut agent, &env).await?;
            ExitCode::SUCCESS
        }
    };
    drop(agent);
    if let Some(runtime) = robot {
        runtime.shutdown().await;
    }
    Ok(code)
}

/// Asks the server for the corners of the usual workspaces (robotd's sim and real robots).
async fn probe_workspaces(tools: &dyn ToolBackend) -> Vec<WorkspaceHint> {
    if !tools
        .tools()
        .iter()
        .any(|t| t.name == "get_workspace_coordinate_from_point")
    {
        return Vec::new();
    }
    let corner = |text: &str| -> Option<[f64; 2]> {
        let inner = text.rsplit('[').next()?.split(']').next()?;
        let mut parts = inner.split(',').map(|p| p.trim().parse::<f64>());
        Some([parts.next()?.ok()?, parts.next()?.ok()?])
    };
    let mut found = Vec::new();
    for id in ["niryo_ws", "widowx_ws"] {
        let mut points = Vec::new();
        for point in ["upper left corner", "lower right corner"] {
            let mut args = serde_json::Map::new();
            args.insert("workspace_id".into(), id.into());
            args.insert("point".into(), point.into());
            let result = tools
                .call(
                    "get_workspace_coordinate_from_point",
                    args,
                    CancellationToken::new(),
                )
                .await;
            if let Some(xy) = result.ok.then(|| corner(&result.text)).flatten() {
                points.push(xy);
            }
        }
        if let [upper_left, lower_right] = points[..] {
            found.push(WorkspaceHint {
                id: id.to_owned(),
                upper_left,
                lower_right,
            });
        }
    }
    found
}

fn print_out(text: &str) {
    let mut out = std::io::stdout().lock();
    let _ = out.write_all(text.as_bytes()).and_then(|_| out.flush());
}

/// Shows one event the way a person follows the agent's work.
pub(crate) fn show(event: &AgentEventKind) {
    match event {
        AgentEventKind::Plan { text } => print_out(&format!("Plan: {text}\n")),
        AgentEventKind::ToolCall {
            name,
            arguments_json,
            ..
        } => print_out(&format!("→ {name} {arguments_json}\n")),
        AgentEventKind::ToolResult { text, .. } => {
            let mut shown: String = text.chars().take(1200).collect();
            if text.chars().count() > 1200 {
                shown.push_str(" …");
            }
            print_out(&format!("← {}\n", shown.replace('\n', "\n  ")));
        }
        AgentEventKind::Picture {
            name,
            mime_type,
            data_base64,
            ..
        } => print_out(&format!(
            "  ({name} returned a picture: {mime_type}, {} kB)\n",
            data_base64.len() * 3 / 4 / 1000
        )),
        AgentEventKind::Answer { text } => print_out(&format!("Answer: {text}\n")),
        AgentEventKind::Error { message } => eprintln!("robotd chat: error: {message}"),
        AgentEventKind::Cancelled => eprintln!("robotd chat: cancelled"),
    }
}

/// Runs `text` with Ctrl-C cancelling it; returns the terminal event.
async fn run_request(agent: &mut Agent, text: &str) -> AgentEventKind {
    let cancel = CancellationToken::new();
    let on_signal = cancel.clone();
    let watcher = tokio::spawn(async move {
        if tokio::signal::ctrl_c().await.is_ok() {
            on_signal.cancel();
        }
    });
    let end = agent.run(text, cancel, |event| show(&event)).await;
    watcher.abort();
    end
}

async fn single_shot(agent: &mut Agent, text: &str) -> ExitCode {
    match run_request(agent, text).await {
        AgentEventKind::Answer { .. } => ExitCode::SUCCESS,
        _ => ExitCode::FAILURE,
    }
}

async fn interactive(agent: &mut Agent, env: &Env) -> Result<()> {
    let mut lines = tokio::io::BufReader::new(tokio::io::stdin()).lines();
    loop {
        print_out("> ");
        let line = tokio::select! {
            line = lines.next_line() => line.context("reading stdin")?,
            _ = tokio::signal::ctrl_c() => None,
        };
        let Some(line) = line else {
            print_out("\n");
            return Ok(());
        };
        let line = line.trim();
        let mut words = line.split_whitespace();
        match words.next().map(str::to_ascii_lowercase).as_deref() {
            None => continue,
            Some("quit" | "exit" | "q") => return Ok(()),
            Some("tools") => {
                let mut listing = String::new();
                for tool in agent.tools() {
                    let first = tool.description.split(". ").next().unwrap_or("");
                    listing.push_str(&format!("  {:38} {first}\n", tool.name));
                }
                print_out(&listing);
            }
            Some("clear") => {
                agent.clear();
                print_out("Conversation cleared.\n");
            }
            Some("switch") => {
                let Some(provider) = words.next() else {
                    print_out("usage: switch <provider> [model]\n");
                    continue;
                };
                let model = words.next();
                match resolve(provider, model, env) {
                    Ok(settings) => match agent.switch(settings) {
                        Ok(()) => print_out(&format!(
                            "Now using {} {} (the conversation is kept).\n",
                            agent.provider().provider,
                            agent.provider().model
                        )),
                        Err(error) => eprintln!("robotd chat: {error}"),
                    },
                    Err(error) => eprintln!("robotd chat: {error}"),
                }
            }
            Some(_) => {
                run_request(agent, line).await;
            }
        }
    }
}
