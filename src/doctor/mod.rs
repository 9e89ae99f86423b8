//! `robotd doctor`: is this machine ready to run robotd, and if not, what exactly to do.
//!
//! robotd leans on a few things outside its own process: shared memory in `/dev/shm` for the
//! iceoryx2 bus, the bus's bookkeeping files (which a crashed process can leave behind), an
//! optional Redis server for the Python tools, `espeak-ng` and an audio output for speech, an
//! LLM provider key for the agent, with the niryo or widowx driver the robot itself, and with
//! the replay driver its recording. When one of them is missing robotd still starts, but a
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
//! The doctor does not carry its own network clients or parsers: it asks the same code the
//! service runs, so it cannot disagree with it. The Redis target comes from
//! [`robotd_redis::resolve_target`] (what `robotd serve` connects to) and is checked with
//! redis-rs (what the Redis edge speaks, TLS included); a running robotd's `/health` is read
//! with reqwest; `secrets.env` is read by the agent crate's parser (what the LLM agent uses).
//!
//! Every check is bounded in time: network checks use short timeouts (an unreachable host costs
//! at most a few hundred milliseconds per step) and external programs are killed if they do not
//! answer. The doctor never prints secrets — only whether a key is set and where it came from.
//!
//! One module per check, each with the reasoning behind its rows:
//!
//! | module | row | what it asks |
//! |---|---|---|
//! | [`shm`] | `shm` | is `/dev/shm` there, writable, big enough |
//! | [`disk`] | `disk` | free space where robotd writes: log directory, audit log, speech spool, recordings |
//! | [`bus`] | `iceoryx2` | dead bus nodes, services of the namespace (`--clean`) |
//! | [`redis`] | `redis` | the service's Redis target answers PING |
//! | [`health`] | `redis-edge` | a running robotd's view of its Redis edge |
//! | [`espeak`] | `espeak-ng` | the speech program runs |
//! | [`audio`] | `audio` | a sound card or sound server to play speech on |
//! | [`llm_keys`] | `llm-keys` | an LLM provider the agent can use |
//! | [`niryo`] | `niryo` | with the niryo driver: the Ned2 answers (connect, handshake, hardware status) |
//! | [`camera`] | `camera` | with a V4L2 camera configured: the device opens and gives the intrinsics' size in MJPG or YUYV |
//! | [`widowx`] | `widowx` | with the widowx driver: the serial port opens, the nine servos answer with the right models, no latched hardware error |
//! | [`stt`] | `stt` | with `[actors.stt]`: the speech-to-text model is there and loads (the actor's own `--check`, through the configured Python) |
//! | [`commissioning`] | `commissioning` | with the niryo or widowx driver: `robotd commission` measured the camera mount on this robot (missing, or stale when the robot changed since) |
//! | [`replay`] | `replay` | with the replay driver: the recording opens and can be played (frames, arm states, robot model); what it holds |
//! | [`secrets`] | — | `secrets.env`, shared by `redis` and `llm-keys` |
//! | [`report`] | — | rows, the table and the JSON |
//!
//! ```ignore
//! # fn demo() -> anyhow::Result<()> {
//! let opts = DoctorOptions {
//!     redis_url: Some("redis://127.0.0.1:6379".into()),
//!     bus_namespace: "robotd".into(),
//!     config_dir: "config".into(),
//!     clean: false,
//!     http_bind: None,
//!     niryo: None,
//!     widowx: None,
//!     camera: None,
//!     replay: None,
//!     disk_places: Vec::new(),
//!     stt: None,
//!     robot: None,
//! };
//! let report = run(&opts)?;
//! print!("{}", report.render_table());
//! std::process::exit(if report.has_problems() { 1 } else { 0 });
//! # }
//! ```

mod audio;
mod bus;
mod camera;
mod commissioning;
mod disk;
mod espeak;
mod health;
mod llm_keys;
mod niryo;
mod redis;
mod replay;
mod report;
mod secrets;
mod shm;
mod stt;
#[cfg(test)]
mod test_support;
mod widowx;

pub use report::{Check, DoctorReport, Status};
pub use stt::stt_command;

use anyhow::Result;
use iceoryx2::prelude::Config;
use secrets::Secrets;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Timeout of each network step (name resolution, connect, one reply).
const NET_TIMEOUT: Duration = Duration::from_millis(500);

/// How the checks read environment variables: `Some` only for a set, non-empty variable.
/// Tests pass a map instead of touching the process environment.
type EnvFn<'a> = &'a dyn Fn(&str) -> Option<String>;

/// What `robotd doctor` checks, and whether it may change anything.
#[derive(Debug, Clone)]
pub struct DoctorOptions {
    /// `[redis] url` of the configuration (`--redis` sets it too): exactly what `robotd serve`
    /// is given. When `None`, `REDIS_HOST`/`REDIS_PORT` from the environment are used, and
    /// when those are unset too the Redis edge counts as off.
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
    /// How to reach the Ned2 when `robot.driver = "niryo"` (`None` for other drivers).
    pub niryo: Option<robotd_driver_niryo::LinkSettings>,
    /// The servo bus (device, baud rate) when `robot.driver = "widowx"` (`None` otherwise).
    pub widowx: Option<(PathBuf, u32)>,
    /// The camera source (`robot.widowx.camera_url`) and the frame size of its intrinsics,
    /// when the widowx driver has one (`None` otherwise).
    pub camera: Option<(String, (u32, u32))>,
    /// `[robot.replay]` when `robot.driver = "replay"` (`None` otherwise).
    pub replay: Option<robotd_driver::ReplayConfig>,
    /// Where robotd writes (`crate::disk::places`): their free space is checked.
    pub disk_places: Vec<(&'static str, PathBuf)>,
    /// `[actors.stt] command` when the STT actor runs as a process ([`stt_command`]).
    pub stt: Option<Vec<String>>,
    /// `[robot]`, for the `commissioning` row (`None`: not checked).
    pub robot: Option<robotd_driver::RobotConfig>,
}

/// Runs every check and returns the report. Takes a few seconds at most, whatever the network
/// does. With `opts.clean`, removes the resources of dead bus nodes.
pub fn run(opts: &DoctorOptions) -> Result<DoctorReport> {
    let secrets = Secrets::load(&opts.config_dir);
    let env = |key: &str| std::env::var(key).ok().filter(|v| !v.trim().is_empty());
    let checks = vec![
        shm::check_shm(Path::new("/dev/shm")),
        disk::check_disk(&opts.disk_places),
        bus::check_bus(Config::global_config(), &opts.bus_namespace, opts.clean),
        redis::check_redis(opts.redis_url.as_deref(), &env, &secrets),
        health::check_redis_edge(opts.http_bind.as_deref()),
        espeak::check_espeak(env("PATH").as_deref()),
        audio::check_audio(Path::new("/dev/snd"), &env),
        llm_keys::check_llm_keys(&env, &secrets, &llm_keys::ollama_reachable),
        niryo::check_niryo(opts.niryo.clone()),
        widowx::check_widowx(opts.widowx.clone()),
        camera::check_camera(opts.camera.clone()),
        replay::check_replay(opts.replay.as_ref()),
        stt::check_stt(opts.stt.as_deref(), stt::LOAD_TIMEOUT),
    ];
    let mut checks = checks;
    if let Some(robot) = &opts.robot {
        checks.push(commissioning::check_commissioning(robot));
    }
    Ok(DoctorReport { checks })
}

/// At most 80 characters of `s` (an ellipsis marks a cut), for quoting replies and URLs.
fn first_chars(s: &str) -> String {
    let mut out: String = s.chars().take(80).collect();
    if s.chars().count() > 80 {
        out.push('…');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Instant;

    #[test]
    fn run_is_bounded_with_unreachable_redis() {
        let opts = DoctorOptions {
            redis_url: Some("redis://127.0.0.1:1".into()),
            bus_namespace: "robotd".into(),
            config_dir: PathBuf::from("/nonexistent"),
            http_bind: None,
            clean: false,
            niryo: None,
            widowx: None,
            camera: None,
            replay: None,
            disk_places: vec![("log", std::env::temp_dir())],
            stt: None,
            robot: None,
        };
        let start = Instant::now();
        let report = run(&opts).expect("doctor runs");
        assert!(start.elapsed() < Duration::from_secs(10));
        let names: Vec<&str> = report.checks.iter().map(|c| c.name).collect();
        assert_eq!(
            names,
            [
                "shm",
                "disk",
                "iceoryx2",
                "redis",
                "redis-edge",
                "espeak-ng",
                "audio",
                "llm-keys",
                "niryo",
                "widowx",
                "camera",
                "replay",
                "stt"
            ]
        );
        assert!(report.has_problems());
    }

    #[test]
    fn first_chars_cuts_long_text() {
        assert_eq!(first_chars("short"), "short");
        let long = "x".repeat(100);
        let cut = first_chars(&long);
        assert_eq!(cut.chars().count(), 81);
        assert!(cut.ends_with('…'));
    }
}
