"""Joining robotd's bus: a node in robotd's namespace, and ports opened as robotd opens them.

A :class:`Bus` is one iceoryx2 node. Its ports open the services of a *running* robotd (with
``open``, never ``create``), so a wrong namespace or a robotd that is not running is a clear
:class:`~robotd.errors.NotRunning` instead of a port nobody else will ever see. Each port is
paired with the event services robotd pairs it with: publishers wake subscribers after every
message, back-pressure subscribers tell publishers they made room, and new ports announce
themselves so robotd's ports connect to them at once.
"""

from __future__ import annotations

import ctypes
import os
import time
from typing import List, Optional

import iceoryx2 as iox2

from . import catalog as _catalog
from .catalog import Catalog, FramesSpec, ServiceSpec, TopicSpec
from .errors import IncompatibleBus, NotRunning, RobotdError
from .shm import FrameSlot, MessageHeader

#: robotd's default bus namespace.
DEFAULT_NAMESPACE = "robotd"


def default_namespace() -> str:
    """``$ROBOTD_BUS__NAMESPACE`` (set by robotd for the actors it starts), else ``robotd``."""
    return os.environ.get("ROBOTD_BUS__NAMESPACE") or DEFAULT_NAMESPACE


def _check_namespace(namespace: str) -> None:
    ok = (
        0 < len(namespace) <= 64
        and all(c.isascii() and (c.isalnum() or c in "_-") for c in namespace)
    )
    if not ok:
        raise RobotdError(
            f"bus namespace {namespace!r}: use 1-64 characters from A-Z, a-z, 0-9, '_' and '-'"
        )


class Bus:
    """Membership of robotd's bus in ``namespace`` (default: :func:`default_namespace`).

    ``node_name`` is shown by ``robotd doctor`` and iceoryx2's tools. Close it with
    :meth:`close` or use it as a context manager; the ports it made keep working until then.
    """

    def __init__(self, namespace: Optional[str] = None, node_name: str = "python-actor"):
        iox2.set_log_level_from_env_or(iox2.LogLevel.Error)
        self.namespace = namespace or default_namespace()
        _check_namespace(self.namespace)
        self.catalog: Catalog = _catalog.load()
        try:
            self.node = (
                iox2.NodeBuilder.new()
                .name(iox2.NodeName.new(node_name))
                .signal_handling_mode(iox2.SignalHandlingMode.Disabled)
                .create(iox2.ServiceType.Ipc)
            )
        except Exception as e:
            raise RobotdError(
                f"cannot create an iceoryx2 node ({e!r}); check that /dev/shm is mounted and "
                "writable (robotd doctor)"
            ) from None

    def __enter__(self) -> "Bus":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Leaves the bus: the node's resources are removed once its ports are closed too."""
        self.__dict__.pop("node", None)

    # -- ports --------------------------------------------------------------------------

    def subscriber(self, topic: str):
        """A subscriber of message topic ``topic`` (e.g. ``"arm/state"``)."""
        from .ports import Subscriber

        return Subscriber(self, self.catalog.topic(topic))

    def publisher(self, topic: str):
        """A publisher on message topic ``topic`` (e.g. ``"perception/pixel_detections"``)."""
        from .ports import Publisher

        return Publisher(self, self.catalog.topic(topic))

    def frame_subscriber(self, topic: str = "camera/frames"):
        """A subscriber of camera frames, received as numpy arrays in shared memory."""
        from .frames import FrameSubscriber

        return FrameSubscriber(self, self.catalog.frame_topic(topic))

    def frame_publisher(self, topic: str):
        """A publisher of frames (a camera in Python) on a frame topic of the catalogue."""
        from .frames import FramePublisher

        return FramePublisher(self, self.catalog.frame_topic(topic))

    def client(self, service: str):
        """A client of robotd service ``service`` (e.g. ``"workspace/query"``)."""
        from .services import Client

        return Client(self, self.catalog.service(service))

    def server(self, service):
        """The server of ``service``: a catalogue name, or a :class:`ServiceSpec` from
        :meth:`custom_service` for a service of your own."""
        from .services import Server

        spec = service if isinstance(service, ServiceSpec) else self.catalog.service(service)
        return Server(self, spec)

    def custom_service(self, name: str, request_type: str, reply_type: str) -> ServiceSpec:
        """A service of your own (not in robotd's catalogue), with robotd's service settings;
        pass it to :meth:`server` and, in the calling process, :meth:`custom_client`."""
        return self.catalog.custom_service(name, request_type, reply_type)

    def custom_client(self, spec: ServiceSpec):
        """A client of a service made with :meth:`custom_service`."""
        from .services import Client

        return Client(self, spec)

    # -- iceoryx2 services, opened the way robotd opens them ----------------------------

    def service_name(self, suffix: str):
        return iox2.ServiceName.new(f"{self.namespace}/{suffix}")

    def open_topic(self, spec: TopicSpec, create: bool = False):
        builder = (
            self.node.service_builder(self.service_name(spec.name))
            .publish_subscribe(iox2.Slice[ctypes.c_uint8])
            .user_header(MessageHeader)
            .enable_safe_overflow(spec.latest_wins)
            .subscriber_max_buffer_size(spec.depth)
            .subscriber_max_borrowed_samples(spec.max_borrowed_samples)
            .history_size(0)
            .max_publishers(spec.max_publishers)
            .max_subscribers(spec.max_subscribers)
            .max_nodes(spec.max_nodes)
        )
        return self._open(builder, spec.name, "topic", create)

    def open_frames(self, spec: FramesSpec, create: bool = False):
        builder = (
            self.node.service_builder(self.service_name(spec.name))
            .publish_subscribe(FrameSlot)
            .enable_safe_overflow(spec.latest_wins)
            .subscriber_max_buffer_size(spec.depth)
            .subscriber_max_borrowed_samples(spec.max_borrowed_samples)
            .history_size(0)
            .max_publishers(spec.max_publishers)
            .max_subscribers(spec.max_subscribers)
            .max_nodes(spec.max_nodes)
        )
        return self._open(builder, spec.name, "frame topic", create)

    def open_event(self, name: str):
        events = self.catalog.events
        builder = (
            self.node.service_builder(self.service_name(name))
            .event()
            .max_notifiers(events["max_notifiers"])
            .max_listeners(events["max_listeners"])
            .max_nodes(events["max_nodes"])
            .event_id_max_value(events["event_id_max_value"])
        )
        # robotd switches the notifier lifecycle events off; a new service must match.
        for switch in (
            "disable_notifier_created_event",
            "disable_notifier_dropped_event",
            "disable_notifier_dead_event",
        ):
            if hasattr(builder, switch):
                builder = getattr(builder, switch)()
        try:
            return builder.open_or_create()
        except Exception as e:
            raise IncompatibleBus(
                f"cannot open event service '{self.namespace}/{name}': {e!r}"
            ) from None

    def _open(self, builder, name: str, what: str, create: bool):
        try:
            return builder.open_or_create() if create else builder.open()
        except Exception as e:
            reason = repr(e)
            if "DoesNotExist" in reason:
                raise NotRunning(self._not_running(name, what)) from None
            raise IncompatibleBus(
                f"iceoryx2 refused {what} '{self.namespace}/{name}': {reason}; robotd opened it "
                "with other settings (install this package from the checkout robotd was built "
                "from, and iceoryx2 0.10.0)"
            ) from None

    def _not_running(self, name: str, what: str) -> str:
        found = sorted(namespaces_on_this_machine())
        where = (
            f"robotd bus namespaces on this machine: {', '.join(found)}"
            if found
            else "no robotd is running on this machine"
        )
        return (
            f"no {what} '{name}' in bus namespace '{self.namespace}': robotd is not running with "
            f"that namespace ({where}; start it with `robotd serve --namespace "
            f"{self.namespace}`, or pass the namespace it runs with)"
        )


def namespaces_on_this_machine() -> List[str]:
    """The namespaces in which a robotd's ``system/ping`` service exists right now."""
    found = set()
    try:
        services = iox2.Service.list(iox2.config.global_config(), iox2.ServiceType.Ipc)
    except Exception:
        return []
    for details in services:
        try:
            name = str(details.name().to_string())
        except Exception:
            try:
                name = str(details.name())
            except Exception:
                continue
        if name.endswith("/system/ping/requests"):
            found.add(name[: -len("/system/ping/requests")])
    return sorted(found)


def wait_s(timeout: Optional[float]) -> Optional[float]:
    """``timeout`` checked: None (forever) or a finite number of seconds ≥ 0."""
    if timeout is None:
        return None
    timeout = float(timeout)
    if not timeout >= 0.0 or timeout == float("inf"):
        raise RobotdError(f"a timeout must be a finite number of seconds >= 0, got {timeout}")
    return timeout


def deadline_of(timeout: Optional[float]) -> Optional[float]:
    t = wait_s(timeout)
    return None if t is None else time.monotonic() + t
