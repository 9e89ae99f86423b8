//! `redis`: would `robotd serve` reach its Redis server, and be let in?
//!
//! The doctor does not have its own idea of where Redis is. It asks
//! [`robotd_redis::resolve_target`] — the function `robotd serve` calls — with the same inputs:
//! `[redis] url` (which `--redis` sets), else `REDIS_HOST` / `REDIS_PORT` / `REDIS_DB` from the
//! environment, with `REDIS_PASSWORD` from the environment filling in a password the URL lacks.
//! Then it talks to that target with redis-rs, the client of the Redis edge: connect (TLS for
//! `rediss://`, checked against the system's root certificates, as the edge does), `AUTH` when a
//! password is known, and `PING`. The row is `ok` only when `PONG` came back; a server that
//! only accepts the connection proves nothing.
//!
//! `REDIS_PASSWORD` in `secrets.env` is *not* used, because the service does not use it either:
//! the `REDIS_*` variables are the lab's Python tools' settings, which those tools read from the
//! environment only, and robotd reads them the same way so that both sides of the edge always
//! connect with the same settings. `secrets.env` holds the LLM keys. When the file does set
//! `REDIS_PASSWORD`, the row says it is ignored and how to pass the password instead.
//!
//! Time is bounded twice: redis-rs gets a timeout for connecting (name resolution, TCP, TLS,
//! the setup commands) and for each reply, and the whole exchange runs on a helper thread that
//! is abandoned after [`CHECK_DEADLINE`] — name resolution cannot be given a timeout, and the
//! doctor must not hang on a DNS server that does not answer.

use super::secrets::{Secrets, SECRETS_FILE};
use super::{first_chars, Check, EnvFn, NET_TIMEOUT};
use redis::{ConnectionAddr, ErrorKind, RedisError};
use robotd_redis::RedisTarget;
use std::sync::mpsc;
use std::time::Duration;

/// The longest a Redis check takes, whatever the network does: a connect and one reply, each
/// bounded by [`NET_TIMEOUT`], plus slack.
const CHECK_DEADLINE: Duration = Duration::from_millis(1200);

const REDIS_START_FIX: &str =
    "start Redis: `apt-get install redis-server && redis-server --daemonize yes`, \
     or set REDIS_HOST/REDIS_PORT (or --redis redis://host:port) to where it runs";

/// What happened when the doctor connected, authenticated and sent PING.
#[derive(Debug, PartialEq, Eq)]
enum PingOutcome {
    /// PING answered PONG.
    Pong,
    /// The server wants a password and none was given.
    NoAuth,
    /// The password (or user) was rejected — or the server has no password and refuses `AUTH`.
    AuthRejected,
    /// Redis refuses this client (protected mode: no password and not on loopback).
    Denied,
    /// `rediss://`: the TLS handshake failed (certificate not trusted, wrong host name, or the
    /// port does not speak TLS).
    Tls(String),
    /// Connected and authenticated, but the server refused a setting (e.g. the database number).
    Refused(String),
    /// Connected, but the reply was not what Redis says (or none came in time).
    Unexpected(String),
    /// Could not resolve or connect.
    Unreachable(String),
}

/// `host:port` (IPv6 hosts in brackets) or the socket path; never contains the password.
fn addr_of(target: &RedisTarget) -> String {
    match target.info.addr() {
        ConnectionAddr::Tcp(host, port) | ConnectionAddr::TcpTls { host, port, .. } => {
            if host.contains(':') && !host.starts_with('[') {
                format!("[{host}]:{port}")
            } else {
                format!("{host}:{port}")
            }
        }
        other => other.to_string(),
    }
}

fn is_tls(target: &RedisTarget) -> bool {
    matches!(target.info.addr(), ConnectionAddr::TcpTls { .. })
}

/// Connects to `target` the way the Redis edge does and sends PING; never takes longer than
/// [`CHECK_DEADLINE`].
fn ping(target: &RedisTarget) -> PingOutcome {
    // rediss:// builds a rustls client, which needs robotd's crypto provider installed.
    robotd_runtime::telemetry::install_tls_provider();
    let client = match redis::Client::open(target.info.clone()) {
        Ok(client) => client,
        Err(e) => return PingOutcome::Unexpected(format!("redis-rs refused the settings: {e}")),
    };
    let (addr, tls) = (addr_of(target), is_tls(target));
    let (tx, rx) = mpsc::channel();
    let spawned = std::thread::Builder::new()
        .name("doctor-redis".into())
        .spawn(move || {
            let _ = tx.send(ping_blocking(&client, &addr, tls));
        });
    if let Err(e) = spawned {
        return PingOutcome::Unexpected(format!("could not start the check: {e}"));
    }
    rx.recv_timeout(CHECK_DEADLINE).unwrap_or_else(|_| {
        PingOutcome::Unreachable(format!(
            "no answer from {} within {} ms (name resolution or the connection hangs)",
            addr_of(target),
            CHECK_DEADLINE.as_millis()
        ))
    })
}

fn ping_blocking(client: &redis::Client, addr: &str, tls: bool) -> PingOutcome {
    let mut connection = match client.get_connection_with_timeout(NET_TIMEOUT) {
        Ok(connection) => connection,
        Err(e) => return classify(&e, addr, tls, "connecting"),
    };
    if connection.set_read_timeout(Some(NET_TIMEOUT)).is_err()
        || connection.set_write_timeout(Some(NET_TIMEOUT)).is_err()
    {
        return PingOutcome::Unexpected("could not set socket timeouts".into());
    }
    match redis::cmd("PING").query::<String>(&mut connection) {
        Ok(reply) if reply == "PONG" => PingOutcome::Pong,
        Ok(reply) => {
            PingOutcome::Unexpected(format!("unexpected reply to PING: {}", first_chars(&reply)))
        }
        Err(e) => classify(&e, addr, tls, "PING"),
    }
}

/// Turns a redis-rs error of `step` into what it means for the user.
fn classify(e: &RedisError, addr: &str, tls: bool, step: &str) -> PingOutcome {
    match e.code() {
        Some("NOAUTH") => return PingOutcome::NoAuth,
        Some("WRONGPASS") => return PingOutcome::AuthRejected,
        Some("DENIED") => return PingOutcome::Denied,
        _ => {}
    }
    if e.kind() == ErrorKind::AuthenticationFailed {
        return PingOutcome::AuthRejected;
    }
    if e.is_timeout() && tls && step == "connecting" {
        return PingOutcome::Tls(format!(
            "no TLS handshake within {} ms",
            NET_TIMEOUT.as_millis()
        ));
    }
    if e.is_timeout() {
        return PingOutcome::Unexpected(format!(
            "no reply while {step} within {} ms",
            NET_TIMEOUT.as_millis()
        ));
    }
    if e.is_connection_refusal() {
        return PingOutcome::Unreachable(format!("cannot connect to {addr}: {e}"));
    }
    if matches!(e.kind(), ErrorKind::Server(_) | ErrorKind::Extension) {
        return PingOutcome::Refused(e.to_string());
    }
    if step == "connecting" && e.is_io_error() {
        // Name resolution and TCP failures read "failed to lookup address" / "No route to
        // host" and the like; anything else while connecting over TLS is the handshake.
        let text = e.to_string();
        let network = [
            "lookup",
            "resolve",
            "route",
            "unreachable",
            "refused",
            "reset",
        ]
        .iter()
        .any(|word| text.to_ascii_lowercase().contains(word));
        if tls && !network {
            return PingOutcome::Tls(text);
        }
        return PingOutcome::Unreachable(format!("cannot connect to {addr}: {text}"));
    }
    PingOutcome::Unexpected(format!("{step} failed: {e}"))
}

/// The `redis` row: where `robotd serve` would connect, and whether it gets PONG there.
pub(super) fn check_redis(url: Option<&str>, env: EnvFn, secrets: &Secrets) -> Check {
    const NAME: &str = "redis";
    let target =
        match robotd_redis::resolve_target(None, url, env) {
            Ok(Some(t)) => t,
            Ok(None) => return Check::ok(
                NAME,
                "not configured (Redis edge off); set REDIS_HOST/REDIS_PORT or --redis to use it",
            ),
            Err(e) => {
                return Check::problem(
                    NAME,
                    e,
                    "use --redis redis://[:password@]host[:port][/db] (rediss:// for TLS), or \
                 REDIS_HOST and a numeric REDIS_PORT",
                )
            }
        };
    let addr = addr_of(&target);
    let settings = target.info.redis_settings();
    let mut from = target.source.to_owned();
    if settings.db() != 0 {
        from.push_str(&format!(", db {}", settings.db()));
    }
    if settings.password().is_some() {
        from.push_str(", password set");
    }
    if is_tls(&target) {
        from.push_str(", TLS");
    }
    // Said on every row, so a user who put the password there learns why it is not used.
    let ignored = if secrets.get("REDIS_PASSWORD").is_some() {
        format!(
            "; REDIS_PASSWORD in {SECRETS_FILE} is not used (robotd serve, like the Python \
             tools, takes REDIS_* from the environment only)"
        )
    } else {
        String::new()
    };
    let password_fix = format!(
        "set REDIS_PASSWORD in the environment robotd serve runs in (not {SECRETS_FILE}), \
         or put it in the URL: redis://:PASSWORD@{addr}"
    );
    match ping(&target) {
        PingOutcome::Pong => Check::ok(NAME, format!("{addr} answers PONG (from {from}){ignored}")),
        PingOutcome::NoAuth => Check::warn(
            NAME,
            format!("{addr} is up but requires a password (from {from}){ignored}"),
            password_fix,
        ),
        PingOutcome::AuthRejected => Check::warn(
            NAME,
            format!("{addr} is up but rejected the password (from {from}){ignored}"),
            "check REDIS_PASSWORD in the environment robotd serve runs in, or the password in \
             the Redis URL, against the server's requirepass/ACL (a server without a password \
             refuses any)",
        ),
        PingOutcome::Denied => Check::problem(
            NAME,
            format!("{addr} is Redis but refuses this client (protected mode) (from {from})"),
            "on the Redis host set a password (`requirepass`, then REDIS_PASSWORD here) or \
             `protected-mode no` with a `bind` limited to trusted networks",
        ),
        PingOutcome::Tls(why) => Check::problem(
            NAME,
            format!("TLS with {addr} failed, PING not sent: {why} (from {from})"),
            format!(
                "make sure {addr} speaks TLS and its certificate is issued for the host in the \
                 URL by a CA this machine trusts (system roots, or SSL_CERT_FILE); or use \
                 redis:// if the server does not speak TLS"
            ),
        ),
        PingOutcome::Refused(why) => Check::problem(
            NAME,
            format!("{addr} refused the connection settings: {why} (from {from})"),
            "check the database number (REDIS_DB or /db in the URL; the server has `databases`, \
             16 by default) and the user of the URL against the server's ACL",
        ),
        PingOutcome::Unexpected(why) => Check::problem(
            NAME,
            format!(
                "something listens on {addr} but it does not answer like Redis: {why} (from {from})"
            ),
            format!("check that {addr} is a Redis server; {REDIS_START_FIX}"),
        ),
        PingOutcome::Unreachable(why) => {
            Check::problem(NAME, format!("{why} (from {from})"), REDIS_START_FIX)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::doctor::report::{DoctorReport, Status};
    use crate::doctor::test_support::{
        env_from, free_port, no_secrets, require_program, temp_dir, RedisServer,
    };
    use std::net::TcpListener;
    use std::path::Path;
    use std::process::{Command, Stdio};
    use std::time::Instant;

    /// The target `robotd serve` resolves from `[redis] url` = `url` and the environment `env`
    /// (serve.rs passes the process environment; the doctor passes the same).
    fn service_target(url: Option<&str>, env: EnvFn) -> RedisTarget {
        robotd_redis::resolve_target(None, url, env)
            .expect("valid settings")
            .expect("configured")
    }

    #[test]
    fn redis_urls_resolve_like_the_service_without_leaking_passwords() {
        let env = env_from(&[]);
        let t = service_target(Some("redis://:s%40cret@10.0.0.5:6380/2"), &env);
        assert_eq!(addr_of(&t), "10.0.0.5:6380");
        assert_eq!(t.info.redis_settings().db(), 2);
        assert_eq!(t.info.redis_settings().password(), Some("s@cret"));
        assert!(!t.display.contains("cret"), "{}", t.display);

        let t = service_target(Some("redis://user:pw@localhost"), &env);
        assert_eq!(addr_of(&t), "localhost:6379");
        assert_eq!(t.info.redis_settings().username(), Some("user"));

        let t = service_target(Some("redis://[::1]:7000"), &env);
        assert_eq!(addr_of(&t), "[::1]:7000");
        assert!(is_tls(&service_target(Some("rediss://example.org"), &env)));
        assert!(!is_tls(&t));

        // What the service refuses, the doctor reports as a problem, password kept out.
        for url in [
            "redis://:topsecret@host:99999",
            "http://host",
            "redis://host/x",
            "127.0.0.1:7001",
        ] {
            let check = check_redis(Some(url), &env, &no_secrets());
            assert_eq!(check.status, Status::Problem, "{url}: {check:?}");
            assert!(check.found.contains("[redis] url"), "{}", check.found);
            assert!(!check.found.contains("topsecret"), "{}", check.found);
        }
    }

    #[test]
    fn redis_unconfigured_is_ok_and_env_is_used() {
        let check = check_redis(None, &env_from(&[]), &no_secrets());
        assert_eq!(check.status, Status::Ok);
        assert!(check.found.contains("not configured"), "{}", check.found);

        let env = env_from(&[("REDIS_PORT", "not-a-port")]);
        let check = check_redis(None, &env, &no_secrets());
        assert_eq!(check.status, Status::Problem);
        assert!(
            check.found.contains("REDIS_PORT 'not-a-port'"),
            "{}",
            check.found
        );

        let env = env_from(&[
            ("REDIS_HOST", "10.1.2.3"),
            ("REDIS_PORT", "6390"),
            ("REDIS_DB", "3"),
        ]);
        let t = service_target(None, &env);
        assert_eq!(addr_of(&t), "10.1.2.3:6390");
        assert_eq!(t.info.redis_settings().db(), 3);
        assert_eq!(t.source, "REDIS_HOST/REDIS_PORT");

        // The option wins over the environment; REDIS_PASSWORD fills in a missing password.
        let env = env_from(&[("REDIS_HOST", "10.1.2.3"), ("REDIS_PASSWORD", "pw")]);
        let t = service_target(Some("redis://127.0.0.1:1"), &env);
        assert_eq!(addr_of(&t), "127.0.0.1:1");
        assert_eq!(t.info.redis_settings().password(), Some("pw"));
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

    /// Accepts connections on a free port and never answers, for `hold`.
    fn silent_server(hold: Duration) -> (u16, std::thread::JoinHandle<()>) {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let port = listener.local_addr().expect("addr").port();
        let holder = std::thread::spawn(move || {
            let conn = listener.accept();
            std::thread::sleep(hold);
            drop(conn);
        });
        (port, holder)
    }

    #[test]
    fn redis_silent_server_is_bounded() {
        let (port, holder) = silent_server(Duration::from_secs(2));
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
    fn rediss_silent_server_is_bounded_and_never_ok() {
        // A TLS client waits for the server's hello, which never comes.
        let (port, holder) = silent_server(Duration::from_secs(2));
        let start = Instant::now();
        let check = check_redis(
            Some(&format!("rediss://127.0.0.1:{port}")),
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
        let server = RedisServer::start(&[]);
        let url = format!("redis://127.0.0.1:{}", server.port);
        let check = check_redis(Some(&url), &env_from(&[]), &no_secrets());
        assert_eq!(check.status, Status::Ok, "{check:?}");
        assert!(check.found.contains("PONG"), "{}", check.found);

        // Through REDIS_HOST/REDIS_PORT as well.
        let port = server.port.to_string();
        let env = env_from(&[("REDIS_HOST", "localhost"), ("REDIS_PORT", &port)]);
        let check = check_redis(None, &env, &no_secrets());
        assert_eq!(check.status, Status::Ok, "{check:?}");

        // A database the server does not have is refused, with the setting to fix named.
        let env = env_from(&[("REDIS_PORT", &port), ("REDIS_DB", "99")]);
        let check = check_redis(None, &env, &no_secrets());
        assert_eq!(check.status, Status::Problem, "{check:?}");
        assert!(check.fix.unwrap_or_default().contains("REDIS_DB"));

        // rediss:// to a server that does not speak TLS: never ok.
        let check = check_redis(
            Some(&format!("rediss://127.0.0.1:{}", server.port)),
            &env_from(&[]),
            &no_secrets(),
        );
        assert_eq!(check.status, Status::Problem, "{check:?}");
    }

    #[test]
    fn redis_with_password_noauth_wrongpass_and_ok() {
        let server = RedisServer::start(&["--requirepass", "hunter2-secret"]);
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

        let good = check_redis(
            Some(&format!("redis://127.0.0.1:{port}")),
            &env_from(&[("REDIS_PASSWORD", "hunter2-secret")]),
            &no_secrets(),
        );
        assert_eq!(good.status, Status::Ok, "{good:?}");
        assert!(good.found.contains("password set"), "{}", good.found);
        let report = DoctorReport {
            checks: vec![none, wrong, good],
        };
        assert!(!report.render_table().contains("hunter2"));
        assert!(!report.to_json().to_string().contains("hunter2"));
    }

    /// What the Redis edge of `robotd serve` gets for this target: its own connect function
    /// (connection manager, one attempt, PING), on a tokio runtime as in the service.
    fn service_connects(target: &RedisTarget) -> Result<(), String> {
        robotd_runtime::telemetry::install_tls_provider();
        let client = redis::Client::open(target.info.clone()).map_err(|e| e.to_string())?;
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("tokio runtime");
        runtime
            .block_on(robotd_redis::writer::connect(&client))
            .map(drop)
            .map_err(|e| e.to_string())
    }

    /// `robotd doctor` and `robotd serve` agree on every way of giving the Redis settings,
    /// against a real password-protected Redis: where the service's edge connects, the doctor
    /// says ok, and where it is refused, the doctor is not ok either. A password only in
    /// `secrets.env` is refused by both — and the doctor says why.
    #[test]
    fn doctor_and_serve_agree_on_every_redis_setting() {
        const PASSWORD: &str = "only-in-secrets-pw";
        let server = RedisServer::start(&["--requirepass", PASSWORD]);
        let port = server.port.to_string();
        let dir = temp_dir("agree");
        std::fs::write(
            dir.join(SECRETS_FILE),
            format!("REDIS_PASSWORD={PASSWORD}\n"),
        )
        .expect("write secrets.env");
        let secrets = Secrets::load(&dir);
        assert_eq!(secrets.get("REDIS_PASSWORD"), Some(PASSWORD));

        let url_with = format!("redis://:{PASSWORD}@127.0.0.1:{port}/1");
        let url_without = format!("redis://127.0.0.1:{port}");
        let url_wrong = format!("redis://:wrong@127.0.0.1:{port}");
        /// What is set, `[redis] url`, the environment, and whether the service gets in.
        type Case<'a> = (&'a str, Option<&'a str>, Vec<(&'a str, &'a str)>, bool);
        let cases: Vec<Case> = vec![
            (
                "password only in secrets.env",
                None,
                vec![("REDIS_HOST", "127.0.0.1"), ("REDIS_PORT", &port)],
                false,
            ),
            (
                "REDIS_PASSWORD in the environment",
                None,
                vec![
                    ("REDIS_HOST", "127.0.0.1"),
                    ("REDIS_PORT", &port),
                    ("REDIS_DB", "2"),
                    ("REDIS_PASSWORD", PASSWORD),
                ],
                true,
            ),
            ("password in the URL", Some(&url_with), vec![], true),
            (
                "URL without password, REDIS_PASSWORD fills in",
                Some(&url_without),
                vec![("REDIS_PASSWORD", PASSWORD)],
                true,
            ),
            (
                "the URL's wrong password wins over the environment",
                Some(&url_wrong),
                vec![("REDIS_PASSWORD", PASSWORD)],
                false,
            ),
            (
                "the URL wins over REDIS_HOST/REDIS_PORT",
                Some(&url_with),
                vec![("REDIS_HOST", "127.0.0.1"), ("REDIS_PORT", "1")],
                true,
            ),
        ];
        for (what, url, pairs, reachable) in cases {
            let env = env_from(&pairs);
            let served = service_connects(&service_target(url, &env));
            assert_eq!(served.is_ok(), reachable, "{what}: service: {served:?}");
            let check = check_redis(url, &env, &secrets);
            assert_eq!(
                check.status == Status::Ok,
                reachable,
                "{what}: doctor: {check:?} / service: {served:?}"
            );
            // The row always says that secrets.env's REDIS_PASSWORD is not used.
            assert!(
                check
                    .found
                    .contains("REDIS_PASSWORD in secrets.env is not used"),
                "{what}: {}",
                check.found
            );
            if !reachable {
                let fix = check.fix.clone().unwrap_or_default();
                assert!(
                    fix.contains("REDIS_PASSWORD in the environment"),
                    "{what}: {fix}"
                );
            }
            assert!(!format!("{check:?}").contains(PASSWORD), "{what}: leaked");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Makes a CA and a server certificate for 127.0.0.1/localhost with `openssl` (the test
    /// fails, naming the package, when it is not installed). Returns (ca.pem, server.pem,
    /// server.key).
    fn make_certificates(dir: &Path) -> [String; 3] {
        require_program("openssl", "openssl");
        let path = |name: &str| dir.join(name).display().to_string();
        let (ca_key, ca, key, csr, cert, ext) = (
            path("ca.key"),
            path("ca.pem"),
            path("server.key"),
            path("server.csr"),
            path("server.pem"),
            path("ext.cnf"),
        );
        std::fs::write(
            &ext,
            "subjectAltName=IP:127.0.0.1,DNS:localhost\nbasicConstraints=CA:FALSE\n",
        )
        .expect("write ext");
        let steps: [&[&str]; 3] = [
            &[
                "req",
                "-x509",
                "-newkey",
                "rsa:2048",
                "-nodes",
                "-days",
                "2",
                "-subj",
                "/CN=robotd doctor test CA",
                "-keyout",
                &ca_key,
                "-out",
                &ca,
            ],
            &[
                "req",
                "-newkey",
                "rsa:2048",
                "-nodes",
                "-subj",
                "/CN=localhost",
                "-keyout",
                &key,
                "-out",
                &csr,
            ],
            &[
                "x509",
                "-req",
                "-in",
                &csr,
                "-CA",
                &ca,
                "-CAkey",
                &ca_key,
                "-CAcreateserial",
                "-days",
                "2",
                "-extfile",
                &ext,
                "-out",
                &cert,
            ],
        ];
        for args in steps {
            let status = Command::new("openssl")
                .args(args)
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .status()
                .expect("run openssl");
            assert!(status.success(), "openssl {args:?}: {status}");
        }
        [ca, cert, key]
    }

    const TLS_ENV: &str = "ROBOTD_DOCTOR_TEST_TLS_URL";

    /// Helper run in a child process by `rediss_is_pinged_over_tls` with `SSL_CERT_FILE` set to
    /// the test CA (the system's trust store read by the edge's rustls): prints the row.
    #[test]
    #[ignore = "helper: run by rediss_is_pinged_over_tls in a child process"]
    fn rediss_helper_check() {
        let Ok(url) = std::env::var(TLS_ENV) else {
            return;
        };
        let check = check_redis(Some(&url), &env_from(&[]), &no_secrets());
        println!("ROW {} {}", check.status.as_str(), check.found);
    }

    /// rediss:// against a real TLS Redis: with a certificate this machine does not trust the
    /// row is a problem (the handshake fails, no PING), and once the CA is trusted the row is ok
    /// only because PONG came back over TLS.
    #[test]
    fn rediss_is_pinged_over_tls() {
        let dir = temp_dir("tls");
        let [ca, cert, key] = make_certificates(&dir);
        let port = free_port();
        let _server = RedisServer::start_on(
            port,
            true,
            &[
                "--tls-cert-file",
                &cert,
                "--tls-key-file",
                &key,
                "--tls-ca-cert-file",
                &ca,
                "--tls-auth-clients",
                "no",
            ],
        );
        let url = format!("rediss://127.0.0.1:{port}");

        let untrusted = check_redis(Some(&url), &env_from(&[]), &no_secrets());
        assert_eq!(untrusted.status, Status::Problem, "{untrusted:?}");
        assert!(untrusted.found.contains("TLS"), "{}", untrusted.found);
        assert!(
            untrusted.fix.unwrap_or_default().contains("SSL_CERT_FILE"),
            "fix names how to trust the CA"
        );

        // Plain redis:// to the TLS port is not Redis either.
        let plain = check_redis(
            Some(&format!("redis://127.0.0.1:{port}")),
            &env_from(&[]),
            &no_secrets(),
        );
        assert_eq!(plain.status, Status::Problem, "{plain:?}");

        let exe = std::env::current_exe().expect("test binary");
        let output = Command::new(exe)
            .args([
                "doctor::redis::tests::rediss_helper_check",
                "--exact",
                "--ignored",
                "--test-threads=1",
                "--nocapture",
            ])
            .env(TLS_ENV, &url)
            .env("SSL_CERT_FILE", &ca)
            .stdin(Stdio::null())
            .output()
            .expect("run helper");
        let stdout = String::from_utf8_lossy(&output.stdout);
        let row = stdout
            .lines()
            .find_map(|l| l.split_once("ROW ").map(|(_, row)| row))
            .unwrap_or_else(|| panic!("helper printed no row: {stdout}"));
        assert!(row.starts_with("ok "), "{row}");
        assert!(row.contains("answers PONG") && row.contains("TLS"), "{row}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
