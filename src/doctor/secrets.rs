//! `secrets.env`: keys kept out of the config file, in the config file's directory.
//!
//! The file is dotenv text (`KEY=VALUE` lines) and is read by the same function the LLM agent
//! uses, [`robotd_agent::providers::load_secrets`], so the doctor and `robotd serve` /
//! `robotd chat` can never read different values from it. Besides the values, the doctor
//! remembers two things a user should hear about: the file exists but cannot be read, or other
//! users can read it.
//!
//! Which variables robotd takes from this file: the agent's (`OPENAI_API_KEY`, `GROQ_API_KEY`,
//! `GEMINI_API_KEY`, `API_KEY`, `LLM_*`, `OLLAMA_HOST`, base URLs). Not the `REDIS_*` variables:
//! those are shared with the lab's Python tools, which read only the environment, and
//! `robotd serve` reads them from the environment too (see [`super::redis`]).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Name of the secrets file in the config directory.
pub(super) const SECRETS_FILE: &str = "secrets.env";

/// Variables read from `secrets.env` in the config directory. Holds secrets: its `Debug`
/// shows the names of the variables, never their values.
#[derive(Default)]
pub(super) struct Secrets {
    /// Where the file is (or would be).
    pub(super) path: PathBuf,
    /// Its variables (empty when there is no file).
    pub(super) vars: HashMap<String, String>,
    /// The file exists but could not be read.
    pub(super) error: Option<String>,
    /// The line (from 1) that is not a `KEY=VALUE` assignment; nothing of the file is used.
    pub(super) bad_line: Option<usize>,
    /// The file can be read by other users.
    pub(super) world_readable: bool,
}

impl std::fmt::Debug for Secrets {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut names: Vec<&str> = self.vars.keys().map(String::as_str).collect();
        names.sort_unstable();
        f.debug_struct("Secrets")
            .field("path", &self.path)
            .field("names", &names)
            .field("error", &self.error)
            .field("bad_line", &self.bad_line)
            .field("world_readable", &self.world_readable)
            .finish()
    }
}

impl Secrets {
    /// Reads `config_dir/secrets.env`; a missing file is an empty one.
    pub(super) fn load(config_dir: &Path) -> Self {
        let path = config_dir.join(SECRETS_FILE);
        let mut secrets = Secrets {
            path: path.clone(),
            ..Default::default()
        };
        match robotd_agent::providers::load_secrets(&path) {
            Ok(vars) => {
                secrets.vars = vars;
                if let Ok(meta) = std::fs::metadata(&path) {
                    use std::os::unix::fs::PermissionsExt;
                    secrets.world_readable = meta.permissions().mode() & 0o004 != 0;
                }
            }
            Err(robotd_agent::providers::ProviderError::Secrets { reason, .. }) => {
                secrets.error = Some(reason)
            }
            Err(robotd_agent::providers::ProviderError::SecretsLine { line, .. }) => {
                secrets.bad_line = Some(line)
            }
            Err(other) => secrets.error = Some(other.to_string()),
        }
        secrets
    }

    /// The value of `key`, when set and not blank.
    pub(super) fn get(&self, key: &str) -> Option<&str> {
        self.vars
            .get(key)
            .map(String::as_str)
            .filter(|v| !v.trim().is_empty())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::doctor::test_support::temp_dir;

    #[test]
    fn load_reads_dotenv_text_and_names_a_bad_line() {
        let dir = temp_dir("secrets-text");
        let path = dir.join(SECRETS_FILE);
        let text = "\
# a comment
OPENAI_API_KEY=sk-abc
  GROQ_API_KEY = gsk_def   # trailing comment
export GEMINI_API_KEY=\"AIza quoted # not a comment\"
SINGLE='p$ss'
ESCAPED=\"a\\\"b\\nc\"
EMPTY=
URL=http://host:1/x#frag
";
        std::fs::write(&path, text).expect("write");
        let loaded = Secrets::load(&dir);
        assert!(loaded.error.is_none(), "{loaded:?}");
        assert_eq!(loaded.get("OPENAI_API_KEY"), Some("sk-abc"));
        assert_eq!(loaded.get("GROQ_API_KEY"), Some("gsk_def"));
        assert_eq!(
            loaded.get("GEMINI_API_KEY"),
            Some("AIza quoted # not a comment")
        );
        assert_eq!(loaded.get("SINGLE"), Some("p$ss"));
        assert_eq!(loaded.get("ESCAPED"), Some("a\"b\nc"));
        assert_eq!(loaded.get("EMPTY"), None);
        assert_eq!(loaded.get("URL"), Some("http://host:1/x#frag"));
        assert_eq!(loaded.vars.len(), 7);

        // A line that is not an assignment: the doctor hears the line, not the text.
        std::fs::write(&path, format!("{text}BAD-KEY=sk-hidden\n")).expect("write");
        let broken = Secrets::load(&dir);
        assert_eq!(broken.bad_line, Some(9), "{broken:?}");
        assert!(broken.vars.is_empty() && broken.error.is_none());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn load_reads_the_file_and_its_permissions() {
        use std::os::unix::fs::PermissionsExt;
        let dir = temp_dir("secrets");
        let missing = Secrets::load(&dir);
        assert!(missing.vars.is_empty() && missing.error.is_none());

        let path = dir.join(SECRETS_FILE);
        std::fs::write(&path, "REDIS_PASSWORD='p$ss # not a comment'\nBLANK=  \n").expect("write");
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).expect("chmod");
        let loaded = Secrets::load(&dir);
        assert_eq!(loaded.get("REDIS_PASSWORD"), Some("p$ss # not a comment"));
        assert_eq!(loaded.get("BLANK"), None);
        assert!(loaded.world_readable);

        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).expect("chmod");
        assert!(!Secrets::load(&dir).world_readable);

        // A directory where the file should be: it exists but cannot be read as text.
        let unreadable = temp_dir("secrets-dir");
        std::fs::create_dir(unreadable.join(SECRETS_FILE)).expect("mkdir");
        let broken = Secrets::load(&unreadable);
        assert!(broken.error.is_some(), "{broken:?}");
        let _ = std::fs::remove_dir_all(&dir);
        let _ = std::fs::remove_dir_all(&unreadable);
    }
}
