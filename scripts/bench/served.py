"""A `robotd serve` for the benchmark scripts: started on a free loopback port in a namespace
of its own (default configuration, logs in a temporary folder), ready once /health answers,
stopped with SIGTERM (so it cleans its shared memory) when the `with` block ends.

    with Served(binary, "mem") as robotd:
        ... robotd.pid, robotd.port ...
"""

import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Served:
    def __init__(self, binary, tag):
        self.port = free_port()
        logs = tempfile.mkdtemp(prefix=f"robotd-{tag}-")
        self.process = subprocess.Popen(
            [binary, "serve", "--namespace", f"{tag}{os.getpid()}",
             "--http", f"127.0.0.1:{self.port}", "--set", f"telemetry.log_dir={logs}"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        self.pid = self.process.pid

    def __enter__(self):
        deadline = time.monotonic() + 60
        while True:
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{self.port}/health", timeout=1).read()
                return self
            except OSError:
                if time.monotonic() > deadline or self.process.poll() is not None:
                    self.__exit__(None, None, None)
                    sys.exit("robotd serve did not answer /health")
                time.sleep(0.2)

    def __exit__(self, *_):
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            self.process.wait(timeout=30)
