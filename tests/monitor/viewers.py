"""Viewers of a monitor, as a process of their own (they sit at other computers in a lab): reading
viewers of the stream, viewers that never read, a bounded flood of requests, malformed requests and
refused methods, all to 127.0.0.1. Started before the monitor listens, it says ``ready`` once it
has loaded and waits for the port to accept a connection (a run that ends quickly is then watched
from its start, whatever the machine's load), then ``watching`` once every viewer is connected. It
ends when every reading viewer has seen the sequence end, and prints what it saw as one JSON line.

    python -m tests.monitor.viewers PORT [--readers N] [--silent N] [--flood N] [--bad]

Used by tests/monitor/test_monitor_load.py and benchmarks/monitor_viewers.py.
"""

from __future__ import annotations

import argparse
import json
import socket
import threading
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor

from tests.monitor.http import SilentViewer, StreamViewer, exchange, request

#: The longest a run may take to end, as the viewers wait for it (s); and for its monitor to listen.
RUN_DEADLINE_S = 300.0
LISTEN_DEADLINE_S = 120.0
#: The flood's requests in flight at once, and the longest it may go on (s).
FLOOD_CONCURRENCY, FLOOD_LIMIT_S = 8, 30.0
FLOOD_PATHS = ("/api/state", "/", "/monitor.js", "/no/such/path")
#: Requests a server must refuse whole: garbage, an over-long header, an unknown version, a body.
MALFORMED = (
    b"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03garbage\r\n\r\n",
    b"GET /api/state HTTP/1.1\r\nHost: x\r\nX-Long: " + b"a" * 20000 + b"\r\n\r\n",
    b"GET /api/state HTTP/9.9\r\n\r\n",
    b"GET / HTTP/1.1\r\nHost: x\r\nContent-Length: -5\r\n\r\n",
    b"\r\n\r\n\r\n",
)


def ended(update: dict) -> bool:
    sequence = update.get("sequence")
    return sequence is not None and sequence.get("status") not in (None, "running")


def read_to_the_end(viewer: StreamViewer, results: list) -> None:
    try:
        last = viewer.read_until(ended, RUN_DEADLINE_S, "the sequence's end")
        status = last["sequence"]["status"]
        results.append({"updates": len(viewer.updates), "status": status, "seq": last["seq"]})
    except AssertionError as exc:
        results.append({"error": str(exc)})
    finally:
        viewer.close()


def flood(port: int, count: int) -> Counter:
    """``count`` GET requests, :data:`FLOOD_CONCURRENCY` at a time, within :data:`FLOOD_LIMIT_S`: the
    count of each answer's status (-1: not sent, the time being up; 0: no answer, the connection
    refused, reset or timed out)."""
    deadline = time.monotonic() + FLOOD_LIMIT_S

    def one(i: int) -> int:
        if time.monotonic() > deadline:
            return -1
        try:
            return request(port, "GET", FLOOD_PATHS[i % len(FLOOD_PATHS)])[0]
        except OSError:  # not answered in time, or the connection refused or reset: the flood's own loss
            return 0

    with ThreadPoolExecutor(FLOOD_CONCURRENCY) as pool:
        return Counter(pool.map(one, range(count)))


def answer_to(port: int, bad: bytes) -> str:
    """The status line the server answers ``bad`` with; "" when it waits for more (blank lines)
    and the viewer gives up."""
    try:
        return exchange(port, bad, timeout_s=2.0).split(b"\r\n", 1)[0].decode()
    except TimeoutError:
        return ""


def wait_until_listening(port: int) -> None:
    """Until 127.0.0.1:``port`` accepts a connection (the monitor started), or
    :data:`LISTEN_DEADLINE_S`."""
    deadline = time.monotonic() + LISTEN_DEADLINE_S
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=5.0).close()
            return
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.01)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("port", type=int)
    parser.add_argument("--readers", type=int, default=19)
    parser.add_argument("--silent", type=int, default=1)
    parser.add_argument("--flood", type=int, default=0)
    parser.add_argument("--bad", action="store_true", help="malformed requests and refused methods")
    args = parser.parse_args()
    print("ready", flush=True)
    wait_until_listening(args.port)
    silent = [SilentViewer(args.port) for _ in range(args.silent)]
    results: list = []
    readers = [
        threading.Thread(target=read_to_the_end, args=(StreamViewer(args.port), results), daemon=True)
        for _ in range(args.readers)
    ]
    for thread in readers:
        thread.start()
    print("watching", flush=True)
    said: dict = {"readers": results}
    if args.flood:
        said["flood"] = {str(k): v for k, v in flood(args.port, args.flood).items()}
    if args.bad:
        said["malformed"] = [answer_to(args.port, bad) for bad in MALFORMED]
        said["refused"] = {m: request(args.port, m, "/api/state")[0] for m in ("POST", "PUT", "DELETE")}
    for thread in readers:
        thread.join(RUN_DEADLINE_S)
    for viewer in silent:
        viewer.close()
    print(json.dumps(said), flush=True)


if __name__ == "__main__":
    main()
