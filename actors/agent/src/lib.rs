//! # robotd-agent: natural language to robot actions
//!
//! A person types "pick up the pencil and place it right next to the red cube"; an LLM plans
//! and calls robotd's tools; the robot does it. This crate is that agent, for any provider
//! (OpenAI, Groq, Gemini, Ollama, any OpenAI-compatible server) and any tool source (robotd's
//! registry in process, or an MCP server), used by `robotd chat` and served on the bus.
//!
//! ```no_run
//! # async fn demo() -> Result<(), Box<dyn std::error::Error>> {
//! use robotd_agent::{Agent, AgentConfig, ToolBackend};
//! use robotd_agent::providers::{resolve, Env};
//! use std::sync::Arc;
//!
//! # fn robot_tools() -> Arc<dyn ToolBackend> { unimplemented!() }
//! let settings = resolve("auto", None, &Env::from_process(None)?)?;
//! // robotd's registry in process (`RegistryTools`), or an MCP server
//! // (`robotd_mcp::agent_tools::McpTools::connect(url, token)` in the MCP edge).
//! let tools: Arc<dyn ToolBackend> = robot_tools();
//! let mut agent = Agent::new(settings, tools, &[], AgentConfig::default())?;
//! let cancel = tokio_util::sync::CancellationToken::new();
//! agent
//!     .run("Pick up the pencil and place it right next to the red cube", cancel, |event| {
//!         println!("{event:?}")
//!     })
//!     .await;
//! # Ok(()) }
//! ```
//!
//! ## Modules
//!
//! - [`providers`]: which LLM — names, keys (environment, `API_KEY` prefixes, `secrets.env`),
//!   base URLs, default models, `auto`.
//! - [`llm`]: the conversation's messages and the two wire formats (OpenAI chat completions,
//!   Ollama `/api/chat`), with retries, timeouts and a `llm.call` span per call.
//! - [`memory`]: the bounded conversation history.
//! - [`tools`]: the [`ToolBackend`] trait and the registry's implementation (the MCP one is in
//!   the MCP edge, `robotd_mcp::agent_tools`).
//! - [`vision`]: which models are sent the pictures tools return (`agent.images`).
//! - [`agent`]: the system prompt and the tool-calling loop.
//! - [`actor`]: the agent on the bus (`agent/request` → `agent/events`, `agent/cancel`).
//! - `mock` (feature `mock`, tests only): a scripted LLM server speaking the real wire formats.

pub mod config;
pub use config::AgentSection;

pub mod actor;
pub mod agent;
pub mod llm;
pub mod memory;
#[cfg(feature = "mock")]
pub mod mock;
pub mod providers;
pub mod tools;
pub mod vision;

pub use agent::{Agent, AgentConfig, WorkspaceHint};
pub use tools::{RegistryTools, ToolBackend, ToolResultText};
