"""Join a running robotd's bus from Python.

A lab's Python code becomes a robotd actor: it subscribes to robotd's topics and publishes on
them, calls and serves services, and reads camera frames as numpy arrays that view robotd's
shared memory — over iceoryx2, the same bus robotd's own actors use, with the same message
envelopes, schema version checks and fault kinds.

    from robotd import Bus

    with Bus() as bus:                               # namespace: $ROBOTD_BUS__NAMESPACE or "robotd"
        arm = bus.subscriber("arm/state")
        print(arm.receive(timeout=2.0).body["tool_pose"])
        frames = bus.frame_subscriber()              # camera/frames
        with frames.receive(timeout=2.0) as frame:
            print(frame.info.frame_id, frame.pixels.shape, frame.pixels.mean())

The topics, frame topics and services (names, message types, iceoryx2 settings) come from
``catalog.json``, the output of ``robotd catalog --json``.
"""

from .bus import Bus, default_namespace, namespaces_on_this_machine
from .envelope import Envelope, Trace
from .errors import (
    BusFull,
    DecodeError,
    Fault,
    IncompatibleBus,
    NoServer,
    NotRunning,
    RobotdError,
    SchemaMismatch,
    Timeout,
    TooLarge,
)

__all__ = [
    "Bus",
    "BusFull",
    "DecodeError",
    "Envelope",
    "Fault",
    "IncompatibleBus",
    "NoServer",
    "NotRunning",
    "RobotdError",
    "SchemaMismatch",
    "Timeout",
    "TooLarge",
    "Trace",
    "default_namespace",
    "namespaces_on_this_machine",
]
