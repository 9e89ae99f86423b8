//! The order of an MCP session, enforced before the server sees a message.
//!
//! rmcp serves any request as soon as `initialize` was answered, and it runs notifications
//! and requests on separate tasks, so a check inside the tool handler would race with the
//! `notifications/initialized` it waits for. [`InitGate`] wraps a session's transport instead
//! and looks at the client's messages in the order they arrive:
//!
//! - before `initialize`, a `ping` is answered here (rmcp's handshake would end the session
//!   on anything but `initialize`), other requests get `-32600` and notifications are
//!   dropped: a confused first message does not close the session;
//! - until the client sends `notifications/initialized`, only `initialize` and `ping` pass;
//!   any other request is answered `-32600` (Invalid Request) and never reaches a tool — a
//!   motion cannot start in a half-open session;
//! - a request to a method MCP defines whose params do not fit it (rmcp would take it for an
//!   unknown custom method and answer `-32601`) is answered `-32602` (Invalid params), naming
//!   the method;
//! - except a `tools/call` of a tool that acts whatever it is sent
//!   ([`robotd_tools::ALWAYS_ACTS`]: `emergency_stop`) whose `arguments` are not an object: it
//!   is passed on as a call with those arguments wrapped under
//!   [`robotd_tools::ARGUMENTS_NOT_AN_OBJECT`], so the stop engages and its reply says what was
//!   wrong ([`always_acting_call`]).
//!
//! Every transport (legacy SSE, streamable HTTP, stdio) serves through this gate. The
//! session's "initialized" state is shared ([`InitGate::initialized_flag`]) so the direct
//! streamable-HTTP path (`crate::http::direct_call`) applies the same rule.

use rmcp::model::{
    ClientJsonRpcMessage, ClientNotification, ClientRequest, EmptyResult, ErrorCode, ErrorData,
    JsonRpcMessage, ServerJsonRpcMessage, ServerResult,
};
use rmcp::transport::{IntoTransport, Transport};
use rmcp::RoleServer;
use std::future::Future;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

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

/// A `tools/call` of a tool that acts whatever it is sent ([`robotd_tools::ALWAYS_ACTS`]) whose
/// params rmcp could not read because its `arguments` are not an object: the same call, with
/// the arguments wrapped under [`robotd_tools::ARGUMENTS_NOT_AN_OBJECT`] (the tool says what
/// was wrong). `None` for anything else.
pub fn always_acting_call(
    method: &str,
    params: Option<&serde_json::Value>,
) -> Option<serde_json::Value> {
    if method != "tools/call" {
        return None;
    }
    let params = params?.as_object()?;
    let name = params.get("name")?.as_str()?;
    if !robotd_tools::ALWAYS_ACTS.contains(&name) {
        return None;
    }
    let mut params = params.clone();
    match params.get("arguments") {
        None | Some(serde_json::Value::Null) | Some(serde_json::Value::Object(_)) => {}
        Some(other) => {
            let wrapped = serde_json::json!({ robotd_tools::ARGUMENTS_NOT_AN_OBJECT: other });
            params.insert("arguments".into(), wrapped);
        }
    }
    Some(serde_json::Value::Object(params))
}

/// `message` with an [`always_acting_call`] made readable; any other message unchanged.
fn readable(message: ClientJsonRpcMessage) -> ClientJsonRpcMessage {
    let JsonRpcMessage::Request(request) = &message else {
        return message;
    };
    let ClientRequest::CustomRequest(custom) = &request.request else {
        return message;
    };
    let Some(params) = always_acting_call(&custom.method, custom.params.as_ref()) else {
        return message;
    };
    let value = serde_json::json!({
        "jsonrpc": "2.0",
        "id": request.id,
        "method": custom.method,
        "params": params,
    });
    match serde_json::from_value::<ClientJsonRpcMessage>(value) {
        Ok(call @ JsonRpcMessage::Request(_)) => {
            tracing::warn!(method = %custom.method, "a malformed call of a tool that always acts, passed on");
            call
        }
        _ => message,
    }
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
    initialize_seen: bool,
    initialized: Arc<AtomicBool>,
}

impl<T> InitGate<T> {
    /// Gates `inner`; the session starts uninitialised.
    pub fn new(inner: T) -> Self {
        Self {
            inner,
            initialize_seen: false,
            initialized: Arc::default(),
        }
    }

    /// True once the client sent `notifications/initialized` (after `initialize`); shared
    /// with whoever else answers this session's requests.
    pub fn initialized_flag(&self) -> Arc<AtomicBool> {
        self.initialized.clone()
    }
}

/// What the gate does with a client message.
enum Verdict {
    /// Hand it to the server.
    Pass,
    /// Answer it here and hold it back.
    Answer(Box<ServerJsonRpcMessage>),
    /// Drop it (a notification or response before `initialize`).
    Drop,
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
    /// What to do with `message`.
    fn verdict(&mut self, message: &ClientJsonRpcMessage) -> Verdict {
        if !self.initialize_seen {
            return match message {
                JsonRpcMessage::Request(r) => match &r.request {
                    ClientRequest::InitializeRequest(_) => {
                        self.initialize_seen = true;
                        Verdict::Pass
                    }
                    ClientRequest::PingRequest(_) => {
                        Verdict::Answer(Box::new(ServerJsonRpcMessage::response(
                            ServerResult::EmptyResult(EmptyResult {}),
                            r.id.clone(),
                        )))
                    }
                    request => Verdict::Answer(Box::new(ServerJsonRpcMessage::error(
                        ErrorData::new(
                            ErrorCode::INVALID_REQUEST,
                            format!(
                                "{} before initialize: a session starts with an initialize \
                                 request",
                                request.method()
                            ),
                            None,
                        ),
                        Some(r.id.clone()),
                    ))),
                },
                _ => Verdict::Drop,
            };
        }
        match self.refusal(message) {
            None => Verdict::Pass,
            Some(error) => Verdict::Answer(Box::new(error)),
        }
    }

    /// The error answering `message`, when it must not reach the server.
    fn refusal(&mut self, message: &ClientJsonRpcMessage) -> Option<ServerJsonRpcMessage> {
        match message {
            JsonRpcMessage::Notification(n) => {
                if matches!(
                    n.notification,
                    ClientNotification::InitializedNotification(_)
                ) {
                    self.initialized.store(true, Ordering::Release);
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
                    request if !self.initialized.load(Ordering::Acquire) => ErrorData::new(
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
            let message = readable(self.inner.receive().await?);
            match self.verdict(&message) {
                Verdict::Pass => return Some(message),
                Verdict::Drop => tracing::trace!("MCP message dropped by the session gate"),
                Verdict::Answer(answer) => {
                    tracing::info!(?answer, "MCP request answered by the session gate");
                    if self.inner.send(*answer).await.is_err() {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn message(value: serde_json::Value) -> ClientJsonRpcMessage {
        serde_json::from_value(value).unwrap()
    }

    fn answer(gate: &mut InitGate<()>, value: serde_json::Value) -> Option<serde_json::Value> {
        match gate.verdict(&message(value)) {
            Verdict::Pass => None,
            Verdict::Drop => Some(serde_json::json!("dropped")),
            Verdict::Answer(a) => Some(serde_json::to_value(*a).unwrap()),
        }
    }

    #[test]
    fn a_session_goes_initialize_then_initialized_then_anything() {
        let mut gate = InitGate::new(());
        let call = serde_json::json!({"jsonrpc": "2.0", "id": 2, "method": "tools/call",
            "params": {"name": "speak", "arguments": {"text": "hi"}}});
        // Before initialize: a call is refused, a ping answered, a notification dropped.
        let refused = answer(&mut gate, call.clone()).unwrap();
        assert_eq!(refused["error"]["code"], -32600, "{refused}");
        let pong = answer(
            &mut gate,
            serde_json::json!({"jsonrpc": "2.0", "id": 3, "method": "ping"}),
        )
        .unwrap();
        assert_eq!(pong["result"], serde_json::json!({}), "{pong}");
        let initialized =
            serde_json::json!({"jsonrpc": "2.0", "method": "notifications/initialized"});
        assert_eq!(
            answer(&mut gate, initialized.clone()),
            Some(serde_json::json!("dropped"))
        );
        // initialize passes; a call before initialized is still refused.
        let init = serde_json::json!({"jsonrpc": "2.0", "id": 1, "method": "initialize", "params": {
            "protocolVersion": "2025-06-18", "capabilities": {}, "clientInfo": {"name": "t", "version": "1"}}});
        assert_eq!(answer(&mut gate, init), None);
        assert_eq!(
            answer(&mut gate, call.clone()).unwrap()["error"]["code"],
            -32600
        );
        // After initialized the call passes; malformed params are -32602.
        assert_eq!(answer(&mut gate, initialized), None);
        assert_eq!(answer(&mut gate, call), None);
        let bad = serde_json::json!({"jsonrpc": "2.0", "id": 4, "method": "tools/call", "params": {"x": 1}});
        assert_eq!(answer(&mut gate, bad).unwrap()["error"]["code"], -32602);
    }

    #[test]
    fn an_estop_whose_arguments_are_not_an_object_is_passed_on_wrapped() {
        for arguments in [
            serde_json::json!(5),
            serde_json::json!("stop"),
            serde_json::json!([1]),
        ] {
            let call = message(
                serde_json::json!({"jsonrpc": "2.0", "id": 9, "method": "tools/call",
                "params": {"name": "emergency_stop", "arguments": arguments}}),
            );
            let JsonRpcMessage::Request(r) = readable(call) else {
                panic!("not a request")
            };
            assert_eq!(r.id, rmcp::model::RequestId::Number(9));
            let ClientRequest::CallToolRequest(c) = r.request else {
                panic!("not a call: {:?}", r.request)
            };
            assert_eq!(c.params.name, "emergency_stop");
            assert_eq!(
                c.params.arguments.unwrap()[robotd_tools::ARGUMENTS_NOT_AN_OBJECT],
                arguments
            );
        }
        // Another tool's bad arguments stay a params error.
        let call = message(
            serde_json::json!({"jsonrpc": "2.0", "id": 9, "method": "tools/call",
            "params": {"name": "speak", "arguments": 5}}),
        );
        let JsonRpcMessage::Request(r) = readable(call) else {
            panic!("not a request")
        };
        assert!(
            matches!(r.request, ClientRequest::CustomRequest(_)),
            "{:?}",
            r.request
        );
    }

    #[test]
    fn the_flag_follows_the_session() {
        let mut gate = InitGate::new(());
        let flag = gate.initialized_flag();
        let init = serde_json::json!({"jsonrpc": "2.0", "id": 1, "method": "initialize", "params": {
            "protocolVersion": "2025-06-18", "capabilities": {}, "clientInfo": {"name": "t", "version": "1"}}});
        assert_eq!(answer(&mut gate, init), None);
        assert!(
            !flag.load(Ordering::Acquire),
            "initialize alone does not initialize"
        );
        let initialized =
            serde_json::json!({"jsonrpc": "2.0", "method": "notifications/initialized"});
        assert_eq!(answer(&mut gate, initialized), None);
        assert!(flag.load(Ordering::Acquire));
    }
}
