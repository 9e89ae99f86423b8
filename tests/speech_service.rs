//! Speech end to end: `robotd say` renders a WAV with the real espeak-ng, and the served TTS
//! actor speaks a text published on the bus into its spool, with events and an overlay.

mod common;

use robotd_protocol::speech::{OverlayKind, SpeakRequest, SpeechEvent};
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::{OVERLAY_TEXT, SPEECH_EVENTS, SPEECH_SPEAK};
use std::process::Command;
use std::time::Duration;

#[test]
fn robotd_say_writes_a_wav_with_espeak_ng() {
    let file = std::env::temp_dir().join(format!("robotd-say-{}.wav", std::process::id()));
    let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["say", "Hello from the robot", "--out"])
        .arg(&file)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(stderr.contains("espeak-ng"), "{stderr}");
    let audio = robotd_speech::engine::parse_wav(&std::fs::read(&file).unwrap()).unwrap();
    assert!(audio.duration_s() > 0.5 && audio.rms() > 0.02);
    let _ = std::fs::remove_file(&file);

    // The none engine makes no audio, and says so.
    let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["--set", "tts.engine=none", "say", "Hello", "--out"])
        .arg(&file)
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("produces no audio"), "{stderr}");
    assert!(!file.exists());
}

#[test]
fn the_served_tts_actor_speaks_into_its_spool() {
    let namespace = common::fresh_namespace("tts");
    let port = common::free_port();
    let spool = std::env::temp_dir().join(format!("robotd-spool-{namespace}"));
    let spool_setting = format!("tts.spool_dir={}", spool.display());
    let _robotd = common::start_robotd(
        &namespace,
        port,
        &["--set", "tts.output=spool", "--set", &spool_setting],
    );
    let (_, body) = common::http_get(port, "/health");
    assert!(body.contains("\"tts\""), "{body}");

    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    runtime.block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "tts-test-client")).unwrap();
        let mut events = bus.subscriber(&SPEECH_EVENTS).unwrap();
        let mut overlays = bus.subscriber(&OVERLAY_TEXT).unwrap();
        let speak = bus.publisher(&SPEECH_SPEAK).unwrap();
        // robotd answers /health only once its actors are up, so the actor is listening.
        let text = "Going to pick the pencil";
        let finished = async {
            loop {
                if let SpeechEvent::Finished { text: t, .. } = events.recv().await.unwrap().body {
                    if t == text {
                        return;
                    }
                }
            }
        };
        speak.publish(&SpeakRequest::new(text, "test")).unwrap();
        tokio::time::timeout(Duration::from_secs(10), finished)
            .await
            .expect("the text finished within 10 s");
        let overlay = tokio::time::timeout(Duration::from_secs(2), overlays.recv())
            .await
            .unwrap()
            .unwrap()
            .body;
        assert_eq!(overlay.kind, OverlayKind::RobotSpeech);
        assert_eq!(overlay.text, text);
    });
    let files: Vec<_> = std::fs::read_dir(&spool)
        .unwrap()
        .filter_map(Result::ok)
        .collect();
    assert_eq!(files.len(), 1);
    let audio = robotd_speech::engine::parse_wav(&std::fs::read(files[0].path()).unwrap()).unwrap();
    assert!(audio.duration_s() > 0.5);
    let _ = std::fs::remove_dir_all(&spool);
}
