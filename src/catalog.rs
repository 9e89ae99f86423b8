//! `robotd catalog`: the bus catalogue for people and for other languages.
//!
//! The table is for reading; `--json` is [`robotd_topics::description`] verbatim,
//! the file `python/robotd/src/robotd_bus/catalog.json` that the Python package loads (a test
//! keeps the two equal, so the Python side cannot drift from the Rust catalogue).

use robotd_runtime::bus::Entry;
use robotd_topics::description;

/// The catalogue as a table or as pretty JSON (with a final newline).
pub fn render(json: bool) -> String {
    let description = description();
    if json {
        let mut text = serde_json::to_string_pretty(&description)
            .expect("the catalogue description is plain data");
        text.push('\n');
        return text;
    }
    let mut out = format!(
        "{:<32} {:<8} {:<40} {}\n",
        "NAME", "KIND", "MESSAGE TYPE (VERSION)", "OVERFLOW OR REPLY"
    );
    for entry in &description.entries {
        let line = match entry {
            Entry::Topic(t) => format!(
                "{:<32} {:<8} {:<40} {} depth {}\n",
                t.name,
                "topic",
                format!("{} (v{})", t.msg_type, t.schema_version),
                t.overflow,
                t.depth
            ),
            Entry::Frames(f) => format!(
                "{:<32} {:<8} {:<40} {} depth {}\n",
                f.name, "frames", description.frame_slot_type, f.overflow, f.depth
            ),
            Entry::Service(s) => format!(
                "{:<32} {:<8} {:<40} reply {} (v{})\n",
                s.name,
                "service",
                format!("{} (v{})", s.requests.msg_type, s.requests.schema_version),
                s.replies.msg_type,
                s.replies.schema_version
            ),
        };
        out.push_str(&line);
    }
    out
}
