"""Checks of the STT actor (``python -m robotd.stt``) through the bus, against a running robotd.

Speaks commands with espeak-ng, sends them to ``stt/transcribe`` as WAV, WebM, Ogg and raw
PCM, then sends bad audio (empty, ten minutes long, not audio, a broken file, wrong sample
rates, odd PCM, too large) and a good request after each, and prints one JSON report for
``tests/stt_actor.rs`` to judge. It only reports; it asserts nothing itself.

    python check_stt.py <namespace>
"""

from __future__ import annotations

import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import speech_audio  # noqa: E402

from robotd import Bus  # noqa: E402
from robotd.errors import RobotdError  # noqa: E402
from robotd.messages import TranscribeRequest  # noqa: E402
from robotd.ports import Subscriber  # noqa: E402


def main() -> int:
    namespace = sys.argv[1]
    bus = Bus(namespace, node_name="check-stt")
    client = bus.client("stt/transcribe")
    heard = Subscriber(bus, bus.catalog.topic("stt/transcripts"), create=True)
    deadline = time.monotonic() + 90
    while not client.has_server():
        if time.monotonic() > deadline:
            print(json.dumps({"error": "no STT server within 90 s"}))
            return 1
        time.sleep(0.1)

    def ask(audio: bytes, fmt: str = "file", rate: int = 0) -> dict:
        started = time.monotonic()
        try:
            reply = client.request(TranscribeRequest(audio, fmt, rate, "check"), timeout=60)
        except RobotdError as e:
            return {"raised": type(e).__name__, "message": str(e)}
        reply["round_trip_s"] = round(time.monotonic() - started, 3)
        return reply

    report = {}
    command = "pick up the pencil and put it left of the red cube"
    samples, rate = speech_audio.speak(command)
    samples = speech_audio.pad(samples, rate, 0.2, 0.2)
    report["wav"] = ask(speech_audio.wav_bytes(samples, rate))
    published = heard.receive(timeout=5)
    report["published"] = published.body if published else None
    report["webm"] = ask(speech_audio.encoded(samples, rate, "webm"))
    report["ogg"] = ask(speech_audio.encoded(samples, rate, "ogg"))
    pcm = speech_audio.resample(samples, rate, 16000).tobytes()
    report["pcm"] = ask(pcm, "pcm_s16le", 16000)

    # Bad audio, each followed by a good request: the actor keeps serving.
    ten_minutes = np.zeros(16000 * 600, dtype="<i2")
    ten_minutes[::50] = 3000  # not pure silence: an encoder keeps it
    bad = {
        "empty": (b"", "file", 0),
        "ten_minutes_ogg": (speech_audio.encoded(ten_minutes, 16000, "ogg", 6000), "file", 0),
        "ten_minutes_pcm": (ten_minutes.tobytes(), "pcm_s16le", 16000),
        "not_audio": (b"this is a text file, not a recording\n" * 40, "file", 0),
        "broken_webm": (speech_audio.encoded(samples, rate, "webm")[:60], "file", 0),
        "wav_without_samples": (speech_audio.wav_bytes(samples[:0], rate), "file", 0),
        "pcm_44100": (pcm, "pcm_s16le", 44100),
        "wav_at_4000": (speech_audio.wav_bytes(speech_audio.resample(samples, rate, 4000), 4000), "file", 0),
        "odd_pcm": (pcm + b"\0", "pcm_s16le", 16000),
        "unknown_format": (pcm, "mp3", 0),
    }
    report["bad"] = {}
    spoken, spoken_rate = speech_audio.speak("move the red cube to the right of the blue square")
    short = speech_audio.wav_bytes(speech_audio.pad(spoken, spoken_rate, 0.2, 0.2), spoken_rate)
    for name, (audio, fmt, r) in bad.items():
        report["bad"][name] = {
            "bytes": len(audio),
            "reply": ask(audio, fmt, r),
            "then": ask(short),
        }
    print(json.dumps(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
