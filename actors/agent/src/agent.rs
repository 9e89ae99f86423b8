//! The agent loop: a request in plain words → LLM rounds with tool calls → an answer.
//!
//! Per request the [`Agent`] sends the system prompt ([`system_prompt`]), the bounded history
//! and the tool list to the model, and then, for at most [`AgentConfig::max_rounds`] rounds:
//!
//! - the model's text that comes with tool calls is its understanding and plan
//!   ([`AgentEventKind::Plan`]) — in the same LLM call as the first tool calls, with no extra
//!   planning round;
//! - the tool calls run one at a time, in order, each reported as
//!   [`AgentEventKind::ToolCall`] and [`AgentEventKind::ToolResult`] (and an
//!   [`AgentEventKind::Picture`] per picture a tool returned, for the user to see); the
//!   results go back to the model;
//! - a reply with no tool calls is the [`AgentEventKind::Answer`] — unless it is a tool call
//!   written as text (`pick_place_object(...)`, a JSON object naming a tool), which gets a
//!   recovery nudge asking for real function calling.
//!
//! Cancelling the request's token stops the LLM call or the running tool (the motion stops
//! safely) and ends the request with [`AgentEventKind::Cancelled`]. The provider can be
//! switched between requests ([`Agent::switch`]) without losing the history.

use crate::llm::{LlmClient, LlmError, Message, RetryPolicy, ToolCall, ToolSpec};
use crate::memory::Memory;
use crate::providers::ProviderSettings;
use crate::tools::{ToolBackend, ToolResultText};
use robotd_protocol::agent::AgentEventKind;
use robotd_protocol::{Location, WorkspacePoint};
use serde_json::{Map, Value};
use std::sync::Arc;
use tokio_util::sync::CancellationToken;
use tracing::Instrument;

/// A workspace as the system prompt describes it.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkspaceHint {
    /// Workspace id, e.g. `niryo_ws`.
    pub id: String,
    /// Far-left corner `[x, y]` (largest x and y), metres.
    pub upper_left: [f64; 2],
    /// Near-right corner `[x, y]` (smallest x and y), metres.
    pub lower_right: [f64; 2],
}

impl From<&robotd_protocol::workspace::WorkspaceInfo> for WorkspaceHint {
    fn from(w: &robotd_protocol::workspace::WorkspaceInfo) -> Self {
        WorkspaceHint {
            id: w.id.clone(),
            upper_left: [w.upper_left.x_m, w.upper_left.y_m],
            lower_right: [w.lower_right.x_m, w.lower_right.y_m],
        }
    }
}

/// Tuning of the loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AgentConfig {
    /// LLM rounds per request, at most.
    pub max_rounds: usize,
    /// Bound of the history, in estimated tokens.
    pub memory_tokens: usize,
    /// Recovery nudges per request for tool calls written as text.
    pub max_nudges: usize,
    /// Whether the model is sent the pictures tools return (`agent.images`).
    pub images: crate::vision::Images,
    /// Pictures kept in the history, newest first.
    pub max_pictures: usize,
    /// Retries and timeouts of LLM calls.
    pub retry: RetryPolicy,
}

impl Default for AgentConfig {
    fn default() -> Self {
        Self {
            max_rounds: 15,
            memory_tokens: 12_000,
            max_nudges: 2,
            images: crate::vision::Images::Auto,
            max_pictures: crate::memory::DEFAULT_MAX_PICTURES,
            retry: RetryPolicy::default(),
        }
    }
}

/// The system prompt: frame, workspaces, gripper limit, Location values and the rules.
pub fn system_prompt(workspaces: &[WorkspaceHint]) -> String {
    let mut p = String::from(
        "You control a robot arm with a gripper and a wrist camera above a table, through the \
         tools you are given.\n\n\
         Frame: the robot's base frame, in metres: x points forward (away from the robot), \
         y points to the robot's left, z up. Coordinates are [x, y].\n",
    );
    if workspaces.is_empty() {
        p.push_str(
            "Workspace: ask get_workspace_coordinate_from_point for its corners \
             (e.g. workspace 'niryo_ws').\n",
        );
    }
    for w in workspaces {
        let center = [
            (w.upper_left[0] + w.lower_right[0]) / 2.0,
            (w.upper_left[1] + w.lower_right[1]) / 2.0,
        ];
        p.push_str(&format!(
            "Workspace '{}': upper left corner (far left) [{:.3}, {:.3}], lower right corner \
             (near right) [{:.3}, {:.3}], centre [{:.3}, {:.3}]. Everything you place must stay \
             inside it.\n",
            w.id,
            w.upper_left[0],
            w.upper_left[1],
            w.lower_right[0],
            w.lower_right[1],
            center[0],
            center[1]
        ));
    }
    let locations: Vec<String> = Location::STRINGS.iter().map(|s| format!("'{s}'")).collect();
    let points: Vec<String> = WorkspacePoint::STRINGS
        .iter()
        .map(|s| format!("'{s}'"))
        .collect();
    p.push_str(&format!(
        "Gripper: it can only grasp objects at most 5 cm wide; wider objects cannot be picked \
         and must be pushed (push_object).\n\
         Location values (the `location` argument of place_object and pick_place_object): {}. \
         'left next to' is +y, 'right next to' is −y, 'above' is +x (farther from the robot), \
         'below' is −x; with a location, place_coordinate is the reference object's \
         coordinate and the robot finds the free spot beside it.\n\
         Workspace points: {}.\n\n",
        locations.join(", "),
        points.join(", ")
    ));
    p.push_str(
        "Rules:\n\
         1. Always look before moving: call get_detected_objects first, and again after \
            objects were moved, and use the coordinates it reports (position.center_of_mass).\n\
         2. Use object labels exactly as detected.\n\
         3. Never place an object onto another object unless the user explicitly asks for it; \
            pick a free spot or a location such as 'right next to'.\n\
         4. To swap two objects, first move one of them to the centre of the largest free \
            space (get_largest_free_space_with_center), then move the other into its old place, \
            then the first one into the other's old place.\n\
         5. When the task is done, return to the observation pose (move2observation_pose).\n\
         6. Call tools one at a time through function calling. Never write a tool call as \
            text, JSON or code in your reply.\n\
         7. Look with get_camera_image when the user names something the detection tools do \
            not list, or before acting on an 'unknown object': the picture shows each object's \
            id. If you recognise it, name it with label_object(object_id, label) and then use \
            that name. (If you are not shown pictures, its text lists the objects; ask the \
            user what an unknown object is.)\n\n\
         Before your first tool call, state in one or two sentences what you understood and \
         your plan — in the same reply as that tool call. When the task is done (or cannot be \
         done), answer briefly in plain words what you did and what you saw.",
    );
    p
}

/// The recovery nudge for a tool call written as text.
pub const NUDGE: &str = "You wrote a tool call as text instead of calling the tool. Do not write \
    tool calls, JSON or code in your reply: call the tool through function calling (tool_calls). \
    If the task is already complete, answer in plain words.";

/// Removes `<think>…</think>` blocks (reasoning models such as Qwen 3 emit them).
pub fn strip_thinking(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(start) = rest.find("<think>") {
        out.push_str(&rest[..start]);
        match rest[start..].find("</think>") {
            Some(end) => rest = &rest[start + end + "</think>".len()..],
            None => {
                rest = "";
            }
        }
    }
    out.push_str(rest);
    out.trim().to_owned()
}

/// Whether `content` is a tool call written as text: `tool_name(`, a JSON object naming a
/// tool (`"name": "tool_name"`), or a `<tool_call>` tag.
pub fn looks_like_text_tool_call(content: &str, tool_names: &[String]) -> bool {
    if content.contains("<tool_call>") || content.contains("<function=") {
        return true;
    }
    let compact: String = content.chars().filter(|c| !c.is_whitespace()).collect();
    tool_names.iter().any(|name| {
        compact.contains(&format!("{name}("))
            || compact.contains(&format!("\"name\":\"{name}\""))
            || compact.contains(&format!("\"tool\":\"{name}\""))
            || compact.contains(&format!("\"function\":\"{name}\""))
            || compact.contains(&format!("\"{name}\":{{"))
    })
}

/// Why an agent could not be set up.
pub type SetupError = LlmError;

/// The LLM agent (see the module docs).
pub struct Agent {
    llm: LlmClient,
    tools: Arc<dyn ToolBackend>,
    specs: Vec<ToolSpec>,
    memory: Memory,
    prompt: String,
    config: AgentConfig,
}

impl std::fmt::Debug for Agent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Agent")
            .field("provider", self.llm.settings())
            .field("tools", &self.specs.len())
            .field("turns", &self.memory.turns())
            .finish()
    }
}

impl Agent {
    /// An agent talking to `settings`' model, calling `tools`, in `workspaces`.
    pub fn new(
        settings: ProviderSettings,
        tools: Arc<dyn ToolBackend>,
        workspaces: &[WorkspaceHint],
        config: AgentConfig,
    ) -> Result<Agent, SetupError> {
        Ok(Agent {
            llm: LlmClient::new(settings, config.retry)?,
            specs: tools.tools(),
            tools,
            memory: Memory::with_pictures(config.memory_tokens, config.max_pictures),
            prompt: system_prompt(workspaces),
            config,
        })
    }

    /// Switches provider and/or model; the conversation is kept.
    pub fn switch(&mut self, settings: ProviderSettings) -> Result<(), SetupError> {
        self.llm = LlmClient::new(settings, self.config.retry)?;
        Ok(())
    }

    /// The provider and model in use.
    pub fn provider(&self) -> &ProviderSettings {
        self.llm.settings()
    }

    /// The tools the model is offered.
    pub fn tools(&self) -> &[ToolSpec] {
        &self.specs
    }

    /// Whether the model in use is sent pictures.
    pub fn takes_images(&self) -> bool {
        let settings = self.llm.settings();
        crate::vision::takes_images(settings.provider, &settings.model, self.config.images)
    }

    /// The conversation so far.
    pub fn memory(&self) -> &Memory {
        &self.memory
    }

    /// Forgets the conversation.
    pub fn clear(&mut self) {
        self.memory.clear();
    }

    /// The messages the next LLM call sends.
    fn conversation(&self) -> Vec<Message> {
        let mut messages = vec![Message::System(self.prompt.clone())];
        if let Some(summary) = self.memory.summary() {
            messages.push(Message::System(summary));
        }
        // A model switched to mid-conversation that takes no images never sees one.
        let pictures = self.takes_images();
        messages.extend(
            self.memory
                .messages()
                .filter(|m| pictures || !matches!(m, Message::Picture { .. }))
                .cloned(),
        );
        messages
    }

    /// Works on `request`, reporting each step to `on_event`; returns the terminal event
    /// (answer, error or cancelled), which `on_event` also received.
    pub async fn run(
        &mut self,
        request: &str,
        cancel: CancellationToken,
        mut on_event: impl FnMut(AgentEventKind) + Send,
    ) -> AgentEventKind {
        let span = tracing::info_span!(
            "agent.request",
            provider = self.llm.settings().provider.name(),
            model = %self.llm.settings().model,
        );
        let terminal = self
            .run_inner(request, cancel, &mut on_event)
            .instrument(span)
            .await;
        on_event(terminal.clone());
        terminal
    }

    async fn run_inner(
        &mut self,
        request: &str,
        cancel: CancellationToken,
        on_event: &mut (impl FnMut(AgentEventKind) + Send),
    ) -> AgentEventKind {
        tracing::info!(request, "agent request");
        self.memory.push(Message::user(request));
        let names: Vec<String> = self.specs.iter().map(|t| t.name.clone()).collect();
        let mut nudges = 0;
        for round in 0..self.config.max_rounds {
            if cancel.is_cancelled() {
                return AgentEventKind::Cancelled;
            }
            let conversation = self.conversation();
            let completion = tokio::select! {
                c = self.llm.complete(&conversation, &self.specs) => c,
                _ = cancel.cancelled() => return AgentEventKind::Cancelled,
            };
            let completion = match completion {
                Ok(c) => c,
                Err(error) => {
                    return AgentEventKind::Error {
                        message: error.to_string(),
                    }
                }
            };
            let text = completion
                .content
                .as_deref()
                .map(strip_thinking)
                .filter(|t| !t.is_empty());
            if completion.tool_calls.is_empty() {
                let text = text.unwrap_or_default();
                if looks_like_text_tool_call(&text, &names) && nudges < self.config.max_nudges {
                    nudges += 1;
                    tracing::info!(round, "the model wrote a tool call as text; nudging");
                    self.memory.push(Message::Assistant {
                        content: Some(text),
                        tool_calls: vec![],
                    });
                    self.memory
                        .push_to_current_turn(Message::User(NUDGE.to_owned()));
                    continue;
                }
                if text.is_empty() {
                    if nudges < self.config.max_nudges {
                        nudges += 1;
                        self.memory.push(Message::Assistant {
                            content: None,
                            tool_calls: vec![],
                        });
                        self.memory.push_to_current_turn(Message::User(
                            "Your reply was empty. Continue the task with a tool call, or \
                             answer in plain words if it is done."
                                .to_owned(),
                        ));
                        continue;
                    }
                    return AgentEventKind::Error {
                        message: "the model replied with nothing".to_owned(),
                    };
                }
                self.memory.push(Message::Assistant {
                    content: Some(text.clone()),
                    tool_calls: vec![],
                });
                return AgentEventKind::Answer { text };
            }
            if let Some(plan) = &text {
                on_event(AgentEventKind::Plan { text: plan.clone() });
            }
            let calls = completion.tool_calls;
            self.memory.push(Message::Assistant {
                content: text,
                tool_calls: calls.clone(),
            });
            // Pictures follow all the round's tool results (a user message may not stand
            // between a model's tool calls and their results).
            let mut pictures = Vec::new();
            for (i, call) in calls.iter().enumerate() {
                if cancel.is_cancelled() {
                    self.skip_calls(&calls[i..]);
                    return AgentEventKind::Cancelled;
                }
                on_event(AgentEventKind::ToolCall {
                    call_id: call.id.clone(),
                    name: call.name.clone(),
                    arguments_json: call.arguments.clone(),
                });
                let result = self.execute(call, &names, cancel.clone()).await;
                on_event(AgentEventKind::ToolResult {
                    call_id: call.id.clone(),
                    name: call.name.clone(),
                    text: result.text.clone(),
                    ok: result.ok,
                });
                // The user sees every picture a tool returned, whether or not the model does.
                let shown = self.takes_images();
                for image in &result.images {
                    match crate::vision::picture_event(&call.id, &call.name, image, shown) {
                        Ok(event) => on_event(event),
                        Err(error) => {
                            tracing::warn!(tool = %call.name, %error, "a picture not passed on")
                        }
                    }
                }
                self.memory.push(Message::Tool {
                    call_id: call.id.clone(),
                    name: call.name.clone(),
                    content: result.text,
                });
                if self.takes_images() {
                    pictures.extend(result.images.into_iter().map(|image| Message::Picture {
                        call_id: call.id.clone(),
                        name: call.name.clone(),
                        image,
                    }));
                }
                if cancel.is_cancelled() {
                    self.skip_calls(&calls[i + 1..]);
                    return AgentEventKind::Cancelled;
                }
            }
            for picture in pictures {
                self.memory.push_to_current_turn(picture);
            }
        }
        AgentEventKind::Error {
            message: format!(
                "stopped after {} LLM rounds without a final answer; the task may be half done — \
                 look at the workspace before asking again",
                self.config.max_rounds
            ),
        }
    }

    /// Records calls that were not run, so the history stays well-formed.
    fn skip_calls(&mut self, calls: &[ToolCall]) {
        for call in calls {
            self.memory.push(Message::Tool {
                call_id: call.id.clone(),
                name: call.name.clone(),
                content: "❌ not run: the user cancelled the request".to_owned(),
            });
        }
    }

    async fn execute(
        &self,
        call: &ToolCall,
        names: &[String],
        cancel: CancellationToken,
    ) -> ToolResultText {
        if !names.contains(&call.name) {
            return ToolResultText::failed(format!(
                "❌ There is no tool '{}'. Available tools: {}",
                call.name,
                names.join(", ")
            ));
        }
        let raw = call.arguments.trim();
        let arguments = if raw.is_empty() {
            Map::new()
        } else {
            match serde_json::from_str::<Value>(raw) {
                Ok(Value::Object(map)) => map,
                Ok(Value::Null) => Map::new(),
                Ok(other) => {
                    return ToolResultText::failed(format!(
                        "❌ The arguments of {} must be a JSON object, not {other}",
                        call.name
                    ))
                }
                Err(error) => {
                    return ToolResultText::failed(format!(
                        "❌ The arguments of {} are not valid JSON ({error}); send a JSON object",
                        call.name
                    ))
                }
            }
        };
        let span = tracing::info_span!("tool.call", tool = %call.name, call_id = %call.id, ok = tracing::field::Empty);
        let result = self
            .tools
            .call(&call.name, arguments, cancel)
            .instrument(span.clone())
            .await;
        span.record("ok", result.ok);
        span.in_scope(|| tracing::info!(text = %result.text, "tool result"));
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_tool_calls_are_recognised() {
        let names = vec![
            "pick_place_object".to_owned(),
            "get_detected_objects".to_owned(),
        ];
        for text in [
            "pick_place_object(object_name='pencil', pick_coordinate=[0.2, 0.1])",
            "I will call get_detected_objects() now.",
            r#"{"name": "get_detected_objects", "arguments": {}}"#,
            "```json\n{\n  \"tool\": \"pick_place_object\"\n}\n```",
            "<tool_call>{\"name\":\"x\"}</tool_call>",
        ] {
            assert!(looks_like_text_tool_call(text, &names), "{text}");
        }
        for text in [
            "I looked with get_detected_objects and placed the pencil right next to the red cube.",
            "Done.",
        ] {
            assert!(!looks_like_text_tool_call(text, &names), "{text}");
        }
    }

    #[test]
    fn thinking_is_stripped() {
        assert_eq!(
            strip_thinking("<think>hmm\nyes</think>\nPlan: look."),
            "Plan: look."
        );
        assert_eq!(strip_thinking("a<think>x</think>b<think>unclosed"), "ab");
        assert_eq!(strip_thinking("plain"), "plain");
    }

    #[test]
    fn the_prompt_teaches_frame_workspace_gripper_locations_and_rules() {
        let p = system_prompt(&[WorkspaceHint {
            id: "niryo_ws".into(),
            upper_left: [0.337, 0.087],
            lower_right: [0.163, -0.087],
        }]);
        for needle in [
            "x points forward",
            "y points to the robot's left",
            "[0.337, 0.087]",
            "[0.163, -0.087]",
            "5 cm",
            "'right next to'",
            "'on top of'",
            "get_detected_objects first",
            "exactly as detected",
            "Never place an object onto another object",
            "get_largest_free_space_with_center",
            "move2observation_pose",
            "same reply as that tool call",
        ] {
            assert!(p.contains(needle), "prompt lacks {needle:?}");
        }
    }
}
