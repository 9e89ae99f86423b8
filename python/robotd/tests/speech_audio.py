"""Spoken test audio, made here: espeak-ng speaks a text, PyAV writes it as a browser would.

Used by ``check_stt.py`` (the STT actor's checks), by the dashboard's voice tests and by
``scripts/bench/stt.py``. Nothing is downloaded: espeak-ng (a Debian package) synthesizes the
speech; PyAV (installed with faster-whisper) resamples and encodes it.

    python speech_audio.py "pick up the pencil" --format webm --out pencil.webm
    python speech_audio.py "stop" --format wav --rate 48000 --out stop.wav   # Chromium's fake mic
"""

from __future__ import annotations

import argparse
import io
import subprocess
import sys
import wave

import numpy as np

#: The two espeak-ng voices the benchmark speaks in.
VOICES = ("en-us", "en-gb-x-rp")


def speak(text: str, voice: str = "en-us", speed: int = 160) -> tuple:
    """(int16 mono samples, rate) of espeak-ng saying ``text``."""
    wav = subprocess.run(
        ["espeak-ng", "-v", voice, "-s", str(speed), "--stdout", text],
        check=True,
        capture_output=True,
    ).stdout
    with wave.open(io.BytesIO(wav)) as w:
        rate = w.getframerate()
        samples = np.frombuffer(w.readframes(w.getnframes()), dtype="<i2")
    return samples.copy(), rate


def resample(samples: np.ndarray, rate: int, to_rate: int) -> np.ndarray:
    """Linear resampling (enough for tests: the actor resamples with FFmpeg itself)."""
    if rate == to_rate:
        return samples
    n = int(round(len(samples) * to_rate / rate))
    x = np.linspace(0, len(samples) - 1, n)
    return np.interp(x, np.arange(len(samples)), samples.astype(np.float64)).astype("<i2")


def pad(samples: np.ndarray, rate: int, before_s: float, after_s: float) -> np.ndarray:
    z = lambda s: np.zeros(int(s * rate), dtype="<i2")  # noqa: E731
    return np.concatenate([z(before_s), samples, z(after_s)])


def wav_bytes(samples: np.ndarray, rate: int) -> bytes:
    out = io.BytesIO()
    with wave.open(out, "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(rate)
        w.writeframes(samples.astype("<i2").tobytes())
    return out.getvalue()


def encoded(samples: np.ndarray, rate: int, container: str = "webm", bitrate: int = 24000) -> bytes:
    """``samples`` as Opus in a WebM or Ogg file, as a browser's MediaRecorder writes them."""
    import av

    out = io.BytesIO()
    with av.open(out, "w", format=container) as c:
        stream = c.add_stream("libopus", rate=48000)
        stream.layout = "mono"
        stream.bit_rate = bitrate
        resampler = av.AudioResampler(format="s16", layout="mono", rate=48000)
        frame = av.AudioFrame.from_ndarray(
            samples.astype("<i2").reshape(1, -1), format="s16", layout="mono"
        )
        frame.sample_rate = rate
        for f in resampler.resample(frame) + resampler.resample(None):
            for packet in stream.encode(f):
                c.mux(packet)
        for packet in stream.encode(None):
            c.mux(packet)
    return out.getvalue()


def with_noise(samples: np.ndarray, snr_db: float, seed: int = 0) -> np.ndarray:
    """White noise added at ``snr_db`` (signal power over the spoken part's power)."""
    x = samples.astype(np.float64)
    power = np.mean(x[np.abs(x) > 0] ** 2) if np.any(x) else 1.0
    noise = np.random.default_rng(seed).normal(0.0, np.sqrt(power / 10 ** (snr_db / 10)), x.size)
    return np.clip(x + noise, -32768, 32767).astype("<i2")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("text")
    parser.add_argument("--voice", default="en-us")
    parser.add_argument("--format", choices=["wav", "webm", "ogg", "pcm"], default="wav")
    parser.add_argument("--rate", type=int, default=0, help="resample to this rate (wav, pcm)")
    parser.add_argument("--pad", type=float, default=0.0, help="silence before and after, s")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    samples, rate = speak(args.text, args.voice)
    if args.rate:
        samples, rate = resample(samples, rate, args.rate), args.rate
    samples = pad(samples, rate, args.pad, args.pad)
    if args.format == "wav":
        data = wav_bytes(samples, rate)
    elif args.format == "pcm":
        data = resample(samples, rate, 16000).tobytes()
    else:
        data = encoded(samples, rate, args.format)
    with open(args.out, "wb") as f:
        f.write(data)
    return 0


if __name__ == "__main__":
    sys.exit(main())
