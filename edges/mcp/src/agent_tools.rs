//! The tools of any MCP server as a [`ToolBackend`] (the agent's tool source; the trait is
//! `robotd_tools::backend`'s): `robotd chat --mcp URL` drives a robotd elsewhere, or another MCP
//! robot server, with the same agent as in process.
//! Cancelling a call sends `notifications/cancelled`, on which robotd's edge stops the motion.

use crate::client::McpClient;
use rmcp::model::CallToolRequestParams;
use robotd_tools::backend::{BoxFuture, ImagePart, ToolBackend, ToolResultText, ToolSpec};
use serde_json::{Map, Value};
use tokio_util::sync::CancellationToken;

/// Why the MCP tools could not be listed.
#[derive(Debug, thiserror::Error)]
pub enum McpToolsError {
    /// Connecting failed.
    #[error(transparent)]
    Connect(#[from] crate::client::ConnectError),
    /// `tools/list` failed.
    #[error("{url}: listing the tools failed: {reason}")]
    List {
        /// The server.
        url: String,
        /// Why.
        reason: String,
    },
}

/// The tools of an MCP server.
pub struct McpTools {
    client: McpClient,
    tools: Vec<ToolSpec>,
    url: String,
}

impl std::fmt::Debug for McpTools {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McpTools")
            .field("url", &self.url)
            .field("tools", &self.tools.len())
            .finish()
    }
}

impl McpTools {
    /// Connects to the MCP server at `url` (`…/sse` for legacy SSE, else streamable HTTP) and
    /// lists its tools.
    pub async fn connect(url: &str, token: Option<&str>) -> Result<McpTools, McpToolsError> {
        let client = crate::client::connect(url, token).await?;
        let listed = client
            .list_all_tools()
            .await
            .map_err(|e| McpToolsError::List {
                url: url.to_owned(),
                reason: e.to_string(),
            })?;
        let tools = listed
            .into_iter()
            .map(|t| ToolSpec {
                name: t.name.to_string(),
                description: t.description.as_deref().unwrap_or("").to_owned(),
                parameters: (*t.input_schema).clone(),
            })
            .collect();
        Ok(McpTools {
            client,
            tools,
            url: url.to_owned(),
        })
    }

    /// The server's URL.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// Closes the session.
    pub async fn close(self) {
        let _ = self.client.cancel().await;
    }
}

impl ToolBackend for McpTools {
    fn tools(&self) -> Vec<ToolSpec> {
        self.tools.clone()
    }

    fn call<'a>(
        &'a self,
        name: &'a str,
        arguments: Map<String, Value>,
        cancel: CancellationToken,
    ) -> BoxFuture<'a, ToolResultText> {
        Box::pin(async move {
            let params = CallToolRequestParams::new(name.to_owned()).with_arguments(arguments);
            // Dropping the call's future sends `notifications/cancelled` to the server.
            let result = tokio::select! {
                r = self.client.peer().call_tool(params) => r,
                _ = cancel.cancelled() => {
                    return ToolResultText::failed(format!("❌ {name} was cancelled"));
                }
            };
            match result {
                Ok(result) => {
                    let text = result
                        .content
                        .iter()
                        .filter_map(|c| c.as_text().map(|t| t.text.clone()))
                        .collect::<Vec<_>>()
                        .join("\n");
                    let failed = result.is_error == Some(true) || text.starts_with('❌');
                    let images = result
                        .content
                        .iter()
                        .filter_map(|c| c.as_image())
                        .map(|i| ImagePart {
                            mime_type: i.mime_type.clone(),
                            data_base64: i.data.clone(),
                        })
                        .collect();
                    ToolResultText {
                        text,
                        ok: !failed,
                        images,
                    }
                }
                Err(error) => ToolResultText::failed(format!(
                    "❌ calling {name} on {} failed: {error}",
                    self.url
                )),
            }
        })
    }
}
