//! `llm-keys`: can the agent talk to an LLM, and where would its key come from?
//!
//! The agent looks for a provider key in the environment first and in `secrets.env` next to the
//! config file second (the agent crate's [`robotd_agent::providers`]). This row names each
//! provider it would find and where its key came from — never the key itself: a generic
//! `API_KEY` is only inspected for its prefix (`sk-`, `gsk_`, `AIza`). An Ollama server counts
//! when something listens at `OLLAMA_HOST` (default `localhost:11434`); that probe is a bare TCP
//! connect, bounded by a short timeout, because Ollama needs no key.
//!
//! No provider at all only warns: robotd runs without its agent, and `robotd chat --mcp` or an
//! MCP client can still drive it. A `secrets.env` other users can read also warns.

use super::secrets::Secrets;
use super::{first_chars, Check, EnvFn, Status};
use std::io::ErrorKind;
use std::net::{IpAddr, SocketAddr, TcpStream, ToSocketAddrs};
use std::sync::mpsc;
use std::time::Duration;

/// How long the Ollama probe may spend on each of name resolution and connecting.
const PROBE_TIMEOUT: Duration = Duration::from_millis(300);

/// Is an Ollama server listening at `host` (an `OLLAMA_HOST` value)? Bounded by a short
/// connect timeout.
pub(super) fn ollama_reachable(host: &str) -> bool {
    let rest = host
        .trim()
        .trim_start_matches("http://")
        .trim_start_matches("https://");
    let authority = rest.split('/').next().unwrap_or("");
    let (h, port) = match authority.rsplit_once(':') {
        Some((h, p)) if !h.ends_with(':') => (h, p.parse::<u16>().unwrap_or(11434)),
        _ => (authority, 11434),
    };
    let h = h.trim_start_matches('[').trim_end_matches(']');
    let h = if h.is_empty() || h == "0.0.0.0" {
        "127.0.0.1"
    } else {
        h
    };
    match resolve(h, port, PROBE_TIMEOUT) {
        Ok(addrs) => connect(&addrs, PROBE_TIMEOUT).is_ok(),
        Err(_) => false,
    }
}

/// timeout, so it runs on a helper thread that is abandoned if it takes too long).
fn resolve(host: &str, port: u16, timeout: Duration) -> std::io::Result<Vec<SocketAddr>> {
    if let Ok(ip) = host.parse::<IpAddr>() {
        return Ok(vec![SocketAddr::new(ip, port)]);
    }
    let (tx, rx) = mpsc::channel();
    let owned = host.to_owned();
    std::thread::Builder::new()
        .name("doctor-resolve".into())
        .spawn(move || {
            let _ = tx.send((owned.as_str(), port).to_socket_addrs().map(Vec::from_iter));
        })?;
    match rx.recv_timeout(timeout) {
        Ok(result) => result,
        Err(_) => Err(std::io::Error::new(
            ErrorKind::TimedOut,
            format!(
                "name resolution took longer than {} ms",
                timeout.as_millis()
            ),
        )),
    }
}

fn connect(addrs: &[SocketAddr], timeout: Duration) -> std::io::Result<TcpStream> {
    let mut last = std::io::Error::new(ErrorKind::NotFound, "the name has no address");
    for addr in addrs.iter().take(3) {
        match TcpStream::connect_timeout(addr, timeout) {
            Ok(stream) => return Ok(stream),
            Err(e) => last = e,
        }
    }
    Err(last)
}

pub(super) fn check_llm_keys(
    env: EnvFn,
    secrets: &Secrets,
    ollama_probe: &dyn Fn(&str) -> bool,
) -> Check {
    const NAME: &str = "llm-keys";
    let secrets_name = secrets.path.display().to_string();
    // (value, "set (from ...)") — the value is only inspected for its prefix, never printed.
    let lookup = |key: &str| -> Option<(String, &'static str)> {
        if let Some(v) = env(key) {
            Some((v, "set (from env)"))
        } else {
            secrets
                .get(key)
                .map(|v| (v.to_owned(), "set (from secrets.env)"))
        }
    };

    let mut providers = Vec::new();
    let mut notes = Vec::new();
    let mut status = Status::Ok;
    let mut fixes = Vec::new();

    for (key, provider) in [
        ("OPENAI_API_KEY", "openai"),
        ("GROQ_API_KEY", "groq"),
        ("GEMINI_API_KEY", "gemini"),
    ] {
        if let Some((_, source)) = lookup(key) {
            providers.push(format!("{provider}: {key} {source}"));
        }
    }
    if let Some((value, source)) = lookup("API_KEY") {
        let provider = if value.starts_with("gsk_") {
            Some("groq")
        } else if value.starts_with("sk-") {
            Some("openai")
        } else if value.starts_with("AIza") {
            Some("gemini")
        } else {
            None
        };
        match provider {
            Some(p) => providers.push(format!("{p}: API_KEY {source}")),
            None => {
                status = Status::Warn;
                notes.push(format!(
                    "API_KEY {source} but not recognised (expected a key starting with sk-, gsk_ or AIza)"
                ));
                fixes.push(
                    "use the provider's own variable (OPENAI_API_KEY, GROQ_API_KEY, GEMINI_API_KEY) \
                     or LLM_API_KEY with LLM_BASE_URL"
                        .to_owned(),
                );
            }
        }
    }
    if let Some((_, source)) = lookup("LLM_API_KEY") {
        match lookup("LLM_BASE_URL") {
            Some((url, _)) => providers.push(format!(
                "openai-compatible at {}: LLM_API_KEY {source}",
                first_chars(&url)
            )),
            None => {
                status = Status::Warn;
                notes.push(format!("LLM_API_KEY {source} but LLM_BASE_URL is not set"));
                fixes.push(
                    "set LLM_BASE_URL to the server's OpenAI-compatible base URL \
                     (e.g. http://localhost:8000/v1)"
                        .to_owned(),
                );
            }
        }
    }
    let ollama_host = lookup("OLLAMA_HOST").map(|(v, _)| v);
    let ollama_url = ollama_host
        .clone()
        .unwrap_or_else(|| "http://localhost:11434".to_owned());
    if ollama_probe(&ollama_url) {
        providers.push(format!("ollama: running at {}", first_chars(&ollama_url)));
    } else if ollama_host.is_some() {
        notes.push(format!(
            "OLLAMA_HOST={} set but nothing answers there",
            first_chars(&ollama_url)
        ));
    }

    if let Some(e) = &secrets.error {
        status = status.max(Status::Warn);
        notes.push(format!("{secrets_name} exists but cannot be read ({e})"));
        fixes.push(format!(
            "make {secrets_name} readable by the user that runs robotd"
        ));
    }
    if let Some(line) = secrets.bad_line {
        status = status.max(Status::Warn);
        notes.push(format!(
            "line {line} of {secrets_name} is not a KEY=VALUE line: none of its keys are used"
        ));
        fixes.push(format!(
            "fix line {line} of {secrets_name} (KEY=VALUE; quote a value with spaces)"
        ));
    }
    if secrets.world_readable && !secrets.vars.is_empty() {
        status = status.max(Status::Warn);
        notes.push(format!("{secrets_name} is readable by every user"));
        fixes.push(format!("chmod 600 {secrets_name}"));
    }

    if providers.is_empty() {
        status = status.max(Status::Warn);
        notes.insert(
            0,
            "no LLM provider: none of OPENAI_API_KEY, GROQ_API_KEY, GEMINI_API_KEY, \
             LLM_API_KEY(+LLM_BASE_URL), API_KEY is set and no Ollama answers; the agent is off"
                .to_owned(),
        );
        fixes.insert(
            0,
            format!(
                "set OPENAI_API_KEY (or GROQ_API_KEY / GEMINI_API_KEY) in the environment or in \
                 {secrets_name}, or run Ollama (OLLAMA_HOST, default http://localhost:11434)"
            ),
        );
    } else {
        notes.insert(0, providers.join("; "));
    }

    Check {
        name: NAME,
        status,
        found: notes.join("; "),
        fix: if status == Status::Ok || fixes.is_empty() {
            None
        } else {
            Some(fixes.join("; "))
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::doctor::report::DoctorReport;
    use crate::doctor::secrets::SECRETS_FILE;
    use crate::doctor::test_support::{env_from, free_port, no_secrets, temp_dir};
    use std::net::TcpListener;
    use std::time::Instant;

    #[test]
    fn a_bad_secrets_line_warns_with_its_number() {
        let secrets = Secrets {
            bad_line: Some(4),
            ..no_secrets()
        };
        let env = env_from(&[("OPENAI_API_KEY", "sk-env")]);
        let check = check_llm_keys(&env, &secrets, &|_| false);
        assert_eq!(check.status, Status::Warn, "{check:?}");
        assert!(check.found.contains("line 4 of"), "{check:?}");
        assert!(check.fix.unwrap_or_default().contains("fix line 4"));
    }

    #[test]
    fn llm_keys_report_sources_never_values() {
        let dir = temp_dir("llm");
        std::fs::write(
            dir.join(SECRETS_FILE),
            "GROQ_API_KEY=gsk_from_file_secret\nAPI_KEY='AIzaFileSecret'\n",
        )
        .expect("write secrets");
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(
                dir.join(SECRETS_FILE),
                std::fs::Permissions::from_mode(0o600),
            )
            .expect("chmod");
        }
        let secrets = Secrets::load(&dir);
        let env = env_from(&[("OPENAI_API_KEY", "sk-env-secret-value")]);
        let check = check_llm_keys(&env, &secrets, &|_| false);
        assert_eq!(check.status, Status::Ok, "{check:?}");
        assert!(
            check
                .found
                .contains("openai: OPENAI_API_KEY set (from env)"),
            "{}",
            check.found
        );
        assert!(
            check
                .found
                .contains("groq: GROQ_API_KEY set (from secrets.env)"),
            "{}",
            check.found
        );
        assert!(
            check
                .found
                .contains("gemini: API_KEY set (from secrets.env)"),
            "{}",
            check.found
        );
        let report = DoctorReport {
            checks: vec![check],
        };
        for text in [report.render_table(), report.to_json().to_string()] {
            for secret in [
                "sk-env-secret-value",
                "gsk_from_file_secret",
                "AIzaFileSecret",
            ] {
                assert!(!text.contains(secret), "{secret} leaked: {text}");
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn llm_keys_none_warns_generic_half_configured_warns_ollama_counts() {
        let check = check_llm_keys(&env_from(&[]), &no_secrets(), &|_| false);
        assert_eq!(check.status, Status::Warn);
        let fix = check.fix.clone().unwrap_or_default();
        assert!(
            fix.contains("OPENAI_API_KEY") && fix.contains("OLLAMA_HOST"),
            "{fix}"
        );

        let env = env_from(&[("LLM_API_KEY", "xyz-secret")]);
        let check = check_llm_keys(&env, &no_secrets(), &|_| false);
        assert_eq!(check.status, Status::Warn);
        assert!(check.fix.unwrap_or_default().contains("LLM_BASE_URL"));

        let env = env_from(&[
            ("LLM_API_KEY", "xyz-secret"),
            ("LLM_BASE_URL", "http://127.0.0.1:8000/v1"),
        ]);
        assert_eq!(
            check_llm_keys(&env, &no_secrets(), &|_| false).status,
            Status::Ok
        );

        let env = env_from(&[("API_KEY", "unknown-prefix-secret")]);
        let check = check_llm_keys(&env, &no_secrets(), &|_| false);
        assert_eq!(check.status, Status::Warn);
        assert!(!check.found.contains("unknown-prefix-secret"));

        let env = env_from(&[("OLLAMA_HOST", "http://127.0.0.1:11434")]);
        let check = check_llm_keys(&env, &no_secrets(), &|h| h.contains("11434"));
        assert_eq!(check.status, Status::Ok, "{check:?}");
        assert!(check.found.contains("ollama"));
    }

    #[test]
    fn ollama_probe_is_bounded_and_false_on_closed_port() {
        let start = Instant::now();
        assert!(!ollama_reachable(&format!(
            "http://127.0.0.1:{}",
            free_port()
        )));
        assert!(start.elapsed() < Duration::from_secs(1));
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let port = listener.local_addr().expect("addr").port();
        assert!(ollama_reachable(&format!("127.0.0.1:{port}")));
    }
}
