"""Ctrl-C during a run: the first SIGINT asks the engine to abort (a tapered stop, the file kept and
the run marked aborted), the second asks for an e-stop.

The handler never raises into the engine's loop while it runs: it only sets the engine's requests,
which the loop honours at once (an excitation under way is tapered out). Two exceptions: before the
engine exists nothing moves yet, so the interrupt ends the command as Python's KeyboardInterrupt
would; and while a terminal read of a prompt's answer blocks (:meth:`RunInterrupts.interruptible`),
the interrupt is taken as no answer, which aborts the sequence the same way. The e-stop is sent
from a thread of its own, since the handler runs on the engine's thread, which may be inside a state
change.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Callable
from types import FrameType

from bench.engine.engine import Engine
from sequences import AnswerError


class RunInterrupts:
    """Context manager installing the SIGINT handler of a run; ``attach(engine)`` once the engine is
    built. What the interrupt does is told on standard error with a raw write: the handler may run
    while the engine's thread is inside a buffered write to standard output, which must not be
    re-entered."""

    def __init__(self) -> None:
        self.engine: Engine | None = None
        self.count = 0
        self._reading = False
        self._estop_thread: threading.Thread | None = None
        self._previous: object = None

    def attach(self, engine: Engine) -> None:
        self.engine = engine

    def interruptible(self, read: Callable[[str], str]) -> Callable[[str], str]:
        """``read`` (a terminal's ``input``) that an interrupt ends with :class:`AnswerError`."""

        def reading(question: str) -> str:
            self._reading = True
            try:
                return read(question)
            finally:
                self._reading = False

        return reading

    def __enter__(self) -> RunInterrupts:
        self._previous = signal.signal(signal.SIGINT, self._on_sigint)
        return self

    def __exit__(self, *exc: object) -> None:
        signal.signal(signal.SIGINT, self._previous)
        if self._estop_thread is not None:
            self._estop_thread.join(10.0)

    def _on_sigint(self, signum: int, frame: FrameType | None) -> None:
        self.count += 1
        if self.engine is None:
            raise KeyboardInterrupt
        if self.count == 1:
            tell("interrupted: stopping with a taper, the run marked aborted (Ctrl-C again: e-stop)")
            self.engine.request_abort()
            if self._reading:
                raise AnswerError("interrupted (Ctrl-C) while waiting for the answer")
        elif self._estop_thread is None:
            tell("interrupted again: e-stop")
            self._estop_thread = threading.Thread(target=self.engine.request_estop, name="sigint-estop")
            self._estop_thread.start()


def tell(text: str) -> None:
    """``text`` on its own line of standard error, unbuffered (safe inside a signal handler); on a
    terminal the progress line it would land on is cleared first (the progress redraws below)."""
    fd = sys.stderr.fileno()
    clear = "\r\x1b[K" if os.isatty(fd) else ""
    os.write(fd, f"{clear}{text}\n".encode())
