"""The run engine: executes a sequence's steps on the bench, point by point.

The loop reads top to bottom: a sequence is split into its steps; a measurement step (dwell grid,
free run, sweep) is one *run*, recorded from the start of its stream to its end; each dwell of a
grid is one *point*. A point is located in the acquisition's samples by the controller's sync
outputs (:mod:`bench.engine.points`), so lengths are counted in samples and the wall clock serves
only timeouts and watchdogs. Between points lies the checkpoint where a pause takes effect.

Requests come from other threads (front ends) and only set flags, except the e-stop, which is sent
to the controller at once from the requesting thread. Everything the engine does is published as an
event; storage, analysis and displays are subscribers.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any, NoReturn

import numpy as np

from bench.engine import events as ev
from bench.engine.amplitude import AmplitudeControl, ServoGains, achieved_amplitude_mm
from bench.engine.channels import FrameChannels
from bench.engine.contracts import Acquisition, Actuator, Operator, ResumePlan
from bench.engine.interlocks import Interlock, Observation, first_trip
from bench.engine.online import DwellVerdict, OnlineDwell
from bench.engine.points import ExcitationSpan, SpanTracker
from bench.engine.refinement import next_point
from bench.engine.run_ids import run_id
from bench.engine.states import RUN_STATUS, RunState, StateMachine, TransitionRefusedError, Trigger
from drivers.errors import CommandRejectedError, LinkError
from drivers.setpoints import DwellSetpoint, SweepSetpoint
from sequences import (
    AdaptiveDwell,
    AnswerError,
    DwellGrid,
    FreeRun,
    HammerTest,
    Hydraulics,
    MeanPosition,
    Prompt,
    Sequence,
    SineDwell,
    Sweep,
    Tare,
    step_fields,
)
from sequences.channels import STANDARD_CHANNELS, Role

log = logging.getLogger(__name__)

#: The recorded kind of a run, by the kind of its step (a single dwell is a grid of one point).
RUN_KIND = {"sine_dwell": "dwell_grid"}
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
class EngineTiming:
    """Bounds (s): how long to wait for a block of frames, how often to read the controller's status
    during an excitation, how long after START the excitation must show on the sync bits (wall
    time and samples, whichever is later: frames recorded before the START took effect may still
    be queued), the margin (s of samples) beyond its planned duration after which a started
    excitation counts as hung (samples received or reported lost count alike), and how long a
    triggered capture may take to arrive after the blow was asked for (beyond its own length), and
    how long a reset may take (the controller tapers out of an e-stop before it takes commands).

    ``backlog_s`` (s of samples): how far the acquisition may run ahead of the engine before the
    reader waits for it. A real acquisition cannot wait (its frames overflow once the serial port's
    buffer is full), so the default covers the longest stall of the engine; a simulated one that
    waits for its host needs little, and a short backlog keeps it from simulating rest the engine
    records while it is busy between points."""

    block_timeout_s: float = 0.05
    status_period_s: float = 0.2
    start_timeout_s: float = 5.0
    end_margin_s: float = 5.0
    capture_timeout_s: float = 10.0
    reset_timeout_s: float = 10.0
    backlog_s: float = 2.0


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


class RunStoppedError(Exception):
    """The sequence cannot go on: ``state`` is the engine state it ended in, ``reason`` why."""

    def __init__(self, state: RunState, reason: str) -> None:
        super().__init__(reason)
        self.state = state
        self.reason = reason


@dataclass(frozen=True)
class _PointPlan:
    """What a point's attempts share: its index, dwell, nominal amplitude and why it was added."""

    index: int
    dwell: SineDwell
    requested_mm: float
    added_reason: str = ""


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
        timing: EngineTiming | None = None,
        bus: ev.EventBus | None = None,
        tare: str = "never",
        bench_kind: str = "shaker",
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``tare``: "before_each_run" (the WFS is tared, at rest, before each run's stream starts),
        "once" (at the start of each sequence) or "never"; ``bench_kind``: "shaker" or
        "four_post", recorded with every run's conditions."""
        self.actuator = actuator
        self.acquisition = acquisition
        self.operator = operator
        self.channels = channels
        self.interlocks = interlocks
        self.sync_bits = sync_bits
        self.sample_rate_hz = sample_rate_hz
        self.amplitude_control = amplitude_control or AmplitudeControl()
        self.timing = timing or EngineTiming()
        self.bus = bus or ev.EventBus()
        if tare not in ("before_each_run", "once", "never"):
            raise ValueError(f"tare policy {tare!r} is not before_each_run, once or never")
        self.tare = tare
        self.bench_kind = bench_kind
        self._clock = clock
        self.machine = StateMachine(on_change=self._state_changed)
        self._pause = threading.Event()
        self._resume = threading.Event()
        self._abort = threading.Event()
        self._abort_reason = ABORT_REASON
        self._estop = threading.Event()
        self.conditions: dict[str, Any] = {}

    # -- requests (any thread) ----------------------------------------------------------------

    @property
    def state(self) -> RunState:
        return self.machine.state

    def request_pause(self) -> None:
        """Pause at the next checkpoint; the point under way is stopped (tapered) and repeated."""
        self._resume.clear()
        self._pause.set()

    def request_resume(self) -> None:
        self._pause.clear()
        self._resume.set()

    def request_abort(self, reason: str = ABORT_REASON) -> None:
        """Taper out and end the sequence as aborted, ``reason`` recorded with the run (who or what
        asked: the operator, a signal); the data recorded so far is kept."""
        self._abort_reason = reason
        self._abort.set()
        self._resume.set()

    def request_estop(self) -> None:
        """E-stop now: the controller is told from this thread, without waiting for the loop."""
        self._estop.set()
        self._resume.set()
        try:
            self.actuator.estop()
        finally:
            if self.machine.allows(Trigger.ESTOP):
                self.machine.fire(Trigger.ESTOP)

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
        self.machine.fire(trigger)

    def reset(self) -> None:
        """Release an interlock or e-stop once the cause is cleared. Returns once the controller
        has come to rest at hydraulics low: out of an e-stop it tapers first and refuses commands
        meanwhile (its status is read every ``status_period_s``). A controller still moving after
        ``reset_timeout_s`` raises TimeoutError and leaves the engine where it was.

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
        self._force_state(Trigger.RESET)  # a controller's own interlock may come while the engine rests
        self._estop.clear()

    # -- the sequence -------------------------------------------------------------------------

    def run(
        self,
        sequence: Sequence,
        *,
        sequence_text: str = "",
        config_text: str = "",
        resume: ResumePlan | None = None,
    ) -> RunOutcome:
        """Run ``sequence`` to its end or until stopped. Nothing a device raises escapes: it ends the
        run, and the outcome says how and why."""
        self._pause.clear()
        self._abort.clear()
        self._abort_reason = ABORT_REASON
        self._estop.clear()
        self.conditions = {"bench": self.bench_kind}
        self.machine.fire(Trigger.START)
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
        status, reason = "complete", ""
        try:
            if self.tare == "once":
                self.acquisition.tare()
            for index in self._steps_to_run(sequence, resume):
                self._execute(sequence, index, resume)
            self.machine.fire(Trigger.FINISH)
        except RunStoppedError as stop:
            status, reason = RUN_STATUS.get(stop.state, "failed"), stop.reason
        except LinkError as exc:
            # a refused command is the controller's answer ("controller refused ..."), not a link fault
            refused = isinstance(exc, CommandRejectedError)
            status, reason = "failed", str(exc) if refused else f"link error: {exc}"
            self._defensive_stop()
            self._force_state(Trigger.INTERLOCK)
        except BaseException as exc:  # a crash (or Ctrl-C) still stops the actuator and marks the end
            self._defensive_stop()
            self._force_state(Trigger.INTERLOCK)
            self.bus.publish(ev.SequenceFinished("failed", f"{type(exc).__name__}: {exc}"))
            raise
        self.bus.publish(ev.SequenceFinished(status, reason))
        return RunOutcome(status, reason)

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
            if resume is None:
                self._measure(run_id, step, RecordedRun())
            elif not resume.run_complete(run_id):
                held = RecordedRun(resume.completed_points(run_id), resume.recorded_samples(run_id))
                self._measure(run_id, step, held)
        else:
            raise RunStoppedError(
                RunState.INTERLOCKED, f"step {index}: {type(step).__name__} is not supported"
            )

    def _measure(self, run_id: str, step: object, held: RecordedRun) -> None:
        if isinstance(step, Sweep):
            self._sweep_run(run_id, step, held)
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
            self._abort_now(f"no valid answer to prompt {prompt.id!r}: {exc}")
        if prompt.answer == "confirm" and answer is False:
            self.bus.publish(ev.PromptAnswered(prompt.id, prompt.text, answer, prompt.unit))
            self._abort_now(f"the operator declined: {prompt.text}")
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
        with _RunRecording(self, run_id, step, held.samples) as run:
            for index, dwell in enumerate(dwells):
                if index not in held.done_points:
                    self._point(run, index, dwell)

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
            raise RunStoppedError(
                RunState.INTERLOCKED,
                f"adaptive grid: the bench records no channel {', '.join(missing)}"
                f" (it has {', '.join(recorded.names)})",
            )
        plan = replace(grid.adaptive, output=output, input=input_)
        coarse = len(grid.freqs_hz)
        added_index = max(coarse * len(grid.amplitudes_mm), max(held.done_points, default=-1) + 1)
        with _RunRecording(self, run_id, grid, held.samples) as run:
            gains = ServoGains()
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
        setpoint = SweepSetpoint(
            step.start_hz,
            step.end_hz,
            step.duration_s,
            step.amplitude_mm,
            spacing=step.law,
            taper_in_s=step.taper_in_s,
            taper_out_s=step.taper_out_s,
            mean_mm=self._mean(step.mean_mm),
        )
        with _RunRecording(self, run_id, step, held.samples) as run:
            attempt = 0
            while True:
                self._checkpoint()
                attempt += 1
                try:
                    span = run.excite(setpoint, planned_s=step.duration_s)
                except _PointInterruptedError as interrupted:
                    self._publish_sweep(run_id, step, attempt, "interrupted", interrupted.span)
                    self._wait_paused()
                    continue
                self._publish_sweep(run_id, step, attempt, "done", span)
                return

    def _publish_sweep(
        self, run_id: str, step: Sweep, attempt: int, status: str, span: ExcitationSpan
    ) -> None:
        """The sweep's one point: ``done``, or ``interrupted`` by a pause (the sweep is repeated from
        its start on resume)."""
        self.bus.publish(
            ev.PointDone(
                0,
                step.start_hz,
                step.amplitude_mm,
                span.start,
                span.hold_start,
                span.hold_end,
                span.end,
                status=status,
                attempt=attempt,
                requested_amplitude_mm=step.amplitude_mm,
                commanded_amplitude_mm=step.amplitude_mm,
                run_id=run_id,
            )
        )

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
            outcome = run_outcome(exc)
            raise
        finally:
            if started:
                counters = self.acquisition.link_counters()
                self.bus.publish(ev.RunFinished(run_id, outcome.status, outcome.reason, counters))

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
        every attempt adds its gain."""
        command_mm, corrections, attempt = dwell.amplitude_mm, 0, 0
        if gains is not None:
            command_mm = min(
                gains.command_mm(dwell.freq_hz, dwell.amplitude_mm), self.amplitude_control.max_command_mm
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
                else OnlineDwell(dwell.freq_hz, self.sample_rate_hz, plan, self.channels.displacement)
            )
            point = _PointPlan(index, dwell, requested, added_reason)
            try:
                span = run.excite(
                    setpoint, planned_s=dwell.taper_in_s + hold_s + dwell.taper_out_s, watch=watch
                )
            except _PointInterruptedError as interrupted:
                self._publish_point(
                    run, point, attempt, "interrupted", command_mm=command_mm, span=interrupted.span
                )
                self._wait_paused()
                continue
            verdict = None if watch is None else watch.verdict()
            if verdict is None:
                achieved = run.achieved_amplitude_mm(span, dwell)
            else:
                achieved = 1e3 * abs(verdict.displacement_m)
            if gains is not None:
                gains.record(dwell.freq_hz, command_mm, achieved)
            decision = self.amplitude_control.decide(dwell.amplitude_mm, command_mm, achieved, corrections)
            status = "done" if decision.keep else "repeated"
            self._publish_point(
                run,
                point,
                attempt,
                status,
                command_mm=command_mm,
                span=span,
                achieved_mm=achieved,
                note=decision.note,
                verdict=verdict,
            )
            if decision.keep:
                return verdict
            command_mm, corrections = decision.corrected_mm, corrections + 1

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
    ) -> None:
        adaptive = {}
        if verdict is not None:
            measure_start = -1
            if np.isfinite(verdict.measure_start_s):
                measure_start = span.hold_start + round(verdict.measure_start_s * self.sample_rate_hz)
            adaptive = {
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
                **adaptive,
                run_id=run.run_id,
            )
        )

    def _mean(self, step_mean_mm: float) -> float:
        return step_mean_mm or float(self.conditions.get("mean_mm", 0.0))

    # -- checkpoints, stops -------------------------------------------------------------------

    def _checkpoint(self) -> None:
        """Between points: honour an e-stop, an abort or a pause request."""
        if self._estop.is_set():
            raise RunStoppedError(RunState.ESTOPPED, "e-stop")
        if self._abort.is_set():
            self._abort_now()
        if self._pause.is_set():
            self._wait_paused()

    def _wait_paused(self) -> None:
        """At rest between points until resumed (or aborted / e-stopped)."""
        if not self._pause.is_set():
            return
        self.machine.fire(Trigger.PAUSE)
        self._resume.wait()
        if self._estop.is_set():
            raise RunStoppedError(RunState.ESTOPPED, "e-stop")
        if self._abort.is_set():
            self._abort_now()
        self.machine.fire(Trigger.RESUME)

    def _abort_now(self, reason: str | None = None) -> NoReturn:
        """End the sequence as aborted, with a taper (``reason`` by default the requested abort's);
        as e-stopped if an e-stop came first (an e-stop pressed while a prompt waited, say, and the
        prompt then left unanswered)."""
        reason = reason or self._abort_reason
        if self._estop.is_set():
            raise RunStoppedError(RunState.ESTOPPED, "e-stop")
        self._force_state(Trigger.ABORT)
        self._defensive_stop()
        self.machine.fire(Trigger.STOPPED)
        raise RunStoppedError(RunState.ABORTED, reason)

    def _defensive_stop(self) -> None:
        """Taper the actuator out; a link error here is logged (the watchdog stops the controller)."""
        try:
            self.actuator.stop()
        except LinkError as exc:
            log.warning("stop not confirmed (%s); the controller's watchdog tapers it out", exc)

    def _force_state(self, trigger: Trigger) -> None:
        if self.machine.allows(trigger):
            self.machine.fire(trigger)

    def _state_changed(self, old: RunState, new: RunState, trigger: Trigger) -> None:
        self.bus.publish(ev.StateChanged(old, new, trigger))


def run_outcome(exc: BaseException | None) -> RunOutcome:
    """How a run ended, from what ended it: nothing, a stop (its state and reason), or an error."""
    if exc is None:
        return RunOutcome("complete")
    if isinstance(exc, RunStoppedError):
        return RunOutcome(RUN_STATUS.get(exc.state, "failed"), exc.reason)
    return RunOutcome("failed", f"{type(exc).__name__}: {exc}")


def is_measurement(step: object) -> bool:
    return isinstance(step, SineDwell | DwellGrid | FreeRun | Sweep | HammerTest)


class _RunRecording:
    """One run's stream: started on entry, every frame published as samples until the exit."""

    def __init__(self, engine: Engine, run_id: str, step: object, first_sample: int = 0) -> None:
        """``first_sample``: how many samples the run held already (a resumed run goes on after them)."""
        self.engine = engine
        self.run_id = run_id
        self.step = step
        self.samples = first_sample  # the run's samples so far: the index of the next one
        # the acquisition's sample time since this recording began: the samples received and those
        # the link reported lost (what the watchdogs count, so that a link that lets only a few
        # frames through cannot hold them off)
        self.elapsed_samples = 0
        self.displacement: list[np.ndarray] = []
        self._subscription = None
        self._last_status_s = -np.inf
        self._last_frame_s = 0.0

    def __enter__(self) -> _RunRecording:
        e = self.engine
        e.bus.publish(
            ev.RunStarted(
                self.run_id,
                RUN_KIND.get(self.step.kind, self.step.kind),
                step_fields(self.step),
                dict(e.conditions),
                e.channels.specs(),
                e.sample_rate_hz,
            )
        )
        if e.tare == "before_each_run":
            e.acquisition.tare()
        backlog = max(1, round(e.timing.backlog_s * e.sample_rate_hz))
        self._subscription = e.acquisition.subscribe(lossless=True, max_frames=backlog)
        e.acquisition.start_stream()
        self._last_frame_s = e._clock()
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        e = self.engine
        outcome = run_outcome(exc)
        try:
            self._stop_stream()
        except LinkError as stop_error:
            log.warning("stopping the WFS stream failed: %s", stop_error)
        finally:
            self._subscription.close()
            counters = e.acquisition.link_counters()
            e.bus.publish(ev.RunFinished(self.run_id, outcome.status, outcome.reason, counters))

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
        if failure:
            raise failure[0]
        while (block := self._subscription.get_all(timeout_s)) is not None:
            self._record(block)

    def _record(self, block) -> Mapping[str, np.ndarray]:
        columns = self.engine.channels.columns(block.frames)
        gaps = tuple((g.index, g.missing) for g in block.gaps)
        self.engine.bus.publish(ev.SamplesRecorded(self.run_id, self.samples, columns, gaps))
        self.displacement.append(np.asarray(columns[self.engine.channels.displacement], dtype=float))
        self.samples += len(block.frames)
        self.elapsed_samples += len(block.frames) + sum(missing for _, missing in gaps)
        return columns

    def achieved_amplitude_mm(self, span: ExcitationSpan, dwell: SineDwell) -> float:
        """The displacement's amplitude over the hold after its settling time (NaN: too short)."""
        settle = round(dwell.settle_s * self.engine.sample_rate_hz)
        start = min(span.hold_start + settle, span.hold_end)
        z = self._displacement(start, span.hold_end)
        return achieved_amplitude_mm(z, self.engine.sample_rate_hz, dwell.freq_hz)

    def _displacement(self, start: int, stop: int) -> np.ndarray:
        """The recorded displacement from run sample ``start`` to ``stop``."""
        parts, end = [], self.samples
        for block in reversed(self.displacement):
            first = end - len(block)
            if first < stop and end > start:
                parts.append(block[max(start - first, 0) : stop - first])
            if first <= start:
                break
            end = first
        return np.concatenate(parts[::-1]) if parts else np.zeros(0)

    def excite(
        self, setpoint: DwellSetpoint | SweepSetpoint, *, planned_s: float, watch: OnlineDwell | None = None
    ) -> ExcitationSpan:
        """Configure, start and record one excitation until the controller's active output falls.

        ``watch`` follows an adaptive dwell's hold block by block: once it is done the excitation is
        stopped with its taper (the hold ends where the controller's hold output falls). A pause
        request stops it with a taper and raises :class:`_PointInterruptedError` once it is at rest;
        an abort tapers it out and ends the run; an e-stop or a tripped interlock ends the run."""
        e = self.engine
        e.actuator.configure(setpoint)
        e.actuator.start()
        tracker = SpanTracker(e.sync_bits.active, e.sync_bits.hold)
        # the start watchdog waits for start_timeout_s of wall time and of samples, whichever is
        # later: a consumer behind the stream sees the start only once it has read up to it
        start_deadline_s = e._clock() + e.timing.start_timeout_s
        start_deadline = self.elapsed_samples + round(e.timing.start_timeout_s * e.sample_rate_hz)
        overrun = round((planned_s + e.timing.end_margin_s) * e.sample_rate_hz)
        end_deadline: int | None = None  # in elapsed samples, once the start is seen
        stopping: str | None = None
        while not tracker.ended:
            columns = self._next_columns()
            first = self.samples - len(columns.get("status", ()))
            tracker.feed(first, columns.get("status", np.zeros(0, int)))
            if tracker.started and end_deadline is None:
                end_deadline = self.elapsed_samples - (self.samples - tracker.start) + overrun
            if watch is not None and not watch.done:
                watch.feed(first, columns, tracker.hold_start, tracker.hold_end)
                if watch.done and stopping is None:
                    e._defensive_stop()
            if e._estop.is_set():
                raise RunStoppedError(RunState.ESTOPPED, "e-stop")
            self._guard(columns)
            if stopping is None and (e._abort.is_set() or e._pause.is_set()):
                stopping = "abort" if e._abort.is_set() else "pause"
                e._defensive_stop()
            elapsed = self.elapsed_samples
            if not tracker.started and e._clock() > start_deadline_s and elapsed > start_deadline:
                self._trip("excitation watchdog", "the controller did not start the excitation")
            if end_deadline is not None and not tracker.ended and elapsed > end_deadline:
                self._trip("excitation watchdog", "the excitation did not end when planned")
        # the controller's own stop (its e-stop button, a tripped limit, its watchdog) also ends the
        # excitation early: its status, read now, tells that from the planned end
        self._guard({}, read_status=True)
        if stopping == "abort":
            e._abort_now()
        if stopping == "pause":
            raise _PointInterruptedError(tracker.span)
        return tracker.span

    def _next_columns(self) -> Mapping[str, np.ndarray]:
        """The next block's columns, recorded; empty columns when none came in time."""
        e = self.engine
        block = self._subscription.get_all(e.timing.block_timeout_s)
        if block is None:
            return {}
        self._last_frame_s = e._clock()
        return self._record(block)

    def _guard(self, columns: Mapping[str, np.ndarray], *, read_status: bool = False) -> None:
        """Check every interlock; the first that trips stops the actuator and ends the run.

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
        seen = Observation(
            columns,
            controller,
            e.actuator.link_fault(),
            0.0 if columns else now - self._last_frame_s,
        )
        tripped = first_trip(e.interlocks, seen)
        if tripped is not None:
            self._trip(*tripped)

    def _trip(self, name: str, reason: str) -> None:
        """Stop the actuator with a taper, publish the interlock and end the run. An e-stop
        requested meanwhile ends it as e-stopped instead: its request is set before the stop is
        sent, so a controller seen e-stopped after the loop last looked at the request (the
        operator's thread sent it in between) is the e-stop's doing, not an interlock."""
        e = self.engine
        if e._estop.is_set():
            raise RunStoppedError(RunState.ESTOPPED, "e-stop")
        e._defensive_stop()
        e.bus.publish(ev.InterlockTripped(name, reason, self.run_id))
        e._force_state(Trigger.INTERLOCK)
        raise RunStoppedError(RunState.INTERLOCKED, f"{name}: {reason}")
