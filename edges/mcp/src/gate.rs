//! The order of an MCP session, enforced before the server sees a message.
//!
//! rmcp serves any request as soon as `initialize` was answered, and it runs notifications
//! and requests on separate tasks, so a check inside the tool handler would race with the
//! `notifications/initialized` it waits for. [`InitGate`] wraps a session's transport instead
//! and looks at the client's messages in the order they arrive:
//!
//! - until the client sends `notifications/initialized`, only `initialize` and `ping` pass;
//!   any other request is answered `-32600` (Invalid Request) and never reaches a tool — a
//!   motion cannot start in a half-open session;
//! - a request to a method MCP defines whose params do not fit it (rmcp would take it for an
//!   unknown custom method and answer `-32601`) is answered `-32602` (Invalid params), naming
//!   the method.
//!
//! Every transport (legacy SSE, streamable HTTP, stdio) serves through this gate.

use rmcp::model::{
    ClientJsonRpcMessage, ClientNotification, ClientRequest, ErrorCode, ErrorData, JsonRpcMessage,
    ServerJsonRpcMessage,
};
use rmcp::transport::{IntoTransport, Transport};
use rmcp::RoleServer;
use std::future::Future;

/// Methods MCP defines for a client to call; a message naming one whose params rmcp could
/// not read is a params error, not an unknown method.
const MCP_METHODS: &[&str] = &[
    "initialize",
    "ping",
    "tools/call",
    "tools/list",
    "prompts/get",
    "prompts/list",
    "resources/list",
    "resources/read",
    "resources/templates/list",
    "resources/subscribe",
    "resources/unsubscribe",
    "completion/complete",
    "logging/setLevel",
];

/// Whether `method` is one MCP defines for a client to call.
pub fn is_mcp_method(method: &str) -> bool {
    MCP_METHODS.contains(&method)
}

/// The `-32602` error for params that do not fit MCP `method`.
pub fn invalid_params(method: &str) -> ErrorData {
    ErrorData::new(
        ErrorCode::INVALID_PARAMS,
        format!(
            "invalid params for {method}: they do not match the MCP schema of this method \
             (tools/call needs {{\"name\": string, \"arguments\"?: object}})"
        ),
        None,
    )
}

/// A server transport that refuses requests out of order (see the module documentation).
pub struct InitGate<T> {
    inner: T,
    initialized: bool,
}

impl<T> InitGate<T> {
    /// Gates `inner`; the session starts uninitialised.
    pub fn new(inner: T) -> Self {
        Self {
            inner,
            initialized: false,
        }
    }
}

/// Gates anything rmcp accepts as a server transport (a sink/stream pair, stdio, …).
pub fn gated<E, A>(
    transport: impl IntoTransport<RoleServer, E, A>,
) -> InitGate<impl Transport<RoleServer, Error = E>>
where
    E: std::error::Error + Send + Sync + 'static,
{
    InitGate::new(transport.into_transport())
}

impl<T> InitGate<T> {
    /// The error answering `message`, when it must not reach the server.
    fn refusal(&mut self, message: &ClientJsonRpcMessage) -> Option<ServerJsonRpcMessage> {
        match message {
            JsonRpcMessage::Notification(n) => {
                if matches!(
                    n.notification,
                    ClientNotification::InitializedNotification(_)
                ) {
                    self.initialized = true;
                }
                None
            }
            JsonRpcMessage::Request(r) => {
                let error = match &r.request {
                    ClientRequest::CustomRequest(custom) if is_mcp_method(&custom.method) => {
                        invalid_params(&custom.method)
                    }
                    ClientRequest::InitializeRequest(_) | ClientRequest::PingRequest(_) => {
                        return None
                    }
                    request if !self.initialized => ErrorData::new(
                        ErrorCode::INVALID_REQUEST,
                        format!(
                            "{} before the session is initialized: send \
                             notifications/initialized after the initialize response first",
                            request.method()
                        ),
                        None,
                    ),
                    _ => return None,
                };
                Some(ServerJsonRpcMessage::error(error, Some(r.id.clone())))
            }
            _ => None,
        }
    }
}

impl<T: Transport<RoleServer>> Transport<RoleServer> for InitGate<T> {
    type Error = T::Error;

    fn send(
        &mut self,
        item: ServerJsonRpcMessage,
    ) -> impl Future<Output = Result<(), Self::Error>> + Send + 'static {
        self.inner.send(item)
    }

    async fn receive(&mut self) -> Option<ClientJsonRpcMessage> {
        loop {
            let message = self.inner.receive().await?;
            match self.refusal(&message) {
                None => return Some(message),
                Some(error) => {
                    tracing::info!(?error, "MCP request refused by the session gate");
                    if self.inner.send(error).await.is_err() {
                        return None;
                    }
                }
            }
        }
    }

    fn close(&mut self) -> impl Future<Output = Result<(), Self::Error>> + Send {
        self.inner.close()
    }
}
