"""A detector written in Python that joins robotd's bus: colour blobs in, objects out.

It reads the wrist camera's frames straight from shared memory (a numpy array, no copy), finds
strongly coloured blobs with OpenCV (HSV threshold, contours), names each by its hue ("red
object", "blue object", ...) and publishes them in pixels on `perception/pixel_detections`.
robotd's perception places them on the table through the workspace sheet, and the workspace
model tracks them with robotd's own detections: `get_detected_objects` over MCP lists them
with `source` = this detector's name.

    python colour_detector.py                 # namespace: $ROBOTD_BUS__NAMESPACE or "robotd"
    python colour_detector.py --namespace lab1 --frames 100

Run it by hand, or let robotd start and supervise it (config):

    [actors.colour_detector]
    mode = "process"
    command = ["python3", "python/robotd/examples/colour_detector.py"]

It prints "ready" once its ports are open, then one line per 100 frames.
"""

import argparse
import sys
import time

import cv2
import numpy as np

from robotd import Bus, NotRunning
from robotd.messages import PixelDetection, PixelDetections

#: The detector's name: the `source` of its objects in robotd.
SOURCE = "python-colour"

#: Hue ranges (OpenCV's 0..180 scale) and their names.
HUES = [
    (0, 8, "red"),
    (8, 20, "orange"),
    (20, 35, "yellow"),
    (35, 85, "green"),
    (85, 100, "cyan"),
    (100, 130, "blue"),
    (130, 160, "purple"),
    (160, 181, "red"),
]

MIN_AREA_PX = 60
MIN_SATURATION = 110
MIN_VALUE = 70


def hue_name(hue: float) -> str:
    for low, high, name in HUES:
        if low <= hue < high:
            return name
    return "red"


def find_blobs(rgb: np.ndarray):
    """Coloured blobs in an RGB image: (label, confidence, box, mask pixel indices)."""
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
    mask = cv2.inRange(hsv, (0, MIN_SATURATION, MIN_VALUE), (180, 255, 255))
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    width = rgb.shape[1]
    blobs = []
    for contour in contours:
        if cv2.contourArea(contour) < MIN_AREA_PX:
            continue
        x, y, w, h = cv2.boundingRect(contour)
        blob = np.zeros(mask.shape, np.uint8)
        cv2.drawContours(blob, [contour], -1, 255, thickness=cv2.FILLED)
        blob &= mask
        vs, us = np.nonzero(blob)
        if len(vs) < MIN_AREA_PX:
            continue
        hue = float(np.median(hsv[vs, us, 0]))
        saturation = float(np.median(hsv[vs, us, 1]))
        pixels = (vs.astype(np.int64) * width + us).tolist()
        confidence = round(min(1.0, saturation / 255.0 + 0.3), 3)
        blobs.append((f"{hue_name(hue)} object", confidence, (x, y, x + w, y + h), pixels))
    return blobs


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--namespace", help="robotd's bus namespace")
    parser.add_argument("--frames", type=int, default=0, help="stop after N frames (0: never)")
    args = parser.parse_args()
    try:
        bus = Bus(args.namespace, node_name="python-colour-detector")
        frames = bus.frame_subscriber("camera/frames")
        out = bus.publisher("perception/pixel_detections")
    except NotRunning as e:
        print(f"colour detector: {e}", file=sys.stderr)
        return 2
    print("ready", flush=True)
    done = 0
    started = time.monotonic()
    while args.frames == 0 or done < args.frames:
        frame = frames.receive(timeout=1.0)
        if frame is None:
            continue
        with frame:
            if frame.info.encoding != "rgb8" or frame.info.channels != 3:
                continue
            blobs = find_blobs(frame.pixels)
            message = PixelDetections(
                frame_id=frame.info.frame_id,
                camera_pose=frame.info.camera_pose,
                source=SOURCE,
                objects=[
                    PixelDetection(label, confidence, box, mask_pixels=pixels)
                    for label, confidence, box, pixels in blobs
                ],
            )
        out.publish(message)
        done += 1
        if done % 100 == 0:
            rate = done / (time.monotonic() - started)
            print(f"{done} frames, {rate:.1f} frames/s, {len(blobs)} objects", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
