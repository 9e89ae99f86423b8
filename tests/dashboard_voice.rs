//! `POST /api/voice` against a served robotd with the real STT actor (faster-whisper tiny.en
//! in its own process) and the scripted mock LLM as the agent:
//!
//! - a spoken command recorded as WebM (what a browser's MediaRecorder sends) comes back as
//!   its transcript and reaches the agent as if typed; with `Accept: text/event-stream` the
//!   answer is the transcript, then the request and its agent events up to the answer;
//! - "stop" at the start of an utterance engages the e-stop (seen on `GET /estop`) and nothing
//!   goes to the LLM; with `voice.stop_words = false` the same words go to the agent instead;
//! - without an STT actor the answer is a 503 naming `[actors.stt]`; an empty, too large or
//!   non-audio body is refused before the bus; the token and Origin rules are the port's.

mod common;

#[path = "common/stt.rs"]
mod stt;

use robotd_agent::mock::{MockLlm, MockReply};
use serde_json::Value;
use std::time::{Duration, Instant};

fn json(body: &str) -> Value {
    serde_json::from_str(body).unwrap_or_else(|e| panic!("not JSON ({e}): {body}"))
}

/// robotd with the STT actor, the mock LLM as its agent and `settings`.
fn robotd(namespace: &str, port: u16, mock: &MockLlm, settings: &[&str]) -> stt::WithConfig {
    let config = stt::config_with_stt(namespace, "");
    let mut args = vec!["--config", config.to_str().unwrap()];
    for setting in settings {
        args.extend(["--set", setting]);
    }
    let url = mock.openai_base_url();
    let env = [
        ("OPENAI_API_KEY", "sk-test-voice"),
        ("OPENAI_BASE_URL", url.as_str()),
    ];
    let robotd = common::start_robotd_with_env(namespace, port, &args, &env);
    stt::wait_for_stt(namespace);
    stt::WithConfig { robotd, config }
}

/// The events of an SSE body: (name, data as JSON).
fn sse_events(body: &str) -> Vec<(String, Value)> {
    body.split("\n\n")
        .filter_map(|block| {
            let name = block.lines().find_map(|l| l.strip_prefix("event:"))?;
            let data: String = block
                .lines()
                .filter_map(|l| l.strip_prefix("data:"))
                .map(str::trim_start)
                .collect();
            Some((name.trim().to_owned(), json(&data)))
        })
        .collect()
}

const WEBM: [(&str, &str); 1] = [("Content-Type", "audio/webm;codecs=opus")];

#[test]
fn a_spoken_command_reaches_the_agent_and_stop_engages_the_estop() {
    let runtime = common::runtime();
    let mock = runtime
        .block_on(MockLlm::start(vec![
            MockReply::text("I heard you: picking up the pencil is next."),
            MockReply::text("Second answer."),
        ]))
        .unwrap();
    let namespace = common::fresh_namespace("voice");
    let port = common::free_port();
    let _robotd = robotd(&namespace, port, &mock, &[]);

    let command = stt::spoken("pick up the pencil", "webm", &["--pad", "0.3"]);
    // JSON: the transcript, and the request the agent got.
    let (status, _, body) = stt::post(port, "/api/voice", &WEBM, &command);
    assert_eq!(status, 200, "{body}");
    let answer = json(&body);
    let text = answer["transcript"]["text"]
        .as_str()
        .unwrap()
        .to_lowercase();
    assert!(text.contains("pick up the pencil"), "{answer}");
    assert_eq!(answer["transcript"]["source"], "dashboard");
    assert_eq!(answer["action"], "agent", "{answer}");
    assert!(answer["request_id"].as_str().unwrap().starts_with("voice-"));

    // The event stream: transcript, request, then the agent's events up to its answer.
    let (status, _, body) = stt::post(
        port,
        "/api/voice",
        &[WEBM[0], ("Accept", "text/event-stream")],
        &command,
    );
    assert_eq!(status, 200, "{body}");
    let events = sse_events(&body);
    let names: Vec<&str> = events.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names[..2], ["transcript", "request"], "{body}");
    let last = &events.last().unwrap().1;
    assert_eq!(last["event"]["kind"], "answer", "{body}");
    assert_eq!(last["request_id"], events[1].1["request_id"]);
    // The LLM was asked with the words that were said, as a typed message would be.
    let asked = mock.requests();
    assert_eq!(asked.len(), 2, "one LLM call per spoken command");
    for request in &asked {
        let said = request.body["messages"].to_string().to_lowercase();
        assert!(said.contains("pick up the pencil"), "{said}");
    }

    // "Stop": the e-stop, without the LLM.
    let stop = stt::spoken("stop", "ogg", &["--pad", "0.3"]);
    let sent = Instant::now();
    let (status, _, body) = stt::post(port, "/api/voice", &[("Content-Type", "audio/ogg")], &stop);
    let round_trip = sent.elapsed();
    assert_eq!(status, 200, "{body}");
    let answer = json(&body);
    assert_eq!(answer["action"], "estop", "{answer}");
    assert_eq!(answer["estop"]["engaged"], true, "{answer}");
    let ms = answer["estop"]["ms"].as_f64().unwrap();
    assert!(ms < 250.0, "transcript to e-stop published took {ms} ms");
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let (_, body) = common::http_get(port, "/estop");
        if json(&body)["engaged"] == true {
            assert!(body.contains("voice"), "{body}");
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the e-stop was not engaged: {body}"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    assert_eq!(mock.requests().len(), 2, "the stop never reached the LLM");
    eprintln!(
        "voice stop: e-stop published {ms:.2} ms after the transcript; whole request {:?} \
         (transcription {} s)",
        round_trip, answer["transcript"]["processing_s"]
    );
}

#[test]
fn with_stop_words_off_stop_is_an_ordinary_command() {
    let runtime = common::runtime();
    let mock = runtime
        .block_on(MockLlm::start(vec![MockReply::text("Nothing is moving.")]))
        .unwrap();
    let namespace = common::fresh_namespace("voiceoff");
    let port = common::free_port();
    let _robotd = robotd(&namespace, port, &mock, &["voice.stop_words=false"]);
    let stop = stt::spoken("stop", "webm", &["--pad", "0.3"]);
    let (status, _, body) = stt::post(port, "/api/voice", &WEBM, &stop);
    assert_eq!(status, 200, "{body}");
    let answer = json(&body);
    assert_eq!(answer["action"], "agent", "{answer}");
    let (_, estop) = common::http_get(port, "/estop");
    assert_eq!(json(&estop)["engaged"], false, "{estop}");
}

#[test]
fn without_an_stt_actor_or_with_a_bad_body_voice_is_refused_clearly() {
    let namespace = common::fresh_namespace("voicenostt");
    let port = common::free_port();
    let token = "voicetoken42";
    let _robotd = common::start_robotd(&namespace, port, &["--set", &format!("mcp.token={token}")]);
    let bearer = format!("Bearer {token}");
    let auth = ("Authorization", bearer.as_str());
    let audio = b"OggS not really, but the STT actor is absent anyway";

    // The port's rules: the token, then the Origin.
    let (status, _, body) = stt::post(port, "/api/voice", &WEBM, audio);
    assert_eq!(status, 401, "{body}");
    let foreign = ("Origin", "http://evil.example");
    let (status, _, body) = stt::post(port, "/api/voice", &[auth, foreign, WEBM[0]], audio);
    assert_eq!(status, 403, "{body}");
    let own = format!("http://127.0.0.1:{port}");
    let (status, _, body) = stt::post(
        port,
        "/api/voice",
        &[auth, ("Origin", own.as_str()), WEBM[0]],
        audio,
    );
    assert_eq!(status, 503, "{body}");
    let refusal = json(&body);
    assert_eq!(refusal["kind"], "no_stt");
    assert!(
        refusal["error"].as_str().unwrap().contains("[actors.stt]"),
        "{body}"
    );

    let (status, _, body) = stt::post(port, "/api/voice", &[auth, WEBM[0]], b"");
    assert_eq!(status, 400, "{body}");
    assert!(json(&body)["error"].as_str().unwrap().contains("empty"));
    let big = vec![0u8; 1_000_001];
    let (status, _, body) = stt::post(port, "/api/voice", &[auth, WEBM[0]], &big);
    assert_eq!(status, 413, "{body}");
    assert!(json(&body)["error"]
        .as_str()
        .unwrap()
        .contains("max_audio_bytes"));
    let text = ("Content-Type", "text/plain");
    let (status, _, body) = stt::post(port, "/api/voice", &[auth, text], b"stop");
    assert_eq!(status, 415, "{body}");
    let pcm = ("Content-Type", "audio/pcm");
    let (status, _, body) = stt::post(port, "/api/voice", &[auth, pcm], &[0u8; 64]);
    assert_eq!(status, 400, "{body}");
    assert!(json(&body)["error"]
        .as_str()
        .unwrap()
        .contains("rate=16000"));
}
