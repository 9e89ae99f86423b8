//! The tools as clients see them: name, description, input and output schema.
//!
//! Everything here is derived from the tool table (`crate::tools`): the schemas come from
//! each tool's argument and data types, so this list cannot drift from what the handlers
//! read and return.

use serde_json::{Map, Value};

/// A tool as listed to clients.
#[derive(Debug, Clone)]
pub struct ToolInfo {
    /// The tool's name, e.g. `pick_place_object`.
    pub name: &'static str,
    /// What it does and how to call it, for people and LLMs.
    pub description: &'static str,
    /// JSON Schema of the arguments.
    pub input_schema: Map<String, Value>,
    /// JSON Schema of `structuredContent`.
    pub output_schema: Map<String, Value>,
    /// Whether the tool moves the arm (long-running, cancellable, reports progress).
    pub moves_arm: bool,
}

/// Every tool, in the order of the contract.
pub fn all() -> Vec<ToolInfo> {
    crate::tools::TOOLS
        .iter()
        .map(|t| ToolInfo {
            name: t.name,
            description: t.description,
            input_schema: (t.input_schema)(),
            output_schema: (t.output_schema)(),
            moves_arm: t.moves_arm,
        })
        .collect()
}
