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

/// Bounded conversation history (see the module docs).
#[derive(Debug, Clone)]
pub struct Memory {
    max_tokens: usize,
    turns: Vec<Vec<Message>>,
    dropped_turns: usize,
    dropped_requests: Vec<String>,
}

impl Memory {
    /// An empty history holding at most about `max_tokens` tokens.
    pub fn new(max_tokens: usize) -> Memory {
        Memory {
            max_tokens: max_tokens.max(64),
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
        if self.estimated_tokens() <= self.max_tokens {
            return;
        }
        // One turn left and still too big: shorten its oldest tool results (never the user's
        // request, never the newest message).
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
}
