"""Services: request-response with exactly one server, as robotd's Rust bus does it.

A request travels on ``<service>/requests`` (one subscriber: the server) inside a frame that
names the client, the request and its deadline; the reply comes back on the client's own
``<service>/replies/<client id>`` topic as ``{"ok": reply}`` or ``{"fault": {kind, message}}``.
A request is never retried, so a command never runs twice; a request whose deadline passed
before the server got to it is answered with an ``expired`` fault and not executed.
"""

from __future__ import annotations

import os
import random
import time
from dataclasses import dataclass
from typing import Any, Dict, Optional

from . import envelope
from .bus import deadline_of, wait_s
from .catalog import ServiceSpec, TopicSpec
from .envelope import Envelope, Trace
from .errors import DecodeError, Fault, NoServer, RobotdError, SchemaMismatch, Timeout
from .ports import Publisher, Subscriber


def _new_client_id() -> int:
    return (os.getpid() << 40) ^ (time.time_ns() & 0xFF_FFFF_FFFF) ^ random.getrandbits(40)


class Client:
    """Calls one service; see :meth:`request`."""

    def __init__(self, bus, spec: ServiceSpec):
        self.spec = spec
        self.client_id = _new_client_id() & 0xFFFF_FFFF_FFFF_FFFF
        replies = spec.replies_for(self.client_id)
        # The reply subscriber first, so the server's reply publisher finds it.
        self._replies = Subscriber(bus, replies, create=True)
        self._requests = Publisher(bus, spec.requests, create=True)
        self._next = 1

    def has_server(self) -> bool:
        n = self._requests._service.dynamic_config.number_of_subscribers
        return (n() if callable(n) else n) > 0

    def request(self, body: Any, timeout: float = 5.0, trace: Optional[Trace] = None) -> Any:
        """Sends ``body`` and returns the reply's body.

        Raises :class:`NoServer`, :class:`Timeout`, or :class:`Fault` (with robotd's fault
        ``kind``) when the server could not reply.
        """
        return self.request_envelope(body, timeout, trace).body

    def request_envelope(
        self, body: Any, timeout: float = 5.0, trace: Optional[Trace] = None
    ) -> Envelope:
        timeout = wait_s(timeout)
        if not self.has_server():
            raise NoServer(f"nobody serves '{self.spec.name}' right now (is robotd running?)")
        if hasattr(body, "to_dict"):
            body = body.to_dict()
        request_id = self._next
        self._next += 1
        frame = {
            "client_id": self.client_id,
            "request_id": request_id,
            "deadline_unix_ns": time.time_ns() + int(timeout * 1e9),
            "body": body,
        }
        self._requests.publish(frame, trace)
        deadline = deadline_of(timeout)
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise Timeout(
                    f"no reply from '{self.spec.name}' within {timeout:.3f} s (the request will "
                    "not be executed later)"
                )
            message = self._replies.receive(left)
            if message is None:
                continue
            reply = message.body
            if not isinstance(reply, dict) or reply.get("request_id") != request_id:
                continue  # a late reply to an earlier request that timed out
            outcome = reply.get("reply")
            if isinstance(outcome, dict) and "ok" in outcome:
                return Envelope(
                    message.msg_type,
                    message.schema_version,
                    outcome["ok"],
                    message.sent_at_unix_ns,
                    message.trace,
                )
            if isinstance(outcome, dict) and "fault" in outcome:
                fault = outcome["fault"] or {}
                raise Fault(str(fault.get("kind")), str(fault.get("message")))
            raise DecodeError(f"a reply of '{self.spec.name}' is neither ok nor fault")

    def close(self) -> None:
        self._requests.close()
        self._replies.close()


@dataclass
class Request:
    """A request a :class:`Server` received: answer it with :meth:`reply` or :meth:`fail`."""

    body: Any
    envelope: Envelope
    client_id: int
    request_id: int
    deadline_unix_ns: int
    _server: "Server"

    def reply(self, body: Any) -> None:
        if hasattr(body, "to_dict"):
            body = body.to_dict()
        self._server._send(self.client_id, self.request_id, {"ok": body})

    def fail(self, kind: str, message: str) -> None:
        if kind not in Fault.KINDS:
            raise RobotdError(f"fault kind {kind!r} is not one of {', '.join(Fault.KINDS)}")
        self._server._send(
            self.client_id, self.request_id, {"fault": {"kind": kind, "message": message}}
        )


class Server:
    """Serves one service; see :meth:`next`. One server per service: a second is refused."""

    def __init__(self, bus, spec: ServiceSpec):
        self.spec = spec
        self._bus = bus
        try:
            self._requests = Subscriber(bus, spec.requests, create=True)
        except Exception as e:
            raise RobotdError(
                f"cannot serve '{spec.name}': {e} (is another robotd or actor already serving it?)"
            ) from None
        self._reply_publishers: Dict[int, Publisher] = {}

    def next(self, timeout: Optional[float] = None) -> Optional[Request]:
        """The next request to answer, or None after ``timeout`` seconds.

        Requests that cannot be read are answered with a ``bad_request`` fault, and expired
        ones with ``expired``, here; they are never returned.
        """
        deadline = deadline_of(timeout)
        while True:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            data = self._requests.receive_bytes(left)
            if data is None:
                return None
            request = self._read(data)
            if request is not None:
                return request
            if deadline is not None and time.monotonic() >= deadline:
                return None

    def _read(self, data: bytes) -> Optional[Request]:
        spec = self.spec.requests
        try:
            message = envelope.decode(data, spec.msg_type, spec.schema_version)
            frame = message.body
            client_id, request_id = int(frame["client_id"]), int(frame["request_id"])
        except (DecodeError, SchemaMismatch, KeyError, TypeError, ValueError) as e:
            routing = _routing(data)
            if routing is not None:
                self._send(*routing, {"fault": {"kind": "bad_request", "message": str(e)}})
            return None
        deadline = int(frame.get("deadline_unix_ns") or 0)
        if deadline and time.time_ns() > deadline:
            self._send(
                client_id,
                request_id,
                {"fault": {"kind": "expired", "message": "the caller had given up; not executed"}},
            )
            return None
        return Request(frame.get("body"), message, client_id, request_id, deadline, self)

    def _send(self, client_id: int, request_id: int, reply: dict) -> None:
        publisher = self._reply_publishers.get(client_id)
        if publisher is None:
            spec: TopicSpec = self.spec.replies_for(client_id)
            publisher = Publisher(self._bus, spec, create=True)
            if len(self._reply_publishers) >= 32:
                oldest = next(iter(self._reply_publishers))
                self._reply_publishers.pop(oldest).close()
            self._reply_publishers[client_id] = publisher
        publisher.publish({"request_id": request_id, "reply": reply})

    def close(self) -> None:
        for publisher in self._reply_publishers.values():
            publisher.close()
        self._reply_publishers.clear()
        self._requests.close()


def _routing(data: bytes):
    """(client_id, request_id) of a request whose body cannot be read, if its frame can."""
    import msgpack

    try:
        raw = msgpack.unpackb(data, raw=False, strict_map_key=False)
        return int(raw["body"]["client_id"]), int(raw["body"]["request_id"])
    except Exception:
        return None
