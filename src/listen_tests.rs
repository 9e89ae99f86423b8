//! Tests of `robotd listen`'s voice activity detection and its WAV source (the whole command,
//! with the STT actor and an agent, is in tests/listen.rs).

use super::*;

/// Frames from memory; counts what was read, so a test sees where the detection stopped.
struct Samples {
    samples: Vec<i16>,
    at: usize,
}

impl Samples {
    fn new(parts: &[Vec<i16>]) -> Self {
        Self {
            samples: parts.concat(),
            at: 0,
        }
    }
}

impl AudioSource for Samples {
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

const RATE: f64 = 16_000.0;

fn silence(seconds: f64) -> Vec<i16> {
    vec![0; (seconds * RATE) as usize]
}

/// A 220 Hz tone with a 4 Hz tremolo (speech-like loudness changes) at about `db` dBFS.
fn voice(seconds: f64, db: f64) -> Vec<i16> {
    let amplitude = 32768.0 * 10f64.powf(db / 20.0) * 2f64.sqrt();
    (0..(seconds * RATE) as usize)
        .map(|i| {
            let t = i as f64 / RATE;
            let tremolo = 0.75 + 0.25 * (2.0 * std::f64::consts::PI * 4.0 * t).sin();
            (amplitude * tremolo * (2.0 * std::f64::consts::PI * 220.0 * t).sin()) as i16
        })
        .collect()
}

/// Deterministic white noise at about `db` dBFS.
fn noise(seconds: f64, db: f64) -> Vec<i16> {
    let amplitude = 32768.0 * 10f64.powf(db / 20.0) * 3f64.sqrt();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    (0..(seconds * RATE) as usize)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let uniform = (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
            (amplitude * uniform) as i16
        })
        .collect()
}

fn mixed(a: &[i16], b: &[i16]) -> Vec<i16> {
    a.iter().zip(b).map(|(x, y)| x.saturating_add(*y)).collect()
}

fn settings() -> VadSettings {
    VadSettings {
        silence_ms: 800,
        threshold_db: -40.0,
        max_seconds: 25.0,
        wait_s: 10.0,
    }
}

fn close(a: f64, b: f64, within: f64) -> bool {
    (a - b).abs() <= within
}

#[test]
fn speech_is_cut_out_between_silences_and_the_rest_is_left_unread() {
    let mut source = Samples::new(&[
        silence(1.0),
        voice(1.5, -20.0),
        silence(2.0),
        voice(1.0, -20.0),
    ]);
    let heard = Vad::record(&mut source, &settings()).unwrap();
    assert_eq!(heard.ended, Ended::Silence);
    assert!(close(heard.start_s, 1.0, 0.04), "{heard:?}");
    assert!(
        close(heard.end_s, 2.5, 0.04),
        "{:?}",
        (heard.start_s, heard.end_s)
    );
    // 300 ms before and after the speech.
    let seconds = heard.samples.len() as f64 / RATE;
    assert!(close(seconds, 2.1, 0.07), "{seconds}");
    // It stopped 800 ms into the silence: the second utterance is still to be read.
    let read_s = source.at as f64 / RATE;
    assert!(close(read_s, 2.5 + 0.8, 0.07), "{read_s}");
}

#[test]
fn background_noise_raises_the_threshold_and_a_click_is_not_speech() {
    // Noise at -45 dBFS is louder than a -60 dBFS threshold: the threshold follows the noise.
    let background = noise(5.0, -45.0);
    let speech = [silence(1.5), voice(1.5, -22.0), silence(2.0)].concat();
    let mut settings = settings();
    settings.threshold_db = -60.0;
    let heard = Vad::record(&mut Samples::new(&[mixed(&background, &speech)]), &settings).unwrap();
    assert_eq!(heard.ended, Ended::Silence);
    assert!(close(heard.start_s, 1.5, 0.07), "{heard:?}");
    assert!(
        close(heard.end_s, 3.0, 0.07),
        "{:?}",
        (heard.start_s, heard.end_s)
    );

    // A 60 ms click (over three frames) is shorter than the 120 ms speech must last to begin.
    let mut source = Samples::new(&[
        silence(0.5),
        voice(0.06, -10.0),
        silence(1.0),
        voice(1.0, -20.0),
        silence(1.0),
    ]);
    let heard = Vad::record(&mut source, &self::settings()).unwrap();
    assert!(close(heard.start_s, 1.56, 0.04), "{heard:?}");
}

#[test]
fn silence_only_long_speech_and_a_recording_that_ends_mid_word() {
    let mut settings = settings();
    settings.wait_s = 1.0;
    let endless = Vad::record(&mut Samples::new(&[silence(3.0)]), &settings).unwrap_err();
    assert!(
        endless.to_string().contains("no speech heard within 1 s"),
        "{endless}"
    );
    let short = Vad::record(&mut Samples::new(&[silence(0.5)]), &self::settings()).unwrap_err();
    assert!(
        short.to_string().contains("ended with no speech"),
        "{short}"
    );
    let quiet =
        Vad::record(&mut Samples::new(&[noise(2.0, -70.0)]), &self::settings()).unwrap_err();
    assert!(
        quiet.to_string().contains("loudest sound was -70 dBFS"),
        "{quiet}"
    );

    let mut settings = self::settings();
    settings.max_seconds = 2.0;
    let long = Vad::record(
        &mut Samples::new(&[silence(0.5), voice(5.0, -20.0)]),
        &settings,
    )
    .unwrap();
    assert_eq!(long.ended, Ended::MaxLength);
    assert!(close(long.end_s - long.start_s, 2.0, 0.04), "{long:?}");

    let cut = Vad::record(
        &mut Samples::new(&[silence(0.5), voice(1.0, -20.0)]),
        &self::settings(),
    )
    .unwrap();
    assert_eq!(cut.ended, Ended::EndOfInput);
}

#[test]
fn a_wav_file_is_mixed_to_mono_16k_and_bad_files_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let stereo = dir.path().join("stereo48k.wav");
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: 48_000,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut writer = hound::WavWriter::create(&stereo, spec).unwrap();
    for i in 0..48_000 {
        let s = if i % 2 == 0 { 1000 } else { 3000 };
        writer.write_sample(s as i16).unwrap();
        writer.write_sample(s as i16).unwrap();
    }
    writer.finalize().unwrap();
    let mut source = WavSource::open(&stereo).unwrap();
    let mut samples = Vec::new();
    while let Some(frame) = source.next_frame().unwrap() {
        samples.extend(frame);
    }
    assert_eq!(samples.len(), 16_000);
    assert!(samples.iter().all(|&s| (1000..=3000).contains(&s)));

    let float = dir.path().join("float.wav");
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 16_000,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut writer = hound::WavWriter::create(&float, spec).unwrap();
    writer.write_sample(0.5f32).unwrap();
    writer.finalize().unwrap();
    let error = WavSource::open(&float).err().unwrap().to_string();
    assert!(error.contains("32-bit Float samples"), "{error}");

    let text = dir.path().join("not.wav");
    std::fs::write(&text, "not audio at all").unwrap();
    let error = WavSource::open(&text).err().unwrap().to_string();
    assert!(error.contains("not a readable WAV file"), "{error}");
    let error = WavSource::open(&dir.path().join("missing.wav"))
        .err()
        .unwrap()
        .to_string();
    assert!(error.contains("missing.wav"), "{error}");
}

#[test]
fn out_of_range_options_are_refused() {
    let args = |f: &dyn Fn(&mut ListenArgs)| {
        let mut args = ListenArgs {
            print_only: true,
            from_file: None,
            device: "default".into(),
            silence_ms: 800,
            threshold_db: -40.0,
            max_seconds: 25.0,
            wait_s: 10.0,
        };
        f(&mut args);
        args.settings().map(|_| ()).map_err(|e| e.to_string())
    };
    assert!(args(&|_| {}).is_ok());
    assert!(args(&|a| a.silence_ms = 50)
        .unwrap_err()
        .contains("--silence-ms"));
    assert!(args(&|a| a.threshold_db = 3.0)
        .unwrap_err()
        .contains("--threshold-db"));
    assert!(args(&|a| a.max_seconds = 60.0)
        .unwrap_err()
        .contains("30 s at once"));
    assert!(args(&|a| a.wait_s = 0.0).unwrap_err().contains("--wait-s"));
}

#[test]
fn without_a_microphone_the_error_says_what_to_do() {
    let error = Microphone::open_with("default", Path::new("/nonexistent/snd"), false, "arecord")
        .err()
        .unwrap()
        .to_string();
    assert!(error.starts_with("no microphone"), "{error}");
    assert!(error.contains("--from-file"), "{error}");

    // A sound device but no arecord.
    let dir = tempfile::tempdir().unwrap();
    let error = Microphone::open_with("default", dir.path(), false, "/nonexistent/arecord")
        .err()
        .unwrap()
        .to_string();
    assert!(error.contains("apt-get install alsa-utils"), "{error}");

    // A recorder that cannot open the device (it exits at once, as arecord does).
    let fake = dir.path().join("arecord");
    std::fs::write(
        &fake,
        "#!/bin/sh\necho 'arecord: main:830: audio open error: No such file or directory' >&2\nexit 1\n",
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    let mut microphone =
        Microphone::open_with("hw:9", dir.path(), false, fake.to_str().unwrap()).unwrap();
    let error = microphone.next_frame().unwrap_err().to_string();
    assert!(
        error.contains("no microphone: arecord could not record from ALSA device 'hw:9'"),
        "{error}"
    );
    assert!(error.contains("audio open error"), "{error}");
}
