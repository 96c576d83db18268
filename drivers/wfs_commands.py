"""The WFS acquisition's text command set and its replies.

Host to device, one ASCII line each, terminated by ``\\n``::

    IDENT          -> $OK,IDENT,<vendor>,<model>,<serial>,<firmware>,<protocol version>*HH
    START          -> $OK,START*HH          stream frames; the sample index restarts at 0
    STOP           -> $OK,STOP*HH           stop streaming
    TARE           -> $OK,TARE*HH           zero the six load channels at the present load
    RATE <hz>      -> $OK,RATE,<hz>*HH      set the sample rate (while stopped)
    RATE?          -> $OK,RATE,<hz>*HH
    CAPTURE <level_n> <pre_trigger_s> <length_s>
                   -> $OK,CAPTURE,<samples>,<pre-trigger samples>,<rate hz>*HH   arm a triggered
                      capture of Fz at the converter rate (drivers/wfs_capture.py); the block follows
                      as a binary message when the trigger has fired

A refused command answers ``$ERR,<COMMAND>,<reason>*HH``; a line that is no command answers
``$ERR,?,<reason>*HH``. Replies are framed like NMEA sentences: ``$``, comma-separated printable
ASCII, ``*``, exactly two upper-case hex digits of the XOR of every byte between ``$`` and ``*``,
then ``\\r\\n``. They are interleaved with the binary frames between two frames; the checksum
lets the stream parser tell a reply from binary bytes that look like one.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import reduce

from drivers.errors import MalformedReplyError

COMMANDS = ("IDENT", "START", "STOP", "TARE", "RATE", "CAPTURE")
REPLY_START = b"$"
REPLY_END = b"\r\n"
MAX_REPLY_LEN = 160
_HEX_DIGITS = frozenset(b"0123456789ABCDEF")
UNKNOWN = "?"  # the command field of the reply to a line that is no command


def checksum(body: bytes) -> int:
    """XOR of the bytes of ``body``."""
    return reduce(lambda acc, b: acc ^ b, body, 0)


def format_command(name: str, argument: str | float | None = None) -> bytes:
    """The line the host sends, e.g. ``format_command("RATE", 1000)`` -> ``b"RATE 1000\\n"``."""
    if name.rstrip("?") not in COMMANDS:
        raise ValueError(f"unknown WFS command {name!r}; known: {', '.join(COMMANDS)}")
    if argument is None:
        return f"{name}\n".encode("ascii")
    text = f"{argument:g}" if isinstance(argument, int | float) else str(argument)
    return f"{name} {text}\n".encode("ascii")


def parse_command(line: bytes) -> tuple[str, list[str]]:
    """Device side: split a command line into ``(NAME, arguments)``; raise ValueError if unknown."""
    try:
        text = line.decode("ascii").strip()
    except UnicodeDecodeError as exc:
        raise ValueError("command is not ASCII") from exc
    parts = text.split()
    if not parts or parts[0].rstrip("?").upper() not in COMMANDS:
        raise ValueError(f"unknown command {text[:20]!r}")
    return parts[0].upper(), parts[1:]


@dataclass(frozen=True)
class Reply:
    """A parsed reply: ``ok``, the command it answers and its fields."""

    ok: bool
    command: str
    fields: tuple[str, ...] = ()

    def encode(self) -> bytes:
        body = ",".join(("OK" if self.ok else "ERR", self.command, *self.fields)).encode("ascii")
        if len(body) + 6 > MAX_REPLY_LEN or any(c in body for c in b"$*\r\n"):
            raise ValueError(f"reply {body[:40]!r} too long or contains reserved characters")
        return REPLY_START + body + b"*" + f"{checksum(body):02X}".encode("ascii") + REPLY_END


def parse_reply(line: bytes) -> Reply:
    """Parse one complete reply line (``$ ... *HH\\r\\n``); raise MalformedReplyError on anything else."""
    if not (line.startswith(REPLY_START) and line.endswith(REPLY_END)) or len(line) > MAX_REPLY_LEN:
        raise MalformedReplyError(f"not a reply line: {line[:40]!r}")
    body, star, tail = line[1 : -len(REPLY_END)].rpartition(b"*")
    if not star or len(tail) != 2 or not _HEX_DIGITS.issuperset(tail):
        raise MalformedReplyError(f"reply without two upper-case hex checksum digits: {line[:40]!r}")
    expected = int(tail, 16)
    try:
        text = body.decode("ascii")
    except UnicodeDecodeError as exc:
        raise MalformedReplyError(f"reply with a non-ASCII body: {line[:40]!r}") from exc
    if checksum(body) != expected or not text.isprintable():
        raise MalformedReplyError(f"reply checksum mismatch: {line[:40]!r}")
    fields = text.split(",")
    if len(fields) < 2 or fields[0] not in ("OK", "ERR") or fields[1] not in (*COMMANDS, UNKNOWN):
        raise MalformedReplyError(f"reply of unknown form: {text[:40]!r}")
    return Reply(fields[0] == "OK", fields[1], tuple(fields[2:]))
