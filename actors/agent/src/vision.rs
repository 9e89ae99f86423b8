//! Pictures for models that look, and only for them.
//!
//! A tool may return pictures beside its text (`get_camera_image`: the camera's view with the
//! objects' ids drawn on it). The agent passes a picture on to the model only when the model
//! takes images, which [`takes_images`] decides from the `agent.images` setting ([`Images`]):
//! `on` and `off` say it outright; `auto` (the default) goes by the model's name — the vision
//! families of OpenAI (`gpt-4o`, `gpt-4.1`, `gpt-5`, `o3`, `o4`), every Gemini, Groq's and
//! Ollama's vision models (`llama-4-scout`/`maverick`, `llava`, `llama3.2-vision`, `qwen2.5vl`,
//! `gemma3`, `minicpm-v`, `moondream`, and any name with `vision` or `-vl`). A text-only model
//! gets the tool's text item alone, which lists the same ids, labels and positions.
//!
//! Whatever the model is sent, the user is shown every picture: [`picture_event`] makes the
//! [`AgentEventKind::Picture`] that follows the call's result (the dashboard's chat shows it),
//! after checking it is a JPEG or PNG of at most
//! [`MAX_PICTURE_BYTES`](robotd_protocol::agent::MAX_PICTURE_BYTES) — a picture from another
//! MCP server is data from outside.
//!
//! A picture travels as a user message after the tool results of its round
//! ([`crate::llm::Message::Picture`]): OpenAI-style servers get an `image_url` part with a
//! `data:` URL, Ollama an `images` entry. History keeps few of them (see [`crate::memory`]):
//! old pictures are dropped first.
//!
//! ```
//! use robotd_agent::providers::Provider;
//! use robotd_agent::vision::{takes_images, Images};
//! assert!(takes_images(Provider::OpenAi, "gpt-4o-mini", Images::Auto));
//! assert!(!takes_images(Provider::Groq, "llama-3.3-70b-versatile", Images::Auto));
//! assert!(takes_images(Provider::Ollama, "qwen2.5vl:7b", Images::Auto));
//! assert!(!takes_images(Provider::OpenAi, "gpt-4o", Images::Off));
//! assert!(takes_images(Provider::OpenAiCompatible, "my-model", Images::On));
//! ```

use crate::providers::Provider;
use robotd_protocol::agent::{validate_picture, AgentEventKind};
use robotd_protocol::validate::ValidationError;

/// Whether the model is sent pictures (`agent.images`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Images {
    /// By the model's name (see the module docs).
    #[default]
    Auto,
    /// Always: the model takes images.
    On,
    /// Never: the model gets the text only.
    Off,
}

impl Images {
    /// The setting's words: `auto`, `on` (`true`, `yes`), `off` (`false`, `no`).
    pub fn parse(word: &str) -> Option<Images> {
        match word.trim().to_ascii_lowercase().as_str() {
            "auto" => Some(Images::Auto),
            "on" | "true" | "yes" => Some(Images::On),
            "off" | "false" | "no" => Some(Images::Off),
            _ => None,
        }
    }
}

/// Name parts of models that take images, by provider family.
const VISION_NAMES: &[&str] = &[
    "gpt-4o",
    "gpt-4.1",
    "gpt-4-turbo",
    "gpt-5",
    "chatgpt-4o",
    "o3",
    "o4",
    "gemini",
    "llama-4-scout",
    "llama-4-maverick",
    "llava",
    "bakllava",
    "llama3.2-vision",
    "qwen2.5vl",
    "qwen2.5-vl",
    "qwen3-vl",
    "gemma3",
    "minicpm-v",
    "moondream",
    "granite3.2-vision",
    "pixtral",
    "vision",
    "-vl",
];

/// Whether `model` of `provider` is sent pictures under `setting`.
pub fn takes_images(provider: Provider, model: &str, setting: Images) -> bool {
    match setting {
        Images::On => true,
        Images::Off => false,
        Images::Auto => {
            let model = model.to_ascii_lowercase();
            // A model's own name (after a vendor prefix such as `openai/` or `models/`).
            let name = model.rsplit('/').next().unwrap_or(&model);
            if provider == Provider::Gemini {
                return true;
            }
            VISION_NAMES.iter().any(|part| match *part {
                // "o3", "o4": the reasoning families, not any name containing those letters.
                "o3" | "o4" => name == *part || name.starts_with(&format!("{part}-")),
                _ => name.contains(part),
            })
        }
    }
}

/// One picture a tool returned, as the model is sent it (defined with the tool backends in
/// `robotd_tools::backend`).
pub use robotd_tools::backend::ImagePart;

/// The event that shows the user `image`, which call `call_id` of tool `name` returned;
/// `shown_to_model` says whether the model was sent it. Refused unless it is a JPEG or PNG in
/// standard base64 of at most
/// [`MAX_PICTURE_BYTES`](robotd_protocol::agent::MAX_PICTURE_BYTES) (see
/// [`robotd_protocol::agent::validate_picture`]).
pub fn picture_event(
    call_id: &str,
    name: &str,
    image: &ImagePart,
    shown_to_model: bool,
) -> Result<AgentEventKind, ValidationError> {
    validate_picture(&image.mime_type, &image.data_base64)?;
    Ok(AgentEventKind::Picture {
        call_id: call_id.to_owned(),
        name: name.to_owned(),
        mime_type: image.mime_type.clone(),
        data_base64: image.data_base64.clone(),
        shown_to_model,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_picture_event_carries_the_exact_file_and_refuses_others() {
        use robotd_protocol::agent::MAX_PICTURE_BYTES;
        let jpeg = ImagePart {
            mime_type: "image/jpeg".into(),
            data_base64: "/9j/4AAQSkZJ".into(),
        };
        assert_eq!(
            picture_event("c1", "get_camera_image", &jpeg, false),
            Ok(AgentEventKind::Picture {
                call_id: "c1".into(),
                name: "get_camera_image".into(),
                mime_type: "image/jpeg".into(),
                data_base64: "/9j/4AAQSkZJ".into(),
                shown_to_model: false,
            })
        );
        let too_big = ImagePart {
            data_base64: format!("/9j/{}", "A".repeat(MAX_PICTURE_BYTES * 4 / 3 + 4)),
            ..jpeg.clone()
        };
        let svg = ImagePart {
            mime_type: "image/svg+xml".into(),
            data_base64: "PHN2Zz4=".into(),
        };
        let not_base64 = ImagePart {
            data_base64: "/9j/<script>".into(),
            ..jpeg
        };
        for image in [too_big, svg, not_base64] {
            assert!(picture_event("c1", "t", &image, true).is_err(), "{image:?}");
        }
    }

    #[test]
    fn vision_is_decided_by_setting_then_by_name() {
        let yes = [
            (Provider::OpenAi, "gpt-4o-mini"),
            (Provider::OpenAi, "gpt-4.1-nano"),
            (Provider::OpenAi, "o4-mini"),
            (Provider::Gemini, "gemini-2.0-flash"),
            (Provider::Groq, "meta-llama/llama-4-scout-17b-16e-instruct"),
            (Provider::Ollama, "llava:13b"),
            (Provider::Ollama, "llama3.2-vision"),
            (Provider::Ollama, "gemma3:4b"),
            (Provider::OpenAiCompatible, "Qwen/Qwen2.5-VL-7B-Instruct"),
        ];
        for (provider, model) in yes {
            assert!(takes_images(provider, model, Images::Auto), "{model}");
            assert!(!takes_images(provider, model, Images::Off), "{model}");
        }
        let no = [
            (Provider::OpenAi, "gpt-3.5-turbo"),
            (Provider::Groq, "llama-3.3-70b-versatile"),
            (Provider::Ollama, "qwen3:8b"),
            (Provider::Ollama, "llama3.1"),
            (Provider::OpenAiCompatible, "mock-model"),
            (Provider::OpenAiCompatible, "phi-o3x"),
        ];
        for (provider, model) in no {
            assert!(!takes_images(provider, model, Images::Auto), "{model}");
            assert!(takes_images(provider, model, Images::On), "{model}");
        }
        assert_eq!(Images::parse(" ON "), Some(Images::On));
        assert_eq!(Images::parse("no"), Some(Images::Off));
        assert_eq!(Images::parse("maybe"), None);
    }
}
