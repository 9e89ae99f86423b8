"""Message topics: typed publish-subscribe in MessagePack envelopes.

A :class:`Subscriber` receives every message published after it was created; it waits on the
topic's data event (no polling) and, on back-pressure topics, tells publishers when it made
room. A :class:`Publisher` writes each message once into shared memory and wakes the
subscribers.
"""

from __future__ import annotations

import ctypes
import time
from typing import Any, Optional

import iceoryx2 as iox2

from . import envelope
from .catalog import TopicSpec
from .envelope import Envelope, Trace
from .errors import BusFull, TooLarge
from .bus import deadline_of


def _duration(seconds: float):
    return iox2.Duration.from_micros(max(0, int(seconds * 1e6)))


def wait_for_data(listener, deadline: Optional[float]) -> bool:
    """Sleeps on ``listener`` (a data event) until notified or ``deadline`` (monotonic time;
    None: a second at a time, forever). False once the deadline has passed."""
    if deadline is None:
        listener.timed_wait(_duration(1.0))
        return True
    left = deadline - time.monotonic()
    if left <= 0:
        return False
    listener.timed_wait(_duration(left))
    return True


class PortOwner:
    """Holds iceoryx2 ports under the attribute names in ``_ports``; :meth:`close` (or leaving a
    ``with`` block) deletes each once."""

    _ports: tuple = ()

    def close(self) -> None:
        for name in self._ports:
            port = self.__dict__.pop(name, None)
            if port is not None:
                port.delete()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class Subscriber(PortOwner):
    """Receives the messages of one topic; see :meth:`receive`."""

    _ports = ("_port", "_data", "_consumed")

    def __init__(self, bus, spec: TopicSpec, create: bool = False):
        self.spec = spec
        self._bus = bus
        self._service = bus.open_topic(spec, create)
        self._port = self._service.subscriber_builder().buffer_size(spec.depth).create()
        self._data = bus.open_event(bus.catalog.event("data", spec.name)).listener_builder().create()
        self._consumed = None
        if not spec.latest_wins:
            self._consumed = (
                bus.open_event(bus.catalog.event("consumed", spec.name)).notifier_builder().create()
            )
        # Tell waiting clients that a server attached, and publishers to connect to us.
        subscribed = bus.open_event(bus.catalog.event("subscribed", spec.name))
        notifier = subscribed.notifier_builder().create()
        notifier.notify()
        notifier.delete()

    def receive_bytes(self, timeout: Optional[float] = None) -> Optional[bytes]:
        """The next message's raw bytes, or None when ``timeout`` seconds passed first."""
        deadline = deadline_of(timeout)
        while True:
            sample = self._port.receive()
            if sample is not None:
                try:
                    data = bytes(sample.payload().as_memory_view())
                finally:
                    sample.delete()
                if self._consumed is not None:
                    self._consumed.notify()
                return data
            if not wait_for_data(self._data, deadline):
                return None

    def receive(self, timeout: Optional[float] = None) -> Optional[Envelope]:
        """The next message as an :class:`~robotd.envelope.Envelope` (its ``body`` a dict), or
        None after ``timeout`` seconds (None: wait as long as it takes).

        Raises :class:`~robotd.errors.SchemaMismatch` or :class:`~robotd.errors.DecodeError`
        for a message this package cannot read (the next call reads the next message).
        """
        data = self.receive_bytes(timeout)
        if data is None:
            return None
        return envelope.decode(data, self.spec.msg_type, self.spec.schema_version)


class Publisher(PortOwner):
    """Publishes messages on one topic; see :meth:`publish`."""

    _ports = ("_port", "_data")

    def __init__(self, bus, spec: TopicSpec, create: bool = False):
        self.spec = spec
        self._service = bus.open_topic(spec, create)
        # One static segment sized for the topic's largest message, as robotd's own
        # publishers do: untouched pages of the sparse segment cost no memory, while a growing
        # segment reserves bookkeeping for 255 segments in every process that reads it.
        self._port = (
            self._service.publisher_builder()
            .initial_max_slice_len(spec.max_bytes)
            .allocation_strategy(iox2.AllocationStrategy.Static)
            .create()
        )
        self._data = bus.open_event(bus.catalog.event("data", spec.name)).notifier_builder().create()
        self._seq = 0
        joined = bus.open_event(bus.catalog.event("joined", spec.name)).notifier_builder().create()
        joined.notify()
        joined.delete()

    def publish_bytes(self, data: bytes) -> int:
        """Sends encoded bytes; returns how many subscribers received them."""
        if len(data) > self.spec.max_bytes:
            raise TooLarge(
                f"a {len(data)}-byte message is larger than topic '{self.spec.name}' admits "
                f"({self.spec.max_bytes} bytes)"
            )
        self._port.update_connections()
        sample = self._port.loan_slice_uninit(len(data))
        ctypes.memmove(sample.payload_ptr, data, len(data))
        self._seq += 1
        sample.user_header().contents.seq = self._seq
        delivered = sample.assume_init().send()
        self._data.notify()
        if not self.spec.latest_wins:
            subscribers = self._service.dynamic_config.number_of_subscribers
            if callable(subscribers):
                subscribers = subscribers()
            if delivered < subscribers:
                raise BusFull(
                    f"{subscribers - delivered} of {subscribers} subscribers of "
                    f"'{self.spec.name}' did not take the message (they are not catching up)"
                )
        return delivered

    def publish(self, body: Any, trace: Optional[Trace] = None) -> int:
        """Sends ``body`` (a dict with the Rust struct's field names, or a dataclass of
        :mod:`robotd.messages`) in an envelope of the topic's type and schema version; returns
        how many subscribers received it."""
        if hasattr(body, "to_dict"):
            body = body.to_dict()
        return self.publish_bytes(
            envelope.encode(self.spec.msg_type, self.spec.schema_version, body, trace)
        )
