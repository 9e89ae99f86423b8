//! `[tts]`: the speech engine, voice, rate, audio output and queue.

use robotd_runtime::config::{Checks, Section};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// `[tts]`
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TtsConfig {
    /// "auto", "espeak-ng", "elevenlabs" or "none".
    pub engine: String,
    /// espeak-ng voice.
    pub voice: String,
    /// espeak-ng speed, words per minute (80 … 450).
    pub rate_wpm: u32,
    /// "auto" (the audio device when there is one, else the spool), "device" or "spool".
    pub output: String,
    /// Directory of the WAV spool.
    pub spool_dir: PathBuf,
    /// Largest size of the spool, MB (oldest files are deleted first).
    pub spool_max_mb: u64,
    /// Texts that may wait (1 … 1000).
    pub queue_capacity: usize,
    /// The same text within this many ms is spoken once.
    pub duplicate_window_ms: u64,
    /// Base URL of the ElevenLabs API.
    pub elevenlabs_base_url: String,
    /// ElevenLabs voice id.
    pub elevenlabs_voice_id: String,
    /// ElevenLabs model id.
    pub elevenlabs_model_id: String,
}

impl Default for TtsConfig {
    fn default() -> Self {
        Self {
            engine: "auto".into(),
            voice: "en".into(),
            rate_wpm: 160,
            output: "auto".into(),
            spool_dir: PathBuf::from("log/speech"),
            spool_max_mb: 50,
            queue_capacity: 50,
            duplicate_window_ms: 2000,
            elevenlabs_base_url: "https://api.elevenlabs.io".into(),
            elevenlabs_voice_id: "21m00Tcm4TlvDq8ikWAM".into(),
            elevenlabs_model_id: "eleven_multilingual_v2".into(),
        }
    }
}

impl Section for TtsConfig {
    fn check(&self, checks: &mut Checks) {
        if !["auto", "espeak-ng", "elevenlabs", "none"].contains(&self.engine.as_str()) {
            checks.problem(
                "engine",
                format!(
                    "unknown value \"{}\"; expected one of \"auto\", \"espeak-ng\", \"elevenlabs\", \"none\"",
                    self.engine
                ),
            );
        }
        if !["auto", "device", "spool"].contains(&self.output.as_str()) {
            checks.problem(
                "output",
                format!(
                    "unknown value \"{}\"; expected one of \"auto\", \"device\", \"spool\"",
                    self.output
                ),
            );
        }
        checks.range_u64("rate_wpm", self.rate_wpm.into(), 80..=450, "");
        checks.range_u64("queue_capacity", self.queue_capacity as u64, 1..=1000, "");
        if self.duplicate_window_ms > 600_000 {
            checks.problem(
                "duplicate_window_ms",
                format!(
                    "must be at most 600000 ms, got {}",
                    self.duplicate_window_ms
                ),
            );
        }
        checks.range_u64("spool_max_mb", self.spool_max_mb, 1..=100_000, "");
        if self.voice.trim().is_empty() || self.voice.starts_with('-') {
            checks.problem(
                "voice",
                format!(
                    "must be an espeak-ng voice name such as \"en\", got \"{}\"",
                    self.voice
                ),
            );
        }
    }
}
