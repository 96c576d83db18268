"""What a front end shows of the bench's condition, defined once for every front end (the terminal
UI's Bench screen and top line, the web monitor): the tone of each engine state, when a reset
clears the tripped interlocks, and the interlock lamps.

The front ends draw these their own way (coloured markup, HTML); what is red and why is decided here.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from enum import StrEnum

from bench.config import BenchConfig
from bench.engine import events as ev
from bench.engine.states import RunState


class Tone(StrEnum):
    """How alarming a state is: ``ok`` (green), ``caution`` (yellow), ``alarm`` (red); ``plain``:
    neither (idle, the hydraulics' levels)."""

    OK = "ok"
    CAUTION = "caution"
    ALARM = "alarm"
    PLAIN = "plain"


#: The tone of each state a front end shows (the engine's states' values; "not open": the bench
#: could not be opened); a state not named here is plain.
STATE_TONES: dict[str, Tone] = {
    RunState.RUNNING.value: Tone.OK,
    RunState.PAUSING.value: Tone.CAUTION,
    RunState.PAUSED.value: Tone.CAUTION,
    RunState.ABORTING.value: Tone.CAUTION,
    RunState.ABORTED.value: Tone.CAUTION,
    RunState.ESTOPPED.value: Tone.ALARM,
    RunState.INTERLOCKED.value: Tone.ALARM,
    RunState.FAILED.value: Tone.ALARM,
    "not open": Tone.ALARM,
}

#: The states a reset leaves for hydraulics low; leaving one of them clears the tripped interlocks.
STOPPED_STATES = (RunState.ESTOPPED, RunState.INTERLOCKED, RunState.FAILED)


def state_tone(state: str) -> Tone:
    return STATE_TONES.get(state, Tone.PLAIN)


def is_reset(event: ev.StateChanged) -> bool:
    """Whether ``event`` is the reset out of an e-stop, interlock or failure (the lamps go green)."""
    return event.new is RunState.HYDRAULICS_LOW and event.old in STOPPED_STATES


@dataclass(frozen=True)
class Lamp:
    """One lamp: its ``text`` and whether it is green (True), red (False) or unknown (None)."""

    text: str
    ok: bool | None


def interlock_lamps(
    interlocks: Iterable[str],
    tripped: Mapping[str, str],
    *,
    controller_state: str | None = None,
    controller_interlock: str | None = None,
    failure: str | None = None,
) -> list[Lamp]:
    """A lamp for every interlock the engine can trip (``interlocks``), red while ``tripped`` (name:
    reason) holds it; a tripped name without a lamp of its own gets a red one, so a run that ended
    interlocked never leaves every lamp green. The controller's own interlock as read (its state and
    what holds it) and a failed sequence (``failure``: why) show as red lamps of their own."""
    names = tuple(interlocks)
    lamps = [Lamp(name, name not in tripped) for name in names]
    lamps += [Lamp(name, False) for name in tripped if name not in names]
    if controller_interlock:
        held = "" if controller_interlock == controller_state else f": {controller_interlock}"
        lamps.append(Lamp(f"controller {controller_state}{held}", False))
    if failure is not None:  # the engine stopped the bench itself: no interlock lamp tells why
        lamps.append(Lamp(f"sequence failed: {failure}", False))
    return lamps


def point_text(event: ev.PointStarted) -> str:
    """The point under way, as the front ends say it (after the run's id)."""
    pressure = event.conditions.get("tyre_pressure_bar")
    shown = f"{pressure:g} bar" if isinstance(pressure, float | int) else "not set"
    return (
        f"point {event.index} attempt {event.attempt}: {event.freq_hz:g} Hz at {event.amplitude_mm:.3f} mm,"
        f" tyre pressure {shown}"
    )


def bench_description(config: BenchConfig) -> str:
    """Which bench, for people: its kind and where its devices are (the simulated lab, or the
    configuration's devices)."""
    return f"{config.kind} bench ({'simulated lab' if config.simulated else config.source})"
