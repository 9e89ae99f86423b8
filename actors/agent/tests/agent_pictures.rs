//! The pictures a tool returns reach whoever follows the agent: through the bus actor, a
//! picture event follows the call's result on `agent/events`, carrying the exact file — a full
//! 150 kB camera picture fits the topic — and a picture that is too big or not a JPEG or PNG
//! is not passed on. The model is the mock LLM (OpenAI wire format).

use robotd_agent::actor::{self, AGENT_EVENTS, AGENT_REQUEST};
use robotd_agent::llm::ToolSpec;
use robotd_agent::mock::{MockLlm, MockReply};
use robotd_agent::providers::{resolve, Env, ProviderSettings};
use robotd_agent::tools::{specs_of, BoxFuture};
use robotd_agent::vision::ImagePart;
use robotd_agent::{Agent, AgentConfig, ToolBackend, ToolResultText};
use robotd_protocol::agent::{AgentEventKind, AgentRequest, MAX_PICTURE_BYTES};
use serde_json::{json, Map, Value};
use std::sync::Arc;
use std::time::Duration;
use tokio_util::sync::CancellationToken;

/// A JPEG-looking base64 text of about `bytes` bytes (`/9j/` is FF D8 FF), varied content.
fn jpeg_base64(bytes: usize) -> String {
    const ALPHABET: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let chars = bytes.div_ceil(3) * 4;
    let mut text = String::from("/9j/");
    text.extend((4..chars).map(|i| ALPHABET[(i * 7 + i / 64) % 64] as char));
    text
}

/// `get_camera_image` answers with its text and three pictures: a full-size one, one too
/// big for an event, and an SVG; every other tool with a ✓ line.
struct CameraTools {
    picture: String,
}

impl ToolBackend for CameraTools {
    fn tools(&self) -> Vec<ToolSpec> {
        specs_of(&robotd_tools::definitions::all())
    }

    fn call<'a>(
        &'a self,
        name: &'a str,
        _arguments: Map<String, Value>,
        _cancel: CancellationToken,
    ) -> BoxFuture<'a, ToolResultText> {
        Box::pin(async move {
            let mut result = ToolResultText::new(format!("✓ {name} done"), true);
            if name == "get_camera_image" {
                let jpeg = |data_base64: String| ImagePart {
                    mime_type: "image/jpeg".into(),
                    data_base64,
                };
                result.images = vec![
                    jpeg(self.picture.clone()),
                    jpeg(jpeg_base64(MAX_PICTURE_BYTES + 3)),
                    ImagePart {
                        mime_type: "image/svg+xml".into(),
                        data_base64: "PHN2Zz48L3N2Zz4=".into(),
                    },
                ];
            }
            result
        })
    }
}

fn openai_at(mock: &MockLlm, model: &str) -> ProviderSettings {
    resolve(
        "openai",
        Some(model),
        &Env::from_pairs([
            ("OPENAI_API_KEY", "sk-test".to_owned()),
            ("OPENAI_BASE_URL", mock.openai_base_url()),
        ]),
    )
    .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_picture_a_tool_returned_follows_its_result_on_the_bus() {
    let namespace = format!("agent-pictures-{}", std::process::id());
    let bus = robotd_runtime::bus::Bus::open(robotd_runtime::bus::BusOptions::new(
        &namespace,
        "agent-pictures-test",
    ))
    .unwrap();
    let mock = MockLlm::start(vec![
        MockReply::plan_and_call("I will look.", "get_camera_image", json!({})),
        MockReply::text("I see the table."),
    ])
    .await
    .unwrap();
    let picture = jpeg_base64(150_000);
    let tools = Arc::new(CameraTools {
        picture: picture.clone(),
    });
    let agent = Agent::new(
        openai_at(&mock, "gpt-4o-mini"),
        tools,
        &[],
        AgentConfig::default(),
    )
    .unwrap();
    assert!(agent.takes_images());
    let _actor = actor::spawn(&bus, agent).unwrap();
    let mut events = bus.subscriber(&AGENT_EVENTS).unwrap();
    bus.publisher(&AGENT_REQUEST)
        .unwrap()
        .publish(&AgentRequest {
            request_id: "r1".into(),
            text: "What is on the table?".into(),
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
        assert_eq!(event.seq as usize, seen.len(), "no event lost");
        let terminal = event.event.is_terminal();
        seen.push(event.event);
        if terminal {
            break;
        }
    }
    let kinds: Vec<&str> = seen
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
    // One picture: the one too big and the SVG are not passed on.
    assert_eq!(kinds, ["plan", "call", "result", "picture", "answer"]);
    let AgentEventKind::ToolCall { call_id, .. } = &seen[1] else {
        unreachable!()
    };
    assert_eq!(
        seen[3],
        AgentEventKind::Picture {
            call_id: call_id.clone(),
            name: "get_camera_image".into(),
            mime_type: "image/jpeg".into(),
            data_base64: picture.clone(),
            shown_to_model: true,
        }
    );
    // The model was sent the same file.
    let requests = mock.requests();
    let sent = requests[1].body.to_string();
    assert!(sent.contains(&format!("data:image/jpeg;base64,{picture}")));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_text_only_model_is_not_sent_the_picture_but_the_user_is_shown_it() {
    let mock = MockLlm::start(vec![
        MockReply::tool_call("get_camera_image", json!({})),
        MockReply::text("Done."),
    ])
    .await
    .unwrap();
    let picture = jpeg_base64(2_000);
    let tools = Arc::new(CameraTools {
        picture: picture.clone(),
    });
    let mut agent = Agent::new(
        openai_at(&mock, "gpt-3.5-turbo"),
        tools,
        &[],
        AgentConfig::default(),
    )
    .unwrap();
    let mut events = Vec::new();
    agent
        .run("Look", CancellationToken::new(), |e| events.push(e))
        .await;
    let pictures: Vec<(&str, bool)> = events
        .iter()
        .filter_map(|e| match e {
            AgentEventKind::Picture {
                data_base64,
                shown_to_model,
                ..
            } => Some((data_base64.as_str(), *shown_to_model)),
            _ => None,
        })
        .collect();
    assert_eq!(pictures, [(picture.as_str(), false)]);
    assert!(!mock.requests()[1].body.to_string().contains("data:image/"));
}
