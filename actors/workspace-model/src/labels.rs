//! The detectable-label registry: which object names the robot says it can recognise.
//!
//! `get_object_labels_as_string` lists these labels and `add_object_name2object_labels` adds
//! one. Labels are stored normalised — trimmed, lower-case, inner runs of whitespace collapsed
//! to one space — so `" Red  Cube"` and `"red cube"` are the same label; the list keeps the
//! order in which labels were first added and never holds one twice.
//!
//! Not every label can be seen by every detector: the built-in colour/shape detector knows a
//! fixed table (its labels are given at start), while a label added later can only be found by
//! an external detector (a model behind the Redis edge). The registry says which is which, so
//! a tool or an LLM can tell "I know the word" from "my own camera pipeline can find it".
//!
//! ```
//! use robotd_workspace_model::labels::LabelRegistry;
//!
//! let mut labels = LabelRegistry::new(&["pencil".into()], &["pencil".into(), "red cube".into()]);
//! assert_eq!(labels.labels(), ["pencil", "red cube"]);
//! let added = labels.add("  Screwdriver ").unwrap();
//! assert_eq!((added.label.as_str(), added.already_known), ("screwdriver", false));
//! assert!(labels.add("SCREWDRIVER").unwrap().already_known);
//! assert_eq!(labels.external_only(), ["screwdriver"]);
//! ```

use robotd_protocol::workspace::DetectableLabels;

/// The label as stored: trimmed, lower-case, inner whitespace runs collapsed to one space.
pub fn normalise(label: &str) -> String {
    label
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .to_lowercase()
}

/// A label could not be added.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LabelError {
    /// Nothing but whitespace was given.
    #[error("object_name must be a non-empty string")]
    Empty,
    /// The label is longer than the registry takes.
    #[error(
        "object_name has {chars} characters; labels are at most {max} (workspace.max_label_chars)"
    )]
    TooLong {
        /// Its length in characters (normalised).
        chars: usize,
        /// The limit.
        max: usize,
    },
    /// The registry holds as many labels as it takes.
    #[error("the label list is full ({max} labels, workspace.max_labels); no label was added")]
    Full {
        /// The limit.
        max: usize,
    },
}

/// How many labels the registry holds and how long each may be, so that one request cannot
/// grow the list (and every reply that lists it) without bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LabelLimits {
    /// Most labels held.
    pub max_labels: usize,
    /// Longest label, characters.
    pub max_chars: usize,
}

impl Default for LabelLimits {
    fn default() -> Self {
        Self {
            max_labels: 500,
            max_chars: 100,
        }
    }
}

/// The outcome of [`LabelRegistry::add`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Added {
    /// The label as stored.
    pub label: String,
    /// True when it was already in the list (nothing changed).
    pub already_known: bool,
}

/// The detectable labels, in the order they were added.
#[derive(Debug, Clone, Default)]
pub struct LabelRegistry {
    labels: Vec<String>,
    builtin: Vec<String>,
    limits: LabelLimits,
}

impl LabelRegistry {
    /// A registry holding the `configured` labels, then any of the built-in detector's labels
    /// (`builtin`) not already among them.
    pub fn new(configured: &[String], builtin: &[String]) -> Self {
        Self::with_limits(configured, builtin, LabelLimits::default())
    }

    /// [`Self::new`] with `limits` on the labels added later (the configured and built-in
    /// ones are always kept).
    pub fn with_limits(configured: &[String], builtin: &[String], limits: LabelLimits) -> Self {
        let mut registry = Self {
            labels: Vec::new(),
            builtin: Vec::new(),
            limits: LabelLimits {
                max_labels: usize::MAX,
                max_chars: usize::MAX,
            },
        };
        for label in builtin {
            let label = normalise(label);
            if !label.is_empty() && !registry.builtin.contains(&label) {
                registry.builtin.push(label);
            }
        }
        for label in configured.iter().chain(builtin) {
            // Empty configured labels are skipped, not fatal: configuration was checked at load.
            let _ = registry.add(label);
        }
        registry.limits = limits;
        registry
    }

    /// Adds `label` (normalised). Adding a known label changes nothing and says so.
    pub fn add(&mut self, label: &str) -> Result<Added, LabelError> {
        let label = normalise(label);
        if label.is_empty() {
            return Err(LabelError::Empty);
        }
        let chars = label.chars().count();
        if chars > self.limits.max_chars {
            return Err(LabelError::TooLong {
                chars,
                max: self.limits.max_chars,
            });
        }
        let already_known = self.labels.contains(&label);
        if !already_known {
            if self.labels.len() >= self.limits.max_labels {
                return Err(LabelError::Full {
                    max: self.limits.max_labels,
                });
            }
            self.labels.push(label.clone());
        }
        Ok(Added {
            label,
            already_known,
        })
    }

    /// Every label, in the order added.
    pub fn labels(&self) -> &[String] {
        &self.labels
    }

    /// The labels the built-in detector can see, in registry order.
    pub fn builtin(&self) -> Vec<String> {
        self.labels
            .iter()
            .filter(|l| self.builtin.contains(l))
            .cloned()
            .collect()
    }

    /// The labels only an external detector could find, in registry order.
    pub fn external_only(&self) -> Vec<String> {
        self.labels
            .iter()
            .filter(|l| !self.builtin.contains(l))
            .cloned()
            .collect()
    }

    /// The registry as published on `workspace/labels`; `added` names the label whose
    /// addition caused the publication.
    pub fn snapshot(&self, added: Option<String>) -> DetectableLabels {
        DetectableLabels {
            labels: self.labels.clone(),
            added,
            builtin: self.builtin(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn strings(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn starts_with_the_configured_labels_then_the_builtin_ones() {
        let r = LabelRegistry::new(
            &strings(&["Pencil", "screwdriver", "pencil "]),
            &strings(&["red cube", "PENCIL"]),
        );
        assert_eq!(r.labels(), ["pencil", "screwdriver", "red cube"]);
        assert_eq!(r.builtin(), ["pencil", "red cube"]);
        assert_eq!(r.external_only(), ["screwdriver"]);
    }

    #[test]
    fn adding_normalises_and_deduplicates_keeping_order() {
        let mut r = LabelRegistry::new(&strings(&["pencil"]), &[]);
        assert_eq!(
            r.add("  Blue\tSQUARE ").unwrap(),
            Added {
                label: "blue square".into(),
                already_known: false
            }
        );
        assert_eq!(
            r.add("blue   square").unwrap(),
            Added {
                label: "blue square".into(),
                already_known: true
            }
        );
        assert_eq!(r.add(" \n").unwrap_err(), LabelError::Empty);
        let mut small = LabelRegistry::with_limits(
            &strings(&["pencil"]),
            &[],
            LabelLimits {
                max_labels: 2,
                max_chars: 10,
            },
        );
        assert_eq!(
            small.add(&"x".repeat(600_000)).unwrap_err(),
            LabelError::TooLong {
                chars: 600_000,
                max: 10
            }
        );
        small.add("cup").unwrap();
        assert_eq!(small.add("mug").unwrap_err(), LabelError::Full { max: 2 });
        assert!(
            small.add("CUP").unwrap().already_known,
            "a known label is no addition"
        );
        assert_eq!(small.labels(), ["pencil", "cup"]);
        assert_eq!(r.labels(), ["pencil", "blue square"]);
        let published = r.snapshot(Some("blue square".into()));
        assert_eq!(published.labels, ["pencil", "blue square"]);
        assert!(published.builtin.is_empty());
        assert_eq!(published.added.as_deref(), Some("blue square"));
    }

    #[test]
    fn an_empty_registry_lists_nothing() {
        let r = LabelRegistry::new(&[], &[]);
        assert!(r.labels().is_empty());
        assert!(r.builtin().is_empty() && r.external_only().is_empty());
    }
}
