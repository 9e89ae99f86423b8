//! `robotd call <tool> --arg key=value …`: one tool call against a running robotd (or any
//! MCP server), for scripts and quick checks.

use anyhow::{bail, Context, Result};
use rmcp::model::CallToolRequestParams;
use serde_json::{Map, Value};
use std::process::ExitCode;

/// What to call and where.
pub struct CallOptions {
    /// MCP URL (`…/sse` or `…/mcp`).
    pub url: String,
    /// Bearer token, if the server wants one.
    pub token: Option<String>,
    /// Tool name, or `list`.
    pub tool: String,
    /// `key=value` arguments.
    pub args: Vec<String>,
    /// Print structuredContent instead of the text.
    pub json: bool,
}

/// Parses `key=value` pairs; values are JSON when they parse as JSON, strings otherwise.
pub fn parse_arguments(pairs: &[String]) -> Result<Map<String, Value>> {
    let mut map = Map::new();
    for pair in pairs {
        let Some((key, value)) = pair.split_once('=') else {
            bail!("--arg {pair:?} is not key=value; write e.g. --arg object_name=pencil");
        };
        let key = key.trim();
        if key.is_empty() {
            bail!("--arg {pair:?} has an empty key");
        }
        let value = serde_json::from_str::<Value>(value)
            .unwrap_or_else(|_| Value::String(value.to_owned()));
        if map.insert(key.to_owned(), value).is_some() {
            bail!("--arg {key} is given twice");
        }
    }
    Ok(map)
}

/// Writes to stdout; a closed pipe (`robotd call list | head`) is not an error.
fn print_out(text: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    let _ = out.write_all(text.as_bytes()).and_then(|_| out.flush());
}

/// Runs the call; the exit code says how it went (0 ✓, 1 ❌, 2 no call).
pub async fn run(options: CallOptions) -> Result<ExitCode> {
    let arguments = parse_arguments(&options.args)?;
    let client = match robotd_mcp::client::connect(&options.url, options.token.as_deref()).await {
        Ok(client) => client,
        Err(error) => {
            eprintln!("robotd call: {error}");
            return Ok(ExitCode::from(2));
        }
    };
    if options.tool == "list" {
        let tools = client.list_all_tools().await.context("listing the tools")?;
        let mut listing = String::new();
        for tool in tools {
            let first_line = tool
                .description
                .as_deref()
                .unwrap_or("")
                .split(". ")
                .next()
                .unwrap_or("")
                .to_owned();
            listing.push_str(&format!("{:38} {first_line}\n", tool.name));
        }
        print_out(&listing);
        let _ = client.cancel().await;
        return Ok(ExitCode::SUCCESS);
    }
    let request = CallToolRequestParams::new(options.tool.clone()).with_arguments(arguments);
    let result = match client.call_tool(request).await {
        Ok(result) => result,
        Err(error) => {
            eprintln!("robotd call: {} failed: {error}", options.tool);
            let _ = client.cancel().await;
            return Ok(ExitCode::from(2));
        }
    };
    let _ = client.cancel().await;
    let text: String = result
        .content
        .iter()
        .filter_map(|c| c.as_text().map(|t| t.text.clone()))
        .collect::<Vec<_>>()
        .join("\n");
    if options.json {
        let structured = result.structured_content.clone().unwrap_or(Value::Null);
        print_out(&format!("{}\n", serde_json::to_string_pretty(&structured)?));
    } else {
        print_out(&format!("{text}\n"));
    }
    let failed = result.is_error == Some(true) || text.starts_with('❌');
    Ok(if failed {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_json_when_they_parse() {
        let m = parse_arguments(&[
            "object_name=red cube".into(),
            "pick_coordinate=[0.28, 0.04]".into(),
            "ascending=false".into(),
            "distance=50".into(),
        ])
        .unwrap();
        assert_eq!(m["object_name"], "red cube");
        assert_eq!(m["pick_coordinate"], serde_json::json!([0.28, 0.04]));
        assert_eq!(m["ascending"], false);
        assert_eq!(m["distance"], 50);
        assert!(parse_arguments(&["nokey".into()]).is_err());
        assert!(parse_arguments(&["a=1".into(), "a=2".into()]).is_err());
    }
}
