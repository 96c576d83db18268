"""The bench behind the terminal UI: devices, engine and sequences on threads of their own.

:class:`BenchSession` opens the configured bench (the simulated lab by default) on its worker
thread, builds the engine once and keeps both open until the UI closes, so that the technician can
switch the hydraulics and tare between sequences. Everything that talks to a device (opening the
links, hydraulics, tare, reset, a sequence) runs on that worker thread, never on the UI's; the
engine's events are handed to the UI through ``post`` (a thread-safe callback). Samples do not
travel as messages: they go into a :class:`LiveTrace` the UI reads at its own refresh rate.

The one exception is the e-stop: :meth:`BenchSession.estop` calls the engine's
``request_estop`` on the caller's thread, which sends the stop to the controller at once.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bench.analysis.campaign import AnalysisKind, CampaignKnowledge
from bench.app.bench_status import bench_description
from bench.app.devices import BenchDevices, open_bench
from bench.app.engine_build import build_engine
from bench.app.live_trace import LiveTrace
from bench.app.pace import DoneBefore, SequencePace
from bench.app.plan import CampaignPlan, plan_campaign
from bench.app.resume import done_in_file, held_runs, sequence_complete
from bench.app.run import run_on_engine
from bench.app.run_analysis import initial_knowledge
from bench.app.run_log import RunLog
from bench.config import BenchConfig, load_bench_config
from bench.engine import events as ev
from bench.engine.engine import Engine
from bench.engine.interlocks import interlock_names
from bench.engine.states import ACTIVE, RunState
from bench.store import StoreError, open_campaign
from sequences import AnswerError, Prompt

if TYPE_CHECKING:
    from bench.monitor.feed import MonitorFeed

log = logging.getLogger(__name__)
#: The run's events, one readable line each (the CLI's run log lines), into the UI's log file.
run_log = logging.getLogger("bench.tui.run")

#: How long the controller status may go unread while no sequence runs (s).
STATUS_PERIOD_S = 0.5


@dataclass(frozen=True)
class BenchOpened:
    """The bench is open: ``description`` says which (simulated or the configured devices)."""

    description: str
    interlocks: tuple[str, ...]


@dataclass(frozen=True)
class BenchFault:
    """Something the technician must see as a banner: a link lost, an interlock, a device error."""

    reason: str


@dataclass(frozen=True)
class BenchUnopened:
    """The bench could not be opened (``reason``: the plain message, naming the configuration's
    keys and the address tried); :meth:`BenchSession.reopen` tries again."""

    reason: str


@dataclass(frozen=True)
class SequenceLaunched:
    """A sequence goes to the engine; ``done_before``: what the resumed file holds done already
    (its points count as done in the progress)."""

    name: str
    resume: bool
    done_before: DoneBefore


@dataclass(frozen=True)
class ControllerStatus:
    """The controller's state as last read while no sequence ran; ``interlock``: its reason."""

    state: str
    interlock: str | None


@dataclass(frozen=True)
class PromptRequest:
    """The engine waits for the technician's answer to ``prompt``."""

    prompt: Prompt


@dataclass(frozen=True)
class BodeCurves:
    """One amplitude's force ratio F_wfs/F_contact, raw and compensated, at the dwell frequencies."""

    label: str
    freq_hz: np.ndarray
    raw: np.ndarray  # complex
    compensated: np.ndarray  # complex
    bands: tuple[str, ...]


@dataclass(frozen=True)
class RunResult:
    """The analysis after a run: its summary lines and, for a shaker grid, the Bode curves."""

    run_id: str
    name: str
    lines: tuple[str, ...]
    bode: tuple[BodeCurves, ...] = ()


@dataclass(frozen=True)
class PastRun:
    """One run of the open campaign file."""

    run_id: str
    kind: str
    status: str
    reason: str
    n_samples: int


@dataclass(frozen=True)
class PastRuns:
    runs: tuple[PastRun, ...]


@dataclass(frozen=True)
class HeldRuns:
    """The runs of a sequence the campaign file holds already, by run id with their status, and
    whether the sequence is complete there (every measurement run of it complete: nothing to
    resume)."""

    statuses: dict[str, str]
    complete: bool


@dataclass(frozen=True)
class PlanChecked:
    """A sequence file checked: ``plan`` when it may run, else ``error`` (file, key, allowed range)."""

    path: Path
    plan: CampaignPlan | None
    error: str


@dataclass(frozen=True)
class CommandFailed:
    """A command of the technician was refused or failed (the bench did not change)."""

    what: str
    reason: str


class UiOperator:
    """The engine's operator: each prompt is handed to the UI, and the engine's thread waits for the
    technician's answer (already checked by the dialog). On the simulated bench the answer is also
    applied to the simulated world, as the person's hands would."""

    def __init__(self, ask: Callable[[Prompt], None], stopped: Callable[[], bool]) -> None:
        """``stopped()``: whether the bench is e-stopped; an answer given then changes nothing in
        the simulated world (nobody handles the bench while it is stopped), and the engine ends
        the sequence as e-stopped at its next checkpoint."""
        self._ask = ask
        self.stopped = stopped
        self._replies: queue.Queue[object] = queue.Queue()
        self.world: Any = None  # the simulated operator, when the bench is simulated
        self.pending: Prompt | None = None

    def answer(self, prompt: Prompt) -> object:
        self.pending = prompt
        self._ask(prompt)
        reply = self._replies.get()
        self.pending = None
        if isinstance(reply, AnswerError):
            raise reply
        value = prompt.check_answer(reply)
        if self.world is not None and prompt.action is not None and not self.stopped():
            self.world.apply(prompt.action, value)
        return value

    def reply(self, value: object) -> None:
        """The technician's (valid) answer to the pending prompt."""
        self._replies.put(value)

    def cancel(self, reason: str) -> None:
        """No answer will come (the technician aborted): the engine aborts the sequence."""
        if self.pending is not None:
            self._replies.put(AnswerError(f"{self.pending.id}: {reason}"))


class BenchSession:
    """The open bench for the terminal UI. ``post(message)`` must be safe to call from any thread."""

    def __init__(
        self,
        config_path: Path | None,
        out_path: Path,
        post: Callable[[object], None],
        monitor: MonitorFeed | None = None,
    ) -> None:
        """``monitor``: the web monitor's feed, given the engine once the bench is open and told of
        each sequence launched (``wfsbench tui --monitor``)."""
        self.config_path = config_path
        self.monitor = monitor
        self.out_path = Path(out_path)
        self.post = post
        self.config: BenchConfig | None = None
        self.operator = UiOperator(
            lambda prompt: post(PromptRequest(prompt)),
            lambda: self.engine is not None and self.engine.state is RunState.ESTOPPED,
        )
        self.engine: Engine | None = None
        self.devices: BenchDevices | None = None
        self.trace: LiveTrace | None = None
        self.pace: SequencePace | None = None  # the figures of the sequence started last
        self.knowledge: CampaignKnowledge | None = None
        self.running = threading.Event()  # a sequence is under way
        self._started = False  # the sequence under way got past its checks (the engine started it)
        self._commands: queue.Queue[Callable[[], None] | None] = queue.Queue()
        self._thread = threading.Thread(target=self._serve, name="tui-bench", daemon=True)
        self.opened = threading.Event()

    # -- lifetime -------------------------------------------------------------------------------

    def start(self) -> None:
        self._thread.start()

    def reopen(self) -> bool:
        """Open the bench again after it could not be opened (the configuration read anew); False
        while a bench is open or being opened."""
        if self._thread.is_alive():
            return False
        self.engine = self.devices = self.trace = None
        self.opened.clear()
        self._thread = threading.Thread(target=self._serve, name="tui-bench", daemon=True)
        run_log.info("opening the bench again")
        self._thread.start()
        return True

    def close(self, timeout_s: float = 30.0) -> None:
        """Stop after the command under way (a running sequence is aborted first)."""
        if self.running.is_set() and self.engine is not None:
            self.abort()
        self._commands.put(None)
        self._thread.join(timeout_s)

    def _serve(self) -> None:
        try:
            self.config = load_bench_config(self.config_path)
            with open_bench(self.config, self.operator) as devices:
                self.devices = devices
                if devices.lab is not None:
                    self.operator.world = devices.lab.operator
                self.engine = build_engine(self.config, devices)
                self.trace = LiveTrace(float(self.config.wfs.rate_hz), self.config.channels)
                self.engine.bus.subscribe(self._on_event)
                self.engine.bus.subscribe(RunLog(self._log_lines))
                if self.monitor is not None:
                    self.monitor.attach(self.engine, self.config)
                description = bench_description(self.config)
                self.post(BenchOpened(description, self._interlock_names()))
                run_log.info("bench open: %s, file %s", description, self.out_path)
                self.opened.set()
                self._post_past_runs()
                self._loop()
        except Exception as exc:  # a bench that cannot open is shown, not raised into the UI
            if self.opened.is_set():
                log.exception("the bench failed")
                self.post(BenchFault(f"the bench failed: {exc or type(exc).__name__}"))
            else:  # the message names the configuration's keys and the address tried
                log.warning("the bench did not open: %s", exc, exc_info=True)
                run_log.info("the bench did not open: %s", exc)
                self.post(BenchUnopened(str(exc) or type(exc).__name__))

    @staticmethod
    def _log_lines(text: str) -> None:
        for line in text.splitlines():
            run_log.info(line)

    def _loop(self) -> None:
        while True:
            try:
                command = self._commands.get(timeout=STATUS_PERIOD_S)
            except queue.Empty:
                self._read_status()
                continue
            if command is None:
                return
            command()

    def _interlock_names(self) -> tuple[str, ...]:
        """The interlocks the Bench screen has a lamp for: every one the engine can trip."""
        return interlock_names(self.engine.interlocks)

    # -- commands (any thread; executed on the worker thread) -----------------------------------

    def check(self, sequence_path: Path) -> None:
        """Validate and dry-run a sequence file; the answer comes as :class:`PlanChecked`. It opens
        no device, so it runs on a thread of its own (a sequence may be running meanwhile)."""
        threading.Thread(
            target=self._check, args=(Path(sequence_path),), name="tui-check", daemon=True
        ).start()

    def held_runs(self, plan: CampaignPlan) -> HeldRuns:
        """The runs of ``plan``'s sequence the campaign file holds already, with their status: a
        start must resume them, unless every one is complete (StoreError when the file is no
        campaign file)."""
        held = held_runs(plan, self.out_path)
        if not held:
            return HeldRuns({}, complete=False)
        with open_campaign(self.out_path) as campaign:
            statuses = {r.run_id: r.status for r in campaign.runs if r.run_id in held}
        return HeldRuns(statuses, sequence_complete(plan, statuses))

    def start_sequence(self, plan: CampaignPlan, *, resume: bool = False) -> None:
        """Run ``plan`` into the campaign file; ``resume`` continues its runs there, skipping its
        complete runs and points (as ``wfsbench run --resume``)."""
        self.running.set()
        self._commands.put(lambda: self._run(plan, resume))

    def hydraulics(self, level: str) -> None:
        run_log.info("operator: hydraulics %s", level)
        self._commands.put(lambda: self._guarded(f"hydraulics {level}", self.engine.set_hydraulics, level))

    def tare(self) -> None:
        run_log.info("operator: tare")
        self._commands.put(lambda: self._guarded("tare", self.devices.acquisition.tare))

    def reset(self) -> None:
        """Release an interlock or e-stop; the commands after it wait until the controller has
        tapered out and takes commands again."""
        run_log.info("operator: reset")
        self._commands.put(lambda: self._guarded("reset", self.engine.reset))

    # -- requests to the running sequence (any thread, at once) ---------------------------------

    def pause(self) -> bool:
        """Request a pause; False when the engine's state does not allow one."""
        done = self.engine.request_pause()
        run_log.info("operator: pause %s", "requested" if done else f"refused ({self.engine.state.value})")
        return done

    def resume(self) -> bool:
        """Resume a paused (or pausing) sequence; False when the state does not allow it."""
        done = self.engine.request_resume()
        run_log.info("operator: resume %s", "requested" if done else f"refused ({self.engine.state.value})")
        return done

    def abort(self) -> bool:
        """Abort the sequence under way (a prompt waiting gets no answer); False when the state
        does not allow it (nothing under way, or aborting already)."""
        if self.engine.state not in ACTIVE:
            return False
        done = self.engine.request_abort()
        run_log.info("operator: abort %s", "requested" if done else f"refused ({self.engine.state.value})")
        if done:
            self.operator.cancel("aborted by the operator")
        return done

    def estop(self) -> None:
        """E-stop from the caller's thread: the controller is told before this returns."""
        run_log.warning("operator: E-STOP")
        self.engine.request_estop()

    def answer(self, value: object) -> None:
        self.operator.reply(value)

    # -- the worker threads ----------------------------------------------------------------------

    def _check(self, path: Path) -> None:
        try:
            plan = plan_campaign(path, self.config_path)
        except Exception as exc:  # SequenceError, ConfigError, PlanRefusedError, OSError: all shown
            self.post(PlanChecked(path, None, str(exc)))
        else:
            self.post(PlanChecked(path, plan, ""))

    def _run(self, plan: CampaignPlan, resume: bool) -> None:
        self.knowledge = initial_knowledge(plan.config)
        self._started = False
        try:
            done_before = done_in_file(plan, self.out_path) if resume else DoneBefore()
            self.pace = SequencePace(done_before=done_before)
            self.post(SequenceLaunched(plan.sequence.name, resume, done_before))
            if self.monitor is not None:
                self.monitor.launched(done_before)
            run_log.info(
                "%s sequence %s into %s%s",
                "resuming" if resume else "starting",
                plan.sequence.name,
                self.out_path,
                f" ({done_before.points} point(s) done there already)" if resume else "",
            )
            run_on_engine(
                self.engine, plan, self.out_path, resume=resume, knowledge=self.knowledge, gate_asks=True
            )
        except Exception as exc:
            if not self._started:  # the campaign file refused it (it names the file): nothing moved
                log.warning("the sequence did not start: %s", exc)
                self.post(BenchFault(f"the sequence did not start: {exc}{self._reset_hint()}"))
            else:
                log.exception("the sequence failed")
                reason = str(exc) or type(exc).__name__  # the plain message, not the class
                self.post(BenchFault(f"the sequence failed: {reason}{self._reset_hint()}"))
        finally:
            self.running.clear()
        self._post_past_runs()

    def _reset_hint(self) -> str:
        """What the technician does next when the engine was left stopped."""
        if self.engine.state in (RunState.INTERLOCKED, RunState.ESTOPPED, RunState.FAILED):
            return f" (the bench is {self.engine.state.value}: x on the Bench screen, F2, resets)"
        return ""

    def _guarded(self, what: str, action: Callable[..., None], *args: object) -> None:
        try:
            action(*args)
        except Exception as exc:  # refused transitions and device errors are shown, not raised
            self.post(CommandFailed(what, str(exc)))
        self._read_status()

    def _read_status(self) -> None:
        try:
            readback = self.devices.actuator.read_status()
        except Exception as exc:
            self.post(BenchFault(f"controller status unreadable: {exc}"))
            return
        self.post(ControllerStatus(readback.status.state.name.lower(), readback.interlock_reason))

    def _post_past_runs(self) -> None:
        if not self.out_path.exists():
            self.post(PastRuns(()))
            return
        try:
            with open_campaign(self.out_path) as campaign:
                runs = tuple(
                    PastRun(r.run_id, r.kind, r.status, r.reason, r.n_samples) for r in campaign.runs
                )
        except StoreError as exc:  # it names the file and the place in it
            self.post(BenchFault(str(exc)))
            return
        except Exception as exc:  # shown, never raised into the worker
            self.post(BenchFault(f"{self.out_path}: {type(exc).__name__}: {exc}"))
            return
        self.post(PastRuns(runs))

    # -- the engine's thread --------------------------------------------------------------------

    def _on_event(self, event: ev.Event) -> None:
        """Forward an event to the UI; every event to the pace; samples go to the live trace;
        results get their curves."""
        if self.pace is not None:
            self.pace(event)
        if isinstance(event, ev.SamplesRecorded):
            self.trace.append(dict(event.columns), event.run_id)
            return
        if isinstance(event, ev.SequenceStarted):
            self._started = True
        self.post(event)
        if isinstance(event, ev.AnalysisDone):
            self.post(RunResult(event.run_id, event.name, tuple(event.summary), self._bode(event)))

    def _bode(self, event: ev.AnalysisDone) -> tuple[BodeCurves, ...]:
        pressure = event.results.get("tyre_pressure_bar")
        shaker = event.name == AnalysisKind.SHAKER
        if not shaker or self.knowledge is None or pressure not in self.knowledge.shaker:
            return ()
        curves = []
        for result in self.knowledge.shaker[pressure].amplitudes.values():
            raw = result.frfs.wfs_per_contact
            comp = result.compensated_per_contact
            bands = tuple(
                f"{name}: {_band_text(band)}"
                for name, band in (
                    ("raw", result.valid_band_raw),
                    ("compensated", result.valid_band_compensated),
                )
            )
            curves.append(
                BodeCurves(
                    result.label,
                    np.asarray(raw.freq_hz),
                    np.asarray(raw.value),
                    np.asarray(comp.value),
                    bands,
                )
            )
        return tuple(curves)


def _band_text(band: Any) -> str:
    if not band.determined:
        return f"not determined (limited by {band.limited_by})"
    return f"{band.lowest_hz:g}-{band.upper_hz:g} Hz (ends: {band.limited_by})"
