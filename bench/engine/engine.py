"""The run engine: executes a sequence's steps on the bench, point by point.

The loop reads top to bottom: a sequence is split into its steps; a measurement step (dwell grid,
free run, sweep, ...) is one *run*, made by the procedure of its run kind
(:data:`bench.engine.procedures.PROCEDURES`, given a :class:`~bench.engine.run_context.RunContext`
rather than the engine) and recorded from the start of its stream to its end
(:mod:`bench.engine.recording`); each dwell of a grid is one *point*. A point is located in the
acquisition's samples by the controller's sync outputs (:mod:`bench.engine.points`), so lengths are
counted in samples and the wall clock serves only timeouts and watchdogs. Between points lies the
checkpoint where a pause takes effect.

Requests come from other threads (front ends) and fire their transition at once: a pause or an
abort request is a state of the table (pausing, aborting) until the loop has acted on it, and the
e-stop is also sent to the controller from the requesting thread. The loop reads the state, never a
flag of its own. However a sequence ends, :meth:`Engine._end` ends it. Everything the engine does is
published as an event; storage, analysis and displays are subscribers.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from bench.engine import events as ev
from bench.engine.amplitude import AmplitudeControl, FramesPresent
from bench.engine.amplitude_hold import AmplitudeHold
from bench.engine.channels import FrameChannels
from bench.engine.contracts import (
    Acquisition,
    Actuator,
    Notching,
    Operator,
    PlannedDrive,
    PlannedIteration,
    ResumePlan,
    RunGate,
)
from bench.engine.interlocks import ActuatorLinkLost, Interlock
from bench.engine.points import SyncBits
from bench.engine.procedures import PROCEDURES
from bench.engine.run_context import MeasurementRun, RecordedRun, RunContext, StreamingRun
from bench.engine.run_ids import run_id
from bench.engine.states import RUN_STATUS, RunState, StateMachine, TransitionRefusedError, Trigger
from bench.engine.stops import RunOutcome, RunStoppedError, stop_with_taper
from bench.engine.timing import EngineTiming
from drivers.errors import CommandRejectedError, LimitError, LinkError
from sequences import AnswerError, Hydraulics, MeanPosition, Prompt, Sequence, Tare
from sequences.runs import RigKind
from sequences.steps import MEASUREMENT_TYPES

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


#: The reason an abort records unless its requester gives its own.
ABORT_REASON = "aborted by the operator"
#: The id of the question put to the operator when the run gate would stop the sequence and the
#: operator is asked instead (``Engine.run(gate_asks=True)``); a yes is recorded as a condition.
GO_ON_DESPITE = "go_on_despite"


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
        bench_kind: RigKind = RigKind.SHAKER,
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
        self._streaming: StreamingRun | None = None  # the run whose stream is recorded now
        self._gate: RunGate | None = None  # the sequence under way's run gate
        self._gate_asks = False  # whether a gate's reason is put to the operator instead of stopping
        self._gate_accepted: set[str] = set()  # the gate's reasons the operator chose to go on despite
        self._drives: Mapping[int, PlannedDrive | PlannedIteration] = {}  # what the plan loaded per step
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
        drives: Mapping[int, PlannedDrive | PlannedIteration] | None = None,
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
        action = STEP_ACTIONS.get(type(step))
        if action is not None:
            action(self, step)
        elif is_measurement(step):
            run_id = self.run_id(sequence, index)
            if resume is not None and resume.run_complete(run_id):
                return
            held = RecordedRun()
            if resume is not None:
                held = RecordedRun(resume.completed_points(run_id), resume.recorded_samples(run_id))
            self._measure(MeasurementRun(run_id, step, held, self._drives.get(index), resume))
        else:
            raise RunStoppedError.fail(f"step {index}: {type(step).__name__} is not supported")

    def _set_hydraulics(self, step: Hydraulics) -> None:
        self.actuator.set_hydraulics(step.level)
        self.conditions["hydraulics"] = step.level

    def _tare(self, step: Tare) -> None:
        self.acquisition.tare()

    def _set_mean_position(self, step: MeanPosition) -> None:
        self.conditions["mean_mm"] = step.mean_mm

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
        reason = self._gate(run_id, steps[upcoming].run_kind)
        if reason is None or reason in self._gate_accepted:
            return
        if not self._gate_asks:
            raise RunStoppedError.abort(f"stopped before {run_id}: {reason}")
        self._ask(Prompt(GO_ON_DESPITE, f"Before {run_id}: {reason}. Go on anyway?"))
        self._gate_accepted.add(reason)

    def _measure(self, run: MeasurementRun) -> None:
        """Make the run of a measurement step by its kind's procedure."""
        PROCEDURES[run.step.run_kind](self._run_context(), run)

    def _run_context(self) -> RunContext:
        """What a run may use of the engine: the bench as the engine has it now, the sequence's
        conditions and the engine's own acts a run takes part in."""
        return RunContext(
            actuator=self.actuator,
            acquisition=self.acquisition,
            channels=self.channels,
            interlocks=self.interlocks,
            sync_bits=self.sync_bits,
            sample_rate_hz=self.sample_rate_hz,
            timing=self.timing,
            clock=self._clock,
            tare_each_run=self.tare == "before_each_run",
            amplitude_control=self.amplitude_control,
            amplitude_hold=self.amplitude_hold,
            frames_present=self.frames_present,
            notching=self.notching,
            conditions=self.conditions,
            publish=self.bus.publish,
            state=lambda: self.state,
            publish_changes=self._publish_changes,
            checkpoint=self._checkpoint,
            wait_paused=self._wait_paused,
            stop_if_requested=self._stop_if_requested,
            request_pause=self.request_pause,
            ask=self._ask,
            end_run=self._run_ended,
            streaming=self._stream_of,
        )

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
            if self._streaming is None:
                self.machine.wait_while(RunState.PAUSED)
            else:
                self._streaming.record_while_paused()
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
            stop_with_taper(self.actuator)
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
        run_id = self._streaming.run_id if self._streaming is not None else None
        tripped = ev.InterlockTripped(ActuatorLinkLost.name, f"{fault} ({error})", run_id)
        return _Ending(Trigger.INTERLOCK, f"{tripped.name}: {tripped.reason}", tripped)

    def _run_ended(self, error: BaseException | None) -> RunOutcome:
        """How a run (a measurement step) ended: complete, or the sequence's ending (a run that does
        not complete ends the sequence)."""
        return RunOutcome("complete") if error is None else self._end(error)

    def _stream_of(self, run: StreamingRun | None) -> None:
        """Note the run whose stream is recorded now (None: none): a pause records it meanwhile, and
        an ending while it streams names it."""
        self._streaming = run

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


#: What the engine does for each step that records no run (a measurement step runs its run kind's
#: procedure, :data:`~bench.engine.procedures.PROCEDURES`): every step type is in one or the other.
STEP_ACTIONS: dict[type, Callable[[Engine, Any], None]] = {
    Prompt: Engine._ask,
    Hydraulics: Engine._set_hydraulics,
    Tare: Engine._tare,
    MeanPosition: Engine._set_mean_position,
}


def is_measurement(step: object) -> bool:
    """Whether ``step`` records a run (a dwell, a grid, a free run, a sweep, a tracked dwell, a road
    replay, a hammer test)."""
    return isinstance(step, MEASUREMENT_TYPES)
