//! The agent looks and names (issue 44), end to end: robotd serves the simulator with an
//! object the label table does not know (`tests/scenes/unknown.toml`), the agent drives it over
//! MCP (SSE), and the mock LLM plays a model that looks (`get_camera_image`), names the
//! unknown object (`label_object`) and moves it by that name (`pick_place_object`). The
//! simulator's ground truth is checked afterwards. The mock records every request, so the test
//! checks what each model was sent: a model that takes images gets the picture as an image
//! part after the round's tool results, a text-only one never gets an image part — and over a
//! long session of looks the history keeps few pictures and stays within its bound.

mod common;
#[path = "common/lab.rs"]
mod lab;

use robotd_agent::mock::{MockLlm, MockReply};
use robotd_agent::providers::{resolve, Env};
use robotd_agent::{Agent, AgentConfig};
use robotd_mcp::agent_tools::McpTools;
use robotd_protocol::agent::AgentEventKind;
use serde_json::{json, Value};
use std::sync::Arc;
use tokio_util::sync::CancellationToken;

/// Where the named object is put.
const PLACE: [f64; 2] = [0.21, 0.04];

/// The image parts of a recorded OpenAI request body.
fn image_parts(body: &Value) -> usize {
    let messages = body["messages"].as_array().cloned().unwrap_or_default();
    messages
        .iter()
        .filter_map(|m| m["content"].as_array())
        .flatten()
        .filter(|part| part["type"] == "image_url")
        .count()
}

/// The newest tool message's text of a recorded request.
fn last_tool_text(body: &Value) -> String {
    let messages = body["messages"].as_array().cloned().unwrap_or_default();
    messages
        .iter()
        .rev()
        .find(|m| m["role"] == "tool")
        .and_then(|m| m["content"].as_str())
        .unwrap_or_default()
        .to_owned()
}

/// The id and `[x, y]` of the line `- obj-N: 'label' at [x, y], …` of a picture's text.
fn listed(text: &str, label: &str) -> Option<(String, [f64; 2])> {
    let line = text
        .lines()
        .find(|l| l.contains(&format!(": '{label}' at [")))?;
    let id = line.trim_start_matches("- ").split(':').next()?.to_owned();
    let at = &line[line.find(" at [")? + 5..];
    let at = &at[..at.find(']')?];
    let mut xy = at.split(',').map(|v| v.trim().parse::<f64>());
    Some((id, [xy.next()?.ok()?, xy.next()?.ok()?]))
}

/// The script of a model that looks, names what it sees and moves it by that name.
fn look_then_name() -> Vec<MockReply> {
    vec![
        MockReply::plan_and_call(
            "Something on the table has no name; I will look at it first.",
            "get_camera_image",
            json!({}),
        ),
        MockReply::dynamic(|body| {
            let text = last_tool_text(body);
            match listed(&text, "unknown object") {
                Some((id, _)) => MockReply::tool_call(
                    "label_object",
                    json!({"object_id": id, "label": "screwdriver"}),
                ),
                None => MockReply::text(&format!("I saw no unknown object: {text}")),
            }
        }),
        MockReply::tool_call("get_camera_image", json!({"max_width": 320})),
        MockReply::dynamic(|body| {
            let text = last_tool_text(body);
            match listed(&text, "screwdriver") {
                Some((_, at)) => MockReply::tool_call(
                    "pick_place_object",
                    json!({"object_name": "screwdriver", "pick_coordinate": at,
                           "place_coordinate": PLACE}),
                ),
                None => MockReply::text(&format!("No screwdriver in sight: {text}")),
            }
        }),
        MockReply::text("It was a screwdriver; it now lies at the left."),
    ]
}

async fn agent_on(lab: &lab::Lab, mock: &MockLlm, model: &str, config: AgentConfig) -> Agent {
    let settings = resolve(
        "openai",
        Some(model),
        &Env::from_pairs([
            ("OPENAI_API_KEY", "sk-test".to_owned()),
            ("OPENAI_BASE_URL", mock.openai_base_url()),
        ]),
    )
    .unwrap();
    let tools = McpTools::connect(&format!("{}/sse", lab.url), None)
        .await
        .unwrap();
    Agent::new(settings, Arc::new(tools), &[], config).unwrap()
}

async fn ask(agent: &mut Agent, text: &str) -> Vec<AgentEventKind> {
    let mut events = Vec::new();
    agent
        .run(text, CancellationToken::new(), |e| events.push(e))
        .await;
    events
}

fn answer(events: &[AgentEventKind]) -> String {
    match events.last() {
        Some(AgentEventKind::Answer { text }) => text.clone(),
        other => panic!("no answer: {other:?} in {events:?}"),
    }
}

#[test]
fn a_model_that_looks_names_the_unknown_object_and_moves_it_by_that_name() {
    lab::runtime().block_on(async {
        let lab = lab::lab(Some(lab::scene("unknown.toml"))).await;
        let mock = MockLlm::start(look_then_name()).await.unwrap();
        let mut agent = agent_on(&lab, &mock, "gpt-4o-mini", AgentConfig::default()).await;
        assert!(agent.takes_images());
        let events = ask(&mut agent, "What is the dark thing? Put it on the left.").await;
        assert_eq!(
            answer(&events),
            "It was a screwdriver; it now lies at the left."
        );
        let results: Vec<(&str, bool)> = events
            .iter()
            .filter_map(|e| match e {
                AgentEventKind::ToolResult { name, ok, .. } => Some((name.as_str(), *ok)),
                _ => None,
            })
            .collect();
        assert_eq!(
            results,
            [
                ("get_camera_image", true),
                ("label_object", true),
                ("get_camera_image", true),
                ("pick_place_object", true)
            ],
            "{events:?}"
        );
        // The model was shown the picture in the round after it looked, as an image part
        // after the tool result.
        let requests = mock.requests();
        assert_eq!(image_parts(&requests[0].body), 0);
        assert_eq!(image_parts(&requests[1].body), 1, "the first picture");
        let messages = requests[1].body["messages"].as_array().unwrap().clone();
        let n = messages.len();
        assert_eq!(messages[n - 2]["role"], "tool");
        assert_eq!(messages[n - 1]["role"], "user");
        let url = messages[n - 1]["content"][1]["image_url"]["url"]
            .as_str()
            .unwrap();
        assert!(url.starts_with("data:image/jpeg;base64,/9j/"), "a JPEG");
        assert_eq!(image_parts(&requests[3].body), 2, "both pictures kept");
        // The simulator's block lies where the model put the "screwdriver".
        let truth = lab.truth_of("black block").await;
        assert!(
            (truth.x_m - PLACE[0]).abs() < 0.008 && (truth.y_m - PLACE[1]).abs() < 0.008,
            "the block is at ({:.3}, {:.3})",
            truth.x_m,
            truth.y_m
        );
        let seen = lab
            .ok("get_detected_objects", json!({"label": "screwdriver"}))
            .await;
        assert_eq!(seen.as_array().unwrap().len(), 1, "{seen}");
    });
}

#[test]
fn a_text_only_model_never_gets_an_image_and_a_long_session_stays_bounded() {
    lab::runtime().block_on(async {
        let lab = lab::lab(Some(lab::scene("unknown.toml"))).await;
        // A text-only model: the same script works from the text items alone.
        let mock = MockLlm::start(look_then_name()).await.unwrap();
        let mut agent = agent_on(&lab, &mock, "gpt-3.5-turbo", AgentConfig::default()).await;
        assert!(!agent.takes_images());
        let events = ask(&mut agent, "What is the dark thing? Put it on the left.").await;
        answer(&events);
        let requests = mock.requests();
        assert_eq!(requests.len(), 5);
        for r in &requests {
            assert_eq!(
                image_parts(&r.body),
                0,
                "an image part sent to a text-only model"
            );
            assert!(
                !r.body.to_string().contains("data:image/"),
                "picture bytes in a text-only model's request"
            );
        }
        // A long session of a model that takes images: 25 requests, each looking twice.
        let rounds = 25;
        let mut script = Vec::new();
        for i in 0..rounds {
            script.push(MockReply::tool_call("get_camera_image", json!({})));
            script.push(MockReply::tool_call(
                "get_camera_image",
                json!({"max_width": 480}),
            ));
            script.push(MockReply::text(&format!("Looked, round {i}.")));
        }
        let mock = MockLlm::start(script).await.unwrap();
        let config = AgentConfig {
            memory_tokens: 6_000,
            ..AgentConfig::default()
        };
        let mut agent = agent_on(&lab, &mock, "gpt-4o", config).await;
        for i in 0..rounds {
            let events = ask(&mut agent, &format!("Look at the table ({i})")).await;
            assert_eq!(answer(&events), format!("Looked, round {i}."));
            assert!(agent.memory().pictures() <= 2);
            assert!(
                agent.memory().estimated_tokens() <= 6_000,
                "{}",
                agent.memory().estimated_tokens()
            );
        }
        let requests = mock.requests();
        assert_eq!(requests.len(), 3 * rounds);
        let most = requests.iter().map(|r| image_parts(&r.body)).max();
        assert_eq!(most, Some(2), "at most two pictures in any request");
        // Bounded: the last request is no bigger than the first requests that held two
        // pictures (plus a little text), however long the session ran.
        let size = |r: &robotd_agent::mock::RecordedRequest| r.body.to_string().len();
        let early = size(&requests[2]);
        let last = size(&requests[requests.len() - 1]);
        assert!(
            last < early + 40_000,
            "the request grew from {early} to {last} bytes"
        );
        // Switched to a text-only model mid-conversation: the kept pictures are not sent.
        let text_only = resolve(
            "openai",
            Some("gpt-3.5-turbo"),
            &Env::from_pairs([
                ("OPENAI_API_KEY", "sk-test".to_owned()),
                ("OPENAI_BASE_URL", mock.openai_base_url()),
            ]),
        )
        .unwrap();
        agent.switch(text_only).unwrap();
        mock.push(MockReply::text("Fine."));
        ask(&mut agent, "Anything else?").await;
        let last = mock.requests().pop().unwrap();
        assert_eq!(image_parts(&last.body), 0);
        assert!(agent.memory().pictures() > 0, "the pictures are still kept");
    });
}
