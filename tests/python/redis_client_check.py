"""A lab's Python detector against robotd's Redis edge, written the way such tools are (redis-py,
decode_responses=True, Pillow).

Usage: python redis_client_check.py REDIS_PORT

1. Reads the newest `robot_camera` entry and decodes its JPEG; reports the fields, the image
   size and mode, and the metadata.
2. Finds the pencil in robotd's own newest steady `detected_objects` entry (its relative box).
3. Acts as an external open-vocabulary detector: answers that entry's camera frame with a
   vision-format detection of a "screwdriver" at the pencil's pixels (box and mask), naming
   the frame, and announces the label on `detectable_labels`.

Prints one JSON object with what it saw and sent; the Rust test (tests/redis_edge.rs) checks it
and then asks robotd's tools where the screwdriver is.
"""

import base64
import io
import json
import sys
import time

import redis
from PIL import Image


def newest(r, stream, predicate=lambda fields: True, timeout_s=10.0):
    deadline = time.time() + timeout_s
    while time.time() < deadline:
        for _id, fields in r.xrevrange(stream, count=20):
            if predicate(fields):
                return fields
        time.sleep(0.1)
    raise SystemExit(f"no entry in {stream} within {timeout_s} s")


def main(port: int) -> None:
    r = redis.Redis(host="127.0.0.1", port=port, db=0, decode_responses=True)
    report = {}

    camera = newest(r, "robot_camera")
    image = Image.open(io.BytesIO(base64.b64decode(camera["image_data"])))
    image.load()
    report["camera_fields"] = sorted(camera.keys())
    report["camera"] = {k: v for k, v in camera.items() if k != "image_data"}
    report["image"] = {"format": image.format, "size": list(image.size), "mode": image.mode}
    report["camera_metadata"] = json.loads(camera["metadata"])

    def published_frame_ids():
        return {
            json.loads(fields["metadata"]).get("frame_id")
            for _id, fields in r.xrevrange("robot_camera", count=10)
        }

    def has_steady_pencil(fields):
        # A view taken with the arm at rest, of a frame robotd published to robot_camera (the
        # camera runs faster than the stream, so not every detected frame is one a detector
        # reading the stream could answer): the frames robotd keeps for answers like ours.
        pose = json.loads(fields.get("camera_pose", "{}"))
        objects = json.loads(fields.get("objects", "[]"))
        return (
            pose.get("steady") is True
            and any(o.get("label") == "pencil" for o in objects)
            and pose.get("frame_id") in published_frame_ids()
        )

    ours = newest(r, "detected_objects", has_steady_pencil)
    ours_pose = json.loads(ours["camera_pose"])
    pencil = next(o for o in json.loads(ours["objects"]) if o["label"] == "pencil")
    report["robotd_object_keys"] = sorted(pencil.keys())
    report["pencil"] = pencil

    # The detector's answer to the frame the pencil was seen in, as OWLv2/YOLOE pipelines write
    # it (answering another frame would put the pencil's box where the camera then looked).
    frame = newest(r, "robot_camera")
    w, h = int(frame["width"]), int(frame["height"])
    box = pencil["image_coordinates"]["bounding_box_rel"]
    x0, y0 = int(box["u_min"] * w), int(box["v_min"] * h)
    x1, y1 = int(round(box["u_max"] * w)), int(round(box["v_max"] * h))
    mask = bytearray(w * h)
    for v in range(y0, y1):
        for u in range(x0, x1):
            mask[v * w + u] = 1
    detection = {
        "label": "screwdriver",
        "confidence": 0.87,
        "class_id": 12,
        "bbox": {"x_min": x0, "y_min": y0, "x_max": x1, "y_max": y1},
        "has_mask": True,
        "mask_data": base64.b64encode(bytes(mask)).decode(),
        "mask_shape": [h, w],
        "mask_dtype": "uint8",
        "track_id": 7,
    }
    now = time.time()
    r.xadd(
        "detected_objects",
        {
            "timestamp": str(now),
            "objects": json.dumps([detection]),
            "camera_pose": json.dumps(
                {
                    "timestamp": float(ours_pose["timestamp"]),
                    "object_count": 1,
                    "detection_method": "yoloe",
                    "model_id": "yoloe-11s-test",
                    "frame_id": ours_pose["frame_id"],
                }
            ),
        },
        maxlen=500,
        approximate=True,
    )
    labels = json.loads(newest(r, "detectable_labels")["labels"])
    r.xadd(
        "detectable_labels",
        {
            "timestamp": str(now),
            "labels": json.dumps(labels + ["screwdriver"]),
            "label_count": str(len(labels) + 1),
            "metadata": json.dumps({"action": "add", "added_label": "screwdriver"}),
        },
        maxlen=1,
        approximate=True,
    )
    report["sent_frame_id"] = ours_pose["frame_id"]
    report["sent_box"] = [x0, y0, x1, y1]
    print(json.dumps(report))


if __name__ == "__main__":
    main(int(sys.argv[1]))
