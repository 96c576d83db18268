"""Where the web monitor listens and who may read it.

``HOST:PORT`` is parsed with every refusal naming the option and the value. A loopback address
(127.0.0.0/8, ::1, ``localhost``) is the default and needs no token; any other address does (given
with ``--monitor-token`` or read from a file), since anyone who reaches it could watch the bench.
The token is compared in constant time and never printed or logged (:class:`Listen` leaves it out
of its ``repr``).
"""

from __future__ import annotations

import hmac
import ipaddress
from dataclasses import dataclass, field
from pathlib import Path

#: The address listened on when only a port is given.
DEFAULT_HOST = "127.0.0.1"
#: The fewest characters a token may have (a short one is guessed by trying).
TOKEN_MIN_CHARS = 16


class MonitorSettingsError(ValueError):
    """The monitor's address or token cannot be used (the message names the option and why)."""


class MonitorUnavailableError(OSError):
    """The monitor could not listen at its address (in use, not this machine's, not allowed)."""


@dataclass(frozen=True)
class Listen:
    """The address to listen on and, for a non-loopback one, the token a viewer must give."""

    host: str
    port: int
    token: str | None = field(default=None, repr=False)

    @property
    def loopback(self) -> bool:
        return is_loopback(self.host)

    def admits(self, given: str | None) -> bool:
        """Whether ``given`` is the token (in constant time); anything goes when none is set."""
        if self.token is None:
            return True
        return given is not None and hmac.compare_digest(given.encode(), self.token.encode())


def is_loopback(host: str) -> bool:
    """``localhost`` or an address of the loopback range; any other name or address is not."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def parse_address(text: str, option: str) -> tuple[str, int]:
    """``HOST:PORT``, ``[IPv6]:PORT`` or ``PORT`` alone (on 127.0.0.1); port 0 takes a free one."""
    host, sep, port_text = text.rpartition(":")
    if not sep:
        host, port_text = DEFAULT_HOST, text
    host = host.removeprefix("[").removesuffix("]") if host.startswith("[") else host
    if not host:
        raise MonitorSettingsError(f"{option} {text!r}: no host before ':' (e.g. {DEFAULT_HOST}:8080)")
    if ":" in host and not text.startswith("["):
        raise MonitorSettingsError(f"{option} {text!r}: write an IPv6 address in brackets ([::1]:8080)")
    try:
        port = int(port_text)
    except ValueError:
        raise MonitorSettingsError(f"{option} {text!r}: the port {port_text!r} is not a number") from None
    if not 0 <= port <= 65535:
        raise MonitorSettingsError(f"{option} {text!r}: the port {port} is outside 0..65535")
    return host, port


def read_token(token: str | None, token_file: Path | None) -> str | None:
    """The token given on the command line or as a file's first line (not both); refused when
    empty or shorter than :data:`TOKEN_MIN_CHARS`. The messages never quote the token."""
    if token is not None and token_file is not None:
        raise MonitorSettingsError("--monitor-token and --monitor-token-file: give one of them, not both")
    where = "--monitor-token"
    if token_file is not None:
        where = f"--monitor-token-file {token_file}"
        try:
            lines = Path(token_file).read_text(encoding="utf-8").splitlines()
        except (OSError, UnicodeDecodeError) as exc:
            raise MonitorSettingsError(f"{where}: cannot be read ({exc.__class__.__name__}: {exc})") from None
        token = lines[0] if lines else ""
    if token is None:
        return None
    token = token.strip()
    if len(token) < TOKEN_MIN_CHARS:
        raise MonitorSettingsError(
            f"{where}: the token has {len(token)} characters; at least {TOKEN_MIN_CHARS} are needed"
        )
    return token


def listen_settings(
    address: str, option: str, *, token: str | None = None, token_file: Path | None = None
) -> Listen:
    """Where to listen and the token; a non-loopback address without a token is refused."""
    host, port = parse_address(address, option)
    secret = read_token(token, token_file)
    if secret is None and not is_loopback(host):
        raise MonitorSettingsError(
            f"{option} {address}: {host} is not a loopback address, so anyone who reaches it could"
            " watch the bench: give --monitor-token or --monitor-token-file, or listen on 127.0.0.1"
        )
    return Listen(host, port, secret)
