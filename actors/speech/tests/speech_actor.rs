//! The speech actor and its engines, with real espeak-ng, a real bus and a local mock of the
//! ElevenLabs HTTP API.

use robotd_protocol::speech::{SpeakRequest, SpeechEvent};
use robotd_runtime::bus::{Bus, BusOptions, Publisher, Subscriber};
use robotd_runtime::supervision::{observer_fn, SupervisionEvent, SupervisionPolicy};
use robotd_speech::engine::{
    Audio, ElevenLabsEngine, EngineError, EspeakEngine, SpeechEngine, Utterance,
};
use robotd_speech::output::{Output, Spool};
use robotd_speech::{Speech, SpeechSettings};
use robotd_topics::{SPEECH_EVENTS, SPEECH_SPEAK};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

#[test]
fn espeak_speaks_longer_for_longer_texts_and_not_silence() {
    let engine = EspeakEngine::new("en", 160).expect("espeak-ng is installed by the test command");
    let audio = |text: &str| match engine.synthesize(text).unwrap() {
        Utterance::Audio(a) => a,
        Utterance::LoggedOnly => panic!("espeak-ng produced no audio"),
    };
    let short = audio("Hello.");
    let long = audio("Hello. I am going to pick up the pencil and place it next to the red cube.");
    assert!(short.duration_s() > 0.2, "{}", short.duration_s());
    assert!(
        long.duration_s() > 2.5 * short.duration_s(),
        "{} vs {}",
        long.duration_s(),
        short.duration_s()
    );
    assert!(long.rms() > 0.02, "rms {}", long.rms());
    // And it writes a WAV that reads back.
    let file = std::env::temp_dir().join(format!("robotd-espeak-{}.wav", std::process::id()));
    long.write_wav(&file).unwrap();
    let back = robotd_speech::engine::parse_wav(&std::fs::read(&file).unwrap()).unwrap();
    assert_eq!(back, long);
    let _ = std::fs::remove_file(file);
}

/// An engine that takes its time, remembers what it said, and panics on "crash".
struct SlowEngine {
    delay: Duration,
    said: Mutex<Vec<String>>,
}

impl SpeechEngine for SlowEngine {
    fn name(&self) -> &'static str {
        "slow-test"
    }
    fn synthesize(&self, text: &str) -> Result<Utterance, EngineError> {
        if text == "crash" {
            panic!("the test engine crashes on purpose");
        }
        std::thread::sleep(self.delay);
        self.said.lock().unwrap().push(text.to_owned());
        Ok(Utterance::Audio(Audio {
            sample_rate: 8000,
            samples: vec![1000; 800],
        }))
    }
}

struct Harness {
    speech: Speech,
    requests: Publisher<SpeakRequest>,
    events: Subscriber<SpeechEvent>,
    restarts: Arc<AtomicUsize>,
    spool: std::path::PathBuf,
    _bus: Bus,
}

async fn harness(name: &str, capacity: usize, delay_ms: u64) -> Harness {
    let namespace = format!("test-tts-{name}-{}", std::process::id());
    let bus = Bus::open(BusOptions::new(&namespace, "speech-test")).unwrap();
    let spool = std::env::temp_dir().join(format!("robotd-tts-{name}-{}", std::process::id()));
    let restarts = Arc::new(AtomicUsize::new(0));
    let counter = restarts.clone();
    let speech = Speech::start(
        &bus,
        SpeechSettings {
            engine: Arc::new(SlowEngine {
                delay: Duration::from_millis(delay_ms),
                said: Mutex::new(Vec::new()),
            }),
            output: Output::Spool(Spool {
                dir: spool.clone(),
                max_bytes: 10_000_000,
            }),
            scratch_dir: spool.clone(),
            queue_capacity: capacity,
            duplicate_window: Duration::from_secs(2),
            policy: SupervisionPolicy::default(),
        },
        observer_fn(move |e: &SupervisionEvent| {
            if matches!(e, SupervisionEvent::Restarted { .. }) {
                counter.fetch_add(1, Ordering::SeqCst);
            }
        }),
    )
    .await
    .unwrap();
    Harness {
        speech,
        requests: bus.publisher(&SPEECH_SPEAK).unwrap(),
        events: bus.subscriber(&SPEECH_EVENTS).unwrap(),
        restarts,
        spool,
        _bus: bus,
    }
}

impl Harness {
    /// Asks to say `text`; returns how long asking took.
    fn say(&self, text: &str, priority: u8) -> Duration {
        let t = Instant::now();
        let mut request = SpeakRequest::new(text, "test");
        request.priority = priority;
        self.requests.publish(&request).unwrap();
        t.elapsed()
    }

    async fn next_event(&mut self) -> SpeechEvent {
        tokio::time::timeout(Duration::from_secs(5), self.events.recv())
            .await
            .expect("a speech event within 5 s")
            .unwrap()
            .body
    }

    /// Events until `n` texts were finished or dropped.
    async fn events_until(&mut self, n: usize) -> Vec<SpeechEvent> {
        let mut out = Vec::new();
        let mut ended = 0;
        while ended < n {
            let e = self.next_event().await;
            if !matches!(e, SpeechEvent::Started { .. }) {
                ended += 1;
            }
            out.push(e);
        }
        out
    }
}

fn started(events: &[SpeechEvent]) -> Vec<&str> {
    events
        .iter()
        .filter_map(|e| match e {
            SpeechEvent::Started { text } => Some(text.as_str()),
            _ => None,
        })
        .collect()
}

fn dropped(events: &[SpeechEvent]) -> Vec<(&str, &str)> {
    events
        .iter()
        .filter_map(|e| match e {
            SpeechEvent::Dropped { text, reason } => Some((text.as_str(), reason.as_str())),
            _ => None,
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn priority_order_duplicates_and_speak_returns_at_once() {
    let mut h = harness("order", 50, 200).await;
    let mut slowest = h.say("first", 5);
    assert!(matches!(h.next_event().await, SpeechEvent::Started { ref text } if text == "first"));
    // The engine is busy with "first": these queue up, and asking never waits for it.
    for (text, priority) in [("low", 1), ("high", 9), ("mid", 5), ("HIGH ", 9)] {
        slowest = slowest.max(h.say(text, priority));
    }
    assert!(
        slowest < Duration::from_millis(5),
        "asking took {slowest:?}"
    );
    let events = h.events_until(5).await;
    assert_eq!(started(&events), ["high", "mid", "low"]);
    let dropped = dropped(&events);
    assert_eq!(dropped.len(), 1, "{events:?}");
    assert_eq!(dropped[0].0, "HIGH ");
    assert!(dropped[0].1.contains("duplicate"));
    let finished = events
        .iter()
        .filter(|e| matches!(e, SpeechEvent::Finished { .. }))
        .count();
    assert_eq!(finished, 4, "first, high, mid and low: {events:?}");
    // Each utterance went to the spool (this machine plays nothing in tests).
    let files = std::fs::read_dir(&h.spool).unwrap().count();
    assert_eq!(files, 4);
    let _ = std::fs::remove_dir_all(&h.spool);
    h.speech.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_queue_drops_the_lowest_priority_oldest() {
    let mut h = harness("full", 2, 200).await;
    h.say("busy", 5);
    assert!(matches!(h.next_event().await, SpeechEvent::Started { .. }));
    h.say("low", 1);
    h.say("high", 9);
    h.say("mid", 5);
    let events = h.events_until(4).await;
    let dropped = dropped(&events);
    assert_eq!(dropped.len(), 1, "{events:?}");
    assert_eq!(dropped[0].0, "low");
    assert!(
        dropped[0].1.contains("queue full (2 texts)"),
        "{}",
        dropped[0].1
    );
    assert_eq!(started(&events), ["high", "mid"]);
    let _ = std::fs::remove_dir_all(&h.spool);
    h.speech.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_crashing_engine_is_restarted_and_speaks_again() {
    let mut h = harness("crash", 50, 10).await;
    h.say("crash", 5);
    let events = h.events_until(1).await;
    let dropped = dropped(&events);
    assert_eq!(dropped.len(), 1, "{events:?}");
    assert!(dropped[0].1.contains("speech engine"), "{}", dropped[0].1);
    // The supervisor restarts the engine; the next text is spoken.
    let deadline = Instant::now() + Duration::from_secs(5);
    while h.restarts.load(Ordering::SeqCst) == 0 && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert_eq!(h.restarts.load(Ordering::SeqCst), 1);
    h.speech
        .engine
        .wait_ready(Duration::from_secs(5))
        .await
        .ok();
    h.say("after the crash", 5);
    let events = h.events_until(1).await;
    assert!(
        events
            .iter()
            .any(|e| matches!(e, SpeechEvent::Finished { text, .. } if text == "after the crash")),
        "{events:?}"
    );
    let _ = std::fs::remove_dir_all(&h.spool);
    h.speech.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn texts_queued_behind_a_crash_wait_for_the_restart_and_are_spoken() {
    // The engine is busy, then crashes on "crash"; "next" waited in the queue meanwhile. Only
    // the text in hand is lost: "next" reaches the restarted engine, not a "restarting" error.
    let mut h = harness("queued-crash", 50, 100).await;
    h.say("busy", 5);
    assert!(matches!(h.next_event().await, SpeechEvent::Started { .. }));
    h.say("crash", 5);
    h.say("next", 5);
    let events = h.events_until(3).await;
    let dropped = dropped(&events);
    assert_eq!(dropped.len(), 1, "{events:?}");
    assert_eq!(dropped[0].0, "crash");
    assert!(
        dropped[0].1.contains("crashed on this text"),
        "{}",
        dropped[0].1
    );
    assert!(
        events
            .iter()
            .any(|e| matches!(e, SpeechEvent::Finished { text, .. } if text == "next")),
        "{events:?}"
    );
    // The supervisor reports the restart just after the new engine is up.
    let deadline = Instant::now() + Duration::from_secs(5);
    while h.restarts.load(Ordering::SeqCst) == 0 && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert_eq!(h.restarts.load(Ordering::SeqCst), 1);
    let _ = std::fs::remove_dir_all(&h.spool);
    h.speech.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn elevenlabs_engine_against_a_local_mock() {
    use axum::extract::{Path, Query};
    use axum::http::{HeaderMap, StatusCode};
    type Seen = Arc<Mutex<Vec<(String, String, String, serde_json::Value)>>>;
    let seen: Seen = Arc::new(Mutex::new(Vec::new()));
    let record = seen.clone();
    let app = axum::Router::new().route(
        "/v1/text-to-speech/{voice}",
        axum::routing::post(
            move |Path(voice): Path<String>,
                  Query(query): Query<std::collections::HashMap<String, String>>,
                  headers: HeaderMap,
                  body: String| {
                let record = record.clone();
                async move {
                    let key = headers
                        .get("xi-api-key")
                        .and_then(|v| v.to_str().ok())
                        .unwrap_or("")
                        .to_owned();
                    let json: serde_json::Value =
                        serde_json::from_str(&body).unwrap_or(serde_json::Value::Null);
                    let format = query.get("output_format").cloned().unwrap_or_default();
                    record
                        .lock()
                        .unwrap()
                        .push((voice, key.clone(), format, json));
                    if key != "test-key" {
                        return (StatusCode::UNAUTHORIZED, Vec::new());
                    }
                    // 0.1 s of a 440 Hz tone, 16 kHz little-endian PCM.
                    let pcm: Vec<u8> = (0..1600)
                        .flat_map(|i| {
                            let s = (f64::from(i) * 440.0 * std::f64::consts::TAU / 16000.0).sin();
                            ((s * 12000.0) as i16).to_le_bytes()
                        })
                        .collect();
                    (StatusCode::OK, pcm)
                }
            },
        ),
    );
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let base = format!("http://{}", listener.local_addr().unwrap());
    tokio::spawn(async move { axum::serve(listener, app).await });

    let engine = ElevenLabsEngine::new(&base, "test-key", "voice-1", "model-x").unwrap();
    let audio = tokio::task::spawn_blocking(move || engine.synthesize("Hello robot"))
        .await
        .unwrap()
        .unwrap();
    let Utterance::Audio(audio) = audio else {
        panic!("no audio");
    };
    assert_eq!(audio.sample_rate, 16000);
    assert_eq!(audio.samples.len(), 1600);
    assert!(audio.rms() > 0.2, "{}", audio.rms());
    {
        let seen = seen.lock().unwrap();
        let (voice, key, format, body) = &seen[0];
        assert_eq!(voice, "voice-1");
        assert_eq!(key, "test-key");
        assert_eq!(format, "pcm_16000");
        assert_eq!(body["text"], "Hello robot");
        assert_eq!(body["model_id"], "model-x");
    }

    let wrong = ElevenLabsEngine::new(&base, "wrong-key", "voice-1", "model-x").unwrap();
    let error = tokio::task::spawn_blocking(move || wrong.synthesize("Hello"))
        .await
        .unwrap()
        .unwrap_err();
    assert!(error.to_string().contains("ELEVENLABS_API_KEY"), "{error}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn elevenlabs_speaks_tls_to_https_urls() {
    use tokio::io::AsyncReadExt;
    // A server that only looks at what the engine sends first: over https:// that must be a
    // TLS handshake record (0x16, version 3.x), not a plain HTTP request.
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let url = format!("https://{}", listener.local_addr().unwrap());
    let first_bytes = tokio::spawn(async move {
        let (mut socket, _) = listener.accept().await.unwrap();
        let mut buf = [0u8; 3];
        socket.read_exact(&mut buf).await.unwrap();
        buf
    });
    let engine = ElevenLabsEngine::new(&url, "test-key", "voice-1", "model-x").unwrap();
    let result = tokio::task::spawn_blocking(move || engine.synthesize("Hello"))
        .await
        .unwrap();
    let error = result.unwrap_err();
    assert!(error.to_string().contains("elevenlabs failed"), "{error}");
    let bytes = first_bytes.await.unwrap();
    assert_eq!(bytes[0], 0x16, "not a TLS handshake: {bytes:?}");
    assert_eq!(bytes[1], 3, "not a TLS handshake: {bytes:?}");
}

#[test]
fn a_hung_espeak_is_killed_after_its_timeout() {
    use std::os::unix::fs::PermissionsExt;
    let script = std::env::temp_dir().join(format!("robotd-hung-espeak-{}", std::process::id()));
    std::fs::write(&script, "#!/bin/sh\nsleep 30\n").unwrap();
    std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).unwrap();
    let engine = EspeakEngine {
        program: script.clone(),
        voice: "en".into(),
        rate_wpm: 160,
        timeout: Duration::from_millis(300),
    };
    let started = Instant::now();
    let error = engine.synthesize("hello").unwrap_err();
    let took = started.elapsed();
    assert!(took < Duration::from_secs(5), "{took:?}");
    assert!(error.to_string().contains("killed"), "{error}");
    let _ = std::fs::remove_file(script);
}
