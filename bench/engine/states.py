"""The engine's states and its explicit transition table.

Every change of state goes through :meth:`StateMachine.fire` with a trigger; a trigger the present
state does not allow raises :class:`TransitionRefusedError` and changes nothing. Front ends request
transitions (hydraulics, start, pause, resume, abort, e-stop, reset); the engine fires the
consequences it observes (a point checkpoint reached, the actuator at rest, an interlock, the end of
the sequence).
"""

from __future__ import annotations

import enum
import threading
from collections.abc import Callable


class RunState(enum.Enum):
    IDLE = "idle"  # hydraulics off, nothing running
    HYDRAULICS_LOW = "hydraulics low"
    HYDRAULICS_HIGH = "hydraulics high"
    RUNNING = "running"
    PAUSED = "paused"  # at a checkpoint between points, actuator at rest, hydraulics on
    STOPPING = "stopping"  # an abort tapers the excitation out
    ABORTED = "aborted"
    ESTOPPED = "e-stopped"
    INTERLOCKED = "interlocked"
    FINISHED = "finished"


class Trigger(enum.Enum):
    HYDRAULICS_OFF = "hydraulics off"
    HYDRAULICS_LOW = "hydraulics low"
    HYDRAULICS_HIGH = "hydraulics high"
    START = "start"
    PAUSE = "pause"  # the checkpoint after a pause request
    RESUME = "resume"
    ABORT = "abort"
    STOPPED = "stopped"  # the aborted excitation is at rest
    ESTOP = "e-stop"
    INTERLOCK = "interlock"
    RESET = "reset"  # interlock or e-stop released (the controller returns to hydraulics low)
    FINISH = "finish"  # the sequence ran to its end


S, T = RunState, Trigger
_READY = (S.IDLE, S.HYDRAULICS_LOW, S.HYDRAULICS_HIGH, S.ABORTED, S.FINISHED)
_AT_REST = (S.IDLE, S.HYDRAULICS_LOW, S.HYDRAULICS_HIGH, S.ABORTED, S.FINISHED)

#: (state, trigger) -> next state; any pair not listed is refused.
TRANSITIONS: dict[tuple[RunState, Trigger], RunState] = {
    **{(s, T.HYDRAULICS_OFF): S.IDLE for s in _AT_REST},
    **{(s, T.HYDRAULICS_LOW): S.HYDRAULICS_LOW for s in _AT_REST},
    **{(s, T.HYDRAULICS_HIGH): S.HYDRAULICS_HIGH for s in _AT_REST if s is not S.IDLE},
    **{(s, T.START): S.RUNNING for s in _READY},
    (S.RUNNING, T.PAUSE): S.PAUSED,
    (S.PAUSED, T.RESUME): S.RUNNING,
    (S.RUNNING, T.ABORT): S.STOPPING,
    (S.PAUSED, T.ABORT): S.STOPPING,
    (S.STOPPING, T.STOPPED): S.ABORTED,
    **{(s, T.ESTOP): S.ESTOPPED for s in S},
    (S.RUNNING, T.INTERLOCK): S.INTERLOCKED,
    (S.PAUSED, T.INTERLOCK): S.INTERLOCKED,
    (S.STOPPING, T.INTERLOCK): S.INTERLOCKED,
    (S.INTERLOCKED, T.RESET): S.HYDRAULICS_LOW,
    (S.ESTOPPED, T.RESET): S.HYDRAULICS_LOW,
    (S.RUNNING, T.FINISH): S.FINISHED,
}

#: states in which the engine's loop is executing a sequence
ACTIVE = frozenset({S.RUNNING, S.PAUSED, S.STOPPING})
#: states a run can end in, with the run status recorded for each
RUN_STATUS = {
    S.FINISHED: "complete",
    S.ABORTED: "aborted",
    S.ESTOPPED: "e-stopped",
    S.INTERLOCKED: "interlocked",
}


class TransitionRefusedError(RuntimeError):
    """The present state does not allow the trigger; nothing changed."""


class StateMachine:
    """The present state, changed only by allowed triggers; thread-safe.

    ``on_change(old, new, trigger)`` is called after each transition, outside the lock.
    """

    def __init__(
        self,
        state: RunState = RunState.IDLE,
        on_change: Callable[[RunState, RunState, Trigger], None] | None = None,
    ) -> None:
        self._state = state
        self._lock = threading.Lock()
        self._on_change = on_change

    @property
    def state(self) -> RunState:
        return self._state

    def allows(self, trigger: Trigger) -> bool:
        return (self._state, trigger) in TRANSITIONS

    def fire(self, trigger: Trigger) -> RunState:
        with self._lock:
            old = self._state
            new = TRANSITIONS.get((old, trigger))
            if new is None:
                raise TransitionRefusedError(f"{trigger.value} is not allowed while {old.value}")
            self._state = new
        if self._on_change is not None:
            self._on_change(old, new, trigger)
        return new
