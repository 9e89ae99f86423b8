"""Resident memory, descriptors and threads of an idle `robotd serve`, and after abandoned
MCP sessions: figures for BENCHMARKS.md (issue 20).

Starts `robotd serve` (default configuration: the simulated Ned2, perception, workspace model,
speech, MCP, dashboard; no LLM key, so no agent) on a free port in a namespace of its own,
waits for /health, then 8 s, and reads VmRSS, descriptors and threads from /proc. Then opens
N streamable-HTTP sessions (`initialize`, never closed) from one plain HTTP client, counts
how many were accepted and refused (503 past `mcp.max_sessions`), and reads the figures again
right after and once more after `--wait` seconds.

Usage: python scripts/bench/memory.py BINARY [--sessions 2000] [--wait 0]
Prints one JSON object. Linux only (/proc).
"""

import argparse
import json
import os
import time
import urllib.error
import urllib.request

from served import Served


def figures(pid):
    with open(f"/proc/{pid}/status") as f:
        rss_kb = next(int(line.split()[1]) for line in f if line.startswith("VmRSS:"))
    return {
        "rss_mb": round(rss_kb / 1024, 1),
        "fds": len(os.listdir(f"/proc/{pid}/fd")),
        "threads": len(os.listdir(f"/proc/{pid}/task")),
    }


INIT = json.dumps(
    {
        "jsonrpc": "2.0",
        "id": 1,
        "method": "initialize",
        "params": {
            "protocolVersion": "2025-06-18",
            "capabilities": {},
            "clientInfo": {"name": "abandoning-client", "version": "1"},
        },
    }
).encode()


def open_session(port):
    """One `initialize` on a fresh connection; returns the HTTP status."""
    request = urllib.request.Request(
        f"http://127.0.0.1:{port}/mcp",
        data=INIT,
        headers={
            "Content-Type": "application/json",
            "Accept": "application/json, text/event-stream",
        },
        method="POST",
    )
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            response.read()
            return response.status
    except urllib.error.HTTPError as error:
        return error.code


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("binary")
    parser.add_argument("--sessions", type=int, default=2000)
    parser.add_argument("--wait", type=float, default=0.0)
    args = parser.parse_args()

    with Served(args.binary, "mem") as robotd:
        time.sleep(8)
        result = {"idle": figures(robotd.pid)}
        statuses = {}
        for _ in range(args.sessions):
            status = open_session(robotd.port)
            statuses[status] = statuses.get(status, 0) + 1
        result["sessions_opened"] = args.sessions
        result["answers"] = {str(k): v for k, v in sorted(statuses.items())}
        result["after_sessions"] = figures(robotd.pid)
        if args.wait > 0:
            time.sleep(args.wait)
            result[f"after_{args.wait:g}_s"] = figures(robotd.pid)
        print(json.dumps(result))


if __name__ == "__main__":
    main()
