//! The agent actor of `robotd serve`: a front end in another process sends an `agent.request`
//! on the bus and reads the plan, each tool call and result, and the answer as `agent.event`s.
//! The LLM is the scripted mock speaking the OpenAI wire format; everything else is real.

mod common;

use robotd_agent::mock::{MockLlm, MockReply};
use robotd_protocol::agent::{AgentEventKind, AgentRequest};
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::{AGENT_EVENTS, AGENT_REQUEST};
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Duration;

#[test]
fn serve_runs_the_agent_on_the_bus() {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    runtime.block_on(async {
        let mock = MockLlm::start(vec![
            MockReply::plan_and_call(
                "You want to know what is on the table; I look first.",
                "get_detected_objects",
                serde_json::json!({}),
            ),
            MockReply::text("I see a pencil, a red cube and more on the table."),
        ])
        .await
        .unwrap();
        let namespace = common::fresh_namespace("agent-serve");
        let port = common::free_port();
        let temp = tempfile::tempdir().unwrap();
        let dir = temp.path();
        let mut command = Command::new(env!("CARGO_BIN_EXE_robotd"));
        command
            .args(["serve", "--namespace", &namespace, "--http"])
            .arg(format!("127.0.0.1:{port}"))
            .args(["--set", "robot.time_scale=0.05", "--set"])
            .arg(format!("telemetry.log_dir={}", dir.display()))
            .current_dir(dir)
            .env("OPENAI_API_KEY", "sk-test-agent-serve")
            .env("OPENAI_BASE_URL", mock.openai_base_url())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        for v in ["GROQ_API_KEY", "GEMINI_API_KEY", "API_KEY", "LLM_BASE_URL", "ROBOTD_CONFIG"] {
            command.env_remove(v);
        }
        let child = command.spawn().expect("start robotd serve");
        let mut robotd = common::Running::new(child, "robotd");
        let stderr = robotd.child.stderr.take().unwrap();
        let mut lines = BufReader::new(stderr).lines();
        loop {
            let line = lines
                .next()
                .expect("robotd serve stopped before serving")
                .unwrap();
            if line.contains("robotd: serving on") {
                break;
            }
        }
        std::thread::spawn(move || for _ in lines {});

        let bus = Bus::open(BusOptions::new(&namespace, "agent-front-end")).unwrap();
        let mut events = bus.subscriber(&AGENT_EVENTS).unwrap();
        let requests = bus.publisher(&AGENT_REQUEST).unwrap();
        requests
            .publish(&AgentRequest {
                request_id: "r-1".into(),
                text: "What is on the table?".into(),
            })
            .unwrap();
        let mut kinds = Vec::new();
        let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
        loop {
            let event = tokio::time::timeout_at(deadline, events.recv())
                .await
                .expect("the agent finished within 30 s")
                .unwrap()
                .body;
            assert_eq!(event.request_id, "r-1");
            let terminal = event.event.is_terminal();
            kinds.push(event.event);
            if terminal {
                break;
            }
        }
        assert!(
            matches!(&kinds[0], AgentEventKind::Plan { text } if text.contains("I look first")),
            "{kinds:?}"
        );
        assert!(
            kinds.iter().any(|k| matches!(k, AgentEventKind::ToolCall { name, .. } if name == "get_detected_objects")),
            "{kinds:?}"
        );
        assert!(
            kinds.iter().any(|k| matches!(k, AgentEventKind::ToolResult { ok: true, text, .. } if text.starts_with("✓ Found"))),
            "{kinds:?}"
        );
        assert!(
            matches!(kinds.last(), Some(AgentEventKind::Answer { text }) if text.contains("pencil")),
            "{kinds:?}"
        );
        // The second LLM call carried the real tool result.
        let recorded = mock.requests();
        assert_eq!(recorded.len(), 2);
        assert!(recorded[1].body.to_string().contains("✓ Found"), "{:?}", recorded[1].body);

        // The dashboard's chat API streams one request's events and ends the response with
        // the terminal one (it used to stay open until the client left).
        mock.push(MockReply::text("Nothing moved."));
        robotd_runtime::telemetry::install_tls_provider();
        let response = tokio::time::timeout(Duration::from_secs(30), async {
            reqwest::Client::new()
                .post(format!("http://127.0.0.1:{port}/api/chat"))
                .header("content-type", "application/json")
                .body(r#"{"text": "Did anything move?"}"#)
                .send()
                .await
                .unwrap()
                .text()
                .await
                .unwrap()
        })
        .await
        .expect("the chat response ended within 30 s of being sent");
        assert!(response.contains("event: request"), "{response}");
        assert!(response.contains("Nothing moved."), "{response}");
        assert!(response.trim_end().ends_with('}'), "ends with the answer: {response}");
    });
}
