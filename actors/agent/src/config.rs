//! `[agent]`: which LLM provider and model the agent uses (`robotd chat`, and the agent actor
//! of `robotd serve`), and the providers' base URLs.

use robotd_runtime::config::{check_url, lenient, Checks, Section};
use serde::{Deserialize, Serialize};

/// `[agent]`. Keys and base URLs set in the environment (or `secrets.env`) win over the base
/// URLs here.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AgentSection {
    /// The provider: `auto` (the first whose key is set: openai, groq, gemini, ollama,
    /// openai-compatible), or one of those names.
    #[serde(default = "defaults::agent_api", deserialize_with = "lenient::string")]
    pub api: String,
    /// The model; `None` = the provider's default.
    #[serde(
        default,
        deserialize_with = "lenient::opt_string",
        skip_serializing_if = "Option::is_none"
    )]
    pub model: Option<String>,
    /// Run the agent actor on the bus in `robotd serve` when a provider is usable.
    #[serde(default = "defaults::yes")]
    pub serve: bool,
    /// Base URL of OpenAI (as `OPENAI_BASE_URL`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub openai_base_url: Option<String>,
    /// Base URL of Groq (as `GROQ_BASE_URL`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub groq_base_url: Option<String>,
    /// Base URL of Gemini's OpenAI-compatible API (as `GEMINI_BASE_URL`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gemini_base_url: Option<String>,
    /// The Ollama server (as `OLLAMA_HOST`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ollama_host: Option<String>,
    /// Any OpenAI-compatible server (as `LLM_BASE_URL`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub llm_base_url: Option<String>,
    /// Largest LLM reply read, bytes (64 KiB … 256 MiB); a larger one is an error.
    #[serde(default = "defaults::max_reply_bytes")]
    pub max_reply_bytes: usize,
    /// Whether the model is sent the pictures tools return: `auto` (by the model's name, see
    /// [`crate::vision`]), `on` or `off`.
    #[serde(default = "defaults::agent_api", deserialize_with = "lenient::string")]
    pub images: String,
}

impl Default for AgentSection {
    fn default() -> Self {
        Self {
            api: defaults::agent_api(),
            model: None,
            serve: true,
            openai_base_url: None,
            groq_base_url: None,
            gemini_base_url: None,
            ollama_host: None,
            llm_base_url: None,
            max_reply_bytes: defaults::max_reply_bytes(),
            images: defaults::agent_api(),
        }
    }
}

impl AgentSection {
    /// The base URLs set here, under the names of their environment variables.
    pub fn base_url_variables(&self) -> Vec<(&'static str, String)> {
        [
            ("OPENAI_BASE_URL", &self.openai_base_url),
            ("GROQ_BASE_URL", &self.groq_base_url),
            ("GEMINI_BASE_URL", &self.gemini_base_url),
            ("OLLAMA_HOST", &self.ollama_host),
            ("LLM_BASE_URL", &self.llm_base_url),
        ]
        .into_iter()
        .filter_map(|(k, v)| v.clone().map(|v| (k, v)))
        .collect()
    }
}

mod defaults {
    pub fn agent_api() -> String {
        "auto".into()
    }
    pub fn yes() -> bool {
        true
    }
    pub fn max_reply_bytes() -> usize {
        crate::llm::DEFAULT_MAX_REPLY_BYTES
    }
}

impl AgentSection {
    /// The agent's settings with this section's limits.
    pub fn agent_config(&self) -> crate::AgentConfig {
        let defaults = crate::AgentConfig::default();
        crate::AgentConfig {
            retry: crate::llm::RetryPolicy {
                max_reply_bytes: self.max_reply_bytes,
                ..defaults.retry
            },
            images: crate::vision::Images::parse(&self.images).unwrap_or_default(),
            ..defaults
        }
    }
}

impl Section for AgentSection {
    fn check(&self, checks: &mut Checks) {
        checks.range_u64(
            "max_reply_bytes",
            self.max_reply_bytes as u64,
            64 * 1024..=256 * 1024 * 1024,
            "",
        );
        if crate::vision::Images::parse(&self.images).is_none() {
            checks.problem(
                "images",
                format!("'{}' is not one of auto, on, off", self.images),
            );
        }
        for (key, url) in [
            ("openai_base_url", &self.openai_base_url),
            ("groq_base_url", &self.groq_base_url),
            ("gemini_base_url", &self.gemini_base_url),
            ("ollama_host", &self.ollama_host),
            ("llm_base_url", &self.llm_base_url),
        ] {
            if let Some(url) = url {
                if let Err(reason) = check_url(url, &["http", "https"]) {
                    checks.problem(key, reason);
                }
            }
        }
        if ![
            "auto",
            "openai",
            "groq",
            "gemini",
            "ollama",
            "openai-compatible",
            "compatible",
            "llm",
        ]
        .contains(&self.api.trim().to_ascii_lowercase().as_str())
        {
            checks.problem(
                "api",
                format!(
                    "'{}' is not a provider; use auto, openai, groq, gemini, ollama or \
                     openai-compatible",
                    self.api
                ),
            );
        }
    }
}
