//! The audit log's tests: bounded lines, the keyed chain, verification, rotation.
use super::*;
use serde_json::json;

type Res = Result<(), Box<dyn std::error::Error>>;
const WAIT: Duration = Duration::from_secs(10);

fn key() -> AuditKey {
    AuditKey::from_bytes([7; 32])
}

/// `verify` with the tests' key.
fn verify(paths: &[PathBuf]) -> Result<VerifyReport, VerifyError> {
    super::verify(paths, Some(&key()))
}

fn config(dir: &tempfile::TempDir, max_file_bytes: u64, queue: usize) -> AuditConfig {
    let (path, keep_files) = (dir.path().join("log/audit.jsonl"), 3);
    AuditConfig {
        path,
        max_file_bytes,
        keep_files,
        queue,
        key: Some(key()),
    }
}

/// Starts a log, records `n` events (waiting when the queue is full) and drops it.
fn write_log(cfg: &AuditConfig, n: u64) -> Result<(), AuditError> {
    let log = AuditLog::start(cfg)?;
    for i in 0..n {
        let event = json!({"who": "agent", "tool": "move_to", "args": {"x": i}});
        if let Err(AuditError::QueueFull { .. }) = log.record(event.clone()) {
            log.flush(WAIT)?;
            log.record(event)?;
        }
    }
    log.flush(WAIT)
}

/// Line and problem where verifying `paths` fails.
fn broken(paths: &[PathBuf]) -> Option<(u64, Break)> {
    match verify(paths) {
        Err(VerifyError::Broken { line, problem, .. }) => Some((line, problem)),
        _ => None,
    }
}

#[test]
fn entries_verify_from_genesis() -> Res {
    let dir = tempfile::tempdir()?;
    let cfg = config(&dir, 1 << 20, 8);
    write_log(&cfg, 25)?;
    let r = verify(std::slice::from_ref(&cfg.path))?;
    assert_eq!((r.files, r.entries, r.first_seq), (1, 25, 1));
    assert!(r.starts_at_genesis && r.last_seq == 25);
    let text = fs::read_to_string(&cfg.path)?;
    assert!(text.starts_with("{\"seq\":1,\"time\":\"") && text.contains(GENESIS));
    assert_eq!(AuditLog::start(&cfg)?.path(), Some(cfg.path.as_path()));
    Ok(())
}

#[test]
fn tampering_is_named_by_line() -> Res {
    let dir = tempfile::tempdir()?;
    let cfg = config(&dir, 1 << 20, 8);
    write_log(&cfg, 10)?;
    let original = fs::read_to_string(&cfg.path)?;
    let one = std::slice::from_ref(&cfg.path);
    let tamper = |edit: &dyn Fn(&mut Vec<String>)| {
        let mut lines: Vec<String> = original.lines().map(String::from).collect();
        edit(&mut lines);
        let text: String = lines.iter().map(|l| format!("{l}\n")).collect();
        fs::write(&cfg.path, text).map(|()| broken(one))
    };
    let (seq, prev_seq) = (6, 4);
    let deleted = tamper(&|l| drop(l.remove(4)))?;
    assert_eq!(deleted, Some((5, Break::Missing { seq, prev_seq })));
    let edited = tamper(&|l| l[6] = l[6].replacen("move_to", "move_tO", 1))?;
    assert_eq!(edited, Some((7, Break::MacMismatch)));
    let (seq, prev_seq) = (4, 2);
    let swapped = tamper(&|l| l.swap(2, 3))?;
    assert_eq!(swapped, Some((3, Break::Missing { seq, prev_seq })));
    let garbled = tamper(&|l| l[1] = "{\"seq\": 2".into())?;
    assert!(matches!(garbled, Some((2, Break::NotEntry(_)))));
    // Line 2 replaced by one with a correct seq and its own valid hash, but a wrong prev.
    let prev = "a".repeat(64);
    let body = format!(r#"{{"seq":2,"time":"t","prev":"{prev}","event":1}}"#);
    let hash = key().mac_hex(body.as_bytes());
    let forged = format!("{}{HMAC_KEY}{hash}\"}}", &body[..body.len() - 1]);
    let relinked = tamper(&|l| l[1] = forged.clone())?;
    assert_eq!(relinked, Some((2, Break::PrevMismatch)));
    let err = verify(one).err().map(|e| e.to_string()).unwrap_or_default();
    let want = "line 2: prev hash does not match the previous line's hash";
    assert!(err.contains("audit.jsonl: ") && err.contains(want), "{err}");
    Ok(())
}

#[test]
fn restart_continues_the_chain() -> Res {
    let dir = tempfile::tempdir()?;
    let cfg = config(&dir, 1 << 20, 8);
    write_log(&cfg, 3)?;
    write_log(&cfg, 2)?;
    let r = verify(std::slice::from_ref(&cfg.path))?;
    assert_eq!((r.entries, r.first_seq, r.last_seq), (5, 1, 5));
    assert!(r.starts_at_genesis);
    Ok(())
}

#[test]
fn rotation_keeps_a_bounded_number_of_chained_files() -> Res {
    let dir = tempfile::tempdir()?;
    let cfg = config(&dir, 1000, 8);
    write_log(&cfg, 60)?;
    assert_eq!(fs::read_dir(dir.path().join("log"))?.count(), 3 + 1);
    let mut files: Vec<PathBuf> = (1..=3).rev().map(|k| rotated_path(&cfg.path, k)).collect();
    files.push(cfg.path.clone());
    for file in &files {
        assert!(fs::metadata(file)?.len() <= 1000, "{}", file.display());
    }
    let r = verify(&files)?;
    assert_eq!((r.files, r.last_seq, r.entries), (4, 60, 61 - r.first_seq));
    assert!(!r.starts_at_genesis, "the oldest entries were rotated away");
    let newest_first: Vec<PathBuf> = files.iter().rev().cloned().collect();
    let wrong_order = broken(&newest_first);
    assert!(matches!(wrong_order, Some((1, Break::Reordered { .. }))));
    write_log(&cfg, 1)?; // a restart continues from the files on disk
    assert_eq!(verify(&files[1..])?.last_seq, 61);
    Ok(())
}

#[test]
fn full_queue_refuses_without_blocking() -> Res {
    let dir = tempfile::tempdir()?;
    let cfg = config(&dir, 1 << 20, 2);
    let (open_gate, gate) = mpsc::channel();
    let log = AuditLog::start_gated(&cfg, Some(gate))?; // the writer waits for the gate
    log.record(json!(1))?;
    log.record(json!(2))?;
    let err = log.record(json!(3)).err().ok_or("third record accepted")?;
    assert!(matches!(err, AuditError::QueueFull { capacity: 2 }));
    let text = "audit log queue full (2 records waiting): motion refused so that";
    assert!(err.to_string().starts_with(text), "{err}");
    let late = log.flush(Duration::from_millis(20));
    assert!(matches!(late, Err(AuditError::FlushTimeout { .. })));
    open_gate.send(())?;
    log.flush(WAIT)?;
    log.record(json!(4))?;
    log.flush(WAIT)?;
    assert_eq!(verify(std::slice::from_ref(&cfg.path))?.entries, 3);
    Ok(())
}

#[test]
fn writer_failure_refuses_later_records() -> Res {
    let dir = tempfile::tempdir()?;
    let cfg = AuditConfig {
        keep_files: 1,
        ..config(&dir, 300, 8)
    };
    let log = AuditLog::start(&cfg)?;
    // A non-empty directory where rotation must delete a file: rotation fails.
    fs::create_dir_all(rotated_path(&cfg.path, 1).join("x"))?;
    for i in 0..5 {
        let _ = log.record(json!({"i": i, "pad": "x".repeat(100)}));
    }
    let err = log.flush(WAIT).err().ok_or("flush succeeded")?;
    let text = err.to_string();
    assert!(
        text.starts_with("audit log writer failed: cannot write"),
        "{err}"
    );
    assert!(text.contains("cannot rotate"), "{err}");
    let later = log.record(json!(0));
    assert!(matches!(later, Err(AuditError::WriterFailed { .. })));
    Ok(())
}

#[test]
fn corrupt_last_line_stops_start() -> Res {
    let dir = tempfile::tempdir()?;
    let cfg = config(&dir, 1 << 20, 8);
    write_log(&cfg, 3)?;
    let mut file = OpenOptions::new().append(true).open(&cfg.path)?;
    file.write_all(b"{\"seq\":4,\"garbage\n")?;
    let err = AuditLog::start(&cfg).err().ok_or("started")?;
    assert!(matches!(err, AuditError::CorruptTail { line: 4, .. }));
    let text = "audit.jsonl: line 4: not a JSON audit entry";
    assert!(err.to_string().contains(text), "{err}");
    Ok(())
}

#[test]
fn control_characters_stay_on_one_line() -> Res {
    let dir = tempfile::tempdir()?;
    let cfg = config(&dir, 1 << 20, 8);
    let nasty = "a\r\nb\n\u{1b}[2Jc\u{0}d\u{7}";
    let log = AuditLog::start(&cfg)?;
    log.record(json!({"reason": nasty}))?;
    log.record(json!({"ok": true}))?;
    log.flush(WAIT)?;
    let text = fs::read_to_string(&cfg.path)?;
    assert_eq!(text.matches('\n').count(), 2);
    assert!(!text.contains(['\r', '\u{1b}', '\u{0}', '\u{7}']));
    let first: Value = serde_json::from_str(text.lines().next().unwrap_or_default())?;
    assert_eq!(first["event"]["reason"], nasty);
    assert_eq!(verify(std::slice::from_ref(&cfg.path))?.entries, 2);
    Ok(())
}

/// Issue 39, door 9: one call with a huge field must not write a huge line.
#[test]
fn long_fields_are_cut_and_marked() -> Res {
    let dir = tempfile::tempdir()?;
    let cfg = config(&dir, 1 << 20, 8);
    let log = AuditLog::start(&cfg)?;
    let huge = "é".repeat(256_000); // 512000 bytes, two per char
    let event = json!({"event": "admission", "arguments": {"workspace_id": huge},
        "reason": "x".repeat(300), "list": (0..10_000).collect::<Vec<u32>>()});
    log.record(event)?;
    log.flush(WAIT)?;
    let text = fs::read_to_string(&cfg.path)?;
    assert!(text.len() < 8 * 1024, "one line of {} bytes", text.len());
    let line: Value = serde_json::from_str(text.lines().next().unwrap_or_default())?;
    let id = line["event"]["arguments"]["workspace_id"]
        .as_str()
        .unwrap_or_default();
    assert!(id.starts_with(&"é".repeat(256)), "{id}");
    assert!(id.ends_with("…(cut, 512000 bytes)"), "{id}");
    let reason = line["event"]["reason"].as_str().unwrap_or_default();
    assert!(reason.ends_with("…(cut, 300 bytes)"), "{reason}");
    assert_eq!(line["event"]["event"], "admission");
    assert!(line["event"]["list"]
        .as_array()
        .is_some_and(|l| l.len() <= 65));
    Ok(())
}

/// Rewrites `lines` from index `from` on as an unkeyed chain would be rewritten by someone
/// without the key: each line's `prev` set to the line before's new hash, and re-hashed.
fn rehash_from(lines: &mut [String], from: usize, key: Option<&AuditKey>) {
    for i in from..lines.len() {
        let mut value: Value = serde_json::from_str(&lines[i]).unwrap_or_default();
        let object = value
            .as_object_mut()
            .map(std::mem::take)
            .unwrap_or_default();
        let prev = (i > 0).then(|| {
            let before: Value = serde_json::from_str(&lines[i - 1]).unwrap_or_default();
            let mac = before.get("hmac").or(before.get("hash")).cloned();
            mac.unwrap_or_default()
        });
        let body = json!({"seq": object["seq"], "time": object["time"],
            "prev": prev.unwrap_or_else(|| object["prev"].clone()), "event": object["event"]});
        let body = serde_json::to_string(&body).unwrap_or_default();
        let (field, hash) = match key {
            Some(key) => (HMAC_KEY, key.mac_hex(body.as_bytes())),
            None => (HASH_KEY, sha256_hex(body.as_bytes())),
        };
        lines[i] = format!("{}{field}{hash}\"}}", &body[..body.len() - 1]);
    }
}

/// Issue 39, door 9: an edited line whose tail was re-hashed without the key is caught.
#[test]
fn a_rehashed_tail_does_not_verify() -> Res {
    let dir = tempfile::tempdir()?;
    let cfg = config(&dir, 1 << 20, 8);
    write_log(&cfg, 6)?;
    let original = fs::read_to_string(&cfg.path)?;
    let one = std::slice::from_ref(&cfg.path);
    let rewrite = |key: Option<&AuditKey>| {
        let mut lines: Vec<String> = original.lines().map(String::from).collect();
        lines[3] = lines[3].replacen("move_to", "move_tO", 1);
        rehash_from(&mut lines, 3, key);
        let text: String = lines.iter().map(|l| format!("{l}\n")).collect();
        fs::write(&cfg.path, text).map(|()| broken(one))
    };
    // Re-hashed as the older unkeyed format: an unkeyed line after keyed ones.
    assert_eq!(rewrite(None)?, Some((4, Break::Unkeyed)));
    // Re-keyed with a guessed key.
    let guess = AuditKey::from_bytes([8; 32]);
    assert_eq!(rewrite(Some(&guess))?, Some((4, Break::MacMismatch)));
    // With the key, the same rewrite verifies: the key is what protects the chain.
    assert!(rewrite(Some(&key()))?.is_none());
    // Without a key, a keyed log cannot be checked at all.
    let no_key = super::verify(one, None);
    assert!(matches!(
        no_key,
        Err(VerifyError::Broken {
            line: 1,
            problem: Break::NoKey,
            ..
        })
    ));
    Ok(())
}

/// Logs written before the key verify as unkeyed; a keyed log may continue them.
#[test]
fn older_unkeyed_logs_still_verify_and_continue_keyed() -> Res {
    let dir = tempfile::tempdir()?;
    let keyed = config(&dir, 1 << 20, 8);
    let unkeyed = AuditConfig {
        key: None,
        ..keyed.clone()
    };
    write_log(&unkeyed, 3)?;
    let one = std::slice::from_ref(&keyed.path);
    let r = super::verify(one, None)?;
    assert_eq!((r.entries, r.keyed, r.unkeyed), (3, 0, 3));
    write_log(&keyed, 2)?; // a robotd with a key continues the old chain
    let r = verify(one)?;
    assert_eq!((r.entries, r.keyed, r.unkeyed, r.last_seq), (5, 2, 3, 5));
    assert!(r.starts_at_genesis);
    // A start with another key refuses to continue the chain.
    let other = AuditConfig {
        key: Some(AuditKey::from_bytes([9; 32])),
        ..keyed.clone()
    };
    let err = AuditLog::start(&other).err().ok_or("started")?;
    assert!(err.to_string().contains("another key"), "{err}");
    Ok(())
}

/// The HMAC against an independent implementation (Python's `hmac`):
/// `hmac.new(b"\x07"*32, b"robotd", "sha256").hexdigest()`.
#[test]
fn hmac_matches_an_independent_implementation() {
    assert_eq!(
        key().mac_hex(b"robotd"),
        "150271e027ab4583201167bb71083a2f84e6b9e4e54aad10faefc58af0271bc3"
    );
}

#[test]
fn key_file_is_created_once_with_mode_0600() -> Res {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("state/audit.key");
    let made = AuditKey::load_or_create(&path)?;
    assert_eq!(AuditKey::load_or_create(&path)?, made);
    let text = fs::read_to_string(&path)?;
    assert_eq!(text.trim().len(), 64);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        assert_eq!(fs::metadata(&path)?.permissions().mode() & 0o777, 0o600);
    }
    fs::write(&path, "not a key")?;
    let err = AuditKey::load(&path).err().ok_or("loaded")?;
    assert!(err.to_string().contains("not 64 hex digits"), "{err}");
    Ok(())
}

#[test]
fn disabled_log_and_bad_config() -> Res {
    let log = AuditLog::disabled();
    assert!(log.record(json!({})).is_ok() && log.flush(WAIT).is_ok() && log.path().is_none());
    let dir = tempfile::tempdir()?;
    let started = AuditLog::start(&config(&dir, 1000, 0));
    assert!(matches!(started, Err(AuditError::InvalidConfig { .. })));
    fn send_sync_clone<T: Send + Sync + Clone>() {}
    send_sync_clone::<AuditLog>();
    Ok(())
}
