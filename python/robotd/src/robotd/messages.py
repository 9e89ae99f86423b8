"""Dataclasses for the messages a Python actor most often sends and reads.

Each mirrors a Rust protocol struct field by field (same names, same units) and converts to
and from the dict the envelope carries (:meth:`to_dict`, :meth:`from_dict`). Messages without
a class here arrive as plain dicts with the Rust field names (see ``docs/`` and
``robotd catalog``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import List, Optional, Sequence


@dataclass
class Pose:
    """A pose in the robot's base frame: metres and radians (``arm.state``'s ``tool_pose``)."""

    x: float
    y: float
    z: float
    roll: float
    pitch: float
    yaw: float

    @classmethod
    def from_dict(cls, d: dict) -> "Pose":
        return cls(*(float(d[k]) for k in ("x", "y", "z", "roll", "pitch", "yaw")))


@dataclass
class ArmState:
    """``arm/state`` (``arm.state`` v1)."""

    tool_pose: Pose
    joints: dict
    moving: bool
    collision_detected: bool
    calibrated: bool
    estop_engaged: bool = False
    still_since_unix_ns: int = 0

    @classmethod
    def from_dict(cls, d: dict) -> "ArmState":
        return cls(
            tool_pose=Pose.from_dict(d["tool_pose"]),
            joints=d.get("joints", {}),
            moving=bool(d["moving"]),
            collision_detected=bool(d["collision_detected"]),
            calibrated=bool(d["calibrated"]),
            estop_engaged=bool(d.get("estop_engaged", False)),
            still_since_unix_ns=int(d.get("still_since_unix_ns", 0)),
        )


@dataclass
class PixelDetection:
    """One object a detector found, in pixels of one frame."""

    label: str
    confidence: float
    #: ``[x_min, y_min, x_max, y_max]``, pixels, max exclusive.
    bbox_px: Sequence[int]
    class_id: int = -1
    #: The object's pixels as indices ``v * width + u`` (from a mask); None: the whole box.
    mask_pixels: Optional[List[int]] = None

    def to_dict(self) -> dict:
        d = asdict(self)
        d["bbox_px"] = [int(v) for v in self.bbox_px]
        if self.mask_pixels is None:
            del d["mask_pixels"]
        return d


@dataclass
class PixelDetections:
    """``perception/pixel_detections`` (``perception.pixel_detections`` v1): robotd places
    these objects on the table and tracks them like its own detections."""

    #: The frame's ``info.frame_id``.
    frame_id: int
    #: The frame's ``info.camera_pose``.
    camera_pose: Sequence[float]
    #: The detector's name (not "robotd"); the objects' source in robotd.
    source: str
    objects: List[PixelDetection] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {
            "frame_id": int(self.frame_id),
            "camera_pose": [float(v) for v in self.camera_pose],
            "source": self.source,
            "objects": [o.to_dict() for o in self.objects],
        }
