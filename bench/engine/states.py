"""The engine's states and its explicit transition table.

Every change of state goes through :meth:`StateMachine.fire` with a trigger; a trigger the present
state does not allow raises :class:`TransitionRefusedError` and changes nothing. Front ends request
transitions (hydraulics, start, pause, resume, abort, e-stop, reset) and a pause or abort request is
a state of its own (``pausing``, ``aborting``) until the engine has acted on it; the engine fires
what it observes (the checkpoint reached at rest, the aborted excitation at rest) and how a sequence
ends (finish, interlock, fail). The table is the only record of what a sequence is doing: the
engine's loop reads the state, never a flag of its own.
"""

from __future__ import annotations

import enum
import threading
from collections import deque

from sequences.runs import RunStatus

Change = tuple["RunState", "RunState", "Trigger"]


class RunState(enum.Enum):
    IDLE = "idle"  # hydraulics off, nothing running
    HYDRAULICS_LOW = "hydraulics low"
    HYDRAULICS_HIGH = "hydraulics high"
    RUNNING = "running"
    PAUSING = "pausing"  # a pause requested: the point under way tapers out, the checkpoint is next
    PAUSED = "paused"  # at a checkpoint between points, actuator at rest, hydraulics on
    ABORTING = "aborting"  # an abort requested: the excitation tapers out
    ABORTED = "aborted"
    ESTOPPED = "e-stopped"
    INTERLOCKED = "interlocked"
    FAILED = "failed"  # a device error or a refused setpoint ended the sequence
    FINISHED = "finished"


class Trigger(enum.Enum):
    HYDRAULICS_OFF = "hydraulics off"
    HYDRAULICS_LOW = "hydraulics low"
    HYDRAULICS_HIGH = "hydraulics high"
    START = "start"
    PAUSE = "pause"  # requested: the point under way is tapered out
    CHECKPOINT = "checkpoint"  # the paused sequence reached its checkpoint, actuator at rest
    RESUME = "resume"
    ABORT = "abort"  # requested (or the engine's own: a declined prompt)
    STOPPED = "stopped"  # the aborted excitation is at rest
    ESTOP = "e-stop"
    INTERLOCK = "interlock"
    FAIL = "fail"  # a device error or a refused setpoint the engine cannot handle
    RESET = "reset"  # e-stop, interlock or failure released (the controller returns to hydraulics low)
    FINISH = "finish"  # the sequence ran to its end


S, T = RunState, Trigger
_READY = (S.IDLE, S.HYDRAULICS_LOW, S.HYDRAULICS_HIGH, S.ABORTED, S.FINISHED)
_AT_REST = (S.IDLE, S.HYDRAULICS_LOW, S.HYDRAULICS_HIGH, S.ABORTED, S.FINISHED)
#: a sequence under way, whatever is requested of it
_UNDER_WAY = (S.RUNNING, S.PAUSING, S.PAUSED, S.ABORTING)

#: (state, trigger) -> next state; any pair not listed is refused.
TRANSITIONS: dict[tuple[RunState, Trigger], RunState] = {
    **{(s, T.HYDRAULICS_OFF): S.IDLE for s in _AT_REST},
    **{(s, T.HYDRAULICS_LOW): S.HYDRAULICS_LOW for s in _AT_REST},
    **{(s, T.HYDRAULICS_HIGH): S.HYDRAULICS_HIGH for s in _AT_REST if s is not S.IDLE},
    **{(s, T.START): S.RUNNING for s in _READY},
    (S.RUNNING, T.PAUSE): S.PAUSING,
    (S.PAUSING, T.CHECKPOINT): S.PAUSED,
    (S.PAUSING, T.RESUME): S.RUNNING,  # the request withdrawn before the checkpoint
    (S.PAUSED, T.RESUME): S.RUNNING,
    (S.RUNNING, T.ABORT): S.ABORTING,
    (S.PAUSING, T.ABORT): S.ABORTING,
    (S.PAUSED, T.ABORT): S.ABORTING,
    (S.ABORTING, T.STOPPED): S.ABORTED,
    **{(s, T.ESTOP): S.ESTOPPED for s in S},
    **{(s, T.INTERLOCK): S.INTERLOCKED for s in _UNDER_WAY},
    **{(s, T.FAIL): S.FAILED for s in _UNDER_WAY},
    (S.ESTOPPED, T.RESET): S.HYDRAULICS_LOW,
    (S.INTERLOCKED, T.RESET): S.HYDRAULICS_LOW,
    (S.FAILED, T.RESET): S.HYDRAULICS_LOW,
    # a pause or abort requested after the last point has nothing left to stop
    (S.RUNNING, T.FINISH): S.FINISHED,
    (S.PAUSING, T.FINISH): S.FINISHED,
    (S.ABORTING, T.FINISH): S.FINISHED,
}

#: states in which the engine's loop is executing a sequence
ACTIVE = frozenset(_UNDER_WAY)
#: states a sequence can end in, with the run status recorded for each
RUN_STATUS = {
    S.FINISHED: RunStatus.COMPLETE,
    S.ABORTED: RunStatus.ABORTED,
    S.ESTOPPED: RunStatus.ESTOPPED,
    S.INTERLOCKED: RunStatus.INTERLOCKED,
    S.FAILED: RunStatus.FAILED,
}


class TransitionRefusedError(RuntimeError):
    """The present state does not allow the trigger; nothing changed."""


class StateMachine:
    """The present state, changed only by allowed triggers; thread-safe.

    Every transition is journaled in the order it happened; :meth:`take_changes` hands the journal
    over, so that whoever publishes the changes (the engine, on its own thread) publishes them in
    that order whichever thread fired them. :meth:`wait_while` blocks until another thread changes
    the state (a paused sequence waits for its resume so)."""

    def __init__(self, state: RunState = RunState.IDLE) -> None:
        self._state = state
        self._changed = threading.Condition()
        self._journal: deque[Change] = deque()

    @property
    def state(self) -> RunState:
        return self._state

    def allows(self, trigger: Trigger) -> bool:
        return (self._state, trigger) in TRANSITIONS

    def fire(self, trigger: Trigger) -> RunState:
        """Apply ``trigger``; the new state, or TransitionRefusedError with nothing changed."""
        with self._changed:
            old = self._state
            new = TRANSITIONS.get((old, trigger))
            if new is None:
                raise TransitionRefusedError(f"{trigger.value} is not allowed while {old.value}")
            self._state = new
            self._journal.append((old, new, trigger))
            self._changed.notify_all()
        return new

    def has_changes(self) -> bool:
        """Whether transitions wait in the journal."""
        return bool(self._journal)

    def take_changes(self) -> list[Change]:
        """The transitions since the last call, oldest first: (old, new, trigger)."""
        with self._changed:
            changes = list(self._journal)
            self._journal.clear()
        return changes

    def wait_while(self, state: RunState) -> RunState:
        """Block until the state is no longer ``state``; the state then."""
        with self._changed:
            self._changed.wait_for(lambda: self._state is not state)
            return self._state
