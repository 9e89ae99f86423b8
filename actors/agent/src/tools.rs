//! Where the agent's tools come from: one small trait, [`ToolBackend`] (defined in
//! `robotd_tools::backend`, below the agent and the MCP edge, and re-exported here), with two
//! implementations — the in-process tool registry ([`RegistryTools`], robotd's own 24 tools
//! over the bus) and any MCP server (`robotd_mcp::agent_tools::McpTools`, SSE or streamable HTTP,
//! in the MCP edge), so the same agent drives robotd in process, a robotd elsewhere, or
//! another MCP robot server.
//!
//! A call takes a [`CancellationToken`]: cancelling it stops the running call — the registry
//! stops the motion and holds the arm; the MCP client sends `notifications/cancelled`, on
//! which robotd's edge does the same.

use robotd_protocol::safety::{Origin, OriginKind};
use robotd_runtime::origin::{current_origin, with_origin};
pub use robotd_tools::backend::{
    specs_of, BoxFuture, ImagePart, ToolBackend, ToolResultText, ToolSpec,
};
use serde_json::{Map, Value};
use tokio_util::sync::CancellationToken;

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
