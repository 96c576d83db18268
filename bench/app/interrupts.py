"""Ctrl-C, a termination or a hang-up during a run: the first signal asks the engine to abort (a
tapered stop, the file kept and closed, the run marked aborted with the signal as its reason), the
second asks for an e-stop.

SIGINT (Ctrl-C), SIGTERM (``kill``, a service manager stopping the command) and SIGHUP (the terminal
or its tmux session closed) are handled alike, so that no signal leaves the actuator running until
the controller's watchdog trips. The handler never raises into the engine's loop while it runs: it
only makes the engine's requests, which the loop honours at once (an excitation under way is tapered
out). Two exceptions: before the engine exists nothing moves yet, so the signal ends the command as
Python's KeyboardInterrupt would; and while a terminal read of a prompt's answer blocks
(:meth:`RunInterrupts.interruptible`), the signal is taken as no answer, which aborts the sequence
the same way. Both requests are made from a thread of their own, since the handler runs on the
engine's thread, which may be inside a state change. After a hang-up the terminal is gone: standard output
and error, where they were that terminal, are sent to ``/dev/null`` so that the run's last lines
cannot fail it.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Callable
from types import FrameType

from bench.engine.engine import Engine
from sequences import AnswerError

#: What each handled signal records as the aborted run's reason, and tells on standard error.
SIGNAL_WORDS: dict[signal.Signals, tuple[str, str]] = {
    signal.SIGINT: ("aborted by the operator", "interrupted"),
    signal.SIGTERM: ("aborted: terminated by SIGTERM", "terminated (SIGTERM)"),
    signal.SIGHUP: ("aborted: the terminal hung up (SIGHUP)", "hung up (SIGHUP)"),
}


class RunInterrupts:
    """Context manager installing the run's handler of SIGINT, SIGTERM and SIGHUP; ``attach(engine)``
    once the engine is built. What the signal does is told on standard error with a raw write: the
    handler may run while the engine's thread is inside a buffered write to standard output, which
    must not be re-entered."""

    def __init__(self) -> None:
        self.engine: Engine | None = None
        self.count = 0
        self._reading = False
        self._abort_thread: threading.Thread | None = None
        self._estop_thread: threading.Thread | None = None
        self._previous: dict[signal.Signals, object] = {}

    def attach(self, engine: Engine) -> None:
        self.engine = engine

    def interruptible(self, read: Callable[[str], str]) -> Callable[[str], str]:
        """``read`` (a terminal's ``input``) that a handled signal ends with :class:`AnswerError`."""

        def reading(question: str) -> str:
            self._reading = True
            try:
                return read(question)
            finally:
                self._reading = False

        return reading

    def __enter__(self) -> RunInterrupts:
        for signum in SIGNAL_WORDS:
            self._previous[signum] = signal.signal(signum, self._on_signal)
        return self

    def __exit__(self, *exc: object) -> None:
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)
        for thread in (self._abort_thread, self._estop_thread):
            if thread is not None:
                thread.join(10.0)

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self.count += 1
        reason, word = SIGNAL_WORDS[signal.Signals(signum)]
        if signum == signal.SIGHUP:
            _detach_from_terminal()
        if self.engine is None:
            raise KeyboardInterrupt
        again = "Ctrl-C" if signum == signal.SIGINT else "a second signal"
        if self.count == 1:
            tell(f"{word}: stopping with a taper, the run marked aborted ({again} again: e-stop)")
            self._abort_thread = threading.Thread(
                target=self.engine.request_abort, args=(reason,), name="signal-abort"
            )
            self._abort_thread.start()
            if self._reading:
                raise AnswerError(f"{word} while waiting for the answer")
        elif self._estop_thread is None:
            tell(f"{word} again: e-stop")
            self._estop_thread = threading.Thread(target=self.engine.request_estop, name="signal-estop")
            self._estop_thread.start()


def _detach_from_terminal() -> None:
    """Standard output and error that were the hung-up terminal go to /dev/null from now on."""
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in (1, 2):
            if os.isatty(fd):
                os.dup2(null, fd)
    finally:
        os.close(null)


def tell(text: str) -> None:
    """``text`` on its own line of standard error, unbuffered (safe inside a signal handler); on a
    terminal the progress line it would land on is cleared first (the progress redraws below)."""
    fd = sys.stderr.fileno()
    clear = "\r\x1b[K" if os.isatty(fd) else ""
    with contextlib.suppress(OSError):  # no reader left (a closed pipe): the run goes on untold
        os.write(fd, f"{clear}{text}\n".encode())
