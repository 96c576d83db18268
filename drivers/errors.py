"""The typed errors of the hardware links, and the soft limits' refusal.

Every failure a caller may want to react to differently has its own class: a setpoint outside the
soft limits (:class:`LimitError`: nothing was sent; a refusal, not a fault of a link), and under
:class:`LinkError` a timeout, a device exception reply, a lost connection, a protocol mismatch, a
malformed register map or command reply.
"""

from __future__ import annotations


class LinkError(Exception):
    """Base of every error of a link to a device (every driver error but :class:`LimitError`)."""


class RegisterMapError(LinkError):
    """A register-map file is malformed; the message names the file and the key."""


class LimitError(ValueError):
    """A setpoint lies outside the bench's soft limits; nothing was written.

    A refusal of the software's own, not a fault of a link: it is no :class:`LinkError`, so that a
    caller reports it as the refusal it is."""


class LinkTimeoutError(LinkError, TimeoutError):
    """The device did not answer in time."""


class CommandOutcomeUnknownError(LinkTimeoutError):
    """A command write timed out: it may or may not have been applied, so it is not re-sent.

    Read the status to learn what the device did.
    """


class DeviceExceptionError(LinkError):
    """The device answered with a Modbus exception response."""

    def __init__(self, operation: str, exception_code: int) -> None:
        super().__init__(f"{operation}: device answered with Modbus exception code {exception_code}")
        self.operation = operation
        self.exception_code = exception_code


class ConnectionLostError(LinkError, ConnectionError):
    """The link to the device is down (not connected, closed, or dropped mid-request)."""


class ProtocolMismatchError(LinkError):
    """The device speaks another protocol version than the register map expects."""


class CommandRejectedError(LinkError):
    """The device refused a command (an ``ERR`` reply, or a state that does not allow it);
    ``awaits_reset``: the device is interlocked or e-stopped and takes no command but a reset."""

    def __init__(self, message: str, *, awaits_reset: bool = False) -> None:
        super().__init__(message)
        self.awaits_reset = awaits_reset


class NotConfiguredError(CommandRejectedError):
    """START refused by the client: the last configure did not complete, so the controller may hold
    a half-written setpoint; nothing was sent. Configure again."""


class DriveMismatchError(LinkError):
    """After a drive's upload the controller reports another length or checksum than the drive
    sent: it does not hold that drive (another master wrote to it meanwhile); nothing plays it."""


class MalformedReplyError(LinkError):
    """A reply could not be parsed, or holds a value the protocol does not define."""


class MismatchedReplyError(MalformedReplyError):
    """A reply that does not belong to its request: another function code, address, quantity or
    byte count (a late reply to an earlier request). Reads are retried; a write's outcome is unknown."""
