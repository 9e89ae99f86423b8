//! One name per object: the label a track answers to is the one its detector gave most often
//! over its last [`LABEL_VOTES`] views.
//!
//! A detector that calls the pencil "pencil" in one view and "yellow bar" in the next does not
//! rename the object on every view: the label is the majority of the recent views (compared
//! case-insensitively, spelled as most recently seen); on a tie the label the track already has
//! stays, so a detector that flips between two names does not flip the object's name.

use std::collections::VecDeque;

/// How many recent views of an object vote on its label.
pub const LABEL_VOTES: usize = 5;

/// The labels a detector gave one object in its recent views, oldest first.
#[derive(Debug, Clone, Default)]
pub(super) struct LabelVotes {
    recent: VecDeque<String>,
}

fn key(label: &str) -> String {
    label.trim().to_lowercase()
}

impl LabelVotes {
    /// Votes starting with one view's `label`.
    pub(super) fn new(label: &str) -> Self {
        let mut votes = Self::default();
        votes.push(label);
        votes
    }

    /// Adds one view's label, dropping the oldest beyond [`LABEL_VOTES`].
    pub(super) fn push(&mut self, label: &str) {
        if self.recent.len() == LABEL_VOTES {
            self.recent.pop_front();
        }
        self.recent.push_back(label.trim().to_owned());
    }

    /// Whether the detector called the object `label` in one of the recent views.
    pub(super) fn contains(&self, label: &str) -> bool {
        let label = key(label);
        self.recent.iter().any(|l| key(l) == label)
    }

    /// The label given most often; on a tie `current` if it is among the tied, else the most
    /// recent of them. Spelled as most recently seen.
    pub(super) fn winner(&self, current: &str) -> String {
        let count = |k: &str| self.recent.iter().filter(|l| key(l) == k).count();
        let best = self
            .recent
            .iter()
            .map(|l| count(&key(l)))
            .max()
            .unwrap_or(0);
        let current_key = key(current);
        let chosen = if count(&current_key) == best {
            current_key
        } else {
            self.recent
                .iter()
                .rev()
                .map(|l| key(l))
                .find(|k| count(k) == best)
                .unwrap_or(current_key)
        };
        self.recent
            .iter()
            .rev()
            .find(|l| key(l) == chosen)
            .cloned()
            .unwrap_or_else(|| current.to_owned())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_majority_of_the_last_five_views_names_and_ties_keep_the_name() {
        let mut votes = LabelVotes::new("pencil");
        votes.push("yellow bar");
        // 1 : 1, the track is called "pencil": it stays.
        assert_eq!(votes.winner("pencil"), "pencil");
        votes.push("Yellow Bar");
        // 1 : 2: the majority, spelled as last seen.
        assert_eq!(votes.winner("pencil"), "Yellow Bar");
        for _ in 0..3 {
            votes.push("pencil");
        }
        // The first "pencil" fell out of the five: 3 pencil : 2 yellow bar.
        assert_eq!(votes.winner("yellow bar"), "pencil");
        assert!(votes.contains(" YELLOW bar") && !votes.contains("red cube"));
        for _ in 0..5 {
            votes.push("red cube");
        }
        assert!(!votes.contains("pencil"));
        assert_eq!(votes.winner("pencil"), "red cube");
    }
}
