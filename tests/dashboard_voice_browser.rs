//! Push-to-talk in a real browser: Debian's `chromium` over WebDriver, its fake microphone
//! playing a command espeak-ng spoke (`--use-fake-device-for-media-stream
//! --use-fake-ui-for-media-stream --use-file-for-fake-audio-capture=<wav>`), against a served
//! robotd on the simulator with the real STT actor and the scripted mock LLM. The button
//! records (MediaRecorder) and posts to `/api/voice`; the transcript appears in the chat, the
//! LLM is asked with those words, and the robot does what was said: the pencil moves (checked
//! against the simulator's ground truth).

#[path = "common/browser.rs"]
mod browser;
mod common;

#[path = "common/stt.rs"]
mod stt;

use browser::Browser;
use robotd_agent::mock::{MockLlm, MockReply};
use robotd_protocol::diagnostics::SimWorldRequest;
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::SIM_WORLD;
use serde_json::json;
use std::time::Duration;

async fn pencil_in_the_world(bus: &Bus) -> [f64; 2] {
    let world = bus
        .client(&SIM_WORLD)
        .unwrap()
        .request(&SimWorldRequest {}, Duration::from_secs(5))
        .await
        .unwrap();
    let pencil = world
        .objects
        .iter()
        .find(|o| o.label == "pencil")
        .expect("a pencil in the scene");
    [pencil.x_m, pencil.y_m]
}

const COMMAND: &str = "pick up the pencil and put it right next to the red cube";

#[test]
fn push_to_talk_in_chromium_moves_the_pencil() {
    let wav = tempfile::Builder::new().suffix(".wav").tempfile().unwrap();
    let audio = stt::spoken(COMMAND, "wav", &["--rate", "48000", "--pad", "0.5"]);
    std::fs::write(wav.path(), &audio).unwrap();
    let seconds = (audio.len() - 44) as f64 / 2.0 / 48_000.0;

    let runtime = common::runtime();
    let mock = runtime
        .block_on(MockLlm::start(vec![
            MockReply::plan_and_call(
                "Plan: pick the pencil and place it right next to the red cube.",
                "pick_place_object",
                json!({"object_name": "pencil", "pick_coordinate": [0.22, -0.05],
                       "place_coordinate": [0.28, 0.04], "location": "right next to"}),
            ),
            MockReply::text("Done: the pencil lies right next to the red cube."),
        ]))
        .unwrap();
    let namespace = common::fresh_namespace("voicebrowser");
    let port = common::free_port();
    let config = stt::config_with_stt(&namespace, "");
    let url = mock.openai_base_url();
    let robotd = common::start_robotd_with_env(
        &namespace,
        port,
        &["--config", config.to_str().unwrap()],
        &[
            ("OPENAI_API_KEY", "sk-test-voice"),
            ("OPENAI_BASE_URL", url.as_str()),
        ],
    );
    let _running = stt::WithConfig { robotd, config };
    stt::wait_for_stt(&namespace);
    runtime.block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "voice-browser-test")).unwrap();
        let before = pencil_in_the_world(&bus).await;

        let browser = Browser::start_with(&[
            "--use-fake-device-for-media-stream".into(),
            "--use-fake-ui-for-media-stream".into(),
            "--autoplay-policy=no-user-gesture-required".into(),
            format!(
                "--use-file-for-fake-audio-capture={}%noloop",
                wav.path().display()
            ),
        ])
        .await;
        browser
            .command("/url", json!({"url": format!("http://127.0.0.1:{port}/")}))
            .await;
        browser
            .wait_for(
                "the agent ready",
                "return document.getElementById('agent-state').textContent.includes('ready')",
                Duration::from_secs(20),
            )
            .await;
        // Click to start, let the fake microphone play the command, click to send.
        browser.click("#voice-button").await;
        browser
            .wait_for(
                "the recording of the whole command",
                &format!("return window.voiceRecordedSeconds >= {:.1}", seconds + 0.5),
                Duration::from_secs(30),
            )
            .await;
        browser.click("#voice-button").await;
        let heard = browser
            .wait_for(
                "the transcript in the chat",
                "const t = document.querySelector('#chat-log .voice-transcript'); \
                 return t ? t.textContent : ''",
                Duration::from_secs(60),
            )
            .await;
        let heard = heard.as_str().unwrap().to_lowercase();
        eprintln!("chromium's microphone was heard as {heard:?}");
        assert!(
            heard.starts_with("you (voice):")
                && heard.contains("pencil")
                && heard.contains("red cube"),
            "{heard}"
        );
        let answer = browser
            .wait_for(
                "the agent's answer",
                "const a = [...document.querySelectorAll('#chat-log .answer')]; \
                 return a.length ? a[a.length - 1].textContent : ''",
                Duration::from_secs(120),
            )
            .await;
        assert!(answer.as_str().unwrap().contains("Done"), "{answer}");
        // The LLM was asked with the spoken words; the pencil moved in the simulated world.
        let asked = mock.requests()[0].body["messages"]
            .to_string()
            .to_lowercase();
        assert!(
            asked.contains("pencil") && asked.contains("red cube"),
            "{asked}"
        );
        let after = pencil_in_the_world(&bus).await;
        let moved = ((after[0] - before[0]).powi(2) + (after[1] - before[1]).powi(2)).sqrt();
        assert!(
            moved > 0.05,
            "the pencil moved {moved:.3} m: {before:?} -> {after:?}"
        );
        browser.close().await;
    });
}
