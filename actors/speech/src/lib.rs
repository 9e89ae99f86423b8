//! robotd's voice: the text-to-speech actor.
//!
//! Anyone on the bus (the `speak` tool, the skills announcing "Going to pick the pencil…", the
//! agent) publishes a [`SpeakRequest`] on `speech/speak` and goes on at once — speaking never
//! blocks a motion. The actor keeps a [`queue::SpeechQueue`] (priority, then age; bounded;
//! duplicates within a window said once), speaks one text at a time through an
//! [`engine::SpeechEngine`] running under a supervisor (an engine that crashes is restarted and
//! costs only the text in hand), sends the audio to the device or the WAV spool
//! ([`output`]), and reports every step on `speech/events` ([`SpeechEvent`]) and each
//! utterance as a `robot_speech` overlay on `overlay/text`.
//!
//! Engines are chosen by configuration ([`choose_engine`]): ElevenLabs when a key is set,
//! espeak-ng when installed, otherwise `none`, which only logs — with one warning saying so.
//!
//! The ElevenLabs engine uses the HTTP client already in robotd's dependency tree (reqwest,
//! blocking) with HTTPS by rustls on the `ring` provider, checking certificates against the
//! system's roots.

pub mod config;
pub use config::TtsConfig;

pub mod engine;
pub mod output;
pub mod queue;

use engine::{ElevenLabsEngine, EngineError, EspeakEngine, NoneEngine, SpeechEngine, Utterance};
use kameo::prelude::*;
use output::{find_device_player, Output, Spool};
use queue::{Rejected, SpeechQueue};
use robotd_protocol::speech::{OverlayKind, SpeakRequest, SpeechEvent, TextOverlay};
use robotd_protocol::validate::Validate;
use robotd_runtime::bus::{Bus, BusError, Publisher};
use robotd_runtime::supervision::{Supervised, SupervisedError, SupervisionObserver, Supervisor};
use robotd_topics::{OVERLAY_TEXT, SPEECH_EVENTS, SPEECH_SPEAK};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::Notify;

/// The environment variable holding the ElevenLabs key.
pub const ELEVENLABS_KEY_VAR: &str = "ELEVENLABS_API_KEY";

/// Picks the engine `config.engine` asks for. With `"auto"`: ElevenLabs when `api_key` is
/// set, else espeak-ng when it runs, else `none` — the second value is then the warning to
/// log once. An explicitly chosen engine that is unavailable is an error.
pub fn choose_engine(
    config: &TtsConfig,
    api_key: Option<&str>,
) -> Result<(Arc<dyn SpeechEngine>, Option<String>), EngineError> {
    let elevenlabs = |key: &str| -> Result<Arc<dyn SpeechEngine>, EngineError> {
        Ok(Arc::new(ElevenLabsEngine::new(
            &config.elevenlabs_base_url,
            key,
            &config.elevenlabs_voice_id,
            &config.elevenlabs_model_id,
        )?))
    };
    let espeak = || -> Result<Arc<dyn SpeechEngine>, EngineError> {
        Ok(Arc::new(EspeakEngine::new(&config.voice, config.rate_wpm)?))
    };
    match config.engine.as_str() {
        "none" => Ok((Arc::new(NoneEngine), None)),
        "espeak-ng" => Ok((espeak()?, None)),
        "elevenlabs" => Ok((elevenlabs(api_key.unwrap_or(""))?, None)),
        _ => {
            let mut reasons = Vec::new();
            if let Some(key) = api_key.filter(|k| !k.trim().is_empty()) {
                match elevenlabs(key) {
                    Ok(e) => return Ok((e, None)),
                    Err(e) => reasons.push(e.to_string()),
                }
            }
            match espeak() {
                Ok(e) => return Ok((e, None)),
                Err(e) => reasons.push(e.to_string()),
            }
            Ok((
                Arc::new(NoneEngine),
                Some(format!(
                    "no speech engine is available, texts will only be logged ({})",
                    reasons.join("; ")
                )),
            ))
        }
    }
}

/// Where audio goes per `config.output`: `"spool"`, `"device"` (an error without one) or
/// `"auto"` (the device when there is one, else the spool).
pub fn choose_output(config: &TtsConfig) -> Result<Output, EngineError> {
    let spool = Output::Spool(Spool {
        dir: config.spool_dir.clone(),
        max_bytes: config.spool_max_mb.saturating_mul(1024 * 1024),
    });
    match config.output.as_str() {
        "spool" => Ok(spool),
        "device" => find_device_player()
            .map(|player| Output::Device { player })
            .ok_or_else(|| {
                EngineError::Output(
                    "tts.output = \"device\" but this machine has no audio device \
                     (neither PulseAudio nor an ALSA card); use \"auto\" or \"spool\""
                        .into(),
                )
            }),
        _ => Ok(find_device_player()
            .map(|player| Output::Device { player })
            .unwrap_or(spool)),
    }
}

/// The supervised engine: one text at a time, on a blocking thread.
#[derive(Actor)]
pub struct EngineActor {
    engine: Arc<dyn SpeechEngine>,
}

impl EngineActor {
    /// An actor around `engine`.
    pub fn new(engine: Arc<dyn SpeechEngine>) -> Self {
        Self { engine }
    }
}

/// Synthesise this text.
#[derive(Debug, Clone)]
pub struct Synthesize(pub String);

impl Message<Synthesize> for EngineActor {
    type Reply = Result<Utterance, EngineError>;

    async fn handle(&mut self, msg: Synthesize, _: &mut Context<Self, Self::Reply>) -> Self::Reply {
        let engine = self.engine.clone();
        match tokio::task::spawn_blocking(move || engine.synthesize(&msg.0)).await {
            Ok(result) => result,
            // A panicking engine takes its actor down: the supervisor restarts it.
            Err(join) if join.is_panic() => std::panic::resume_unwind(join.into_panic()),
            Err(join) => Err(EngineError::Failed {
                engine: self.engine.name(),
                reason: join.to_string(),
            }),
        }
    }
}

/// How the speech actor starts.
#[derive(Clone)]
pub struct SpeechSettings {
    /// The engine.
    pub engine: Arc<dyn SpeechEngine>,
    /// Where audio goes.
    pub output: Output,
    /// Directory for the file being played.
    pub scratch_dir: PathBuf,
    /// Queue capacity.
    pub queue_capacity: usize,
    /// Same text within this window is said once.
    pub duplicate_window: Duration,
    /// Restart policy of the engine actor.
    pub policy: robotd_runtime::supervision::SupervisionPolicy,
}

/// The speech actor could not start.
#[derive(Debug, thiserror::Error)]
pub enum SpeechStartError {
    /// A bus port could not be opened.
    #[error("speech: cannot open its bus ports: {0}")]
    Bus(#[from] BusError),
    /// The engine actor did not start.
    #[error("speech: the engine actor did not start: {0}")]
    Engine(String),
}

/// The running speech actor.
pub struct Speech {
    /// The supervised engine actor.
    pub engine: Supervised<EngineActor>,
    engine_name: &'static str,
    stop: Arc<Notify>,
    task: tokio::task::JoinHandle<()>,
}

impl std::fmt::Debug for Speech {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Speech")
            .field("engine", &self.engine_name)
            .finish_non_exhaustive()
    }
}

struct Outlets {
    events: Publisher<SpeechEvent>,
    overlays: Publisher<TextOverlay>,
}

impl Outlets {
    fn event(&self, event: SpeechEvent) {
        if let Err(error) = self.events.publish(&event) {
            tracing::debug!(%error, "speech: publishing an event failed");
        }
    }
}

impl Speech {
    /// Starts the actor on `bus`; its ports are open on return.
    pub async fn start<O: SupervisionObserver>(
        bus: &Bus,
        settings: SpeechSettings,
        observer: O,
    ) -> Result<Speech, SpeechStartError> {
        let mut requests = bus.subscriber(&SPEECH_SPEAK)?;
        let outlets = Arc::new(Outlets {
            events: bus.publisher(&SPEECH_EVENTS)?,
            overlays: bus.publisher(&OVERLAY_TEXT)?,
        });
        let engine_for_actor = settings.engine.clone();
        let engine = Supervisor::new("tts")
            .policy(settings.policy.clone())
            .observer(observer)
            .spawn_actor::<EngineActor>(move || EngineActor::new(engine_for_actor.clone()))
            .await
            .map_err(|e| SpeechStartError::Engine(e.to_string()))?;
        let engine_name = settings.engine.name();
        // A text that finds the engine restarting waits this long for it (the longest backoff
        // and a margin) instead of being lost with the one that crashed it.
        let restart_wait = settings.policy.backoff_max + Duration::from_secs(1);
        let stop = Arc::new(Notify::new());
        let task = {
            let engine = engine.clone();
            let stop = stop.clone();
            tokio::spawn(async move {
                let mut queue =
                    SpeechQueue::new(settings.queue_capacity, settings.duplicate_window);
                let mut speaking: Option<tokio::task::JoinHandle<()>> = None;
                loop {
                    tokio::select! {
                        _ = stop.notified() => break,
                        received = requests.recv() => match received {
                            Ok(message) => {
                                let request: SpeakRequest = message.body;
                                if let Err(e) = request.validate() {
                                    outlets.event(SpeechEvent::Dropped {
                                        text: request.text,
                                        reason: format!("invalid request: {e}"),
                                    });
                                } else {
                                    let dropped = queue.push(
                                        &request.text,
                                        request.priority,
                                        &request.source,
                                        Instant::now(),
                                    );
                                    report_rejected(&outlets, dropped, settings.queue_capacity);
                                }
                            }
                            Err(error) => tracing::warn!(%error, "speech: a request could not be read"),
                        },
                        _ = async {
                            if let Some(handle) = speaking.as_mut() {
                                let _ = handle.await;
                            }
                        }, if speaking.is_some() => speaking = None,
                    }
                    if speaking.is_none() {
                        if let Some(next) = queue.pop() {
                            speaking = Some(tokio::spawn(speak_one(
                                next.text,
                                engine.clone(),
                                restart_wait,
                                settings.output.clone(),
                                settings.scratch_dir.clone(),
                                outlets.clone(),
                            )));
                        }
                    }
                }
                if let Some(handle) = speaking {
                    handle.abort();
                }
            })
        };
        tracing::info!(engine = engine_name, "speech started");
        Ok(Speech {
            engine,
            engine_name,
            stop,
            task,
        })
    }

    /// The engine's name.
    pub fn engine_name(&self) -> &'static str {
        self.engine_name
    }

    /// Stops the actor.
    pub async fn shutdown(self) {
        self.stop.notify_one();
        let _ = self.task.await;
    }
}

fn report_rejected(outlets: &Outlets, rejected: Option<Rejected>, capacity: usize) {
    match rejected {
        None => {}
        Some(Rejected::Duplicate(text)) => outlets.event(SpeechEvent::Dropped {
            text,
            reason: "duplicate: the same text was asked for moments ago".into(),
        }),
        Some(Rejected::QueueFull(item)) => {
            tracing::warn!(text = %item.text, priority = item.priority, "speech queue full: dropped the lowest-priority oldest text");
            outlets.event(SpeechEvent::Dropped {
                text: item.text,
                reason: format!(
                    "queue full ({capacity} texts): lowest priority ({}) and oldest",
                    item.priority
                ),
            });
        }
    }
}

/// Has the supervised engine synthesise `text`. A text that finds the engine restarting (it
/// was not delivered, so nothing ran) waits once for the restart and is sent again; only the
/// text the engine crashed on is lost.
async fn synthesize(
    engine: &Supervised<EngineActor>,
    text: &str,
    restart_wait: Duration,
) -> Result<Utterance, String> {
    let mut waited = false;
    loop {
        match engine.ask(Synthesize(text.to_owned())).await {
            Ok(utterance) => return Ok(utterance),
            Err(SupervisedError::Restarting { .. }) if !waited => {
                waited = true;
                if let Err(error) = engine.wait_ready(restart_wait).await {
                    return Err(format!(
                        "the speech engine did not come back from a restart: {error}"
                    ));
                }
            }
            Err(SupervisedError::ActorFailed { reason, .. }) => {
                return Err(format!(
                    "the speech engine crashed on this text ({reason}); it is restarted for the \
                     next one"
                ))
            }
            Err(SupervisedError::Handler { error, .. }) => {
                return Err(format!("speech engine: {error}"))
            }
            Err(error) => return Err(format!("speech engine: {error}")),
        }
    }
}

async fn speak_one(
    text: String,
    engine: Supervised<EngineActor>,
    restart_wait: Duration,
    output: Output,
    scratch: PathBuf,
    outlets: Arc<Outlets>,
) {
    let started = Instant::now();
    outlets.event(SpeechEvent::Started { text: text.clone() });
    let overlay = TextOverlay::new(text.clone(), OverlayKind::RobotSpeech);
    if let Err(error) = outlets.overlays.publish(&overlay) {
        tracing::debug!(%error, "speech: publishing the overlay failed");
    }
    let outcome = match synthesize(&engine, &text, restart_wait).await {
        Ok(Utterance::Audio(audio)) => {
            match tokio::task::spawn_blocking(move || output.emit(&audio, &scratch)).await {
                Ok(Ok(place)) => Ok(place),
                Ok(Err(e)) => Err(e.to_string()),
                Err(e) => Err(format!("audio output task: {e}")),
            }
        }
        Ok(Utterance::LoggedOnly) => {
            Err("not spoken: no speech engine is available (the text was logged)".into())
        }
        Err(reason) => Err(reason),
    };
    match outcome {
        Ok(place) => {
            tracing::debug!(%text, %place, "spoke");
            outlets.event(SpeechEvent::Finished {
                text,
                duration_ms: started.elapsed().as_millis() as u64,
            });
        }
        Err(reason) => {
            tracing::warn!(%text, %reason, "a text was not spoken");
            outlets.event(SpeechEvent::Dropped { text, reason });
        }
    }
}
