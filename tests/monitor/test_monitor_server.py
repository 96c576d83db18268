"""The monitor's HTTP server on 127.0.0.1, fed with states as the bench's feed publishes them:
read-only (every method but GET refused, unknown paths 404), the token where one is set, malformed
requests refused without harm, a reconnecting viewer caught up, and a viewer that never reads
losing its own updates while the others get every one and publishing never waits."""

from __future__ import annotations

import time

import pytest

from bench.monitor.listen import Listen
from bench.monitor.server import TOKEN_COOKIE, MonitorServer
from tests.monitor.http import SilentViewer, StreamViewer, exchange, get_json, request
from tests.waiting import wait_until

TOKEN = "s3cret-token-of-the-lab-0123"


@pytest.fixture
def server():
    server = MonitorServer(Listen("127.0.0.1", 0))
    server.start()
    yield server
    server.close()


def test_page_and_state_served(server) -> None:
    assert get_json(server.port) == {"seq": 0, "state": "starting"}
    server.publish({"state": "running", "points_done": 3})
    wait_until(lambda: get_json(server.port).get("seq") == 1, 5, "the state published")
    state = get_json(server.port)
    assert state == {"seq": 1, "server": server.instance, "state": "running", "points_done": 3}
    status, page = request(server.port, "GET", "/")
    assert status == 200 and b'<script src="/monitor.js"' in page and b"http" not in page.split(b"<body>")[0]
    for path in ("/monitor.js", "/monitor.css"):
        assert request(server.port, "GET", path)[0] == 200
    assert request(server.port, "HEAD", "/api/state")[0] == 200


@pytest.mark.parametrize("method", ["POST", "PUT", "DELETE", "PATCH", "OPTIONS"])
@pytest.mark.parametrize("path", ["/", "/api/state", "/api/stream", "/no/such/path"])
def test_every_method_but_get_refused(server, method: str, path: str) -> None:
    status, body = request(server.port, method, path)
    assert status == 405 and b"read-only" in body


@pytest.mark.parametrize("path", ["/api", "/api/state/x", "/index.html", "/../etc/passwd", "/api/stop"])
def test_unknown_paths_refused(server, path: str) -> None:
    assert request(server.port, "GET", path)[0] == 404


def test_malformed_requests_refused_and_the_server_goes_on(server) -> None:
    server.publish({"state": "running"})
    answers = [
        exchange(server.port, b"\x16\x03\x01\x02\x00garbage\r\n\r\n"),  # a TLS hello to a plain port
        exchange(server.port, b"GET /api/state HTTP/1.1\r\nHost: x\r\nX-Long: " + b"a" * 20000 + b"\r\n\r\n"),
        exchange(server.port, b"GET /api/state HTTP/9.9\r\n\r\n"),
        exchange(server.port, b"GET /api/state HTTP/1.1\r\nHost: x\r\nContent-Length: -5\r\n\r\n"),
    ]
    for answer in answers:
        status = answer.split(b" ", 2)[1]
        assert status in (b"400", b"431", b"505"), answer[:80]
    assert get_json(server.port)["state"] == "running"


def test_token_needed_off_loopback(caplog) -> None:
    server = MonitorServer(Listen("0.0.0.0", 0, TOKEN))  # all addresses; reached here on 127.0.0.1 only
    server.start()
    try:
        server.publish({"state": "idle"})
        wrong = ({}, {"Authorization": "Bearer wrong-token-of-the-lab-01"}, {"Cookie": f"{TOKEN_COOKIE}=x"})
        for headers in wrong:
            status, body = request(server.port, "GET", "/api/state", headers)
            assert status == 401 and TOKEN.encode() not in body
        assert request(server.port, "GET", "/?token=not-it")[0] == 401
        assert get_json(server.port, headers={"Authorization": f"Bearer {TOKEN}"})["state"] == "idle"
        assert get_json(server.port, f"/api/state?token={TOKEN}")["state"] == "idle"
        page = f"GET /?token={TOKEN} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n"
        answer = exchange(server.port, page.encode())
        assert answer.startswith(b"HTTP/1.1 200") and f"{TOKEN_COOKIE}={TOKEN}".encode() in answer
        assert b"HttpOnly" in answer and b"SameSite=Strict" in answer
        assert get_json(server.port, headers={"Cookie": f"{TOKEN_COOKIE}={TOKEN}"})["state"] == "idle"
        assert request(server.port, "POST", f"/api/state?token={TOKEN}")[0] == 405  # read-only all the same
        bad = f"GET /api/state?token={TOKEN} HTTP/1.1\r\nHost: x\r\nX: {'a' * 20000}\r\n\r\n"
        assert exchange(server.port, bad.encode()).split(b" ", 2)[1] == b"400"
        wait_until(lambda: "a request was refused" in caplog.text, 5, "the refusal logged")
        assert TOKEN not in caplog.text  # neither the refused request nor any other logs it
    finally:
        server.close()


def test_a_reconnecting_viewer_catches_up(server) -> None:
    for n in range(5):
        server.publish({"state": "running", "points_done": n})
    wait_until(lambda: get_json(server.port)["seq"] == 5, 5, "five states published")
    first = StreamViewer(server.port)
    assert first.read_until(lambda u: u["seq"] == 5, 5, "the latest state at once")["points_done"] == 4
    first.close()
    for n in range(5, 8):  # while it is away
        server.publish({"state": "running", "points_done": n})
    again = StreamViewer(server.port, {"Last-Event-ID": "5"})
    caught_up = again.read_until(lambda u: u["seq"] == 8, 5, "the newest state on reconnecting")
    assert caught_up["points_done"] == 7
    assert min(again.updates) == 8  # the whole state: the newest is all it needs
    server.publish({"state": "finished", "points_done": 8})
    assert again.read_until(lambda u: u["seq"] == 9, 5, "the next state")["state"] == "finished"
    again.close()
    elsewhere = StreamViewer(server.port, {"Last-Event-ID": "999"})  # seen from a server before this one
    assert elsewhere.read_until(lambda u: True, 5, "the latest state at once")["seq"] == 9
    elsewhere.close()


def test_a_viewer_that_never_reads_loses_only_its_own_updates(server) -> None:
    silent = SilentViewer(server.port)
    reader = StreamViewer(server.port)
    wait_until(lambda: len(server._updates.viewers) == 2, 5, "both viewers connected")
    padding = "x" * 20000  # the silent viewer's socket is full after a few
    worst_s = 0.0
    for n in range(1, 301):
        start = time.perf_counter()
        server.publish({"state": "running", "points_done": n, "padding": padding})
        worst_s = max(worst_s, time.perf_counter() - start)
        if n % 20 == 0:  # read along, as a live page does: the newest arrives
            reader.read_until(lambda u, n=n: u["seq"] >= n, 10, f"state {n} at the reading viewer")
    assert reader.updates[300]["points_done"] == 300
    # the silent viewer's socket took the first few; every later update it lost (its own loss)
    wait_until(lambda: server.updates_dropped > 100, 10, "the silent viewer losing updates")
    assert worst_s < 0.05, f"a publish waited {worst_s * 1e3:.1f} ms"
    silent.close()
    reader.close()
