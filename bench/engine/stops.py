"""How a sequence stops: the error that carries a stop from where the loop sees its cause to the
one place that ends the sequence (:meth:`bench.engine.engine.Engine._end`), the outcome recorded,
and the taper that stops the actuator on the way.

Apart from the engine, so that the run procedures and the run's recording raise and report stops
without importing the engine that runs them.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Self

from bench.engine import events as ev
from bench.engine.contracts import Excitable
from bench.engine.states import Trigger
from drivers.errors import LinkError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RunOutcome:
    """How a sequence ended: ``status`` complete, aborted, e-stopped, interlocked or failed, and why."""

    status: str
    reason: str = ""


class RunStoppedError(Exception):
    """The sequence cannot go on: ``trigger`` is the ending the transition table is to apply, ``reason``
    why, ``interlock`` the event published once the table has applied an interlock. Raised where the
    loop sees the cause; :meth:`bench.engine.engine.Engine._end` applies it."""

    def __init__(self, trigger: Trigger, reason: str, interlock: ev.InterlockTripped | None = None) -> None:
        super().__init__(reason)
        self.trigger = trigger
        self.reason = reason
        self.interlock = interlock

    @classmethod
    def abort(cls, reason: str) -> Self:
        """An abort: requested, or the engine's own (a declined prompt)."""
        return cls(Trigger.STOPPED, reason)

    @classmethod
    def estop(cls) -> Self:
        return cls(Trigger.ESTOP, "e-stop")

    @classmethod
    def interlock_tripped(cls, tripped: ev.InterlockTripped) -> Self:
        return cls(Trigger.INTERLOCK, f"{tripped.name}: {tripped.reason}", tripped)

    @classmethod
    def fail(cls, reason: str) -> Self:
        """A sequence the engine cannot run on this bench (an unsupported step, a missing channel)."""
        return cls(Trigger.FAIL, reason)


def stop_with_taper(actuator: Excitable) -> None:
    """Taper the actuator out; a link error here is logged (the watchdog stops the controller)."""
    try:
        actuator.stop()
    except LinkError as exc:
        log.warning("stop not confirmed (%s); the controller's watchdog tapers it out", exc)
