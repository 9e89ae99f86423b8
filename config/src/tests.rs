//! Loading, layering and refusing: the whole configuration as users write it.

use super::*;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

fn no_env() -> Vec<(String, String)> {
    Vec::new()
}

fn env(pairs: &[(&str, &str)]) -> Vec<(String, String)> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

/// A uniquely named file holding `text`, removed on drop.
struct TempFile(PathBuf);

impl TempFile {
    fn new(text: &str) -> Self {
        static NEXT: AtomicU32 = AtomicU32::new(0);
        let path = std::env::temp_dir().join(format!(
            "robotd-config-test-{}-{}.toml",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::write(&path, text).expect("write temp config");
        TempFile(path)
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

fn with_file(file: &TempFile) -> LoadOptions {
    LoadOptions {
        file: Some(file.0.clone()),
        overrides: Vec::new(),
    }
}

fn problems_of(error: ConfigError) -> Vec<Problem> {
    match error {
        ConfigError::Invalid { problems } => problems,
        other => panic!("expected Invalid, got {other}"),
    }
}

/// Loads `toml` and checks that each `(key, says)` is refused with a reason containing `says`.
fn assert_refused(toml: &str, expected: &[(&str, &str)]) {
    let file = TempFile::new(toml);
    let error = Config::load_with_env(with_file(&file), no_env()).unwrap_err();
    let message = error.to_string();
    let problems = problems_of(error);
    for (key, says) in expected {
        let problem = problems
            .iter()
            .find(|p| p.key == *key)
            .unwrap_or_else(|| panic!("no problem for {key}:\n{message}"));
        assert!(problem.reason.contains(says), "{key}: {}", problem.reason);
    }
}

#[test]
fn defaults_load() {
    let config = Config::load_with_env(LoadOptions::default(), no_env()).unwrap();
    assert_eq!(config, Config::default());
    assert_eq!(config.service.name, "robotd");
    assert_eq!(config.service.worker_threads, 2);
    assert_eq!(config.http.bind, "127.0.0.1:8000".parse().unwrap());
    assert_eq!(config.bus.namespace, "robotd");
    assert_eq!(config.bus.request_timeout(), Duration::from_secs(30));
    assert_eq!(config.bus.frame_subscriber_buffer, 2);
    assert_eq!(config.telemetry.log_dir, PathBuf::from("log"));
    assert_eq!(config.telemetry.filter, "info");
    assert_eq!(config.telemetry.log_format, LogFormat::Text);
    assert_eq!(config.telemetry.otlp_endpoint, None);
    assert_eq!(config.telemetry.service_name.as_deref(), Some("robotd"));
    assert_eq!(
        config.supervision,
        SupervisionConfig {
            max_restarts: 5,
            window_s: 60,
            backoff_initial_ms: 10,
            backoff_max_ms: 5000,
            backoff_multiplier: 2.0,
        }
    );
    assert_eq!(config.robot.driver, RobotDriver::SimNed2);
    assert_eq!(config.redis.url, None);
    assert!(config.actors.is_empty());
    config.validate().unwrap();
}

#[test]
fn file_layers_over_defaults() {
    let file = TempFile::new(
        r#"
        [service]
        name = "lab-2"
        [robot]
        driver = "niryo"
        host = "192.168.1.50"
        [redis]
        url = "redis://localhost:6379/0"
        [actors.camera]
        mode = "process"
        command = ["robotd-camera", "--device", "0"]
        supervision = { max_restarts = 10 }
        "#,
    );
    let config = Config::load_with_env(with_file(&file), no_env()).unwrap();
    assert_eq!(config.service.name, "lab-2");
    // Untouched keys keep their defaults.
    assert_eq!(config.http.bind.port(), 8000);
    assert_eq!(config.telemetry.service_name.as_deref(), Some("lab-2"));
    assert_eq!(config.robot.driver, RobotDriver::Niryo);
    assert_eq!(
        config.redis.url.as_deref(),
        Some("redis://localhost:6379/0")
    );
    let camera = config.actor("camera");
    assert_eq!(camera.mode, ActorMode::Process);
    assert_eq!(camera.command, ["robotd-camera", "--device", "0"]);
    assert_eq!(config.supervision_for("camera").max_restarts, 10);
    assert_eq!(config.supervision_for("camera").window_s, 60);
    assert_eq!(config.supervision_for("arm"), config.supervision);
    assert_eq!(config.actor("arm").mode, ActorMode::InProcess);
}

/// The robot gets its own sections, and the restart policy of each of its actors as the whole
/// configuration says (`[actors.<name>]` over `[supervision]`).
#[test]
fn the_robot_sections_are_the_configured_ones() {
    let file = TempFile::new(
        "[telemetry]\nlog_dir = \"/var/log/lab\"\n[safety]\nfloor_z_m = 0.01\n\
         [actors.camera]\nsupervision = { max_restarts = 10 }\n\
         [actors.perception]\nsupervision = { max_restarts = 7 }\n",
    );
    let config = Config::load_with_env(with_file(&file), no_env()).unwrap();
    let sections = config.robot_sections();
    assert_eq!(sections.robot, config.robot);
    assert_eq!(sections.safety.floor_z_m, 0.01);
    assert_eq!(sections.log_dir, std::path::Path::new("/var/log/lab"));
    for actor in robotd_robot::ACTORS {
        assert_eq!(
            sections.supervision_for(actor),
            &config.supervision_for(actor)
        );
    }
    assert_eq!(sections.supervision_for("camera").max_restarts, 10);
    // Only the robot's own actors are handed over.
    assert_eq!(
        sections.actor_supervision.keys().collect::<Vec<_>>(),
        ["camera"]
    );
}

#[test]
fn env_overrides_file() {
    let file =
        TempFile::new("[http]\nbind = \"127.0.0.1:9000\"\n[bus]\nnamespace = \"from-file\"\n");
    let config = Config::load_with_env(
        with_file(&file),
        env(&[
            ("ROBOTD_HTTP__BIND", "0.0.0.0:8001"),
            ("ROBOTD_MCP__TOKEN", "a-long-random-token"),
            ("robotd_supervision__max_restarts", "7"),
            ("ROBOTD_SERVICE__NAME", "42"),
            ("ROBOTD_ACTORS__CAMERA__MODE", "process"),
            ("ROBOTD_ACTORS__CAMERA__COMMAND", "[robotd-camera, 0]"),
            ("ROBOTD_CONFIG", "/ignored/here.toml"),
            ("PATH", "/usr/bin"),
        ]),
    )
    .unwrap();
    assert_eq!(config.http.bind, "0.0.0.0:8001".parse().unwrap());
    assert_eq!(config.mcp.token.as_deref(), Some("a-long-random-token"));
    assert_eq!(config.bus.namespace, "from-file");
    assert_eq!(config.supervision.max_restarts, 7);
    assert_eq!(config.service.name, "42");
    assert_eq!(config.actor("camera").command, ["robotd-camera", "0"]);
}

#[test]
fn overrides_beat_env() {
    let options = LoadOptions {
        file: None,
        overrides: vec![
            ("http.bind".into(), "127.0.0.1:9100".into()),
            ("telemetry.log_format".into(), "json".into()),
        ],
    };
    let config = Config::load_with_env(
        options,
        env(&[
            ("ROBOTD_HTTP__BIND", "0.0.0.0:8001"),
            ("ROBOTD_TELEMETRY__FILTER", "debug"),
        ]),
    )
    .unwrap();
    assert_eq!(config.http.bind, "127.0.0.1:9100".parse().unwrap());
    assert_eq!(config.telemetry.log_format, LogFormat::Json);
    assert_eq!(config.telemetry.filter, "debug");
}

#[test]
fn unknown_key_in_file_is_refused_naming_file_and_key() {
    let file = TempFile::new("[http]\nbind = \"127.0.0.1:8000\"\nbnid = \"oops\"\n");
    let error = Config::load_with_env(with_file(&file), no_env()).unwrap_err();
    let message = error.to_string();
    let problems = problems_of(error);
    assert_eq!(problems.len(), 1, "{message}");
    assert_eq!(problems[0].key, "http.bnid");
    assert_eq!(problems[0].origin, Some(Origin::File(file.0.clone())));
    assert!(problems[0].reason.contains("unknown key"), "{message}");
    assert!(problems[0].reason.contains("bind"), "{message}");
    assert!(message.contains(&file.0.display().to_string()), "{message}");
    assert!(message.contains("http.bnid"), "{message}");
}

#[test]
fn unknown_section_and_actor_key_are_refused() {
    let file = TempFile::new("[htp]\nbind = 1\n[actors.arm]\nmod = \"process\"\n");
    let problems = problems_of(Config::load_with_env(with_file(&file), no_env()).unwrap_err());
    let keys: Vec<&str> = problems.iter().map(|p| p.key.as_str()).collect();
    assert!(keys.contains(&"htp"), "{problems:?}");
    assert!(keys.contains(&"actors.arm.mod"), "{problems:?}");
}

#[test]
fn invalid_values_are_refused_naming_key_and_reason() {
    let file = TempFile::new(
        r#"
        [http]
        bind = "nope"
        [supervision]
        max_restarts = -1
        "#,
    );
    let error = Config::load_with_env(with_file(&file), no_env()).unwrap_err();
    let message = error.to_string();
    let problems = problems_of(error);
    let bind = problems
        .iter()
        .find(|p| p.key == "http.bind")
        .expect(&message);
    assert!(bind.reason.contains("IP address and port"), "{message}");
    assert_eq!(bind.origin, Some(Origin::File(file.0.clone())));
    let restarts = problems
        .iter()
        .find(|p| p.key == "supervision.max_restarts")
        .expect(&message);
    assert!(restarts.reason.contains("-1"), "{message}");
    assert!(restarts.reason.contains("at least 1"), "{message}");
}

#[test]
fn the_runtime_needs_at_least_one_thread_and_at_most_64() {
    assert_refused(
        "[service]\nworker_threads = 0\n",
        &[("service.worker_threads", "must be from 1 to 64, got 0")],
    );
    assert_refused(
        "[service]\nworker_threads = 65\n",
        &[("service.worker_threads", "got 65")],
    );
}

#[test]
fn out_of_range_values_are_refused_by_validation() {
    let file = TempFile::new(
        r#"
        [bus]
        namespace = "robot d/1"
        request_timeout_ms = 0
        frame_subscriber_buffer = 0
        [supervision]
        max_restarts = 0
        backoff_initial_ms = 100
        backoff_max_ms = 50
        backoff_multiplier = 0.5
        [telemetry]
        filter = "info,[=bad"
        otlp_endpoint = "localhost:4318"
        [robot]
        driver = "ned3"
        "#,
    );
    let error = Config::load_with_env(with_file(&file), no_env()).unwrap_err();
    let message = error.to_string();
    let problems = problems_of(error);
    // The driver is a type error, reported before range checks run.
    let driver = problems
        .iter()
        .find(|p| p.key == "robot.driver")
        .expect(&message);
    assert!(driver.reason.contains("\"sim-ned2\""), "{message}");

    let file = TempFile::new(
        r#"
        [bus]
        namespace = "robot d/1"
        request_timeout_ms = 0
        frame_subscriber_buffer = 0
        [supervision]
        max_restarts = 0
        backoff_initial_ms = 100
        backoff_max_ms = 50
        backoff_multiplier = 0.5
        [telemetry]
        filter = "info,[=bad"
        otlp_endpoint = "localhost:4318"
        [actors.camera]
        mode = "process"
        [actors.arm]
        command = ["x"]
        [http]
        bind = "127.0.0.1:8000"
        max_connections = 2
        idle_timeout_s = 0
        "#,
    );
    let error = Config::load_with_env(with_file(&file), no_env()).unwrap_err();
    let message = error.to_string();
    let problems = problems_of(error);
    for key in [
        "bus.namespace",
        "bus.request_timeout_ms",
        "bus.frame_subscriber_buffer",
        "supervision.max_restarts",
        "supervision.backoff_max_ms",
        "supervision.backoff_multiplier",
        "telemetry.filter",
        "telemetry.otlp_endpoint",
        "actors.camera.command",
        "actors.arm.command",
        "http.max_connections",
        "http.idle_timeout_s",
    ] {
        let problem = problems
            .iter()
            .find(|p| p.key == key)
            .unwrap_or_else(|| panic!("no problem for {key}:\n{message}"));
        assert_eq!(problem.origin, Some(Origin::File(file.0.clone())), "{key}");
    }
    let namespace = problems.iter().find(|p| p.key == "bus.namespace").unwrap();
    assert!(namespace.reason.contains("' '"), "{message}");
}

#[test]
fn bad_namespace_from_env_names_the_variable() {
    let error = Config::load_with_env(
        LoadOptions::default(),
        env(&[("ROBOTD_BUS__NAMESPACE", "a.b")]),
    )
    .unwrap_err();
    let message = error.to_string();
    assert!(message.contains("bus.namespace"), "{message}");
    assert!(message.contains("ROBOTD_BUS__NAMESPACE"), "{message}");
}

#[test]
fn env_var_with_unknown_key_is_refused() {
    let error = Config::load_with_env(
        LoadOptions::default(),
        env(&[("ROBOTD_HTTP__BINDD", "0.0.0.0:1"), ("ROBOTD_NOPE", "1")]),
    )
    .unwrap_err();
    let message = error.to_string();
    let problems = problems_of(error);
    let bindd = problems
        .iter()
        .find(|p| p.key == "http.bindd")
        .expect(&message);
    assert_eq!(bindd.origin, Some(Origin::Env("ROBOTD_HTTP__BINDD".into())));
    let nope = problems.iter().find(|p| p.key == "nope").expect(&message);
    assert_eq!(nope.origin, Some(Origin::Env("ROBOTD_NOPE".into())));
    assert!(
        message.contains("environment variable ROBOTD_HTTP__BINDD"),
        "{message}"
    );
}

#[test]
fn invalid_env_value_names_the_variable() {
    let error = Config::load_with_env(
        LoadOptions::default(),
        env(&[("ROBOTD_HTTP__BIND", "nope")]),
    )
    .unwrap_err();
    let problems = problems_of(error);
    assert_eq!(problems.len(), 1);
    assert_eq!(problems[0].key, "http.bind");
    assert_eq!(
        problems[0].origin,
        Some(Origin::Env("ROBOTD_HTTP__BIND".into()))
    );
}

#[test]
fn invalid_override_names_the_override() {
    let options = LoadOptions {
        file: None,
        overrides: vec![("supervision.window_s".into(), "soon".into())],
    };
    let problems = problems_of(Config::load_with_env(options, no_env()).unwrap_err());
    assert_eq!(problems[0].key, "supervision.window_s");
    assert_eq!(
        problems[0].origin,
        Some(Origin::Override("supervision.window_s".into()))
    );
}

#[test]
fn missing_file_and_bad_toml_are_reported() {
    let missing = LoadOptions {
        file: Some(PathBuf::from("/definitely/not/here/robotd.toml")),
        overrides: Vec::new(),
    };
    let error = Config::load_with_env(missing, no_env()).unwrap_err();
    assert!(matches!(error, ConfigError::ReadFile { .. }), "{error}");
    assert!(error
        .to_string()
        .contains("/definitely/not/here/robotd.toml"));

    let file = TempFile::new("[http\nbind = 1\n");
    let message = Config::load_with_env(with_file(&file), no_env())
        .unwrap_err()
        .to_string();
    assert!(message.contains("not valid TOML"), "{message}");
    assert!(message.contains(&file.0.display().to_string()), "{message}");
}

#[test]
fn parse_override_splits_on_the_first_equals() {
    assert_eq!(
        LoadOptions::parse_override("telemetry.filter=info,a=debug").unwrap(),
        ("telemetry.filter".into(), "info,a=debug".into())
    );
    assert!(matches!(
        LoadOptions::parse_override("=x"),
        Err(ConfigError::BadOverride { .. })
    ));
}

#[test]
fn filter_with_commas_from_env_stays_text() {
    let config = Config::load_with_env(
        LoadOptions::default(),
        env(&[("ROBOTD_TELEMETRY__FILTER", "info,robotd_runtime::bus=debug")]),
    )
    .unwrap();
    assert_eq!(config.telemetry.filter, "info,robotd_runtime::bus=debug");
}

#[test]
fn workspaces_come_from_the_configuration_or_the_model() {
    let config = Config::default();
    let ids: Vec<String> = config
        .robot
        .workspaces()
        .into_iter()
        .map(|w| w.id)
        .collect();
    assert_eq!(ids, ["niryo_ws", "gazebo_1"], "the Ned2's built-in sheets");
    let widowx = Config::load_with_env(
        LoadOptions {
            file: None,
            overrides: vec![("robot.driver".into(), "widowx".into())],
        },
        no_env(),
    )
    .unwrap();
    let ids: Vec<String> = widowx
        .robot
        .workspaces()
        .into_iter()
        .map(|w| w.id)
        .collect();
    assert_eq!(
        ids,
        ["widowx_ws"],
        "a real WidowX starts with workspaces too"
    );

    let file = TempFile::new(
        "[robot]\ndriver = \"niryo\"\nhost = \"10.10.10.10\"\n\n[[robot.workspaces]]\nid = \"lab_ws\"\n\
         upper_left = [0.30, 0.10]\nlower_right = [0.15, -0.10]\n\
         observation_pose = [0.2, 0.0, 0.3, 0.0, 1.57, 0.0]\n",
    );
    let config = Config::load_with_env(with_file(&file), no_env()).unwrap();
    let infos = config.robot.workspace_infos();
    assert_eq!(infos.len(), 1);
    assert_eq!(infos[0].id, "lab_ws");
    assert_eq!(infos[0].upper_left.x_m, 0.30);
}

#[test]
fn the_niryo_driver_needs_a_host_and_sane_settings() {
    assert_refused(
        "[robot]\ndriver = \"niryo\"\nport = 0\n[robot.niryo]\nsegment_rad = 0.0\n\
         reconnect_max_ms = 60000\ngripper_speed = 5\n",
        &[
            ("robot.host", "needs the robot's address"),
            ("robot.port", "1 to 65535"),
            ("robot.niryo.segment_rad", "0"),
            ("robot.niryo.reconnect_max_ms", "60000"),
            ("robot.niryo.gripper_speed", "5"),
        ],
    );
    let spaces = TempFile::new("[robot]\ndriver = \"niryo\"\nhost = \"http://robot/x\"\n");
    let message = Config::load_with_env(with_file(&spaces), no_env())
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("is not a host name or address"),
        "{message}"
    );
}

#[test]
fn the_widowx_driver_settings_are_refused_with_their_key_and_reason() {
    assert_refused(
        "[robot]\ndriver = \"widowx\"\n[robot.widowx]\ndevice = \"\"\nbaud_rate = 9600\n\
         gripper_closed_ticks = 2000\ngripper_open_ticks = 2050\ngripper_pwm = 900\n\
         camera_url = \"rtsp://cam/stream\"\ncamera_latency_ms = 5000\n",
        &[
            ("robot.widowx.device", "must name the serial device"),
            ("robot.widowx.baud_rate", "9600"),
            ("robot.widowx.gripper_open_ticks", "100 ticks away"),
            ("robot.widowx.gripper_pwm", "900"),
            ("robot.widowx.camera_url", "neither a V4L2 device"),
            ("robot.widowx.camera_latency_ms", "5000"),
        ],
    );
    let v4l2 = TempFile::new(
        "[robot]\ndriver = \"widowx\"\n[robot.widowx]\ncamera_url = \"/dev/video0\"\n",
    );
    let config = Config::load_with_env(with_file(&v4l2), no_env()).unwrap();
    assert_eq!(
        config.robot.widowx.camera_url.as_deref(),
        Some("/dev/video0")
    );
    let fine = TempFile::new("[robot]\ndriver = \"widowx\"\n");
    let config = Config::load_with_env(with_file(&fine), no_env()).unwrap();
    assert_eq!(
        config.robot.widowx.device,
        std::path::PathBuf::from("/dev/ttyDXL")
    );
}

#[test]
fn bad_workspaces_are_refused_naming_each_one() {
    let file = TempFile::new(
        "[[robot.workspaces]]\nid = \"a\"\nupper_left = [0.1, 0.1]\nlower_right = [0.3, -0.1]\n\
         observation_pose = [0.2, 0.0, 0.3, 0.0, 1.57, 0.0]\n\n\
         [[robot.workspaces]]\nid = \"b\"\nupper_left = [0.3, 0.1]\nlower_right = [0.1, -0.1]\n\
         observation_pose = [0.2, 0.0, 0.3, 0.0, 1.57, 0.0]\n\n\
         [[robot.workspaces]]\nid = \"b\"\nupper_left = [0.3, 0.1]\nlower_right = [0.1, -0.1]\n\
         observation_pose = [0.2, 0.0, 0.3, 0.0, 1.57, 0.0]\n",
    );
    let problems = problems_of(Config::load_with_env(with_file(&file), no_env()).unwrap_err());
    let text: Vec<String> = problems.iter().map(|p| p.to_string()).collect();
    assert_eq!(problems.len(), 2, "{text:#?}");
    assert!(
        text[0].starts_with(
            "robot.workspaces[0]: 'a': upper_left [0.1, 0.1] must be the far-left corner"
        ),
        "{text:#?}"
    );
    assert!(text[0].contains("(set in config file"), "{text:#?}");
    assert!(
        text[1].starts_with("robot.workspaces[2]: id 'b' is used twice"),
        "{text:#?}"
    );
    let missing = TempFile::new("[[robot.workspaces]]\nid = \"c\"\n");
    let problems = problems_of(Config::load_with_env(with_file(&missing), no_env()).unwrap_err());
    assert!(
        problems
            .iter()
            .any(|p| p.key.starts_with("robot.workspaces")),
        "{problems:#?}"
    );
}

#[test]
fn the_replay_driver_needs_a_recording_and_takes_its_model_from_robot_replay() {
    let load = |overrides: &[(&str, &str)]| {
        Config::load_with_env(
            LoadOptions {
                file: None,
                overrides: overrides
                    .iter()
                    .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
                    .collect(),
            },
            no_env(),
        )
    };
    let error = load(&[("robot.driver", "replay")]).unwrap_err();
    let message = error.to_string();
    let problems = problems_of(error);
    let problem = problems
        .iter()
        .find(|p| p.key == "robot.replay.file")
        .expect(&message);
    assert!(problem.reason.contains("needs a recording"), "{message}");

    let error = load(&[
        ("robot.driver", "replay"),
        ("robot.replay.file", "session.mcap"),
        ("robot.replay.speed", "0"),
    ])
    .unwrap_err();
    assert!(problems_of(error)
        .iter()
        .any(|p| p.key == "robot.replay.speed"));

    let config = load(&[
        ("robot.driver", "replay"),
        ("robot.replay.file", "session.mcap"),
        ("robot.replay.loop", "true"),
        ("robot.replay.model", "widowx250"),
    ])
    .unwrap();
    assert_eq!(config.robot.driver, RobotDriver::Replay);
    assert!(config.robot.replay.looping);
    assert_eq!(config.robot.model(), config.robot.replay.model);
    assert_eq!(config.robot.model().as_str(), "widowx250");
    let ids: Vec<String> = config
        .robot
        .workspaces()
        .into_iter()
        .map(|w| w.id)
        .collect();
    assert_eq!(ids, ["widowx_ws"], "the replayed model's built-in sheets");
    // The file itself is checked when the driver opens it, not while loading the config.
    assert_eq!(
        config.robot.replay.file.as_deref(),
        Some(std::path::Path::new("session.mcap"))
    );
}

#[test]
fn the_viewers_sections_refuse_bad_values() {
    assert_refused(
        r#"
        [dashboard]
        camera_fps = 0.1
        jpeg_quality = 5
        [foxglove]
        bind = "0.0.0.0:8765"
        camera_fps = 31.0
        [record]
        dir = "recordings"
        max_file_bytes = 1000
        keep_files = 0
        topics = ["arm/state", "no/such/topic"]
        "#,
        &[
            ("dashboard.camera_fps", "0.5 … 30"),
            ("dashboard.jpeg_quality", "10 to 100"),
            ("foxglove.bind", "loopback"),
            ("foxglove.camera_fps", "0.5 … 30"),
            ("record.max_file_bytes", "1048576"),
            ("record.keep_files", "from 1"),
            ("record.topics", "no/such/topic"),
        ],
    );
}
