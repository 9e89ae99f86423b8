//! The conversation history, bounded so a long lab session never overflows the model's context.
//!
//! History is kept as *turns*: a user request and everything the agent and the tools said while
//! working on it. The size is estimated (characters / 4, see
//! [`Message::estimated_tokens`]); when it exceeds the bound, the oldest whole turns are
//! dropped — a turn is never split, so an assistant message with tool calls always keeps its
//! tool results — and a one-line summary of what was dropped is kept instead. If the current
//! turn alone is over the bound (a very long tool loop), the oldest tool results in it are
//! shortened.
//!
//! Pictures (`get_camera_image`'s, for models that take images) are the heaviest messages and
//! the soonest stale: history keeps only the newest few ([`DEFAULT_MAX_PICTURES`]), and when it
//! is over the bound the oldest pictures go first, before any turn. The tool result that came
//! with a picture stays (its text lists what the picture showed).
//!
//! ```
//! use robotd_agent::memory::Memory;
//! use robotd_agent::llm::Message;
//!
//! let mut memory = Memory::new(300);
//! for i in 0..50 {
//!     memory.push(Message::user(format!("request {i}: {}", "x".repeat(100))));
//!     memory.push(Message::Assistant { content: Some("done".into()), tool_calls: vec![] });
//! }
//! assert!(memory.estimated_tokens() <= 300);
//! let summary = memory.summary().expect("old turns were dropped and summarised");
//! assert!(summary.contains("request(s) were handled"));
//! ```

use crate::llm::Message;

/// How many dropped requests the summary line names.
const SUMMARY_REQUESTS: usize = 4;
/// Characters of each dropped request in the summary.
const SUMMARY_CHARS: usize = 60;
/// Characters a shortened tool result keeps.
const SHORTENED_RESULT: usize = 160;
/// Pictures kept in the history by default: the newest two (the scene now, and before the
/// last change).
pub const DEFAULT_MAX_PICTURES: usize = 2;

/// Bounded conversation history (see the module docs).
#[derive(Debug, Clone)]
pub struct Memory {
    max_tokens: usize,
    max_pictures: usize,
    turns: Vec<Vec<Message>>,
    dropped_turns: usize,
    dropped_requests: Vec<String>,
}

impl Memory {
    /// An empty history holding at most about `max_tokens` tokens.
    pub fn new(max_tokens: usize) -> Memory {
        Self::with_pictures(max_tokens, DEFAULT_MAX_PICTURES)
    }

    /// An empty history holding at most about `max_tokens` tokens and `max_pictures`
    /// pictures.
    pub fn with_pictures(max_tokens: usize, max_pictures: usize) -> Memory {
        Memory {
            max_tokens: max_tokens.max(64),
            max_pictures,
            turns: Vec::new(),
            dropped_turns: 0,
            dropped_requests: Vec::new(),
        }
    }

    /// The bound, in estimated tokens.
    pub fn max_tokens(&self) -> usize {
        self.max_tokens
    }

    /// Adds a message: a user message starts a new turn, anything else joins the current one.
    pub fn push(&mut self, message: Message) {
        match (&message, self.turns.last_mut()) {
            (Message::User(_), _) | (_, None) => self.turns.push(vec![message]),
            (_, Some(turn)) => turn.push(message),
        }
        self.enforce();
    }

    /// Adds a message to the current turn (a nudge from the agent is a user message that
    /// must not start a new turn).
    pub fn push_to_current_turn(&mut self, message: Message) {
        match self.turns.last_mut() {
            Some(turn) => turn.push(message),
            None => self.turns.push(vec![message]),
        }
        self.enforce();
    }

    /// Forgets everything.
    pub fn clear(&mut self) {
        self.turns.clear();
        self.dropped_turns = 0;
        self.dropped_requests.clear();
    }

    /// Pictures kept.
    pub fn pictures(&self) -> usize {
        self.messages()
            .filter(|m| matches!(m, Message::Picture { .. }))
            .count()
    }

    /// Drops the oldest picture (of the turns before the current one, with `older_turns_only`);
    /// false when there is none.
    fn drop_oldest_picture(&mut self, older_turns_only: bool) -> bool {
        let turns = if older_turns_only {
            self.turns.len().saturating_sub(1)
        } else {
            self.turns.len()
        };
        for turn in &mut self.turns[..turns] {
            if let Some(i) = turn
                .iter()
                .position(|m| matches!(m, Message::Picture { .. }))
            {
                turn.remove(i);
                return true;
            }
        }
        false
    }

    /// Turns kept.
    pub fn turns(&self) -> usize {
        self.turns.len()
    }

    /// The kept messages, oldest first.
    pub fn messages(&self) -> impl Iterator<Item = &Message> {
        self.turns.iter().flatten()
    }

    /// The summary of dropped turns, if any were dropped.
    pub fn summary(&self) -> Option<String> {
        if self.dropped_turns == 0 {
            return None;
        }
        let mut line = format!(
            "Earlier in this session {} request(s) were handled and are no longer shown",
            self.dropped_turns
        );
        if !self.dropped_requests.is_empty() {
            line.push_str("; the latest of them: ");
            let quoted: Vec<String> = self
                .dropped_requests
                .iter()
                .map(|r| format!("\"{r}\""))
                .collect();
            line.push_str(&quoted.join(", "));
        }
        line.push_str(". Look at the workspace again rather than relying on old positions.");
        Some(line)
    }

    /// The estimated size of what [`Memory::messages`] and [`Memory::summary`] hold.
    pub fn estimated_tokens(&self) -> usize {
        self.messages()
            .map(Message::estimated_tokens)
            .sum::<usize>()
            + self.summary().map_or(0, |s| s.len() / 4 + 4)
    }

    fn enforce(&mut self) {
        while self.pictures() > self.max_pictures && self.drop_oldest_picture(false) {}
        // Old pictures go before old turns; the current turn's stay while a turn can go.
        while self.estimated_tokens() > self.max_tokens && self.drop_oldest_picture(true) {}
        while self.estimated_tokens() > self.max_tokens && self.turns.len() > 1 {
            let turn = self.turns.remove(0);
            self.dropped_turns += 1;
            if let Some(Message::User(text)) = turn.first() {
                let mut short: String = text.chars().take(SUMMARY_CHARS).collect();
                if text.chars().count() > SUMMARY_CHARS {
                    short.push('…');
                }
                self.dropped_requests.push(short.replace('"', "'"));
                if self.dropped_requests.len() > SUMMARY_REQUESTS {
                    self.dropped_requests.remove(0);
                }
            }
        }
        // One turn left and still too big: its pictures but the newest go, then its oldest
        // tool results are shortened (never the user's request, never the newest message).
        while self.estimated_tokens() > self.max_tokens
            && self.pictures() > 1
            && self.drop_oldest_picture(false)
        {}
        if self.estimated_tokens() <= self.max_tokens {
            return;
        }
        self.shorten_current_turn();
    }

    fn shorten_current_turn(&mut self) {
        let max = self.max_tokens;
        let Some(turn) = self.turns.last_mut() else {
            return;
        };
        let last = turn.len().saturating_sub(1);
        for i in 0..last {
            let total: usize = turn.iter().map(Message::estimated_tokens).sum();
            if total <= max {
                return;
            }
            if let Message::Tool { content, .. } = &mut turn[i] {
                if content.chars().count() > SHORTENED_RESULT + 40 {
                    let short: String = content.chars().take(SHORTENED_RESULT).collect();
                    *content = format!("{short}… (shortened to save context)");
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::llm::ToolCall;

    fn tool_turn(memory: &mut Memory, i: usize) {
        memory.push(Message::user(format!(
            "request {i}: pick up the pencil {}",
            "please ".repeat(10)
        )));
        memory.push(Message::Assistant {
            content: Some("Plan: look, then move.".into()),
            tool_calls: vec![ToolCall {
                id: format!("c{i}"),
                name: "get_detected_objects".into(),
                arguments: "{}".into(),
            }],
        });
        memory.push(Message::Tool {
            call_id: format!("c{i}"),
            name: "get_detected_objects".into(),
            content: format!("✓ Found 3 object(s): {}", "[0.250, 0.010] ".repeat(40)),
        });
        memory.push(Message::Assistant {
            content: Some(format!("Done with {i}.")),
            tool_calls: vec![],
        });
    }

    #[test]
    fn two_hundred_turns_stay_under_the_bound() {
        let mut memory = Memory::new(2000);
        for i in 0..200 {
            tool_turn(&mut memory, i);
            assert!(
                memory.estimated_tokens() <= 2000,
                "turn {i}: {}",
                memory.estimated_tokens()
            );
        }
        assert!(
            memory.turns() > 1 && memory.turns() < 200,
            "{}",
            memory.turns()
        );
        let summary = memory.summary().expect("a summary of what was dropped");
        assert!(summary.contains("request(s) were handled"), "{summary}");
        // The newest dropped request is named; the kept ones are the latest.
        let kept_first = memory.messages().next().unwrap();
        let Message::User(first) = kept_first else {
            panic!("history starts with a user message, not {kept_first:?}");
        };
        let first_kept: usize = first["request ".len()..]
            .split(':')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!(
            summary.contains(&format!("request {}", first_kept - 1)),
            "{summary}"
        );
        assert!(memory
            .messages()
            .any(|m| matches!(m, Message::User(t) if t.starts_with("request 199:"))));
    }

    #[test]
    fn tool_calls_keep_their_results() {
        let mut memory = Memory::new(700);
        for i in 0..30 {
            tool_turn(&mut memory, i);
            let messages: Vec<&Message> = memory.messages().collect();
            for (j, m) in messages.iter().enumerate() {
                if let Message::Assistant { tool_calls, .. } = m {
                    for (k, call) in tool_calls.iter().enumerate() {
                        assert!(
                            matches!(messages.get(j + 1 + k), Some(Message::Tool { call_id, .. }) if *call_id == call.id),
                            "the result of {} was separated from its call",
                            call.id
                        );
                    }
                }
                if let Message::Tool { call_id, .. } = m {
                    assert!(j > 0, "a tool result {call_id} without its call");
                }
            }
        }
    }

    #[test]
    fn one_huge_turn_is_shortened_not_split() {
        let mut memory = Memory::new(500);
        memory.push(Message::user("sort everything"));
        for i in 0..10 {
            memory.push(Message::Assistant {
                content: None,
                tool_calls: vec![ToolCall {
                    id: format!("c{i}"),
                    name: "get_detected_objects".into(),
                    arguments: "{}".into(),
                }],
            });
            memory.push(Message::Tool {
                call_id: format!("c{i}"),
                name: "get_detected_objects".into(),
                content: "x".repeat(2000),
            });
        }
        assert_eq!(memory.turns(), 1);
        assert_eq!(memory.messages().count(), 21);
        assert!(memory.messages().next() == Some(&Message::user("sort everything")));
        memory.clear();
        assert_eq!(memory.messages().count(), 0);
        assert_eq!(memory.summary(), None);
    }

    #[test]
    fn old_pictures_go_first_and_the_history_stays_bounded() {
        let picture = |i: usize| Message::Picture {
            call_id: format!("c{i}"),
            name: "get_camera_image".into(),
            image: crate::vision::ImagePart {
                mime_type: "image/jpeg".into(),
                data_base64: "A".repeat(40_000),
            },
        };
        let mut memory = Memory::new(3000);
        for i in 0..100 {
            tool_turn(&mut memory, i);
            memory.push(picture(i));
            assert!(memory.pictures() <= DEFAULT_MAX_PICTURES);
            assert!(
                memory.estimated_tokens() <= 3000,
                "{i}: {}",
                memory.estimated_tokens()
            );
        }
        // The newest pictures are the ones kept.
        let kept: Vec<&str> = memory
            .messages()
            .filter_map(|m| match m {
                Message::Picture { call_id, .. } => Some(call_id.as_str()),
                _ => None,
            })
            .collect();
        assert_eq!(kept.last(), Some(&"c99"), "the newest picture is kept");
        // With room, the two newest are kept.
        let mut roomy = Memory::new(50_000);
        for i in 0..10 {
            tool_turn(&mut roomy, i);
            roomy.push(picture(i));
        }
        let kept: Vec<String> = roomy
            .messages()
            .filter_map(|m| match m {
                Message::Picture { call_id, .. } => Some(call_id.clone()),
                _ => None,
            })
            .collect();
        assert_eq!(kept, ["c8", "c9"]);
        assert_eq!(roomy.turns(), 10, "pictures went, no turn did");
        // Over the bound, a picture goes before a turn.
        let mut small = Memory::with_pictures(1100, 5);
        tool_turn(&mut small, 0);
        small.push(picture(0));
        tool_turn(&mut small, 1);
        assert_eq!(small.turns(), 2, "the first turn is kept");
        assert_eq!(small.pictures(), 0, "its picture was dropped instead");
    }
}
