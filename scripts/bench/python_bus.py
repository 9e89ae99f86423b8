"""Python actors on the bus, measured: figures for BENCHMARKS.md (issue 19).

In one run, on this machine:

1. Camera frames (640×480×3) from one Python process to another:
   - robotd's package: FramePublisher -> FrameSubscriber (numpy view of shared memory);
   - raw iceoryx2 Python pub/sub of the same payload (a byte slice of the same size, the same
     wake-up event, numpy view), the baseline;
   - the Redis path Python tools used before: JPEG q85 (OpenCV) + base64 + XADD, read with
     XREAD BLOCK, decoded back to a numpy array.
   Each twice: paced at 30 frames/s (latency: receive time minus the capture time stamped by
   the sender, p50 / p99) and unpaced (frames/s the subscriber takes in, touching a pixel).
2. A service round trip to a running robotd's system/ping: the Python client beside
   `robotd bench ping` (a Rust client of the same service of the same robotd).

Usage: python scripts/bench/python_bus.py ROBOTD_BINARY [--frames N] [--round-trips N]
Starts its own robotd serve and redis-server; prints one JSON object.
"""

import argparse
import atexit
import ctypes
import json
import os
import socket
import subprocess
import sys
import tempfile
import time

import numpy as np

FRAME_SHAPE = (480, 640, 3)
PACED_FPS = 30.0


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def percentile(values, p):
    values = sorted(values)
    if not values:
        return float("nan")
    return values[min(len(values) - 1, int(round(p / 100 * (len(values) - 1))))]


def test_image(i):
    image = np.full(FRAME_SHAPE, 90, np.uint8)
    image[100:300, (i * 7) % 400 : (i * 7) % 400 + 200] = (200, 40, 40)
    return image


# -- senders (run as child processes: `--role ...`) ---------------------------------------


def send_robotd(namespace, count, fps):
    from robotd import Bus

    with Bus(namespace, node_name="bench-py-pub") as bus:
        camera = bus.frame_publisher("example/test_pattern/frames")
        images = [test_image(i) for i in range(8)]
        wait_for_subscriber(lambda: camera._service.dynamic_config.number_of_subscribers)
        for i in range(count):
            started = time.perf_counter()
            camera.publish(images[i % 8], frame_id=i + 1, timestamp_unix_ns=time.time_ns())
            pace(started, fps)


def raw_service(node, name, create):
    import iceoryx2 as iox2

    builder = (
        node.service_builder(iox2.ServiceName.new(name))
        .publish_subscribe(iox2.Slice[ctypes.c_uint8])
        .enable_safe_overflow(True)
        .subscriber_max_buffer_size(2)
        .history_size(0)
    )
    return builder.open_or_create() if create else builder.open()


def raw_event(node, name):
    import iceoryx2 as iox2

    return node.service_builder(iox2.ServiceName.new(name + "/ready")).event().open_or_create()


def send_raw(namespace, count, fps):
    import iceoryx2 as iox2

    iox2.set_log_level_from_env_or(iox2.LogLevel.Error)
    node = iox2.NodeBuilder.new().create(iox2.ServiceType.Ipc)
    name = f"{namespace}/raw_frames"
    service = raw_service(node, name, True)
    publisher = service.publisher_builder().initial_max_slice_len(8 + np.prod(FRAME_SHAPE)).create()
    notifier = raw_event(node, name).notifier_builder().create()
    images = [test_image(i) for i in range(8)]
    wait_for_subscriber(lambda: service.dynamic_config.number_of_subscribers)
    n = 8 + int(np.prod(FRAME_SHAPE))
    for i in range(count):
        started = time.perf_counter()
        stamp = time.time_ns()  # the capture time, before the copy (as the robotd sender)
        sample = publisher.loan_slice_uninit(n)
        ctypes.c_uint64.from_address(sample.payload_ptr).value = stamp
        ctypes.memmove(sample.payload_ptr + 8, images[i % 8].ctypes.data, n - 8)
        sample.assume_init().send()
        notifier.notify()
        pace(started, fps)


def send_redis(port, count, fps):
    import base64

    import cv2
    import redis

    r = redis.Redis(port=port)
    images = [test_image(i) for i in range(8)]
    time.sleep(0.3)
    for i in range(count):
        started = time.perf_counter()
        stamp = time.time_ns()
        ok, jpeg = cv2.imencode(".jpg", images[i % 8], [cv2.IMWRITE_JPEG_QUALITY, 85])
        r.xadd(
            "robot_camera",
            {"timestamp": str(stamp), "image_data": base64.b64encode(jpeg.tobytes())},
            maxlen=10,
            approximate=True,
        )
        pace(started, fps)


def wait_for_subscriber(count):
    deadline = time.time() + 10
    while time.time() < deadline:
        n = count()
        if (n() if callable(n) else n) > 0:
            return
        time.sleep(0.01)
    raise SystemExit("no subscriber connected within 10 s")


def pace(started, fps):
    if fps > 0:
        left = 1.0 / fps - (time.perf_counter() - started)
        if left > 0:
            time.sleep(left)


# -- receivers (this process) ---------------------------------------------------------------


def spawn(role, *args):
    return subprocess.Popen([sys.executable, __file__, "--role", role, *map(str, args)])


def receive_robotd(namespace, count, fps):
    from robotd import Bus, NotRunning

    sender = spawn("robotd", namespace, count, fps)
    with Bus(namespace, node_name="bench-py-sub") as bus:
        deadline = time.time() + 10
        while True:
            try:
                frames = bus.frame_subscriber("example/test_pattern/frames")
                break
            except NotRunning:
                if time.time() > deadline:
                    raise
                time.sleep(0.01)
        return collect(sender, lambda: robotd_frame(frames))


def robotd_frame(frames):
    frame = frames.receive(timeout=2.0)
    if frame is None:
        return None
    with frame:
        _ = int(frame.pixels[240, 320, 0])
        return frame.info.timestamp_unix_ns


def receive_raw(namespace, count, fps):
    import iceoryx2 as iox2

    sender = spawn("raw", namespace, count, fps)
    node = iox2.NodeBuilder.new().create(iox2.ServiceType.Ipc)
    name = f"{namespace}/raw_frames"
    deadline = time.time() + 10
    while True:
        try:
            service = raw_service(node, name, False)
            break
        except Exception:
            if time.time() > deadline:
                raise
            time.sleep(0.01)
    subscriber = service.subscriber_builder().create()
    listener = raw_event(node, name).listener_builder().create()

    def one():
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            sample = subscriber.receive()
            if sample is None:
                listener.timed_wait(iox2.Duration.from_millis(100))
                continue
            newer = subscriber.receive()
            while newer is not None:
                sample.delete()
                sample, newer = newer, subscriber.receive()
            n = 8 + int(np.prod(FRAME_SHAPE))
            memory = (ctypes.c_uint8 * n).from_address(sample.payload_ptr)
            pixels = np.ctypeslib.as_array(memory)[8:].reshape(FRAME_SHAPE)
            _ = int(pixels[240, 320, 0])
            stamp = ctypes.c_uint64.from_address(sample.payload_ptr).value
            del pixels, memory
            sample.delete()
            return stamp
        return None

    return collect(sender, one)


def receive_redis(port, count, fps):
    import base64

    import cv2
    import redis

    r = redis.Redis(port=port)
    last = "$"
    sender = spawn("redis", port, count, fps)

    def one():
        nonlocal last
        reply = r.xread({"robot_camera": last}, count=100, block=2000)
        if not reply:
            return None
        entries = reply[0][1]
        last, fields = entries[-1]
        jpeg = base64.b64decode(fields[b"image_data"])
        pixels = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
        _ = int(pixels[240, 320, 0])
        return int(fields[b"timestamp"])

    return collect(sender, one)


def collect(sender, one):
    latencies, got, first = [], 0, None
    while True:
        stamp = one()
        if stamp is None:
            if sender.poll() is not None:
                break
            continue
        now = time.time_ns()
        first = first or time.perf_counter()
        latencies.append((now - stamp) / 1e3)
        got += 1
    elapsed = time.perf_counter() - first if first else float("nan")
    sender.wait()
    return {
        "frames_received": got,
        "frames_per_s": round(got / elapsed, 1) if got > 1 else 0.0,
        "latency_us_p50": round(percentile(latencies, 50), 1),
        "latency_us_p99": round(percentile(latencies, 99), 1),
    }


def start(command, ready_text, stream="stderr"):
    process = subprocess.Popen(
        command,
        stdout=subprocess.PIPE if stream == "stdout" else subprocess.DEVNULL,
        stderr=subprocess.PIPE if stream == "stderr" else subprocess.DEVNULL,
        text=True,
    )
    atexit.register(process.kill)
    pipe = process.stderr if stream == "stderr" else process.stdout
    for line in pipe:
        if ready_text in line:
            return process
    raise SystemExit(f"{command[0]} ended before '{ready_text}'")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("robotd")
    parser.add_argument("--frames", type=int, default=600)
    parser.add_argument("--round-trips", type=int, default=3000)
    args = parser.parse_args()
    namespace = f"bench-py-{os.getpid()}"
    report = {"frame": list(FRAME_SHAPE), "paced_fps": PACED_FPS}

    redis_port = free_port()
    start(
        ["redis-server", "--port", str(redis_port), "--save", "", "--appendonly", "no"],
        "Ready to accept connections",
        stream="stdout",
    )
    for label, fps, count in (("paced", PACED_FPS, min(args.frames, 300)), ("unpaced", 0, args.frames)):
        report[label] = {
            "robotd_package": receive_robotd(namespace + "-f", count, fps),
            "raw_iceoryx2": receive_raw(namespace + "-r", count, fps),
            "redis_jpeg": receive_redis(redis_port, count, fps),
        }
    paced = report["paced"]
    unpaced = report["unpaced"]
    report["latency_ratio_robotd_to_raw"] = round(
        paced["robotd_package"]["latency_us_p50"] / paced["raw_iceoryx2"]["latency_us_p50"], 2
    )
    report["throughput_ratio_raw_to_robotd"] = round(
        unpaced["raw_iceoryx2"]["frames_per_s"] / unpaced["robotd_package"]["frames_per_s"], 2
    )

    http = free_port()
    logs = tempfile.mkdtemp(prefix="robotd-bench-py-")
    start(
        [
            args.robotd, "serve", "--namespace", namespace, "--http", f"127.0.0.1:{http}",
            "--set", f"telemetry.log_dir={logs}",
        ],
        "robotd: serving on",
    )
    from robotd import Bus

    with Bus(namespace, node_name="bench-py-client") as bus:
        ping = bus.client("system/ping")
        samples = []
        for seq in range(args.round_trips + 200):
            started = time.perf_counter()
            ping.request({"seq": seq, "payload": b""}, timeout=5.0)
            if seq >= 200:
                samples.append((time.perf_counter() - started) * 1e6)
    rust = json.loads(
        subprocess.run(
            [args.robotd, "bench", "ping", "--json", "--namespace", namespace,
             "--round-trips", str(args.round_trips)],
            check=True, capture_output=True, text=True,
        ).stdout
    )
    report["service_round_trip"] = {
        "python_client_us_p50": round(percentile(samples, 50), 1),
        "python_client_us_p99": round(percentile(samples, 99), 1),
        "rust_client_us_p50": round(rust["round_trip_us_p50"], 1),
        "rust_client_us_p99": round(rust["round_trip_us_p99"], 1),
        "round_trips": args.round_trips,
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--role":
        role, target, count, fps = sys.argv[2], sys.argv[3], int(sys.argv[4]), float(sys.argv[5])
        {"robotd": send_robotd, "raw": send_raw, "redis": lambda t, c, f: send_redis(int(t), c, f)}[
            role
        ](target, count, fps)
    else:
        main()
