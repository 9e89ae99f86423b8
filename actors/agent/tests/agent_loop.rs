//! The agent loop and the LLM clients against the mock LLM server speaking the real OpenAI and
//! Ollama wire formats: plan and first tool call in one round, retries on 429 and 5xx, a
//! rejected key, the text-tool-call nudge, the round limit, malformed replies, provider
//! switching with the history kept, cancellation reaching the tool, and the bus actor.

use robotd_agent::actor::{self, AGENT_CANCEL, AGENT_EVENTS, AGENT_REQUEST};
use robotd_agent::agent::NUDGE;
use robotd_agent::llm::ToolSpec;
use robotd_agent::llm::{LlmClient, LlmError, Message, RetryPolicy};
use robotd_agent::mock::{MockLlm, MockReply};
use robotd_agent::providers::{resolve, Env, ProviderSettings};
use robotd_agent::tools::{specs_of, BoxFuture};
use robotd_agent::{Agent, AgentConfig, ToolBackend, ToolResultText};
use robotd_protocol::agent::{AgentCancel, AgentEventKind, AgentRequest};
use serde_json::{json, Map, Value};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio_util::sync::CancellationToken;

/// robotd's real tool list; calls are recorded and answered with a ✓ line, except
/// `move2observation_pose`, which runs until it is cancelled (a long motion).
#[derive(Default)]
struct RecordingTools {
    calls: Mutex<Vec<(String, Map<String, Value>)>>,
    /// Told when `move2observation_pose` is running (and waiting to be cancelled).
    moving: tokio::sync::Notify,
}

impl ToolBackend for RecordingTools {
    fn tools(&self) -> Vec<ToolSpec> {
        specs_of(&robotd_tools::definitions::all())
    }

    fn call<'a>(
        &'a self,
        name: &'a str,
        arguments: Map<String, Value>,
        cancel: CancellationToken,
    ) -> BoxFuture<'a, ToolResultText> {
        Box::pin(async move {
            self.calls
                .lock()
                .unwrap()
                .push((name.to_owned(), arguments.clone()));
            if name == "move2observation_pose" {
                self.moving.notify_one();
                cancel.cancelled().await;
                return ToolResultText::failed("❌ Motion stopped: cancelled");
            }
            ToolResultText::new(format!("✓ {name} done"), true)
        })
    }
}

fn fast_retry() -> RetryPolicy {
    RetryPolicy {
        max_retries: 2,
        initial_backoff: Duration::from_millis(20),
        max_backoff: Duration::from_millis(200),
        request_timeout: Duration::from_secs(10),
        max_reply_bytes: 64 * 1024,
    }
}

fn openai_at(mock: &MockLlm) -> ProviderSettings {
    resolve(
        "openai",
        None,
        &Env::from_pairs([
            ("OPENAI_API_KEY", "sk-test".to_owned()),
            ("OPENAI_BASE_URL", mock.openai_base_url()),
        ]),
    )
    .unwrap()
}

fn ollama_at(mock: &MockLlm) -> ProviderSettings {
    resolve(
        "ollama",
        None,
        &Env::from_pairs([("OLLAMA_HOST", mock.base_url())]),
    )
    .unwrap()
}

fn agent(settings: ProviderSettings, tools: Arc<RecordingTools>) -> Agent {
    let config = AgentConfig {
        retry: fast_retry(),
        ..AgentConfig::default()
    };
    Agent::new(settings, tools, &[], config).unwrap()
}

async fn run(agent: &mut Agent, text: &str) -> Vec<AgentEventKind> {
    let mut events = Vec::new();
    agent
        .run(text, CancellationToken::new(), |e| events.push(e))
        .await;
    events
}

/// The messages of a recorded request.
fn messages(body: &Value) -> Vec<Value> {
    body["messages"].as_array().cloned().unwrap_or_default()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn plan_and_first_tool_call_come_from_one_llm_call() {
    let mock = MockLlm::start(vec![
        MockReply::plan_and_call(
            "I understand: look first, then move the pencil. Plan: 1. look 2. pick and place.",
            "get_detected_objects",
            json!({}),
        ),
        MockReply::tool_call(
            "pick_place_object",
            json!({"object_name": "pencil", "pick_coordinate": [0.2, 0.05],
                   "place_coordinate": [0.25, -0.03], "location": "right next to"}),
        ),
        MockReply::text("Done: the pencil is right next to the red cube."),
    ])
    .await
    .unwrap();
    let tools = Arc::new(RecordingTools::default());
    let mut agent = agent(openai_at(&mock), tools.clone());
    let events = run(
        &mut agent,
        "Pick up the pencil and place it right next to the red cube",
    )
    .await;
    let kinds: Vec<&str> = events
        .iter()
        .map(|e| match e {
            AgentEventKind::Plan { .. } => "plan",
            AgentEventKind::ToolCall { .. } => "call",
            AgentEventKind::ToolResult { .. } => "result",
            AgentEventKind::Picture { .. } => "picture",
            AgentEventKind::Answer { .. } => "answer",
            AgentEventKind::Error { .. } => "error",
            AgentEventKind::Cancelled => "cancelled",
        })
        .collect();
    assert_eq!(
        kinds,
        ["plan", "call", "result", "call", "result", "answer"],
        "{events:?}"
    );
    // Three LLM calls: no extra planning round.
    let requests = mock.requests();
    assert_eq!(requests.len(), 3);
    assert_eq!(requests[0].path, "/v1/chat/completions");
    assert_eq!(requests[0].authorization.as_deref(), Some("Bearer sk-test"));
    let body = &requests[0].body;
    assert_eq!(body["model"], "gpt-4o-mini");
    assert_eq!(body["tools"].as_array().unwrap().len(), 24);
    let first = messages(body);
    assert_eq!(first[0]["role"], "system");
    assert!(first[0]["content"]
        .as_str()
        .unwrap()
        .contains("get_largest_free_space_with_center"));
    assert_eq!(
        first[1]["content"],
        "Pick up the pencil and place it right next to the red cube"
    );
    // The tool results went back to the model with their call ids.
    let last = messages(&requests[2].body);
    let tool_msgs: Vec<&Value> = last.iter().filter(|m| m["role"] == "tool").collect();
    assert_eq!(tool_msgs.len(), 2);
    assert_eq!(tool_msgs[1]["content"], "✓ pick_place_object done");
    let calls = tools.calls.lock().unwrap().clone();
    assert_eq!(calls.len(), 2);
    assert_eq!(calls[1].1["location"], "right next to");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rate_limits_are_retried_honouring_a_capped_retry_after() {
    let mock = MockLlm::start(vec![
        MockReply::Status {
            status: 429,
            retry_after: Some(100),
            body: r#"{"error":{"message":"rate limited"}}"#.into(),
        },
        MockReply::text("hello"),
    ])
    .await
    .unwrap();
    let client = LlmClient::new(openai_at(&mock), fast_retry()).unwrap();
    let started = Instant::now();
    let reply = client.complete(&[Message::user("hi")], &[]).await.unwrap();
    let took = started.elapsed();
    assert_eq!(reply.content.as_deref(), Some("hello"));
    assert_eq!(mock.requests().len(), 2);
    // Retry-After: 100 s is capped at max_backoff (200 ms).
    assert!(took >= Duration::from_millis(190), "{took:?}");
    assert!(took < Duration::from_secs(5), "{took:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn server_errors_are_retried_a_bounded_number_of_times() {
    let mock = MockLlm::start(vec![
        MockReply::status(500),
        MockReply::status(502),
        MockReply::status(503),
        MockReply::text("never reached"),
    ])
    .await
    .unwrap();
    let client = LlmClient::new(openai_at(&mock), fast_retry()).unwrap();
    let error = client
        .complete(&[Message::user("hi")], &[])
        .await
        .unwrap_err();
    assert!(
        matches!(
            error,
            LlmError::Exhausted {
                status: 503,
                attempts: 3,
                ..
            }
        ),
        "{error:?}"
    );
    assert!(error.to_string().contains("after 3 attempts"), "{error}");
    assert_eq!(mock.requests().len(), 3);
    assert_eq!(mock.remaining(), 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rejected_key_names_the_variable_and_is_not_retried() {
    let mock = MockLlm::start(vec![MockReply::Status {
        status: 401,
        retry_after: None,
        body: r#"{"error":{"message":"Incorrect API key provided"}}"#.into(),
    }])
    .await
    .unwrap();
    let tools = Arc::new(RecordingTools::default());
    let mut agent = agent(openai_at(&mock), tools);
    let events = run(&mut agent, "look").await;
    let Some(AgentEventKind::Error { message }) = events.last() else {
        panic!("{events:?}");
    };
    assert!(message.contains("rejected the API key"), "{message}");
    assert!(message.contains("OPENAI_API_KEY"), "{message}");
    assert!(message.contains("Incorrect API key provided"), "{message}");
    assert_eq!(mock.requests().len(), 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tool_call_written_as_text_gets_the_recovery_nudge() {
    let mock = MockLlm::start(vec![
        MockReply::text(
            "Plan: look first.\npick_place_object(object_name=\"pencil\", pick_coordinate=[0.2, 0.05])",
        ),
        MockReply::tool_call("get_detected_objects", json!({})),
        MockReply::text("I looked."),
    ])
    .await
    .unwrap();
    let tools = Arc::new(RecordingTools::default());
    let mut agent = agent(openai_at(&mock), tools.clone());
    let events = run(&mut agent, "move the pencil").await;
    assert_eq!(
        events.last(),
        Some(&AgentEventKind::Answer {
            text: "I looked.".into()
        })
    );
    let requests = mock.requests();
    assert_eq!(requests.len(), 3);
    let second = messages(&requests[1].body);
    let nudge = second.last().unwrap();
    assert_eq!(nudge["role"], "user");
    assert_eq!(nudge["content"], NUDGE);
    // The text was never executed as a call; the real call was.
    let calls = tools.calls.lock().unwrap().clone();
    assert_eq!(calls.len(), 1);
    assert_eq!(calls[0].0, "get_detected_objects");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_round_limit_ends_a_request_that_never_answers() {
    let replies = (0..20)
        .map(|_| MockReply::tool_call("get_object_labels_as_string", json!({})))
        .collect();
    let mock = MockLlm::start(replies).await.unwrap();
    let tools = Arc::new(RecordingTools::default());
    let mut agent = agent(openai_at(&mock), tools.clone());
    let events = run(&mut agent, "loop forever").await;
    let Some(AgentEventKind::Error { message }) = events.last() else {
        panic!("{events:?}");
    };
    assert!(message.contains("15 LLM rounds"), "{message}");
    assert_eq!(mock.requests().len(), 15);
    assert_eq!(tools.calls.lock().unwrap().len(), 15);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_replies_and_arguments_give_clear_errors() {
    let mock = MockLlm::start(vec![
        // Arguments that are not JSON go back to the model as a failed tool result.
        MockReply::dynamic(|_| MockReply::Raw(
            json!({"choices": [{"message": {"role": "assistant", "content": null, "tool_calls": [
                {"id": "x1", "type": "function", "function": {"name": "speak", "arguments": "{text: hi"}}
            ]}}]})
            .to_string(),
        )),
        MockReply::Raw("this is not json".into()),
    ])
    .await
    .unwrap();
    let tools = Arc::new(RecordingTools::default());
    let mut agent = agent(openai_at(&mock), tools.clone());
    let events = run(&mut agent, "say hi").await;
    let result = events
        .iter()
        .find_map(|e| match e {
            AgentEventKind::ToolResult { text, ok, .. } => Some((text.clone(), *ok)),
            _ => None,
        })
        .expect("a tool result");
    assert!(!result.1);
    assert!(result.0.contains("not valid JSON"), "{}", result.0);
    assert!(tools.calls.lock().unwrap().is_empty());
    let Some(AgentEventKind::Error { message }) = events.last() else {
        panic!("{events:?}");
    };
    assert!(message.contains("cannot read"), "{message}");
    assert!(message.contains("this is not json"), "{message}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn switching_provider_keeps_the_history_and_ollama_gets_real_tool_calls() {
    let openai = MockLlm::start(vec![MockReply::text("The red cube is at [0.25, 0.08].")])
        .await
        .unwrap();
    let ollama = MockLlm::start(vec![MockReply::tool_call(
        "move2observation_pose",
        json!({"workspace_id": "niryo_ws"}),
    )])
    .await
    .unwrap();
    let tools = Arc::new(RecordingTools::default());
    let mut agent = agent(openai_at(&openai), tools.clone());
    let events = run(&mut agent, "Where is the red cube?").await;
    assert!(
        matches!(events.last(), Some(AgentEventKind::Answer { .. })),
        "{events:?}"
    );
    agent.switch(ollama_at(&ollama)).unwrap();
    assert_eq!(agent.provider().model, "llama3.2:1b");
    // The Ollama mock's first reply calls a tool that runs until cancelled; cancel it once
    // it runs so the request ends, then check what Ollama was sent.
    let cancel = CancellationToken::new();
    let canceller = {
        let (cancel, tools) = (cancel.clone(), tools.clone());
        tokio::spawn(async move {
            tokio::time::timeout(Duration::from_secs(10), tools.moving.notified())
                .await
                .expect("the tool call reached the tool within 10 s");
            cancel.cancel();
        })
    };
    let mut events = Vec::new();
    let end = agent
        .run("Go back to the observation pose", cancel, |e| {
            events.push(e)
        })
        .await;
    canceller.await.unwrap();
    assert_eq!(end, AgentEventKind::Cancelled);
    let requests = ollama.requests();
    assert_eq!(requests.len(), 1);
    assert_eq!(requests[0].path, "/api/chat");
    assert_eq!(requests[0].authorization, None);
    let body = &requests[0].body;
    assert_eq!(body["stream"], false);
    assert_eq!(body["model"], "llama3.2:1b");
    assert_eq!(body["tools"][0]["type"], "function");
    let sent = messages(body);
    let contents: Vec<&str> = sent.iter().filter_map(|m| m["content"].as_str()).collect();
    assert!(contents.contains(&"Where is the red cube?"), "{contents:?}");
    assert!(
        contents.contains(&"The red cube is at [0.25, 0.08]."),
        "{contents:?}"
    );
    assert!(
        contents.contains(&"Go back to the observation pose"),
        "{contents:?}"
    );
    // Ollama's tool call (arguments as an object) reached the tool, and the cancel stopped it.
    let calls = tools.calls.lock().unwrap().clone();
    assert_eq!(calls.last().unwrap().0, "move2observation_pose");
    assert_eq!(calls.last().unwrap().1["workspace_id"], "niryo_ws");
    assert!(events.iter().any(
        |e| matches!(e, AgentEventKind::ToolResult { text, .. } if text.contains("cancelled"))
    ));
    // The next request sees a well-formed history (the call has its result) and works.
    ollama.push(MockReply::text("ok"));
    let events = run(&mut agent, "thanks").await;
    assert_eq!(
        events.last(),
        Some(&AgentEventKind::Answer { text: "ok".into() })
    );
    let sent = messages(&ollama.requests()[1].body);
    let tool_results = sent.iter().filter(|m| m["role"] == "tool").count();
    assert_eq!(tool_results, 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_bus_actor_streams_events_and_cancels() {
    let namespace = format!("agent-actor-{}", std::process::id());
    let bus = robotd_runtime::bus::Bus::open(robotd_runtime::bus::BusOptions::new(
        &namespace,
        "agent-test",
    ))
    .unwrap();
    let mock = MockLlm::start(vec![
        MockReply::plan_and_call(
            "Plan: list the labels.",
            "get_object_labels_as_string",
            json!({}),
        ),
        MockReply::text("pencil, red cube"),
        MockReply::tool_call("move2observation_pose", json!({"workspace_id": "niryo_ws"})),
    ])
    .await
    .unwrap();
    let tools = Arc::new(RecordingTools::default());
    let _actor = actor::spawn(&bus, agent(openai_at(&mock), tools)).unwrap();
    let mut events = bus.subscriber(&AGENT_EVENTS).unwrap();
    let requests = bus.publisher(&AGENT_REQUEST).unwrap();
    let cancels = bus.publisher(&AGENT_CANCEL).unwrap();
    requests
        .publish(&AgentRequest {
            request_id: "r1".into(),
            text: "Which objects can you see?".into(),
        })
        .unwrap();
    let mut seen = Vec::new();
    loop {
        let event = tokio::time::timeout(Duration::from_secs(10), events.recv())
            .await
            .expect("agent events")
            .unwrap()
            .body;
        assert_eq!(event.request_id, "r1");
        assert_eq!(event.seq as usize, seen.len());
        let terminal = event.event.is_terminal();
        seen.push(event.event);
        if terminal {
            break;
        }
    }
    assert!(matches!(seen[0], AgentEventKind::Plan { .. }), "{seen:?}");
    assert_eq!(
        seen.last(),
        Some(&AgentEventKind::Answer {
            text: "pencil, red cube".into()
        })
    );
    // A long motion, cancelled over the bus.
    requests
        .publish(&AgentRequest {
            request_id: "r2".into(),
            text: "Go to the observation pose".into(),
        })
        .unwrap();
    let last = loop {
        let event = tokio::time::timeout(Duration::from_secs(10), events.recv())
            .await
            .expect("agent events")
            .unwrap()
            .body;
        assert_eq!(event.request_id, "r2");
        if matches!(event.event, AgentEventKind::ToolCall { .. }) {
            cancels
                .publish(&AgentCancel {
                    request_id: "r2".into(),
                })
                .unwrap();
        }
        if event.event.is_terminal() {
            break event.event;
        }
    };
    assert_eq!(last, AgentEventKind::Cancelled);
    // An invalid request gets an error event, not silence.
    requests
        .publish(&AgentRequest {
            request_id: "r3".into(),
            text: "".into(),
        })
        .unwrap();
    let event = tokio::time::timeout(Duration::from_secs(10), events.recv())
        .await
        .expect("agent events")
        .unwrap()
        .body;
    assert_eq!(event.request_id, "r3");
    assert!(
        matches!(event.event, AgentEventKind::Error { ref message } if message.contains("text")),
        "{event:?}"
    );
}

/// A writer collecting what the fmt layer prints.
#[derive(Clone, Default)]
struct Captured(Arc<Mutex<Vec<u8>>>);

impl std::io::Write for Captured {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[tokio::test(flavor = "current_thread")]
async fn every_llm_call_is_a_span_with_its_token_counts() {
    let mock = MockLlm::start(vec![MockReply::text("hello")])
        .await
        .unwrap();
    let captured = Captured::default();
    let writer = captured.clone();
    let subscriber = tracing_subscriber::fmt()
        .with_writer(move || writer.clone())
        .with_ansi(false)
        .with_max_level(tracing::Level::INFO)
        .finish();
    let _default = tracing::subscriber::set_default(subscriber);
    let client = LlmClient::new(openai_at(&mock), fast_retry()).unwrap();
    client.complete(&[Message::user("hi")], &[]).await.unwrap();
    let text = String::from_utf8(captured.0.lock().unwrap().clone()).unwrap();
    let line = text
        .lines()
        .find(|l| l.contains("LLM replied"))
        .unwrap_or_else(|| panic!("no LLM call logged:\n{text}"));
    for field in [
        "llm.call{",
        "provider=\"openai\"",
        "model=gpt-4o-mini",
        "prompt_tokens=100",
        "completion_tokens=20",
    ] {
        assert!(line.contains(field), "{field} missing in: {line}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reply_larger_than_the_limit_is_refused_not_read_whole() {
    let huge = "x".repeat(200 * 1024);
    let mock = MockLlm::start(vec![MockReply::text(&huge)]).await.unwrap();
    let client = LlmClient::new(openai_at(&mock), fast_retry()).unwrap();
    let error = client
        .complete(&[Message::user("hi")], &[])
        .await
        .unwrap_err();
    assert!(
        error
            .to_string()
            .contains("larger than 65536 bytes ([agent] max_reply_bytes)"),
        "{error}"
    );
}
