//! The speech-to-text actor's part of `/health` and `/metrics`.
//!
//! The STT actor is a Python process (`python -m robotd.stt`); the supervisor's generic row
//! says whether it runs. What it does is in the [`SttStatus`] it publishes on `stt/status`
//! when its model is loaded and after every request: this module follows that topic on a
//! thread of its own, keeps the latest status for `/health`'s `stt` part ([`SttHealth::report`])
//! and turns the actor's running totals into robotd's Prometheus series
//! (`robotd_stt_utterances_total`, `robotd_stt_audio_seconds_total`,
//! `robotd_stt_real_time_factor`, …; see `robotd_runtime::metrics`). The actor's counts start
//! at 0 again when it restarts (a new pid); the series keep counting.

use anyhow::{Context, Result};
use robotd_protocol::stt::SttStatus;
use robotd_runtime::bus::Bus;
use robotd_runtime::metrics::Metrics;
use robotd_topics::STT_STATUS;
use std::sync::{Arc, Mutex};
use std::time::Instant;
use tokio_util::sync::CancellationToken;

/// What robotd knows of the STT actor.
pub struct SttHealth {
    /// Whether `[actors.stt]` runs the actor as a process of this robotd.
    configured: bool,
    state: Mutex<State>,
    metrics: Metrics,
    stop: CancellationToken,
}

#[derive(Default)]
struct State {
    /// The latest status and when it arrived.
    latest: Option<(SttStatus, Instant)>,
}

impl SttHealth {
    /// A board without a reader (tests feed it with [`SttHealth::apply`]).
    pub fn new(configured: bool, metrics: Metrics) -> Self {
        Self {
            configured,
            state: Mutex::default(),
            metrics,
            stop: CancellationToken::new(),
        }
    }

    /// Follows `stt/status` on `bus` on a thread of its own; returns once the topic is
    /// subscribed (so the actor's first status, sent when its model is loaded, is seen).
    pub fn start(bus: &Bus, configured: bool) -> Result<Arc<Self>> {
        let health = Arc::new(Self::new(configured, Metrics::global().clone()));
        let (opened, opened_rx) = std::sync::mpsc::channel();
        let (reader, bus) = (health.clone(), bus.clone());
        robotd_runtime::bus::spawn_reader_thread("stt-status", move || async move {
            let mut statuses = match bus.subscriber(&STT_STATUS) {
                Ok(subscriber) => {
                    let _ = opened.send(Ok(()));
                    subscriber
                }
                Err(error) => {
                    let _ = opened.send(Err(error));
                    return;
                }
            };
            loop {
                tokio::select! {
                    _ = reader.stop.cancelled() => break,
                    message = statuses.recv() => match message {
                        Ok(message) => reader.apply(message.body),
                        Err(error) => {
                            tracing::warn!(%error, "stt/status: reading stopped");
                            break;
                        }
                    },
                }
            }
        })
        .context("starting the stt/status reader")?;
        opened_rx
            .recv()
            .context("the stt/status reader ended before subscribing")?
            .context("subscribing to stt/status")?;
        Ok(health)
    }

    /// Takes a status from the actor: keeps it, and adds what it did since its previous
    /// status to the metrics.
    pub fn apply(&self, status: SttStatus) {
        let Ok(mut state) = self.state.lock() else {
            return;
        };
        // The previous totals of the same process; a new process counts from 0.
        let (utterances, errors, audio_s, processing_s) = match &state.latest {
            Some((before, _))
                if before.pid == status.pid && before.utterances <= status.utterances =>
            {
                (
                    before.utterances,
                    before.errors,
                    before.audio_s,
                    before.processing_s,
                )
            }
            _ => (0, 0, 0.0, 0.0),
        };
        self.metrics.stt_model_loaded(status.model_loaded);
        self.metrics.stt_served(
            status.utterances.saturating_sub(utterances),
            status.errors.saturating_sub(errors),
            status.audio_s - audio_s,
            status.processing_s - processing_s,
        );
        if status.utterances > utterances {
            self.metrics
                .stt_real_time_factor(status.last_real_time_factor);
        }
        state.latest = Some((status, Instant::now()));
    }

    /// `/health`'s `stt` part: `{"state": "off"}` without `[actors.stt]`, `"loading"` until
    /// the actor's first status, then what it loaded and what it has done.
    pub fn report(&self) -> serde_json::Value {
        if !self.configured {
            return serde_json::json!({"state": "off"});
        }
        let state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let Some((status, at)) = &state.latest else {
            return serde_json::json!({"state": "loading", "model_loaded": false});
        };
        let real_time_factor = if status.audio_s > 0.0 {
            (status.processing_s / status.audio_s * 1000.0).round() / 1000.0
        } else {
            0.0
        };
        serde_json::json!({
            "state": if status.model_loaded { "ready" } else { "loading" },
            "model_loaded": status.model_loaded,
            "model": status.model,
            "model_path": status.model_path,
            "load_s": status.load_s,
            "beam_size": status.beam_size,
            "pid": status.pid,
            "utterances": status.utterances,
            "errors": status.errors,
            "audio_s": status.audio_s,
            "processing_s": status.processing_s,
            "real_time_factor": real_time_factor,
            "last_real_time_factor": status.last_real_time_factor,
            "last_error": status.last_error,
            "status_age_s": (at.elapsed().as_secs_f64() * 10.0).round() / 10.0,
        })
    }

    /// Stops the reader thread.
    pub fn stop(&self) {
        self.stop.cancel();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(
        pid: u32,
        utterances: u64,
        errors: u64,
        audio_s: f64,
        processing_s: f64,
    ) -> SttStatus {
        SttStatus {
            pid,
            model: "tiny.en".into(),
            model_path: "/models/tiny.en".into(),
            model_loaded: true,
            load_s: 1.5,
            beam_size: 5,
            utterances,
            errors,
            audio_s,
            processing_s,
            last_real_time_factor: 0.5,
            last_error: (errors > 0).then(|| "empty: no audio".into()),
        }
    }

    fn series(metrics: &Metrics, name: &str) -> f64 {
        let text = metrics.render();
        text.lines()
            .find_map(|line| line.strip_prefix(name)?.strip_prefix(' '))
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no {name} in {text}"))
    }

    #[test]
    fn the_report_follows_the_actor_and_the_series_survive_its_restart() {
        let metrics = Metrics::new();
        let health = SttHealth::new(true, metrics.clone());
        assert_eq!(health.report()["state"], "loading");
        health.apply(status(10, 0, 0, 0.0, 0.0));
        health.apply(status(10, 2, 0, 6.0, 2.0));
        health.apply(status(10, 2, 1, 6.0, 2.0));
        let report = health.report();
        assert_eq!(report["state"], "ready");
        assert_eq!(report["model"], "tiny.en");
        assert_eq!(report["utterances"], 2);
        assert_eq!(report["real_time_factor"], 0.333);
        assert_eq!(report["last_error"], "empty: no audio");
        // The actor restarts: its counts begin again, robotd's series keep counting.
        health.apply(status(11, 1, 0, 3.0, 1.5));
        assert_eq!(health.report()["pid"], 11);
        assert_eq!(series(&metrics, "robotd_stt_utterances_total"), 3.0);
        assert_eq!(series(&metrics, "robotd_stt_errors_total"), 1.0);
        assert_eq!(series(&metrics, "robotd_stt_audio_seconds_total"), 9.0);
        assert_eq!(series(&metrics, "robotd_stt_processing_seconds_total"), 3.5);
        assert_eq!(series(&metrics, "robotd_stt_model_loaded"), 1.0);
        assert_eq!(
            SttHealth::new(false, Metrics::new()).report(),
            serde_json::json!({"state": "off"})
        );
    }
}
