//! A WebDriver session of one headless Debian `chromium`, driven by `chromedriver`, for the
//! dashboard's browser tests: open a page, run script in it, wait for what it shows, click,
//! type, and keep screenshots in `target/test-artifacts/`.
#![allow(dead_code)]

use super::common;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A WebDriver session of one headless chromium; chromium and its driver stop when dropped.
pub struct Browser {
    http: reqwest::Client,
    base: String,
    driver: common::Running,
}

impl Drop for Browser {
    fn drop(&mut self) {
        // chromium is chromedriver's child: stop it first, or a failed test leaves it running.
        let _ = Command::new("pkill")
            .args(["-TERM", "-P", &self.driver.pid().to_string()])
            .status();
    }
}

impl Browser {
    /// Starts chromedriver on a free port and a headless chromium session (1280×1000).
    pub async fn start() -> Browser {
        Browser::start_with(&[]).await
    }

    /// The same, with more chromium switches (a fake microphone, say).
    pub async fn start_with(extra_args: &[String]) -> Browser {
        let port = common::free_port();
        let child = Command::new("chromedriver")
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromedriver (apt install chromium-driver; ./scripts/test.sh does)");
        let driver = common::Running::new(child, "chromedriver");
        robotd_runtime::telemetry::install_tls_provider();
        let http = reqwest::Client::new();
        let root = format!("http://127.0.0.1:{port}");
        let deadline = Instant::now() + Duration::from_secs(20);
        while http.get(format!("{root}/status")).send().await.is_err() {
            assert!(Instant::now() < deadline, "chromedriver did not start");
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        let mut args: Vec<String> = [
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--window-size=1280,1000",
        ]
        .map(String::from)
        .to_vec();
        args.extend_from_slice(extra_args);
        let capabilities = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": {"binary": "/usr/bin/chromium", "args": args}
        }}});
        let reply: Value = http
            .post(format!("{root}/session"))
            .json(&capabilities)
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        let session = reply["value"]["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("no WebDriver session: {reply}"));
        Browser {
            base: format!("{root}/session/{session}"),
            http,
            driver,
        }
    }

    /// Sends a WebDriver command; its `value`, or a panic with the driver's error.
    pub async fn command(&self, path: &str, body: Value) -> Value {
        let reply: Value = self
            .http
            .post(format!("{}{path}", self.base))
            .json(&body)
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        if reply["value"]["error"].is_string() {
            panic!("WebDriver {path}: {reply}");
        }
        reply["value"].clone()
    }

    /// Opens `url`.
    pub async fn open(&self, url: &str) {
        self.command("/url", json!({ "url": url })).await;
    }

    /// Runs `script` (a function body) in the page and returns its value.
    pub async fn eval(&self, script: &str) -> Value {
        self.command("/execute/sync", json!({"script": script, "args": []}))
            .await
    }

    /// Runs `script` (a function body that ends by calling `done(value)`) in the page and
    /// returns the value it passed.
    pub async fn eval_async(&self, script: &str) -> Value {
        let script = format!("const done = arguments[arguments.length - 1]; {script}");
        self.command("/execute/async", json!({"script": script, "args": []}))
            .await
    }

    /// Waits until `script` returns something truthy; returns it.
    pub async fn wait_for(&self, what: &str, script: &str, within: Duration) -> Value {
        let deadline = Instant::now() + within;
        loop {
            let value = self.eval(script).await;
            let truthy = !matches!(&value, Value::Null | Value::Bool(false))
                && value != json!(0)
                && value != json!("");
            if truthy {
                return value;
            }
            assert!(Instant::now() < deadline, "the page never showed {what}");
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    }

    /// The WebDriver id of the first element matching `css`.
    pub async fn element(&self, css: &str) -> String {
        let found = self
            .command("/element", json!({"using": "css selector", "value": css}))
            .await;
        found
            .as_object()
            .and_then(|o| o.values().next())
            .and_then(Value::as_str)
            .unwrap_or_else(|| panic!("no element {css}: {found}"))
            .to_owned()
    }

    /// Accepts the page's open `confirm()`/`alert()` dialog.
    pub async fn accept_dialog(&self) {
        self.command("/alert/accept", json!({})).await;
    }

    /// Clicks the first element matching `css`.
    pub async fn click(&self, css: &str) {
        let id = self.element(css).await;
        self.command(&format!("/element/{id}/click"), json!({}))
            .await;
    }

    /// Types `text` into the first element matching `css`.
    pub async fn type_into(&self, css: &str, text: &str) {
        let id = self.element(css).await;
        self.command(&format!("/element/{id}/value"), json!({ "text": text }))
            .await;
    }

    /// Saves a screenshot as `target/test-artifacts/<name>.png`.
    pub async fn screenshot(&self, name: &str) -> PathBuf {
        use base64::Engine;
        let reply: Value = self
            .http
            .get(format!("{}/screenshot", self.base))
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        let png = base64::engine::general_purpose::STANDARD
            .decode(reply["value"].as_str().unwrap())
            .unwrap();
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/test-artifacts");
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!("{name}.png"));
        std::fs::write(&path, png).unwrap();
        path
    }

    /// Ends the session.
    pub async fn close(&self) {
        let _ = self.http.delete(&self.base).send().await;
    }
}
