"""Waiting for a condition in tests: poll with a deadline, fail with what was awaited."""

from __future__ import annotations

import asyncio
import queue
import threading
import time
from collections.abc import Callable


def wait_until(predicate: Callable[[], bool], timeout_s: float, what: str) -> None:
    """Poll ``predicate`` until true; fail the test with ``what`` after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(0.005)


async def async_wait_until(predicate, timeout_s: float, what: str):
    """Async variant: ``predicate`` is an async callable returning a truthy value, which is returned."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = await predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        await asyncio.sleep(0.01)


class LineReader:
    """The lines of a child process's text stream, read on a thread of their own, so that a test
    waits for the next line with a deadline instead of hanging when the child falls silent."""

    def __init__(self, stream) -> None:
        self._lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=self._read, args=(stream,), daemon=True).start()

    def _read(self, stream) -> None:
        for line in stream:
            self._lines.put(line)
        self._lines.put("")  # end of the stream

    def next(self, timeout_s: float, what: str) -> str:
        """The next line ("" at the stream's end); fail the test with ``what`` after ``timeout_s``."""
        try:
            return self._lines.get(timeout=timeout_s)
        except queue.Empty:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}") from None

    def until(self, found: Callable[[str], bool], timeout_s: float, what: str) -> list[str]:
        """The lines up to and including the first that ``found`` accepts (each within ``timeout_s``
        of the one before); fails the test with ``what`` if the stream ends first."""
        seen = [self.next(timeout_s, what)]
        while not found(seen[-1]):
            if seen[-1] == "":
                raise AssertionError(f"the stream ended before {what}: {''.join(seen)!r}")
            seen.append(self.next(timeout_s, what))
        return seen

    def rest(self, timeout_s: float) -> str:
        """Every line to the stream's end, each within ``timeout_s`` of the one before."""
        return "".join(self.until(lambda line: line == "", timeout_s, "the end of the stream"))
