//! What the robot hears: speech to text.
//!
//! The STT actor (a Python actor on the bus, `python -m robotd.stt`, built on faster-whisper)
//! serves `stt/transcribe`: a [`TranscribeRequest`] carries audio — raw 16 kHz mono 16-bit
//! PCM, or the bytes of a WAV, WebM or Ogg file — and the reply is a [`TranscribeReply`]: the
//! [`Transcript`] (text, language, per-segment times, a confidence) or an [`SttError`] that
//! says what was wrong with the audio. Every transcript is also published on
//! `stt/transcripts`, so the dashboard, the agent and recordings see what was heard, and how
//! the actor is doing (model, counts, last error) on `stt/status` ([`SttStatus`]).
//!
//! ```
//! use robotd_protocol::stt::{AudioFormat, TranscribeRequest, MAX_AUDIO_BYTES};
//! use robotd_protocol::validate::Validate;
//!
//! let pcm = TranscribeRequest::pcm16k(vec![0; 32_000], "dashboard");
//! assert!(pcm.validate().is_ok());
//! assert_eq!(pcm.format, AudioFormat::PcmS16le);
//! assert!(TranscribeRequest::file(Vec::new(), "dashboard").validate().is_err());
//! assert!(TranscribeRequest::file(vec![0; MAX_AUDIO_BYTES + 1], "x").validate().is_err());
//! ```

use crate::envelope::Message;
use crate::validate::{non_empty, Validate, ValidationError};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Largest audio one request may carry, bytes: 31 s of 16 kHz 16-bit PCM, minutes of
/// compressed speech. The bus admits requests of up to 1 MiB; this leaves room for the
/// envelope.
pub const MAX_AUDIO_BYTES: usize = 1_000_000;

/// The only sample rate raw PCM is accepted at, Hz (what Whisper listens at).
pub const PCM_SAMPLE_RATE_HZ: u32 = 16_000;

/// Longest `source` name, bytes.
pub const MAX_SOURCE_BYTES: usize = 64;

/// How the request's audio is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum AudioFormat {
    /// Raw samples: mono, signed 16-bit little-endian, at `sample_rate_hz` (must be 16,000).
    PcmS16le,
    /// The bytes of an audio file: WAV, WebM or Ogg (Opus or Vorbis), as a browser's
    /// MediaRecorder or a recorder writes it; the container says its rate and channels.
    File,
}

/// Transcribe this audio (`stt/transcribe`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TranscribeRequest {
    /// The audio, at most [`MAX_AUDIO_BYTES`].
    #[serde(with = "serde_bytes")]
    #[schemars(with = "Vec<u8>")]
    pub audio: Vec<u8>,
    /// How `audio` is encoded.
    pub format: AudioFormat,
    /// Sample rate of raw PCM, Hz (16,000); ignored for files.
    pub sample_rate_hz: u32,
    /// Who asks (`"dashboard"`, `"listen"`, a process name): carried into the transcript.
    pub source: String,
}

impl TranscribeRequest {
    /// Raw 16 kHz mono 16-bit little-endian samples.
    pub fn pcm16k(audio: Vec<u8>, source: impl Into<String>) -> Self {
        Self {
            audio,
            format: AudioFormat::PcmS16le,
            sample_rate_hz: PCM_SAMPLE_RATE_HZ,
            source: source.into(),
        }
    }

    /// An audio file's bytes (WAV, WebM, Ogg).
    pub fn file(audio: Vec<u8>, source: impl Into<String>) -> Self {
        Self {
            audio,
            format: AudioFormat::File,
            sample_rate_hz: 0,
            source: source.into(),
        }
    }
}

impl Validate for TranscribeRequest {
    fn validate(&self) -> Result<(), ValidationError> {
        non_empty("source", &self.source)?;
        if self.source.len() > MAX_SOURCE_BYTES {
            return Err(invalid(
                "source",
                format!("at most {MAX_SOURCE_BYTES} bytes"),
            ));
        }
        if self.audio.is_empty() {
            return Err(invalid("audio", "no audio (0 bytes)".into()));
        }
        if self.audio.len() > MAX_AUDIO_BYTES {
            return Err(invalid(
                "audio",
                format!(
                    "{} bytes is more than the {MAX_AUDIO_BYTES} one request may carry",
                    self.audio.len()
                ),
            ));
        }
        Ok(())
    }
}

fn invalid(field: &str, reason: String) -> ValidationError {
    ValidationError::Invalid {
        field: field.into(),
        reason,
    }
}

impl Message for TranscribeRequest {
    const TYPE: &'static str = "stt.transcribe";
}

/// One stretch of speech in a [`Transcript`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Segment {
    /// Start, seconds from the beginning of the audio.
    pub start_s: f64,
    /// End, seconds from the beginning of the audio.
    pub end_s: f64,
    /// What was said in it.
    pub text: String,
    /// How sure the model is of it, 0 … 1 (the mean token probability).
    pub confidence: f64,
}

/// What was heard in one request's audio (the reply of `stt/transcribe`, and a message on
/// `stt/transcripts`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Transcript {
    /// The whole text, trimmed; empty when nothing was said.
    pub text: String,
    /// The language, ISO 639-1 (`"en"`).
    pub language: String,
    /// The segments, in order.
    pub segments: Vec<Segment>,
    /// How sure the model is of the whole text, 0 … 1 (segments weighted by length; 0 when
    /// nothing was said).
    pub confidence: f64,
    /// Length of the audio, seconds.
    pub audio_s: f64,
    /// Time from the request's arrival to its text, seconds (decoding included).
    pub processing_s: f64,
    /// The model that heard it (a faster-whisper name or a directory's name).
    pub model: String,
    /// The request's `source`.
    pub source: String,
}

impl Message for Transcript {
    const TYPE: &'static str = "stt.transcript";
}

/// What was wrong with a request's audio.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SttErrorKind {
    /// No audio, or no samples in it.
    Empty,
    /// More bytes than [`MAX_AUDIO_BYTES`].
    TooLarge,
    /// Longer than the actor's duration limit.
    TooLong,
    /// Not audio the actor can decode (not WAV, WebM or Ogg; a broken file; odd PCM).
    NotAudio,
    /// Raw PCM at another rate than 16 kHz, or a file at an unusable rate.
    WrongSampleRate,
    /// The model failed on it.
    Failed,
}

/// Why a request was not transcribed; `message` is meant for a person.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema, thiserror::Error)]
#[error("{message}")]
pub struct SttError {
    /// What kind of problem.
    pub kind: SttErrorKind,
    /// What was wrong and what to do.
    pub message: String,
}

/// The reply of `stt/transcribe`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum TranscribeReply {
    /// What was heard.
    Transcript {
        /// The transcript.
        transcript: Transcript,
    },
    /// Why nothing was transcribed.
    Error {
        /// The reason.
        error: SttError,
    },
}

impl Message for TranscribeReply {
    const TYPE: &'static str = "stt.reply";
}

/// How the STT actor is doing (`stt/status`): published when its model is loaded and after
/// every request, so `/health` and `/metrics` show what it loaded and how it listens. The
/// counts are the running process's: they start again at 0 when the actor restarts (a new
/// `pid`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SttStatus {
    /// The actor's process id.
    pub pid: u32,
    /// The model that listens (a faster-whisper name or a directory's name, `"tiny.en"`).
    pub model: String,
    /// Where it was loaded from (the model directory, or the faster-whisper name).
    pub model_path: String,
    /// Whether the model is loaded and the service open.
    pub model_loaded: bool,
    /// Time it took to load the model (and warm it up), seconds.
    pub load_s: f64,
    /// Beam size of the decoding (1: greedy).
    pub beam_size: u32,
    /// Requests transcribed.
    pub utterances: u64,
    /// Requests refused or failed (bad audio, a model failure).
    pub errors: u64,
    /// Seconds of audio transcribed.
    pub audio_s: f64,
    /// Seconds spent transcribing them (decoding included).
    pub processing_s: f64,
    /// Processing time over audio length of the last transcribed request (0 before the first).
    pub last_real_time_factor: f64,
    /// The last refusal or failure, for a person (`None` while there was none).
    pub last_error: Option<String>,
}

impl Message for SttStatus {
    const TYPE: &'static str = "stt.status";
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::envelope::{decode, encode, Envelope};

    #[test]
    fn audio_travels_as_msgpack_bin_and_replies_round_trip() {
        let request = TranscribeRequest::pcm16k(vec![1, 2, 3, 4], "test");
        let mut bytes = Vec::new();
        encode(&Envelope::new(request.clone()), &mut bytes).unwrap();
        // bin 8 marker (0xc4) with length 4, then the bytes: not an array of integers.
        assert!(bytes.windows(6).any(|w| w == [0xc4, 4, 1, 2, 3, 4]));
        assert_eq!(decode::<TranscribeRequest>(&bytes).unwrap().body, request);

        let reply = TranscribeReply::Error {
            error: SttError {
                kind: SttErrorKind::TooLong,
                message: "600.0 s of audio".into(),
            },
        };
        let json = serde_json::to_value(&reply).unwrap();
        assert_eq!(json["kind"], "error");
        assert_eq!(json["error"]["kind"], "too_long");
    }

    #[test]
    fn requests_are_checked() {
        assert!(TranscribeRequest::pcm16k(vec![0; 2], "")
            .validate()
            .is_err());
        assert!(TranscribeRequest::pcm16k(vec![0; 2], "x".repeat(65))
            .validate()
            .is_err());
        assert!(TranscribeRequest::file(vec![0; MAX_AUDIO_BYTES], "x")
            .validate()
            .is_ok());
    }
}
