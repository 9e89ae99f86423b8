//! The tamper-evident audit log of motion requests.
//!
//! Every motion request robotd handles (who asked, the arguments, the policy's decision and
//! reason, the outcome) is appended to a file such as `log/audit.jsonl` as one JSON line. Each
//! line carries the HMAC-SHA256 (keyed with an [`AuditKey`]) of its own bytes and that of the
//! line before it, so the lines form a keyed chain: a line that is edited, deleted or moved
//! breaks the chain at a place [`verify`] names, and without the key nobody can re-compute the
//! tail after an edit. Logs written before the key existed carry a plain SHA-256 `hash`
//! instead of the `hmac`; they still verify, reported as unkeyed (older format).
//!
//! # Bounded lines
//!
//! [`AuditLog::record`] cuts every string longer than [`MAX_FIELD_CHARS`] characters (on a
//! char boundary) and marks it `…(cut, N bytes)` with its original length; arrays and objects
//! keep their first [`MAX_ITEMS`] entries, nesting stops at [`MAX_DEPTH`], and an event still
//! longer than [`MAX_EVENT_BYTES`] has its big top-level fields replaced by the mark. One call
//! cannot write a megabyte, nor rotate the history out.
//!
//! # Line format
//!
//! The *body* is written by serde_json with its fields in this order:
//! `{"seq":7,"time":"2026-11-25T13:40:00.123456Z","prev":"<64 hex>","event":{…}}`.
//! `seq` counts from 1 and grows by exactly 1; `time` is UTC with microseconds; `prev` is the
//! previous line's hash (64 zeros, "genesis", for the first entry ever); `event` is the caller's
//! JSON. The MAC is the lowercase hex HMAC-SHA256 (RFC 2104) of the body's *bytes* under the
//! key, and the line is the body with `,"hmac":"<64 hex>"` inserted before its final `}` (an
//! older, unkeyed line has `,"hash":"<64 hex>"`, the plain SHA-256). To check a line, strip the
//! trailing `,"hmac":"…"}`, put back the `}` and compute: no JSON re-serialisation is involved.
//! Control characters in events (CR, LF, ESC, NUL) are JSON-escaped, so an entry is always one
//! line.
//!
//! # The key
//!
//! 32 random bytes from the OS, written as 64 hex digits to a file created with mode 0600
//! (`audit.key` beside the audit file unless `[safety.audit] key_file` names another) on the
//! first start, and read on every later one ([`AuditKey::load_or_create`]).
//!
//! # Never blocking, and refusing instead
//!
//! [`AuditLog::record`] puts the event in a bounded queue and returns at once; a thread named
//! `robotd-audit` appends it. When the queue is full, or the writer has failed (disk full,
//! permissions), `record` returns an error and robotd **refuses the motion**. An unattended,
//! LLM-driven arm must not move without a trace: a refused motion is safe and can be retried, a
//! lost record cannot be recovered. The writer flushes its buffer to the OS after each batch it
//! drains from the queue, but does not `fsync` each line (that would cost a disk round trip per
//! motion): a crash of robotd loses nothing flushed, a power cut may lose the last batch.
//!
//! # Rotation and restarts
//!
//! Before a line would make the active file exceed `max_file_bytes`, the file becomes
//! `audit.jsonl.1`, `.1` becomes `.2`, … up to `keep_files`; older files are deleted. The chain
//! continues across files. On start the log reads the last line of the active file (or of `.1`
//! if the active file is empty) and continues its `seq` and hash; a last line that is not a valid
//! entry stops the start with [`AuditError::CorruptTail`] instead of silently starting a new chain.
//!
//! # Verifying
//!
//! `robotd audit verify log/audit.jsonl.2 log/audit.jsonl.1 log/audit.jsonl` (oldest first)
//! calls [`verify`] with the key, which recomputes every MAC and checks `seq` and `prev` across
//! the files. An unkeyed line after a keyed one is a break (a tail re-hashed without the key).
//! If the first entry is not `seq` 1, the files are a suffix of the log (older files were
//! rotated away) and the report says `starts_at_genesis: false`: what came before cannot be
//! checked. Nor can a chain reveal lines cut off its *end*; to detect that, keep
//! [`VerifyReport::last_hash`] somewhere else and compare later.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use robotd_runtime::telemetry::rotating::{rotated_path, RotatingFile};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use sha2::{Digest, Sha256};

/// `prev` of the first entry ever.
const GENESIS: &str = "0000000000000000000000000000000000000000000000000000000000000000";
/// Inserted before the body's final `}` of an unkeyed (older) line, followed by the hash and `"}`.
const HASH_KEY: &str = ",\"hash\":\"";
/// Inserted before the body's final `}` of a keyed line, followed by the HMAC and `"}`.
const HMAC_KEY: &str = ",\"hmac\":\"";
/// Length of `,"hash":"<64 hex>"}` (or `,"hmac":…`) at the end of every line.
const TAIL_LEN: usize = HASH_KEY.len() + 64 + 2;

/// Strings in an event longer than this many characters are cut and marked.
pub const MAX_FIELD_CHARS: usize = 256;
/// Arrays and objects in an event keep this many entries; the rest is counted in a mark.
pub const MAX_ITEMS: usize = 64;
/// Values nested deeper than this are replaced by a mark.
pub const MAX_DEPTH: usize = 8;
/// An event longer than this (serialised, after the cuts above) has each top-level field
/// longer than [`MAX_TOP_FIELD_BYTES`] replaced by a mark.
pub const MAX_EVENT_BYTES: usize = 16 * 1024;
/// See [`MAX_EVENT_BYTES`].
const MAX_TOP_FIELD_BYTES: usize = 512;

/// The key of the audit log's HMAC chain: 32 bytes, kept in a file of 64 hex digits.
#[derive(Clone, PartialEq, Eq)]
pub struct AuditKey([u8; 32]);

impl std::fmt::Debug for AuditKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("AuditKey(…)")
    }
}

impl AuditKey {
    /// A key of these bytes.
    pub fn from_bytes(bytes: [u8; 32]) -> AuditKey {
        AuditKey(bytes)
    }

    /// Reads the key file at `path` (64 hex digits, surrounding white space ignored).
    pub fn load(path: &Path) -> Result<AuditKey, AuditError> {
        let text = fs::read_to_string(path).map_err(io_err(path))?;
        let bad = || AuditError::Key {
            path: path.to_path_buf(),
            reason: "is not 64 hex digits (an audit key)".into(),
        };
        let hex = text.trim();
        if hex.len() != 64 || !hex.is_ascii() {
            return Err(bad());
        }
        let mut key = [0u8; 32];
        for (byte, pair) in key.iter_mut().zip(hex.as_bytes().chunks(2)) {
            let pair = std::str::from_utf8(pair).map_err(|_| bad())?;
            *byte = u8::from_str_radix(pair, 16).map_err(|_| bad())?;
        }
        Ok(AuditKey(key))
    }

    /// Reads the key file at `path`, or, when there is none, creates it (and its directory)
    /// with mode 0600 holding 32 new random bytes from the OS.
    pub fn load_or_create(path: &Path) -> Result<AuditKey, AuditError> {
        match fs::metadata(path) {
            Ok(_) => return AuditKey::load(path),
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(e) => return Err(io_err(path)(e)),
        }
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            fs::create_dir_all(dir).map_err(io_err(dir))?;
        }
        let mut key = [0u8; 32];
        ring::rand::SecureRandom::fill(&ring::rand::SystemRandom::new(), &mut key).map_err(
            |_| AuditError::Key {
                path: path.to_path_buf(),
                reason: "the operating system gave no random bytes".into(),
            },
        )?;
        let mut options = OpenOptions::new();
        options.write(true).create_new(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
        let mut file = match options.open(path) {
            // Another start created it first: use that one.
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => return AuditKey::load(path),
            other => other.map_err(io_err(path))?,
        };
        let written = file.write_all(format!("{}\n", hex(&key)).as_bytes());
        written
            .and_then(|()| file.sync_all())
            .map_err(io_err(path))?;
        Ok(AuditKey(key))
    }

    /// Lowercase hex HMAC-SHA256 (RFC 2104) of `bytes` under this key (`ring::hmac`).
    fn mac_hex(&self, bytes: &[u8]) -> String {
        let key = ring::hmac::Key::new(ring::hmac::HMAC_SHA256, &self.0);
        hex(ring::hmac::sign(&key, bytes).as_ref())
    }
}

/// Where and how to write the audit log; built by the caller from its config.
#[derive(Clone, Debug)]
pub struct AuditConfig {
    /// The active file, e.g. `log/audit.jsonl`; missing parent directories are created.
    pub path: PathBuf,
    /// Rotate before a line would make the active file exceed this many bytes.
    pub max_file_bytes: u64,
    /// Rotated files kept: `<path>.1` (newest) to `<path>.N`; older ones are deleted.
    pub keep_files: u32,
    /// Length of the bounded queue between [`AuditLog::record`] and the writer (>= 1).
    pub queue: usize,
    /// The key of the HMAC chain; `None` writes the older, unkeyed format (plain SHA-256),
    /// which anyone can re-hash after an edit.
    pub key: Option<AuditKey>,
}

/// Why the audit log could not start or take a record. When recording, any of these refuses
/// the motion.
#[derive(Debug, thiserror::Error)]
pub enum AuditError {
    /// The writer is behind; the record was not taken.
    #[error(
        "audit log queue full ({capacity} records waiting): motion refused so that no motion \
         goes unrecorded"
    )]
    QueueFull { capacity: usize },
    /// The writer stopped after an error; nothing more will be written.
    #[error(
        "audit log writer failed: {reason}; motion refused so that no motion goes unrecorded \
         (fix the cause and restart robotd)"
    )]
    WriterFailed { reason: String },
    /// A file or directory could not be created, opened or read at start.
    #[error("audit log {}: {source}", path.display())]
    Io { path: PathBuf, source: io::Error },
    /// The log ends in a line (1-based) that is not a valid entry, so its chain cannot go on.
    #[error(
        "audit log {}: line {line}: {reason}; refusing to start a new chain on top of it \
         (inspect the file, or move it aside to start a new log)",
        path.display()
    )]
    CorruptTail {
        path: PathBuf,
        line: u64,
        reason: Break,
    },
    /// The configuration cannot work.
    #[error("invalid audit log configuration: {reason}")]
    InvalidConfig { reason: String },
    /// The key file cannot be used.
    #[error("audit key {}: {reason}", path.display())]
    Key { path: PathBuf, reason: String },
    /// [`AuditLog::flush`] gave up before everything was written.
    #[error("audit log flush timed out after {timeout:?} ({pending} records not yet written)")]
    FlushTimeout { timeout: Duration, pending: u64 },
}

/// Handle to the audit log; `Clone` is cheap. All clones share one writer thread, which writes
/// what is queued and stops when the last clone is dropped (that drop waits for it).
#[derive(Clone)]
pub struct AuditLog {
    inner: Option<Arc<Inner>>,
}

/// Fields drop in declaration order: `tx` closes the queue, then `_writer` waits for the
/// writer thread to drain it.
struct Inner {
    tx: SyncSender<Value>,
    shared: Arc<Shared>,
    path: PathBuf,
    capacity: usize,
    _writer: Joiner,
}

/// Joins the writer thread when dropped.
struct Joiner(Option<JoinHandle<()>>);

impl Drop for Joiner {
    fn drop(&mut self) {
        if let Some(handle) = self.0.take() {
            let _ = handle.join();
        }
    }
}

/// What the handles and the writer thread share.
#[derive(Default)]
struct Shared {
    state: Mutex<State>,
    changed: Condvar,
}

#[derive(Default)]
struct State {
    sent: u64,
    written: u64,
    failed: Option<String>,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl State {
    /// `WriterFailed` once the writer has stopped.
    fn check(&self) -> Result<(), AuditError> {
        let failed = self.failed.clone();
        failed.map_or(Ok(()), |reason| Err(AuditError::WriterFailed { reason }))
    }
}

impl AuditLog {
    /// Opens or creates `config.path`, continues the chain from its last line and starts the
    /// writer thread `robotd-audit`.
    pub fn start(config: &AuditConfig) -> Result<AuditLog, AuditError> {
        Self::start_gated(config, None)
    }

    /// [`start`](Self::start), with a writer that first waits for `gate` (tests hold it shut).
    fn start_gated(config: &AuditConfig, gate: Option<Receiver<()>>) -> Result<Self, AuditError> {
        if config.queue == 0 {
            let reason = "queue must be at least 1".into();
            return Err(AuditError::InvalidConfig { reason });
        }
        let path = &config.path;
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            fs::create_dir_all(dir).map_err(io_err(dir))?;
        }
        let key = config.key.as_ref();
        let mut tail = read_tail(path, key)?;
        if tail.is_none() {
            // Only `.1` has entries (stopped right after a rotation): continue from it.
            tail = read_tail(&rotated_path(path, 1), key)?.map(|(entry, _)| (entry, true));
        }
        let mut out = BufWriter::new(open_append(path).map_err(io_err(path))?);
        if let Some((_, false)) = tail {
            // The last entry is valid but its line end was cut off: end the line, keep the chain.
            let ended = out.write_all(b"\n").and_then(|()| out.flush());
            ended.map_err(io_err(path))?;
        }
        drop(out);
        let out = RotatingFile::open(path, config.max_file_bytes, config.keep_files)
            .map_err(io_err(path))?;
        let (seq, prev) = tail.map_or((0, GENESIS.into()), |(last, _)| (last.seq, last.hash));
        let shared = Arc::new(Shared::default());
        let writer = Writer {
            cfg: config.clone(),
            out,
            seq,
            prev,
            shared: shared.clone(),
        };
        let (tx, rx) = mpsc::sync_channel(config.queue);
        let thread = std::thread::Builder::new().name("robotd-audit".into());
        let handle = thread.spawn(move || writer.run(rx, gate)).map_err(|e| {
            let reason = format!("cannot start the writer thread: {e}");
            AuditError::WriterFailed { reason }
        })?;
        let inner = Inner {
            tx,
            shared,
            path: path.clone(),
            capacity: config.queue,
            _writer: Joiner(Some(handle)),
        };
        let inner = Some(Arc::new(inner));
        Ok(AuditLog { inner })
    }

    /// A log that records nothing; [`record`](Self::record) always returns `Ok`. For tests and
    /// benches that turn auditing off.
    pub fn disabled() -> AuditLog {
        AuditLog { inner: None }
    }

    /// Queues `event` for writing without blocking. An error means the event will not be
    /// written, and the motion must be refused. `Ok` means queued: if the writer fails later,
    /// the next `record` (and [`flush`](Self::flush)) says so.
    pub fn record(&self, event: Value) -> Result<(), AuditError> {
        let Some(inner) = &self.inner else {
            return Ok(());
        };
        let event = bound_event(event);
        let mut state = inner.shared.lock();
        state.check()?;
        let capacity = inner.capacity;
        inner.tx.try_send(event).map_err(|e| match e {
            TrySendError::Full(_) => AuditError::QueueFull { capacity },
            TrySendError::Disconnected(_) => {
                let reason = "the writer thread stopped".into();
                AuditError::WriterFailed { reason }
            }
        })?;
        state.sent += 1;
        Ok(())
    }

    /// Waits up to `timeout` until everything queued before this call is written and flushed
    /// to the OS (not fsynced). For tests and shutdown.
    pub fn flush(&self, timeout: Duration) -> Result<(), AuditError> {
        let Some(inner) = &self.inner else {
            return Ok(());
        };
        let deadline = Instant::now() + timeout;
        let mut state = inner.shared.lock();
        let target = state.sent;
        loop {
            state.check()?;
            if state.written >= target {
                return Ok(());
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                let pending = target - state.written;
                return Err(AuditError::FlushTimeout { timeout, pending });
            }
            let waited = inner.shared.changed.wait_timeout(state, left);
            state = waited.unwrap_or_else(PoisonError::into_inner).0;
        }
    }

    /// The active file, or `None` for a [`disabled`](Self::disabled) log.
    pub fn path(&self) -> Option<&Path> {
        self.inner.as_ref().map(|i| i.path.as_path())
    }
}

/// The writer thread: the open file and the end of the chain.
struct Writer {
    cfg: AuditConfig,
    out: RotatingFile,
    seq: u64,
    prev: String,
    shared: Arc<Shared>,
}

/// The body of a line, serialised with its fields in this order.
#[derive(Serialize)]
struct Body<'a> {
    seq: u64,
    time: &'a str,
    prev: &'a str,
    event: &'a Value,
}

impl Writer {
    fn run(mut self, rx: Receiver<Value>, gate: Option<Receiver<()>>) {
        if let Some(gate) = gate {
            let _ = gate.recv();
        }
        while let Ok(first) = rx.recv() {
            let more = rx.try_iter().take(self.cfg.queue);
            let batch: Vec<Value> = std::iter::once(first).chain(more).collect();
            let result = (batch.iter().try_for_each(|event| self.append(event)))
                .and_then(|()| self.out.flush().map_err(|e| self.reason("write", e)));
            let mut state = self.shared.lock();
            match result {
                Ok(()) => state.written += batch.len() as u64,
                Err(reason) => state.failed = Some(reason),
            }
            let failed = state.failed.is_some();
            drop(state);
            self.shared.changed.notify_all();
            if failed {
                return; // dropping `rx` makes later records fail
            }
        }
    }

    fn reason(&self, what: &str, e: io::Error) -> String {
        format!("cannot {what} {}: {e}", self.cfg.path.display())
    }

    fn append(&mut self, event: &Value) -> Result<(), String> {
        let (seq, time) = (self.seq + 1, now_utc());
        let body = Body {
            seq,
            time: &time,
            prev: &self.prev,
            event,
        };
        let body = serde_json::to_string(&body).map_err(|e| format!("cannot serialise: {e}"))?;
        let (field, hash) = match &self.cfg.key {
            Some(key) => (HMAC_KEY, key.mac_hex(body.as_bytes())),
            None => (HASH_KEY, sha256_hex(body.as_bytes())),
        };
        let open = body.strip_suffix('}').ok_or("serialised body lacks '}'")?;
        let line = format!("{open}{field}{hash}\"}}\n");
        let written = self.out.write(line.as_bytes());
        written.map_err(|e| self.reason("write", e))?;
        (self.seq, self.prev) = (seq, hash);
        Ok(())
    }
}

fn io_err(path: &Path) -> impl FnOnce(io::Error) -> AuditError {
    let path = path.to_path_buf();
    move |source| AuditError::Io { path, source }
}

fn open_append(path: &Path) -> io::Result<File> {
    OpenOptions::new().create(true).append(true).open(path)
}

/// UTC now as RFC 3339 with microseconds, e.g. `2026-11-25T13:40:00.123456Z`.
fn now_utc() -> String {
    let t = time::OffsetDateTime::now_utc();
    let (y, mo, d) = (t.year(), u8::from(t.month()), t.day());
    let (h, mi, s, us) = (t.hour(), t.minute(), t.second(), t.microsecond());
    format!("{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}.{us:06}Z")
}

/// `audit.key` in the directory of the audit file `path`: where the key is kept unless the
/// configuration names another file.
pub fn default_key_file(path: &Path) -> PathBuf {
    path.with_file_name("audit.key")
}

/// Lowercase hex SHA-256.
fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// Lowercase hex, written by hand (the digest type need not implement `LowerHex`).
fn hex(bytes: &[u8]) -> String {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let nibbles = bytes.iter().flat_map(|b| [b >> 4, b & 15]);
    nibbles
        .map(|nibble| char::from(DIGITS[usize::from(nibble)]))
        .collect()
}

/// `text` if it has at most [`MAX_FIELD_CHARS`] characters; otherwise its first
/// [`MAX_FIELD_CHARS`] characters and the mark `…(cut, N bytes)` with its length in bytes.
pub fn cut(text: &str) -> std::borrow::Cow<'_, str> {
    match text.char_indices().nth(MAX_FIELD_CHARS) {
        None => text.into(),
        Some((end, _)) => format!("{}…(cut, {} bytes)", &text[..end], text.len()).into(),
    }
}

/// `event` with every long string cut and marked, long arrays and objects shortened, deep
/// nesting replaced, and, if it is still longer than [`MAX_EVENT_BYTES`], its big top-level
/// fields replaced by marks.
fn bound_event(mut event: Value) -> Value {
    bound(&mut event, 0);
    let len = |v: &Value| serde_json::to_string(v).map_or(usize::MAX, |s| s.len());
    if len(&event) > MAX_EVENT_BYTES {
        let fields: Vec<&mut Value> = match &mut event {
            Value::Object(map) => map.values_mut().collect(),
            Value::Array(items) => items.iter_mut().collect(),
            _ => Vec::new(),
        };
        for field in fields {
            let n = len(field);
            if n > MAX_TOP_FIELD_BYTES {
                *field = format!("…(cut, {n} bytes)").into();
            }
        }
    }
    event
}

fn bound(value: &mut Value, depth: usize) {
    if depth >= MAX_DEPTH && (value.is_array() || value.is_object()) {
        *value = format!("…(cut, nested deeper than {MAX_DEPTH})").into();
        return;
    }
    match value {
        Value::String(text) => {
            if let std::borrow::Cow::Owned(short) = cut(text) {
                *text = short;
            }
        }
        Value::Array(items) => {
            let more = items.len().saturating_sub(MAX_ITEMS);
            items.truncate(MAX_ITEMS);
            items.iter_mut().for_each(|item| bound(item, depth + 1));
            if more > 0 {
                items.push(format!("…(cut, {more} more items)").into());
            }
        }
        Value::Object(map) => {
            let more = map.len().saturating_sub(MAX_ITEMS);
            let kept = std::mem::take(map).into_iter().take(MAX_ITEMS);
            for (name, mut item) in kept {
                bound(&mut item, depth + 1);
                map.insert(cut(&name).into_owned(), item);
            }
            if more > 0 {
                map.insert("…cut".into(), format!("{more} more fields").into());
            }
        }
        _ => {}
    }
}

fn is_hash(s: &str) -> bool {
    s.len() == 64 && s.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

/// What one line says about the chain.
struct Entry {
    seq: u64,
    prev: String,
    hash: String,
    /// Whether the line carries an HMAC (else the older, unkeyed SHA-256).
    keyed: bool,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)] // `time` and `event` are only checked for presence and type
struct ParsedBody {
    seq: u64,
    time: String,
    prev: String,
    event: Value,
}

/// Parses one line (without its `\n`) and checks it against its own MAC (with `key`) or, for
/// an older unkeyed line, its hash.
fn parse_line(bytes: &[u8], key: Option<&AuditKey>) -> Result<Entry, Break> {
    let bad = |s: &str| Break::NotEntry(s.to_string());
    let line = std::str::from_utf8(bytes).map_err(|_| bad("not UTF-8"))?;
    let cut = line.len().saturating_sub(TAIL_LEN);
    let tail = line.get(cut..).unwrap_or_default();
    let keyed = tail.starts_with(HMAC_KEY);
    let hash = (tail
        .strip_prefix(HMAC_KEY)
        .or_else(|| tail.strip_prefix(HASH_KEY)))
    .and_then(|t| t.strip_suffix("\"}"))
    .filter(|h| is_hash(h))
    .ok_or_else(|| bad("does not end in ,\"hmac\":\"<64 lowercase hex>\"}"))?;
    let body = format!("{}}}", line.get(..cut).unwrap_or_default());
    let parsed: ParsedBody = serde_json::from_str(&body).map_err(|e| bad(&e.to_string()))?;
    let (seq, prev, hash) = (parsed.seq, parsed.prev, hash.to_string());
    if !is_hash(&prev) {
        return Err(bad("prev is not 64 lowercase hex digits"));
    }
    if keyed {
        let key = key.ok_or(Break::NoKey)?;
        if key.mac_hex(body.as_bytes()) != hash {
            return Err(Break::MacMismatch);
        }
    } else if sha256_hex(body.as_bytes()) != hash {
        return Err(Break::Edited);
    }
    Ok(Entry {
        seq,
        prev,
        hash,
        keyed,
    })
}

/// The last line of `path` and whether it ends in `\n`; `None` if the file is missing or empty.
fn read_tail(path: &Path, key: Option<&AuditKey>) -> Result<Option<(Entry, bool)>, AuditError> {
    let file = match File::open(path) {
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
        other => other.map_err(io_err(path))?,
    };
    let mut reader = BufReader::new(file);
    let (mut buf, mut last, mut line) = (Vec::new(), Vec::new(), 0u64);
    while reader.read_until(b'\n', &mut buf).map_err(io_err(path))? > 0 {
        (line, last) = (line + 1, std::mem::take(&mut buf));
    }
    if line == 0 {
        return Ok(None);
    }
    let complete = last.ends_with(b"\n");
    let path = path.to_path_buf();
    match parse_line(last.strip_suffix(b"\n").unwrap_or(&last), key) {
        Ok(entry) => Ok(Some((entry, complete))),
        Err(reason) => Err(AuditError::CorruptTail { path, line, reason }),
    }
}

/// What [`verify`] found in an unbroken chain.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VerifyReport {
    /// Files read.
    pub files: usize,
    /// Entries checked.
    pub entries: u64,
    /// `seq` of the first entry (0 if there are none).
    pub first_seq: u64,
    /// `seq` of the last entry (0 if there are none).
    pub last_seq: u64,
    /// The first entry is `seq` 1 with the genesis `prev`. If false the files are a suffix of
    /// the log, and nothing before their first entry could be checked.
    pub starts_at_genesis: bool,
    /// Hash of the last entry (genesis if none); keep it elsewhere to detect truncation later.
    pub last_hash: String,
    /// Entries with an HMAC, checked with the key.
    pub keyed: u64,
    /// Entries of the older, unkeyed format (plain SHA-256, all before the first keyed one):
    /// they show a deletion or a careless edit, but anyone can rewrite them with their tail.
    pub unkeyed: u64,
}

/// Why [`verify`] rejects the files.
#[derive(Debug, thiserror::Error)]
pub enum VerifyError {
    /// No files were given.
    #[error("no audit files given")]
    NoFiles,
    /// A file could not be opened or read.
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: io::Error },
    /// The chain is broken at this line (1-based) of this file.
    #[error("{}: line {line}: {problem}", path.display())]
    Broken {
        path: PathBuf,
        line: u64,
        problem: Break,
    },
}

/// What is wrong with one line of the log.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Break {
    /// Not UTF-8, not JSON, or not shaped like an entry.
    #[error("not a JSON audit entry: {0}")]
    NotEntry(String),
    /// The line's bytes do not hash to its `hash`.
    #[error("hash does not match its content (the line was edited)")]
    Edited,
    /// The line's bytes do not give its `hmac` under the key.
    #[error("hmac does not match its content (the line was edited, or written with another key)")]
    MacMismatch,
    /// A keyed line, but no key to check it with.
    #[error("the line is keyed (hmac) but no audit key was given to check it")]
    NoKey,
    /// An unkeyed line after a keyed one.
    #[error(
        "an unkeyed line (hash) after keyed ones (hmac): the log was rewritten from here without \
         the key"
    )]
    Unkeyed,
    /// `seq` skips entries.
    #[error("seq {seq} follows seq {prev_seq} ({} missing)", entries(seq - prev_seq - 1))]
    Missing { seq: u64, prev_seq: u64 },
    /// `seq` does not grow.
    #[error("seq {seq} follows seq {prev_seq} (lines or files reordered or repeated)")]
    Reordered { seq: u64, prev_seq: u64 },
    /// `prev` is not the hash of the entry before.
    #[error("prev hash does not match the previous line's hash (a line was removed or reordered)")]
    PrevMismatch,
    /// The first entry has `seq` 0, or `seq` 1 without the genesis `prev`.
    #[error("seq {seq} cannot start a chain (seq starts at 1, with prev = 64 zeros)")]
    BadGenesis { seq: u64 },
}

fn entries(n: u64) -> String {
    format!("{n} {}", if n == 1 { "entry" } else { "entries" })
}

/// Checks the chain across `paths`, given oldest first (e.g. `audit.jsonl.2 audit.jsonl.1
/// audit.jsonl`): each line's HMAC under `key` (or the hash of an older unkeyed line), `seq`
/// growing by exactly 1, and `prev` linking to the entry before it, also across files. Unkeyed
/// lines may only come before the first keyed one. A keyed line without `key` is
/// [`Break::NoKey`].
pub fn verify(paths: &[PathBuf], key: Option<&AuditKey>) -> Result<VerifyReport, VerifyError> {
    if paths.is_empty() {
        return Err(VerifyError::NoFiles);
    }
    let mut report = VerifyReport {
        files: paths.len(),
        entries: 0,
        first_seq: 0,
        last_seq: 0,
        starts_at_genesis: true,
        last_hash: GENESIS.into(),
        keyed: 0,
        unkeyed: 0,
    };
    for path in paths {
        let io = |source| VerifyError::Io {
            path: path.clone(),
            source,
        };
        let lines = BufReader::new(File::open(path).map_err(io)?).split(b'\n');
        for (line, bytes) in (1..).zip(lines) {
            let broken = |problem| VerifyError::Broken {
                path: path.clone(),
                line,
                problem,
            };
            let entry = parse_line(&bytes.map_err(io)?, key).map_err(broken)?;
            let (seq, prev_seq) = (entry.seq, report.last_seq);
            let problem = if !entry.keyed && report.keyed > 0 {
                Some(Break::Unkeyed)
            } else if report.entries == 0 {
                (report.first_seq, report.starts_at_genesis) = (seq, seq == 1);
                let bad = seq == 0 || (seq == 1 && entry.prev != GENESIS);
                bad.then_some(Break::BadGenesis { seq })
            } else if seq <= prev_seq {
                Some(Break::Reordered { seq, prev_seq })
            } else if seq > prev_seq + 1 {
                Some(Break::Missing { seq, prev_seq })
            } else {
                (entry.prev != report.last_hash).then_some(Break::PrevMismatch)
            };
            if let Some(problem) = problem {
                return Err(broken(problem));
            }
            (report.entries, report.last_seq) = (report.entries + 1, seq);
            if entry.keyed {
                report.keyed += 1;
            } else {
                report.unkeyed += 1;
            }
            report.last_hash = entry.hash;
        }
    }
    Ok(report)
}

#[cfg(test)]
mod tests;
