//! Where the agent's tools come from: one small trait, [`ToolBackend`], with two
//! implementations — the in-process tool registry ([`RegistryTools`], robotd's own 24 tools
//! over the bus) and any MCP server (`robotd_mcp::agent_tools::McpTools`, SSE or streamable HTTP,
//! in the MCP edge), so the same agent drives robotd in process, a robotd elsewhere, or
//! another MCP robot server.
//!
//! A call takes a [`CancellationToken`]: cancelling it stops the running call — the registry
//! stops the motion and holds the arm; the MCP client sends `notifications/cancelled`, on
//! which robotd's edge does the same.

use crate::llm::ToolSpec;
use crate::vision::ImagePart;
use robotd_protocol::safety::{Origin, OriginKind};
use robotd_runtime::origin::{current_origin, with_origin};
use serde_json::{Map, Value};
use std::future::Future;
use std::pin::Pin;
use tokio_util::sync::CancellationToken;

/// The outcome of one tool call, as the model will read it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ToolResultText {
    /// The reply text (robotd's tools say `✓ …` or `❌ …`).
    pub text: String,
    /// Whether the call succeeded.
    pub ok: bool,
    /// Pictures that came with the text (`get_camera_image`); sent on only to models that
    /// take images ([`crate::vision`]).
    pub images: Vec<ImagePart>,
}

impl ToolResultText {
    /// A call's text, without pictures.
    pub fn new(text: impl Into<String>, ok: bool) -> Self {
        Self {
            text: text.into(),
            ok,
            images: Vec::new(),
        }
    }

    /// A failed call with this explanation.
    pub fn failed(text: impl Into<String>) -> Self {
        Self::new(text, false)
    }
}

/// A boxed future, so the trait stays object-safe without extra crates.
pub type BoxFuture<'a, T> = Pin<Box<dyn Future<Output = T> + Send + 'a>>;

/// A set of tools the agent may call.
pub trait ToolBackend: Send + Sync {
    /// The tools, as the model sees them.
    fn tools(&self) -> Vec<ToolSpec>;

    /// Calls `name` with `arguments`; cancelling `cancel` stops the call. Never fails: a
    /// problem is a failed [`ToolResultText`] the model can read and react to.
    fn call<'a>(
        &'a self,
        name: &'a str,
        arguments: Map<String, Value>,
        cancel: CancellationToken,
    ) -> BoxFuture<'a, ToolResultText>;
}

/// robotd's tool registry, in process.
#[derive(Debug, Clone)]
pub struct RegistryTools {
    registry: robotd_tools::Registry,
}

impl RegistryTools {
    /// Wraps a connected registry.
    pub fn new(registry: robotd_tools::Registry) -> Self {
        Self { registry }
    }
}

/// The tool specs of robotd's registry definitions.
pub fn specs_of(tools: &[robotd_tools::ToolInfo]) -> Vec<ToolSpec> {
    tools
        .iter()
        .map(|t| ToolSpec {
            name: t.name.to_owned(),
            description: t.description.to_owned(),
            parameters: t.input_schema.clone(),
        })
        .collect()
}

impl ToolBackend for RegistryTools {
    fn tools(&self) -> Vec<ToolSpec> {
        specs_of(self.registry.tools())
    }

    fn call<'a>(
        &'a self,
        name: &'a str,
        arguments: Map<String, Value>,
        cancel: CancellationToken,
    ) -> BoxFuture<'a, ToolResultText> {
        Box::pin(async move {
            let hooks = robotd_tools::CallHooks {
                progress: None,
                cancel,
            };
            // The agent's calls are an LLM's: keep the request's origin if the agent actor
            // set one, else name the agent (`robotd chat` in process).
            let origin = match current_origin() {
                origin if origin.kind == OriginKind::Agent => origin,
                _ => Origin::new(OriginKind::Agent).session("chat"),
            };
            match with_origin(origin, self.registry.call(name, Some(arguments), hooks)).await {
                Ok(out) => ToolResultText {
                    ok: !out.is_failure,
                    images: out
                        .images
                        .iter()
                        .map(|i| ImagePart {
                            mime_type: i.mime_type.to_owned(),
                            data_base64: i.base64(),
                        })
                        .collect(),
                    text: out.text,
                },
                Err(error) => ToolResultText::failed(format!("❌ {error}")),
            }
        })
    }
}
