"""A run's recording: its WFS stream started, every frame published as samples, its excitations
configured, started and followed to their end, its interlocks and limits watched, until the run ends.

A run's procedure (:mod:`bench.engine.procedures`) opens one :class:`RunRecording` for the run and
excites the bench through it; the recording sees the engine only through the run's
:class:`~bench.engine.run_context.RunContext`.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping
from typing import Any, NoReturn

import numpy as np

from bench.engine import events as ev
from bench.engine.amplitude import AMPLITUDE_EXCURSION
from bench.engine.amplitude_hold import HeldAmplitude
from bench.engine.contracts import SampleBlockLike
from bench.engine.interlocks import Observation, Trip, trips
from bench.engine.online import OnlineDwell
from bench.engine.points import ExcitationSpan, SpanTracker, excitation_frequency_hz
from bench.engine.run_context import MeasurementRun, RunContext
from bench.engine.states import RunState
from bench.engine.stops import RunStoppedError, stop_with_taper
from bench.engine.tracking import TrackWatch
from bench.numerics.sine_fit import SineFit, fit_latest_cycles, frame_offsets
from drivers.errors import LinkError
from drivers.setpoints import DriveSetpoint, DwellSetpoint, SweepSetpoint
from sequences import SineDwell, step_fields
from sequences.response_limits import LimitAction

log = logging.getLogger(__name__)


class PointInterruptedError(Exception):
    """A pause request interrupted the present point at ``span``: repeat it after the pause."""

    def __init__(self, span: ExcitationSpan) -> None:
        super().__init__("point interrupted by a pause")
        self.span = span


class RunRecording:
    """One run's stream: started on entry, every frame published as samples until the exit."""

    def __init__(
        self,
        context: RunContext,
        run: MeasurementRun,
        *,
        drive: Mapping[str, Any] | None = None,
        before_stream: Callable[[], None] | None = None,
        keep: tuple[str, ...] = (),
    ) -> None:
        """The recording of ``run``, which goes on after the samples the campaign file holds of it
        already (resume); ``drive``: a road replay's drive as the run records it; ``before_stream``:
        called once the run has begun, before its stream starts (a road replay's upload); ``keep``:
        the recorded channels kept whole beside the displacement (a drive iteration's response)."""
        self.context = context
        self.run_id = run.run_id
        self.step = run.step
        self.drive = drive or {}
        self.before_stream = before_stream
        self.samples = run.held.samples  # the run's samples so far: the index of the next one
        # the acquisition's sample time since this recording began: the samples received and those
        # the link reported lost (what the watchdogs count, so that a link that lets only a few
        # frames through cannot hold them off)
        self.elapsed_samples = 0
        self.displacement: list[np.ndarray] = []
        self.seq: list[np.ndarray] = []  # each block's frame counters, beside its displacement
        self.kept: dict[str, list[np.ndarray]] = {name: [] for name in keep}
        self._gaps: list[tuple[int, int]] = []  # (run sample a gap came before, frames missing)
        self._subscription = None
        self._last_status_s = -np.inf
        self._stream_started_s = 0.0
        # open host stall: unread s, arrival, end sample, frames missing before it
        self._stall: tuple[float, float, int, int] | None = None
        self._limits_acted: set[str] = set()  # the limits milder than an interlock published this excitation

    def __enter__(self) -> RunRecording:
        context = self.context
        context.publish(
            ev.RunStarted(
                self.run_id,
                self.step.run_kind,
                step_fields(self.step),
                dict(context.conditions),
                context.channels.specs(),
                context.sample_rate_hz,
                self.drive,
            )
        )
        try:
            if self.before_stream is not None:
                self.before_stream()
            self._start_stream()
            context.streaming(self)
        except BaseException as exc:  # the run began: it ends too, with the sequence's ending
            if self._subscription is not None:
                self._subscription.close()
            context.finish_run(self.run_id, context.end_run(exc))
            raise
        return self

    def _start_stream(self) -> None:
        context = self.context
        if context.tare_each_run:
            context.acquisition.tare()
        backlog = max(1, round(context.timing.backlog_s * context.sample_rate_hz))
        self._subscription = context.acquisition.subscribe(lossless=True, max_frames=backlog)
        context.acquisition.start_stream()
        self._stream_started_s = context.clock()

    def __exit__(self, exc_type, exc, tb) -> None:
        """End the run: the sequence's ending first, if the run did not complete (the actuator
        stopped before the stream), then the stream stopped and the run's end published."""
        outcome = self.context.end_run(exc)
        try:
            self._stop_stream()
        except LinkError as stop_error:
            log.warning("stopping the WFS stream failed: %s", stop_error)
        finally:
            self.context.streaming(None)
            self._subscription.close()
            self._close_host_stall()  # one still open: published with the frames missing since, no trip
            self.context.finish_run(self.run_id, outcome)

    def _stop_stream(self) -> None:
        """Stop the stream and record every frame sent before it stopped.

        The frames are recorded while the STOP awaits its reply: the reply comes on the same line
        behind the frames still in flight, and the reader hands those over to this run's lossless
        subscription first; left undrained, a full subscription would hold the reader and the reply
        with it."""
        acquisition, timeout_s = self.context.acquisition, self.context.timing.block_timeout_s
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
        columns = self.context.channels.columns(block.frames)
        gaps = tuple((g.index, g.missing) for g in block.gaps)
        self.context.publish(ev.SamplesRecorded(self.run_id, self.samples, columns, gaps))
        self.displacement.append(np.asarray(columns[self.context.channels.displacement], dtype=float))
        self.seq.append(np.asarray(columns["seq"]))
        for name, blocks in self.kept.items():
            blocks.append(np.asarray(columns[name], dtype=float))
        self._gaps.extend((self.samples + index, missing) for index, missing in gaps)
        self.samples += len(block.frames)
        self.elapsed_samples += len(block.frames) + sum(missing for _, missing in gaps)
        return columns

    def achieved_fit(self, span: ExcitationSpan, dwell: SineDwell) -> SineFit | None:
        """The displacement's fit over the hold after its settling time, on the frames' true times
        (None: too short). The window's time runs from the settling time's end, counted in sample
        times from the hold's first frame, to the hold's end."""
        fs = self.context.sample_rate_hz
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

    def kept_between(self, name: str, start: int, stop: int) -> np.ndarray:
        """The kept channel ``name`` from run sample ``start`` to ``stop``."""
        return self._between(self.kept[name], start, stop, float)

    def frames_lost_between(self, start: int, stop: int) -> int:
        """The frames the link lost between run samples ``start`` and ``stop``."""
        return sum(missing for sample, missing in self._gaps if start < sample <= stop)

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

    def point_done(
        self, index: int, freq_hz: float, amplitude_mm: float, span: ExcitationSpan, **attempt: Any
    ) -> ev.PointDone:
        """The end of an attempt at point ``index`` of this run (at ``freq_hz`` and ``amplitude_mm``)
        over ``span``, with the frames the link lost in its hold; ``attempt``: its other fields."""
        return ev.PointDone(
            index,
            freq_hz,
            amplitude_mm,
            span.start,
            span.hold_start,
            span.hold_end,
            span.end,
            frames_missing=self.frames_missing_between(span.hold_start, span.hold_end),
            run_id=self.run_id,
            **attempt,
        )

    def check_excursion(self, target_mm: float, achieved_mm: float, where: str) -> None:
        """A measured amplitude beyond the target by more than the amplitude control's excursion
        tolerance is a limit reached, acted on with its configured action."""
        control = self.context.amplitude_control
        if reason := control.excursion(target_mm, achieved_mm):
            self._act(Trip(AMPLITUDE_EXCURSION, f"{where}: {reason}", control.excursion_action))

    def excite(
        self,
        setpoint: DwellSetpoint | SweepSetpoint | DriveSetpoint,
        *,
        planned_s: float,
        watch: OnlineDwell | TrackWatch | None = None,
        held: HeldAmplitude | None = None,
    ) -> ExcitationSpan:
        """Configure, start and record one excitation until the controller's active output falls.

        ``watch`` follows an adaptive dwell's hold (or a tracked dwell's track) block by block: once
        it is done the excitation is stopped with its taper (the hold ends where the controller's
        hold output falls). ``held`` holds a dwell's amplitude within its hold, block by block (each
        update it makes lengthens the excitation's planned duration). A pause request (the table
        ``pausing``) stops it with a taper and raises
        :class:`PointInterruptedError` once it is at rest; an abort (``aborting``) tapers it out and
        ends the run; an e-stop or a tripped interlock ends the run."""
        context = self.context
        context.actuator.configure(setpoint)
        context.actuator.start()
        self._limits_acted = set()
        tracker = SpanTracker(context.sync_bits.active, context.sync_bits.hold)
        # the start watchdog waits for start_timeout_s of wall time and of samples, whichever is
        # later: a consumer behind the stream sees the start only once it has read up to it
        start_deadline_s = context.clock() + context.timing.start_timeout_s
        start_deadline = self.elapsed_samples + round(context.timing.start_timeout_s * context.sample_rate_hz)
        overrun = round((planned_s + context.timing.end_margin_s) * context.sample_rate_hz)
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
                    stop_with_taper(context.actuator)
            if held is not None and not stopping:
                held.feed(first, columns)
            context.publish_changes()
            state = context.state()
            if state is RunState.ESTOPPED:
                raise RunStoppedError.estop()
            freq_hz = None
            if tracker.started and columns:
                if start_seq is None:  # the excitation's time runs by the frame counter: gaps count
                    start_seq = int(self.seq_between(tracker.start, tracker.start + 1)[0])
                t_s = frame_offsets(columns["seq"], start_seq) / context.sample_rate_hz
                freq_hz = excitation_frequency_hz(setpoint, t_s)
            self._guard(columns, freq_hz=freq_hz)
            if not stopping and state in (RunState.PAUSING, RunState.ABORTING):
                stopping = True
                stop_with_taper(context.actuator)
            elapsed = self.elapsed_samples
            if not tracker.started and context.clock() > start_deadline_s and elapsed > start_deadline:
                self._trip("excitation watchdog", "the controller did not start the excitation")
            extension = 0 if held is None else round(held.extension_s * context.sample_rate_hz)
            if end_deadline is not None and not tracker.ended and elapsed > end_deadline + extension:
                self._trip("excitation watchdog", "the excitation did not end when planned")
        # the controller's own stop (its e-stop button, a tripped limit, its watchdog) also ends the
        # excitation early: its status, read now, tells that from the planned end
        self._guard({}, read_status=True)
        if stopping:  # ended by an abort (or an e-stop since); else paused, or resumed meanwhile
            context.stop_if_requested()
            raise PointInterruptedError(tracker.span)
        return tracker.span

    def _next_columns(self) -> Mapping[str, np.ndarray]:
        """The next block's columns, recorded; empty columns when none came in time."""
        context = self.context
        block = self._subscription.get_all(context.timing.block_timeout_s)
        if block is None:
            return {}
        columns = self._record(block)
        self._follow_host_stall(block)
        return columns

    def record_while_paused(self) -> None:
        """At rest in a pause: the stream is recorded and the interlocks are watched until the state
        leaves ``paused`` (resumed, aborting, e-stopped)."""
        while self.context.state() is RunState.PAUSED:
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
        context = self.context
        missing = self.elapsed_samples - self.samples  # frames missing so far, this block's included
        before = missing - sum(g.missing for g in block.gaps)
        if self._stall is not None:
            _, arrived_s, end, _ = self._stall
            late = block.arrived_s - arrived_s > context.timing.host_stall_s
            stall_samples = context.timing.host_stall_s * context.sample_rate_hz
            if late and self.samples - len(block.frames) - end > stall_samples:
                self._close_host_stall(before, trips=not stopping)  # too late to be the stall's
        if block.unread_s >= context.timing.host_stall_s:
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
        self.context.publish(ev.HostStalled(self.run_id, stalled_s, lost, counted))
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
        context = self.context
        now = context.clock()
        controller = None
        if read_status or now - self._last_status_s >= context.timing.status_period_s:
            self._last_status_s = now
            try:
                controller = context.actuator.read_status()
            except LinkError as exc:
                log.warning("status read failed: %s", exc)
        # the link's silence is judged at the port, bounded by this stream's age (bytes of an
        # earlier stream do not count): bytes waiting there unread are the host's delay
        silence_s = 0.0
        if not columns:
            silence_s = min(context.acquisition.link_silence_s(), now - self._stream_started_s)
        seen = Observation(columns, controller, context.actuator.link_fault(), silence_s, freq_hz)
        for trip in trips(context.interlocks, seen):
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
        context = self.context
        context.publish(ev.LimitReached(self.run_id, trip.name, trip.reason, str(trip.action)))
        if trip.action is LimitAction.STOP:
            raise RunStoppedError.abort(f"{trip.name} (stop): {trip.reason}")
        if trip.action is LimitAction.HOLD:
            context.request_pause()

    def _trip(self, name: str, reason: str) -> NoReturn:
        """End the run on a tripped interlock: the ending stops the actuator with a taper and
        publishes the interlock. An e-stop requested meanwhile ends it as e-stopped instead: the
        table shows the e-stop before it is sent, so a controller seen e-stopped after the loop last
        looked at the state (the operator's thread sent it in between) is the e-stop's doing, not
        an interlock."""
        raise RunStoppedError.interlock_tripped(ev.InterlockTripped(name, reason, self.run_id))
