"""What a measurement run may use of the engine: the run context.

A measurement step is run by the procedure of its run kind (:mod:`bench.engine.procedures`) and
recorded by :class:`~bench.engine.recording.RunRecording`; both are handed a :class:`RunContext`
instead of the engine: the bench's devices and settings, the sequence's conditions, and the few of
the engine's own acts a run takes part in (publish an event, the checkpoint where a pause waits,
a question to the operator, the sequence's ending when a run does not complete). A run cannot reach
the transition table, the run gate or the sequence's other steps, and the engine imports the
procedures, never the other way round.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from bench.engine import events as ev
from bench.engine.amplitude import AmplitudeControl, FramesPresent
from bench.engine.amplitude_hold import AmplitudeHold
from bench.engine.channels import FrameChannels
from bench.engine.contracts import (
    Acquisition,
    Actuator,
    Notching,
    PlannedDrive,
    PlannedIteration,
    ResumePlan,
)
from bench.engine.interlocks import Interlock
from bench.engine.points import SyncBits
from bench.engine.states import RunState
from bench.engine.stops import RunOutcome
from bench.engine.timing import EngineTiming
from sequences import (
    DriveIteration,
    DwellGrid,
    FreeRun,
    HammerTest,
    Prompt,
    RoadReplay,
    SineDwell,
    Sweep,
    TrackedDwell,
)

#: A step that records a run.
MeasurementStep = (
    SineDwell | DwellGrid | FreeRun | Sweep | TrackedDwell | RoadReplay | DriveIteration | HammerTest
)


@dataclass(frozen=True)
class RecordedRun:
    """What the campaign file holds of a run already (resume): its done points and its samples,
    which the run's new samples follow."""

    done_points: frozenset[int] = frozenset()
    samples: int = 0


@dataclass(frozen=True)
class MeasurementRun:
    """One measurement step to run: its run id, its step, what the campaign file holds of it already,
    what the plan loaded for it (a road replay's drive, a drive iteration's target; None for any
    other), and the resumed campaign's plan (None: not a resume; a drive iteration's runs are its
    own, ``<run id>-iNN``, which it looks up there)."""

    run_id: str
    step: MeasurementStep
    held: RecordedRun = RecordedRun()
    drive: PlannedDrive | PlannedIteration | None = None
    resume: ResumePlan | None = None


class StreamingRun(Protocol):
    """The run whose stream is recorded now, as the engine sees it: the run an ending names (a lost
    link's interlock), and what a pause does meanwhile (the stream goes on being recorded)."""

    @property
    def run_id(self) -> str: ...

    def record_while_paused(self) -> None:
        """Record the stream and watch the interlocks until the sequence leaves ``paused``."""
        ...


@dataclass(frozen=True)
class RunContext:
    """The bench and the sequence under way, as one measurement run sees them.

    The bench: its devices (``actuator``, ``acquisition``) and settings: the recorded ``channels``,
    the ``interlocks`` watched, the frame status bits of the controller's sync outputs, the sample
    rate, the engine's ``timing`` and ``clock`` (wall time, for timeouts and watchdogs only),
    whether the WFS is tared before each run's stream, the amplitude control and hold, how much of
    a window's frames must be present, and the notching of responses (None: none).

    The sequence: its ``conditions`` (a prompt answered within a run adds to them), and the
    engine's acts a run takes part in: ``publish`` an event; read the ``state``; ``publish_changes``
    other threads requested; ``checkpoint`` (an abort or e-stop ends the sequence, a pause waits);
    ``wait_paused`` after a point a pause interrupted; ``stop_if_requested`` (an abort or e-stop
    ends the sequence); ``request_pause`` (a limit that holds); ``ask`` the operator; ``end_run``:
    how a run ended, complete or the sequence's ending (which a run that does not complete
    decides); ``streaming``: tell the engine which run's stream is recorded now (None: none)."""

    actuator: Actuator
    acquisition: Acquisition
    channels: FrameChannels
    interlocks: tuple[Interlock, ...]
    sync_bits: SyncBits
    sample_rate_hz: float
    timing: EngineTiming
    clock: Callable[[], float]
    tare_each_run: bool
    amplitude_control: AmplitudeControl
    amplitude_hold: AmplitudeHold | None
    frames_present: FramesPresent
    notching: Notching | None

    conditions: dict[str, Any]
    publish: Callable[[ev.Event], None]
    state: Callable[[], RunState]
    publish_changes: Callable[[], None]
    checkpoint: Callable[[], None]
    wait_paused: Callable[[], None]
    stop_if_requested: Callable[[], None]
    request_pause: Callable[[], bool]
    ask: Callable[[Prompt], None]
    end_run: Callable[[BaseException | None], RunOutcome]
    streaming: Callable[[StreamingRun | None], None]

    def mean_mm(self, step_mean_mm: float) -> float:
        """The mean an excitation runs about: the step's own, else the last mean-position step's."""
        return step_mean_mm or float(self.conditions.get("mean_mm", 0.0))

    def finish_run(self, run_id: str, outcome: RunOutcome) -> None:
        """Publish the end of run ``run_id`` with its ``outcome`` and the WFS link's counters."""
        counters = self.acquisition.link_counters()
        self.publish(ev.RunFinished(run_id, outcome.status, outcome.reason, counters))
