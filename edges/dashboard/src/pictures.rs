//! The pictures the agent looked at, for the chat.
//!
//! When a tool returns a picture (`get_camera_image`: the camera's view with the objects' ids
//! drawn), the agent publishes an `agent.event` of kind `picture` with the file in base64
//! right after the call's result. The live thread hands it to [`Pictures::add`], which checks
//! it (a JPEG or PNG of at most [`MAX_PICTURE_BYTES`], decoded and its magic bytes checked),
//! keeps the file under a fresh random id and turns the event into what the page gets: the
//! same `agent` event with a `url` in place of the bytes ([`PictureShown`]). `GET
//! /api/chat/pictures/{id}` ([`serve`]) answers with the exact file the agent got. Only the
//! newest [`KEPT`] pictures are kept, so their memory is bounded (at most 32 × 160 KiB) and
//! the events every viewer receives stay small.

use crate::live::LiveEvent;
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use base64::Engine;
use bytes::Bytes;
use robotd_protocol::agent::{validate_picture, AgentEvent, AgentEventKind, MAX_PICTURE_BYTES};
use serde::Serialize;
use serde_json::json;
use std::collections::VecDeque;
use std::sync::Mutex;

/// Pictures kept for the chat; an older one answers 404.
pub const KEPT: usize = 32;

/// Where the page fetches picture `id`.
pub fn url_of(id: &str) -> String {
    format!("/api/chat/pictures/{id}")
}

/// One kept picture.
#[derive(Debug, Clone)]
pub struct Picture {
    /// `image/jpeg` or `image/png`.
    pub mime_type: &'static str,
    /// The file, byte for byte as the agent got it.
    pub file: Bytes,
}

/// The newest [`KEPT`] pictures by id.
#[derive(Debug, Default)]
pub struct Pictures {
    kept: Mutex<VecDeque<(String, Picture)>>,
}

/// A picture event as the page gets it: `{"type": "agent", "request_id", "seq", "event":
/// {"kind": "picture", "call_id", "name", "mime_type", "url", "bytes", "shown_to_model"}}`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PictureEvent {
    /// The request this is about.
    pub request_id: String,
    /// The event's number within the request.
    pub seq: u32,
    /// The picture.
    pub event: PictureShown,
}

/// The `event` of a [`PictureEvent`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PictureShown {
    /// Always `"picture"`.
    pub kind: &'static str,
    /// Id of the tool call that returned it.
    pub call_id: String,
    /// Tool name.
    pub name: String,
    /// `image/jpeg` or `image/png`.
    pub mime_type: &'static str,
    /// Where the file is: `/api/chat/pictures/{id}`.
    pub url: String,
    /// The file's size.
    pub bytes: usize,
    /// Whether the model was sent it.
    pub shown_to_model: bool,
}

/// The first bytes of each picture type (JPEG: SOI and the next marker; PNG: its signature).
const MAGIC: [(&str, &[u8]); 2] = [
    ("image/jpeg", &[0xFF, 0xD8, 0xFF]),
    (
        "image/png",
        &[0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A],
    ),
];

fn new_id() -> String {
    use rand::RngCore;
    let mut bytes = [0u8; 8];
    rand::rng().fill_bytes(&mut bytes);
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Whether `id` is one [`new_id`] could have made: 16 lowercase hex digits.
fn is_id(id: &str) -> bool {
    id.len() == 16 && id.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

impl Pictures {
    /// Checks and keeps a picture; its id, or why it was refused.
    pub fn add(&self, mime_type: &str, data_base64: &str) -> Result<String, String> {
        validate_picture(mime_type, data_base64).map_err(|e| e.to_string())?;
        let file = base64::engine::general_purpose::STANDARD
            .decode(data_base64)
            .map_err(|e| format!("data_base64: not base64 ({e})"))?;
        let (mime_type, magic) = MAGIC
            .iter()
            .find(|(t, _)| *t == mime_type)
            .ok_or_else(|| format!("mime_type: {mime_type:?} is not a picture type"))?;
        if !file.starts_with(magic) {
            return Err(format!("data_base64: not a {mime_type} file"));
        }
        if file.len() > MAX_PICTURE_BYTES {
            return Err(format!(
                "data_base64: {} bytes, more than {MAX_PICTURE_BYTES}",
                file.len()
            ));
        }
        let id = new_id();
        let mut kept = self.kept.lock().unwrap_or_else(|e| e.into_inner());
        if kept.len() == KEPT {
            kept.pop_front();
        }
        kept.push_back((
            id.clone(),
            Picture {
                mime_type,
                file: Bytes::from(file),
            },
        ));
        Ok(id)
    }

    /// Picture `id`, if it is still kept.
    pub fn get(&self, id: &str) -> Option<Picture> {
        let kept = self.kept.lock().unwrap_or_else(|e| e.into_inner());
        kept.iter().find(|(k, _)| k == id).map(|(_, p)| p.clone())
    }

    /// How many pictures are kept.
    pub fn len(&self) -> usize {
        self.kept.lock().unwrap_or_else(|e| e.into_inner()).len()
    }

    /// Whether none is kept.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The page's form of an agent event from the bus: a picture is kept and becomes a
    /// [`PictureEvent`] with its URL; other events pass as they are. `None` (with a warning
    /// logged) for an event that fails its checks.
    pub fn to_live(&self, event: AgentEvent) -> Option<LiveEvent> {
        use robotd_protocol::validate::Validate;
        if let Err(error) = event.validate() {
            tracing::warn!(%error, request_id = %event.request_id, "dashboard: an invalid agent event dropped");
            return None;
        }
        let AgentEventKind::Picture {
            call_id,
            name,
            mime_type,
            data_base64,
            shown_to_model,
        } = event.event
        else {
            return Some(LiveEvent::Agent(event));
        };
        match self.add(&mime_type, &data_base64) {
            Ok(id) => {
                let picture = self.get(&id)?;
                Some(LiveEvent::Picture(PictureEvent {
                    request_id: event.request_id,
                    seq: event.seq,
                    event: PictureShown {
                        kind: "picture",
                        call_id,
                        name,
                        mime_type: picture.mime_type,
                        url: url_of(&id),
                        bytes: picture.file.len(),
                        shown_to_model,
                    },
                }))
            }
            Err(error) => {
                tracing::warn!(%error, tool = %name, "dashboard: a picture of the agent refused");
                None
            }
        }
    }
}

/// The answer of `GET /api/chat/pictures/{id}`: the kept picture, byte for byte, or 404.
pub fn response(pictures: &Pictures, id: &str) -> Response {
    let not_found =
        |message: String| (StatusCode::NOT_FOUND, Json(json!({"error": message}))).into_response();
    if !is_id(id) {
        return not_found("a picture id is 16 hex digits".to_owned());
    }
    match pictures.get(id) {
        None => not_found(format!(
            "no picture {id}: the dashboard keeps the newest {KEPT} pictures of the agent"
        )),
        Some(picture) => (
            [
                (header::CONTENT_TYPE, picture.mime_type),
                // An id is never reused: the file under it never changes.
                (header::CACHE_CONTROL, "private, max-age=86400, immutable"),
            ],
            picture.file,
        )
            .into_response(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const JPEG_B64: &str = "/9j/4AAQSkZJRgABAQ==";

    fn picture_event(mime_type: &str, data_base64: &str) -> AgentEvent {
        AgentEvent {
            request_id: "web-1".into(),
            seq: 3,
            event: AgentEventKind::Picture {
                call_id: "call_7".into(),
                name: "get_camera_image".into(),
                mime_type: mime_type.into(),
                data_base64: data_base64.into(),
                shown_to_model: true,
            },
        }
    }

    #[test]
    fn a_picture_becomes_a_url_that_serves_the_exact_file() {
        let pictures = Pictures::default();
        let Some(LiveEvent::Picture(shown)) =
            pictures.to_live(picture_event("image/jpeg", JPEG_B64))
        else {
            panic!("not a picture event");
        };
        let id = shown.event.url.rsplit('/').next().unwrap().to_owned();
        assert!(is_id(&id), "{id}");
        assert_eq!(shown.event.url, url_of(&id));
        let file = pictures.get(&id).unwrap().file;
        let expected = base64::engine::general_purpose::STANDARD
            .decode(JPEG_B64)
            .unwrap();
        assert_eq!(file.as_ref(), expected.as_slice());
        assert_eq!(shown.event.bytes, expected.len());
        let json = serde_json::to_value(LiveEvent::Picture(shown)).unwrap();
        assert_eq!(json["type"], "agent");
        assert_eq!(json["request_id"], "web-1");
        assert_eq!(json["event"]["kind"], "picture");
        assert_eq!(json["event"]["call_id"], "call_7");
        assert!(json["event"].get("data_base64").is_none(), "{json}");
    }

    #[test]
    fn only_checked_pictures_are_kept_and_only_the_newest() {
        let pictures = Pictures::default();
        // PNG bytes called a JPEG, a JPEG called a PNG, an SVG, padding inside the text.
        for (mime, data) in [
            ("image/jpeg", "iVBORw0KGgo="),
            ("image/png", JPEG_B64),
            ("image/svg+xml", "PHN2Zz4="),
            ("image/jpeg", "/9j/4A=A"),
        ] {
            assert!(
                pictures.to_live(picture_event(mime, data)).is_none(),
                "{mime} {data}"
            );
        }
        // "/9j/" is FF D8 FF: the smallest file that starts like a JPEG.
        assert!(pictures.add("image/jpeg", "/9j/").is_ok());
        let first = pictures.add("image/jpeg", JPEG_B64).unwrap();
        for _ in 0..KEPT {
            pictures.add("image/jpeg", JPEG_B64).unwrap();
        }
        assert_eq!(pictures.len(), KEPT);
        assert!(pictures.get(&first).is_none(), "the oldest is dropped");
        assert!(!is_id("../../etc/passwd") && !is_id("ABCDEF0123456789"));
    }
}
