//! `audio`: somewhere to play speech — a sound card, or a PulseAudio/PipeWire server.
//!
//! Without an output robotd still works: speech is written as WAV files to the spool
//! directory instead of being played, so this row only warns. It counts the playback devices
//! in `/dev/snd` (`pcm*p`; capture devices end in `c`), `PULSE_SERVER`, and the usual sound
//! server sockets of the user (`$XDG_RUNTIME_DIR/pulse/native`, `pipewire-0`, `/run/user/UID`).

use super::{Check, EnvFn};
use std::path::{Path, PathBuf};

pub(super) fn check_audio(snd_dir: &Path, env: EnvFn) -> Check {
    const NAME: &str = "audio";
    let mut outputs = Vec::new();

    let mut pcms: Vec<String> = std::fs::read_dir(snd_dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.starts_with("pcm") && n.ends_with('p'))
                .collect()
        })
        .unwrap_or_default();
    pcms.sort();
    if !pcms.is_empty() {
        outputs.push(format!(
            "{} playback device(s) in {} ({})",
            pcms.len(),
            snd_dir.display(),
            pcms.join(", ")
        ));
    }
    if let Some(server) = env("PULSE_SERVER") {
        outputs.push(format!("PULSE_SERVER={server}"));
    }
    let mut sockets = Vec::new();
    if let Some(runtime) = env("XDG_RUNTIME_DIR") {
        sockets.push(PathBuf::from(&runtime).join("pulse/native"));
        sockets.push(PathBuf::from(&runtime).join("pipewire-0"));
    }
    // SAFETY: getuid cannot fail and has no preconditions.
    let uid = unsafe { libc::getuid() };
    sockets.push(PathBuf::from(format!("/run/user/{uid}/pulse/native")));
    sockets.push(PathBuf::from("/run/pulse/native"));
    sockets.push(PathBuf::from("/var/run/pulse/native"));
    if let Some(socket) = sockets.iter().find(|s| s.exists()) {
        outputs.push(format!("sound server socket {}", socket.display()));
    }

    if outputs.is_empty() {
        Check::warn(
            NAME,
            format!(
                "no audio output (no {}/pcm*p device, no PULSE_SERVER, no PulseAudio/PipeWire \
                 socket); speech will be written as WAV files to the spool directory",
                snd_dir.display()
            ),
            "attach a sound card (in a container: pass --device /dev/snd), or set PULSE_SERVER \
             to a running PulseAudio server (e.g. unix:/run/user/1000/pulse/native)",
        )
    } else {
        Check::ok(NAME, outputs.join("; "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::doctor::report::Status;
    use crate::doctor::test_support::{env_from, temp_dir};

    #[test]
    fn audio_devices_and_sockets() {
        let dir = temp_dir("snd");
        let env = env_from(&[("XDG_RUNTIME_DIR", "/nonexistent-runtime")]);
        let none = check_audio(&dir, &env);
        if none.status == Status::Warn {
            assert!(none.found.contains("WAV"), "{}", none.found);
        }
        std::fs::write(dir.join("pcmC0D0p"), b"").expect("fake device");
        std::fs::write(dir.join("pcmC0D0c"), b"").expect("fake capture device");
        let some = check_audio(&dir, &env);
        assert_eq!(some.status, Status::Ok);
        assert!(some.found.contains("pcmC0D0p") && !some.found.contains("pcmC0D0c"));
        let pulse = check_audio(
            Path::new("/nonexistent"),
            &env_from(&[("PULSE_SERVER", "tcp:host")]),
        );
        assert_eq!(pulse.status, Status::Ok);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
