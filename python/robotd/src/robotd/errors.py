"""The errors of robotd's Python bus client: each names its cause and what to do about it."""


class RobotdError(Exception):
    """Base of every error this package raises."""


class NotRunning(RobotdError):
    """No robotd (or no port of the needed kind) is on the bus in this namespace.

    Raised for a wrong namespace too: the message lists the namespaces in which robotd services
    exist on this machine.
    """


class IncompatibleBus(RobotdError):
    """iceoryx2 refused to open a service: its settings differ from robotd's (another iceoryx2
    or robotd version, or a catalogue out of date)."""


class SchemaMismatch(RobotdError):
    """A message has another type or schema version than this package reads."""


class DecodeError(RobotdError):
    """A message's bytes are not a robotd envelope of the expected shape."""


class BusFull(RobotdError):
    """A back-pressure subscriber did not take the message (it is not catching up)."""


class TooLarge(RobotdError):
    """A message is larger than its topic admits."""


class Timeout(RobotdError):
    """No reply (or message) came within the deadline."""


class NoServer(RobotdError):
    """Nobody serves the service right now."""


class Fault(RobotdError):
    """The server answered with a fault instead of a reply.

    ``kind`` is one of robotd's fault kinds: ``actor_failed``, ``unavailable``, ``bad_request``,
    ``dropped``, ``expired``, ``reply_failed``, ``refused``.
    """

    KINDS = (
        "actor_failed",
        "unavailable",
        "bad_request",
        "dropped",
        "expired",
        "reply_failed",
        "refused",
    )

    def __init__(self, kind: str, message: str):
        super().__init__(f"{kind}: {message}")
        self.kind = kind
        self.message = message
