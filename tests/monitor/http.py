"""Plain HTTP as a viewer sends it, over a socket of its own (no client library in between), for
the monitor's tests: a request, its status line, a stream read as Server-Sent Events, and a viewer
that connects and never reads."""

from __future__ import annotations

import json
import socket
import time
from typing import Any

TIMEOUT_S = 10.0


def exchange(port: int, request: bytes, host: str = "127.0.0.1", timeout_s: float = TIMEOUT_S) -> bytes:
    """Send ``request`` as it is and read the whole answer (the server closes after it);
    TimeoutError when none comes within ``timeout_s``."""
    with socket.create_connection((host, port), timeout=timeout_s) as sock:
        sock.sendall(request)
        chunks = []
        while chunk := sock.recv(65536):
            chunks.append(chunk)
    return b"".join(chunks)


def request(port: int, method: str, path: str, headers: dict[str, str] | None = None) -> tuple[int, bytes]:
    """``method path`` with ``Connection: close``: the status and the body."""
    lines = [f"{method} {path} HTTP/1.1", "Host: 127.0.0.1", "Connection: close", "Content-Length: 0"]
    lines += [f"{name}: {value}" for name, value in (headers or {}).items()]
    answer = exchange(port, ("\r\n".join(lines) + "\r\n\r\n").encode())
    head, _, body = answer.partition(b"\r\n\r\n")
    return int(head.split(b" ", 2)[1]), body


def get_json(port: int, path: str = "/api/state", headers: dict[str, str] | None = None) -> dict[str, Any]:
    status, body = request(port, "GET", path, headers)
    assert status == 200, (status, body)
    return json.loads(body)


class StreamViewer:
    """A viewer of ``/api/stream``: the updates it has read, by their number."""

    def __init__(self, port: int, headers: dict[str, str] | None = None) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=TIMEOUT_S)
        lines = ["GET /api/stream HTTP/1.1", "Host: 127.0.0.1"]
        lines += [f"{name}: {value}" for name, value in (headers or {}).items()]
        self.sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
        self._buffer = b""
        self.updates: dict[int, dict[str, Any]] = {}

    def read_until(self, found, timeout_s: float, what: str) -> dict[str, Any]:
        """Read updates until one satisfies ``found``; fail the test with ``what`` after the deadline."""
        deadline = time.monotonic() + timeout_s
        while True:
            for update in self._take():
                if found(update):
                    return update
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
            self.sock.settimeout(left)
            try:
                chunk = self.sock.recv(65536)
            except TimeoutError:
                continue
            if not chunk:
                raise AssertionError(f"the stream ended before {what}")
            self._buffer += chunk

    def _take(self) -> list[dict[str, Any]]:
        taken = []
        while b"\n\n" in self._buffer:
            block, self._buffer = self._buffer.split(b"\n\n", 1)
            for line in block.split(b"\n"):
                if line.startswith(b"data: "):
                    update = json.loads(line[6:])
                    self.updates[update["seq"]] = update
                    taken.append(update)
        return taken

    def close(self) -> None:
        self.sock.close()


class SilentViewer:
    """A viewer that asks for the stream and never reads a byte of it (its receive buffer kept
    small, so that it is full soon)."""

    def __init__(self, port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        self.sock.connect(("127.0.0.1", port))
        self.sock.sendall(b"GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")

    def close(self) -> None:
        self.sock.close()
