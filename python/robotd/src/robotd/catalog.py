"""robotd's bus catalogue, as ``robotd catalog --json`` prints it.

``catalog.json`` beside this file is that output, checked by a test of the Rust workspace
(``tests/python_actor.rs``) so the two cannot drift apart. It holds, for every topic, frame
topic and service, the message types with their schema versions and the exact iceoryx2
settings robotd opens them with; iceoryx2 refuses a port whose settings differ.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from importlib import resources
from typing import Dict, Optional

from .errors import RobotdError

#: The layout version of ``catalog.json`` this package reads.
DESCRIPTION_VERSION = 1


@dataclass(frozen=True)
class TopicSpec:
    """A message topic (also each half of a service)."""

    name: str
    msg_type: str
    schema_version: int
    overflow: str
    depth: int
    max_wait_ms: int
    max_bytes: int
    max_publishers: int
    max_subscribers: int
    max_borrowed_samples: int
    max_nodes: int

    @property
    def latest_wins(self) -> bool:
        return self.overflow == "latest_wins"


@dataclass(frozen=True)
class FramesSpec:
    """A frame topic."""

    name: str
    overflow: str
    depth: int
    max_borrowed_samples: int
    max_publishers: int
    max_subscribers: int
    max_nodes: int
    max_width: int
    max_height: int
    channels: int

    @property
    def latest_wins(self) -> bool:
        return self.overflow == "latest_wins"


@dataclass(frozen=True)
class ServiceSpec:
    """A request-response service."""

    name: str
    requests: TopicSpec
    replies: TopicSpec

    def replies_for(self, client_id: int) -> TopicSpec:
        """The replies topic of one client."""
        name = f"{self.name}/replies/{client_id:016x}"
        return TopicSpec(**{**self.replies.__dict__, "name": name})


class Catalog:
    """The catalogue: look entries up by name."""

    def __init__(self, description: dict):
        version = description.get("description_version")
        if version != DESCRIPTION_VERSION:
            raise RobotdError(
                f"catalog.json has layout version {version}; this package reads "
                f"{DESCRIPTION_VERSION}: install the package from the same robotd checkout"
            )
        self.message_header_type: str = description["message_header_type"]
        self.frame_slot_type: str = description["frame_slot_type"]
        self.events: dict = description["events"]
        self.event_names: dict = description["event_names"]
        self.topics: Dict[str, TopicSpec] = {}
        self.frames: Dict[str, FramesSpec] = {}
        self.services: Dict[str, ServiceSpec] = {}
        for entry in description["entries"]:
            kind = entry.pop("kind")
            if kind == "topic":
                self.topics[entry["name"]] = TopicSpec(**entry)
            elif kind == "frames":
                self.frames[entry["name"]] = FramesSpec(**entry)
            elif kind == "service":
                self.services[entry["name"]] = ServiceSpec(
                    name=entry["name"],
                    requests=TopicSpec(**entry["requests"]),
                    replies=TopicSpec(**entry["replies"]),
                )
            else:
                raise RobotdError(f"catalog.json has an entry of unknown kind {kind!r}")

    def topic(self, name: str) -> TopicSpec:
        try:
            return self.topics[name]
        except KeyError:
            raise RobotdError(
                f"'{name}' is not a message topic of robotd's catalogue; topics: "
                f"{', '.join(sorted(self.topics))}"
            ) from None

    def frame_topic(self, name: str) -> FramesSpec:
        try:
            return self.frames[name]
        except KeyError:
            raise RobotdError(
                f"'{name}' is not a frame topic of robotd's catalogue; frame topics: "
                f"{', '.join(sorted(self.frames))}"
            ) from None

    def service(self, name: str) -> ServiceSpec:
        try:
            return self.services[name]
        except KeyError:
            raise RobotdError(
                f"'{name}' is not a service of robotd's catalogue; services: "
                f"{', '.join(sorted(self.services))} (serve your own with Bus.custom_service)"
            ) from None

    def custom_service(
        self,
        name: str,
        request_type: str,
        reply_type: str,
        request_version: int = 1,
        reply_version: int = 1,
    ) -> ServiceSpec:
        """A service that is not in robotd's catalogue (one a Python actor offers), with the
        settings robotd gives every service."""
        template = self.services["system/ping"]
        return ServiceSpec(
            name=name,
            requests=TopicSpec(
                **{
                    **template.requests.__dict__,
                    "name": f"{name}/requests",
                    "msg_type": request_type,
                    "schema_version": request_version,
                }
            ),
            replies=TopicSpec(
                **{
                    **template.replies.__dict__,
                    "name": f"{name}/replies/{{client_id:016x}}",
                    "msg_type": reply_type,
                    "schema_version": reply_version,
                }
            ),
        )

    def event(self, kind: str, topic: str) -> str:
        """The name of the ``kind`` event (data, consumed, subscribed, joined) of ``topic``."""
        return self.event_names[kind].replace("{topic}", topic)


_loaded: Optional[Catalog] = None


def load() -> Catalog:
    """The catalogue shipped with this package."""
    global _loaded
    if _loaded is None:
        text = resources.files(__package__).joinpath("catalog.json").read_text("utf-8")
        _loaded = Catalog(json.loads(text))
    return _loaded
