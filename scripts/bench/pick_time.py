"""How long a pick takes, as a user sees it: figures for BENCHMARKS.md ("Picks").

For each robotd binary given (e.g. one built before a change and one after), alternated
`--rounds` times, it starts the robot and times `move2by` calls (look, pick the object, move it
1 cm, place it, back to the observation pose) over streamable HTTP:

- `sim`: the built-in simulator at time_scale 1.0 (the real arm's speeds); the pencil is moved;
- `widowx`: the real WidowX driver against `robotd fake-widowx` (servos on a pseudo-terminal,
  the camera over MJPEG), whose servos move in real time; the red cube is moved.

Usage: python scripts/bench/pick_time.py BINARY [BINARY ...] [--rounds 2] [--moves 8]
Prints one JSON object: the p50 and the spread of the calls, per binary, driver and round.
"""

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time

import httpx

from served import free_port

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
HEADERS = {"Content-Type": "application/json", "Accept": "application/json, text/event-stream"}


class Mcp:
    """One streamable-HTTP MCP session."""

    def __init__(self, base):
        self.base = base
        self.client = httpx.Client(timeout=60)
        self.next_id = 1
        reply = self.rpc({"method": "initialize", "params": {
            "protocolVersion": "2025-06-18", "capabilities": {},
            "clientInfo": {"name": "pick-bench", "version": "1"}}})
        self.session = reply.headers["mcp-session-id"]
        self.rpc({"method": "notifications/initialized"}, notify=True)

    def rpc(self, body, notify=False):
        body = {"jsonrpc": "2.0", **body}
        if not notify:
            self.next_id += 1
            body["id"] = self.next_id
        headers = dict(HEADERS)
        if getattr(self, "session", None):
            headers["Mcp-Session-Id"] = self.session
        return self.client.post(f"{self.base}/mcp", headers=headers, content=json.dumps(body))

    def call(self, tool, arguments):
        """The tool's reply text."""
        reply = self.rpc({"method": "tools/call", "params": {"name": tool, "arguments": arguments}})
        text = reply.text
        if "text/event-stream" in reply.headers.get("content-type", ""):
            text = next(line[5:] for line in text.splitlines() if line.startswith("data:"))
        return json.loads(text)["result"]["content"][0]["text"]


def start(command, ready, logs):
    """Starts `command`; waits for a stderr or stdout line matching `ready`, returns (process, match)."""
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                               cwd=logs)
    deadline = time.monotonic() + 60
    for line in process.stdout:
        found = re.search(ready, line)
        if found:
            return process, found
        if time.monotonic() > deadline:
            break
    process.kill()
    sys.exit(f"{' '.join(command[:3])} did not start")


def stop(process):
    if process.poll() is None:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()


def robot(binary, driver, logs, namespace, port):
    """Starts the robot of `driver`; the processes to stop and where the object to move lies (the pencil; the WidowX scene's red cube)."""
    common = ["--namespace", namespace, "--set", f"telemetry.log_dir={logs}",
              "--set", "safety.llm_motions_per_minute=0"]
    if driver == "sim":
        served, _ = start([binary, *common, "--http", f"127.0.0.1:{port}",
                           "--set", "robot.time_scale=1.0", "serve"], "robotd: serving on", logs)
        return [served], (0.22, -0.05)
    config = os.path.join(ROOT, "config", "widowx.toml")
    scene = os.path.join(ROOT, "config", "scenes", "widowx.toml")
    device = os.path.join(logs, "ttyDXL")
    fake, found = start([binary, *common, "--config", config, "--set", f'robot.scene="{scene}"',
                         "fake-widowx", "--device", device, "--camera-listen", "127.0.0.1:0"],
                        r"camera (http://\S+)", logs)
    served, _ = start([binary, *common, "--config", config, "--http", f"127.0.0.1:{port}",
                       "--set", f"robot.widowx.device={device}",
                       "--set", f"robot.widowx.camera_url={found.group(1)}", "serve"],
                      "robotd: serving on", logs)
    return [served, fake], (0.30, 0.05)


def seen_near(mcp, near):
    """The label and [x, y] (metres) of the object the camera sees nearest `near`."""
    reply = mcp.call("get_detected_objects", {})
    objects = json.loads(reply[reply.index("["):]) if "[" in reply else []
    if not objects:
        sys.exit(f"nothing seen: {reply[:500]}")
    centre = lambda o: (o["position"]["center_of_mass"]["x"], o["position"]["center_of_mass"]["y"])
    nearest = min(objects, key=lambda o: (centre(o)[0] - near[0]) ** 2 + (centre(o)[1] - near[1]) ** 2)
    x, y = centre(nearest)
    return nearest["label"], [round(x, 3), round(y, 3)]


def time_moves(binary, driver, moves):
    logs = tempfile.mkdtemp(prefix="robotd-pick-")
    port = free_port()
    processes, near = robot(binary, driver, logs, f"pick{os.getpid()}{driver}", port)
    try:
        mcp = Mcp(f"http://127.0.0.1:{port}")
        label, at = seen_near(mcp, near)
        times = []
        for i in range(moves):
            direction, step = ("left", 0.01) if i % 2 == 0 else ("right", -0.01)
            started = time.perf_counter()
            text = mcp.call("move2by", {"object_name": label, "pick_coordinate": at,
                                        "direction": direction, "distance": 0.01})
            times.append((time.perf_counter() - started) * 1000)
            if "✓" not in text:
                sys.exit(f"{driver}: move2by failed: {text}")
            at = [at[0], at[1] + step]
        return {"p50_ms": round(statistics.median(times), 1),
                "min_ms": round(min(times), 1), "max_ms": round(max(times), 1), "moves": moves}
    finally:
        for process in processes:
            stop(process)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("binaries", nargs="+")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--moves", type=int, default=8)
    parser.add_argument("--drivers", default="sim,widowx")
    args = parser.parse_args()
    results = []
    for round_ in range(1, args.rounds + 1):
        for binary in args.binaries:
            for driver in args.drivers.split(","):
                figures = time_moves(binary, driver, args.moves)
                results.append({"binary": binary, "driver": driver, "round": round_, **figures})
                print(json.dumps(results[-1]), file=sys.stderr)
    print(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
