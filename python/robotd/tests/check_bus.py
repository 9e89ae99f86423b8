"""The robotd Python package against a running robotd (run by tests/python_actor.rs).

Usage: python check_bus.py NAMESPACE

Checks, printing one JSON object with what it saw (the Rust test asserts on it):
- arm/state arrives as a typed message;
- camera frames arrive as numpy arrays that view shared memory (no copy, read-only), with
  frame ids increasing, and are given back;
- system/ping (served by robotd in Rust) answers, with the payload bytes echoed;
- workspace/query answers a malformed request with robotd's bad_request fault;
- a service served here in Python is called from here; an expired request is not executed;
- a Python camera publishes frames that a second subscriber receives with header and pixels;
- errors: a wrong namespace, a schema version mismatch and undecodable bytes each raise their
  own exception with a message naming the cause.
"""

import json
import sys
import threading
import time

import numpy as np

import robotd
from robotd import Bus, DecodeError, Fault, NotRunning, SchemaMismatch
from robotd.catalog import TopicSpec
from robotd.messages import ArmState
from robotd.ports import Publisher, Subscriber
from robotd.shm import PIXELS_OFFSET


def main(namespace: str) -> None:
    report = {}
    with Bus(namespace, node_name="python-check") as bus:
        arm = bus.subscriber("arm/state")
        message = arm.receive(timeout=5.0)
        state = ArmState.from_dict(message.body)
        report["arm_state"] = {
            "msg_type": message.msg_type,
            "schema_version": message.schema_version,
            "z": state.tool_pose.z,
            "calibrated": state.calibrated,
        }

        frames = bus.frame_subscriber("camera/frames")
        ids, views = [], []
        for _ in range(5):
            with frames.receive(timeout=5.0) as frame:
                pixels = frame.pixels
                views.append(
                    {
                        "shape": list(pixels.shape),
                        "dtype": str(pixels.dtype),
                        "owns_data": bool(pixels.flags.owndata),
                        "writeable": bool(pixels.flags.writeable),
                        "address_is_shared_memory": pixels.ctypes.data
                        == frame._sample.payload_ptr + PIXELS_OFFSET,
                        "mean": float(pixels.mean()),
                    }
                )
                ids.append(frame.info.frame_id)
            report["released"] = frame.released
        report["frame_ids"] = ids
        report["frames"] = views

        ping = bus.client("system/ping")
        started = time.perf_counter()
        pong = ping.request({"seq": 42, "payload": b"from python"}, timeout=5.0)
        report["ping"] = {
            "seq": pong["seq"],
            "payload": pong["payload"].decode(),
            "served_by_pid": pong["served_by_pid"],
            "round_trip_ms": (time.perf_counter() - started) * 1e3,
        }
        try:
            bus.client("workspace/query").request({"nonsense": True}, timeout=5.0)
            report["bad_query"] = "answered"
        except Fault as e:
            report["bad_query"] = {"kind": e.kind, "message": e.message}

        # A service of our own, served in a thread, called from here.
        spec = bus.custom_service("python_check/echo", "check.echo", "check.echo_reply")
        server = bus.server(spec)
        served = []

        def serve():
            while len(served) < 2:
                request = server.next(timeout=5.0)
                if request is None:
                    return
                served.append(request.body)
                if request.body.get("refuse"):
                    request.fail("refused", "asked to refuse")
                else:
                    request.reply({"echo": request.body["text"].upper()})

        thread = threading.Thread(target=serve)
        thread.start()
        client = bus.custom_client(spec)
        deadline = time.time() + 5
        while not client.has_server() and time.time() < deadline:
            time.sleep(0.01)
        report["echo"] = client.request({"text": "hello"}, timeout=5.0)
        try:
            client.request({"text": "no", "refuse": True}, timeout=5.0)
            report["refused"] = "answered"
        except Fault as e:
            report["refused"] = {"kind": e.kind, "message": e.message}
        thread.join()
        report["served"] = served

        # A camera in Python, on the example frame topic.
        camera = bus.frame_publisher("example/test_pattern/frames")
        viewer = bus.frame_subscriber("example/test_pattern/frames")
        image = np.zeros((480, 640, 3), np.uint8)
        image[:, :, 0] = 200
        image[100:200, 300:400] = (10, 250, 30)
        delivered = camera.publish(image, frame_id=77, camera_pose=(0.1, 0.2, 0.3, 0, 1.5, 0))
        with viewer.receive(timeout=5.0) as seen:
            report["python_camera"] = {
                "delivered": delivered,
                "frame_id": seen.info.frame_id,
                "camera_pose": list(seen.info.camera_pose),
                "equal": bool(np.array_equal(seen.pixels, image)),
            }

        # Errors.
        errors = {}
        try:
            Bus("no-robotd-here", node_name="python-check-wrong").subscriber("arm/state")
            errors["wrong_namespace"] = None
        except NotRunning as e:
            errors["wrong_namespace"] = str(e)
        newer = TopicSpec(**{**bus.catalog.topic("arm/state").__dict__, "schema_version": 2})
        try:
            Subscriber(bus, newer).receive(timeout=5.0)
            errors["schema_mismatch"] = None
        except SchemaMismatch as e:
            errors["schema_mismatch"] = str(e)
        scratch = TopicSpec(
            **{
                **bus.catalog.topic("overlay/text").__dict__,
                "name": "python_check/scratch",
            }
        )
        listener = Subscriber(bus, scratch, create=True)
        garbage = Publisher(bus, scratch, create=True)
        garbage.publish_bytes(b"\xc1 not msgpack")
        try:
            listener.receive(timeout=5.0)
            errors["undecodable"] = None
        except DecodeError as e:
            errors["undecodable"] = str(e)
        report["errors"] = errors
        report["version"] = robotd.__name__
    print(json.dumps(report))


if __name__ == "__main__":
    main(sys.argv[1])
