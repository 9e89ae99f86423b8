//! The MCP server handler: the tool registry as MCP `tools/list` and `tools/call`.
//!
//! One [`McpService`] value serves every transport (each session gets a clone). A call
//! becomes one [`Registry::call`]: its text is the first text content item, and
//! `structuredContent` is `{"result": text, "data": …}` matching each tool's `outputSchema`;
//! a tool's pictures (`get_camera_image`) follow the text as `ImageContent` items. The camera
//! is also a resource, `camera://{workspace_id}/latest` ([`crate::resources`]), read through
//! the same call path.
//! A client's progress token turns the skills' steps into `notifications/progress`; a
//! `notifications/cancelled` (or a client that goes away) cancels the call, which stops the
//! arm. Failures are ordinary results unless `strict_errors` sets `isError` on them.

use crate::call_log::{CallLog, CallRecord};
use crate::sessions::CallScopes;
use rmcp::model::{
    CallToolRequestParams, CallToolResponse, CallToolResult, ContentBlock, Implementation,
    ListResourceTemplatesResult, ListResourcesResult, ListToolsResult, PaginatedRequestParams,
    ProgressNotificationParam, ProgressToken, ReadResourceRequestParams, ReadResourceResponse,
    ServerCapabilities, ServerConfig, Tool,
};
use rmcp::service::RequestContext;
use rmcp::{ErrorData as McpError, RoleServer, ServerHandler};
use robotd_protocol::safety::{Origin, OriginKind};
use robotd_runtime::origin::with_origin;
use robotd_tools::{CallError, CallHooks, Progress, Registry};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;
use tokio_util::sync::CancellationToken;
use tracing::Instrument;

/// What the MCP edge serves and how.
#[derive(Clone)]
pub struct McpService {
    registry: Registry,
    tools: Arc<Vec<Tool>>,
    strict_errors: bool,
    log: Arc<CallLog>,
    transport: &'static str,
    scopes: Arc<CallScopes>,
    /// The legacy SSE session this clone serves (streamable HTTP names it per request).
    sse_session: Option<String>,
}

impl std::fmt::Debug for McpService {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McpService")
            .field("tools", &self.tools.len())
            .field("strict_errors", &self.strict_errors)
            .field("transport", &self.transport)
            .finish()
    }
}

impl McpService {
    /// A service over `registry`, logging every call to `log`.
    pub fn new(registry: Registry, strict_errors: bool, log: Arc<CallLog>) -> Self {
        let tools = registry
            .tools()
            .iter()
            .map(|t| {
                Tool::new(t.name, t.description, Arc::new(t.input_schema.clone()))
                    .with_raw_output_schema(Arc::new(t.output_schema.clone()))
            })
            .collect();
        Self {
            registry,
            tools: Arc::new(tools),
            strict_errors,
            log,
            transport: "unknown",
            scopes: Arc::default(),
            sse_session: None,
        }
    }

    /// The session and request tokens this service's calls are cancelled by.
    pub fn scopes(&self) -> Arc<CallScopes> {
        self.scopes.clone()
    }

    /// The same service for legacy SSE session `id` (its calls stop when the stream closes).
    pub fn for_sse_session(&self, id: &str) -> Self {
        self.scopes.session(id);
        Self {
            transport: "sse",
            sse_session: Some(id.to_owned()),
            ..self.clone()
        }
    }

    /// The session a call belongs to: the SSE session, or streamable HTTP's
    /// `Mcp-Session-Id` header.
    fn session_of(&self, context: &RequestContext<RoleServer>) -> Option<String> {
        if let Some(id) = &self.sse_session {
            return Some(id.clone());
        }
        context
            .extensions
            .get::<axum::http::request::Parts>()
            .and_then(|parts| parts.headers.get("mcp-session-id"))
            .and_then(|v| v.to_str().ok())
            .map(str::to_owned)
    }

    /// What cancels a call: the client (`notifications/cancelled`), its session closing, or
    /// its connection dropping. The future resolves when one of them happens.
    fn cancellation(
        &self,
        by_client: CancellationToken,
        session: Option<&str>,
        request: &str,
    ) -> impl std::future::Future<Output = ()> + Send + 'static {
        let by_session = session.and_then(|s| self.scopes.find_session(s));
        let by_connection = session.and_then(|s| self.scopes.find_request(s, request));
        async move {
            let session_closed = async {
                match by_session {
                    Some(t) => t.cancelled().await,
                    None => std::future::pending().await,
                }
            };
            let connection_dropped = async {
                match by_connection {
                    Some(t) => t.cancelled().await,
                    None => std::future::pending().await,
                }
            };
            tokio::select! {
                _ = by_client.cancelled() => {}
                _ = session_closed => tracing::info!("the MCP session closed: cancelling its call"),
                _ = connection_dropped => {}
            }
        }
    }

    /// The same service, naming `transport` (`sse`, `streamable_http`, `stdio`) in spans and
    /// the call log.
    pub fn for_transport(&self, transport: &'static str) -> Self {
        Self {
            transport,
            ..self.clone()
        }
    }
}

impl ServerHandler for McpService {
    fn get_info(&self) -> ServerConfig {
        ServerConfig::new(
            ServerCapabilities::builder()
                .enable_resources()
                .enable_tools()
                .build(),
        )
        .with_server_info(Implementation::new("robotd", env!("CARGO_PKG_VERSION")))
        .with_instructions(
            "Tools of a tabletop robot arm with a wrist camera. Coordinates are [x, y] in \
                 metres in the robot base frame: x forward (away from the robot), y left. Look \
                 at the scene with get_detected_objects before picking; push_object distances \
                 are millimetres, move2by distances metres. get_camera_image shows the table \
                 with object ids; label_object names an object the detector cannot.",
        )
    }

    async fn list_tools(
        &self,
        _request: Option<PaginatedRequestParams>,
        _context: RequestContext<RoleServer>,
    ) -> Result<ListToolsResult, McpError> {
        Ok(ListToolsResult::with_all_items(self.tools.as_ref().clone()))
    }

    async fn list_resources(
        &self,
        _request: Option<PaginatedRequestParams>,
        _context: RequestContext<RoleServer>,
    ) -> Result<ListResourcesResult, McpError> {
        let ids = self.registry.workspace_ids();
        Ok(ListResourcesResult::with_all_items(crate::resources::list(
            &ids,
        )))
    }

    async fn list_resource_templates(
        &self,
        _request: Option<PaginatedRequestParams>,
        _context: RequestContext<RoleServer>,
    ) -> Result<ListResourceTemplatesResult, McpError> {
        Ok(ListResourceTemplatesResult::with_all_items(
            crate::resources::templates(),
        ))
    }

    async fn read_resource(
        &self,
        request: ReadResourceRequestParams,
        context: RequestContext<RoleServer>,
    ) -> Result<ReadResourceResponse, McpError> {
        let ids = self.registry.workspace_ids();
        let workspace_id = crate::resources::workspace_of(&request.uri, &ids)?;
        let mut arguments = serde_json::Map::new();
        arguments.insert("workspace_id".into(), workspace_id.into());
        let call = CallContext {
            session: self.session_of(&context),
            request_id: context.id.to_string(),
            by_client: context.ct.clone(),
            progress: None,
        };
        let params = CallToolRequestParams::new("get_camera_image").with_arguments(arguments);
        let result = self.serve_call(params, call).await.result?;
        crate::resources::contents_of(&request.uri, result).map(Into::into)
    }

    async fn call_tool(
        &self,
        request: CallToolRequestParams,
        context: RequestContext<RoleServer>,
    ) -> Result<CallToolResponse, McpError> {
        let token = context.meta.get_progress_token().or_else(|| {
            request
                .meta
                .as_ref()
                .and_then(|meta| meta.get_progress_token())
        });
        let progress: Option<Box<dyn Fn(Progress) + Send + Sync>> = token.map(|token| {
            let peer = context.peer.clone();
            let report = move |p: Progress| {
                let peer = peer.clone();
                let param = progress_param(&token, p);
                tokio::spawn(async move {
                    if let Err(error) = peer.notify_progress(param).await {
                        tracing::debug!(%error, "progress notification not delivered");
                    }
                });
            };
            Box::new(report) as Box<dyn Fn(Progress) + Send + Sync>
        });
        let call = CallContext {
            session: self.session_of(&context),
            request_id: context.id.to_string(),
            by_client: context.ct.clone(),
            progress,
        };
        // rmcp itself sends no answer to a request its client cancelled.
        self.serve_call(request, call).await.result.map(Into::into)
    }
}

/// The `notifications/progress` params of a skill's step `p`, for the client's `token`.
pub(crate) fn progress_param(token: &ProgressToken, p: Progress) -> ProgressNotificationParam {
    let mut param = ProgressNotificationParam::new(token.clone(), f64::from(p.step));
    param.total = Some(f64::from(p.total));
    param.message = Some(p.message);
    param
}

/// Who made a tool call and what can stop it, whichever way it arrived.
pub(crate) struct CallContext {
    /// The session the call belongs to (legacy SSE or streamable HTTP).
    pub(crate) session: Option<String>,
    /// The JSON-RPC id of the request, as text.
    pub(crate) request_id: String,
    /// Cancelled by the client's `notifications/cancelled`.
    pub(crate) by_client: CancellationToken,
    /// Reports the skill's steps as `notifications/progress`, when the client asked for them.
    pub(crate) progress: Option<Box<dyn Fn(Progress) + Send + Sync>>,
}

/// How a tool call ended.
pub(crate) struct Served {
    /// Its result, or a protocol error.
    pub(crate) result: Result<CallToolResult, McpError>,
    /// It was cancelled before it started: it waited (behind another client's motion, for an
    /// approval) and reported no step. The MCP spec asks that such a request get no answer.
    pub(crate) cancelled_before_start: bool,
}

impl McpService {
    /// Runs one `tools/call` and writes it to the call log. Both rmcp's handler
    /// ([`ServerHandler::call_tool`]) and the direct streamable-HTTP path
    /// (`crate::http::direct_call`) end here, so a call is the same call either way.
    ///
    /// A call has started once its tool reported a step: a skill reports one before it moves
    /// anything, so a cancelled call that reported none never moved the arm.
    pub(crate) async fn serve_call(
        &self,
        request: CallToolRequestParams,
        call: CallContext,
    ) -> Served {
        // Once the calls stop for a second, the memory a burst of them used goes back.
        robotd_runtime::heap::release_soon();
        let CallContext {
            session,
            request_id,
            by_client,
            progress,
        } = call;
        let name = request.name.to_string();
        let span = tracing::info_span!(
            "mcp.tool_call",
            tool = %name,
            transport = self.transport,
            status = tracing::field::Empty
        );
        let cancelled = self.cancellation(by_client, session.as_deref(), &request_id);
        let cancel = CancellationToken::new();
        // Fires when this future is dropped before its end (its caller went away): the call's
        // motion stops as for any cancellation.
        let dropped_early = cancel.clone().drop_guard();
        let started = Arc::new(AtomicBool::new(false));
        let step = started.clone();
        let progress = Box::new(move |p: Progress| {
            step.store(true, Ordering::Release);
            if let Some(report) = &progress {
                report(p);
            }
        });
        let hooks = CallHooks {
            progress: Some(progress),
            cancel: cancel.clone(),
        };
        let origin = Origin::new(OriginKind::Mcp)
            .session(session.unwrap_or_else(|| self.transport.to_owned()))
            .request(request_id);
        let arguments = request.arguments;
        // The call's trace id, for the call log: the actors' spans of this call share it.
        let trace_id = span
            .in_scope(robotd_runtime::telemetry::current_trace_context)
            .traceparent
            .and_then(|tp| tp.split('-').nth(1).map(str::to_owned));
        let started_at = Instant::now();
        let call = with_origin(
            origin,
            self.registry
                .call(&name, arguments.clone(), hooks)
                .instrument(span.clone()),
        );
        let outcome = until_done(call, cancelled, &cancel).await;
        dropped_early.disarm();
        let elapsed = started_at.elapsed();
        let cancelled_before_start = cancel.is_cancelled() && !started.load(Ordering::Acquire);
        if cancelled_before_start {
            tracing::info!(tool = %name, "MCP call cancelled before it started: no answer");
        }
        let result = match outcome {
            Ok(output) => {
                let status = if output.is_failure { "failed" } else { "ok" };
                span.record("status", status);
                self.log.record(&CallRecord {
                    transport: self.transport,
                    tool: &name,
                    arguments: arguments.as_ref(),
                    result: &output.text,
                    status,
                    duration: elapsed,
                    trace_id: trace_id.as_deref(),
                });
                let mut content = vec![ContentBlock::text(output.text.clone())];
                for image in &output.images {
                    content.push(ContentBlock::image(image.base64(), image.mime_type));
                }
                let mut result = CallToolResult::success(content);
                result.structured_content = Some(output.structured());
                result.is_error = Some(self.strict_errors && output.is_failure);
                Ok(result)
            }
            Err(CallError::UnknownTool { name }) => {
                span.record("status", "unknown_tool");
                self.log.record(&CallRecord {
                    transport: self.transport,
                    tool: &name,
                    arguments: arguments.as_ref(),
                    result: "unknown tool",
                    status: "protocol_error",
                    duration: elapsed,
                    trace_id: trace_id.as_deref(),
                });
                Err(McpError::invalid_params(
                    format!("unknown tool '{name}'"),
                    None,
                ))
            }
        };
        Served {
            result,
            cancelled_before_start,
        }
    }
}

/// Runs `call` to its end. When `cancelled` resolves first, `cancel` fires (the call sees it,
/// stops its motion and answers) and the call is still awaited. Both are polled by the
/// caller's task: a call costs no task of its own for watching.
async fn until_done<T>(
    call: impl std::future::Future<Output = T>,
    cancelled: impl std::future::Future<Output = ()>,
    cancel: &CancellationToken,
) -> T {
    tokio::pin!(call);
    tokio::select! {
        biased;
        outcome = &mut call => return outcome,
        () = cancelled => cancel.cancel(),
    }
    call.await
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::sync::oneshot;

    #[tokio::test]
    async fn a_call_that_ends_first_is_not_cancelled() {
        let cancel = CancellationToken::new();
        let outcome = until_done(async { 7 }, std::future::pending(), &cancel).await;
        assert_eq!(outcome, 7);
        assert!(!cancel.is_cancelled());
    }

    #[tokio::test]
    async fn a_cancellation_fires_the_token_and_the_call_still_answers() {
        let cancel = CancellationToken::new();
        let (cancel_now, cancelled) = oneshot::channel::<()>();
        let seen = cancel.clone();
        // The call answers only once it has seen the token fire, as a stopped motion does.
        let call = async move {
            seen.cancelled().await;
            "stopped"
        };
        cancel_now.send(()).unwrap();
        let cancelled = async {
            let _ = cancelled.await;
        };
        assert_eq!(until_done(call, cancelled, &cancel).await, "stopped");
        assert!(cancel.is_cancelled());
    }
}
