//! `robotd listen`: say a command to the robot from the robot PC.
//!
//! Records from the default microphone until the speaker stops (voice activity detection:
//! [`Vad`], energy-based with a hang time), sends the utterance as 16 kHz PCM to the STT
//! actor's bus service `stt/transcribe` (the one `POST /api/voice` uses), then, as the
//! dashboard does with a recording:
//!
//! - a stop phrase at the start (`[voice] stop_words`, on by default: "stop", "emergency
//!   stop") engages the e-stop on `safety/estop` at once, and nothing goes to the LLM;
//! - anything else goes to the running robotd's agent on `agent/request`, as if typed, and the
//!   agent's plan, tool calls and answer are printed as `robotd chat` prints them; the words
//!   are also the current task on `overlay/text` (`user_task`), which the dashboard and
//!   Foxglove show over the video.
//!
//! `--print-only` prints the transcript and does nothing else (no e-stop, no agent).
//!
//! The audio source is pluggable ([`AudioSource`]): the microphone is read through `arecord`
//! (alsa-utils) as a child process — no audio crate to build, no ALSA headers at build time;
//! `--from-file x.wav` reads a WAV file instead, for tests and for replaying a recording (the
//! same voice activity detection cuts the utterance out of it).

use anyhow::{bail, Context, Result};
use clap::Args;
use robotd_config::Config;
use robotd_protocol::agent::{AgentCancel, AgentEventKind, AgentRequest};
use robotd_protocol::health::EmergencyStop;
use robotd_protocol::speech::{OverlayKind, TextOverlay};
use robotd_protocol::stt::{TranscribeReply, TranscribeRequest, Transcript, PCM_SAMPLE_RATE_HZ};
use robotd_runtime::bus::{Bus, BusError, BusOptions};
use robotd_topics::{
    AGENT_CANCEL, AGENT_EVENTS, AGENT_REQUEST, OVERLAY_TEXT, SAFETY_ESTOP, STT_TRANSCRIBE,
};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, ExitCode, Stdio};
use std::time::{Duration, Instant};

/// Samples per analysis frame: 30 ms at 16 kHz.
pub const FRAME: usize = 480;
const FRAME_S: f64 = FRAME as f64 / PCM_SAMPLE_RATE_HZ as f64;

/// How long the agent may take to show it works on a request (its first event).
const AGENT_START_WAIT: Duration = Duration::from_secs(60);

/// Options of `robotd listen`.
#[derive(Debug, Args)]
pub struct ListenArgs {
    /// Print the transcript and do nothing else (no e-stop, no agent).
    #[arg(long)]
    pub print_only: bool,
    /// Read this WAV file instead of the microphone (for tests, and to replay a recording):
    /// PCM 16-bit, mono or stereo, 8-192 kHz.
    #[arg(long, value_name = "WAV")]
    pub from_file: Option<PathBuf>,
    /// The ALSA capture device `arecord` records from.
    #[arg(long, default_value = "default", value_name = "DEVICE")]
    pub device: String,
    /// Silence that ends the utterance, milliseconds (200 … 5000).
    #[arg(long, default_value_t = 800)]
    pub silence_ms: u32,
    /// Sound louder than this is speech, dBFS (-90 … -5); raised to 12 dB over the measured
    /// background noise when that is louder.
    #[arg(long, default_value_t = -40.0, allow_negative_numbers = true)]
    pub threshold_db: f64,
    /// Longest utterance, seconds (1 … 30); the recording stops there.
    #[arg(long, default_value_t = 25.0)]
    pub max_seconds: f64,
    /// How long to wait for speech to begin, seconds (1 … 600).
    #[arg(long, default_value_t = 10.0)]
    pub wait_s: f64,
}

/// How the voice activity detection decides (from [`ListenArgs`]).
#[derive(Debug, Clone, Copy)]
pub struct VadSettings {
    pub silence_ms: u32,
    pub threshold_db: f64,
    pub max_seconds: f64,
    pub wait_s: f64,
}

impl ListenArgs {
    fn settings(&self) -> Result<VadSettings> {
        let check = |ok: bool, what: &str| {
            if ok {
                Ok(())
            } else {
                Err(anyhow::anyhow!("{what}"))
            }
        };
        check(
            (200..=5000).contains(&self.silence_ms),
            "--silence-ms must be 200 … 5000",
        )?;
        check(
            (-90.0..=-5.0).contains(&self.threshold_db),
            "--threshold-db must be -90 … -5 (dBFS)",
        )?;
        check(
            (1.0..=30.0).contains(&self.max_seconds),
            "--max-seconds must be 1 … 30 (the STT actor transcribes at most 30 s at once)",
        )?;
        check(
            (1.0..=600.0).contains(&self.wait_s),
            "--wait-s must be 1 … 600",
        )?;
        Ok(VadSettings {
            silence_ms: self.silence_ms,
            threshold_db: self.threshold_db,
            max_seconds: self.max_seconds,
            wait_s: self.wait_s,
        })
    }
}

// -- audio sources ------------------------------------------------------------------------

/// Where the audio comes from: 16 kHz mono 16-bit frames of [`FRAME`] samples.
pub trait AudioSource {
    /// The next frame (shorter at the very end), or `None` at the end of the input.
    fn next_frame(&mut self) -> Result<Option<Vec<i16>>>;
}

/// A WAV file's samples, mixed to mono and resampled to 16 kHz.
pub struct WavSource {
    samples: Vec<i16>,
    at: usize,
}

impl WavSource {
    /// Reads `path`; says what is wrong when it is not 16-bit PCM WAV speech audio.
    pub fn open(path: &Path) -> Result<Self> {
        let reader = hound::WavReader::open(path).map_err(|e| {
            anyhow::anyhow!(
                "{} is not a readable WAV file ({e}); --from-file takes 16-bit PCM WAV",
                path.display()
            )
        })?;
        let spec = reader.spec();
        if spec.sample_format != hound::SampleFormat::Int || spec.bits_per_sample != 16 {
            bail!(
                "{} holds {}-bit {:?} samples; --from-file takes 16-bit PCM WAV (sox in.wav -b 16 \
                 out.wav converts it)",
                path.display(),
                spec.bits_per_sample,
                spec.sample_format
            );
        }
        if !(1..=2).contains(&spec.channels) {
            bail!(
                "{} has {} channels; --from-file takes mono or stereo",
                path.display(),
                spec.channels
            );
        }
        if !(8_000..=192_000).contains(&spec.sample_rate) {
            bail!(
                "{} is at {} Hz; speech audio is 8,000 … 192,000 Hz",
                path.display(),
                spec.sample_rate
            );
        }
        let channels = usize::from(spec.channels);
        let raw: Vec<i16> = reader
            .into_samples::<i16>()
            .collect::<Result<_, _>>()
            .with_context(|| format!("reading the samples of {}", path.display()))?;
        let mono: Vec<f64> = raw
            .chunks(channels)
            .map(|c| c.iter().map(|&s| f64::from(s)).sum::<f64>() / c.len() as f64)
            .collect();
        Ok(Self {
            samples: resample(&mono, spec.sample_rate),
            at: 0,
        })
    }
}

/// Linear resampling to 16 kHz (enough for speech into Whisper, which hears up to 8 kHz).
fn resample(samples: &[f64], rate: u32) -> Vec<i16> {
    if samples.is_empty() {
        return Vec::new();
    }
    let step = f64::from(rate) / f64::from(PCM_SAMPLE_RATE_HZ);
    let n = ((samples.len() as f64) / step).floor() as usize;
    (0..n)
        .map(|i| {
            let x = i as f64 * step;
            let (j, frac) = (x.floor() as usize, x.fract());
            let a = samples[j.min(samples.len() - 1)];
            let b = samples[(j + 1).min(samples.len() - 1)];
            (a + (b - a) * frac).round().clamp(-32768.0, 32767.0) as i16
        })
        .collect()
}

impl AudioSource for WavSource {
    fn next_frame(&mut self) -> Result<Option<Vec<i16>>> {
        if self.at >= self.samples.len() {
            return Ok(None);
        }
        let end = (self.at + FRAME).min(self.samples.len());
        let frame = self.samples[self.at..end].to_vec();
        self.at = end;
        Ok(Some(frame))
    }
}

/// The microphone, through `arecord -f S16_LE -c 1 -r 16000 -t raw`.
pub struct Microphone {
    child: Child,
    stdout: ChildStdout,
    device: String,
}

impl Microphone {
    /// Starts recording from ALSA `device`; a clear error when there is no capture device.
    pub fn open(device: &str) -> Result<Self> {
        let pulse = std::env::var_os("PULSE_SERVER").is_some();
        Self::open_with(device, Path::new("/dev/snd"), pulse, "arecord")
    }

    /// [`Microphone::open`] with the sound device directory, whether a sound server is
    /// named, and the recorder program given (tests).
    fn open_with(device: &str, snd: &Path, pulse: bool, arecord: &str) -> Result<Self> {
        if !snd.exists() && !pulse {
            bail!(
                "no microphone: this machine has no sound devices ({} is missing) and no \
                 PULSE_SERVER; attach a microphone, or give a recording with --from-file x.wav",
                snd.display()
            );
        }
        let mut child = Command::new(arecord)
            .args([
                "-q", "-D", device, "-f", "S16_LE", "-c", "1", "-r", "16000", "-t", "raw",
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| {
                anyhow::anyhow!(
                    "cannot run arecord ({e}): robotd listen records the microphone with it; \
                     apt-get install alsa-utils"
                )
            })?;
        let stdout = child.stdout.take().context("arecord's output")?;
        Ok(Self {
            child,
            stdout,
            device: device.to_owned(),
        })
    }

    fn failure(&mut self) -> anyhow::Error {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let mut said = String::new();
        if let Some(mut stderr) = self.child.stderr.take() {
            let _ = stderr.read_to_string(&mut said);
        }
        anyhow::anyhow!(
            "no microphone: arecord could not record from ALSA device '{}' ({}); plug in a \
             microphone, pick another with --device (arecord -L lists them), or give a \
             recording with --from-file x.wav",
            self.device,
            said.trim()
        )
    }
}

impl AudioSource for Microphone {
    fn next_frame(&mut self) -> Result<Option<Vec<i16>>> {
        let mut bytes = [0u8; FRAME * 2];
        let mut filled = 0;
        while filled < bytes.len() {
            match self.stdout.read(&mut bytes[filled..]) {
                Ok(0) => break,
                Ok(n) => filled += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e).context("reading arecord's output"),
            }
        }
        if filled < bytes.len() {
            // arecord never ends by itself: it failed (no device, busy, refused).
            return Err(self.failure());
        }
        Ok(Some(
            bytes
                .chunks_exact(2)
                .map(|b| i16::from_le_bytes([b[0], b[1]]))
                .collect(),
        ))
    }
}

impl Drop for Microphone {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

// -- voice activity detection -----------------------------------------------------------------

/// Level of a frame, dBFS (-100 for digital silence).
pub fn level_db(frame: &[i16]) -> f64 {
    if frame.is_empty() {
        return -100.0;
    }
    let power = frame.iter().map(|&s| f64::from(s).powi(2)).sum::<f64>() / frame.len() as f64;
    (10.0 * (power / (32768.0f64 * 32768.0)).log10()).max(-100.0)
}

/// Why the utterance ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ended {
    /// `silence_ms` of silence after speech.
    Silence,
    /// It reached `max_seconds`.
    MaxLength,
    /// The input ended (a file) while speech went on.
    EndOfInput,
}

/// One utterance cut out of the input.
pub struct Utterance {
    /// 16 kHz mono samples: 300 ms before the speech, the speech, 300 ms after.
    pub samples: Vec<i16>,
    /// Where the speech began and ended in the input, seconds.
    pub start_s: f64,
    pub end_s: f64,
    pub ended: Ended,
}

impl std::fmt::Debug for Utterance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Utterance")
            .field("samples", &self.samples.len())
            .field("start_s", &self.start_s)
            .field("end_s", &self.end_s)
            .field("ended", &self.ended)
            .finish()
    }
}

/// Energy-based voice activity detection with a hang time: speech begins with 120 ms of frames
/// above the threshold (the threshold is `threshold_db`, or 12 dB over the background noise
/// when that is louder: measured in the first 300 ms, then followed while waiting) and ends
/// after `silence_ms` below it.
pub struct Vad;

/// Frames above the threshold in a row that begin speech (120 ms: a click or a knock, even
/// one that straddles three frames, is not speech).
const START_FRAMES: usize = 4;
/// Audio kept before the speech and after it, frames (300 ms).
const MARGIN_FRAMES: usize = 10;
/// The first frames measure the background noise, frames (300 ms); speech found in them
/// counts from where it began.
const CALIBRATION_FRAMES: usize = 10;

impl Vad {
    /// Reads `source` until one utterance has been spoken and has ended.
    pub fn record(source: &mut dyn AudioSource, settings: &VadSettings) -> Result<Utterance> {
        let silence_frames = (f64::from(settings.silence_ms) / 1000.0 / FRAME_S).ceil() as usize;
        let max_frames = (settings.max_seconds / FRAME_S).floor() as usize;
        let wait_frames = (settings.wait_s / FRAME_S).ceil() as usize;
        let mut frames: Vec<Vec<i16>> = Vec::new();
        let mut noise_db: Option<f64> = None;
        let mut loudest = -100.0f64;
        let mut above = 0usize; // frames above the threshold in a row
        let mut start: Option<usize> = None;
        let mut last_speech = 0usize;
        let threshold =
            |noise: Option<f64>| settings.threshold_db.max(noise.unwrap_or(-100.0) + 12.0);
        let ended = loop {
            let Some(frame) = source.next_frame()? else {
                match start {
                    Some(_) => break Ended::EndOfInput,
                    None => bail!(
                        "the recording ended with no speech in it (the loudest sound was \
                         {loudest:.0} dBFS; speech is over {:.0} dBFS): lower --threshold-db, \
                         or check the recording",
                        threshold(noise_db)
                    ),
                }
            };
            let level = level_db(&frame);
            loudest = loudest.max(level);
            let index = frames.len();
            frames.push(frame);
            let speech = level > threshold(noise_db);
            match start {
                None => {
                    if index < CALIBRATION_FRAMES {
                        // The background: the quietest frame of the first 300 ms (a word
                        // begun at once still has a quieter frame in it).
                        noise_db = Some(noise_db.map_or(level, |n: f64| n.min(level)));
                        above = if level > threshold(noise_db) {
                            above + 1
                        } else {
                            0
                        };
                        continue;
                    }
                    above = if speech { above + 1 } else { 0 };
                    if !speech {
                        // The background noise, followed slowly (a door, a fan coming on).
                        noise_db = noise_db.map(|n| 0.95 * n + 0.05 * level);
                    }
                    if above >= START_FRAMES {
                        start = Some(index + 1 - START_FRAMES);
                        last_speech = index;
                    } else if index + 1 >= wait_frames {
                        bail!(
                            "no speech heard within {} s (the loudest sound was {loudest:.0} \
                             dBFS; speech is over {:.0} dBFS): speak closer to the microphone, \
                             or lower --threshold-db",
                            settings.wait_s,
                            threshold(noise_db)
                        );
                    }
                }
                Some(begun) => {
                    if speech {
                        last_speech = index;
                    }
                    if index - last_speech >= silence_frames {
                        break Ended::Silence;
                    }
                    if index + 1 - begun >= max_frames {
                        break Ended::MaxLength;
                    }
                }
            }
        };
        let begun = start.unwrap_or(0);
        let first = begun.saturating_sub(MARGIN_FRAMES);
        let last = (last_speech + MARGIN_FRAMES).min(frames.len() - 1);
        let offset = |frame: usize| {
            frames[..frame].iter().map(Vec::len).sum::<usize>() as f64
                / f64::from(PCM_SAMPLE_RATE_HZ)
        };
        let (start_s, end_s) = (offset(begun), offset(last_speech + 1));
        Ok(Utterance {
            samples: frames[first..=last].concat(),
            start_s,
            end_s,
            ended,
        })
    }
}

// -- the command ------------------------------------------------------------------------------

/// Runs `robotd listen`.
pub fn run(config: &Config, args: &ListenArgs) -> Result<ExitCode> {
    let settings = args.settings()?;
    // Multi-threaded: a new publisher on agent/request then waits (bounded) until the agent's
    // subscriber has connected to it, so the request cannot go out before anyone hears it.
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?
        .block_on(listen(config, args, settings))
}

async fn listen(config: &Config, args: &ListenArgs, settings: VadSettings) -> Result<ExitCode> {
    let namespace = &config.bus.namespace;
    let bus = Bus::open(BusOptions::new(namespace, "robotd-listen"))
        .with_context(|| format!("joining the bus '{namespace}'"))?;
    let stt = bus.client(&STT_TRANSCRIBE)?;
    // Before recording: nobody should talk to a robot that cannot hear.
    if !stt.wait_for_server(Duration::from_secs(2)).await {
        bail!(
            "no speech-to-text actor serves stt/transcribe on bus '{namespace}': run robotd serve \
             with [actors.stt] (mode = \"process\", command = [\"python3\", \"-m\", \
             \"robotd.stt\"]; docs/speech.md)"
        );
    }
    let mut source: Box<dyn AudioSource> = match &args.from_file {
        Some(path) => Box::new(WavSource::open(path)?),
        None => {
            eprintln!(
                "robotd listen: listening (speak; {} ms of silence ends it)",
                settings.silence_ms
            );
            Box::new(Microphone::open(&args.device)?)
        }
    };
    // Blocking reads (a pipe, a file): off the runtime's workers.
    let utterance = tokio::task::block_in_place(|| Vad::record(source.as_mut(), &settings))?;
    drop(source);
    let ended = match utterance.ended {
        Ended::Silence => format!("{} ms of silence ended it", settings.silence_ms),
        Ended::MaxLength => format!("cut at --max-seconds {}", settings.max_seconds),
        Ended::EndOfInput => "the recording ended".to_owned(),
    };
    eprintln!(
        "robotd listen: speech from {:.2} s to {:.2} s ({ended})",
        utterance.start_s, utterance.end_s
    );
    let pcm: Vec<u8> = utterance
        .samples
        .iter()
        .flat_map(|s| s.to_le_bytes())
        .collect();
    let asked = Instant::now();
    let timeout = Duration::from_secs_f64(config.voice.timeout_s);
    let transcript = match stt
        .request(&TranscribeRequest::pcm16k(pcm, "listen"), timeout)
        .await
    {
        Ok(TranscribeReply::Transcript { transcript }) => transcript,
        Ok(TranscribeReply::Error { error }) => bail!("the STT actor refused the audio: {error}"),
        Err(BusError::Timeout { .. }) => bail!(
            "the speech-to-text actor did not answer within {} s ([voice] timeout_s)",
            config.voice.timeout_s
        ),
        Err(error) => return Err(error).context("asking stt/transcribe"),
    };
    eprintln!(
        "robotd listen: transcribed in {:.2} s (confidence {:.2})",
        asked.elapsed().as_secs_f64(),
        transcript.confidence
    );
    println!("{}", transcript.text);
    if transcript.text.trim().is_empty() {
        eprintln!("robotd listen: nothing was heard");
        return Ok(ExitCode::FAILURE);
    }
    if args.print_only {
        return Ok(ExitCode::SUCCESS);
    }
    act(config, &bus, &transcript).await
}

/// The e-stop for a stop phrase, or the agent for anything else.
async fn act(config: &Config, bus: &Bus, transcript: &Transcript) -> Result<ExitCode> {
    let voice = &config.voice;
    if voice.stop_words {
        if let Some(phrase) =
            robotd_dashboard::voice::stop_phrase(&transcript.text, &voice.stop_phrases)
        {
            let sent = bus.publisher(&SAFETY_ESTOP)?.publish(&EmergencyStop {
                engaged: true,
                reason: format!("voice: heard \"{phrase}\" ({:?})", transcript.text),
                source: "voice".into(),
            })?;
            if sent == 0 {
                bail!("heard \"{phrase}\", but no arm listens on safety/estop (is robotd serve running?)");
            }
            eprintln!("robotd listen: heard \"{phrase}\": emergency stop engaged");
            return Ok(ExitCode::SUCCESS);
        }
    }
    // What was said is the task now: the dashboard and Foxglove show it over the video. The
    // publisher lives until the agent answered: a message of a dropped publisher can be lost.
    let overlay = TextOverlay::new(transcript.text.trim(), OverlayKind::UserTask);
    let _task_shown = match bus.publisher(&OVERLAY_TEXT) {
        Ok(publisher) => {
            if let Err(error) = publisher.publish(&overlay) {
                tracing::warn!(%error, "overlay/text: the spoken task is not shown");
            }
            Some(publisher)
        }
        Err(error) => {
            tracing::warn!(%error, "overlay/text: the spoken task is not shown");
            None
        }
    };
    let request_id = format!(
        "listen-{}-{}",
        std::process::id(),
        robotd_protocol::envelope::unix_now_ns()
    );
    // Listen before asking, so that no event of this request is missed.
    let mut events = bus.subscriber(&AGENT_EVENTS)?;
    let sent = bus.publisher(&AGENT_REQUEST)?.publish(&AgentRequest {
        request_id: request_id.clone(),
        text: transcript.text.chars().take(4000).collect(),
    })?;
    if sent == 0 {
        bail!(
            "no LLM agent listens on agent/request: robotd serve runs its agent when a provider \
             is configured ([agent], an API key; robotd doctor's llm-keys row); use --print-only \
             to only transcribe"
        );
    }
    let cancel = bus.publisher(&AGENT_CANCEL)?;
    // The agent starts on a request at once (its first event is the plan or a tool call); a
    // motion may then take minutes, which Ctrl-C cancels.
    let mut first_by = Some(tokio::time::Instant::now() + AGENT_START_WAIT);
    loop {
        let event = tokio::select! {
            event = events.recv() => event?.body,
            _ = tokio::time::sleep_until(first_by.unwrap_or_else(tokio::time::Instant::now)), if first_by.is_some() => {
                bail!(
                    "the agent did not start on the request within {} s (is it busy with another \
                     one, or restarting? robotd's log says)",
                    AGENT_START_WAIT.as_secs()
                );
            }
            _ = tokio::signal::ctrl_c() => {
                cancel.publish(&AgentCancel { request_id })?;
                eprintln!("robotd listen: cancelled");
                return Ok(ExitCode::FAILURE);
            }
        };
        if event.request_id != request_id {
            continue;
        }
        first_by = None;
        crate::chat::show(&event.event);
        if event.event.is_terminal() {
            return Ok(match event.event {
                AgentEventKind::Answer { .. } => ExitCode::SUCCESS,
                _ => ExitCode::FAILURE,
            });
        }
    }
}

#[cfg(test)]
#[path = "listen_tests.rs"]
mod tests;
