"""The engine's transition table, transition by transition, against a table written out by hand."""

from __future__ import annotations

import pytest

from bench.engine.states import RunState, StateMachine, TransitionRefusedError, Trigger

# rows: state; columns: the triggers in this order; "-" refused
COLUMNS = (
    "off",
    "low",
    "high",
    "start",
    "pause",
    "resume",
    "abort",
    "stopped",
    "estop",
    "interlock",
    "reset",
    "finish",
)
TABLE = """
idle         idle  low   -     run   -     -     -     -     estop -     -     -
low          idle  low   high  run   -     -     -     -     estop -     -     -
high         idle  low   high  run   -     -     -     -     estop -     -     -
running      -     -     -     -     pause -     stop  -     estop ilock -     done
paused       -     -     -     -     -     run   stop  -     estop ilock -     -
stopping     -     -     -     -     -     -     -     abort estop ilock -     -
aborted      idle  low   high  run   -     -     -     -     estop -     -     -
estopped     -     -     -     -     -     -     -     -     estop -     low   -
interlocked  -     -     -     -     -     -     -     -     estop -     low   -
finished     idle  low   high  run   -     -     -     -     estop -     -     -
"""
NAMES = {
    "idle": RunState.IDLE,
    "low": RunState.HYDRAULICS_LOW,
    "high": RunState.HYDRAULICS_HIGH,
    "run": RunState.RUNNING,
    "running": RunState.RUNNING,
    "pause": RunState.PAUSED,
    "paused": RunState.PAUSED,
    "stop": RunState.STOPPING,
    "stopping": RunState.STOPPING,
    "abort": RunState.ABORTED,
    "aborted": RunState.ABORTED,
    "estop": RunState.ESTOPPED,
    "estopped": RunState.ESTOPPED,
    "ilock": RunState.INTERLOCKED,
    "interlocked": RunState.INTERLOCKED,
    "done": RunState.FINISHED,
    "finished": RunState.FINISHED,
}
TRIGGERS = {
    "off": Trigger.HYDRAULICS_OFF,
    "low": Trigger.HYDRAULICS_LOW,
    "high": Trigger.HYDRAULICS_HIGH,
    "start": Trigger.START,
    "pause": Trigger.PAUSE,
    "resume": Trigger.RESUME,
    "abort": Trigger.ABORT,
    "stopped": Trigger.STOPPED,
    "estop": Trigger.ESTOP,
    "interlock": Trigger.INTERLOCK,
    "reset": Trigger.RESET,
    "finish": Trigger.FINISH,
}
CASES = [
    (NAMES[row.split()[0]], TRIGGERS[column], None if cell == "-" else NAMES[cell])
    for row in TABLE.strip().splitlines()
    for column, cell in zip(COLUMNS, row.split()[1:], strict=True)
]


def test_the_table_covers_every_state_and_trigger():
    assert {state for state, _, _ in CASES} == set(RunState)
    assert len(CASES) == len(RunState) * len(Trigger)


@pytest.mark.parametrize(("state", "trigger", "expected"), CASES, ids=lambda v: getattr(v, "value", str(v)))
def test_transition(state, trigger, expected):
    changes = []
    machine = StateMachine(state, on_change=lambda old, new, t: changes.append((old, new, t)))
    if expected is None:
        with pytest.raises(TransitionRefusedError, match=trigger.value):
            machine.fire(trigger)
        assert machine.state is state and changes == []
    else:
        assert machine.fire(trigger) is expected
        assert changes == [(state, expected, trigger)]
