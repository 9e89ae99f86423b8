"""The envelope every control message travels in: MessagePack, fields by name.

Like robotd's Rust side, a reader refuses an envelope whose message type or schema version it
does not expect, with an error naming both sides, instead of misreading it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Optional

import msgpack

from .errors import DecodeError, SchemaMismatch


@dataclass
class Trace:
    """W3C trace context carried across the bus."""

    traceparent: Optional[str] = None
    tracestate: Optional[str] = None


@dataclass
class Envelope:
    """A message with its type, schema version, trace context and send time."""

    msg_type: str
    schema_version: int
    body: Any
    sent_at_unix_ns: int = 0
    trace: Trace = field(default_factory=Trace)


def encode(msg_type: str, schema_version: int, body: Any, trace: Optional[Trace] = None) -> bytes:
    """The envelope's MessagePack bytes (``body`` is a dict, list or scalar)."""
    trace = trace or Trace()
    return msgpack.packb(
        {
            "msg_type": msg_type,
            "schema_version": schema_version,
            "trace": {"traceparent": trace.traceparent, "tracestate": trace.tracestate},
            "sent_at_unix_ns": time.time_ns(),
            "body": body,
        },
        use_bin_type=True,
    )


def decode(data: bytes, msg_type: str, schema_version: int) -> Envelope:
    """Decodes an envelope of ``msg_type`` at ``schema_version``.

    Raises :class:`DecodeError` for bytes that are not an envelope and
    :class:`SchemaMismatch` for another type or version.
    """
    try:
        raw = msgpack.unpackb(data, raw=False, strict_map_key=False)
    except Exception as e:  # msgpack raises several unrelated types
        raise DecodeError(
            f"a {len(data)}-byte message on a '{msg_type}' topic is not MessagePack "
            f"({type(e).__name__}: {str(e) or 'invalid bytes'})"
        ) from None
    if not isinstance(raw, dict) or not {"msg_type", "schema_version", "body"} <= raw.keys():
        raise DecodeError(
            f"a message on a '{msg_type}' topic is not a robotd envelope "
            f"(a map with msg_type, schema_version, trace, sent_at_unix_ns and body)"
        )
    if raw["msg_type"] != msg_type:
        raise SchemaMismatch(f"expected a '{msg_type}' message but got '{raw['msg_type']}'")
    if raw["schema_version"] != schema_version:
        raise SchemaMismatch(
            f"'{msg_type}' schema version {raw['schema_version']} is not supported (this "
            f"package reads version {schema_version}); upgrade the older side"
        )
    trace = raw.get("trace") or {}
    return Envelope(
        msg_type=raw["msg_type"],
        schema_version=raw["schema_version"],
        body=raw["body"],
        sent_at_unix_ns=int(raw.get("sent_at_unix_ns") or 0),
        trace=Trace(trace.get("traceparent"), trace.get("tracestate")),
    )
