//! One trace from an MCP tool call into the actors: the bus request a tool sends carries the
//! call's trace, and the call log names the same trace id.

use robotd_config::Config;
use robotd_mcp::call_log::CallLog;
use robotd_mcp::client::connect;
use robotd_mcp::{http, McpService};
use robotd_protocol::workspace::{WorkspaceInfo, WorkspaceReply};
use robotd_protocol::{Point2, Pose, RobotModel};
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_runtime::telemetry::{self, Mode};
use robotd_tools::{Registry, ToolSettings};
use robotd_topics::WORKSPACE_QUERY;
use std::sync::Arc;

#[test]
fn the_actors_see_the_trace_of_the_tool_call_that_the_call_log_names() {
    let (dispatch, _guard) =
        telemetry::build(&Config::default().telemetry, Mode::Command).expect("telemetry");
    tracing::dispatcher::set_global_default(dispatch).expect("one subscriber per test binary");
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let log_dir = std::env::temp_dir().join(format!("robotd-mcp-trace-{}", std::process::id()));
    runtime.block_on(async {
        let namespace = format!("mcp-trace-{}", std::process::id());
        let bus = Bus::open(BusOptions::new(&namespace, "mcp-trace-test")).unwrap();
        // The workspace model's side of the bus: it records the trace of what it is asked.
        let mut server = bus.server(&WORKSPACE_QUERY).unwrap();
        let (seen_tx, mut seen_rx) = tokio::sync::mpsc::unbounded_channel();
        tokio::spawn(async move {
            while let Ok(incoming) = server.next().await {
                let (envelope, pending) = incoming.split();
                let _ = seen_tx.send(envelope.trace.clone());
                let reply = WorkspaceReply::Coordinate {
                    coordinate: Point2::new(0.25, 0.0),
                };
                let _ = server.respond(pending, Ok(reply));
            }
        });
        let workspaces = vec![WorkspaceInfo {
            id: "niryo_ws".into(),
            robot: RobotModel::Ned2,
            upper_left: Point2::new(0.337, 0.087),
            lower_right: Point2::new(0.163, -0.087),
            observation_pose: Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027),
        }];
        let registry = Registry::connect(&bus, ToolSettings::new("trace", workspaces)).unwrap();
        let (log, error) = CallLog::open(&log_dir, Default::default());
        assert!(error.is_none());
        let log = Arc::new(log);
        let service = McpService::new(registry, false, log.clone());
        let app = http::router(service, Default::default(), Default::default());
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let port = listener.local_addr().unwrap().port();
        tokio::spawn(async move { axum::serve(listener, app).await });

        let client = connect(&format!("http://127.0.0.1:{port}/mcp"), None)
            .await
            .unwrap();
        let mut params =
            rmcp::model::CallToolRequestParams::new("get_workspace_coordinate_from_point");
        params = params.with_arguments(
            serde_json::json!({"workspace_id": "niryo_ws", "point": "center point"})
                .as_object()
                .cloned()
                .unwrap(),
        );
        let result = client.call_tool(params).await.unwrap();
        let text = &result.content[0].as_text().unwrap().text;
        assert_eq!(
            text,
            "✓ Coordinate of 'center point' in workspace 'niryo_ws': [0.250, 0.000]"
        );
        let trace = seen_rx.recv().await.expect("the workspace model was asked");
        let traceparent = trace.traceparent.expect("the request carries a trace");
        let trace_id = traceparent.split('-').nth(1).unwrap().to_owned();
        assert_ne!(trace_id, "0".repeat(32));

        let text = std::fs::read_to_string(log.path().unwrap()).unwrap();
        let line: serde_json::Value = serde_json::from_str(text.lines().last().unwrap()).unwrap();
        assert_eq!(line["tool"], "get_workspace_coordinate_from_point");
        assert_eq!(line["trace_id"], serde_json::Value::String(trace_id));
        client.cancel().await.unwrap();
    });
    std::fs::remove_dir_all(&log_dir).ok();
}
