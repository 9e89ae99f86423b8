"""What watching the robot costs the robot: figures for BENCHMARKS.md (issue 18).

Starts its own `robotd serve` (the simulator, the dashboard, the Foxglove live view) and
measures, in one run:

- motion command latency (`move2by`: the pencil 1 cm left, then back, over streamable HTTP;
  the simulator at time_scale 0.05)
  without viewers and with viewers connected: a dashboard client reading the MJPEG camera and
  the event stream, and a Foxglove client subscribed to every channel; interleaved twice;
- a cheap tool call (`get_workspace_coordinate_from_point`) the same way;
- camera frame -> received by the dashboard client: capture time in each MJPEG part's
  `X-Frame-Timestamp-Ns` header against the client's clock (same machine);
- the camera's rate on the bus (the dashboard's `bus_fps`) without and with `robotd record`
  writing an MCAP file.

Usage: python scripts/bench/viewers.py target/release/robotd
Prints one JSON object.
"""

import asyncio
import atexit
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time

import httpx
import websockets

ROBOTD = sys.argv[1]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


HTTP, FOX = free_port(), free_port()
NAMESPACE = f"viewers{os.getpid()}"
BASE = f"http://127.0.0.1:{HTTP}"
logs = tempfile.mkdtemp()
served = subprocess.Popen(
    [ROBOTD, "serve", "--namespace", NAMESPACE, "--http", f"127.0.0.1:{HTTP}",
     "--set", "robot.time_scale=0.05", "--set", f'foxglove.bind="127.0.0.1:{FOX}"',
     "--set", "safety.llm_motions_per_minute=0",
     "--set", f"telemetry.log_dir={logs}"],
    stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
for line in served.stderr:
    if "robotd: serving on" in line:
        break
threading.Thread(target=lambda: [None for _ in served.stderr], daemon=True).start()
# Whatever happens below, the service started here does not outlive the script.
atexit.register(lambda: (served.terminate(), served.wait()))

HEADERS = {"Content-Type": "application/json", "Accept": "application/json, text/event-stream"}
client = httpx.Client(timeout=30)


def rpc(body, session=None):
    headers = dict(HEADERS)
    if session:
        headers["Mcp-Session-Id"] = session
    return client.post(f"{BASE}/mcp", headers=headers, content=json.dumps(body))


reply = rpc({"jsonrpc": "2.0", "id": 1, "method": "initialize", "params": {
    "protocolVersion": "2025-06-18", "capabilities": {}, "clientInfo": {"name": "bench", "version": "1"}}})
SESSION = reply.headers["mcp-session-id"]
rpc({"jsonrpc": "2.0", "method": "notifications/initialized"}, SESSION)
call_id = 10


def call(tool, arguments):
    global call_id
    call_id += 1
    reply = rpc({"jsonrpc": "2.0", "id": call_id, "method": "tools/call",
                 "params": {"name": tool, "arguments": arguments}}, SESSION)
    text = reply.text
    return text


call("get_detected_objects", {})


def motions(n=20):
    times = []
    for i in range(n):
        direction, y = ("left", -0.05) if i % 2 == 0 else ("right", -0.04)
        started = time.perf_counter()
        text = call("move2by", {"object_name": "pencil", "pick_coordinate": [0.22, y],
                                "direction": direction, "distance": 0.01})
        times.append((time.perf_counter() - started) * 1000)
        if "✓" not in text:
            raise SystemExit(f"move2by failed: {text}")
    return statistics.median(times)


def cheap_calls(n=300):
    times = []
    for _ in range(n):
        started = time.perf_counter()
        call("get_workspace_coordinate_from_point", {"workspace_id": "niryo_ws", "point": "center point"})
        times.append((time.perf_counter() - started) * 1000)
    return statistics.median(times)


stop = threading.Event()
ages = []


def camera_viewer():
    with httpx.stream("GET", f"{BASE}/api/camera.mjpg", timeout=30) as response:
        buffer = b""
        for chunk in response.iter_bytes():
            buffer += chunk
            while True:
                at = buffer.find(b"X-Frame-Timestamp-Ns: ")
                end = buffer.find(b"\r\n", at) if at >= 0 else -1
                if at < 0 or end < 0:
                    break
                ns = int(buffer[at + 22:end])
                ages.append(time.time() * 1000 - ns / 1e6)
                buffer = buffer[end:]
            if stop.is_set():
                return


def events_viewer():
    with httpx.stream("GET", f"{BASE}/api/events", timeout=30) as response:
        for _ in response.iter_lines():
            if stop.is_set():
                return


received = {"foxglove_messages": 0}


async def foxglove_viewer():
    async with websockets.connect(f"ws://127.0.0.1:{FOX}", subprotocols=["foxglove.sdk.v1"],
                                  max_size=None) as ws:
        subscribed = 0
        while not stop.is_set():
            try:
                message = await asyncio.wait_for(ws.recv(), 0.5)
            except asyncio.TimeoutError:
                continue
            if isinstance(message, str):
                value = json.loads(message)
                if value.get("op") == "advertise":
                    subs = []
                    for channel in value["channels"]:
                        subscribed += 1
                        subs.append({"id": subscribed, "channelId": channel["id"]})
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            else:
                received["foxglove_messages"] += 1


def with_viewers(run):
    stop.clear()
    threads = [threading.Thread(target=camera_viewer, daemon=True),
               threading.Thread(target=events_viewer, daemon=True),
               threading.Thread(target=lambda: asyncio.run(foxglove_viewer()), daemon=True)]
    for t in threads:
        t.start()
    time.sleep(2)
    try:
        return run()
    finally:
        stop.set()
        time.sleep(1)


results = {"motion_ms_p50_without": [], "motion_ms_p50_with_viewers": [],
           "cheap_call_ms_p50_without": [], "cheap_call_ms_p50_with_viewers": []}
for _ in range(2):
    results["motion_ms_p50_without"].append(round(motions(), 2))
    results["motion_ms_p50_with_viewers"].append(round(with_viewers(motions), 2))
    results["cheap_call_ms_p50_without"].append(round(cheap_calls(), 3))
    results["cheap_call_ms_p50_with_viewers"].append(round(with_viewers(cheap_calls), 3))
results["foxglove_messages_received"] = received["foxglove_messages"]
ages.sort()
results["camera_to_client_ms_p50"] = round(ages[len(ages) // 2], 2) if ages else None
results["camera_to_client_ms_p95"] = round(ages[int(len(ages) * 0.95)], 2) if ages else None
results["camera_frames_measured"] = len(ages)


def bus_fps(seconds=12):
    samples = []
    for _ in range(seconds):
        time.sleep(1)
        samples.append(client.get(f"{BASE}/api/status").json()["camera"]["bus_fps"])
    return round(statistics.mean(samples[2:]), 2)


results["camera_bus_fps_without_recording"] = bus_fps()
path = os.path.join(tempfile.mkdtemp(), "bench.mcap")
recorder = subprocess.Popen([ROBOTD, "record", "--namespace", NAMESPACE, "--duration", "20s", path],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
time.sleep(1)
results["camera_bus_fps_with_recording"] = bus_fps()
recorder.wait()
results["recording_bytes"] = os.path.getsize(path)
results["camera_bus_fps_without_recording_after"] = bus_fps()
served.terminate()
served.wait()
print(json.dumps(results))
