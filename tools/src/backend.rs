//! A source of tools for an LLM: the [`ToolBackend`] trait and the plain data it speaks
//! ([`ToolSpec`], [`ToolResultText`], [`ImagePart`]). The agent (`robotd-agent`) drives any
//! backend; robotd's registry in process (`robotd_agent::RegistryTools`) and any MCP server
//! (`robotd_mcp::agent_tools::McpTools`, in the MCP edge) implement it. It lives here, below
//! both, so that the MCP edge need not depend on the agent.
//!
//! A call takes a [`CancellationToken`]: cancelling it stops the running call — the registry
//! stops the motion and holds the arm; the MCP client sends `notifications/cancelled`, on
//! which robotd's edge does the same.

use serde_json::{Map, Value};
use std::future::Future;
use std::pin::Pin;
use tokio_util::sync::CancellationToken;

/// A tool as the model sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolSpec {
    /// Name.
    pub name: String,
    /// What it does.
    pub description: String,
    /// JSON Schema of the arguments.
    pub parameters: Map<String, Value>,
}

/// The tool specs of robotd's registry definitions.
pub fn specs_of(tools: &[crate::ToolInfo]) -> Vec<ToolSpec> {
    tools
        .iter()
        .map(|t| ToolSpec {
            name: t.name.to_owned(),
            description: t.description.to_owned(),
            parameters: t.input_schema.clone(),
        })
        .collect()
}

/// One picture a tool returned, as the model is sent it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ImagePart {
    /// `image/jpeg`.
    pub mime_type: String,
    /// The file, standard base64.
    pub data_base64: String,
}

impl ImagePart {
    /// The `data:` URL of OpenAI's `image_url` parts.
    pub fn data_url(&self) -> String {
        format!("data:{};base64,{}", self.mime_type, self.data_base64)
    }
}

/// The outcome of one tool call, as the model will read it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ToolResultText {
    /// The reply text (robotd's tools say `✓ …` or `❌ …`).
    pub text: String,
    /// Whether the call succeeded.
    pub ok: bool,
    /// Pictures that came with the text (`get_camera_image`); the agent sends them on only to
    /// models that take images.
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

/// A set of tools an LLM may call.
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
