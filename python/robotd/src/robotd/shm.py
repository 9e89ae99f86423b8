"""The shared-memory types robotd declares, as ctypes structures of the same layout.

iceoryx2 compares a service's payload and user-header types by name, size and alignment in
every process; these classes carry the names robotd's Rust structs declare
(``#[type_name(...)]``) and the same ``repr(C)`` layout.
"""

import ctypes

#: Largest frame and bytes per pixel (the Ned2 wrist camera's 640×480 RGB8).
FRAME_WIDTH = 640
FRAME_HEIGHT = 480
FRAME_CHANNELS = 3
FRAME_BYTES = FRAME_WIDTH * FRAME_HEIGHT * FRAME_CHANNELS
TRACEPARENT_BYTES = 64


class MessageHeader(ctypes.Structure):
    """The user header of every message topic: the publisher's sequence number."""

    _fields_ = [("seq", ctypes.c_uint64)]

    @staticmethod
    def type_name() -> str:
        return "robotd.MessageHeader.v1"


class FrameHeader(ctypes.Structure):
    """A camera frame's metadata, stored in shared memory before its pixels."""

    _fields_ = [
        ("frame_id", ctypes.c_uint64),
        ("timestamp_unix_ns", ctypes.c_uint64),
        ("width", ctypes.c_uint32),
        ("height", ctypes.c_uint32),
        ("channels", ctypes.c_uint32),
        # 0 = RGB8, 1 = BGR8.
        ("encoding", ctypes.c_uint32),
        # Camera pose at capture: x, y, z (m), roll, pitch, yaw (rad), robot base frame.
        ("camera_pose", ctypes.c_double * 6),
        ("seq", ctypes.c_uint64),
        ("traceparent_len", ctypes.c_uint32),
        ("traceparent", ctypes.c_uint8 * TRACEPARENT_BYTES),
    ]

    @staticmethod
    def type_name() -> str:
        return "robotd.FrameHeader.v1"


class FrameSlot(ctypes.Structure):
    """One frame in shared memory: header and pixels."""

    _fields_ = [("header", FrameHeader), ("pixels", ctypes.c_uint8 * FRAME_BYTES)]

    @staticmethod
    def type_name() -> str:
        return "robotd.FrameSlot.v1"


#: Offset of the pixels in a slot.
PIXELS_OFFSET = FrameSlot.pixels.offset
