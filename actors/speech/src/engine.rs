//! Speech engines: text in, audio out.
//!
//! - [`EspeakEngine`] runs the `espeak-ng` program (offline, the Debian package) and reads the
//!   WAV it writes to stdout;
//! - [`ElevenLabsEngine`] asks the ElevenLabs HTTP API for 16 kHz PCM (the base URL is
//!   configurable, so tests and proxies can stand in for the real service);
//! - [`NoneEngine`] speaks nothing and says so: it is what robotd falls back to, with one
//!   warning, when no engine is available, so the service still runs.
//!
//! Engines are blocking (a process, an HTTP request); the actor runs them off the async
//! threads.

use std::io::Read;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::Duration;

/// Mono 16-bit audio.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Audio {
    /// Samples per second.
    pub sample_rate: u32,
    /// The samples.
    pub samples: Vec<i16>,
}

impl Audio {
    /// Length in seconds.
    pub fn duration_s(&self) -> f64 {
        self.samples.len() as f64 / f64::from(self.sample_rate.max(1))
    }

    /// Root-mean-square level, 0 … 1 of full scale.
    pub fn rms(&self) -> f64 {
        if self.samples.is_empty() {
            return 0.0;
        }
        let sum: f64 = self
            .samples
            .iter()
            .map(|s| (f64::from(*s) / 32768.0).powi(2))
            .sum();
        (sum / self.samples.len() as f64).sqrt()
    }

    /// Writes the audio as a WAV file.
    pub fn write_wav(&self, path: &std::path::Path) -> Result<(), EngineError> {
        let spec = hound::WavSpec {
            channels: 1,
            sample_rate: self.sample_rate,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        };
        let io = |e: hound::Error| EngineError::Output(format!("{}: {e}", path.display()));
        let mut writer = hound::WavWriter::create(path, spec).map_err(io)?;
        for s in &self.samples {
            writer.write_sample(*s).map_err(io)?;
        }
        writer.finalize().map_err(io)
    }
}

/// What an engine made of a text.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Utterance {
    /// Audio to play.
    Audio(Audio),
    /// Nothing was synthesised (the `none` engine): the text was only logged.
    LoggedOnly,
}

/// An engine could not speak a text.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EngineError {
    /// The engine is not installed or not configured.
    #[error("{engine} is not available: {reason}")]
    Unavailable {
        /// Which engine.
        engine: &'static str,
        /// Why, and what to do.
        reason: String,
    },
    /// The engine ran but failed.
    #[error("{engine} failed: {reason}")]
    Failed {
        /// Which engine.
        engine: &'static str,
        /// What went wrong.
        reason: String,
    },
    /// The audio could not be written or played.
    #[error("audio output: {0}")]
    Output(String),
}

/// Turns text into audio.
pub trait SpeechEngine: Send + Sync + 'static {
    /// The engine's name (`espeak-ng`, `elevenlabs`, `none`).
    fn name(&self) -> &'static str;
    /// Speaks `text` into audio (blocking).
    fn synthesize(&self, text: &str) -> Result<Utterance, EngineError>;
}

/// The `espeak-ng` program.
#[derive(Debug, Clone)]
pub struct EspeakEngine {
    /// The program (found on `PATH` by default).
    pub program: PathBuf,
    /// Voice, e.g. `en` or `en-us`.
    pub voice: String,
    /// Words per minute.
    pub rate_wpm: u32,
    /// Longest a synthesis may take before the process is killed.
    pub timeout: Duration,
}

/// Default [`EspeakEngine::timeout`].
pub const ESPEAK_TIMEOUT: Duration = Duration::from_secs(30);

/// Runs `command` to the end, collecting its output, but kills it after `timeout`.
pub(crate) fn run_with_timeout(
    command: &mut Command,
    timeout: Duration,
) -> std::io::Result<std::process::Output> {
    let mut child = command
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()?;
    let drain = |pipe: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            if let Some(mut pipe) = pipe {
                let _ = pipe.read_to_end(&mut bytes);
            }
            bytes
        })
    };
    let stdout = drain(
        child
            .stdout
            .take()
            .map(|p| Box::new(p) as Box<dyn Read + Send>),
    );
    let stderr = drain(
        child
            .stderr
            .take()
            .map(|p| Box::new(p) as Box<dyn Read + Send>),
    );
    let deadline = std::time::Instant::now() + timeout;
    let status = loop {
        if let Some(status) = child.try_wait()? {
            break status;
        }
        if std::time::Instant::now() >= deadline {
            let _ = child.kill();
            let _ = child.wait();
            return Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!("did not finish within {timeout:?} and was killed"),
            ));
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    Ok(std::process::Output {
        status,
        stdout: stdout.join().unwrap_or_default(),
        stderr: stderr.join().unwrap_or_default(),
    })
}

impl EspeakEngine {
    /// The engine with `voice` and `rate_wpm`, after checking that `espeak-ng` runs.
    pub fn new(voice: &str, rate_wpm: u32) -> Result<Self, EngineError> {
        let engine = Self {
            program: PathBuf::from("espeak-ng"),
            voice: voice.to_owned(),
            rate_wpm,
            timeout: ESPEAK_TIMEOUT,
        };
        let status = Command::new(&engine.program)
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status();
        match status {
            Ok(s) if s.success() => Ok(engine),
            Ok(s) => Err(EngineError::Unavailable {
                engine: "espeak-ng",
                reason: format!("`espeak-ng --version` exited with {s}"),
            }),
            Err(e) => Err(EngineError::Unavailable {
                engine: "espeak-ng",
                reason: format!(
                    "cannot run espeak-ng ({e}); install it with `apt-get install espeak-ng`"
                ),
            }),
        }
    }
}

impl SpeechEngine for EspeakEngine {
    fn name(&self) -> &'static str {
        "espeak-ng"
    }

    fn synthesize(&self, text: &str) -> Result<Utterance, EngineError> {
        let failed = |reason: String| EngineError::Failed {
            engine: "espeak-ng",
            reason,
        };
        let mut command = Command::new(&self.program);
        command
            .args([
                "--stdout",
                "-v",
                &self.voice,
                "-s",
                &self.rate_wpm.to_string(),
                "--",
            ])
            .arg(text)
            .stdin(Stdio::null());
        let output = run_with_timeout(&mut command, self.timeout)
            .map_err(|e| failed(format!("cannot run it: {e}")))?;
        if !output.status.success() {
            return Err(failed(format!(
                "exited with {}: {}",
                output.status,
                String::from_utf8_lossy(&output.stderr).trim()
            )));
        }
        parse_wav(&output.stdout)
            .map(Utterance::Audio)
            .map_err(|e| failed(format!("its output is not a usable WAV: {e}")))
    }
}

/// Reads mono 16-bit PCM from a WAV file's bytes. Tolerates the unknown lengths a streaming
/// writer (espeak-ng on a pipe) puts in the header: the data runs to the end of the bytes.
pub fn parse_wav(bytes: &[u8]) -> Result<Audio, String> {
    if bytes.len() < 12 || &bytes[0..4] != b"RIFF" || &bytes[8..12] != b"WAVE" {
        return Err("no RIFF/WAVE header".into());
    }
    let mut at = 12;
    let mut format: Option<(u16, u16, u32, u16)> = None;
    while at + 8 <= bytes.len() {
        let id = &bytes[at..at + 4];
        let len = u32::from_le_bytes([bytes[at + 4], bytes[at + 5], bytes[at + 6], bytes[at + 7]])
            as usize;
        let body = at + 8;
        if id == b"fmt " {
            if body + 16 > bytes.len() {
                return Err("truncated fmt chunk".into());
            }
            let b = &bytes[body..body + 16];
            format = Some((
                u16::from_le_bytes([b[0], b[1]]),
                u16::from_le_bytes([b[2], b[3]]),
                u32::from_le_bytes([b[4], b[5], b[6], b[7]]),
                u16::from_le_bytes([b[14], b[15]]),
            ));
        } else if id == b"data" {
            let (kind, channels, rate, bits) = format.ok_or("data before fmt")?;
            if kind != 1 || channels != 1 || bits != 16 {
                return Err(format!(
                    "expected mono 16-bit PCM, got format {kind}, {channels} channels, {bits} bits"
                ));
            }
            let end = body.saturating_add(len).min(bytes.len());
            let samples = bytes[body..end]
                .chunks_exact(2)
                .map(|c| i16::from_le_bytes([c[0], c[1]]))
                .collect();
            return Ok(Audio {
                sample_rate: rate,
                samples,
            });
        }
        at = body.saturating_add(len + (len & 1));
    }
    Err("no data chunk".into())
}

/// The ElevenLabs text-to-speech API.
#[derive(Clone)]
pub struct ElevenLabsEngine {
    /// Base URL, e.g. `https://api.elevenlabs.io`.
    pub base_url: String,
    /// The API key (from `ELEVENLABS_API_KEY`; never logged).
    api_key: String,
    /// Voice id.
    pub voice_id: String,
    /// Model id.
    pub model_id: String,
}

/// Shows everything but the key, so the engine can be logged.
impl std::fmt::Debug for ElevenLabsEngine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ElevenLabsEngine")
            .field("base_url", &self.base_url)
            .field("api_key", &"<redacted>")
            .field("voice_id", &self.voice_id)
            .field("model_id", &self.model_id)
            .finish()
    }
}

/// Sample rate asked of ElevenLabs (`output_format=pcm_16000`).
pub const ELEVENLABS_SAMPLE_RATE: u32 = 16_000;

impl ElevenLabsEngine {
    /// An engine talking to `base_url` with `api_key`.
    pub fn new(
        base_url: &str,
        api_key: &str,
        voice_id: &str,
        model_id: &str,
    ) -> Result<Self, EngineError> {
        let unavailable = |reason: String| EngineError::Unavailable {
            engine: "elevenlabs",
            reason,
        };
        if api_key.trim().is_empty() {
            return Err(unavailable(
                "set ELEVENLABS_API_KEY to use ElevenLabs".into(),
            ));
        }
        if !(base_url.starts_with("http://") || base_url.starts_with("https://")) {
            return Err(unavailable(format!(
                "base URL '{base_url}' must start with http:// or https://"
            )));
        }
        robotd_runtime::telemetry::install_tls_provider();
        Ok(Self {
            base_url: base_url.trim_end_matches('/').to_owned(),
            api_key: api_key.to_owned(),
            voice_id: voice_id.to_owned(),
            model_id: model_id.to_owned(),
        })
    }
}

impl SpeechEngine for ElevenLabsEngine {
    fn name(&self) -> &'static str {
        "elevenlabs"
    }

    fn synthesize(&self, text: &str) -> Result<Utterance, EngineError> {
        let failed = |reason: String| EngineError::Failed {
            engine: "elevenlabs",
            reason,
        };
        let url = format!(
            "{}/v1/text-to-speech/{}?output_format=pcm_{ELEVENLABS_SAMPLE_RATE}",
            self.base_url, self.voice_id
        );
        let body = serde_json::json!({ "text": text, "model_id": self.model_id }).to_string();
        // A blocking client owns a small runtime that must be dropped outside async code: it
        // lives only for this call, on the engine's blocking thread.
        let client = reqwest::blocking::Client::builder()
            .timeout(Duration::from_secs(30))
            .build()
            .map_err(|e| failed(format!("HTTP client: {e}")))?;
        let response = client
            .post(&url)
            .header("xi-api-key", &self.api_key)
            .header("content-type", "application/json")
            .header("accept", "audio/pcm")
            .body(body)
            .send()
            .map_err(|e| failed(format!("request to {url}: {e}")))?;
        let status = response.status();
        let mut bytes = Vec::new();
        response
            .take(64 * 1024 * 1024)
            .read_to_end(&mut bytes)
            .map_err(|e| failed(format!("reading the reply: {e}")))?;
        if status.as_u16() == 401 {
            return Err(failed(
                "the API key was rejected (401); check ELEVENLABS_API_KEY".into(),
            ));
        }
        if !status.is_success() {
            return Err(failed(format!(
                "HTTP {status}: {}",
                String::from_utf8_lossy(&bytes[..bytes.len().min(300)])
            )));
        }
        if bytes.len() % 2 != 0 {
            return Err(failed(format!(
                "{} bytes of PCM is not a whole number of 16-bit samples",
                bytes.len()
            )));
        }
        let samples = bytes
            .chunks_exact(2)
            .map(|c| i16::from_le_bytes([c[0], c[1]]))
            .collect();
        Ok(Utterance::Audio(Audio {
            sample_rate: ELEVENLABS_SAMPLE_RATE,
            samples,
        }))
    }
}

/// Speaks nothing: logs the text.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoneEngine;

impl SpeechEngine for NoneEngine {
    fn name(&self) -> &'static str {
        "none"
    }

    fn synthesize(&self, text: &str) -> Result<Utterance, EngineError> {
        tracing::info!(%text, "speech (no engine: logged, not spoken)");
        Ok(Utterance::LoggedOnly)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wav_parsing_accepts_streamed_headers_and_refuses_garbage() {
        let mut wav = Vec::new();
        wav.extend_from_slice(b"RIFF\xff\xff\xff\xffWAVEfmt ");
        wav.extend_from_slice(&16u32.to_le_bytes());
        wav.extend_from_slice(&1u16.to_le_bytes());
        wav.extend_from_slice(&1u16.to_le_bytes());
        wav.extend_from_slice(&22050u32.to_le_bytes());
        wav.extend_from_slice(&44100u32.to_le_bytes());
        wav.extend_from_slice(&2u16.to_le_bytes());
        wav.extend_from_slice(&16u16.to_le_bytes());
        wav.extend_from_slice(b"data\xff\xff\xff\x7f");
        wav.extend_from_slice(&[1, 0, 0xff, 0xff, 7]);
        let audio = parse_wav(&wav).unwrap();
        assert_eq!(audio.sample_rate, 22050);
        assert_eq!(audio.samples, [1, -1]);
        assert!(parse_wav(b"hello").is_err());
        assert!(parse_wav(b"RIFF\0\0\0\0WAVEdata\x02\0\0\0\0\0").is_err());
    }

    #[test]
    fn elevenlabs_needs_a_key_and_a_usable_url() {
        let e = ElevenLabsEngine::new("http://127.0.0.1:1", "", "v", "m").unwrap_err();
        assert!(e.to_string().contains("set ELEVENLABS_API_KEY"), "{e}");
        let e = ElevenLabsEngine::new("ftp://x", "k", "v", "m").unwrap_err();
        assert!(e.to_string().contains("must start with http"), "{e}");
        let engine =
            ElevenLabsEngine::new("https://api.elevenlabs.io", "sk-secret", "v", "m").unwrap();
        let shown = format!("{engine:?}");
        assert!(
            !shown.contains("sk-secret") && shown.contains("redacted"),
            "{shown}"
        );
    }
}
