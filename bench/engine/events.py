"""The engine's typed events and the bus that hands them to subscribers.

Writer, front ends and post-run analysis subscribe; none of them drives the engine. Subscribers are
called on the engine's thread in subscription order and must return quickly: a front end that
draws hands the event over to its own thread. A subscriber that raises is reported once and removed
(a broken display must not stop a run; the recorder is subscribed with ``critical=True``, so its
failure stops the run instead).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from bench.engine.states import RunState, Trigger
from sequences.channels import Channel
from sequences.points import PointAttempt
from sequences.runs import EventKind

if TYPE_CHECKING:
    from bench.report.figure_list import KeptFigure

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SequenceStarted:
    """A sequence begins: the whole configuration and sequence as text, and the plan of runs."""

    sequence_name: str
    sequence_text: str
    config_text: str
    total_points: int
    estimated_duration_s: float
    estimated_with_operator_s: float | None = None  # with the operator's answers (prompts, blows)


@dataclass(frozen=True)
class StateChanged:
    old: RunState
    new: RunState
    trigger: Trigger


@dataclass(frozen=True)
class RunStarted:
    """A measurement step (dwell grid, free run, sweep, road replay, hammer test) begins recording
    as ``run_id``; ``drive``: a road replay's drive, where it came from and its checksum
    (:class:`~bench.engine.contracts.PlannedDrive`), empty for any other run."""

    run_id: str
    kind: str
    step: Mapping[str, Any]
    conditions: Mapping[str, Any]
    channels: tuple[Channel, ...]
    sample_rate_hz: float
    drive: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class SamplesRecorded:
    """Consecutive samples of the present run, by channel name, from run sample ``first_sample`` on;
    ``gaps``: ``(index, missing)`` for each place in the block where the link lost frames (``missing``
    of them just before its sample ``index``)."""

    run_id: str
    first_sample: int
    columns: Mapping[str, np.ndarray]
    gaps: tuple[tuple[int, int], ...] = ()

    def __len__(self) -> int:
        return len(next(iter(self.columns.values())))


@dataclass(frozen=True)
class PointStarted:
    run_id: str
    index: int
    attempt: int
    freq_hz: float
    amplitude_mm: float
    conditions: Mapping[str, Any]


@dataclass(frozen=True, slots=True)
class PointDone(PointAttempt):
    """One attempt at a point of run ``run_id`` ended: the :class:`~sequences.points.PointAttempt`
    as the campaign file records it (its status "done", "repeated" or "interrupted"; sample indices
    count this run's recorded frames, :class:`bench.engine.points.ExcitationSpan`)."""

    run_id: str = field(kw_only=True)


@dataclass(frozen=True)
class AmplitudeChecked:
    """The amplitude of point ``index`` (attempt ``attempt``) of run ``run_id`` looked at within its
    hold (:mod:`bench.engine.amplitude_hold`): ``achieved_mm`` over the window ending at run sample
    ``sample`` under the command ``command_mm``; ``updated_mm`` the new amplitude sent (NaN: none),
    ``refusal`` why an update that was due was not made; ``frames_missing`` of the window's
    frames were lost on the link, and ``lost`` says why the window was not decided on (the same
    command is measured again over the next window; empty: it was decided on)."""

    stored_as: ClassVar[EventKind] = EventKind.AMPLITUDE

    run_id: str
    index: int
    attempt: int
    sample: int
    target_mm: float
    achieved_mm: float
    command_mm: float
    updated_mm: float
    refusal: str = ""
    frames_missing: int = 0
    lost: str = ""

    @property
    def text(self) -> str:
        """How a log and the campaign file's events say it."""
        said = (
            f"point {self.index} attempt {self.attempt}: {self.achieved_mm:.4g} mm achieved of"
            f" {self.target_mm:g} mm under {self.command_mm:.4g} mm"
        )
        if self.lost:
            return f"{said}; {self.lost}: measured again at the same command"
        if self.refusal:
            return f"{said}; not updated ({self.refusal}): the amplitude control's repeat takes over"
        if self.updated_mm == self.updated_mm:  # not NaN
            return f"{said}; updated to {self.updated_mm:.4g} mm"
        return said


@dataclass(frozen=True)
class ResonanceTracked:
    """One look at the resonance point ``index`` of run ``run_id`` tracks
    (:mod:`bench.engine.tracking`): the window's end (run sample), the drive frequency, the
    resonance estimated there, the ratio's magnitude and phase, the damping ratio."""

    stored_as: ClassVar[EventKind] = EventKind.TRACK

    run_id: str
    index: int
    sample: int
    drive_hz: float
    resonance_hz: float
    ratio: float
    phase_deg: float
    damping_ratio: float

    @property
    def text(self) -> str:
        return (
            f"resonance {self.resonance_hz:.3f} Hz (drive {self.drive_hz:.3f} Hz), ratio {self.ratio:.4g}"
            f" at {self.phase_deg:.1f} deg, damping ratio {self.damping_ratio:.4f}"
        )


@dataclass(frozen=True)
class GridRefined:
    """An adaptive grid adds points to run ``run_id`` at the nominal ``amplitude_mm``: each
    ``(freq_hz, reason)`` in ``added``."""

    run_id: str
    amplitude_mm: float
    added: tuple[tuple[float, str], ...]


@dataclass(frozen=True)
class PromptAsked:
    prompt_id: str
    text: str


@dataclass(frozen=True)
class PromptAnswered:
    prompt_id: str
    text: str
    answer: Any
    unit: str | None


@dataclass(frozen=True)
class HostStalled:
    """The host left the WFS port unread for ``stalled_s`` seconds during run ``run_id`` (a busy
    machine, not the link); ``frames_lost`` frames overran the port's buffer meanwhile. ``counted``:
    whether frames after the stall were read, which show what it lost; a run that ended first (a
    controller's watchdog that tripped while the host stood still) stops its stream before they come,
    and its stall's losses are then not known."""

    stored_as: ClassVar[EventKind] = EventKind.HOST_STALL

    run_id: str
    stalled_s: float
    frames_lost: int
    counted: bool = True

    @property
    def text(self) -> str:
        """How a log and the campaign file's events say a host stall."""
        if not self.counted:
            return (
                f"host stall: the WFS port went unread for {self.stalled_s:.2f} s; the frames it lost are"
                f" not known: the run ended before the stream after it was read ({self.run_id})"
            )
        return (
            f"host stall: the WFS port went unread for {self.stalled_s:.2f} s,"
            f" {self.frames_lost} frames lost ({self.run_id})"
        )


@dataclass(frozen=True)
class LimitReached:
    """A limit tripped with an action milder than an interlock, during run ``run_id``: ``name`` (a
    response limit's level, "wfs_fz alarm", or a graded interlock), why, and its ``action``
    (indicate: recorded only; hold: the sequence pauses; stop: it ends, aborted)."""

    stored_as: ClassVar[EventKind] = EventKind.LIMIT

    run_id: str
    name: str
    reason: str
    action: str

    @property
    def text(self) -> str:
        return f"{self.name} ({self.action}): {self.reason}"


@dataclass(frozen=True)
class InterlockTripped:
    """Interlock ``name`` tripped for ``reason``, during run ``run_id`` (None: between runs)."""

    stored_as: ClassVar[EventKind] = EventKind.INTERLOCK

    name: str
    reason: str
    run_id: str | None

    @property
    def text(self) -> str:
        return f"{self.name}: {self.reason}"


#: The events a campaign file stores as a run's (or, between runs, the campaign's) events, each as
#: its ``stored_as`` kind, its ``text`` and :func:`stored_fields`.
StoredEvent = AmplitudeChecked | ResonanceTracked | HostStalled | LimitReached | InterlockTripped


def stored_fields(event: StoredEvent) -> dict[str, object]:
    """The fields a stored event keeps (docs/hdf5.md, *Events*): all of the event's but its run,
    which the file says by where the event is."""
    return {f.name: getattr(event, f.name) for f in fields(event) if f.name != "run_id"}


@dataclass(frozen=True)
class RunFinished:
    run_id: str
    status: str  # complete, aborted, e-stopped, interlocked, failed
    reason: str
    link_counters: Mapping[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class AnalysisDone:
    """Results of the analysis after a run: ``summary`` lines for people, ``results`` for storage;
    ``status`` how far it got (``complete``, ``partial`` or ``failed``: the analysis's
    :class:`~bench.analysis.campaign.AnalysisStatus`) and, when not complete, ``why``; ``record``:
    the analysis kept as a record (JSON text, :mod:`bench.app.analysis_record`; empty when the
    analysis process was lost before it made one); ``figures``: the report's figures whose values
    the run changed, drawn by the analysis process, to be kept beside the run
    (:mod:`bench.app.kept_figures`)."""

    run_id: str
    name: str
    summary: tuple[str, ...]
    results: Mapping[str, Any]
    status: str
    why: str = ""
    record: str = ""
    figures: tuple[KeptFigure, ...] = ()

    @property
    def complete(self) -> bool:
        return self.status == "complete"


@dataclass(frozen=True)
class SequenceFinished:
    status: str
    reason: str


Event = (
    SequenceStarted
    | StateChanged
    | RunStarted
    | SamplesRecorded
    | PointStarted
    | PointDone
    | AmplitudeChecked
    | ResonanceTracked
    | GridRefined
    | PromptAsked
    | PromptAnswered
    | HostStalled
    | LimitReached
    | InterlockTripped
    | RunFinished
    | AnalysisDone
    | SequenceFinished
)
Subscriber = Callable[[Event], None]


class EventBus:
    """Hands each event to every subscriber in order."""

    def __init__(self) -> None:
        self._subscribers: list[tuple[Subscriber, bool]] = []

    def subscribe(self, subscriber: Subscriber, *, critical: bool = False) -> None:
        """Add ``subscriber``; a critical subscriber's exception propagates to the publisher."""
        self._subscribers.append((subscriber, critical))

    def unsubscribe(self, subscriber: Subscriber) -> None:
        self._subscribers = [(s, c) for s, c in self._subscribers if s is not subscriber]

    def publish(self, event: Event) -> None:
        for subscriber, critical in list(self._subscribers):
            try:
                subscriber(event)
            except Exception:
                if critical:
                    raise
                log.exception("subscriber %r failed on %s; removed", subscriber, type(event).__name__)
                self.unsubscribe(subscriber)
