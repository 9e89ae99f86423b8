//! The queue of texts waiting to be spoken.
//!
//! Higher priority first, then older first. It holds at most `capacity` texts: when one more
//! arrives, the lowest-priority oldest text (which may be the new one) is dropped. The same
//! text (case and surrounding spaces ignored) asked again within the duplicate window of its
//! last acceptance is dropped too — three skills announcing the same thing say it once. A text
//! the full queue dropped was never said, so asking for it again is not a duplicate.

use std::collections::HashMap;
use std::time::{Duration, Instant};

/// A text waiting to be spoken.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Queued {
    /// The text.
    pub text: String,
    /// Its priority (higher first).
    pub priority: u8,
    /// Who asked.
    pub source: String,
    seq: u64,
}

/// Why a text was not queued or was pushed out.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Rejected {
    /// The same text was accepted less than the duplicate window ago.
    Duplicate(String),
    /// The queue was full and this text had the lowest priority (the oldest of those).
    QueueFull(Queued),
}

/// The priority queue with duplicate suppression.
#[derive(Debug)]
pub struct SpeechQueue {
    capacity: usize,
    duplicate_window: Duration,
    items: Vec<Queued>,
    next_seq: u64,
    /// Normalised text → when it was last accepted, and the `seq` it was accepted as.
    accepted_at: HashMap<String, (Instant, u64)>,
}

impl SpeechQueue {
    /// A queue of at most `capacity` (≥ 1) texts.
    pub fn new(capacity: usize, duplicate_window: Duration) -> Self {
        Self {
            capacity: capacity.max(1),
            duplicate_window,
            items: Vec::new(),
            next_seq: 0,
            accepted_at: HashMap::new(),
        }
    }

    /// Texts waiting.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Whether nothing waits.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Offers a text at time `now`. Returns what was dropped, if anything: the text itself
    /// (a duplicate, or the lowest priority of a full queue) or an older one it pushed out.
    pub fn push(
        &mut self,
        text: &str,
        priority: u8,
        source: &str,
        now: Instant,
    ) -> Option<Rejected> {
        let key = text.trim().to_lowercase();
        if let Some((at, _)) = self.accepted_at.get(&key) {
            if now.saturating_duration_since(*at) < self.duplicate_window {
                return Some(Rejected::Duplicate(text.to_owned()));
            }
        }
        self.accepted_at
            .retain(|_, (at, _)| now.saturating_duration_since(*at) < self.duplicate_window);
        self.accepted_at.insert(key, (now, self.next_seq));
        self.items.push(Queued {
            text: text.to_owned(),
            priority,
            source: source.to_owned(),
            seq: self.next_seq,
        });
        self.next_seq += 1;
        if self.items.len() > self.capacity {
            let victim = self
                .items
                .iter()
                .enumerate()
                .min_by_key(|(_, q)| (q.priority, q.seq))
                .map(|(i, _)| i)?;
            let victim = self.items.remove(victim);
            let key = victim.text.trim().to_lowercase();
            if self
                .accepted_at
                .get(&key)
                .is_some_and(|(_, seq)| *seq == victim.seq)
            {
                self.accepted_at.remove(&key);
            }
            return Some(Rejected::QueueFull(victim));
        }
        None
    }

    /// Takes the next text to speak: highest priority, oldest first.
    pub fn pop(&mut self) -> Option<Queued> {
        let next = self
            .items
            .iter()
            .enumerate()
            .max_by_key(|(_, q)| (q.priority, std::cmp::Reverse(q.seq)))
            .map(|(i, _)| i)?;
        Some(self.items.remove(next))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn higher_priority_first_then_older() {
        let t = Instant::now();
        let mut q = SpeechQueue::new(50, Duration::from_secs(2));
        q.push("a", 5, "s", t);
        q.push("b", 9, "s", t);
        q.push("c", 5, "s", t);
        q.push("d", 9, "s", t);
        let order: Vec<String> = std::iter::from_fn(|| q.pop()).map(|i| i.text).collect();
        assert_eq!(order, ["b", "d", "a", "c"]);
    }

    #[test]
    fn duplicates_within_the_window_are_dropped() {
        let t = Instant::now();
        let mut q = SpeechQueue::new(50, Duration::from_secs(2));
        assert_eq!(q.push("Hello", 5, "s", t), None);
        assert_eq!(
            q.push(" hello ", 5, "s", t + Duration::from_millis(1999)),
            Some(Rejected::Duplicate(" hello ".into()))
        );
        assert_eq!(
            q.push("hello", 5, "s", t + Duration::from_millis(2000)),
            None
        );
        assert_eq!(q.len(), 2);
    }

    #[test]
    fn a_full_queue_drops_the_lowest_priority_oldest() {
        let t = Instant::now();
        let mut q = SpeechQueue::new(3, Duration::ZERO);
        q.push("low old", 1, "s", t);
        q.push("high", 9, "s", t);
        q.push("low new", 1, "s", t);
        match q.push("mid", 5, "s", t) {
            Some(Rejected::QueueFull(item)) => assert_eq!(item.text, "low old"),
            other => panic!("{other:?}"),
        }
        // A newcomer of lower priority than everything waiting is itself dropped.
        match q.push("lowest", 0, "s", t) {
            Some(Rejected::QueueFull(item)) => assert_eq!(item.text, "lowest"),
            other => panic!("{other:?}"),
        }
        let order: Vec<String> = std::iter::from_fn(|| q.pop()).map(|i| i.text).collect();
        assert_eq!(order, ["high", "mid", "low new"]);
    }

    #[test]
    fn a_text_dropped_by_a_full_queue_is_no_duplicate() {
        let t = Instant::now();
        let mut q = SpeechQueue::new(1, Duration::from_secs(2));
        q.push("high", 9, "s", t);
        assert!(matches!(
            q.push("low", 1, "s", t),
            Some(Rejected::QueueFull(item)) if item.text == "low"
        ));
        q.pop();
        // "low" was never said: asked again at once, it is queued, not called a duplicate.
        assert_eq!(q.push("low", 1, "s", t + Duration::from_millis(10)), None);
        assert_eq!(
            q.push("low", 1, "s", t + Duration::from_millis(20)),
            Some(Rejected::Duplicate("low".into()))
        );
    }
}
