//! `robotd say "text" [--out file.wav]`: one utterance with the configured engine, to check a
//! lab's audio set-up in one command. With `--out` the audio is written to that WAV file;
//! without, it is played on the audio device (or, on a machine without one, written to the
//! spool, and the command says where).

use anyhow::{bail, Context, Result};
use robotd_config::Config;
use robotd_protocol::speech::SpeakRequest;
use robotd_protocol::validate::Validate;
use robotd_speech::engine::Utterance;
use std::path::Path;

/// Speaks `text` once; returns what happened, for the terminal.
pub fn run(config: &Config, text: &str, out: Option<&Path>) -> Result<String> {
    if text.trim().is_empty() {
        bail!("nothing to say: give a non-empty text");
    }
    SpeakRequest::new(text, "cli")
        .validate()
        .map_err(|e| anyhow::anyhow!("cannot say that: {e}"))?;
    let key = std::env::var(robotd_speech::ELEVENLABS_KEY_VAR).ok();
    let (engine, warning) = robotd_speech::choose_engine(&config.tts, key.as_deref())
        .context("choosing the speech engine ([tts] engine)")?;
    if let Some(warning) = warning {
        bail!("{warning}; install espeak-ng (apt-get install espeak-ng) or set ELEVENLABS_API_KEY");
    }
    let started = std::time::Instant::now();
    let audio = match engine
        .synthesize(text)
        .with_context(|| format!("speaking with {}", engine.name()))?
    {
        Utterance::Audio(audio) => audio,
        Utterance::LoggedOnly => bail!("the '{}' engine produces no audio", engine.name()),
    };
    let took = started.elapsed();
    let summary = format!(
        "{}: {:.2} s of audio at {} Hz, synthesised in {} ms",
        engine.name(),
        audio.duration_s(),
        audio.sample_rate,
        took.as_millis()
    );
    match out {
        Some(path) => {
            audio
                .write_wav(path)
                .with_context(|| format!("writing {}", path.display()))?;
            Ok(format!("{summary}; written to {}", path.display()))
        }
        None => {
            let output = robotd_speech::choose_output(&config.tts).context("[tts] output")?;
            let place = output
                .emit(&audio, &config.tts.spool_dir)
                .context("playing the audio")?;
            Ok(format!("{summary}; {place}"))
        }
    }
}
