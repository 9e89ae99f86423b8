//! Fuzzing the configuration: files, `--set` overrides and environment variables built from
//! every key robotd knows, with values of every wrong shape (and random bytes as whole files).
//! robotd must never panic on them, and every refusal must be a clear error: `Invalid` lists
//! problems, each naming its key (or the whole layer for a syntax error) and a reason.
//!
//! Bounded for CI (PROPTEST_CASES, 256 by default per property); failures are kept in
//! `proptest-regressions/` and replayed first.

use proptest::prelude::*;
use robotd_config::{Config, DEFAULT_TOML};
use robotd_runtime::config::{ConfigError, LoadOptions};
use std::sync::atomic::{AtomicU32, Ordering};

/// Every dotted key of the documented defaults, e.g. `http.bind`, `robot.time_scale`.
fn known_keys() -> Vec<String> {
    fn walk(prefix: &str, table: &toml::Table, out: &mut Vec<String>) {
        for (key, value) in table {
            let path = if prefix.is_empty() {
                key.clone()
            } else {
                format!("{prefix}.{key}")
            };
            match value {
                toml::Value::Table(inner) if !inner.is_empty() => walk(&path, inner, out),
                _ => out.push(path),
            }
        }
    }
    let table: toml::Table = DEFAULT_TOML.parse().expect("default.toml parses");
    let mut keys = Vec::new();
    walk("", &table, &mut keys);
    keys
}

/// Values of every shape, as TOML source text.
fn toml_value() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<i64>().prop_map(|v| v.to_string()),
        prop_oneof![
            Just(f64::NAN),
            Just(f64::INFINITY),
            Just(-1e300),
            any::<f64>()
        ]
        .prop_map(|v| format!("{v:?}").replace("NaN", "nan")),
        any::<bool>().prop_map(|v| v.to_string()),
        "[ -~]{0,40}".prop_map(|s| format!("{s:?}")),
        "\\PC{0,20}".prop_map(|s| format!("{s:?}")),
        Just("\"\"".to_owned()),
        Just("[1, \"two\", 3.0]".to_owned()),
        Just("{ a = 1 }".to_owned()),
        Just("\"x\".repeat".to_owned()),
    ]
}

/// Values of every shape, as environment or `--set` text.
fn text_value() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<i64>().prop_map(|v| v.to_string()),
        any::<f64>().prop_map(|v| v.to_string()),
        Just("NaN".to_owned()),
        Just("-0".to_owned()),
        Just("[1,2".to_owned()),
        Just("{}".to_owned()),
        "[ -~]{0,40}",
        "\\PC{0,20}",
        "[\\x00-\\x1f]{1,5}",
        // A quoted string with an escape after any text (figment 0.10 panicked on "é\\n").
        ("\\PC{1,8}", "\\PC{0,8}").prop_map(|(a, b)| format!("\"{a}\\{b}\"")),
    ]
}

fn temp_file(text: &[u8]) -> std::path::PathBuf {
    static NEXT: AtomicU32 = AtomicU32::new(0);
    let path = std::env::temp_dir().join(format!(
        "robotd-config-fuzz-{}-{}.toml",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::write(&path, text).expect("write temp config");
    path
}

/// The outcome must be a configuration or a clear error: never a panic, never an empty
/// reason, every problem naming a key that was set (or the whole layer).
fn check(outcome: Result<Config, ConfigError>, keys_set: &[String]) -> Result<(), TestCaseError> {
    match outcome {
        Ok(_) => Ok(()),
        Err(ConfigError::Invalid { problems }) => {
            prop_assert!(!problems.is_empty(), "Invalid without problems");
            for problem in &problems {
                prop_assert!(!problem.reason.trim().is_empty(), "empty reason: {problem}");
                let named = problem.key.is_empty()
                    || keys_set.iter().any(|k| {
                        k.starts_with(&problem.key)
                            || problem.key.starts_with(k.as_str())
                            || k.split('.').next() == problem.key.split('.').next()
                    });
                prop_assert!(named, "problem {problem} names none of {keys_set:?}");
            }
            Ok(())
        }
        Err(other) => {
            prop_assert!(!other.to_string().trim().is_empty());
            Ok(())
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(256),
        ..ProptestConfig::default()
    })]

    /// A file setting known keys to values of any shape.
    #[test]
    fn files_with_values_of_every_shape(picks in proptest::collection::vec((any::<prop::sample::Index>(), toml_value()), 1..6)) {
        let keys = known_keys();
        let mut text = String::new();
        let mut set = Vec::new();
        for (index, value) in &picks {
            let key = &keys[index.index(keys.len())];
            let (section, name) = key.rsplit_once('.').unwrap_or(("", key.as_str()));
            if !section.is_empty() {
                text.push_str(&format!("[{section}]\n"));
            }
            text.push_str(&format!("{name} = {value}\n"));
            set.push(key.clone());
        }
        let path = temp_file(text.as_bytes());
        let outcome = std::panic::catch_unwind(|| {
            Config::load_with_env(
                LoadOptions { file: Some(path.clone()), overrides: Vec::new() },
                Vec::<(String, String)>::new(),
            )
        });
        let _ = std::fs::remove_file(&path);
        let outcome = outcome.map_err(|_| TestCaseError::fail(format!("panicked on:\n{text}")))?;
        check(outcome, &set)?;
    }

    /// Random bytes as the whole file.
    #[test]
    fn files_of_random_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let path = temp_file(&bytes);
        let outcome = std::panic::catch_unwind(|| {
            Config::load_with_env(
                LoadOptions { file: Some(path.clone()), overrides: Vec::new() },
                Vec::<(String, String)>::new(),
            )
        });
        let _ = std::fs::remove_file(&path);
        let outcome = outcome.map_err(|_| TestCaseError::fail("panicked on random bytes"))?;
        check(outcome, &[])?;
    }

    /// `--set key=value` and `ROBOTD_SECTION__KEY=value` with values of any shape.
    #[test]
    fn overrides_and_environment_of_every_shape(
        picks in proptest::collection::vec((any::<prop::sample::Index>(), text_value(), any::<bool>()), 1..6)
    ) {
        let keys = known_keys();
        let mut overrides = Vec::new();
        let mut env = Vec::new();
        let mut set = Vec::new();
        for (index, value, as_env) in &picks {
            let key = &keys[index.index(keys.len())];
            if *as_env {
                env.push((format!("ROBOTD_{}", key.to_uppercase().replace('.', "__")), value.clone()));
            } else {
                overrides.push((key.clone(), value.clone()));
            }
            set.push(key.clone());
        }
        let outcome = std::panic::catch_unwind(|| {
            Config::load_with_env(LoadOptions { file: None, overrides: overrides.clone() }, env.clone())
        });
        let outcome = outcome.map_err(|_| TestCaseError::fail(format!("panicked on {overrides:?} {env:?}")))?;
        check(outcome, &set)?;
    }
}
