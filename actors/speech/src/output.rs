//! Where audio goes: the default audio device, or WAV files in a bounded spool directory.
//!
//! Playing uses the system's player (`paplay` for PulseAudio/PipeWire, `aplay` for ALSA) on a
//! WAV file, so robotd needs no audio libraries to build. A machine without a sound card (a
//! server, CI) has no device: speech then goes to the spool, whose oldest files are deleted
//! once it grows past its size limit.

use crate::engine::{Audio, EngineError};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};

/// Where utterances go.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Output {
    /// Played by this program on the default device (`paplay` or `aplay`).
    Device {
        /// The player program.
        player: PathBuf,
    },
    /// Written to the spool.
    Spool(Spool),
}

/// A directory of WAV files with a size limit.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Spool {
    /// The directory.
    pub dir: PathBuf,
    /// Largest total size, bytes.
    pub max_bytes: u64,
}

static SPOOL_COUNTER: AtomicU64 = AtomicU64::new(0);

impl Spool {
    /// Writes `audio` as a new WAV file and trims the spool; returns the file.
    pub fn write(&self, audio: &Audio) -> Result<PathBuf, EngineError> {
        std::fs::create_dir_all(&self.dir).map_err(|e| {
            EngineError::Output(format!(
                "cannot create the spool {}: {e}",
                self.dir.display()
            ))
        })?;
        let stamp = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_millis())
            .unwrap_or(0);
        let n = SPOOL_COUNTER.fetch_add(1, Ordering::Relaxed);
        let path = self
            .dir
            .join(format!("{stamp}-{}-{n}.wav", std::process::id()));
        audio.write_wav(&path)?;
        self.trim();
        Ok(path)
    }

    /// Deletes the oldest WAV files until the spool fits its limit.
    pub fn trim(&self) {
        let Ok(entries) = std::fs::read_dir(&self.dir) else {
            return;
        };
        let mut files: Vec<(std::time::SystemTime, u64, PathBuf)> = entries
            .filter_map(Result::ok)
            .filter(|e| e.path().extension().is_some_and(|x| x == "wav"))
            .filter_map(|e| {
                let meta = e.metadata().ok()?;
                Some((meta.modified().ok()?, meta.len(), e.path()))
            })
            .collect();
        files.sort();
        let mut total: u64 = files.iter().map(|f| f.1).sum();
        for (_, len, path) in files {
            if total <= self.max_bytes {
                break;
            }
            if std::fs::remove_file(&path).is_ok() {
                total = total.saturating_sub(len);
            }
        }
    }
}

/// The audio player of this machine, when it has an audio device: `paplay` when a PulseAudio
/// (or PipeWire) server answers, else `aplay` when ALSA lists a playback device.
pub fn find_device_player() -> Option<PathBuf> {
    let runs = |program: &str, args: &[&str]| {
        Command::new(program)
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .output()
            .ok()
            .filter(|o| o.status.success())
    };
    if runs("pactl", &["info"]).is_some() && runs("paplay", &["--version"]).is_some() {
        return Some(PathBuf::from("paplay"));
    }
    if let Some(out) = runs("aplay", &["-l"]) {
        if String::from_utf8_lossy(&out.stdout).contains("card ") {
            return Some(PathBuf::from("aplay"));
        }
    }
    None
}

impl Output {
    /// Plays or spools `audio`; returns where it went (for logs).
    pub fn emit(&self, audio: &Audio, scratch: &Path) -> Result<String, EngineError> {
        match self {
            Output::Spool(spool) => spool.write(audio).map(|p| p.display().to_string()),
            Output::Device { player } => {
                std::fs::create_dir_all(scratch).map_err(|e| {
                    EngineError::Output(format!("cannot create {}: {e}", scratch.display()))
                })?;
                let file = scratch.join(format!("playing-{}.wav", std::process::id()));
                audio.write_wav(&file)?;
                // A hung player is killed once the audio should long be over.
                let timeout = std::time::Duration::from_secs_f64(audio.duration_s() + 10.0);
                let result =
                    crate::engine::run_with_timeout(Command::new(player).arg(&file), timeout);
                let _ = std::fs::remove_file(&file);
                let status = result
                    .map_err(|e| EngineError::Output(format!("{}: {e}", player.display())))?
                    .status;
                if status.success() {
                    Ok(format!("played with {}", player.display()))
                } else {
                    Err(EngineError::Output(format!(
                        "{} exited with {status}",
                        player.display()
                    )))
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_spool_keeps_to_its_size() {
        let dir = std::env::temp_dir().join(format!("robotd-spool-test-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let audio = Audio {
            sample_rate: 8000,
            samples: vec![100; 8000],
        };
        // Each file is 16,044 bytes; the limit holds two.
        let spool = Spool {
            dir: dir.clone(),
            max_bytes: 40_000,
        };
        let mut written = Vec::new();
        for _ in 0..4 {
            written.push(spool.write(&audio).unwrap());
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(Result::ok)
            .collect();
        assert_eq!(left.len(), 2);
        assert!(written[3].exists() && written[2].exists() && !written[0].exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
