//! The Debian package (`[package.metadata.deb]` in Cargo.toml, packaging/): built with
//! `cargo deb`, its control fields, files, conffiles and maintainer scripts checked, its
//! systemd unit verified by `systemd-analyze verify`, and the packaged binary started with the
//! unit's own `ExecStart` line and the packaged configuration until `/health` answers, with
//! this test playing systemd's `Type=notify` (it waits for `READY=1`).
//!
//! The package's profile is `dist` (fat LTO, a long build). The test does not rebuild robotd
//! for it: it packs the binary the tests already built (`cargo deb --no-build` on a scratch
//! target directory whose `dist/robotd` is that binary), and `--fast` compression. What is
//! checked is the packaging, not the optimisation.
//!
//! Needs `cargo-deb` (installed with `cargo install --locked cargo-deb` when missing, as
//! scripts/test.sh does), `dpkg-deb` and `dpkg-shlibdeps` (dpkg-dev), and `systemd-analyze`
//! (systemd). Without dpkg (not a Debian machine) the test fails, saying what is missing.
//!
//! The package is not installed on this machine (that would add a user and a service to
//! it), so the binary runs as the user running the tests, with the state and log directories
//! that systemd would create (`StateDirectory=`, `LogsDirectory=`) given as settings.

mod common;

use std::collections::BTreeMap;
use std::os::unix::net::UnixDatagram;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn have(tool: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {tool}")])
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// `cargo deb` works, installing cargo-deb first when it is missing.
fn ensure_cargo_deb() {
    let works = |args: &[&str]| {
        Command::new(env!("CARGO"))
            .args(args)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    };
    if works(&["deb", "--version"]) {
        return;
    }
    eprintln!("cargo-deb is missing: cargo install --locked cargo-deb (a few minutes)");
    let installed = Command::new(env!("CARGO"))
        .args(["install", "--locked", "cargo-deb"])
        .status()
        .expect("run cargo install");
    assert!(
        installed.success(),
        "cargo install --locked cargo-deb failed"
    );
    assert!(works(&["deb", "--version"]), "cargo deb still does not run");
}

fn run(command: &mut Command) -> String {
    let out = command.output().expect("run a command");
    assert!(
        out.status.success(),
        "{command:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Builds the .deb from the tests' robotd binary; returns its path.
fn build_deb(scratch: &Path) -> PathBuf {
    let dist = scratch.join("target").join("dist");
    std::fs::create_dir_all(&dist).unwrap();
    let binary = dist.join("robotd");
    if std::fs::hard_link(env!("CARGO_BIN_EXE_robotd"), &binary).is_err() {
        std::fs::copy(env!("CARGO_BIN_EXE_robotd"), &binary).unwrap();
    }
    let deb = scratch.join("robotd.deb");
    let started = Instant::now();
    run(Command::new(env!("CARGO"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("CARGO_TARGET_DIR", scratch.join("target"))
        .args([
            "deb",
            "-p",
            "robotd",
            "--no-build",
            "--profile",
            "dist",
            "--fast",
        ])
        .arg("--output")
        .arg(&deb));
    eprintln!("cargo deb took {:?}", started.elapsed());
    deb
}

/// `Key=value` lines of a unit file; a key given twice keeps every value.
fn unit_keys(unit: &str) -> BTreeMap<String, Vec<String>> {
    let mut keys: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for line in unit.lines().map(str::trim) {
        if line.starts_with('#') || line.starts_with('[') {
            continue;
        }
        if let Some((key, value)) = line.split_once('=') {
            keys.entry(key.to_owned())
                .or_default()
                .push(value.to_owned());
        }
    }
    keys
}

fn one<'a>(keys: &'a BTreeMap<String, Vec<String>>, key: &str) -> &'a str {
    keys.get(key)
        .and_then(|values| values.last())
        .unwrap_or_else(|| panic!("the unit has no {key}="))
}

#[test]
fn the_deb_holds_robotd_its_configs_user_and_a_unit_that_starts_it() {
    assert!(
        have("dpkg-deb"),
        "dpkg-deb is missing: apt-get install dpkg (scripts/test.sh runs on Debian, where it is \
         always there); the .deb cannot be built here"
    );
    ensure_cargo_deb();
    let scratch = tempfile::tempdir().unwrap();
    let deb = build_deb(scratch.path());

    // Control fields.
    let control = run(Command::new("dpkg-deb").arg("--field").arg(&deb));
    for expected in [
        "Package: robotd",
        &format!("Version: {}-1", env!("CARGO_PKG_VERSION")),
        "Section: science",
        "Recommends: espeak-ng",
        "Maintainer: The robotd developers",
    ] {
        assert!(control.contains(expected), "no '{expected}' in\n{control}");
    }
    assert!(
        control
            .lines()
            .any(|l| l.starts_with("Depends:") && l.contains("libc6")),
        "the shared libraries' packages are found: {control}"
    );

    // Files.
    let files = run(Command::new("dpkg-deb").arg("--contents").arg(&deb));
    for path in [
        "./usr/bin/robotd",
        "./etc/robotd/robotd.toml",
        "./etc/robotd/robotd.env",
        "./etc/robotd/default.toml",
        "./etc/robotd/niryo.toml",
        "./etc/robotd/widowx.toml",
        "./usr/lib/systemd/system/robotd.service",
        "./usr/share/doc/robotd/install.md",
    ] {
        assert!(
            files.lines().any(|l| l.ends_with(path)),
            "no {path} in\n{files}"
        );
    }

    // Conffiles and maintainer scripts.
    let control_dir = scratch.path().join("control");
    run(Command::new("dpkg-deb")
        .arg("--control")
        .arg(&deb)
        .arg(&control_dir));
    let conffiles = std::fs::read_to_string(control_dir.join("conffiles")).unwrap();
    for conf in [
        "robotd.toml",
        "robotd.env",
        "default.toml",
        "niryo.toml",
        "widowx.toml",
    ] {
        assert!(
            conffiles
                .lines()
                .any(|l| l == format!("/etc/robotd/{conf}")),
            "{conf} is not a conffile: {conffiles}"
        );
    }
    let postinst = std::fs::read_to_string(control_dir.join("postinst")).unwrap();
    assert!(postinst.contains("useradd --system"), "{postinst}");
    assert!(postinst.contains("dialout video"), "{postinst}");
    assert!(
        postinst.contains("deb-systemd-helper enable"),
        "the unit is enabled on install: {postinst}"
    );
    let postrm = std::fs::read_to_string(control_dir.join("postrm")).unwrap();
    assert!(postrm.contains("purge"), "{postrm}");

    // The unit.
    let root = scratch.path().join("root");
    run(Command::new("dpkg-deb").arg("-x").arg(&deb).arg(&root));
    let unit_path = root.join("usr/lib/systemd/system/robotd.service");
    let unit = std::fs::read_to_string(&unit_path).unwrap();
    let keys = unit_keys(&unit);
    for (key, value) in [
        ("Type", "notify"),
        ("NotifyAccess", "main"),
        ("Restart", "on-failure"),
        ("RemoveIPC", "no"),
        ("ProtectSystem", "strict"),
        ("NoNewPrivileges", "yes"),
        ("User", "robotd"),
        ("StateDirectory", "robotd"),
        ("LogsDirectory", "robotd"),
        ("DevicePolicy", "closed"),
    ] {
        assert_eq!(one(&keys, key), value, "{key}=");
    }
    let watchdog_s: u64 = one(&keys, "WatchdogSec").parse().expect("WatchdogSec in s");
    assert!((10..=300).contains(&watchdog_s), "WatchdogSec={watchdog_s}");
    assert!(one(&keys, "StartLimitBurst").parse::<u32>().unwrap() >= 1);
    let devices = &keys["DeviceAllow"];
    for device in ["char-ttyUSB rw", "char-ttyACM rw", "char-video4linux rw"] {
        assert!(devices.iter().any(|d| d == device), "{devices:?}");
    }
    // systemd-analyze verify checks the unit against this machine's units (targets, users'
    // lookups) and the files it names: a copy whose /usr/bin/robotd is the unpacked binary.
    assert!(
        have("systemd-analyze"),
        "systemd-analyze is missing: apt-get install systemd (scripts/test.sh does)"
    );
    let unpacked = |text: &str| {
        text.replace("/usr/bin/", &format!("{}/usr/bin/", root.display()))
            .replace("/etc/robotd/", &format!("{}/etc/robotd/", root.display()))
    };
    let copy = scratch.path().join("robotd.service");
    std::fs::write(&copy, unpacked(&unit)).unwrap();
    let verify = Command::new("systemd-analyze")
        .args(["verify", "--man=no"])
        .arg(&copy)
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&verify.stderr);
    assert!(
        verify.status.success() && !said.contains("robotd.service:"),
        "systemd-analyze verify: {said}"
    );

    // The unit's ExecStart, on the unpacked files, as systemd would run it.
    let exec_start = one(&keys, "ExecStart");
    let args: Vec<String> = exec_start.split_whitespace().map(unpacked).collect();
    assert!(args.contains(&"serve".to_owned()), "{exec_start}");
    let state = scratch.path().join("var-lib-robotd");
    let logs = scratch.path().join("var-log-robotd");
    std::fs::create_dir_all(&state).unwrap();
    std::fs::create_dir_all(&logs).unwrap();
    let notify = scratch.path().join("notify.sock");
    let socket = UnixDatagram::bind(&notify).unwrap();
    socket
        .set_read_timeout(Some(Duration::from_secs(60)))
        .unwrap();
    let port = common::free_port();
    let child = Command::new(&args[0])
        .args(&args[1..])
        .current_dir(&state)
        .env("NOTIFY_SOCKET", &notify)
        .env("ROBOTD_BUS__NAMESPACE", common::fresh_namespace("deb"))
        .env("ROBOTD_HTTP__BIND", format!("127.0.0.1:{port}"))
        // What StateDirectory= and LogsDirectory= are on the robot PC.
        .env("ROBOTD_TELEMETRY__LOG_DIR", &logs)
        .env("ROBOTD_TTS__SPOOL_DIR", state.join("speech"))
        .env(
            "ROBOTD_SAFETY__AUDIT__PATH",
            state.join("audit/audit.jsonl"),
        )
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let _robotd = common::Running::new(child, "packaged robotd");
    let mut buffer = [0u8; 4096];
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let n = socket
            .recv(&mut buffer)
            .expect("READY=1 from the packaged robotd within 60 s");
        if String::from_utf8_lossy(&buffer[..n])
            .lines()
            .any(|l| l == "READY=1")
        {
            break;
        }
        assert!(Instant::now() < deadline, "no READY=1 within 60 s");
    }
    let (status, body) = common::http_get(port, "/health");
    assert_eq!(status, 200, "{body}");
    assert!(body.contains("\"status\""), "{body}");
    assert!(
        state.join("audit/audit.jsonl").exists(),
        "the audit log is in the state directory"
    );
}
