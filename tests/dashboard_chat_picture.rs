//! The dashboard's chat shows the picture the agent looked at (issue 44). A served robotd on
//! the simulator has the scripted mock LLM as its agent; the mock calls `get_camera_image`.
//!
//! - In a real browser (Debian's `chromium` over WebDriver): after the call's result the chat
//!   holds an `<img>` whose file is byte for byte the JPEG the tool returned — the one the
//!   model was sent, as the mock recorded it — with that JPEG's width and height; a click
//!   enlarges it and another shrinks it back. Screenshots in `target/test-artifacts/`.
//! - Over the API: `POST /api/chat`'s events carry the picture as an `agent` event of kind
//!   `picture` right after the call's result, with a URL (not the bytes) that serves the exact
//!   file; a picture id that is not kept answers 404.

#[path = "common/browser.rs"]
mod browser;
mod common;

use base64::Engine;
use robotd_agent::mock::{MockLlm, MockReply};
use serde_json::{json, Value};
use std::time::Duration;

/// The picture the model was sent in a recorded request (the `data:` URL of its image part,
/// which the agent builds from the tool's own bytes) and the id of the call that returned it.
fn picture_sent(body: &Value) -> (Vec<u8>, String) {
    let messages = body["messages"].as_array().expect("messages");
    // The newest: the history may hold an earlier one too.
    let url = messages
        .iter()
        .filter_map(|m| m["content"].as_array())
        .flatten()
        .rev()
        .find_map(|part| part["image_url"]["url"].as_str())
        .unwrap_or_else(|| panic!("no image part in {body}"));
    let data = url
        .strip_prefix("data:image/jpeg;base64,")
        .unwrap_or_else(|| panic!("not a JPEG data URL: {}", &url[..40.min(url.len())]));
    let jpeg = base64::engine::general_purpose::STANDARD
        .decode(data)
        .unwrap();
    let call_id = messages
        .iter()
        .rev()
        .find(|m| m["role"] == "tool" && m["name"] == "get_camera_image")
        .and_then(|m| m["tool_call_id"].as_str())
        .expect("the tool's result")
        .to_owned();
    (jpeg, call_id)
}

/// Width and height of a JPEG file.
fn size_of(jpeg: &[u8]) -> (u32, u32) {
    let image = image::load_from_memory_with_format(jpeg, image::ImageFormat::Jpeg)
        .expect("a JPEG the tool returned");
    (image.width(), image.height())
}

/// The `agent` events of a chat request's Server-Sent Events, in order.
fn agent_events(sse: &str) -> Vec<Value> {
    sse.split("\n\n")
        .filter(|block| block.lines().any(|l| l == "event: agent"))
        .map(|block| {
            let data: String = block
                .lines()
                .filter_map(|l| l.strip_prefix("data:"))
                .map(str::trim_start)
                .collect();
            serde_json::from_str(&data).unwrap_or_else(|e| panic!("{e}: {data}"))
        })
        .collect()
}

#[test]
fn the_chat_shows_the_picture_the_agent_looked_at() {
    common::runtime().block_on(async {
        let mock = MockLlm::start(vec![
            // The browser's request.
            MockReply::plan_and_call(
                "I will look at the table first.",
                "get_camera_image",
                json!({}),
            ),
            MockReply::text("I see the objects on the table."),
            // The API's request.
            MockReply::tool_call("get_camera_image", json!({"max_width": 320})),
            MockReply::text("Looked again."),
        ])
        .await
        .unwrap();
        let namespace = common::fresh_namespace("chatpicture");
        let port = common::free_port();
        let base_url = mock.openai_base_url();
        // gpt-4o-mini, the openai default, takes images; no other provider is configured.
        let env = [
            ("OPENAI_API_KEY", "sk-test-dashboard"),
            ("OPENAI_BASE_URL", base_url.as_str()),
            ("GROQ_API_KEY", ""),
            ("GEMINI_API_KEY", ""),
            ("API_KEY", ""),
            ("LLM_API_KEY", ""),
        ];
        let _robotd = common::start_robotd_with_env(&namespace, port, &[], &env);
        let root = format!("http://127.0.0.1:{port}");

        let browser = browser::Browser::start().await;
        browser.open(&format!("{root}/")).await;
        browser
            .wait_for(
                "the agent ready",
                "return !document.getElementById('chat-send').disabled",
                Duration::from_secs(20),
            )
            .await;
        browser
            .type_into("#chat-input", "what is on the table?")
            .await;
        browser.click("#chat-send").await;
        let log = browser
            .wait_for(
                "the agent's answer",
                "const t = document.getElementById('chat-log').innerText; \
                 return t.includes('I see the objects') ? t : ''",
                Duration::from_secs(60),
            )
            .await;
        assert!(log.as_str().unwrap().contains("← ✓"), "{log}");
        // The picture in the chat, loaded.
        let shown = browser
            .wait_for(
                "the picture in the chat",
                "const i = document.querySelector('#chat-log img.chat-picture'); \
                 return i && i.complete && i.naturalWidth > 0 ? \
                   {width: i.naturalWidth, height: i.naturalHeight, call: i.dataset.callId, \
                    shown: i.getBoundingClientRect().width, \
                    after_result: i.previousElementSibling.textContent.startsWith('← ✓')} : null",
                Duration::from_secs(10),
            )
            .await;
        let requests = mock.requests();
        assert_eq!(requests.len(), 2, "two LLM rounds");
        let (jpeg, call_id) = picture_sent(&requests[1].body);
        let (width, height) = size_of(&jpeg);
        assert_eq!(
            (shown["width"].as_u64(), shown["height"].as_u64()),
            (Some(u64::from(width)), Some(u64::from(height))),
            "{shown}"
        );
        assert_eq!(shown["call"], call_id.as_str(), "{shown}");
        assert_eq!(shown["after_result"], true, "under the call's result: {shown}");
        assert!(shown["shown"].as_f64().unwrap() <= 160.5, "a thumbnail: {shown}");
        // The file the page shows, read back in the page: the tool's JPEG, byte for byte.
        let in_page = browser
            .eval_async(
                "const i = document.querySelector('#chat-log img.chat-picture'); \
                 fetch(i.src).then((r) => r.arrayBuffer()).then((b) => { \
                   const u = new Uint8Array(b); let s = ''; \
                   for (let k = 0; k < u.length; k += 0x8000) \
                     s += String.fromCharCode.apply(null, u.subarray(k, k + 0x8000)); \
                   done(btoa(s)); }).catch((e) => done('failed: ' + e));",
            )
            .await;
        let in_page = base64::engine::general_purpose::STANDARD
            .decode(in_page.as_str().unwrap())
            .unwrap_or_else(|e| panic!("{e}: {in_page}"));
        assert!(in_page == jpeg, "the page shows another file than the tool's");
        browser.screenshot("dashboard-chat-picture").await;
        // A click enlarges it, another shrinks it back.
        browser.click("#chat-log img.chat-picture").await;
        let large = browser
            .wait_for(
                "the picture enlarged",
                "const i = document.querySelector('#chat-log img.chat-picture'); \
                 return i.classList.contains('enlarged') ? i.getBoundingClientRect().width : 0",
                Duration::from_secs(5),
            )
            .await;
        assert!(
            large.as_f64().unwrap() >= f64::from(width.min(400)) - 1.0,
            "shown {large} px wide, the picture is {width}"
        );
        browser.screenshot("dashboard-chat-picture-enlarged").await;
        browser.click("#chat-log img.chat-picture").await;
        browser
            .wait_for(
                "the picture small again",
                "const i = document.querySelector('#chat-log img.chat-picture'); \
                 return !i.classList.contains('enlarged') && i.getBoundingClientRect().width <= 160.5",
                Duration::from_secs(5),
            )
            .await;
        browser.close().await;

        // The API: the picture event right after the call's result, with a URL, no bytes.
        let http = reqwest::Client::new();
        let sse = http
            .post(format!("{root}/api/chat"))
            .json(&json!({"text": "look again"}))
            .send()
            .await
            .unwrap();
        assert_eq!(sse.status(), 200);
        let events = agent_events(&sse.text().await.unwrap());
        let kinds: Vec<&str> = events
            .iter()
            .map(|e| e["event"]["kind"].as_str().unwrap_or("?"))
            .collect();
        assert_eq!(
            kinds,
            ["tool_call", "tool_result", "picture", "answer"],
            "{events:?}"
        );
        let seqs: Vec<u64> = events.iter().filter_map(|e| e["seq"].as_u64()).collect();
        assert_eq!(seqs, [0, 1, 2, 3]);
        let picture = &events[2]["event"];
        let (jpeg, call_id) = picture_sent(&mock.requests()[3].body);
        assert!(size_of(&jpeg).0 <= 320, "the second look asked for 320 px");
        assert_eq!(picture["call_id"], call_id.as_str(), "{picture}");
        assert_eq!(events[0]["event"]["call_id"], call_id.as_str());
        assert_eq!(picture["name"], "get_camera_image");
        assert_eq!(picture["mime_type"], "image/jpeg");
        assert_eq!(picture["shown_to_model"], true);
        assert_eq!(picture["bytes"].as_u64(), Some(jpeg.len() as u64));
        assert!(picture.get("data_base64").is_none(), "{picture}");
        let url = picture["url"].as_str().unwrap();
        let id = url.strip_prefix("/api/chat/pictures/").expect(url);
        assert!(
            id.len() == 16 && id.bytes().all(|b| b.is_ascii_hexdigit()),
            "{url}"
        );
        let served = http.get(format!("{root}{url}")).send().await.unwrap();
        assert_eq!(served.status(), 200);
        assert_eq!(served.headers()["content-type"], "image/jpeg");
        assert!(
            served.bytes().await.unwrap().as_ref() == jpeg.as_slice(),
            "the URL serves another file than the tool's"
        );
        for missing in ["0000000000000000", "not-a-picture", "..%2F..%2Fetc"] {
            let reply = http
                .get(format!("{root}/api/chat/pictures/{missing}"))
                .send()
                .await
                .unwrap();
            assert_eq!(reply.status(), 404, "{missing}");
        }
    });
}
