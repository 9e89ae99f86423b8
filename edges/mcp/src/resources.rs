//! MCP resources: the camera's picture as `camera://{workspace_id}/latest`.
//!
//! Some MCP clients read resources rather than call tools. Reading
//! `camera://niryo_ws/latest` is a `get_camera_image` call for that workspace (annotated, full
//! width) made through the same path as every tool call — the call log, the caller's origin
//! for the motion policy, cancellation when the client goes away — and answered as the JPEG
//! (`image/jpeg`, base64 `blob`) followed by the text listing the objects. The resource list
//! names one such resource per configured workspace, and the template
//! `camera://{workspace_id}/latest` describes them all.

use rmcp::model::{
    CallToolResult, ContentBlock, ReadResourceResult, Resource, ResourceContents, ResourceTemplate,
};
use rmcp::ErrorData as McpError;

/// The URI template of the camera resource.
pub const CAMERA_TEMPLATE: &str = "camera://{workspace_id}/latest";

/// The camera resource of workspace `id`.
pub fn camera_uri(id: &str) -> String {
    format!("camera://{id}/latest")
}

/// The resources listed: one camera picture per workspace.
pub fn list(workspace_ids: &[String]) -> Vec<Resource> {
    workspace_ids
        .iter()
        .map(|id| {
            Resource::new(camera_uri(id), format!("camera {id}"))
                .with_description(format!(
                    "The wrist camera's picture of workspace '{id}' from its observation pose, \
                     with the detected objects' ids drawn on it (reading it may move the arm \
                     to that pose)"
                ))
                .with_mime_type("image/jpeg")
        })
        .collect()
}

/// The resource template.
pub fn templates() -> Vec<ResourceTemplate> {
    vec![ResourceTemplate::new(CAMERA_TEMPLATE, "camera")
        .with_description(
            "The wrist camera's latest picture of a workspace, annotated with object ids",
        )
        .with_mime_type("image/jpeg")]
}

/// The workspace a camera URI names, or why the URI is not one robotd serves.
pub fn workspace_of(uri: &str, workspace_ids: &[String]) -> Result<String, McpError> {
    let not_found = |why: String| McpError::resource_not_found(why, None);
    let id = uri
        .strip_prefix("camera://")
        .and_then(|rest| rest.strip_suffix("/latest"))
        .ok_or_else(|| {
            not_found(format!(
                "unknown resource '{}'; robotd serves {CAMERA_TEMPLATE}",
                cut(uri)
            ))
        })?;
    if workspace_ids.iter().any(|w| w == id) {
        Ok(id.to_owned())
    } else {
        Err(not_found(format!(
            "unknown workspace '{}' in '{}'; known: {}",
            cut(id),
            cut(uri),
            workspace_ids.join(", ")
        )))
    }
}

/// The resource contents of a `get_camera_image` result: the JPEG, then the text. A failed
/// call (no picture) is an error carrying the tool's text.
pub fn contents_of(uri: &str, result: CallToolResult) -> Result<ReadResourceResult, McpError> {
    let text: Vec<String> = result
        .content
        .iter()
        .filter_map(|c| c.as_text().map(|t| t.text.clone()))
        .collect();
    let text = text.join("\n");
    let image = result.content.into_iter().find_map(|c| match c {
        ContentBlock::Image(image) => Some(image),
        _ => None,
    });
    match image {
        Some(image) => Ok(ReadResourceResult::new(vec![
            ResourceContents::blob(image.data.clone(), uri).with_mime_type("image/jpeg"),
            ResourceContents::text(text, uri),
        ])),
        None => Err(McpError::internal_error(text, None)),
    }
}

/// At most 200 characters of something a client sent, for an error message.
fn cut(text: &str) -> String {
    match text.char_indices().nth(200) {
        Some((at, _)) => format!("{}…", &text[..at]),
        None => text.to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_uris_name_a_configured_workspace() {
        let ids = vec!["niryo_ws".to_owned(), "gazebo_1".to_owned()];
        assert_eq!(
            workspace_of("camera://gazebo_1/latest", &ids).unwrap(),
            "gazebo_1"
        );
        let unknown = workspace_of("camera://moon/latest", &ids).unwrap_err();
        assert!(
            unknown.message.contains("unknown workspace 'moon'"),
            "{unknown:?}"
        );
        assert!(unknown.message.contains("known: niryo_ws, gazebo_1"));
        let other = workspace_of("file:///etc/passwd", &ids).unwrap_err();
        assert!(other.message.contains(CAMERA_TEMPLATE), "{other:?}");
        let long = format!("camera://{}/latest", "x".repeat(100_000));
        let error = workspace_of(&long, &ids).unwrap_err();
        assert!(
            error.message.len() < 1000,
            "the error does not echo a huge URI"
        );
        assert_eq!(list(&ids)[1].uri, "camera://gazebo_1/latest");
    }

    #[test]
    fn a_result_without_a_picture_is_an_error_with_its_text() {
        let failed =
            CallToolResult::success(vec![ContentBlock::text("❌ Error getting camera image: x")]);
        let error = contents_of("camera://a/latest", failed).unwrap_err();
        assert!(error.message.contains("❌ Error getting camera image: x"));
        let ok = CallToolResult::success(vec![
            ContentBlock::text("✓ Camera image"),
            ContentBlock::image("/9j/", "image/jpeg"),
        ]);
        let read = contents_of("camera://a/latest", ok).unwrap();
        assert_eq!(read.contents.len(), 2);
        assert!(
            matches!(&read.contents[0], ResourceContents::BlobResourceContents { blob, .. } if blob == "/9j/")
        );
    }
}
