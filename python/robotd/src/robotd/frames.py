"""Camera frames as numpy arrays that view robotd's shared memory: no byte is copied.

``with sub.receive() as frame:`` gives a :class:`Frame` whose ``pixels`` is a read-only
``height × width × channels`` uint8 array over the very memory the camera wrote. Leaving the
``with`` block (or :meth:`Frame.release`) gives the memory back to the camera: the array must
not be used after that (copy what you keep: ``frame.pixels.copy()``). A subscriber may hold
at most two frames at once.
"""

from __future__ import annotations

import ctypes
import time
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from .bus import deadline_of
from .catalog import FramesSpec
from .errors import RobotdError
from .ports import PortOwner, wait_for_data
from .shm import FrameSlot, PIXELS_OFFSET


@dataclass(frozen=True)
class FrameInfo:
    """A frame's header fields."""

    frame_id: int
    timestamp_unix_ns: int
    width: int
    height: int
    channels: int
    #: "rgb8" or "bgr8".
    encoding: str
    #: Camera pose at capture: x, y, z (m), roll, pitch, yaw (rad), robot base frame.
    camera_pose: Tuple[float, float, float, float, float, float]
    seq: int


class Frame:
    """One received frame: :attr:`info` and :attr:`pixels` (a view of shared memory)."""

    def __init__(self, sample):
        self._sample = sample
        slot = FrameSlot.from_address(sample.payload_ptr)
        h = slot.header
        if not (0 < h.width <= 640 and 0 < h.height <= 480 and h.channels in (1, 3)):
            sample.delete()
            self._sample = None
            raise RobotdError(
                f"frame {h.frame_id} has an impossible size {h.width}x{h.height}x{h.channels}"
            )
        self.info = FrameInfo(
            frame_id=h.frame_id,
            timestamp_unix_ns=h.timestamp_unix_ns,
            width=h.width,
            height=h.height,
            channels=h.channels,
            encoding="bgr8" if h.encoding == 1 else "rgb8",
            camera_pose=tuple(h.camera_pose),
            seq=h.seq,
        )
        n = h.width * h.height * h.channels
        memory = (ctypes.c_uint8 * n).from_address(sample.payload_ptr + PIXELS_OFFSET)
        pixels = np.ctypeslib.as_array(memory).reshape(h.height, h.width, h.channels)
        # The subscriber's mapping is read-only: writing would crash the process.
        pixels.flags.writeable = False
        self.pixels: np.ndarray = pixels

    @property
    def released(self) -> bool:
        return self._sample is None

    def release(self) -> None:
        """Gives the frame's memory back; :attr:`pixels` must not be used afterwards."""
        if self._sample is not None:
            self.pixels = None
            self._sample.delete()
            self._sample = None

    def __enter__(self) -> "Frame":
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    def __del__(self):
        self.release()


class FrameSubscriber(PortOwner):
    """Receives a frame topic's frames; see :meth:`receive`."""

    _ports = ("_port", "_data", "_consumed")

    def __init__(self, bus, spec: FramesSpec):
        self.spec = spec
        self._service = bus.open_frames(spec)
        self._port = self._service.subscriber_builder().buffer_size(spec.depth).create()
        self._data = bus.open_event(bus.catalog.event("data", spec.name)).listener_builder().create()
        self._consumed = None
        if not spec.latest_wins:
            self._consumed = (
                bus.open_event(bus.catalog.event("consumed", spec.name)).notifier_builder().create()
            )

    def receive(self, timeout: Optional[float] = None, newest: bool = True) -> Optional[Frame]:
        """The next frame, or None after ``timeout`` seconds (None: wait as long as it takes).

        With ``newest`` (the default) older frames waiting are skipped: a slow consumer always
        works on the newest view, as robotd's own perception does.
        """
        deadline = deadline_of(timeout)
        while True:
            sample = self._port.receive()
            if sample is not None:
                if newest:
                    while True:
                        later = self._port.receive()
                        if later is None:
                            break
                        sample.delete()
                        sample = later
                if self._consumed is not None:
                    self._consumed.notify()
                return Frame(sample)
            if not wait_for_data(self._data, deadline):
                return None


class FramePublisher(PortOwner):
    """Publishes frames on a frame topic (a camera written in Python); see :meth:`publish`."""

    _ports = ("_port", "_data")

    def __init__(self, bus, spec: FramesSpec):
        self.spec = spec
        self._service = bus.open_frames(spec, create=True)
        self._port = self._service.publisher_builder().max_loaned_samples(2).create()
        self._data = bus.open_event(bus.catalog.event("data", spec.name)).notifier_builder().create()
        self._seq = 0

    def publish(
        self,
        pixels: np.ndarray,
        frame_id: int,
        camera_pose=(0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        timestamp_unix_ns: Optional[int] = None,
        encoding: str = "rgb8",
    ) -> int:
        """Copies ``pixels`` (``height × width × channels`` uint8, at most 640×480×3) once, into
        shared memory, and sends the frame; returns how many subscribers received it."""
        pixels = np.ascontiguousarray(pixels, dtype=np.uint8)
        if pixels.ndim != 3 or pixels.shape[2] not in (1, 3):
            raise RobotdError(f"frames are height × width × 1 or 3 uint8, got {pixels.shape}")
        h, w, c = pixels.shape
        if w > self.spec.max_width or h > self.spec.max_height:
            raise RobotdError(
                f"a {w}x{h} frame is larger than {self.spec.max_width}x{self.spec.max_height}"
            )
        if encoding not in ("rgb8", "bgr8"):
            raise RobotdError(f"encoding must be 'rgb8' or 'bgr8', got {encoding!r}")
        if len(camera_pose) != 6:
            raise RobotdError("camera_pose is x, y, z, roll, pitch, yaw: 6 numbers")
        sample = self._port.loan_uninit()
        slot = FrameSlot.from_address(sample.payload_ptr)
        header = slot.header
        header.frame_id = int(frame_id)
        header.timestamp_unix_ns = int(
            time.time_ns() if timestamp_unix_ns is None else timestamp_unix_ns
        )
        header.width, header.height, header.channels = w, h, c
        header.encoding = 1 if encoding == "bgr8" else 0
        for i, v in enumerate(camera_pose):
            header.camera_pose[i] = float(v)
        self._seq += 1
        header.seq = self._seq
        header.traceparent_len = 0
        ctypes.memmove(sample.payload_ptr + PIXELS_OFFSET, pixels.ctypes.data, pixels.nbytes)
        delivered = sample.assume_init().send()
        self._data.notify()
        return delivered
