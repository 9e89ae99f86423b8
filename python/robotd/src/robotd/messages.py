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


# -- speech to text (``stt/transcribe``, ``stt/transcripts``; protocol/src/stt.rs) -----------

#: Largest audio one ``stt.transcribe`` request may carry, bytes (``MAX_AUDIO_BYTES``).
MAX_AUDIO_BYTES = 1_000_000
#: The only sample rate raw PCM is accepted at, Hz (``PCM_SAMPLE_RATE_HZ``).
PCM_SAMPLE_RATE_HZ = 16_000


@dataclass
class TranscribeRequest:
    """``stt/transcribe`` request (``stt.transcribe`` v1): raw 16 kHz mono 16-bit PCM
    (``format="pcm_s16le"``) or a WAV/WebM/Ogg file's bytes (``format="file"``)."""

    audio: bytes
    format: str = "file"
    sample_rate_hz: int = 0
    source: str = "python"

    def to_dict(self) -> dict:
        return {
            "audio": bytes(self.audio),
            "format": self.format,
            "sample_rate_hz": int(self.sample_rate_hz),
            "source": self.source,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "TranscribeRequest":
        return cls(
            audio=d["audio"],
            format=d["format"],
            sample_rate_hz=int(d["sample_rate_hz"]),
            source=d["source"],
        )


@dataclass
class Segment:
    """One stretch of speech of a :class:`Transcript` (seconds from the audio's start)."""

    start_s: float
    end_s: float
    text: str
    confidence: float

    def to_dict(self) -> dict:
        return {
            "start_s": float(self.start_s),
            "end_s": float(self.end_s),
            "text": self.text,
            "confidence": float(self.confidence),
        }


@dataclass
class Transcript:
    """``stt/transcripts`` (``stt.transcript`` v1), and the body of a transcribe reply."""

    text: str
    language: str
    segments: List[Segment]
    confidence: float
    audio_s: float
    processing_s: float
    model: str
    source: str

    def to_dict(self) -> dict:
        return {
            "text": self.text,
            "language": self.language,
            "segments": [s.to_dict() for s in self.segments],
            "confidence": float(self.confidence),
            "audio_s": float(self.audio_s),
            "processing_s": float(self.processing_s),
            "model": self.model,
            "source": self.source,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "Transcript":
        return cls(
            text=d["text"],
            language=d["language"],
            segments=[Segment(**s) for s in d["segments"]],
            confidence=float(d["confidence"]),
            audio_s=float(d["audio_s"]),
            processing_s=float(d["processing_s"]),
            model=d["model"],
            source=d["source"],
        )


#: The kinds of :class:`SttError` (``SttErrorKind``).
STT_ERROR_KINDS = ("empty", "too_large", "too_long", "not_audio", "wrong_sample_rate", "failed")


@dataclass
class SttError(Exception):
    """Why audio was not transcribed (``SttError``): ``kind`` of :data:`STT_ERROR_KINDS`."""

    kind: str
    message: str

    def __str__(self) -> str:
        return self.message

    def reply(self) -> dict:
        """The ``stt.reply`` body saying so."""
        return {"kind": "error", "error": {"kind": self.kind, "message": self.message}}


def transcript_reply(transcript: Transcript) -> dict:
    """The ``stt.reply`` body carrying ``transcript``."""
    return {"kind": "transcript", "transcript": transcript.to_dict()}


@dataclass
class SttStatus:
    """``stt/status`` (``stt.status`` v1): how the STT actor is doing (``SttStatus``).

    Published when the model is loaded and after every request; the counts are this
    process's (they start at 0 again after a restart, with a new ``pid``).
    """

    pid: int
    model: str
    model_path: str
    model_loaded: bool
    load_s: float
    beam_size: int
    utterances: int = 0
    errors: int = 0
    audio_s: float = 0.0
    processing_s: float = 0.0
    last_real_time_factor: float = 0.0
    last_error: Optional[str] = None

    def to_dict(self) -> dict:
        return {
            "pid": int(self.pid),
            "model": self.model,
            "model_path": self.model_path,
            "model_loaded": bool(self.model_loaded),
            "load_s": float(self.load_s),
            "beam_size": int(self.beam_size),
            "utterances": int(self.utterances),
            "errors": int(self.errors),
            "audio_s": float(self.audio_s),
            "processing_s": float(self.processing_s),
            "last_real_time_factor": float(self.last_real_time_factor),
            "last_error": self.last_error,
        }

    def counted(self, transcript: "Transcript") -> None:
        """Counts one transcribed request."""
        self.utterances += 1
        self.audio_s = round(self.audio_s + transcript.audio_s, 3)
        self.processing_s = round(self.processing_s + transcript.processing_s, 3)
        if transcript.audio_s > 0:
            self.last_real_time_factor = round(transcript.processing_s / transcript.audio_s, 4)

    def failed(self, error: "SttError") -> None:
        """Counts one refused or failed request."""
        self.errors += 1
        self.last_error = f"{error.kind}: {error.message}"[:500]
