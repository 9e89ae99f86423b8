//! Which LLM to talk to: the five providers, their keys, base URLs and default models, and
//! how `auto` picks one.
//!
//! A provider is chosen by name (`openai`, `groq`, `gemini`, `ollama`, `openai-compatible`) or
//! by `auto`, which takes the first provider of this table whose key is present:
//!
//! | provider | key variable | base URL (override) | default model |
//! |---|---|---|---|
//! | openai | `OPENAI_API_KEY` | `https://api.openai.com/v1` (`OPENAI_BASE_URL`) | `gpt-4o-mini` |
//! | groq | `GROQ_API_KEY` | `https://api.groq.com/openai/v1` (`GROQ_BASE_URL`) | `qwen/qwen3-32b` |
//! | gemini | `GEMINI_API_KEY` | `https://generativelanguage.googleapis.com/v1beta/openai/` (`GEMINI_BASE_URL`) | `gemini-2.5-flash` |
//! | ollama | none | `http://localhost:11434` (`OLLAMA_HOST`) | `llama3.2:1b` |
//! | openai-compatible | `LLM_API_KEY` (optional) | `LLM_BASE_URL` (required) | `LLM_MODEL` |
//!
//! A generic `API_KEY` counts for the provider its prefix names (`sk-` openai, `gsk_` groq,
//! `AIza` gemini). Values come from the environment or, when a variable is not set there, from
//! a `secrets.env` file (dotenv format) next to the configuration file. All lookups go through
//! an [`Env`], so tests pass a map instead of touching the process environment:
//!
//! ```
//! use robotd_agent::providers::{resolve, Env, Provider};
//!
//! let env = Env::from_pairs([("API_KEY", "gsk_abc"), ("GEMINI_API_KEY", "AIza-x")]);
//! let chosen = resolve("auto", None, &env).unwrap();
//! assert_eq!(chosen.provider, Provider::Groq); // groq comes before gemini in the table
//! assert_eq!(chosen.model, "qwen/qwen3-32b");
//!
//! let err = resolve("openai", None, &Env::default()).unwrap_err();
//! assert!(err.to_string().contains("OPENAI_API_KEY"));
//! ```

use std::collections::HashMap;
use std::path::Path;

/// An LLM provider robotd can talk to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Provider {
    /// OpenAI chat completions.
    OpenAi,
    /// Groq (OpenAI-compatible).
    Groq,
    /// Google Gemini through its OpenAI-compatible endpoint.
    Gemini,
    /// A local Ollama server (`/api/chat`).
    Ollama,
    /// Any other OpenAI-compatible server (`LLM_BASE_URL`).
    OpenAiCompatible,
}

/// Which wire format a provider speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wire {
    /// `POST {base}/chat/completions` with `tools` / `tool_calls`.
    OpenAi,
    /// `POST {host}/api/chat` with `tools`, not streamed.
    Ollama,
}

impl Provider {
    /// Every provider, in `auto`'s order.
    pub const ALL: [Provider; 5] = [
        Provider::OpenAi,
        Provider::Groq,
        Provider::Gemini,
        Provider::Ollama,
        Provider::OpenAiCompatible,
    ];

    /// The provider's name, as `--api` and `switch` take it.
    pub const fn name(self) -> &'static str {
        match self {
            Provider::OpenAi => "openai",
            Provider::Groq => "groq",
            Provider::Gemini => "gemini",
            Provider::Ollama => "ollama",
            Provider::OpenAiCompatible => "openai-compatible",
        }
    }

    /// Reads a provider name (case-insensitive; `compatible` and `llm` mean
    /// `openai-compatible`).
    pub fn parse(name: &str) -> Result<Provider, ProviderError> {
        let lower = name.trim().to_ascii_lowercase();
        Ok(match lower.as_str() {
            "openai" => Provider::OpenAi,
            "groq" => Provider::Groq,
            "gemini" | "google" => Provider::Gemini,
            "ollama" => Provider::Ollama,
            "openai-compatible" | "compatible" | "llm" => Provider::OpenAiCompatible,
            _ => {
                return Err(ProviderError::UnknownProvider {
                    name: name.to_owned(),
                })
            }
        })
    }

    /// The variable holding the provider's API key (`None` for Ollama).
    pub const fn key_variable(self) -> Option<&'static str> {
        match self {
            Provider::OpenAi => Some("OPENAI_API_KEY"),
            Provider::Groq => Some("GROQ_API_KEY"),
            Provider::Gemini => Some("GEMINI_API_KEY"),
            Provider::Ollama => None,
            Provider::OpenAiCompatible => Some("LLM_API_KEY"),
        }
    }

    /// The prefix of a generic `API_KEY` that belongs to this provider.
    pub const fn key_prefix(self) -> Option<&'static str> {
        match self {
            Provider::OpenAi => Some("sk-"),
            Provider::Groq => Some("gsk_"),
            Provider::Gemini => Some("AIza"),
            Provider::Ollama | Provider::OpenAiCompatible => None,
        }
    }

    /// The variable that overrides the base URL.
    pub const fn base_url_variable(self) -> &'static str {
        match self {
            Provider::OpenAi => "OPENAI_BASE_URL",
            Provider::Groq => "GROQ_BASE_URL",
            Provider::Gemini => "GEMINI_BASE_URL",
            Provider::Ollama => "OLLAMA_HOST",
            Provider::OpenAiCompatible => "LLM_BASE_URL",
        }
    }

    /// The base URL when none is configured (`None`: one must be configured).
    pub const fn default_base_url(self) -> Option<&'static str> {
        match self {
            Provider::OpenAi => Some("https://api.openai.com/v1"),
            Provider::Groq => Some("https://api.groq.com/openai/v1"),
            Provider::Gemini => Some("https://generativelanguage.googleapis.com/v1beta/openai/"),
            Provider::Ollama => Some("http://localhost:11434"),
            Provider::OpenAiCompatible => None,
        }
    }

    /// The model used when none is given.
    pub const fn default_model(self) -> &'static str {
        match self {
            Provider::OpenAi => "gpt-4o-mini",
            Provider::Groq => "qwen/qwen3-32b",
            Provider::Gemini => "gemini-2.5-flash",
            Provider::Ollama => "llama3.2:1b",
            // `LLM_MODEL` normally names it; this is only a placeholder the server may accept.
            Provider::OpenAiCompatible => "default",
        }
    }

    /// The wire format the provider speaks.
    pub const fn wire(self) -> Wire {
        match self {
            Provider::Ollama => Wire::Ollama,
            _ => Wire::OpenAi,
        }
    }
}

impl std::fmt::Display for Provider {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Why no provider could be chosen.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ProviderError {
    /// The name is not a provider.
    #[error("unknown LLM provider '{name}'; use one of openai, groq, gemini, ollama, openai-compatible or auto")]
    UnknownProvider {
        /// The name given.
        name: String,
    },
    /// The chosen provider's key is missing.
    #[error("no API key for {provider}: set {variable} (in the environment or in secrets.env next to the config file){hint}")]
    MissingKey {
        /// The provider.
        provider: Provider,
        /// The variable to set.
        variable: &'static str,
        /// Extra advice (may be empty).
        hint: String,
    },
    /// `openai-compatible` needs a base URL.
    #[error("the openai-compatible provider needs a server: set LLM_BASE_URL (e.g. http://localhost:8080/v1), and LLM_API_KEY if it wants a key")]
    MissingBaseUrl,
    /// `auto` found no key at all.
    #[error("no LLM API key found: set OPENAI_API_KEY, GROQ_API_KEY or GEMINI_API_KEY (or API_KEY, or LLM_API_KEY with LLM_BASE_URL) in the environment or in secrets.env next to the config file; or use --api ollama for a local Ollama server")]
    NoKeyFound,
    /// `secrets.env` exists but cannot be read.
    #[error("cannot read {path}: {reason}")]
    Secrets {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// A line of `secrets.env` is not an assignment (its text is not repeated: it may hold a
    /// key).
    #[error("{path}:{line}: not a KEY=VALUE line (or a quote opened and never closed); fix or remove it")]
    SecretsLine {
        /// The file.
        path: String,
        /// The line, counted from 1.
        line: usize,
    },
}

/// Where variables come from: the environment first, then `secrets.env`.
#[derive(Debug, Clone, Default)]
pub struct Env {
    vars: HashMap<String, String>,
    secrets: HashMap<String, String>,
}

impl Env {
    /// The process environment, with `secrets_file` (when it exists) as fallback.
    pub fn from_process(secrets_file: Option<&Path>) -> Result<Env, ProviderError> {
        let vars = std::env::vars().collect();
        let mut env = Env {
            vars,
            secrets: HashMap::new(),
        };
        if let Some(path) = secrets_file {
            env.secrets = load_secrets(path)?;
        }
        Ok(env)
    }

    /// An environment made of these pairs only (for tests and embedding).
    pub fn from_pairs<K: Into<String>, V: Into<String>>(
        pairs: impl IntoIterator<Item = (K, V)>,
    ) -> Env {
        Env {
            vars: pairs
                .into_iter()
                .map(|(k, v)| (k.into(), v.into()))
                .collect(),
            secrets: HashMap::new(),
        }
    }

    /// Adds `secrets.env` content (used only for variables the environment does not set).
    pub fn with_secrets(mut self, secrets: HashMap<String, String>) -> Env {
        self.secrets = secrets;
        self
    }

    /// Adds fallbacks (e.g. base URLs from the config file) for variables that neither the
    /// environment nor `secrets.env` sets.
    pub fn with_defaults<K: Into<String>, V: Into<String>>(
        mut self,
        defaults: impl IntoIterator<Item = (K, V)>,
    ) -> Env {
        for (k, v) in defaults {
            self.secrets.entry(k.into()).or_insert_with(|| v.into());
        }
        self
    }

    /// The value of `name`: the environment's if set and not empty, else the secrets file's.
    pub fn get(&self, name: &str) -> Option<&str> {
        [&self.vars, &self.secrets]
            .into_iter()
            .find_map(|m| m.get(name).map(|v| v.trim()).filter(|v| !v.is_empty()))
    }
}

/// Reads a `secrets.env` file; a missing file is an empty one. A line that is not an
/// assignment is an error naming the file and the line (never the line's text: it may hold a
/// key).
pub fn load_secrets(path: &Path) -> Result<HashMap<String, String>, ProviderError> {
    let secrets_error = |reason: String| ProviderError::Secrets {
        path: path.display().to_string(),
        reason,
    };
    match std::fs::read_to_string(path) {
        Ok(text) => parse_dotenv(&text).map_err(|e| ProviderError::SecretsLine {
            path: path.display().to_string(),
            line: e.line,
        }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(HashMap::new()),
        Err(e) => Err(secrets_error(e.to_string())),
    }
}

/// A line of dotenv text that is not an assignment.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("line {line} is not a KEY=VALUE assignment (or opens a quote it never closes)")]
pub struct DotenvError {
    /// The line, counted from 1.
    pub line: usize,
}

/// Parses dotenv text with the [`dotenvy`] crate — the one parser of `secrets.env` in robotd
/// (the agent's keys and `robotd doctor` read the file through it, so both always see the same
/// values). Nothing is put into the process environment: the caller decides the precedence
/// ([`Env`]: the environment first, then these values).
///
/// The format is dotenvy's: `KEY=VALUE` lines; blank lines and `#` comments; an optional
/// `export ` in front; values in single quotes (taken literally) or double quotes (escapes such
/// as `\n` and `\"`, and may span lines); ` # comment` after an unquoted value. Keys are
/// letters, digits, `_` and `.`, starting with a letter or `_`. `$VAR` and `${VAR}` in an
/// unquoted or double-quoted value are replaced by the variable (from the process environment,
/// else from an earlier line): put a value with a `$` in it in single quotes. A key given twice
/// keeps its last value. Any other line is an error with its line number.
///
/// ```
/// use robotd_agent::providers::parse_dotenv;
///
/// let vars = parse_dotenv("export GROQ_API_KEY=gsk_1 # lab key\nPW='p$ss'\n").unwrap();
/// assert_eq!(vars["GROQ_API_KEY"], "gsk_1");
/// assert_eq!(vars["PW"], "p$ss");
/// assert_eq!(parse_dotenv("A=1\n\nnot a line\n").unwrap_err().line, 3);
/// ```
pub fn parse_dotenv(text: &str) -> Result<HashMap<String, String>, DotenvError> {
    let mut out = HashMap::new();
    let body = text.strip_prefix('\u{feff}').unwrap_or(text);
    for item in dotenvy::from_read_iter(body.as_bytes()) {
        match item {
            Ok((key, value)) => {
                out.insert(key, value);
            }
            // dotenvy gives the failing text (the whole line, or its value when the value is
            // at fault), not its number: the number is that of the first assignment line that
            // ends with that text's first line (an earlier line that also ended so would have
            // failed first, unless it sat inside a multi-line quoted value).
            Err(dotenvy::Error::LineParse(bad, _)) => {
                let first = bad.lines().next().unwrap_or("").trim_end();
                let line = body
                    .lines()
                    .enumerate()
                    .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
                    .find(|(_, l)| l.trim_end().ends_with(first))
                    .map_or_else(|| body.lines().count(), |(i, _)| i + 1);
                return Err(DotenvError { line });
            }
            // Reading from a byte slice cannot fail; anything else is reported on the last line.
            Err(_) => {
                return Err(DotenvError {
                    line: body.lines().count(),
                })
            }
        }
    }
    Ok(out)
}

/// A chosen provider with everything needed to call it.
#[derive(Clone, PartialEq, Eq)]
pub struct ProviderSettings {
    /// The provider.
    pub provider: Provider,
    /// The model name.
    pub model: String,
    /// Base URL (OpenAI wire: up to `/v1`; Ollama: the host).
    pub base_url: String,
    /// The API key, if any.
    pub api_key: Option<String>,
    /// The variable the key came from (named in "rejected key" errors).
    pub key_variable: Option<&'static str>,
}

impl std::fmt::Debug for ProviderSettings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProviderSettings")
            .field("provider", &self.provider)
            .field("model", &self.model)
            .field("base_url", &self.base_url)
            .field("api_key", &self.api_key.as_ref().map(|_| "<set>"))
            .field("key_variable", &self.key_variable)
            .finish()
    }
}

/// The key of `provider` and where it came from, if present.
fn find_key(provider: Provider, env: &Env) -> Option<(String, &'static str)> {
    let variable = provider.key_variable()?;
    if let Some(v) = env.get(variable) {
        return Some((v.to_owned(), variable));
    }
    let prefix = provider.key_prefix()?;
    env.get("API_KEY")
        .filter(|v| v.starts_with(prefix))
        .map(|v| (v.to_owned(), "API_KEY"))
}

/// Whether `auto` would take `provider`.
fn is_present(provider: Provider, env: &Env) -> bool {
    match provider {
        Provider::Ollama => env.get("OLLAMA_HOST").is_some(),
        Provider::OpenAiCompatible => {
            env.get("LLM_BASE_URL").is_some() && env.get("LLM_API_KEY").is_some()
        }
        other => find_key(other, env).is_some(),
    }
}

/// Resolves `api` (`auto` or a provider name) and an optional model into settings.
pub fn resolve(
    api: &str,
    model: Option<&str>,
    env: &Env,
) -> Result<ProviderSettings, ProviderError> {
    let provider = if api.trim().eq_ignore_ascii_case("auto") || api.trim().is_empty() {
        Provider::ALL
            .into_iter()
            .find(|p| is_present(*p, env))
            .ok_or(ProviderError::NoKeyFound)?
    } else {
        Provider::parse(api)?
    };
    settings_for(provider, model, env)
}

/// Settings for `provider` (explicitly chosen), with `model` or its default.
pub fn settings_for(
    provider: Provider,
    model: Option<&str>,
    env: &Env,
) -> Result<ProviderSettings, ProviderError> {
    let (api_key, key_variable) = match provider {
        Provider::Ollama => (None, None),
        Provider::OpenAiCompatible => match env.get("LLM_API_KEY") {
            Some(k) => (Some(k.to_owned()), Some("LLM_API_KEY")),
            None => (None, Some("LLM_API_KEY")),
        },
        other => match find_key(other, env) {
            Some((key, var)) => (Some(key), Some(var)),
            None => {
                let variable = other.key_variable().unwrap_or("API_KEY");
                let hint = match env.get("API_KEY") {
                    Some(k) => format!(
                        " (API_KEY is set, but its prefix '{}…' is not {}'s '{}')",
                        k.chars().take(4).collect::<String>(),
                        other,
                        other.key_prefix().unwrap_or("")
                    ),
                    None => String::new(),
                };
                return Err(ProviderError::MissingKey {
                    provider: other,
                    variable,
                    hint,
                });
            }
        },
    };
    let base_url = match env.get(provider.base_url_variable()) {
        Some(url) => url.to_owned(),
        None => provider
            .default_base_url()
            .ok_or(ProviderError::MissingBaseUrl)?
            .to_owned(),
    };
    let base_url = if provider == Provider::Ollama && !base_url.contains("://") {
        // OLLAMA_HOST is often host:port.
        format!("http://{base_url}")
    } else {
        base_url
    };
    let model = model
        .map(str::trim)
        .filter(|m| !m.is_empty())
        .map(str::to_owned)
        .or_else(|| {
            (provider == Provider::OpenAiCompatible)
                .then(|| env.get("LLM_MODEL").map(str::to_owned))
                .flatten()
        })
        .unwrap_or_else(|| provider.default_model().to_owned());
    Ok(ProviderSettings {
        provider,
        model,
        base_url,
        api_key,
        key_variable,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(pairs: &[(&str, &str)]) -> Env {
        Env::from_pairs(pairs.iter().copied())
    }

    #[test]
    fn auto_takes_the_first_present_key_in_table_order() {
        let all = env(&[
            ("GEMINI_API_KEY", "g"),
            ("GROQ_API_KEY", "q"),
            ("OPENAI_API_KEY", "o"),
        ]);
        assert_eq!(
            resolve("auto", None, &all).unwrap().provider,
            Provider::OpenAi
        );
        let two = env(&[("GEMINI_API_KEY", "g"), ("GROQ_API_KEY", "q")]);
        let s = resolve("auto", None, &two).unwrap();
        assert_eq!(s.provider, Provider::Groq);
        assert_eq!(s.api_key.as_deref(), Some("q"));
        assert_eq!(s.base_url, "https://api.groq.com/openai/v1");
        let gemini = resolve("auto", None, &env(&[("GEMINI_API_KEY", "g")])).unwrap();
        assert_eq!(gemini.provider, Provider::Gemini);
        assert_eq!(gemini.model, "gemini-2.5-flash");
        assert_eq!(
            gemini.base_url,
            "https://generativelanguage.googleapis.com/v1beta/openai/"
        );
        let ollama = resolve("auto", None, &env(&[("OLLAMA_HOST", "box:11434")])).unwrap();
        assert_eq!(ollama.provider, Provider::Ollama);
        assert_eq!(ollama.base_url, "http://box:11434");
        assert_eq!(ollama.model, "llama3.2:1b");
        let compatible = resolve(
            "auto",
            None,
            &env(&[
                ("LLM_API_KEY", "k"),
                ("LLM_BASE_URL", "http://h/v1"),
                ("LLM_MODEL", "m1"),
            ]),
        )
        .unwrap();
        assert_eq!(compatible.provider, Provider::OpenAiCompatible);
        assert_eq!(compatible.model, "m1");
        assert_eq!(
            resolve("auto", None, &env(&[])).unwrap_err(),
            ProviderError::NoKeyFound
        );
        // An empty variable is not a key.
        assert_eq!(
            resolve("auto", None, &env(&[("OPENAI_API_KEY", " ")])).unwrap_err(),
            ProviderError::NoKeyFound
        );
    }

    #[test]
    fn a_generic_api_key_is_recognised_by_prefix() {
        for (key, provider) in [
            ("sk-proj-1", Provider::OpenAi),
            ("gsk_2", Provider::Groq),
            ("AIzaSy3", Provider::Gemini),
        ] {
            let s = resolve("auto", None, &env(&[("API_KEY", key)])).unwrap();
            assert_eq!(s.provider, provider, "{key}");
            assert_eq!(s.api_key.as_deref(), Some(key));
            assert_eq!(s.key_variable, Some("API_KEY"));
        }
        assert_eq!(
            resolve("auto", None, &env(&[("API_KEY", "xyz")])).unwrap_err(),
            ProviderError::NoKeyFound
        );
        // A specific variable wins over the generic one.
        let s = resolve(
            "openai",
            None,
            &env(&[("API_KEY", "sk-generic"), ("OPENAI_API_KEY", "sk-own")]),
        )
        .unwrap();
        assert_eq!(s.api_key.as_deref(), Some("sk-own"));
    }

    #[test]
    fn a_missing_key_names_the_variable_to_set() {
        let err = resolve("groq", None, &env(&[])).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("set GROQ_API_KEY"), "{text}");
        assert!(text.contains("secrets.env"), "{text}");
        let err = resolve("gemini", None, &env(&[("API_KEY", "sk-1")])).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("GEMINI_API_KEY"), "{text}");
        assert!(text.contains("'AIza'"), "{text}");
        assert_eq!(
            resolve("openai-compatible", None, &env(&[])).unwrap_err(),
            ProviderError::MissingBaseUrl
        );
        assert!(matches!(
            resolve("claude", None, &env(&[])),
            Err(ProviderError::UnknownProvider { .. })
        ));
    }

    #[test]
    fn base_urls_and_models_can_be_overridden() {
        let s = resolve(
            "openai",
            Some("gpt-4.1"),
            &env(&[
                ("OPENAI_API_KEY", "sk-1"),
                ("OPENAI_BASE_URL", "http://127.0.0.1:9/v1"),
            ]),
        )
        .unwrap();
        assert_eq!(s.base_url, "http://127.0.0.1:9/v1");
        assert_eq!(s.model, "gpt-4.1");
        let s = resolve("ollama", None, &env(&[])).unwrap();
        assert_eq!(s.base_url, "http://localhost:11434");
        assert_eq!(s.api_key, None);
        assert!(!format!(
            "{:?}",
            resolve("openai", None, &env(&[("OPENAI_API_KEY", "sk-secret")])).unwrap()
        )
        .contains("secret"));
    }

    #[test]
    fn dotenv_errors_name_the_line_of_the_fault() {
        let line = |text: &str| parse_dotenv(text).unwrap_err().line;
        // A key that is not one, no `=`, a value with a space, an unclosed quote.
        assert_eq!(line("A=1\n1BAD=x\n"), 2);
        assert_eq!(line("# A=1 2\nA=1\n\nnot an assignment\n"), 4);
        assert_eq!(line("A=1\nB=two words\nC=3\n"), 2);
        assert_eq!(line("A=\"one\ntwo\"\nB='open\n"), 3);
        // A quoted value may span lines; a UTF-8 byte order mark is not part of the first key.
        let vars = parse_dotenv("\u{feff}A=\"one\ntwo\"\nB=${A}!\nC='$A'\n").unwrap();
        assert_eq!(vars["A"], "one\ntwo");
        assert_eq!(vars["B"], "one\ntwo!");
        assert_eq!(vars["C"], "$A");
    }

    #[test]
    fn secrets_env_fills_in_what_the_environment_lacks() {
        let secrets = parse_dotenv(
            "# keys\nexport GROQ_API_KEY=\"gsk_from_file\"\nOPENAI_API_KEY='sk-file' \n\
             GEMINI_API_KEY=AIza123 # trailing comment\n\nMULTI=\"a\\nb\"\n",
        )
        .unwrap();
        assert_eq!(secrets["GROQ_API_KEY"], "gsk_from_file");
        assert_eq!(secrets["OPENAI_API_KEY"], "sk-file");
        assert_eq!(secrets["GEMINI_API_KEY"], "AIza123");
        assert_eq!(secrets["MULTI"], "a\nb");
        assert_eq!(secrets.len(), 4);
        let e = env(&[("OPENAI_API_KEY", "sk-env")]).with_secrets(secrets.clone());
        assert_eq!(e.get("OPENAI_API_KEY"), Some("sk-env"));
        assert_eq!(e.get("GROQ_API_KEY"), Some("gsk_from_file"));
        let only_file = Env::default().with_secrets(secrets);
        assert_eq!(
            resolve("auto", None, &only_file)
                .unwrap()
                .api_key
                .as_deref(),
            Some("sk-file")
        );
        // Files on disk: missing = empty; present = parsed.
        let dir = std::env::temp_dir().join(format!("robotd-agent-secrets-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("secrets.env");
        assert!(load_secrets(&path).unwrap().is_empty());
        std::fs::write(&path, "LLM_API_KEY=k1\n").unwrap();
        assert_eq!(load_secrets(&path).unwrap()["LLM_API_KEY"], "k1");
        // A bad line: the error names the file and the line, never the line's text.
        std::fs::write(&path, "# keys\nLLM_API_KEY=k1\nGROQ_API_KEY gsk_secret\n").unwrap();
        let err = load_secrets(&path).unwrap_err().to_string();
        assert!(err.contains("secrets.env:3:"), "{err}");
        assert!(!err.contains("gsk_secret"), "{err}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
