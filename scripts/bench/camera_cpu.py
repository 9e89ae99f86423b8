"""CPU of an idle `robotd serve` with and without someone watching the dashboard's camera:
figures for BENCHMARKS.md (issue 20).

The dashboard encodes camera frames (JPEG, with the detections drawn) only while a viewer
watches. This starts `robotd serve` (default configuration, simulated Ned2) on a free port in
a namespace of its own, waits for /health and 5 s more, then measures the service's CPU (user
+ system time from /proc, as a percentage of one core) over `--seconds` in three phases:
nobody watching, one `/api/camera.mjpg` viewer reading every frame, and nobody again (after
the 5 s the dashboard keeps encoding for a single-frame request). Each phase also reports the
dashboard's `page_fps` and `bus_fps`.

Usage: python scripts/bench/camera_cpu.py BINARY [--seconds 20]
Prints one JSON object. Linux only (/proc).
"""

import argparse
import json
import os
import socket
import threading
import time
import urllib.request

from served import Served


def cpu_seconds(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    # utime and stime are fields 14 and 15 of stat; after the command name they are 12 and 13.
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def camera(port):
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/api/status", timeout=5) as r:
        return json.load(r)["camera"]


def measure(pid, port, seconds):
    start_cpu, start = cpu_seconds(pid), time.monotonic()
    time.sleep(seconds)
    used, elapsed = cpu_seconds(pid) - start_cpu, time.monotonic() - start
    figures = camera(port)
    return {
        "cpu_percent": round(100 * used / elapsed, 1),
        "page_fps": round(figures["page_fps"], 1),
        "bus_fps": round(figures["bus_fps"], 1),
    }


class Viewer:
    """An open MJPEG stream, read to the end on a thread (as a browser's <img> does)."""

    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port))
        self.sock.sendall(
            f"GET /api/camera.mjpg HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode()
        )
        self.bytes = 0
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        try:
            while chunk := self.sock.recv(65536):
                self.bytes += len(chunk)
        except OSError:
            pass

    def close(self):
        self.sock.close()


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("binary")
    parser.add_argument("--seconds", type=float, default=20)
    args = parser.parse_args()
    with Served(args.binary, "camcpu") as robotd:
        port = robotd.port
        time.sleep(5)
        result = {"nobody_watching": measure(robotd.pid, port, args.seconds)}
        viewer = Viewer(port)
        time.sleep(3)
        result["one_mjpeg_viewer"] = measure(robotd.pid, port, args.seconds)
        result["one_mjpeg_viewer"]["viewer_mb_read"] = round(viewer.bytes / 1e6, 1)
        viewer.close()
        time.sleep(8)
        result["nobody_watching_again"] = measure(robotd.pid, port, args.seconds)
        print(json.dumps(result))


if __name__ == "__main__":
    main()
