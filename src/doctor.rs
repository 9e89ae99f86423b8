//! `robotd doctor`: is this machine ready to run robotd, and if not, what exactly to do.
//!
//! robotd leans on a few things outside its own process: shared memory in `/dev/shm` for the
//! iceoryx2 bus, the bus's bookkeeping files (which a crashed process can leave behind), an
//! optional Redis server for the Python tools, `espeak-ng` and an audio output for speech, and an
//! LLM provider key for the agent. When one of them is missing robotd still starts, but a
//! feature quietly degrades or an actor keeps failing — and the log line that says why is easy
//! to miss. The doctor checks each of them up front, in a few seconds, and prints one row per
//! check:
//!
//! ```text
//! STATUS   CHECK      FOUND
//! ok       shm        /dev/shm: 1.0 GiB, 1020.0 MiB free, writable
//! warn     audio      no audio output (...); speech will be written as WAV files to the spool directory
//!                     fix: attach a sound card, or set PULSE_SERVER=...
//! PROBLEM  redis      cannot connect to 127.0.0.1:6379 (Connection refused)
//!                     fix: apt-get install redis-server && redis-server --daemonize yes, ...
//! ```
//!
//! A row is `ok`, `warn` (works, but degraded or worth a look) or `problem` (something robotd
//! was configured to use does not work). Every row that is not `ok` carries a concrete fix.
//! `robotd doctor` exits with 1 when there is a problem, so scripts and CI can gate on it;
//! `--json` prints the same report as JSON, and `--clean` removes the shared-memory resources
//! of dead bus nodes (robotd also does that by itself when it starts).
//!
//! Every check is bounded in time: network checks use short timeouts (an unreachable host costs
//! at most a few hundred milliseconds per step) and external programs are killed if they do not
//! answer. The doctor never prints secrets — only whether a key is set and where it came from.
//!
//! ```ignore
//! # fn demo() -> anyhow::Result<()> {
//! let opts = DoctorOptions {
//!     redis_url: Some("redis://127.0.0.1:6379".into()),
//!     bus_namespace: "robotd".into(),
//!     config_dir: "config".into(),
//!     clean: false,
//!     http_bind: None,
//! };
//! let report = run(&opts)?;
//! print!("{}", report.render_table());
//! std::process::exit(if report.has_problems() { 1 } else { 0 });
//! # }
//! ```

use anyhow::Result;
use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::io::{ErrorKind, Read, Write};
use std::net::{IpAddr, SocketAddr, TcpStream, ToSocketAddrs};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Timeout of each network step (name resolution, connect, one reply).
const NET_TIMEOUT: Duration = Duration::from_millis(500);
/// How long an external program (`espeak-ng --version`) may take.
const PROGRAM_TIMEOUT: Duration = Duration::from_secs(3);
/// Below this much free space in /dev/shm the shm row warns.
const SHM_MIN_FREE: u64 = 256 * 1024 * 1024;
/// Name of the secrets file in the config directory.
const SECRETS_FILE: &str = "secrets.env";

/// What `robotd doctor` checks, and whether it may change anything.
#[derive(Debug, Clone)]
pub struct DoctorOptions {
    /// Redis URL (`redis://[:password@]host[:port][/db]`) from the command line or config; when
    /// `None`, `REDIS_HOST`/`REDIS_PORT` from the environment are used, and when those are unset
    /// too the Redis edge counts as off.
    pub redis_url: Option<String>,
    /// The bus namespace robotd uses (prefix of its iceoryx2 service names).
    pub bus_namespace: String,
    /// Directory of the configuration; a `secrets.env` there is read for keys.
    pub config_dir: PathBuf,
    /// Remove the stale resources of dead bus nodes (`robotd doctor --clean`).
    pub clean: bool,
    /// Where a running robotd serves HTTP (`http.bind`): its `/health` tells how its Redis edge
    /// is doing.
    pub http_bind: Option<String>,
}

/// Outcome of one check.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Status {
    /// Works.
    Ok,
    /// Works, but degraded or worth a look; does not fail `robotd doctor`.
    Warn,
    /// Something robotd needs or was configured to use does not work.
    Problem,
}

impl Status {
    /// Lower-case name, as printed in the table and the JSON.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Warn => "warn",
            Status::Problem => "problem",
        }
    }
}

/// One row of the report.
#[derive(Debug, Clone)]
pub struct Check {
    /// Short, stable identifier: `shm`, `iceoryx2`, `redis`, `espeak-ng`, `audio`, `llm-keys`.
    pub name: &'static str,
    /// How it went.
    pub status: Status,
    /// What the doctor found, in words (never a secret).
    pub found: String,
    /// What to do about it; set for every row that is not `ok`.
    pub fix: Option<String>,
}

impl Check {
    fn ok(name: &'static str, found: impl Into<String>) -> Self {
        Self {
            name,
            status: Status::Ok,
            found: found.into(),
            fix: None,
        }
    }

    fn warn(name: &'static str, found: impl Into<String>, fix: impl Into<String>) -> Self {
        Self {
            name,
            status: Status::Warn,
            found: found.into(),
            fix: Some(fix.into()),
        }
    }

    fn problem(name: &'static str, found: impl Into<String>, fix: impl Into<String>) -> Self {
        Self {
            name,
            status: Status::Problem,
            found: found.into(),
            fix: Some(fix.into()),
        }
    }
}

/// The result of `robotd doctor`: one [`Check`] per row.
#[derive(Debug, Clone)]
pub struct DoctorReport {
    /// The rows, in the order they were checked.
    pub checks: Vec<Check>,
}

impl DoctorReport {
    /// True when at least one row is a problem (warnings do not count).
    pub fn has_problems(&self) -> bool {
        self.checks.iter().any(|c| c.status == Status::Problem)
    }

    fn count(&self, status: Status) -> usize {
        self.checks.iter().filter(|c| c.status == status).count()
    }

    /// The report as a plain-text table for a terminal, fixes under their rows, and a summary
    /// line at the end.
    pub fn render_table(&self) -> String {
        let name_width = self
            .checks
            .iter()
            .map(|c| c.name.len())
            .chain(std::iter::once("CHECK".len()))
            .max()
            .unwrap_or(5);
        let status_width = "PROBLEM".len();
        let indent = " ".repeat(status_width + 2 + name_width + 2);
        let mut out = format!(
            "{:<status_width$}  {:<name_width$}  FOUND\n",
            "STATUS", "CHECK"
        );
        for check in &self.checks {
            let status = match check.status {
                Status::Ok => "ok",
                Status::Warn => "warn",
                Status::Problem => "PROBLEM",
            };
            out.push_str(&format!(
                "{status:<status_width$}  {:<name_width$}  {}\n",
                check.name, check.found
            ));
            if let Some(fix) = &check.fix {
                out.push_str(&format!("{indent}fix: {fix}\n"));
            }
        }
        let problems = self.count(Status::Problem);
        let warnings = self.count(Status::Warn);
        out.push('\n');
        out.push_str(&format!(
            "{} checks: {} ok, {} {}, {} {}\n",
            self.checks.len(),
            self.count(Status::Ok),
            warnings,
            if warnings == 1 { "warning" } else { "warnings" },
            problems,
            if problems == 1 { "problem" } else { "problems" },
        ));
        out
    }

    /// The report as JSON:
    /// `{"ok": bool, "summary": {"ok": n, "warn": n, "problem": n},
    ///   "checks": [{"name", "status", "found", "fix"}]}`; `ok` is false when there are problems.
    pub fn to_json(&self) -> Value {
        let checks: Vec<Value> = self
            .checks
            .iter()
            .map(|c| {
                json!({
                    "name": c.name,
                    "status": c.status.as_str(),
                    "found": c.found,
                    "fix": c.fix,
                })
            })
            .collect();
        json!({
            "ok": !self.has_problems(),
            "summary": {
                "ok": self.count(Status::Ok),
                "warn": self.count(Status::Warn),
                "problem": self.count(Status::Problem),
            },
            "checks": checks,
        })
    }
}

/// Runs every check and returns the report. Takes a few seconds at most, whatever the network
/// does. With `opts.clean`, removes the resources of dead bus nodes.
pub fn run(opts: &DoctorOptions) -> Result<DoctorReport> {
    let secrets = Secrets::load(&opts.config_dir);
    let env = |key: &str| std::env::var(key).ok().filter(|v| !v.trim().is_empty());
    let checks = vec![
        check_shm(Path::new("/dev/shm")),
        check_bus(Config::global_config(), &opts.bus_namespace, opts.clean),
        check_redis(opts.redis_url.as_deref(), &env, &secrets),
        check_redis_edge(opts.http_bind.as_deref()),
        check_espeak(env("PATH").as_deref()),
        check_audio(Path::new("/dev/snd"), &env),
        check_llm_keys(&env, &secrets, &ollama_reachable),
    ];
    Ok(DoctorReport { checks })
}

// ---------------------------------------------------------------------------------------------
// /dev/shm

fn check_shm(dir: &Path) -> Check {
    const NAME: &str = "shm";
    let shown = dir.display();
    if !dir.is_dir() {
        return Check::problem(
            NAME,
            format!("{shown} does not exist; the iceoryx2 bus needs shared memory there"),
            format!("mount -t tmpfs -o size=1G tmpfs {shown} (in Docker: run with --shm-size=1g)"),
        );
    }
    let probe = dir.join(format!(
        ".robotd-doctor-{}-{}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or_default()
    ));
    let writable = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .and_then(|mut f| f.write_all(b"robotd"));
    let _ = std::fs::remove_file(&probe);
    if let Err(e) = writable {
        return Check::problem(
            NAME,
            format!("{shown} is not writable ({e})"),
            format!("chmod 1777 {shown}, or run robotd as a user that may write there"),
        );
    }
    let (total, free) = match fs_space(dir) {
        Ok(v) => v,
        Err(e) => {
            return Check::warn(
                NAME,
                format!("{shown} is writable, but its size is unknown (statvfs: {e})"),
                format!("check `df -h {shown}`; robotd needs at least 256 MiB free there"),
            )
        }
    };
    let found = format!(
        "{shown}: {} total, {} free, writable",
        human_bytes(total),
        human_bytes(free)
    );
    if free < SHM_MIN_FREE {
        Check::warn(
            NAME,
            format!(
                "{found}; less than 256 MiB free (a frame buffer set needs ~10 MiB per subscriber)"
            ),
            format!("mount -o remount,size=1G {shown} (in Docker: run with --shm-size=1g)"),
        )
    } else {
        Check::ok(NAME, found)
    }
}

/// Total and available bytes of the file system holding `dir`.
fn fs_space(dir: &Path) -> std::io::Result<(u64, u64)> {
    use std::os::unix::ffi::OsStrExt;
    let c_path = std::ffi::CString::new(dir.as_os_str().as_bytes())
        .map_err(|e| std::io::Error::new(ErrorKind::InvalidInput, e))?;
    // SAFETY: `statvfs` is plain old data, so all-zero is a valid value; `c_path` is a valid
    // NUL-terminated string and `st` a valid, writable statvfs for the duration of the call.
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    let rc = unsafe { libc::statvfs(c_path.as_ptr(), &mut st) };
    if rc != 0 {
        return Err(std::io::Error::last_os_error());
    }
    #[allow(clippy::unnecessary_cast)] // the field types differ between platforms
    let (frsize, blocks, avail) = (st.f_frsize as u64, st.f_blocks as u64, st.f_bavail as u64);
    Ok((blocks.saturating_mul(frsize), avail.saturating_mul(frsize)))
}

fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

// ---------------------------------------------------------------------------------------------
// iceoryx2 nodes and services

/// Same rule as the runtime's bus: 1-64 characters from A-Z, a-z, 0-9, '_' and '-'.
fn valid_namespace(namespace: &str) -> bool {
    !namespace.is_empty()
        && namespace.len() <= 64
        && namespace
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

fn describe_node(details: &Option<iceoryx2::node::NodeDetails>) -> String {
    match details {
        Some(d) if !d.name().as_str().is_empty() => {
            format!("'{}' pid {}", d.name().as_str(), d.process_id())
        }
        Some(d) => format!("pid {}", d.process_id()),
        None => "unknown".to_owned(),
    }
}

// The bus itself uses `ipc_threadsafe::Service`; it shares every file (node monitors, node
// details, service storage) with `ipc::Service`, so listing and cleaning with `ipc::Service`
// sees and removes the same resources.
fn check_bus(config: &Config, namespace: &str, clean: bool) -> Check {
    const NAME: &str = "iceoryx2";
    if !valid_namespace(namespace) {
        return Check::problem(
            NAME,
            format!("bus namespace '{namespace}' is not valid; robotd would refuse to start"),
            "use 1-64 characters from A-Z, a-z, 0-9, '_' and '-' for the bus namespace",
        );
    }

    let mut alive = 0usize;
    let mut dead = Vec::new();
    let mut inaccessible = 0usize;
    let mut undefined = 0usize;
    let listed = Node::<ipc::Service>::list(config, |state| {
        match state {
            NodeState::Alive(_) => alive += 1,
            NodeState::Dead(view) => dead.push(view),
            NodeState::Inaccessible(_) => inaccessible += 1,
            NodeState::Undefined(_) => undefined += 1,
        }
        CallbackProgression::Continue
    });
    if let Err(e) = listed {
        return Check::warn(
            NAME,
            format!("could not list iceoryx2 nodes ({e})"),
            "run `robotd doctor` as the user that runs robotd (or as root)",
        );
    }

    let prefix = format!("{namespace}/");
    let mut services = 0usize;
    let services_listed = ipc::Service::list(config, |details| {
        if details.static_details.name().as_str().starts_with(&prefix) {
            services += 1;
        }
        CallbackProgression::Continue
    });
    let services_text = match services_listed {
        Ok(()) => format!("{services} services in namespace '{namespace}'"),
        Err(e) => format!("services not listed ({e:?})"),
    };

    let dead_names: Vec<String> = dead
        .iter()
        .take(5)
        .map(|v| describe_node(v.details()))
        .collect();
    let dead_text = if dead.is_empty() {
        "0 dead".to_owned()
    } else {
        let more = if dead.len() > dead_names.len() {
            ", ..."
        } else {
            ""
        };
        format!("{} dead ({}{more})", dead.len(), dead_names.join(", "))
    };

    let mut notes = Vec::new();
    let mut status = Status::Ok;
    let mut fixes = Vec::new();

    if clean && !dead.is_empty() {
        let total = dead.len();
        let mut removed = 0usize;
        let mut failures = Vec::new();
        for view in dead {
            match view.try_remove_stale_resources() {
                Ok(()) | Err(iceoryx2::node::NodeCleanupFailure::ResourcesAlreadyCleanedUp) => {
                    removed += 1
                }
                Err(e) => failures.push(format!("{e:?}")),
            }
        }
        notes.push(format!(
            "nodes: {alive} live, {total} dead, removed the resources of {removed}"
        ));
        if !failures.is_empty() {
            status = Status::Problem;
            notes.push(format!(
                "{} could not be removed ({})",
                failures.len(),
                failures.join(", ")
            ));
            fixes.push(
                "run `robotd doctor --clean` as the user that owns them (or as root), \
                 with no other process cleaning at the same time"
                    .to_owned(),
            );
        }
    } else {
        notes.push(format!("nodes: {alive} live, {dead_text}"));
        if !dead.is_empty() {
            status = Status::Warn;
            fixes.push("robotd cleans them at start; or run `robotd doctor --clean`".to_owned());
        }
    }
    if inaccessible > 0 {
        status = status.max(Status::Warn);
        notes.push(format!(
            "{inaccessible} nodes not accessible (another user's processes)"
        ));
        fixes.push("run `robotd doctor` as that user (or as root) to inspect or clean them".into());
    }
    if undefined > 0 {
        status = status.max(Status::Warn);
        notes.push(format!(
            "{undefined} nodes in an undefined state (damaged files)"
        ));
        fixes.push(format!(
            "stop every iceoryx2 process, then remove {}* and /dev/shm/{}*",
            config.global.root_path(),
            config.global.prefix
        ));
    }
    notes.push(services_text);

    Check {
        name: NAME,
        status,
        found: notes.join("; "),
        fix: if fixes.is_empty() {
            None
        } else {
            Some(fixes.join("; "))
        },
    }
}

// ---------------------------------------------------------------------------------------------
// secrets.env

/// Variables read from `secrets.env` in the config directory (dotenv format).
#[derive(Debug, Default)]
struct Secrets {
    path: PathBuf,
    vars: BTreeMap<String, String>,
    /// The file exists but could not be read.
    error: Option<String>,
    /// The file can be read by other users.
    world_readable: bool,
}

impl Secrets {
    fn load(config_dir: &Path) -> Self {
        let path = config_dir.join(SECRETS_FILE);
        let mut secrets = Secrets {
            path: path.clone(),
            ..Default::default()
        };
        match std::fs::read_to_string(&path) {
            Ok(text) => {
                secrets.vars = parse_dotenv(&text);
                if let Ok(meta) = std::fs::metadata(&path) {
                    use std::os::unix::fs::PermissionsExt;
                    secrets.world_readable = meta.permissions().mode() & 0o004 != 0;
                }
            }
            Err(e) if e.kind() == ErrorKind::NotFound => {}
            Err(e) => secrets.error = Some(e.to_string()),
        }
        secrets
    }

    fn get(&self, key: &str) -> Option<&str> {
        self.vars
            .get(key)
            .map(String::as_str)
            .filter(|v| !v.trim().is_empty())
    }
}

/// Parses dotenv text: `KEY=VALUE` lines, `#` comments, optional `export `, optional single or
/// double quotes (double quotes understand `\n`, `\"` and `\\`), and `# comment` after an
/// unquoted value. Lines that are not assignments are skipped.
fn parse_dotenv(text: &str) -> BTreeMap<String, String> {
    let mut vars = BTreeMap::new();
    for line in text.lines() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let line = line
            .strip_prefix("export ")
            .map(str::trim_start)
            .unwrap_or(line);
        let Some((key, value)) = line.split_once('=') else {
            continue;
        };
        let key = key.trim();
        if key.is_empty()
            || key.starts_with(|c: char| c.is_ascii_digit())
            || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        {
            continue;
        }
        let value = value.trim();
        let value = if let Some(rest) = value.strip_prefix('"') {
            let mut out = String::new();
            let mut chars = rest.chars();
            while let Some(c) = chars.next() {
                match c {
                    '"' => break,
                    '\\' => match chars.next() {
                        Some('n') => out.push('\n'),
                        Some(other) => out.push(other),
                        None => out.push('\\'),
                    },
                    c => out.push(c),
                }
            }
            out
        } else if let Some(rest) = value.strip_prefix('\'') {
            rest.split('\'').next().unwrap_or_default().to_owned()
        } else {
            let end = value.find(" #").or_else(|| value.find("\t#"));
            value[..end.unwrap_or(value.len())].trim_end().to_owned()
        };
        vars.insert(key.to_owned(), value);
    }
    vars
}

// ---------------------------------------------------------------------------------------------
// Redis

/// Where the Redis check connects to. Holds the password, so it has no `Debug`/`Display`.
struct RedisTarget {
    host: String,
    port: u16,
    db: u32,
    username: Option<String>,
    password: Option<String>,
    tls: bool,
    source: &'static str,
}

impl RedisTarget {
    /// `host:port` for messages (IPv6 hosts in brackets); never contains the password.
    fn addr(&self) -> String {
        if self.host.contains(':') {
            format!("[{}]:{}", self.host, self.port)
        } else {
            format!("{}:{}", self.host, self.port)
        }
    }
}

fn percent_decode(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            let hex = |b: u8| (b as char).to_digit(16);
            if let (Some(hi), Some(lo)) = (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                out.push((hi * 16 + lo) as u8);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Parses `redis://[[user]:password@]host[:port][/db]` (or `rediss://`, or a bare `host[:port]`).
/// Errors never contain the password.
fn parse_redis_url(url: &str) -> std::result::Result<RedisTarget, String> {
    let url = url.trim();
    let (tls, rest) = if let Some(rest) = url.strip_prefix("redis://") {
        (false, rest)
    } else if let Some(rest) = url.strip_prefix("rediss://") {
        (true, rest)
    } else if let Some((scheme, _)) = url.split_once("://") {
        return Err(format!(
            "unsupported scheme '{scheme}://' (expected redis:// or rediss://)"
        ));
    } else {
        (false, url)
    };
    let (authority, path) = match rest.split_once('/') {
        Some((a, p)) => (a, p),
        None => (rest, ""),
    };
    let (userinfo, hostport) = match authority.rsplit_once('@') {
        Some((u, h)) => (Some(u), h),
        None => (None, authority),
    };
    let (username, password) = match userinfo {
        None => (None, None),
        Some(u) => match u.split_once(':') {
            Some((user, pass)) => (
                Some(percent_decode(user)).filter(|u| !u.is_empty()),
                Some(percent_decode(pass)).filter(|p| !p.is_empty()),
            ),
            None => (None, Some(percent_decode(u)).filter(|p| !p.is_empty())),
        },
    };
    let (host, port) = if let Some(v6) = hostport.strip_prefix('[') {
        let (host, after) = v6
            .split_once(']')
            .ok_or_else(|| "unclosed '[' in the host".to_owned())?;
        (host, after.strip_prefix(':'))
    } else {
        match hostport.rsplit_once(':') {
            Some((h, p)) => (h, Some(p)),
            None => (hostport, None),
        }
    };
    let host = if host.is_empty() { "localhost" } else { host };
    let port = match port {
        None | Some("") => 6379,
        Some(p) => p
            .parse::<u16>()
            .ok()
            .filter(|p| *p != 0)
            .ok_or_else(|| format!("port '{p}' is not a number from 1 to 65535"))?,
    };
    let db_text = path.split(['?', '#']).next().unwrap_or("");
    let db = if db_text.is_empty() {
        0
    } else {
        db_text
            .parse::<u32>()
            .map_err(|_| format!("database '{db_text}' is not a number"))?
    };
    Ok(RedisTarget {
        host: host.to_owned(),
        port,
        db,
        username,
        password,
        tls,
        source: "",
    })
}

type EnvFn<'a> = &'a dyn Fn(&str) -> Option<String>;

/// Where the Redis edge would connect: the URL option first, then `REDIS_HOST`/`REDIS_PORT`.
/// `Ok(None)` when neither is configured.
fn redis_target(
    url: Option<&str>,
    env: EnvFn,
    secrets: &Secrets,
) -> std::result::Result<Option<RedisTarget>, String> {
    let mut target = if let Some(url) = url.filter(|u| !u.trim().is_empty()) {
        let mut t = parse_redis_url(url).map_err(|e| format!("Redis URL is not valid: {e}"))?;
        t.source = "--redis";
        t
    } else {
        let host = env("REDIS_HOST");
        let port = env("REDIS_PORT");
        if host.is_none() && port.is_none() {
            return Ok(None);
        }
        let port = match port {
            None => 6379,
            Some(p) => p
                .trim()
                .parse::<u16>()
                .ok()
                .filter(|p| *p != 0)
                .ok_or_else(|| format!("REDIS_PORT '{p}' is not a number from 1 to 65535"))?,
        };
        let db = match env("REDIS_DB") {
            None => 0,
            Some(d) => d
                .trim()
                .parse::<u32>()
                .map_err(|_| format!("REDIS_DB '{d}' is not a number"))?,
        };
        RedisTarget {
            host: host
                .unwrap_or_else(|| "localhost".to_owned())
                .trim()
                .to_owned(),
            port,
            db,
            username: None,
            password: None,
            tls: false,
            source: "REDIS_HOST/REDIS_PORT",
        }
    };
    if target.password.is_none() {
        target.password =
            env("REDIS_PASSWORD").or_else(|| secrets.get("REDIS_PASSWORD").map(str::to_owned));
    }
    Ok(Some(target))
}

/// Resolves `host:port`, giving up after `timeout` (name resolution itself cannot be given a
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

/// Encodes a command as a RESP array of bulk strings.
fn resp_command(args: &[&str]) -> Vec<u8> {
    let mut out = format!("*{}\r\n", args.len()).into_bytes();
    for arg in args {
        out.extend_from_slice(format!("${}\r\n", arg.len()).as_bytes());
        out.extend_from_slice(arg.as_bytes());
        out.extend_from_slice(b"\r\n");
    }
    out
}

/// Reads one RESP line (up to CRLF, at most 512 bytes) within the stream's read timeout.
fn read_line(stream: &mut TcpStream) -> std::io::Result<String> {
    let mut line = Vec::new();
    let mut byte = [0u8; 1];
    let deadline = Instant::now() + NET_TIMEOUT;
    while line.len() < 512 {
        if Instant::now() > deadline {
            return Err(std::io::Error::new(
                ErrorKind::TimedOut,
                "no complete reply",
            ));
        }
        match stream.read(&mut byte) {
            Ok(0) => {
                return Err(std::io::Error::new(
                    ErrorKind::UnexpectedEof,
                    "the server closed the connection",
                ))
            }
            Ok(_) => {
                if byte[0] == b'\n' {
                    break;
                }
                line.push(byte[0]);
            }
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    if line.last() == Some(&b'\r') {
        line.pop();
    }
    Ok(String::from_utf8_lossy(&line).into_owned())
}

/// The Redis edge of a robotd serving on `bind`, from its `/health`.
fn check_redis_edge(bind: Option<&str>) -> Check {
    const NAME: &str = "redis-edge";
    let Some(bind) = bind else {
        return Check::ok(NAME, "no HTTP address configured; nothing to ask");
    };
    let health = match fetch_health(bind) {
        Ok(health) => health,
        Err(_) => {
            return Check::ok(
                NAME,
                format!("no robotd answers on {bind}; start it to see its Redis edge here"),
            )
        }
    };
    let redis = &health["redis"];
    let state = redis["state"].as_str().unwrap_or("off");
    let target = redis["target"].as_str().unwrap_or("?");
    let sum = |prefix: &str| -> u64 {
        redis["streams"]
            .as_object()
            .map(|streams| {
                streams
                    .values()
                    .filter_map(|counts| counts.as_object())
                    .flat_map(|counts| counts.iter())
                    .filter(|(k, _)| k.starts_with(prefix))
                    .filter_map(|(_, v)| v.as_u64())
                    .sum()
            })
            .unwrap_or(0)
    };
    let counts = format!(
        "{} entries published, {} dropped, {} consumed, {} skipped as bad",
        sum("published"),
        sum("dropped_"),
        sum("consumed"),
        sum("skipped_")
    );
    match state {
        "connected" => Check::ok(
            NAME,
            format!(
                "the robotd on {bind} is connected to {target} (trust {}; {counts})",
                redis["trust"].as_str().unwrap_or("?")
            ),
        ),
        "off" => Check::ok(
            NAME,
            format!("the robotd on {bind} runs without a Redis edge"),
        ),
        _ => Check::problem(
            NAME,
            format!(
                "the robotd on {bind} cannot reach {target} ({state}: {}); {counts}",
                redis["last_error"].as_str().unwrap_or("no error recorded")
            ),
            "start redis-server or correct the URL; robotd reconnects by itself within a second",
        ),
    }
}

/// `GET /health` of the robotd serving on `bind` (plain HTTP/1.1, bounded by the timeouts).
fn fetch_health(bind: &str) -> std::io::Result<serde_json::Value> {
    let addrs: Vec<SocketAddr> = bind.to_socket_addrs()?.collect();
    let mut stream = connect(&addrs, NET_TIMEOUT)?;
    stream.set_read_timeout(Some(NET_TIMEOUT))?;
    stream.set_write_timeout(Some(NET_TIMEOUT))?;
    write!(
        stream,
        "GET /health HTTP/1.1\r\nHost: {bind}\r\nConnection: close\r\n\r\n"
    )?;
    let mut response = Vec::new();
    let _ = stream.take(1 << 20).read_to_end(&mut response);
    let text = String::from_utf8_lossy(&response);
    let body = text.split_once("\r\n\r\n").map(|(_, b)| b).unwrap_or("");
    serde_json::from_str(body).map_err(|e| std::io::Error::new(ErrorKind::InvalidData, e))
}

/// What a Redis server said to AUTH (if a password is known) and PING.
#[derive(Debug, PartialEq, Eq)]
enum PingOutcome {
    Pong,
    /// The server wants a password and none was given.
    NoAuth,
    /// The password (or user) was rejected.
    AuthRejected,
    /// Redis refuses this client (protected mode: no password and not on loopback).
    Denied,
    /// Reachable by TCP, but TLS (`rediss://`) keeps the doctor from speaking RESP.
    TlsReachable,
    /// Connected, but the reply was not what Redis says (or none came).
    Unexpected(String),
    /// Could not resolve or connect.
    Unreachable(String),
}

fn redis_ping(target: &RedisTarget) -> PingOutcome {
    let addrs = match resolve(&target.host, target.port, NET_TIMEOUT) {
        Ok(a) => a,
        Err(e) => {
            return PingOutcome::Unreachable(format!("cannot resolve '{}': {e}", target.host))
        }
    };
    let mut stream = match connect(&addrs, NET_TIMEOUT) {
        Ok(s) => s,
        Err(e) => {
            return PingOutcome::Unreachable(format!("cannot connect to {}: {e}", target.addr()))
        }
    };
    if target.tls {
        return PingOutcome::TlsReachable;
    }
    if stream.set_read_timeout(Some(NET_TIMEOUT)).is_err()
        || stream.set_write_timeout(Some(NET_TIMEOUT)).is_err()
    {
        return PingOutcome::Unexpected("could not set socket timeouts".into());
    }
    let exchange = |stream: &mut TcpStream, cmd: &[&str]| -> std::result::Result<String, String> {
        stream
            .write_all(&resp_command(cmd))
            .map_err(|e| format!("sending {} failed: {e}", cmd[0]))?;
        read_line(stream).map_err(|e| {
            format!(
                "no reply to {} within {} ms ({e})",
                cmd[0],
                NET_TIMEOUT.as_millis()
            )
        })
    };
    if let Some(password) = &target.password {
        let reply = match &target.username {
            Some(user) => exchange(&mut stream, &["AUTH", user, password]),
            None => exchange(&mut stream, &["AUTH", password]),
        };
        match reply {
            Ok(r) if r.starts_with("+OK") => {}
            Ok(r)
                if r.starts_with("-WRONGPASS")
                    || r.contains("invalid password")
                    || r.contains("invalid username") =>
            {
                return PingOutcome::AuthRejected
            }
            // Redis without a password answers AUTH with an error; PING tells the rest.
            Ok(r) if r.starts_with('-') => {}
            Ok(r) => {
                return PingOutcome::Unexpected(format!(
                    "unexpected reply to AUTH: {}",
                    first_chars(&r)
                ))
            }
            Err(e) => return PingOutcome::Unexpected(e),
        }
    }
    match exchange(&mut stream, &["PING"]) {
        Ok(r) if r == "+PONG" => PingOutcome::Pong,
        Ok(r) if r.starts_with("-NOAUTH") => PingOutcome::NoAuth,
        Ok(r) if r.starts_with("-DENIED") => PingOutcome::Denied,
        Ok(r) if r.starts_with("-WRONGPASS") => PingOutcome::AuthRejected,
        Ok(r) => PingOutcome::Unexpected(format!("unexpected reply to PING: {}", first_chars(&r))),
        Err(e) => PingOutcome::Unexpected(e),
    }
}

fn first_chars(s: &str) -> String {
    let mut out: String = s.chars().take(80).collect();
    if s.chars().count() > 80 {
        out.push('…');
    }
    out
}

const REDIS_START_FIX: &str =
    "start Redis: `apt-get install redis-server && redis-server --daemonize yes`, \
     or set REDIS_HOST/REDIS_PORT (or --redis redis://host:port) to where it runs";

fn check_redis(url: Option<&str>, env: EnvFn, secrets: &Secrets) -> Check {
    const NAME: &str = "redis";
    let target = match redis_target(url, env, secrets) {
        Ok(Some(t)) => t,
        Ok(None) => {
            return Check::ok(
                NAME,
                "not configured (Redis edge off); set REDIS_HOST/REDIS_PORT or --redis to use it",
            )
        }
        Err(e) => {
            return Check::problem(
                NAME,
                e,
                "use --redis redis://[:password@]host[:port][/db], or REDIS_HOST and a numeric REDIS_PORT",
            )
        }
    };
    let addr = target.addr();
    let from = target.source;
    let db = if target.db == 0 {
        String::new()
    } else {
        format!(", db {}", target.db)
    };
    match redis_ping(&target) {
        PingOutcome::Pong => Check::ok(
            NAME,
            format!("{addr} answers PONG (from {from}{db}{})", if target.password.is_some() { ", password set" } else { "" }),
        ),
        PingOutcome::TlsReachable => Check::ok(
            NAME,
            format!("{addr} accepts connections (TLS, rediss://; PING not checked; from {from})"),
        ),
        PingOutcome::NoAuth => Check::warn(
            NAME,
            format!("{addr} is up but requires a password (from {from})"),
            format!(
                "set REDIS_PASSWORD (environment or {SECRETS_FILE} in the config directory), \
                 or put it in the URL: redis://:PASSWORD@{addr}"
            ),
        ),
        PingOutcome::Denied => Check::problem(
            NAME,
            format!("{addr} is Redis but refuses this client (protected mode) (from {from})"),
            "on the Redis host set a password (`requirepass`, then REDIS_PASSWORD here) or \
             `protected-mode no` with a `bind` limited to trusted networks",
        ),
        PingOutcome::AuthRejected => Check::warn(
            NAME,
            format!("{addr} is up but rejected the password (from {from})"),
            format!(
                "check REDIS_PASSWORD (environment or {SECRETS_FILE}) or the password in the \
                 Redis URL against the server's requirepass/ACL"
            ),
        ),
        PingOutcome::Unexpected(why) => Check::problem(
            NAME,
            format!("something listens on {addr} but it does not answer like Redis: {why} (from {from})"),
            format!("check that {addr} is a Redis server; {REDIS_START_FIX}"),
        ),
        PingOutcome::Unreachable(why) => Check::problem(
            NAME,
            format!("{why} (from {from})"),
            REDIS_START_FIX,
        ),
    }
}

// ---------------------------------------------------------------------------------------------
// espeak-ng

fn find_on_path(program: &str, path_var: Option<&str>) -> Option<PathBuf> {
    use std::os::unix::fs::PermissionsExt;
    let path_var = path_var?;
    std::env::split_paths(path_var)
        .map(|dir| dir.join(program))
        .find(|candidate| {
            std::fs::metadata(candidate)
                .map(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
                .unwrap_or(false)
        })
}

/// Runs `program args`, killing it if it takes longer than `timeout`; returns its stdout.
fn run_bounded(
    program: &Path,
    args: &[&str],
    timeout: Duration,
) -> std::result::Result<String, String> {
    let mut child = Command::new(program)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| format!("could not start: {e}"))?;
    let deadline = Instant::now() + timeout;
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(10)),
            Ok(None) => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(format!("no answer within {} s", timeout.as_secs()));
            }
            Err(e) => return Err(format!("could not wait for it: {e}")),
        }
    };
    let mut out = String::new();
    if let Some(mut stdout) = child.stdout.take() {
        let _ = stdout.read_to_string(&mut out);
    }
    if status.success() {
        Ok(out)
    } else {
        Err(format!("exited with {status}"))
    }
}

fn check_espeak(path_var: Option<&str>) -> Check {
    const NAME: &str = "espeak-ng";
    const FIX: &str = "apt-get install espeak-ng";
    let Some(path) = find_on_path("espeak-ng", path_var) else {
        return Check::problem(
            NAME,
            "espeak-ng not found on PATH; robotd cannot speak",
            FIX,
        );
    };
    match run_bounded(&path, &["--version"], PROGRAM_TIMEOUT) {
        Ok(out) => {
            // "eSpeak NG text-to-speech: 1.51  Data at: /usr/lib/..."
            let version = out
                .split_once(':')
                .and_then(|(_, rest)| rest.split_whitespace().next())
                .unwrap_or("(unknown version)");
            Check::ok(NAME, format!("espeak-ng {version} at {}", path.display()))
        }
        Err(e) => Check::problem(
            NAME,
            format!("{} --version failed: {e}", path.display()),
            format!("reinstall it: apt-get install --reinstall espeak-ng ({FIX})"),
        ),
    }
}

// ---------------------------------------------------------------------------------------------
// audio output

fn check_audio(snd_dir: &Path, env: EnvFn) -> Check {
    const NAME: &str = "audio";
    let mut outputs = Vec::new();

    let mut pcms: Vec<String> = std::fs::read_dir(snd_dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.starts_with("pcm") && n.ends_with('p'))
                .collect()
        })
        .unwrap_or_default();
    pcms.sort();
    if !pcms.is_empty() {
        outputs.push(format!(
            "{} playback device(s) in {} ({})",
            pcms.len(),
            snd_dir.display(),
            pcms.join(", ")
        ));
    }
    if let Some(server) = env("PULSE_SERVER") {
        outputs.push(format!("PULSE_SERVER={server}"));
    }
    let mut sockets = Vec::new();
    if let Some(runtime) = env("XDG_RUNTIME_DIR") {
        sockets.push(PathBuf::from(&runtime).join("pulse/native"));
        sockets.push(PathBuf::from(&runtime).join("pipewire-0"));
    }
    // SAFETY: getuid cannot fail and has no preconditions.
    let uid = unsafe { libc::getuid() };
    sockets.push(PathBuf::from(format!("/run/user/{uid}/pulse/native")));
    sockets.push(PathBuf::from("/run/pulse/native"));
    sockets.push(PathBuf::from("/var/run/pulse/native"));
    if let Some(socket) = sockets.iter().find(|s| s.exists()) {
        outputs.push(format!("sound server socket {}", socket.display()));
    }

    if outputs.is_empty() {
        Check::warn(
            NAME,
            format!(
                "no audio output (no {}/pcm*p device, no PULSE_SERVER, no PulseAudio/PipeWire \
                 socket); speech will be written as WAV files to the spool directory",
                snd_dir.display()
            ),
            "attach a sound card (in a container: pass --device /dev/snd), or set PULSE_SERVER \
             to a running PulseAudio server (e.g. unix:/run/user/1000/pulse/native)",
        )
    } else {
        Check::ok(NAME, outputs.join("; "))
    }
}

// ---------------------------------------------------------------------------------------------
// LLM provider keys

/// Is an Ollama server listening at `host` (an `OLLAMA_HOST` value)? Bounded by a short
/// connect timeout.
fn ollama_reachable(host: &str) -> bool {
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
    match resolve(h, port, Duration::from_millis(300)) {
        Ok(addrs) => connect(&addrs, Duration::from_millis(300)).is_ok(),
        Err(_) => false,
    }
}

fn check_llm_keys(env: EnvFn, secrets: &Secrets, ollama_probe: &dyn Fn(&str) -> bool) -> Check {
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

// ---------------------------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;
    use std::process::Child;

    fn env_from(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let map: BTreeMap<String, String> = pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        move |key: &str| map.get(key).cloned().filter(|v| !v.trim().is_empty())
    }

    fn no_secrets() -> Secrets {
        Secrets {
            path: PathBuf::from("/nonexistent/secrets.env"),
            ..Default::default()
        }
    }

    fn free_port() -> u16 {
        TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .map(|a| a.port())
            .expect("bind an ephemeral port")
    }

    fn temp_dir(tag: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "robotd-doctor-{tag}-{}-{:?}",
            std::process::id(),
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap_or_default()
                .as_nanos()
        ));
        std::fs::create_dir_all(&dir).expect("create temp dir");
        dir
    }

    /// A redis-server on a free port, killed on drop. `None` when redis-server is not installed.
    struct RedisServer {
        child: Child,
        port: u16,
    }

    impl RedisServer {
        fn start(extra: &[&str]) -> Option<Self> {
            let path = std::env::var("PATH").ok();
            if find_on_path("redis-server", path.as_deref()).is_none() {
                eprintln!("SKIPPED: redis-server is not installed (scripts/test.sh installs it)");
                return None;
            }
            let port = free_port();
            let port_text = port.to_string();
            let mut args = vec![
                "--port",
                &port_text,
                "--bind",
                "127.0.0.1",
                "--save",
                "",
                "--appendonly",
                "no",
            ];
            args.extend_from_slice(extra);
            let child = Command::new("redis-server")
                .args(&args)
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .expect("start redis-server");
            let server = RedisServer { child, port };
            let deadline = Instant::now() + Duration::from_secs(10);
            while TcpStream::connect(("127.0.0.1", port)).is_err() {
                assert!(
                    Instant::now() < deadline,
                    "redis-server did not start on {port}"
                );
                std::thread::sleep(Duration::from_millis(20));
            }
            Some(server)
        }
    }

    impl Drop for RedisServer {
        fn drop(&mut self) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }

    #[test]
    fn dotenv_parses_comments_quotes_and_export() {
        let text = "\
# a comment
OPENAI_API_KEY=sk-abc
  GROQ_API_KEY = gsk_def   # trailing comment
export GEMINI_API_KEY=\"AIza quoted # not a comment\"
SINGLE='it''s'
ESCAPED=\"a\\\"b\\nc\"
EMPTY=
not an assignment
1BAD=x
BAD-KEY=x
URL=http://host:1/x#frag
";
        let vars = parse_dotenv(text);
        assert_eq!(
            vars.get("OPENAI_API_KEY").map(String::as_str),
            Some("sk-abc")
        );
        assert_eq!(
            vars.get("GROQ_API_KEY").map(String::as_str),
            Some("gsk_def")
        );
        assert_eq!(
            vars.get("GEMINI_API_KEY").map(String::as_str),
            Some("AIza quoted # not a comment")
        );
        assert_eq!(vars.get("SINGLE").map(String::as_str), Some("it"));
        assert_eq!(vars.get("ESCAPED").map(String::as_str), Some("a\"b\nc"));
        assert_eq!(vars.get("EMPTY").map(String::as_str), Some(""));
        assert_eq!(
            vars.get("URL").map(String::as_str),
            Some("http://host:1/x#frag")
        );
        assert!(!vars.contains_key("1BAD"));
        assert!(!vars.contains_key("BAD-KEY"));
        assert_eq!(vars.len(), 7);
    }

    #[test]
    fn redis_urls_parse_without_leaking_passwords() {
        let t = parse_redis_url("redis://:s%40cret@10.0.0.5:6380/2").expect("valid");
        assert_eq!((t.host.as_str(), t.port, t.db), ("10.0.0.5", 6380, 2));
        assert_eq!(t.password.as_deref(), Some("s@cret"));
        assert_eq!(t.username, None);
        assert!(!t.addr().contains("cret"));

        let t = parse_redis_url("redis://user:pw@localhost").expect("valid");
        assert_eq!((t.host.as_str(), t.port), ("localhost", 6379));
        assert_eq!(t.username.as_deref(), Some("user"));

        let t = parse_redis_url("redis://[::1]:7000").expect("valid");
        assert_eq!((t.host.as_str(), t.port), ("::1", 7000));
        assert_eq!(t.addr(), "[::1]:7000");

        let t = parse_redis_url("127.0.0.1:7001").expect("bare host:port");
        assert_eq!(t.port, 7001);
        assert!(parse_redis_url("rediss://example.org").expect("tls").tls);

        let err = parse_redis_url("redis://:topsecret@host:99999")
            .err()
            .expect("bad port");
        assert!(!err.contains("topsecret"), "{err}");
        assert!(parse_redis_url("http://host").is_err());
        assert!(parse_redis_url("redis://host/x").is_err());
    }

    #[test]
    fn redis_unconfigured_is_ok_and_env_is_used() {
        let check = check_redis(None, &env_from(&[]), &no_secrets());
        assert_eq!(check.status, Status::Ok);
        assert!(check.found.contains("not configured"), "{}", check.found);

        let env = env_from(&[("REDIS_PORT", "not-a-port")]);
        assert_eq!(
            check_redis(None, &env, &no_secrets()).status,
            Status::Problem
        );

        let env = env_from(&[
            ("REDIS_HOST", "10.1.2.3"),
            ("REDIS_PORT", "6390"),
            ("REDIS_DB", "3"),
        ]);
        let t = redis_target(None, &env, &no_secrets())
            .expect("ok")
            .expect("configured");
        assert_eq!((t.host.as_str(), t.port, t.db), ("10.1.2.3", 6390, 3));
        assert_eq!(t.source, "REDIS_HOST/REDIS_PORT");

        // The option wins over the environment; REDIS_PASSWORD fills in a missing password.
        let env = env_from(&[("REDIS_HOST", "10.1.2.3"), ("REDIS_PASSWORD", "pw")]);
        let t = redis_target(Some("redis://127.0.0.1:1"), &env, &no_secrets())
            .expect("ok")
            .expect("configured");
        assert_eq!((t.host.as_str(), t.port), ("127.0.0.1", 1));
        assert_eq!(t.password.as_deref(), Some("pw"));
    }

    #[test]
    fn redis_closed_port_is_a_problem_quickly() {
        let port = free_port();
        let start = Instant::now();
        let check = check_redis(
            Some(&format!("redis://127.0.0.1:{port}")),
            &env_from(&[]),
            &no_secrets(),
        );
        assert_eq!(check.status, Status::Problem, "{check:?}");
        assert!(check.fix.as_deref().unwrap_or("").contains("redis-server"));
        assert!(start.elapsed() < Duration::from_secs(2));
    }

    #[test]
    fn redis_silent_server_is_bounded() {
        // Accepts the connection but never answers.
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let port = listener.local_addr().expect("addr").port();
        let holder = std::thread::spawn(move || {
            let conn = listener.accept();
            std::thread::sleep(Duration::from_secs(2));
            drop(conn);
        });
        let start = Instant::now();
        let check = check_redis(
            Some(&format!("redis://127.0.0.1:{port}")),
            &env_from(&[]),
            &no_secrets(),
        );
        assert_eq!(check.status, Status::Problem, "{check:?}");
        assert!(
            start.elapsed() < Duration::from_millis(1500),
            "{:?}",
            start.elapsed()
        );

        let _ = holder.join();
    }

    #[test]
    fn redis_real_server_pongs() {
        let Some(server) = RedisServer::start(&[]) else {
            return;
        };
        let url = format!("redis://127.0.0.1:{}", server.port);
        let check = check_redis(Some(&url), &env_from(&[]), &no_secrets());
        assert_eq!(check.status, Status::Ok, "{check:?}");
        assert!(check.found.contains("PONG"), "{}", check.found);

        // Through REDIS_HOST/REDIS_PORT as well.
        let port = server.port.to_string();
        let env = env_from(&[("REDIS_HOST", "localhost"), ("REDIS_PORT", &port)]);
        let check = check_redis(None, &env, &no_secrets());
        assert_eq!(check.status, Status::Ok, "{check:?}");
    }

    #[test]
    fn redis_with_password_noauth_wrongpass_and_ok() {
        let Some(server) = RedisServer::start(&["--requirepass", "hunter2-secret"]) else {
            return;
        };
        let port = server.port;
        let none = check_redis(
            Some(&format!("redis://127.0.0.1:{port}")),
            &env_from(&[]),
            &no_secrets(),
        );
        assert_eq!(none.status, Status::Warn, "{none:?}");
        assert!(none.fix.as_deref().unwrap_or("").contains("REDIS_PASSWORD"));

        let wrong = check_redis(
            Some(&format!("redis://:wrong@127.0.0.1:{port}")),
            &env_from(&[]),
            &no_secrets(),
        );
        assert_eq!(wrong.status, Status::Warn, "{wrong:?}");
        assert!(wrong.found.contains("rejected"), "{}", wrong.found);

        let secrets = Secrets {
            vars: parse_dotenv("REDIS_PASSWORD=hunter2-secret\n"),
            ..no_secrets()
        };
        let good = check_redis(
            Some(&format!("redis://127.0.0.1:{port}")),
            &env_from(&[]),
            &secrets,
        );
        assert_eq!(good.status, Status::Ok, "{good:?}");
        let report = DoctorReport {
            checks: vec![none, wrong, good],
        };
        assert!(!report.render_table().contains("hunter2"));
        assert!(!report.to_json().to_string().contains("hunter2"));
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

    #[test]
    fn shm_check_real_and_missing() {
        let check = check_shm(Path::new("/dev/shm"));
        if Path::new("/dev/shm").is_dir() {
            assert_ne!(check.status, Status::Problem, "{check:?}");
            assert!(check.found.contains("free"), "{}", check.found);
        }
        let missing = check_shm(Path::new("/nonexistent/shm"));
        assert_eq!(missing.status, Status::Problem);
        assert!(missing.fix.is_some());
        assert_eq!(human_bytes(512), "512 B");
        assert_eq!(human_bytes(3 * 1024 * 1024 * 1024 / 2), "1.5 GiB");
    }

    #[test]
    fn audio_devices_and_sockets() {
        let dir = temp_dir("snd");
        let env = env_from(&[("XDG_RUNTIME_DIR", "/nonexistent-runtime")]);
        let none = check_audio(&dir, &env);
        if none.status == Status::Warn {
            assert!(none.found.contains("WAV"), "{}", none.found);
        }
        std::fs::write(dir.join("pcmC0D0p"), b"").expect("fake device");
        std::fs::write(dir.join("pcmC0D0c"), b"").expect("fake capture device");
        let some = check_audio(&dir, &env);
        assert_eq!(some.status, Status::Ok);
        assert!(some.found.contains("pcmC0D0p") && !some.found.contains("pcmC0D0c"));
        let pulse = check_audio(
            Path::new("/nonexistent"),
            &env_from(&[("PULSE_SERVER", "tcp:host")]),
        );
        assert_eq!(pulse.status, Status::Ok);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn espeak_missing_is_a_problem() {
        let check = check_espeak(Some("/nonexistent"));
        assert_eq!(check.status, Status::Problem);
        assert_eq!(check.fix.as_deref(), Some("apt-get install espeak-ng"));
        let path = std::env::var("PATH").ok();
        if find_on_path("espeak-ng", path.as_deref()).is_some() {
            let check = check_espeak(path.as_deref());
            assert_eq!(check.status, Status::Ok, "{check:?}");
        }
    }

    #[test]
    fn bad_namespace_is_a_problem() {
        let check = check_bus(Config::global_config(), "has space", false);
        assert_eq!(check.status, Status::Problem);
    }

    /// An iceoryx2 config whose files do not meet anyone else's (own prefix).
    fn isolated_config(prefix: &str) -> Config {
        let mut config = Config::global_config().clone();
        config.global.prefix = FileName::new(prefix.as_bytes()).expect("valid prefix");
        config
    }

    const DIE_ENV: &str = "ROBOTD_DOCTOR_TEST_DIE_PREFIX";

    /// Helper run in a child process by `bus_dead_nodes_are_reported_and_cleaned`: creates a
    /// node and exits without cleaning up, as a crashed actor would. Does nothing otherwise.
    #[test]
    #[ignore = "helper: run by bus_dead_nodes_are_reported_and_cleaned in a child process"]
    fn bus_helper_create_node_and_die() {
        let Ok(prefix) = std::env::var(DIE_ENV) else {
            return;
        };
        let config = isolated_config(&prefix);
        let node = NodeBuilder::new()
            .name(&NodeName::new("doctor-test-dead").expect("name"))
            .config(&config)
            .create::<ipc::Service>()
            .expect("create node");
        let _service = node
            .service_builder(&ServiceName::new("doctortest/topic").expect("service name"))
            .publish_subscribe::<u64>()
            .open_or_create()
            .expect("service");
        std::mem::forget(node);
        // SAFETY: ends this helper process at once, skipping every destructor on purpose.
        unsafe { libc::_exit(0) };
    }

    /// Removes every file the isolated config left in /dev/shm and the iceoryx2 root directory.
    struct PrefixCleanup {
        prefix: String,
        root: PathBuf,
    }

    impl Drop for PrefixCleanup {
        fn drop(&mut self) {
            fn sweep(dir: &Path, prefix: &str, depth: u32) {
                let Ok(entries) = std::fs::read_dir(dir) else {
                    return;
                };
                for entry in entries.flatten() {
                    let path = entry.path();
                    if entry.file_name().to_string_lossy().starts_with(prefix) {
                        let _ = std::fs::remove_file(&path);
                        let _ = std::fs::remove_dir_all(&path);
                    } else if depth > 0 && path.is_dir() {
                        sweep(&path, prefix, depth - 1);
                    }
                }
            }
            sweep(Path::new("/dev/shm"), &self.prefix, 0);
            sweep(&self.root, &self.prefix, 3);
        }
    }

    #[test]
    fn bus_dead_nodes_are_reported_and_cleaned() {
        let prefix = format!("rdoc{}_", std::process::id());
        let config = isolated_config(&prefix);
        let _cleanup = PrefixCleanup {
            prefix: prefix.clone(),
            root: PathBuf::from(config.global.root_path().to_string()),
        };

        let empty = check_bus(&config, "doctortest", false);
        assert_eq!(empty.status, Status::Ok, "{empty:?}");
        assert!(
            empty.found.contains("nodes: 0 live, 0 dead"),
            "{}",
            empty.found
        );

        // A live node in this process, with a service in the namespace.
        let live = NodeBuilder::new()
            .config(&config)
            .create::<ipc::Service>()
            .expect("create node");
        let _service = live
            .service_builder(&ServiceName::new("doctortest/live").expect("service name"))
            .publish_subscribe::<u64>()
            .open_or_create()
            .expect("service");
        let check = check_bus(&config, "doctortest", false);
        assert_eq!(check.status, Status::Ok, "{check:?}");
        assert!(
            check.found.contains("nodes: 1 live, 0 dead"),
            "{}",
            check.found
        );
        assert!(
            check.found.contains("1 services in namespace 'doctortest'"),
            "{}",
            check.found
        );

        // A crashed process leaves a dead node behind.
        let exe = std::env::current_exe().expect("test binary");
        let status = Command::new(exe)
            .args([
                "doctor::tests::bus_helper_create_node_and_die",
                "--exact",
                "--ignored",
                "--test-threads=1",
            ])
            .env(DIE_ENV, &prefix)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .expect("run helper");
        assert!(status.success(), "helper failed: {status}");

        let check = check_bus(&config, "doctortest", false);
        assert_eq!(check.status, Status::Warn, "{check:?}");
        assert!(
            check.found.contains("1 dead ('doctor-test-dead' pid"),
            "{}",
            check.found
        );
        assert!(check
            .fix
            .as_deref()
            .unwrap_or("")
            .contains("robotd doctor --clean"));

        let cleaned = check_bus(&config, "doctortest", true);
        assert_eq!(cleaned.status, Status::Ok, "{cleaned:?}");
        assert!(
            cleaned.found.contains("removed the resources of 1"),
            "{}",
            cleaned.found
        );

        let after = check_bus(&config, "doctortest", false);
        assert_eq!(after.status, Status::Ok, "{after:?}");
        assert!(
            after.found.contains("nodes: 1 live, 0 dead"),
            "{}",
            after.found
        );
    }

    #[test]
    fn report_json_table_and_problems() {
        let report = DoctorReport {
            checks: vec![
                Check::ok("shm", "fine"),
                Check::warn("audio", "no device", "attach one"),
            ],
        };
        assert!(!report.has_problems());
        let json = report.to_json();
        assert_eq!(json["ok"], true);
        assert_eq!(json["summary"]["warn"], 1);
        assert_eq!(json["checks"][1]["status"], "warn");
        assert_eq!(json["checks"][1]["fix"], "attach one");
        assert!(json["checks"][0]["fix"].is_null());

        let mut report = report;
        report
            .checks
            .push(Check::problem("redis", "down", "start it"));
        assert!(report.has_problems());
        assert_eq!(report.to_json()["ok"], false);
        let table = report.render_table();
        assert!(table.contains("PROBLEM  redis"), "{table}");
        assert!(table.contains("fix: start it"), "{table}");
        assert!(
            table.contains("3 checks: 1 ok, 1 warning, 1 problem"),
            "{table}"
        );
    }

    #[test]
    fn run_is_bounded_with_unreachable_redis() {
        let opts = DoctorOptions {
            redis_url: Some("redis://127.0.0.1:1".into()),
            bus_namespace: "robotd".into(),
            config_dir: PathBuf::from("/nonexistent"),
            http_bind: None,
            clean: false,
        };
        let start = Instant::now();
        let report = run(&opts).expect("doctor runs");
        assert!(start.elapsed() < Duration::from_secs(10));
        let names: Vec<&str> = report.checks.iter().map(|c| c.name).collect();
        assert_eq!(
            names,
            [
                "shm",
                "iceoryx2",
                "redis",
                "redis-edge",
                "espeak-ng",
                "audio",
                "llm-keys"
            ]
        );
        assert!(report.has_problems());
    }
}
