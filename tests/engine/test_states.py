"""The engine's transition table, transition by transition, against a table written out by hand."""

from __future__ import annotations

import threading

import pytest

from bench.engine.states import RUN_STATUS, RunState, StateMachine, TransitionRefusedError, Trigger

# rows: state; columns: the triggers in this order; "-" refused
COLUMNS = (
    "off",
    "low",
    "high",
    "start",
    "pause",
    "checkpoint",
    "resume",
    "abort",
    "stopped",
    "estop",
    "interlock",
    "fail",
    "reset",
    "finish",
)
TABLE = """
idle         idle  low  -     run  -        -       -    -         -        estop  -      -       -    -
low          idle  low  high  run  -        -       -    -         -        estop  -      -       -    -
high         idle  low  high  run  -        -       -    -         -        estop  -      -       -    -
running      -     -    -     -    pausing  -       -    aborting  -        estop  ilock  failed  -    done
pausing      -     -    -     -    -        paused  run  aborting  -        estop  ilock  failed  -    done
paused       -     -    -     -    -        -       run  aborting  -        estop  ilock  failed  -    -
aborting     -     -    -     -    -        -       -    -         aborted  estop  ilock  failed  -    done
aborted      idle  low  high  run  -        -       -    -         -        estop  -      -       -    -
estopped     -     -    -     -    -        -       -    -         -        estop  -      -       low  -
interlocked  -     -    -     -    -        -       -    -         -        estop  -      -       low  -
failed       -     -    -     -    -        -       -    -         -        estop  -      -       low  -
finished     idle  low  high  run  -        -       -    -         -        estop  -      -       -    -
"""
NAMES = {
    "idle": RunState.IDLE,
    "low": RunState.HYDRAULICS_LOW,
    "high": RunState.HYDRAULICS_HIGH,
    "run": RunState.RUNNING,
    "running": RunState.RUNNING,
    "pausing": RunState.PAUSING,
    "paused": RunState.PAUSED,
    "aborting": RunState.ABORTING,
    "aborted": RunState.ABORTED,
    "estop": RunState.ESTOPPED,
    "estopped": RunState.ESTOPPED,
    "ilock": RunState.INTERLOCKED,
    "interlocked": RunState.INTERLOCKED,
    "failed": RunState.FAILED,
    "done": RunState.FINISHED,
    "finished": RunState.FINISHED,
}
TRIGGERS = {
    "off": Trigger.HYDRAULICS_OFF,
    "low": Trigger.HYDRAULICS_LOW,
    "high": Trigger.HYDRAULICS_HIGH,
    "start": Trigger.START,
    "pause": Trigger.PAUSE,
    "checkpoint": Trigger.CHECKPOINT,
    "resume": Trigger.RESUME,
    "abort": Trigger.ABORT,
    "stopped": Trigger.STOPPED,
    "estop": Trigger.ESTOP,
    "interlock": Trigger.INTERLOCK,
    "fail": Trigger.FAIL,
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
    machine = StateMachine(state)
    if expected is None:
        with pytest.raises(TransitionRefusedError, match=trigger.value):
            machine.fire(trigger)
        assert machine.state is state and machine.take_changes() == []
    else:
        assert machine.fire(trigger) is expected
        assert machine.take_changes() == [(state, expected, trigger)]
        assert machine.take_changes() == []


def test_every_state_a_sequence_ends_in_allows_a_new_sequence_or_a_reset_that_readies_one():
    """Whatever ended it, the engine is never left where neither start nor reset is allowed."""
    for state in RUN_STATUS:
        machine = StateMachine(state)
        if not machine.allows(Trigger.START):
            machine.fire(Trigger.RESET)
        assert machine.allows(Trigger.START), state


def test_a_waiting_thread_wakes_on_another_threads_change():
    machine = StateMachine(RunState.PAUSED)
    woke: list[RunState] = []
    waiter = threading.Thread(target=lambda: woke.append(machine.wait_while(RunState.PAUSED)))
    waiter.start()
    machine.fire(Trigger.RESUME)
    waiter.join(timeout=10)
    assert woke == [RunState.RUNNING]
