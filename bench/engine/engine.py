"""The run engine: executes a sequence's steps on the bench, point by point.

The loop reads top to bottom: a sequence is split into its steps; a measurement step (dwell grid,
free run, sweep) is one *run*, recorded from the start of its stream to its end; each dwell of a
grid is one *point*. A point is located in the acquisition's samples by the controller's sync
outputs (:mod:`bench.engine.points`), so lengths are counted in samples and the wall clock serves
only timeouts and watchdogs. Between points lies the checkpoint where a pause takes effect.

Requests come from other threads (front ends) and fire their transition at once: a pause or an
abort request is a state of the table (pausing, aborting) until the loop has acted on it, and the
e-stop is also sent to the controller from the requesting thread. The loop reads the state, never a
flag of its own. However a sequence ends, :meth:`Engine._end` ends it. Everything the engine does is
published as an event; storage, analysis and displays are subscribers.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any, NoReturn, Self

import numpy as np

from bench.engine import events as ev
from bench.engine.amplitude import (
    AMPLITUDE_EXCURSION,
    AmplitudeControl,
    FramesPresent,
    ServoGains,
    amplitude_mm,
)
from bench.engine.amplitude_hold import AmplitudeHold, AmplitudeStep, HeldAmplitude
from bench.engine.channels import FrameChannels
from bench.engine.contracts import (
    Acquisition,
    Actuator,
    Notch,
    Notching,
    Operator,
    PlannedDrive,
    ResumePlan,
    RunGate,
    SampleBlockLike,
)
from bench.engine.interlocks import ActuatorLinkLost, Interlock, Observation, Trip, trips
from bench.engine.online import DwellVerdict, OnlineDwell
from bench.engine.points import ExcitationSpan, SpanTracker, excitation_frequency_hz, sweep_time_s
from bench.engine.refinement import next_point
from bench.engine.run_ids import run_id
from bench.engine.states import RUN_STATUS, RunState, StateMachine, TransitionRefusedError, Trigger
from bench.engine.timing import EngineTiming
from bench.engine.tracking import GLIDE_S, Resonance, TrackWatch, TrackWindow, find_resonance
from bench.numerics.sine_fit import SineFit, fit_latest_cycles, frame_offsets
from drivers.errors import CommandOutcomeUnknownError, CommandRejectedError, LimitError, LinkError
from drivers.setpoints import (
    AmplitudeUpdate,
    DriveSetpoint,
    DwellSetpoint,
    FrequencyUpdate,
    SweepNotch,
    SweepSetpoint,
)
from sequences import (
    AdaptiveDwell,
    AnswerError,
    DwellGrid,
    FreeRun,
    HammerTest,
    Hydraulics,
    MeanPosition,
    Prompt,
    RoadReplay,
    Sequence,
    SineDwell,
    Sweep,
    Tare,
    TrackedDwell,
    step_fields,
)
from sequences.channels import STANDARD_CHANNELS, Role
from sequences.points import PointStatus, Verdict
from sequences.response_limits import LimitAction
from sequences.runs import RunKind

log = logging.getLogger(__name__)

HAMMER_CHANNEL = replace(
    STANDARD_CHANNELS[Role.WFS_FZ],
    description="Fz of the bare sensor, triggered capture at the converter rate",
)

#: The bench condition a prompt's answer establishes, by the prompt's action: (name, value), where a
#: value of None stands for the answer itself.
CONDITION_OF_ACTION: dict[str, tuple[str, object]] = {
    "set_tyre_pressure": ("tyre_pressure_bar", None),
    "remove_wheel": ("wheel_fitted", False),
    "fit_wheel": ("wheel_fitted", True),
    "car_on_posts": ("car_on_posts", True),
    "car_off_posts": ("car_on_posts", False),
    "set_damper": ("damper", None),
}


@dataclass(frozen=True)
class SyncBits:
    """The frame status bits carrying the controller's sync outputs."""

    active: int
    hold: int


@dataclass(frozen=True)
class RunOutcome:
    """How a sequence ended: ``status`` complete, aborted, e-stopped, interlocked or failed, and why."""

    status: str
    reason: str = ""


@dataclass(frozen=True)
class RecordedRun:
    """What the campaign file holds of a run already (resume): its done points and its samples,
    which the run's new samples follow."""

    done_points: frozenset[int] = frozenset()
    samples: int = 0


#: The reason an abort records unless its requester gives its own.
ABORT_REASON = "aborted by the operator"
#: The id of the question put to the operator when the run gate would stop the sequence and the
#: operator is asked instead (``Engine.run(gate_asks=True)``); a yes is recorded as a condition.
GO_ON_DESPITE = "go_on_despite"


class RunStoppedError(Exception):
    """The sequence cannot go on: ``trigger`` is the ending the transition table is to apply, ``reason``
    why, ``interlock`` the event published once the table has applied an interlock. Raised where the
    loop sees the cause; :meth:`Engine._end` applies it."""

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


#: What ends a sequence without being a crash: raised on by :meth:`Engine.run` only when it is not one.
_ENDING_ERRORS = (RunStoppedError, LimitError, LinkError)
#: The endings that stop the actuator with a taper first (the end of the sequence left it at rest,
#: and an e-stop has gone to the controller already).
_STOPS_ACTUATOR = frozenset({Trigger.STOPPED, Trigger.INTERLOCK, Trigger.FAIL})


@dataclass(frozen=True)
class _Ending:
    """The trigger that ends a sequence, why, and the interlock event to publish once applied."""

    trigger: Trigger
    reason: str
    interlock: ev.InterlockTripped | None = None


#: What a refusal by a controller that awaits a reset adds: the way out.
AWAITS_RESET = (
    "it takes no command until its interlock is reset, once its cause is cleared:"
    " `wfsbench actuator reset`, or x in the terminal UI"
)


def _ending_of(error: BaseException | None) -> _Ending:
    """How the sequence ends, from what stopped its loop: nothing (it ran to its end), a stop the
    engine decided, a setpoint the soft limits refused (nothing was written), a command the
    controller refused (its answer, "controller refused ..."), a fault of a link, or a crash."""
    match error:
        case None:
            return _Ending(Trigger.FINISH, "")
        case RunStoppedError():
            return _Ending(error.trigger, error.reason, error.interlock)
        case LimitError():
            return _Ending(Trigger.FAIL, f"setpoint refused by the soft limits: {error}")
        case CommandRejectedError():
            return _Ending(Trigger.FAIL, f"{error}; {AWAITS_RESET}" if error.awaits_reset else str(error))
        case LinkError():
            return _Ending(Trigger.FAIL, f"link error: {error}")
    return _Ending(Trigger.FAIL, f"{type(error).__name__}: {error}")


@dataclass(frozen=True)
class _PointPlan:
    """What a point's attempts share: its index, dwell, nominal amplitude and why it was added."""

    index: int
    dwell: SineDwell
    requested_mm: float
    added_reason: str = ""
    notch: Notch | None = None


class _PointInterruptedError(Exception):
    """A pause request interrupted the present point at ``span``: repeat it after the pause."""

    def __init__(self, span: ExcitationSpan) -> None:
        super().__init__("point interrupted by a pause")
        self.span = span


class Engine:
    """Runs sequences on one bench. Create it once per bench; :meth:`run` one sequence at a time."""

    def __init__(
        self,
        actuator: Actuator,
        acquisition: Acquisition,
        operator: Operator,
        *,
        channels: FrameChannels,
        interlocks: tuple[Interlock, ...],
        sync_bits: SyncBits,
        sample_rate_hz: float,
        amplitude_control: AmplitudeControl | None = None,
        amplitude_hold: AmplitudeHold | None = None,
        frames_present: FramesPresent | None = None,
        notching: Notching | None = None,
        timing: EngineTiming | None = None,
        bus: ev.EventBus | None = None,
        tare: str = "never",
        bench_kind: str = "shaker",
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``tare``: "before_each_run" (the WFS is tared, at rest, before each run's stream starts),
        "once" (at the start of each sequence) or "never"; ``bench_kind``: "shaker" or
        "four_post", recorded with every run's conditions; ``amplitude_hold``: hold a fixed-timing
        dwell's amplitude within its hold by updates the actuator takes while running
        (:mod:`bench.engine.amplitude_hold`; None: correct it by repeating the point); ``notching``:
        lower the drive of dwells and sweeps where a response would pass a response limit's notch
        level (sweeps only where the actuator notches them); ``frames_present``: how much of a
        window's frames must be there before a command is changed on it, a dwell's settling
        judged or a resonance's track moved (:class:`~bench.engine.amplitude.FramesPresent`)."""
        self.actuator = actuator
        self.acquisition = acquisition
        self.operator = operator
        self.channels = channels
        self.interlocks = interlocks
        self.sync_bits = sync_bits
        self.sample_rate_hz = sample_rate_hz
        self.amplitude_control = amplitude_control or AmplitudeControl()
        self.amplitude_hold = amplitude_hold
        self.frames_present = frames_present or FramesPresent()
        self.notching = notching
        self.timing = timing or EngineTiming()
        self.bus = bus or ev.EventBus()
        if tare not in ("before_each_run", "once", "never"):
            raise ValueError(f"tare policy {tare!r} is not before_each_run, once or never")
        self.tare = tare
        self.bench_kind = bench_kind
        self._clock = clock
        self.machine = StateMachine()
        self._abort_reason = ABORT_REASON
        self._outcome: RunOutcome | None = None  # how the sequence under way ended, once it has
        self._sequence_thread: int | None = None  # the thread running a sequence, while one runs
        self._publishing = threading.Lock()
        self._recording: _RunRecording | None = None  # the run whose stream is recorded now
        self._gate: RunGate | None = None  # the sequence under way's run gate
        self._gate_asks = False  # whether a gate's reason is put to the operator instead of stopping
        self._gate_accepted: set[str] = set()  # the gate's reasons the operator chose to go on despite
        self._drives: Mapping[int, PlannedDrive] = {}  # the sequence under way's road replays' drives
        self.conditions: dict[str, Any] = {}

    # -- requests (any thread) ----------------------------------------------------------------

    @property
    def state(self) -> RunState:
        return self.machine.state

    # The requests return whether the table took them: a request the present state does not allow
    # (a pause while nothing runs, a second abort) changes nothing, as a front end racing the end of
    # a sequence expects.

    def request_pause(self) -> bool:
        """Pause: ``pausing`` until the point under way is stopped (tapered, to be repeated on
        resume), then ``paused`` at the checkpoint."""
        return self._request(Trigger.PAUSE)

    def request_resume(self) -> bool:
        """Go on from ``paused``, or withdraw a pause still ``pausing``."""
        return self._request(Trigger.RESUME)

    def request_abort(self, reason: str = ABORT_REASON) -> bool:
        """Taper out and end the sequence as aborted (``aborting`` meanwhile), ``reason`` recorded
        with the run (who or what asked: the operator, a signal); the data recorded so far is kept."""
        if not self.machine.allows(Trigger.ABORT):
            return False
        self._abort_reason = reason
        return self._request(Trigger.ABORT)

    def request_estop(self) -> None:
        """E-stop now: the table shows it first, then the controller is told from this thread,
        without waiting for the loop. In that order, a controller the loop sees e-stopped is the
        e-stop's doing, not an interlock."""
        self._request(Trigger.ESTOP)
        self.actuator.estop()

    def set_hydraulics(self, level: str) -> None:
        """Switch the hydraulics while no sequence runs (refused while one does)."""
        trigger = {
            "off": Trigger.HYDRAULICS_OFF,
            "low": Trigger.HYDRAULICS_LOW,
            "high": Trigger.HYDRAULICS_HIGH,
        }[level]
        if not self.machine.allows(trigger):
            raise RuntimeError(f"hydraulics {level} is not allowed while {self.state.value}")
        self.actuator.set_hydraulics(level)
        self._fire(trigger)

    def reset(self) -> None:
        """Release an interlock, an e-stop or a failed sequence once the cause is cleared. Returns
        once the controller has come to rest at hydraulics low: out of an e-stop it tapers first and
        refuses commands meanwhile (its status is read every ``status_period_s``). A controller
        still moving after ``reset_timeout_s`` raises TimeoutError and leaves the engine where it
        was.

        The controller is sent its reset when it holds an interlock or e-stop of its own, or when
        its link was lost (the reset reconnects). A stop the engine made alone (its own interlock,
        a failed sequence) leaves the controller with nothing to release, and it refuses a reset
        then: it is switched to hydraulics low once at rest instead, as its reset would leave it."""
        needs_reset = self.actuator.link_fault() is not None or self.actuator.read_status().interlock_reason
        if not needs_reset and not self.machine.allows(Trigger.RESET):
            raise TransitionRefusedError(
                f"nothing to reset while {self.state.value}: neither the engine nor the controller is stopped"
            )
        if needs_reset:
            self.actuator.reset_interlock()
        deadline_s = self._clock() + self.timing.reset_timeout_s
        while self.actuator.read_status().moving:
            if self._clock() > deadline_s:
                raise TimeoutError(
                    f"the controller still moves {self.timing.reset_timeout_s:g} s after the reset"
                )
            time.sleep(self.timing.status_period_s)  # the controller tells no event: read it again
        if not needs_reset:
            self.actuator.set_hydraulics("low")
        self._request(Trigger.RESET)  # a controller's own interlock may come while the engine rests

    # -- the sequence -------------------------------------------------------------------------

    def run(
        self,
        sequence: Sequence,
        *,
        sequence_text: str = "",
        config_text: str = "",
        resume: ResumePlan | None = None,
        gate: RunGate | None = None,
        gate_asks: bool = False,
        drives: Mapping[int, PlannedDrive] | None = None,
    ) -> RunOutcome:
        """Run ``sequence`` to its end or until stopped (refused unless the engine is ready: at rest,
        aborted or finished). Nothing a device raises escapes: it ends the sequence, and the outcome
        says how and why. A crash (or Ctrl-C) still stops the actuator and ends the sequence
        ``failed``, then is raised on. ``gate``: asked before each step about the next measurement
        run (:meth:`_pass_gate`); a reason it gives ends the sequence there, ``aborted`` with that
        reason, or with ``gate_asks`` is put to the operator, who may go on despite it. ``drives``:
        the drive of each road replay, by its step's index, as the plan loaded and dry-ran it."""
        if self._sequence_thread is not None:
            raise TransitionRefusedError(f"start is not allowed while {self.state.value}: a sequence runs")
        self._sequence_thread = threading.get_ident()  # before the start: its change is published here
        try:
            self._fire(Trigger.START)
            self.conditions = {"bench": self.bench_kind}
            self._outcome = None
            self._gate, self._gate_asks, self._gate_accepted = gate, gate_asks, set()
            self._drives = drives or {}
            self.bus.publish(
                ev.SequenceStarted(
                    sequence.name,
                    sequence_text,
                    config_text,
                    sequence.points(),
                    sequence.estimated_duration_s,
                    sequence.estimated_duration_with_operator_s,
                )
            )
            try:
                self._execute_all(sequence, resume)
            except BaseException as exc:
                outcome = self._sequence_finished(self._end(exc))
                if not isinstance(exc, _ENDING_ERRORS):
                    raise
                return outcome
            return self._sequence_finished(self._end(None))
        finally:
            self._sequence_thread = None
            self._gate = None
            self._abort_reason = ABORT_REASON
            self._publish_changes()  # what another thread requested after the loop last looked

    def _execute_all(self, sequence: Sequence, resume: ResumePlan | None) -> None:
        if self.tare == "once":
            self.acquisition.tare()
        for index in self._steps_to_run(sequence, resume):
            self._execute(sequence, index, resume)

    def _sequence_finished(self, outcome: RunOutcome) -> RunOutcome:
        self.bus.publish(ev.SequenceFinished(outcome.status, outcome.reason))
        return outcome

    def _steps_to_run(self, sequence: Sequence, resume: ResumePlan | None) -> list[int]:
        """Step indices to execute. On resume, a prompt and its steps up to the next prompt are
        skipped when every measurement run among them is complete (the bench is already past them);
        a prompt with no measurement before the next prompt ("fit the wheel" before "set the
        pressure") is skipped only when the measurements after it are, since they need what it
        asks for. Hydraulics steps always run."""
        if resume is None:
            return list(range(len(sequence.steps)))
        segments: list[list[int]] = [[]]
        for index, step in enumerate(sequence.steps):
            if isinstance(step, Prompt) and segments[-1]:
                segments.append([])
            segments[-1].append(index)
        chosen: list[int] = []
        done_after = False  # nothing follows the last segment: a prompt left there is asked
        for segment in reversed(segments):
            runs = [self.run_id(sequence, i) for i in segment if is_measurement(sequence.steps[i])]
            done = all(resume.run_complete(run_id) for run_id in runs) if runs else done_after
            chosen[:0] = [i for i in segment if not done or isinstance(sequence.steps[i], Hydraulics)]
            done_after = done
        return chosen

    @staticmethod
    def run_id(sequence: Sequence, index: int) -> str:
        """The run id of a measurement step: the sequence's name, the step's position and kind, so
        that runs of several sequences share a campaign file and a resume finds its runs again
        (:data:`bench.engine.run_ids.RUN_ID` reads them back)."""
        return run_id(sequence, index)

    def _execute(self, sequence: Sequence, index: int, resume: ResumePlan | None) -> None:
        step = sequence.steps[index]
        self._checkpoint()
        self._pass_gate(sequence, index, resume)
        if isinstance(step, Prompt):
            self._ask(step)
        elif isinstance(step, Hydraulics):
            self.actuator.set_hydraulics(step.level)
            self.conditions["hydraulics"] = step.level
        elif isinstance(step, Tare):
            self.acquisition.tare()
        elif isinstance(step, MeanPosition):
            self.conditions["mean_mm"] = step.mean_mm
        elif is_measurement(step):
            run_id = self.run_id(sequence, index)
            if resume is not None and resume.run_complete(run_id):
                return
            held = RecordedRun()
            if resume is not None:
                held = RecordedRun(resume.completed_points(run_id), resume.recorded_samples(run_id))
            if isinstance(step, RoadReplay):
                self._replay_run(run_id, step, held, self._drives.get(index))
            else:
                self._measure(run_id, step, held)
        else:
            raise RunStoppedError.fail(f"step {index}: {type(step).__name__} is not supported")

    def _pass_gate(self, sequence: Sequence, index: int, resume: ResumePlan | None) -> None:
        """Ask the run gate about the next measurement run from step ``index`` on (that step's own
        run, or the run the prompts, hydraulics and tare before it prepare), so that a sequence the
        gate stops is stopped before the operator is asked to prepare a run that will not start. A
        reason ends the sequence; with ``gate_asks`` the operator is asked instead whether to go on
        (declined: the sequence ends, aborted), and is not asked the same again in this sequence."""
        if self._gate is None:
            return
        steps = sequence.steps
        upcoming = next((i for i in range(index, len(steps)) if is_measurement(steps[i])), None)
        if upcoming is None:
            return
        run_id = self.run_id(sequence, upcoming)
        if resume is not None and resume.run_complete(run_id):
            return
        reason = self._gate(run_id, RunKind.of_step(steps[upcoming].kind))
        if reason is None or reason in self._gate_accepted:
            return
        if not self._gate_asks:
            raise RunStoppedError.abort(f"stopped before {run_id}: {reason}")
        self._ask(Prompt(GO_ON_DESPITE, f"Before {run_id}: {reason}. Go on anyway?"))
        self._gate_accepted.add(reason)

    def _measure(self, run_id: str, step: object, held: RecordedRun) -> None:
        if isinstance(step, Sweep):
            self._sweep_run(run_id, step, held)
        elif isinstance(step, TrackedDwell):
            self._tracked_run(run_id, step, held)
        elif isinstance(step, HammerTest):
            self._hammer_run(run_id, step, held)
        else:
            self._dwell_run(run_id, step, held)

    def _ask(self, prompt: Prompt) -> None:
        """Ask the operator; a refused confirmation, or no answer at all, aborts the sequence."""
        self.bus.publish(ev.PromptAsked(prompt.id, prompt.text))
        try:
            answer = self.operator.answer(prompt)
        except AnswerError as exc:
            raise RunStoppedError.abort(f"no valid answer to prompt {prompt.id!r}: {exc}") from exc
        if prompt.answer == "confirm" and answer is False:
            self.bus.publish(ev.PromptAnswered(prompt.id, prompt.text, answer, prompt.unit))
            raise RunStoppedError.abort(f"the operator declined: {prompt.text}")
        self.conditions[prompt.id] = answer
        if prompt.action in CONDITION_OF_ACTION:
            name, value = CONDITION_OF_ACTION[prompt.action]
            self.conditions[name] = answer if value is None else value
        self.bus.publish(ev.PromptAnswered(prompt.id, prompt.text, answer, prompt.unit))

    # -- runs ---------------------------------------------------------------------------------

    def _dwell_run(self, run_id: str, step: SineDwell | DwellGrid | FreeRun, held: RecordedRun) -> None:
        if isinstance(step, DwellGrid) and step.adaptive is not None:
            self._adaptive_run(run_id, step, held)
            return
        dwells = (step,) if isinstance(step, SineDwell) else step.dwells()
        # held within the dwell, each point starts with the command the gains measured so far
        # expect: an update costs the hold again, a good first command none
        gains = None if self.amplitude_hold is None else self._servo_gains()
        with _RunRecording(self, run_id, step, held.samples) as run:
            for index, dwell in enumerate(dwells):
                if index not in held.done_points:
                    self._point(run, index, dwell, gains=gains)

    def _servo_gains(self) -> ServoGains:
        """The gains of one run, each start command within the command margin of its target."""
        return ServoGains(1 + self.amplitude_control.command_margin)

    def _adaptive_run(self, run_id: str, grid: DwellGrid, held: RecordedRun) -> None:
        """An adaptive grid, amplitude by amplitude: the grid's frequencies (points 0, 1, ... in grid
        order), then the points the refinement adds (numbered on after the grid's), each announced
        with a :class:`~bench.engine.events.GridRefined` event before it runs.

        A resumed run skips the grid's done points; its refinement starts from the points measured
        since the resume."""
        recorded = self.channels.recorded
        output, input_ = recorded.resolve(grid.adaptive.output), recorded.resolve(grid.adaptive.input)
        if output is None or input_ is None:
            missing = [
                name for name in (grid.adaptive.output, grid.adaptive.input) if not recorded.resolve(name)
            ]
            raise RunStoppedError.fail(
                f"adaptive grid: the bench records no channel {', '.join(missing)}"
                f" (it has {', '.join(recorded.names)})"
            )
        plan = replace(grid.adaptive, output=output, input=input_)
        coarse = len(grid.freqs_hz)
        added_index = max(coarse * len(grid.amplitudes_mm), max(held.done_points, default=-1) + 1)
        with _RunRecording(self, run_id, grid, held.samples) as run:
            gains = self._servo_gains()
            for a, nominal_mm in enumerate(grid.amplitudes_mm):
                measured: dict[float, complex] = {}
                for k, freq_hz in enumerate(grid.freqs_hz):
                    if a * coarse + k not in held.done_points:
                        dwell = grid.dwell_at(freq_hz, nominal_mm)
                        verdict = self._point(run, a * coarse + k, dwell, plan=plan, gains=gains)
                        measured[freq_hz] = verdict.frf
                for _ in range(plan.max_added_points):
                    added = next_point(tuple(measured), tuple(measured.values()), plan)
                    if added is None:
                        break
                    self.bus.publish(ev.GridRefined(run_id, nominal_mm, ((added.freq_hz, added.reason),)))
                    dwell = grid.dwell_at(added.freq_hz, nominal_mm)
                    verdict = self._point(
                        run, added_index, dwell, plan=plan, added_reason=added.reason, gains=gains
                    )
                    measured[added.freq_hz] = verdict.frf
                    added_index += 1

    def _sweep_run(self, run_id: str, step: Sweep, held: RecordedRun) -> None:
        notch = self._sweep_notch(step)
        setpoint = SweepSetpoint(
            step.start_hz,
            step.end_hz,
            step.duration_s,
            step.amplitude_mm,
            spacing=step.law,
            taper_in_s=step.taper_in_s,
            taper_out_s=step.taper_out_s,
            mean_mm=self._mean(step.mean_mm),
            notch=None if notch is None else SweepNotch(notch.start_hz, notch.end_hz, notch.amplitude_mm),
        )
        with _RunRecording(self, run_id, step, held.samples) as run:

            def publish(status: str, attempt: int, span: ExcitationSpan) -> None:
                self._publish_sweep(run, setpoint, attempt, status, span, notch=notch)

            self._one_excitation(run, setpoint, step.duration_s, publish)

    def _one_excitation(
        self,
        run: _RunRecording,
        setpoint: SweepSetpoint | DriveSetpoint,
        planned_s: float,
        publish: Callable[[str, int, ExcitationSpan], None],
    ) -> None:
        """A run that is one excitation (a sweep, a road replay), its point published with
        ``publish(status, attempt, span)``: a pause interrupts it (``interrupted``), and on resume it
        runs again whole, from its start, until it is ``done``."""
        attempt = 0
        while True:
            self._checkpoint()
            attempt += 1
            try:
                span = run.excite(setpoint, planned_s=planned_s)
            except _PointInterruptedError as interrupted:
                publish(PointStatus.INTERRUPTED, attempt, interrupted.span)
                self._wait_paused()
                continue
            publish(PointStatus.DONE, attempt, span)
            return

    def _replay_run(
        self, run_id: str, step: RoadReplay, held: RecordedRun, drive: PlannedDrive | None
    ) -> None:
        """A road replay: the drive given to the controller once the run has begun, before its
        stream starts (an upload takes as long as the drive needs; a refused one ends the run), then
        played once as the run's one point, on the step's mean. A pause stops it with its taper and
        plays it again from its start on resume, as a sweep; an abort, an e-stop or a lost link end
        it as they end a sweep."""
        if drive is None:
            raise RunStoppedError.fail(f"road replay {run_id}: no drive was planned for it")
        if not getattr(self.actuator, "drive_files", False):
            raise RunStoppedError.fail(
                f"road replay {run_id}: the controller plays no drive file (docs/protocols.md, *Drive files*)"
            )
        setpoint = replace(drive.setpoint, mean_mm=self._mean(step.mean_mm))
        upload = _RunRecording(self, run_id, step, held.samples, drive=drive.record)
        upload.before_stream = lambda: self.actuator.load_drive(setpoint)
        with upload as run:

            def publish(status: str, attempt: int, span: ExcitationSpan) -> None:
                self._publish_drive(run, setpoint, attempt, status, span)

            self._one_excitation(run, setpoint, setpoint.duration_s, publish)

    def _publish_drive(
        self, run: _RunRecording, setpoint: DriveSetpoint, attempt: int, status: str, span: ExcitationSpan
    ) -> None:
        """The road replay's one point: its amplitude is the drive's largest sample about the mean,
        the achieved one the displacement's over the part between the tapers (a drive has no
        frequency: 0)."""
        z = run.displacement_between(span.hold_start, span.hold_end)
        achieved_mm = 1e3 * float(np.max(np.abs(z - np.mean(z)))) if z.size else float("nan")
        achieved = {"achieved_amplitude_mm": achieved_mm}
        self._publish_whole(run, (0.0, setpoint.peak_mm), span, status, attempt, **achieved)

    def _publish_whole(
        self,
        run: _RunRecording,
        commanded: tuple[float, float],
        span: ExcitationSpan,
        status: str,
        attempt: int,
        **measured: object,
    ) -> None:
        """The one point (index 0) of a run that is one excitation (a sweep, a road replay), as
        ``commanded``: at a frequency (a sweep's start) and an amplitude (mm), over ``span``;
        ``measured``: what the excitation showed (its achieved amplitude, a notch)."""
        freq_hz, amplitude_mm = commanded
        self.bus.publish(
            ev.PointDone(
                0,
                freq_hz,
                amplitude_mm,
                span.start,
                span.hold_start,
                span.hold_end,
                span.end,
                status=status,
                attempt=attempt,
                requested_amplitude_mm=amplitude_mm,
                commanded_amplitude_mm=amplitude_mm,
                frames_missing=run.frames_missing_between(span.hold_start, span.hold_end),
                **measured,
                run_id=run.run_id,
            )
        )

    def _tracked_run(self, run_id: str, step: TrackedDwell, held: RecordedRun) -> None:
        """A tracked dwell: its search (points 0 .. n-1, adaptive dwells measuring the ratio), the
        resonance found, then the track (point n). A resumed run searches again: the resonance
        moves. A search that finds no resonance ends the sequence (aborted) with the reason."""
        recorded = self.channels.recorded
        output, input_ = recorded.resolve(step.output), recorded.resolve(step.input)
        if output is None or input_ is None:
            missing = [name for name in (step.output, step.input) if not recorded.resolve(name)]
            raise RunStoppedError.fail(
                f"tracked dwell: the bench records no channel {', '.join(missing)}"
                f" (it has {', '.join(recorded.names)})"
            )
        if not getattr(self.actuator, "frequency_updates", False):
            raise RunStoppedError.fail(
                "tracked dwell: the controller takes no frequency update"
                " (docs/protocols.md, *Frequency updates*)"
            )
        plan = replace(step.search_plan(), output=output, input=input_)
        with _RunRecording(self, run_id, step, held.samples) as run:
            freqs = step.search_freqs_hz()
            frfs, gains = [], self._servo_gains()
            for k, freq_hz in enumerate(freqs):
                dwell = SineDwell(
                    freq_hz,
                    step.amplitude_mm,
                    taper_in_s=step.taper_in_s,
                    taper_out_s=step.taper_out_s,
                    mean_mm=step.mean_mm,
                )
                frfs.append(self._point(run, k, dwell, plan=plan, gains=gains).frf)
            resonance = find_resonance(np.array(freqs), np.array(frfs))
            if resonance is None:
                raise RunStoppedError.abort(
                    f"tracked dwell {run_id}: no resonance of {output} / {input_} within"
                    f" {freqs[0]:g}-{freqs[-1]:g} Hz (the largest ratio at an end of the search)"
                )
            self._track(run, len(freqs), step, resonance, (output, input_, self.channels.displacement))

    def _track(
        self,
        run: _RunRecording,
        index: int,
        step: TrackedDwell,
        resonance: Resonance,
        channels: tuple[str, str, str],
    ) -> None:
        """The track: one dwell at the resonance until its length or a stop rule (repeated whole
        after a pause), every look published; its point records the resonance found, the verdict
        (tracked, or stopped with the reason) and the last look's resonance as achieved."""
        attempt = 0
        while True:
            self._checkpoint()
            attempt += 1
            self.bus.publish(
                ev.PointStarted(
                    run.run_id, index, attempt, resonance.freq_hz, step.amplitude_mm, dict(self.conditions)
                )
            )

            def update(freq_hz: float) -> str | None:
                try:
                    self.actuator.update_frequency(FrequencyUpdate(freq_hz, GLIDE_S))
                except LimitError as exc:
                    return f"refused by the soft limits: {exc}"
                except CommandRejectedError as exc:
                    return str(exc)
                return None

            def looked(window: TrackWindow) -> None:
                self.bus.publish(
                    ev.ResonanceTracked(
                        run.run_id,
                        index,
                        window.sample,
                        window.drive_hz,
                        window.resonance_hz,
                        abs(window.ratio),
                        float(np.degrees(np.angle(window.ratio))),
                        window.damping_ratio,
                    )
                )

            watch = TrackWatch(
                step,
                resonance,
                sample_rate_hz=self.sample_rate_hz,
                channels=channels,
                hold_bit=self.sync_bits.hold,
                present=self.frames_present,
                update=update,
                on_window=looked,
            )
            setpoint = DwellSetpoint(
                resonance.freq_hz,
                step.amplitude_mm,
                dwell_s=0.0,
                taper_in_s=step.taper_in_s,
                taper_out_s=step.taper_out_s,
                mean_mm=self._mean(step.mean_mm),
            )
            # the track's length in cycles ends later at a lower frequency: allow for its band
            track_s = step.track_length_s * (1 + step.freq_band_pct / 100)
            planned_s = step.taper_in_s + track_s + step.taper_out_s
            dwell = SineDwell(resonance.freq_hz, step.amplitude_mm)
            point = _PointPlan(index, dwell, step.amplitude_mm)
            try:
                span = run.excite(setpoint, planned_s=planned_s, watch=watch)
            except _PointInterruptedError as interrupted:
                self._publish_point(
                    run,
                    point,
                    attempt,
                    PointStatus.INTERRUPTED,
                    command_mm=step.amplitude_mm,
                    span=interrupted.span,
                )
                self._wait_paused()
                continue
            self._publish_point(
                run,
                point,
                attempt,
                PointStatus.DONE,
                command_mm=step.amplitude_mm,
                span=span,
                note=watch.reason,
                tracked=Verdict.STOPPED if watch.reason else Verdict.TRACKED,
            )
            return

    def _sweep_notch(self, step: Sweep) -> Notch | None:
        """The notch of a sweep where a response would pass a limit's notch level, if the actuator
        notches sweeps (a controller without the notch registers: none, the limits' actions guard)."""
        if self.notching is None:
            return None
        notch = self.notching.sweep(step, self.conditions)
        if notch is not None and not getattr(self.actuator, "sweep_notches", False):
            log.warning("the controller notches no sweep: %s would be notched by %s", step, notch.limit)
            return None
        return notch

    def _publish_sweep(
        self,
        run: _RunRecording,
        setpoint: SweepSetpoint,
        attempt: int,
        status: str,
        span: ExcitationSpan,
        *,
        notch: Notch | None,
    ) -> None:
        """The sweep's one point: ``done``, or ``interrupted`` by a pause (the sweep is repeated from
        its start on resume); a notched sweep with its notch and the amplitude reached within it."""
        notched = {}
        if notch is not None:
            t1, t2 = sorted(sweep_time_s(setpoint, f) for f in (notch.start_hz, notch.end_hz))
            first, last = (run.sample_at(span.start, round(t * self.sample_rate_hz)) for t in (t1, t2))
            z = run.displacement_between(first, min(last, span.end))
            notched = {
                "notched_by": notch.limit,
                "notch_start_hz": notch.start_hz,
                "notch_end_hz": notch.end_hz,
                "notch_amplitude_mm": notch.amplitude_mm,
                "achieved_amplitude_mm": 1e3 * float(np.ptp(z)) / 2 if z.size else float("nan"),
            }
        self._publish_whole(run, (setpoint.start_hz, setpoint.amplitude_mm), span, status, attempt, **notched)

    def _hammer_run(self, run_id: str, step: HammerTest, held: RecordedRun) -> None:
        """Per blow: arm the triggered capture, ask for the blow, record the captured block.

        The blocks are recorded one after the other in the run's single Fz channel at the
        converter's rate; each blow is a point spanning its block, its hold from the trigger on."""
        samples = held.samples
        started = False
        outcome = RunOutcome("complete")
        try:
            for blow in range(step.blows):
                if blow in held.done_points:
                    continue
                self._checkpoint()
                self.acquisition.arm_capture(step.trigger_level_n, step.pre_trigger_s, step.capture_s)
                self._ask(step.strike_prompt(blow + 1))
                capture = self.acquisition.wait_capture(step.capture_s + self.timing.capture_timeout_s)
                if not started:
                    started = True
                    self.bus.publish(
                        ev.RunStarted(
                            run_id,
                            step.kind,
                            step_fields(step),
                            dict(self.conditions),
                            (HAMMER_CHANNEL,),
                            capture.rate_hz,
                        )
                    )
                n = len(capture.samples_n)
                columns = {HAMMER_CHANNEL.name: np.asarray(capture.samples_n, dtype=np.float32)}
                self.bus.publish(ev.SamplesRecorded(run_id, samples, columns))
                trigger = samples + capture.pre_trigger_samples
                self.bus.publish(
                    ev.PointDone(
                        blow, 0.0, 0.0, samples, trigger, samples + n, samples + n, run_id=run_id
                    )
                )
                samples += n
        except BaseException as exc:
            outcome = self._run_ended(exc)
            raise
        finally:
            if started:
                self._run_finished(run_id, outcome)

    def _point(
        self,
        run: _RunRecording,
        index: int,
        dwell: SineDwell,
        *,
        plan: AdaptiveDwell | None = None,
        added_reason: str = "",
        gains: ServoGains | None = None,
    ) -> DwellVerdict | None:
        """One dwell, repeated with a corrected command while the achieved amplitude is off.

        With ``plan`` the hold lasts until the dwell's online verdicts (at most ``max_hold_s``) and
        the kept attempt's verdict is returned. With ``gains`` the first command is the one the
        servo gains measured so far expect to reach the target (within the command limit), and
        every attempt adds its gain. Where a response would pass a response limit's notch level the
        dwell's amplitude is lowered to what the notching allows (its nominal one recorded as
        requested)."""
        notch = None
        if self.notching is not None:
            specimen = not isinstance(run.step, FreeRun)
            notch = self.notching.dwell(dwell.freq_hz, dwell.amplitude_mm, self.conditions, specimen=specimen)
        if notch is not None:
            nominal = dwell.requested_amplitude_mm or dwell.amplitude_mm
            dwell = replace(dwell, amplitude_mm=notch.amplitude_mm, requested_amplitude_mm=nominal)
        command_mm, corrections, attempt = dwell.amplitude_mm, 0, 0
        if gains is not None:
            command_mm = min(
                gains.command_mm(dwell.freq_hz, dwell.amplitude_mm),
                self.amplitude_control.command_cap_mm(dwell.amplitude_mm),
            )
        requested = dwell.requested_amplitude_mm or dwell.amplitude_mm
        hold_s = dwell.hold_s if plan is None else plan.max_hold_s
        while True:
            self._checkpoint()
            attempt += 1
            self.bus.publish(
                ev.PointStarted(run.run_id, index, attempt, dwell.freq_hz, command_mm, dict(self.conditions))
            )
            setpoint = DwellSetpoint(
                dwell.freq_hz,
                command_mm,
                dwell_s=hold_s,
                taper_in_s=dwell.taper_in_s,
                taper_out_s=dwell.taper_out_s,
                mean_mm=self._mean(dwell.mean_mm),
            )
            watch = (
                None
                if plan is None
                else OnlineDwell(
                    dwell.freq_hz,
                    self.sample_rate_hz,
                    plan,
                    self.channels.displacement,
                    present=self.frames_present,
                )
            )
            held = None if plan is not None else self._held_amplitude(run, index, attempt, dwell, command_mm)
            point = _PointPlan(index, dwell, requested, added_reason, notch)
            try:
                span = run.excite(
                    setpoint, planned_s=dwell.taper_in_s + hold_s + dwell.taper_out_s, watch=watch, held=held
                )
            except _PointInterruptedError as interrupted:
                self._publish_point(
                    run, point, attempt, PointStatus.INTERRUPTED, command_mm=command_mm, span=interrupted.span
                )
                self._wait_paused()
                continue
            verdict = None if watch is None else watch.verdict()
            sent_mm = command_mm
            if verdict is None:  # held within the dwell, the hold is the part after the last update's ramp
                command_mm = command_mm if held is None else held.command_mm
            achieved, lost = self._measured(run, span, dwell, verdict)
            if not lost:  # nothing is learnt from what the bench did not see
                if gains is not None:
                    gains.record(dwell.freq_hz, command_mm, achieved)
                run.check_excursion(dwell.amplitude_mm, achieved, f"point {index} attempt {attempt}")
            decision = self.amplitude_control.decide(
                dwell.amplitude_mm, command_mm, achieved, corrections, refusal=lost
            )
            status = PointStatus.DONE if decision.keep else PointStatus.REPEATED
            self._publish_point(
                run,
                point,
                attempt,
                status,
                command_mm=sent_mm,
                span=span,
                achieved_mm=achieved,
                note="; ".join(n for n in (held.refusal if held else "", decision.note) if n),
                verdict=verdict,
                held=held,
            )
            if decision.keep:
                return verdict
            command_mm, corrections = decision.corrected_mm, corrections + 1

    def _measured(
        self, run: _RunRecording, span: ExcitationSpan, dwell: SineDwell, verdict: DwellVerdict | None
    ) -> tuple[float, str]:
        """The amplitude (mm) an attempt achieved over its hold (the adaptive dwell's measured part,
        or the hold after its settling time), and why it may not be decided on (empty: it may):
        frames lost, or none of its hold left to measure because they were."""
        if verdict is not None:
            achieved = 1e3 * abs(verdict.displacement_m)
            present, span_samples = verdict.frames_present, verdict.span_samples
        else:
            fit = run.achieved_fit(span, dwell)
            achieved = amplitude_mm(fit)
            present, span_samples = (0, 0) if fit is None else (fit.frames_present, fit.span_samples)
        if span_samples:
            lost = self.frames_present.refusal_of(present, span_samples, dwell.freq_hz, self.sample_rate_hz)
        else:
            missing = run.frames_missing_between(span.hold_start, span.hold_end)
            lost = f"holds no cycle: {missing} frames lost" if missing else ""
        return achieved, f"the hold's measurement {lost}" if lost else ""

    def _held_amplitude(
        self, run: _RunRecording, index: int, attempt: int, dwell: SineDwell, command_mm: float
    ) -> HeldAmplitude | None:
        """The amplitude hold of one attempt at a fixed-timing dwell (None: the engine holds none)."""
        settings = self.amplitude_hold
        if settings is None:
            return None
        mean_mm = self._mean(dwell.mean_mm)

        def update(amplitude_mm: float) -> str | None:
            try:
                self.actuator.update_amplitude(AmplitudeUpdate(amplitude_mm, settings.ramp_s, mean_mm))
            except LimitError as exc:
                return f"refused by the soft limits: {exc}"
            except CommandOutcomeUnknownError as exc:
                log.warning("amplitude update: %s; the hold sync output tells whether it came", exc)
            except CommandRejectedError as exc:
                return str(exc)
            return None

        def checked(step: AmplitudeStep) -> None:
            if not step.lost:
                run.check_excursion(dwell.amplitude_mm, step.achieved_mm, f"point {index} attempt {attempt}")
            self.bus.publish(
                ev.AmplitudeChecked(
                    run.run_id,
                    index,
                    attempt,
                    step.sample,
                    dwell.amplitude_mm,
                    step.achieved_mm,
                    step.command_mm,
                    step.updated_mm,
                    step.refusal,
                    step.frames_missing,
                    step.lost,
                )
            )

        return HeldAmplitude(
            freq_hz=dwell.freq_hz,
            target_mm=dwell.amplitude_mm,
            command_mm=command_mm,
            settle_s=dwell.settle_s,
            hold_s=dwell.hold_s,
            settings=settings,
            control=self.amplitude_control,
            present=self.frames_present,
            sample_rate_hz=self.sample_rate_hz,
            displacement=self.channels.displacement,
            hold_bit=self.sync_bits.hold,
            update=update,
            on_step=checked,
        )

    def _publish_point(
        self,
        run: _RunRecording,
        point: _PointPlan,
        attempt: int,
        status: str,
        *,
        command_mm: float,
        span: ExcitationSpan,
        achieved_mm: float = float("nan"),
        note: str = "",
        verdict: DwellVerdict | None = None,
        held: HeldAmplitude | None = None,
        tracked: str | None = None,
    ) -> None:
        adaptive: dict[str, object] = {}  # what an adaptive dwell, a held amplitude or a notch adds
        if point.notch is not None:
            adaptive = {
                "notched_by": point.notch.limit,
                "notch_start_hz": point.notch.start_hz,
                "notch_end_hz": point.notch.end_hz,
                "notch_amplitude_mm": point.notch.amplitude_mm,
            }
        if held is not None and held.updates:
            adaptive |= {
                "amplitude_updates": held.updates,
                "held_amplitude_mm": held.command_mm,
            }
        if tracked is not None:
            adaptive |= {"verdict": tracked}
        if verdict is not None:
            measure_start = -1
            if np.isfinite(verdict.measure_start_s):
                measured_after = round(verdict.measure_start_s * self.sample_rate_hz)  # in sample times
                measure_start = run.sample_at(span.hold_start, measured_after)
            adaptive |= {
                "verdict": verdict.verdict,
                "settle_s": verdict.settle_s,
                "measure_start_sample": min(measure_start, span.hold_end),
                "magnitude_uncertainty_pct": verdict.magnitude_uncertainty_pct,
                "phase_uncertainty_deg": verdict.phase_uncertainty_deg,
            }
        self.bus.publish(
            ev.PointDone(
                point.index,
                point.dwell.freq_hz,
                point.dwell.amplitude_mm,
                span.start,
                span.hold_start,
                span.hold_end,
                span.end,
                status=status,
                attempt=attempt,
                requested_amplitude_mm=point.requested_mm,
                commanded_amplitude_mm=command_mm,
                achieved_amplitude_mm=achieved_mm,
                note=note,
                added_reason=point.added_reason,
                frames_missing=run.frames_missing_between(span.hold_start, span.hold_end),
                **adaptive,
                run_id=run.run_id,
            )
        )

    def _mean(self, step_mean_mm: float) -> float:
        return step_mean_mm or float(self.conditions.get("mean_mm", 0.0))

    # -- checkpoints ----------------------------------------------------------------------------

    def _checkpoint(self) -> None:
        """Between points: an e-stop or an abort ends the sequence, a pause waits here."""
        self._stop_if_requested()
        if self.state is RunState.PAUSING:
            self._wait_paused()

    def _stop_if_requested(self) -> None:
        """End the sequence if the table shows it e-stopped or aborting (another thread's request)."""
        self._publish_changes()
        state = self.state
        if state is RunState.ESTOPPED:
            raise RunStoppedError.estop()
        if state is RunState.ABORTING:
            raise RunStoppedError.abort(self._abort_reason)

    def _wait_paused(self) -> None:
        """At rest at the checkpoint until resumed; an abort or e-stop meanwhile ends the sequence.
        A pause withdrawn before the checkpoint (resumed while pausing) goes straight on. Within a
        run the stream goes on while paused: it is recorded and the interlocks watched (a stream
        left unread would overrun the port)."""
        if self._request(Trigger.CHECKPOINT):
            if self._recording is None:
                self.machine.wait_while(RunState.PAUSED)
            else:
                self._recording.record_while_paused()
        self._stop_if_requested()

    # -- the ending -----------------------------------------------------------------------------

    def _end(self, error: BaseException | None) -> RunOutcome:
        """End the sequence under way: the one place that does. ``error`` is what stopped its loop
        (None: it ran to its end). Stops the actuator with a taper unless nothing moves (the end
        of the sequence) or the controller has its e-stop, fires the ending's trigger into the
        table, and records the outcome: the status of the state the table lands in, and why. An
        e-stop that came first ends the sequence e-stopped whatever stopped the loop.

        Called again for the same sequence (a run that ends ends the sequence, which then reports
        the same), it returns the outcome recorded."""
        if self._outcome is not None:
            return self._outcome
        ending = self._link_lost_ending(error) or _ending_of(error)
        if ending.trigger in _STOPS_ACTUATOR:
            self._defensive_stop()
        state = self._apply_ending(ending.trigger)
        outcome = RunOutcome(RUN_STATUS[state], "e-stop" if state is RunState.ESTOPPED else ending.reason)
        self._outcome = outcome  # recorded before any subscriber runs: one that raises changes nothing
        self._publish_changes()
        if state is RunState.INTERLOCKED and ending.interlock is not None:
            self.bus.publish(ending.interlock)
        return outcome

    def _apply_ending(self, trigger: Trigger) -> RunState:
        """Fire the ending's ``trigger``; the state it leads to. An abort the engine decides itself
        (a declined prompt) is fired as its request first. The table refuses an ending only when an
        e-stop of another thread came first."""
        if self.state is not RunState.ESTOPPED:
            if trigger is Trigger.STOPPED:
                with contextlib.suppress(TransitionRefusedError):  # refused: requested already
                    self.machine.fire(Trigger.ABORT)
            try:
                return self.machine.fire(trigger)
            except TransitionRefusedError:
                if self.state is not RunState.ESTOPPED:
                    raise
        return RunState.ESTOPPED

    def _link_lost_ending(self, error: BaseException | None) -> _Ending | None:
        """A link error met while the actuator's link is lost (the connection dropped, the heartbeat
        unconfirmed) is that loss's doing: the sequence ends on the link-lost interlock, as the
        interlock check would have ended it a moment later, not as a failed command. None for any
        other ending (a refusal is the controller's answer, not a loss)."""
        if not isinstance(error, LinkError) or isinstance(error, CommandRejectedError):
            return None
        fault = self.actuator.link_fault()
        if fault is None:
            return None
        run_id = self._recording.run_id if self._recording is not None else None
        tripped = ev.InterlockTripped(ActuatorLinkLost.name, f"{fault} ({error})", run_id)
        return _Ending(Trigger.INTERLOCK, f"{tripped.name}: {tripped.reason}", tripped)

    def _run_ended(self, error: BaseException | None) -> RunOutcome:
        """How a run (a measurement step) ended: complete, or the sequence's ending (a run that does
        not complete ends the sequence)."""
        return RunOutcome("complete") if error is None else self._end(error)

    def _run_finished(self, run_id: str, outcome: RunOutcome) -> None:
        counters = self.acquisition.link_counters()
        self.bus.publish(ev.RunFinished(run_id, outcome.status, outcome.reason, counters))

    def _defensive_stop(self) -> None:
        """Taper the actuator out; a link error here is logged (the watchdog stops the controller)."""
        try:
            self.actuator.stop()
        except LinkError as exc:
            log.warning("stop not confirmed (%s); the controller's watchdog tapers it out", exc)

    # -- the table ------------------------------------------------------------------------------

    def _fire(self, trigger: Trigger) -> RunState:
        """Fire ``trigger`` (refused: TransitionRefusedError) and publish the change."""
        new = self.machine.fire(trigger)
        self._publish_changes()
        return new

    def _request(self, trigger: Trigger) -> bool:
        """Fire ``trigger`` if the present state allows it; whether it did."""
        try:
            self._fire(trigger)
        except TransitionRefusedError:
            return False
        return True

    def _publish_changes(self) -> None:
        """Publish the table's changes as StateChanged events, in the order they were made.

        While a sequence runs they are published on its thread only, as every other event: a change
        another thread requested is published at the loop's next look (within a block of frames).
        A change made while changes are being published (a subscriber's request) follows them."""
        if self._sequence_thread not in (None, threading.get_ident()):
            return
        while self.machine.has_changes():
            if not self._publishing.acquire(blocking=False):
                return  # the thread publishing now publishes this change too
            try:
                for change in self.machine.take_changes():
                    self.bus.publish(ev.StateChanged(*change))
            finally:
                self._publishing.release()


def is_measurement(step: object) -> bool:
    return isinstance(step, SineDwell | DwellGrid | FreeRun | Sweep | TrackedDwell | RoadReplay | HammerTest)


class _RunRecording:
    """One run's stream: started on entry, every frame published as samples until the exit."""

    def __init__(
        self,
        engine: Engine,
        run_id: str,
        step: object,
        first_sample: int = 0,
        drive: Mapping[str, Any] | None = None,
    ) -> None:
        """``first_sample``: how many samples the run held already (a resumed run goes on after
        them); ``drive``: a road replay's drive as the run records it."""
        self.engine = engine
        self.run_id = run_id
        self.step = step
        self.drive = drive or {}
        #: called once the run has begun, before its stream starts (a road replay's upload)
        self.before_stream: Callable[[], None] | None = None
        self.samples = first_sample  # the run's samples so far: the index of the next one
        # the acquisition's sample time since this recording began: the samples received and those
        # the link reported lost (what the watchdogs count, so that a link that lets only a few
        # frames through cannot hold them off)
        self.elapsed_samples = 0
        self.displacement: list[np.ndarray] = []
        self.seq: list[np.ndarray] = []  # each block's frame counters, beside its displacement
        self._gaps: list[tuple[int, int]] = []  # (run sample a gap came before, frames missing)
        self._subscription = None
        self._last_status_s = -np.inf
        self._stream_started_s = 0.0
        # open host stall: unread s, arrival, end sample, frames missing before it
        self._stall: tuple[float, float, int, int] | None = None
        self._limits_acted: set[str] = set()  # the limits milder than an interlock published this excitation

    def __enter__(self) -> _RunRecording:
        e = self.engine
        e.bus.publish(
            ev.RunStarted(
                self.run_id,
                RunKind.of_step(self.step.kind),
                step_fields(self.step),
                dict(e.conditions),
                e.channels.specs(),
                e.sample_rate_hz,
                self.drive,
            )
        )
        try:
            if self.before_stream is not None:
                self.before_stream()
            self._start_stream()
            e._recording = self
        except BaseException as exc:  # the run began: it ends too, with the sequence's ending
            if self._subscription is not None:
                self._subscription.close()
            e._run_finished(self.run_id, e._run_ended(exc))
            raise
        return self

    def _start_stream(self) -> None:
        e = self.engine
        if e.tare == "before_each_run":
            e.acquisition.tare()
        backlog = max(1, round(e.timing.backlog_s * e.sample_rate_hz))
        self._subscription = e.acquisition.subscribe(lossless=True, max_frames=backlog)
        e.acquisition.start_stream()
        self._stream_started_s = e._clock()

    def __exit__(self, exc_type, exc, tb) -> None:
        """End the run: the sequence's ending first, if the run did not complete (the actuator
        stopped before the stream), then the stream stopped and the run's end published."""
        outcome = self.engine._run_ended(exc)
        try:
            self._stop_stream()
        except LinkError as stop_error:
            log.warning("stopping the WFS stream failed: %s", stop_error)
        finally:
            self.engine._recording = None
            self._subscription.close()
            self._close_host_stall()  # one still open: published with the frames missing since, no trip
            self.engine._run_finished(self.run_id, outcome)

    def _stop_stream(self) -> None:
        """Stop the stream and record every frame sent before it stopped.

        The frames are recorded while the STOP awaits its reply: the reply comes on the same line
        behind the frames still in flight, and the reader hands those over to this run's lossless
        subscription first; left undrained, a full subscription would hold the reader and the reply
        with it."""
        acquisition, timeout_s = self.engine.acquisition, self.engine.timing.block_timeout_s
        stopped = threading.Event()
        failure: list[LinkError] = []

        def stop() -> None:
            try:
                acquisition.stop_stream()
            except LinkError as exc:
                failure.append(exc)
            finally:
                stopped.set()

        threading.Thread(target=stop, name="wfs-stop", daemon=True).start()
        while not stopped.is_set():
            if (block := self._subscription.get_all(timeout_s)) is not None:
                self._record(block)
                self._follow_host_stall(block, stopping=True)
        if failure:
            raise failure[0]
        while (block := self._subscription.get_all(timeout_s)) is not None:
            self._record(block)
            self._follow_host_stall(block, stopping=True)

    def _record(self, block) -> Mapping[str, np.ndarray]:
        columns = self.engine.channels.columns(block.frames)
        gaps = tuple((g.index, g.missing) for g in block.gaps)
        self.engine.bus.publish(ev.SamplesRecorded(self.run_id, self.samples, columns, gaps))
        self.displacement.append(np.asarray(columns[self.engine.channels.displacement], dtype=float))
        self.seq.append(np.asarray(columns["seq"]))
        self._gaps.extend((self.samples + index, missing) for index, missing in gaps)
        self.samples += len(block.frames)
        self.elapsed_samples += len(block.frames) + sum(missing for _, missing in gaps)
        return columns

    def achieved_fit(self, span: ExcitationSpan, dwell: SineDwell) -> SineFit | None:
        """The displacement's fit over the hold after its settling time, on the frames' true times
        (None: too short). The window's time runs from the settling time's end, counted in sample
        times from the hold's first frame, to the hold's end."""
        fs = self.engine.sample_rate_hz
        z = self.displacement_between(span.hold_start, span.hold_end)
        if z.size == 0:
            return None
        # the frame after the hold, where there is one, tells the hold's true end
        offsets = frame_offsets(self.seq_between(span.hold_start, span.hold_end + 1))
        end = int(offsets[-1]) + (1 if len(offsets) == len(z) else 0)
        offsets = offsets[: len(z)]
        start = min(round(dwell.settle_s * fs), end)
        kept = offsets >= start
        return fit_latest_cycles(z[kept], offsets[kept], fs, dwell.freq_hz, start=start, end=end)

    def displacement_between(self, start: int, stop: int) -> np.ndarray:
        """The recorded displacement from run sample ``start`` to ``stop``."""
        return self._between(self.displacement, start, stop, float)

    def seq_between(self, start: int, stop: int) -> np.ndarray:
        """The frame counters of run samples ``start`` to ``stop``."""
        return self._between(self.seq, start, stop, np.int64)

    def _between(self, blocks: list[np.ndarray], start: int, stop: int, dtype: type) -> np.ndarray:
        parts, end = [], self.samples
        for block in reversed(blocks):
            first = end - len(block)
            if first < stop and end > start:
                parts.append(block[max(start - first, 0) : stop - first])
            if first <= start:
                break
            end = first
        return np.concatenate(parts[::-1]).astype(dtype) if parts else np.zeros(0, dtype)

    def sample_at(self, first: int, offset: int) -> int:
        """The run sample of the first frame ``offset`` sample times or more after run sample
        ``first`` (by the frame counter: frames lost between count as time); the run's next sample
        when none has come yet."""
        offsets = frame_offsets(self.seq_between(first, self.samples))
        return first + int(np.searchsorted(offsets, offset))

    def frames_missing_between(self, start: int, stop: int) -> int:
        """Frames lost on the link from run sample ``start`` to ``stop``, the gaps at either end
        included (frames lost just before a hold's first recorded frame, or its last, may have been
        the hold's own: their sync bits were lost with them)."""
        return sum(missing for index, missing in self._gaps if start <= index <= stop)

    def check_excursion(self, target_mm: float, achieved_mm: float, where: str) -> None:
        """A measured amplitude beyond the target by more than the amplitude control's excursion
        tolerance is a limit reached, acted on with its configured action."""
        control = self.engine.amplitude_control
        if reason := control.excursion(target_mm, achieved_mm):
            self._act(Trip(AMPLITUDE_EXCURSION, f"{where}: {reason}", control.excursion_action))

    def excite(
        self,
        setpoint: DwellSetpoint | SweepSetpoint | DriveSetpoint,
        *,
        planned_s: float,
        watch: OnlineDwell | None = None,
        held: HeldAmplitude | None = None,
    ) -> ExcitationSpan:
        """Configure, start and record one excitation until the controller's active output falls.

        ``watch`` follows an adaptive dwell's hold block by block: once it is done the excitation is
        stopped with its taper (the hold ends where the controller's hold output falls). ``held``
        holds a dwell's amplitude within its hold, block by block (each update it makes lengthens
        the excitation's planned duration). A pause
        request (the table ``pausing``) stops it with a taper and raises
        :class:`_PointInterruptedError` once it is at rest; an abort (``aborting``) tapers it out and
        ends the run; an e-stop or a tripped interlock ends the run."""
        e = self.engine
        e.actuator.configure(setpoint)
        e.actuator.start()
        self._limits_acted = set()
        tracker = SpanTracker(e.sync_bits.active, e.sync_bits.hold)
        # the start watchdog waits for start_timeout_s of wall time and of samples, whichever is
        # later: a consumer behind the stream sees the start only once it has read up to it
        start_deadline_s = e._clock() + e.timing.start_timeout_s
        start_deadline = self.elapsed_samples + round(e.timing.start_timeout_s * e.sample_rate_hz)
        overrun = round((planned_s + e.timing.end_margin_s) * e.sample_rate_hz)
        end_deadline: int | None = None  # in elapsed samples, once the start is seen
        stopping = False  # tapered out early, on a pause or an abort request
        start_seq: int | None = None  # the frame counter where the excitation started
        while not tracker.ended:
            columns = self._next_columns()
            first = self.samples - len(columns.get("status", ()))
            tracker.feed(first, columns.get("status", np.zeros(0, int)))
            if tracker.started and end_deadline is None:
                end_deadline = self.elapsed_samples - (self.samples - tracker.start) + overrun
            if watch is not None and not watch.done:
                watch.feed(first, columns, tracker.hold_start, tracker.hold_end)
                if watch.done and not stopping:
                    e._defensive_stop()
            if held is not None and not stopping:
                held.feed(first, columns)
            e._publish_changes()
            state = e.state
            if state is RunState.ESTOPPED:
                raise RunStoppedError.estop()
            freq_hz = None
            if tracker.started and columns:
                if start_seq is None:  # the excitation's time runs by the frame counter: gaps count
                    start_seq = int(self.seq_between(tracker.start, tracker.start + 1)[0])
                t_s = frame_offsets(columns["seq"], start_seq) / e.sample_rate_hz
                freq_hz = excitation_frequency_hz(setpoint, t_s)
            self._guard(columns, freq_hz=freq_hz)
            if not stopping and state in (RunState.PAUSING, RunState.ABORTING):
                stopping = True
                e._defensive_stop()
            elapsed = self.elapsed_samples
            if not tracker.started and e._clock() > start_deadline_s and elapsed > start_deadline:
                self._trip("excitation watchdog", "the controller did not start the excitation")
            extension = 0 if held is None else round(held.extension_s * e.sample_rate_hz)
            if end_deadline is not None and not tracker.ended and elapsed > end_deadline + extension:
                self._trip("excitation watchdog", "the excitation did not end when planned")
        # the controller's own stop (its e-stop button, a tripped limit, its watchdog) also ends the
        # excitation early: its status, read now, tells that from the planned end
        self._guard({}, read_status=True)
        if stopping:  # ended by an abort (or an e-stop since); else paused, or resumed meanwhile
            e._stop_if_requested()
            raise _PointInterruptedError(tracker.span)
        return tracker.span

    def _next_columns(self) -> Mapping[str, np.ndarray]:
        """The next block's columns, recorded; empty columns when none came in time."""
        e = self.engine
        block = self._subscription.get_all(e.timing.block_timeout_s)
        if block is None:
            return {}
        columns = self._record(block)
        self._follow_host_stall(block)
        return columns

    def record_while_paused(self) -> None:
        """At rest in a pause: the stream is recorded and the interlocks are watched until the state
        leaves ``paused`` (resumed, aborting, e-stopped)."""
        while self.engine.state is RunState.PAUSED:
            self._guard(self._next_columns())

    def _follow_host_stall(self, block: SampleBlockLike, *, stopping: bool = False) -> None:
        """Host stalls, from the blocks' port timing: a block the port went unread ``unread_s``
        before (the host busy, not the link) opens a stall once that reaches ``host_stall_s``. The
        frames lost to it show as gaps in that block or in those read right after it (the port
        first gives the bytes it kept, then what came after the bytes it dropped): the stall takes
        the gaps of the blocks that arrived within ``host_stall_s`` of its own, or that begin within
        ``host_stall_s`` of samples after it (the device's clock, which a host slow to resume cannot
        stretch: the first frames after the kept bytes carry the overrun's gap however late they are
        read), and is published at its first gap, or once a later block comes, or at the run's end.
        Frames lost stop the run, unless ``stopping``: a block recorded while the stream stops, the
        run's ending decided already, only has its stall published.

        ``_stall`` holds the stall's length, its block's arrival and end (a run sample), and the
        frames the recording had counted missing before it: what it lost is what the recording
        counts missing beyond that when it closes (:meth:`_close_host_stall`), so blocks recorded
        and not followed here count too."""
        e = self.engine
        missing = self.elapsed_samples - self.samples  # frames missing so far, this block's included
        before = missing - sum(g.missing for g in block.gaps)
        if self._stall is not None:
            _, arrived_s, end, _ = self._stall
            late = block.arrived_s - arrived_s > e.timing.host_stall_s
            if late and self.samples - len(block.frames) - end > e.timing.host_stall_s * e.sample_rate_hz:
                self._close_host_stall(before, trips=not stopping)  # too late to be the stall's
        if block.unread_s >= e.timing.host_stall_s:
            self._close_host_stall(before, trips=not stopping)
            self._stall = (block.unread_s, block.arrived_s, self.samples, before)
        if self._stall is not None and missing > self._stall[3]:
            self._close_host_stall(missing, trips=not stopping)

    def _close_host_stall(self, missing: int | None = None, *, trips: bool = True) -> None:
        """Publish the open host stall, if any, with the frames lost to it: those the recording
        counted missing from its block up to ``missing`` (its count when the stall closes). It ends
        the run as the ``host stalled`` interlock when frames were lost, if it ``trips``.

        Without ``missing`` the run is ending (its exit): the stall takes every frame the recording
        counted missing since, the blocks recorded while the stream stopped included, where the
        port's overrun shows when another ending came first (a host stopped for longer than the
        controller's watchdog can find the controller tripped before the engine has read past the
        stall's first block; the stream stops right after, so a loss of the link's own in those
        moments would be counted with it), and it stops nothing: the run has its ending already."""
        if self._stall is None:
            return
        stalled_s, _, end, before = self._stall
        self._stall = None
        ending = missing is None
        lost = (self.elapsed_samples - self.samples if ending else missing) - before
        counted = not ending or lost > 0 or self.samples > end  # frames after the stall's block read
        self.engine.bus.publish(ev.HostStalled(self.run_id, stalled_s, lost, counted))
        if lost and trips and not ending:
            self._trip(
                "host stalled",
                f"the host left the WFS port unread for {stalled_s:.2f} s and {lost} frames were lost"
                " (a busy machine, not the link)",
            )

    def _guard(
        self,
        columns: Mapping[str, np.ndarray],
        *,
        read_status: bool = False,
        freq_hz: np.ndarray | None = None,
    ) -> None:
        """Check every interlock and limit (``freq_hz``: the excitation's frequency at each sample of
        ``columns``, None while none runs); the most severe that trips acts (:meth:`_act`).

        The controller's status is read every ``status_period_s``, or now when ``read_status``."""
        e = self.engine
        now = e._clock()
        controller = None
        if read_status or now - self._last_status_s >= e.timing.status_period_s:
            self._last_status_s = now
            try:
                controller = e.actuator.read_status()
            except LinkError as exc:
                log.warning("status read failed: %s", exc)
        # the link's silence is judged at the port, bounded by this stream's age (bytes of an
        # earlier stream do not count): bytes waiting there unread are the host's delay
        silence_s = 0.0 if columns else min(e.acquisition.link_silence_s(), now - self._stream_started_s)
        seen = Observation(columns, controller, e.actuator.link_fault(), silence_s, freq_hz)
        for trip in trips(e.interlocks, seen):
            self._act(trip)

    def _act(self, trip: Trip) -> None:
        """Do what a tripped check's action says: an interlock ends the run interlocked, a stop ends
        the sequence aborted (both after a taper); a hold pauses the sequence (the point under way
        tapered out, repeated on resume); an indication is recorded only. Each limit milder than an
        interlock is published once per excitation."""
        if trip.action is LimitAction.INTERLOCK:
            self._trip(trip.name, trip.reason)
        if trip.name in self._limits_acted:
            return
        self._limits_acted.add(trip.name)
        e = self.engine
        e.bus.publish(ev.LimitReached(self.run_id, trip.name, trip.reason, str(trip.action)))
        if trip.action is LimitAction.STOP:
            raise RunStoppedError.abort(f"{trip.name} (stop): {trip.reason}")
        if trip.action is LimitAction.HOLD:
            e.request_pause()

    def _trip(self, name: str, reason: str) -> NoReturn:
        """End the run on a tripped interlock: the ending stops the actuator with a taper and
        publishes the interlock. An e-stop requested meanwhile ends it as e-stopped instead: the
        table shows the e-stop before it is sent, so a controller seen e-stopped after the loop last
        looked at the state (the operator's thread sent it in between) is the e-stop's doing, not
        an interlock."""
        raise RunStoppedError.interlock_tripped(ev.InterlockTripped(name, reason, self.run_id))
