"""The monitor's HTTP server: the page, ``/api/state`` and the stream of updates, read-only.

aiohttp on an event loop of its own, in a thread of its own: nothing it does runs on the engine's
thread, and the engine never waits for it. Every state published (:meth:`MonitorServer.publish`,
from any thread) is numbered (``seq``) and kept as the latest; each viewer of the stream has its own
bounded backlog of updates, and a viewer that reads too slowly (or not at all) loses its own older
updates, never anyone else's, and nothing of the bench's. Each update is the whole state, so the
newest one is all a viewer needs; a viewer that reconnects gets the latest at once (Server-Sent
Events: ``Last-Event-ID`` is the last ``seq`` it saw).

Read-only by construction: the routes are GET (and HEAD) only, any other method is refused with 405
before routing, an unknown path is 404, a request body is never read. With a token set every request
must carry it (``Authorization: Bearer``, the ``token`` query parameter, or the cookie the page sets
from it); the access log is off, so no request line (which may hold the token) is logged.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import threading
import time
from collections.abc import Awaitable, Callable
from importlib import resources
from typing import Any

from aiohttp import web

from bench.monitor.listen import Listen, MonitorUnavailableError

log = logging.getLogger(__name__)

#: The most viewers of the stream at once (others get 503 until one leaves).
MAX_VIEWERS = 64
#: Updates kept per viewer not yet sent (the oldest go first).
VIEWER_BACKLOG = 4
#: A comment line sent on a quiet stream, so that a viewer gone away is noticed (s).
KEEPALIVE_S = 15.0
#: How long a stream may take to send its last updates when the server closes (s).
CLOSE_GRACE_S = 2.0
#: The cookie the page keeps the token in (same site only, not readable by scripts).
TOKEN_COOKIE = "wfsbench_monitor_token"
#: The page's files, served as they ship with the package (no network needed).
PAGE_FILES = {
    "/": ("index.html", "text/html"),
    "/monitor.js": ("monitor.js", "text/javascript"),
    "/monitor.css": ("monitor.css", "text/css"),
}
#: Headers of every answer: no framing, no sniffing, no referrer (a URL may hold the token), no cache.
SAFE_HEADERS = {
    "Content-Security-Policy": "default-src 'self'; frame-ancestors 'none'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Cache-Control": "no-store",
}
READ_METHODS = ("GET", "HEAD")


class _RefusalsUnquoted(logging.Filter):
    """aiohttp's word on a request it refused (malformed, too long), without the request's text,
    which may hold the token: the kind of error only, at INFO."""

    def filter(self, record: logging.LogRecord) -> bool:
        kind = record.exc_info[0].__name__ if record.exc_info and record.exc_info[0] else "error"
        record.msg, record.args = "monitor: a request was refused (%s)", (kind,)
        record.exc_info, record.exc_text, record.stack_info = None, None, None
        record.levelno, record.levelname = logging.INFO, "INFO"
        return True


#: On aiohttp's server logger from the first monitor on (one filter, however many monitors).
REFUSALS_UNQUOTED = _RefusalsUnquoted()


def page_file(name: str) -> bytes:
    return resources.files("bench.monitor").joinpath("page", name).read_bytes()


class Updates:
    """The latest state and each viewer's backlog; used on the server's event loop only."""

    def __init__(self) -> None:
        self.latest: tuple[int, str] | None = None
        self.viewers: set[asyncio.Queue[tuple[int, str] | None]] = set()
        self.dropped = 0  # updates a slow viewer lost

    def publish(self, seq: int, text: str) -> None:
        self.latest = (seq, text)
        for backlog in self.viewers:
            if backlog.full():  # this viewer reads too slowly: it loses its oldest update
                backlog.get_nowait()
                self.dropped += 1
            backlog.put_nowait((seq, text))

    def join(self) -> asyncio.Queue[tuple[int, str] | None]:
        backlog: asyncio.Queue[tuple[int, str] | None] = asyncio.Queue(VIEWER_BACKLOG)
        self.viewers.add(backlog)
        return backlog

    def leave(self, backlog: asyncio.Queue[tuple[int, str] | None]) -> None:
        self.viewers.discard(backlog)

    def end(self) -> None:
        """Every stream ends after what it has still to send."""
        for backlog in self.viewers:
            if backlog.full():
                backlog.get_nowait()
            backlog.put_nowait(None)


def sse(seq: int, text: str) -> bytes:
    """One update as a Server-Sent Event (the JSON is one line)."""
    return f"id: {seq}\nevent: state\ndata: {text}\n\n".encode()


class MonitorServer:
    """The HTTP server of the monitor at ``listen``; :meth:`start` binds (or raises
    :class:`MonitorUnavailableError`), :meth:`publish` hands it a state, :meth:`close` ends it."""

    def __init__(self, listen: Listen) -> None:
        self.listen = listen
        self.port = listen.port
        self._seq = 0
        self._seq_lock = threading.Lock()
        #: this server's own id in every state: a viewer that sees another knows the numbers restarted
        self.instance = f"{os.getpid()}-{time.time_ns()}"
        self._updates = Updates()
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._error: OSError | None = None
        self._closing: asyncio.Event | None = None
        self._thread = threading.Thread(target=self._serve, name="monitor-http", daemon=True)

    # -- any thread ---------------------------------------------------------------------------

    @property
    def url(self) -> str:
        host = f"[{self.listen.host}]" if ":" in self.listen.host else self.listen.host
        return f"http://{host}:{self.port}/"

    def start(self, timeout_s: float = 10.0) -> None:
        self._thread.start()
        if not self._ready.wait(timeout_s):
            raise MonitorUnavailableError(f"the monitor did not start listening within {timeout_s:g} s")
        if self._error is not None:
            where, why = f"{self.listen.host}:{self.listen.port}", self._error.strerror or self._error
            raise MonitorUnavailableError(f"the monitor cannot listen at {where}: {why}")

    def publish(self, state: dict[str, Any]) -> int:
        """Number ``state`` and send it to every viewer; returns its number."""
        with self._seq_lock:
            self._seq += 1
            seq = self._seq
        text = json.dumps(
            {"seq": seq, "server": self.instance, **state}, allow_nan=False, separators=(",", ":")
        )
        with contextlib.suppress(RuntimeError):  # a closed loop: nobody is left to tell
            self._loop.call_soon_threadsafe(self._updates.publish, seq, text)
        return seq

    @property
    def updates_dropped(self) -> int:
        """Updates that slow viewers lost (each its own)."""
        return self._updates.dropped

    def close(self) -> None:
        """Stop listening; each stream first sends what it has (within :data:`CLOSE_GRACE_S`)."""
        if self._thread.is_alive() and self._closing is not None:
            self._loop.call_soon_threadsafe(self._closing.set)
        self._thread.join(CLOSE_GRACE_S + 10.0)

    # -- the server's thread --------------------------------------------------------------------

    def _serve(self) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self._main())
        finally:
            self._loop.close()

    async def _main(self) -> None:
        logging.getLogger("aiohttp.server").addFilter(REFUSALS_UNQUOTED)
        self._closing = asyncio.Event()
        app = web.Application(middlewares=[self._guard], client_max_size=1024)
        for path in PAGE_FILES:
            app.router.add_get(path, self._page)
        app.router.add_get("/api/state", self._state)
        app.router.add_get("/api/stream", self._stream)
        runner = web.AppRunner(app, access_log=None, handle_signals=False, shutdown_timeout=CLOSE_GRACE_S)
        await runner.setup()
        site = web.TCPSite(runner, self.listen.host, self.listen.port)
        try:
            await site.start()
        except OSError as exc:
            self._error = exc
            self._ready.set()
            await runner.cleanup()
            return
        self.port = runner.addresses[0][1]
        self._ready.set()
        await self._closing.wait()
        self._updates.end()
        await runner.cleanup()

    @web.middleware
    async def _guard(
        self, request: web.Request, handler: Callable[[web.Request], Awaitable[web.StreamResponse]]
    ) -> web.StreamResponse:
        """Refuse every method but GET and HEAD, and a request without the token when one is set."""
        if request.method not in READ_METHODS:
            return _refusal(405, "the monitor is read-only: only GET is served", Allow="GET, HEAD")
        if not self.listen.admits(_token_of(request)):
            return _refusal(401, "a token is needed: open the page as /?token=TOKEN (docs/monitor.md)")
        response = await handler(request)
        if not response.prepared:
            response.headers.update(SAFE_HEADERS)
        return response

    async def _page(self, request: web.Request) -> web.Response:
        name, kind = PAGE_FILES[request.path]
        response = web.Response(body=page_file(name), content_type=kind)
        given = request.query.get("token")
        if given is not None and self.listen.token is not None:  # admitted: the page's requests carry it
            response.set_cookie(TOKEN_COOKIE, given, httponly=True, samesite="Strict", path="/")
        return response

    async def _state(self, request: web.Request) -> web.Response:
        latest = self._updates.latest
        text = latest[1] if latest is not None else json.dumps({"seq": 0, "state": "starting"})
        return web.Response(text=text, content_type="application/json")

    async def _stream(self, request: web.Request) -> web.StreamResponse:
        updates = self._updates
        if len(updates.viewers) >= MAX_VIEWERS:
            return _refusal(503, f"{MAX_VIEWERS} viewers already: try again later", **{"Retry-After": "5"})
        response = web.StreamResponse(headers={**SAFE_HEADERS, "Content-Type": "text/event-stream"})
        await response.prepare(request)
        backlog = updates.join()
        try:
            latest_seq = updates.latest[0] if updates.latest is not None else 0
            seen = _last_seen(request)
            seen = 0 if seen > latest_seq else seen  # seen from another server (a restarted bench)
            await response.write(b"retry: 1000\n\n")
            if updates.latest is not None and updates.latest[0] > seen:  # catch up at once
                seen = updates.latest[0]
                await response.write(sse(*updates.latest))
            while True:
                try:
                    item = await asyncio.wait_for(backlog.get(), KEEPALIVE_S)
                except TimeoutError:
                    await response.write(b": keepalive\n\n")
                    continue
                if item is None:
                    break
                if item[0] > seen:
                    seen = item[0]
                    await response.write(sse(*item))
        except (ConnectionError, asyncio.CancelledError):
            pass
        finally:
            updates.leave(backlog)
        return response


def _refusal(status: int, text: str, **headers: str) -> web.Response:
    return web.Response(status=status, text=text + "\n", headers={**SAFE_HEADERS, **headers})


def _token_of(request: web.Request) -> str | None:
    """The token a request carries: the Authorization header's bearer token, the ``token`` query
    parameter or the page's cookie."""
    auth = request.headers.get("Authorization", "")
    if auth.startswith("Bearer "):
        return auth.removeprefix("Bearer ").strip()
    return request.query.get("token") or request.cookies.get(TOKEN_COOKIE)


def _last_seen(request: web.Request) -> int:
    """The last update a reconnecting viewer saw (``Last-Event-ID``, or ``since``); 0: none."""
    text = request.headers.get("Last-Event-ID") or request.query.get("since") or "0"
    return int(text) if text.isdigit() else 0
