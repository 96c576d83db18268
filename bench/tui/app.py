"""The technician's terminal UI: one app, four panes (bench, sequence, run, results), prompts and
confirmations as modal dialogs, a banner for link losses and interlocks, and the e-stop on F12 from
every pane and dialog.

The app draws and routes keys only. The bench lives in a :class:`BenchSession` (its worker thread
does every device call and runs the sequences); the session's messages arrive through
``post_message`` (thread-safe), and the live plots are redrawn from its trace by a timer, so the
drawing rate never depends on the acquisition's rate.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

from textual import events
from textual.actions import parse as parse_action
from textual.app import App, ComposeResult, ScreenStackError
from textual.binding import Binding
from textual.containers import Horizontal
from textual.css.query import NoMatches
from textual.message import Message
from textual.widgets import ContentSwitcher, Footer, Input, OptionList, Static

from bench.app.bench_status import Tone, is_reset, state_tone
from bench.app.plan import CampaignPlan
from bench.engine import events as ev
from bench.engine.states import ACTIVE, RunState
from bench.store import StoreError
from bench.tui.dialogs import ConfirmDialog, HelpDialog, MetadataDialog, PromptDialog
from bench.tui.panes import BenchPane, ResultsPane, RunPane, SequencePane, show_text
from bench.tui.session import (
    BenchFault,
    BenchOpened,
    BenchSession,
    BenchUnopened,
    CommandFailed,
    ControllerStatus,
    PastRuns,
    PlanChecked,
    PromptRequest,
    RunResult,
    SequenceLaunched,
)
from sequences import shipped_file

if TYPE_CHECKING:
    from bench.monitor.feed import MonitorFeed

#: How often the live values and plots are redrawn (s).
REFRESH_S = 0.1
#: The state line's style of each tone (:mod:`bench.app.bench_status`: the tone of each state).
TONE_STYLES = {
    Tone.OK: "bold green",
    Tone.CAUTION: "bold yellow",
    Tone.ALARM: "bold white on red",
    Tone.PLAIN: "bold",
}
#: The banner for q while a sequence runs (cleared when the sequence ends).
QUIT_WHILE_RUNNING = "a sequence is under way: a aborts it (with a taper); q quits once it has ended"
PANES = {"bench": "Bench", "sequence": "Sequence", "run": "Run", "results": "Results"}


class SessionMessage(Message):
    """Something the bench session reports, carried to the UI's thread."""

    def __init__(self, payload: object) -> None:
        super().__init__()
        self.payload = payload


class WfsBenchApp(App):
    """``wfsbench tui``: the bench of ``config_path`` (None: the simulated shaker bench), runs
    recorded into the campaign file ``out_path``."""

    TITLE = "wfs-bench"
    CSS = """
    #topbar { height: 1; background: $panel; }
    #state { width: 1fr; padding: 0 1; }
    #estop { width: auto; background: red; color: white; text-style: bold; padding: 0 1; }
    #tabs { width: auto; padding: 0 1; }
    #banner { display: none; background: darkred; color: white; text-style: bold; padding: 0 1; }
    #banner.shown { display: block; }
    ContentSwitcher { height: 1fr; }
    ContentSwitcher > * { padding: 0 1; }
    #seq-shipped { height: auto; max-height: 12; }
    #run-plots { height: 12; }
    #run-plots BraillePlot { width: 1fr; height: 12; }
    #results-text { height: 1fr; }
    #results-bode { height: 12; }
    #results-bode BraillePlot { width: 1fr; height: 12; }
    #results-runs { height: auto; max-height: 8; }
    #run-points { height: 1fr; }
    .dialog {
        width: 84; max-width: 100%; height: auto; max-height: 100%;
        border: thick $accent; background: $surface; padding: 1 2; overflow-y: auto;
    }
    .dialog > Label, .dialog > Static { width: 100%; height: auto; }
    ModalScreen { align: center middle; }
    #prompt-error { height: auto; }
    """
    # every key of the footer fits 80 columns: the screens' keys are in the top bar, not repeated
    BINDINGS: ClassVar[list[Binding]] = [
        Binding("f12", "estop", "E-STOP", priority=True, show=False),  # in the top bar, always
        Binding("f2", "pane('bench')", "Bench", show=False),
        Binding("f3", "pane('sequence')", "Sequence", show=False),
        Binding("f4", "pane('run')", "Run", show=False),
        Binding("f5", "pane('results')", "Results", show=False),
        Binding("question_mark", "help", "Help"),
        Binding("l", "hydraulics('low')", "Hyd. low"),
        Binding("h", "hydraulics('high')", "Hyd. high"),
        Binding("o", "hydraulics('off')", "Hyd. off"),
        Binding("t", "tare", "Tare"),
        Binding("x", "reset", "Reset"),
        Binding("g", "start", "Start"),
        Binding("m", "metadata", "Operator/notes"),
        Binding("b", "reopen", "Open the bench again"),
        Binding("p", "pause", "Pause", priority=True),
        Binding("r", "resume", "Resume", priority=True),
        Binding("a", "abort", "Abort", priority=True),
        # the same from a prompt's text field, where p, r and a are typed (shown in its dialog)
        Binding("f6", "pause('f6')", "Pause", priority=True, show=False),
        Binding("f7", "resume('f7')", "Resume", priority=True, show=False),
        Binding("f8", "abort('f8')", "Abort", priority=True, show=False),
        Binding("q", "quit", "Quit", priority=True),
    ]
    #: Nothing is focused by default: each pane sets its own focus (:meth:`action_pane`), so that a
    #: widget of a hidden pane (a text field above all, which takes the printable keys) never
    #: holds the focus when a dialog closes.
    AUTO_FOCUS = None
    ENABLE_COMMAND_PALETTE = False

    def __init__(
        self,
        config_path: Path | None = None,
        out_path: Path = Path("campaign.h5"),
        monitor: MonitorFeed | None = None,
        monitor_url: str | None = None,
    ) -> None:
        """``monitor``: the web monitor's feed (``--monitor``), fed by the bench session; its
        address (``monitor_url``) is said when the UI starts."""
        super().__init__()
        self.monitor_url = monitor_url
        self.session = BenchSession(
            config_path, out_path, lambda p: self.post_message(SessionMessage(p)), monitor
        )
        self.plan = None
        self.bench_name = "bench"
        self.interlock_names: tuple[str, ...] = ()
        self.controller: ControllerStatus | None = None
        self.tripped: dict[str, str] = {}
        self.failure: str | None = None  # why the last sequence failed, until a reset or a start
        self.unopened: str | None = None  # why the bench could not be opened, until it opens
        #: the operator and notes typed in (m), recorded with the runs the next sequences begin
        self.run_metadata: dict[str, str] = {}
        self.refreshes = 0  # redraws of the live view (the benchmark reads the rate)
        self.banner_text = ""  # what the banner says while it is shown
        self._keys_shown: tuple[bool | None, ...] = ()  # the footer's keys: which can act

    # -- layout ---------------------------------------------------------------------------------

    def compose(self) -> ComposeResult:
        with Horizontal(id="topbar"):
            yield Static("", id="tabs")
            yield Static("", id="state")
            yield Static("F12 E-STOP", id="estop")
        yield Static("", id="banner")
        with ContentSwitcher(initial="bench"):
            yield BenchPane(id="bench")
            yield SequencePane(id="sequence")
            yield RunPane(id="run")
            yield ResultsPane(id="results")
        yield Footer(compact=True)

    def on_mount(self) -> None:
        self.session.start()
        if self.monitor_url is not None:
            self.notify(f"web monitor: {self.monitor_url} (read-only)", timeout=30)
        self._show_tabs()
        self._refresh_timer = self.set_interval(REFRESH_S, self.refresh_live)

    def on_unmount(self) -> None:
        self._refresh_timer.stop()
        self.session.close()

    @property
    def main(self):
        """The main screen (the panes), under any dialog open above it: the session's messages
        reach its panes while a dialog is open."""
        return self.screen_stack[0]

    @property
    def pane(self) -> str:
        return self.main.query_one(ContentSwitcher).current or "bench"

    def _show_tabs(self) -> None:
        keys = dict(zip(PANES, ("F2", "F3", "F4", "F5"), strict=True))
        self.main.query_one("#tabs", Static).update(
            "  ".join(
                f"[reverse] {keys[p]} {name} [/reverse]" if p == self.pane else f"{keys[p]} {name}"
                for p, name in PANES.items()
            )
        )

    def show_banner(self, text: str) -> None:
        """Say ``text`` in the main screen's banner (a dialog open above it leaves it in view)."""
        banner = self.main.query_one("#banner", Static)
        banner.update(text)
        banner.add_class("shown")
        self.banner_text = text

    def clear_banner(self) -> None:
        self.main.query_one("#banner", Static).remove_class("shown")
        self.banner_text = ""

    # -- keys -----------------------------------------------------------------------------------

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:  # noqa: PLR0911
        """Show and allow a pane's keys on its pane only, and only when they can act; p, r and a
        wherever a sequence runs (they say why when its state refuses them)."""
        engine = self.session.engine
        running = self.session.running.is_set()
        if action in ("hydraulics", "tare", "reset"):
            return self.pane == "bench" and engine is not None and not running
        if action == "start":
            return self.pane == "sequence" and self.plan is not None and engine is not None and not running
        if action == "metadata":
            return self.pane == "sequence" and not running
        if action == "reopen":
            return self.unopened is not None
        if action in ("pause", "resume", "abort"):  # from dialogs too; p, r, a never while typing
            if self._typing() and not parameters:
                return False
            return engine is not None and (running or bool(parameters))
        if action == "quit":  # from a prompt's dialog too; the help dialog's q closes it
            return not self._typing() and not isinstance(self.screen, HelpDialog)
        return True

    def refresh_keys(self) -> None:
        """Have the footer show the keys that can act now, once they changed: the footer is built
        again at every refresh of the bindings, laying the whole screen out again, and the
        session's messages come several a second while a sequence runs."""
        acting = tuple(self.check_action(*parse_action(binding.action)[1:]) for binding in self.BINDINGS)
        if acting != self._keys_shown:
            self._keys_shown = acting
            self.refresh_bindings()

    def _typing(self) -> bool:
        """Whether the keys go into a visible text input (a prompt's answer, a sequence's path)."""
        focused = self.focused
        if not isinstance(focused, Input):
            return False
        return focused.screen is not self.screen_stack[0] or self.pane == "sequence"

    def on_key(self, event: events.Key) -> None:
        """p, r or a that no binding took (nothing runs), or g on the Sequence screen that cannot
        start anything: say why, so that a key is never silently ignored."""
        if self._typing():
            return
        verb = {"p": "pause", "r": "resume", "a": "abort"}.get(event.key)
        if verb is not None:
            why = "the bench is not open" if self.session.engine is None else "no sequence is running"
            self.notify(f"{event.key}: {why}: nothing to {verb}", severity="warning")
        elif event.key == "g" and self.pane == "sequence" and not self.check_action("start", ()):
            self.notify(f"g: {self._why_not_started()}: nothing started", severity="warning")

    def _why_not_started(self) -> str:
        if self.session.engine is None:
            return "the bench is not open"
        if self.session.running.is_set():
            return "a sequence is running"
        return "no valid sequence is checked (choose one, or fix the one shown)"

    def on_descendant_focus(self, event: events.DescendantFocus) -> None:
        """A widget of a hidden pane never keeps the focus (it would take keys meant for the app)."""
        if not self.screen_stack:  # the app is closing: its screens went first
            return
        widget, main = event.widget, self.main
        if widget.screen is not main:
            return
        pane = main.query_one(ContentSwitcher).visible_content
        if pane is not None and pane not in widget.ancestors_with_self:
            main.set_focus(self._pane_focus())

    def _pane_focus(self):
        """The widget that takes the keys on the current pane (None: the app takes them all)."""
        return self.main.query_one("#seq-shipped") if self.pane == "sequence" else None

    def action_estop(self) -> None:
        """E-stop from the key handler itself: the controller is told before this returns."""
        if self.session.engine is None:
            self.show_banner("E-STOP: no bench is open to stop")
            return
        try:
            self.session.estop()
        except Exception as exc:  # the stop could not be sent: say so, loudly
            self.show_banner(f"E-STOP NOT CONFIRMED: {exc}; use the bench's own e-stop button")
            return
        self.show_banner("E-STOP: the actuator is stopped; x on the Bench screen (F2) resets")
        self.refresh_keys()

    async def action_quit(self) -> None:
        """Quit once no sequence runs; while one does, say what to do instead of ignoring the key."""
        if self.session.running.is_set():
            self.show_banner(QUIT_WHILE_RUNNING)
            return
        self.exit()

    def action_pane(self, pane: str) -> None:
        self.main.query_one(ContentSwitcher).current = pane
        self.screen_stack[0].set_focus(self._pane_focus())  # a hidden input keeps no keys
        self._show_tabs()
        self.refresh_keys()
        self.refresh_live()

    def action_help(self) -> None:
        self.push_screen(HelpDialog())

    def action_hydraulics(self, level: str) -> None:
        self._confirmed(f"Switch the hydraulics {level}?", lambda: self.session.hydraulics(level))

    def action_tare(self) -> None:
        self._confirmed("Tare the WFS now (the wheel unloaded and at rest)?", self.session.tare)

    def action_reset(self) -> None:
        self._confirmed("Reset the interlock / e-stop (the cause is cleared)?", self.session.reset)

    def _confirmed(self, question: str, then) -> None:
        def answered(yes: bool | None) -> None:
            if yes:
                then()

        self.push_screen(ConfirmDialog(question), answered)

    def action_metadata(self) -> None:
        """The operator and notes for the runs to come, in a dialog; kept until changed again."""

        def answered(fields: dict[str, str] | None) -> None:
            if fields is not None:
                self.run_metadata = {name: value for name, value in fields.items() if value}
                self.main.query_one(SequencePane).show_metadata(self.run_metadata)

        self.push_screen(MetadataDialog(self.run_metadata), answered)

    def action_reopen(self) -> None:
        """Open the bench again after it could not be opened (the configuration is read again)."""
        if self.session.reopen():
            self.unopened = None
            self.clear_banner()
            self.main.query_one(BenchPane).show_opening()
            self.refresh_keys()

    def action_start(self) -> None:
        """Start the checked sequence; when the campaign file holds runs of it already, offer to
        resume them (its complete runs and points skipped, as ``wfsbench run --resume``), unless
        every run of it is complete there: then nothing is left to resume, and it says so."""
        plan, out = self.plan, self.session.out_path
        try:
            held = self.session.held_runs(plan)
        except StoreError as exc:
            self.show_banner(f"the sequence did not start: {exc} (quit and give another --out)")
            return
        if not held.statuses:
            self._start(plan, resume=False)
            return
        name = plan.sequence.name
        if held.complete:
            self.notify(
                f"{out} holds sequence {name!r} complete (its {len(held.statuses)} run(s) all complete):"
                " nothing to resume; to run it again, quit and give another --out",
                title="nothing started",
                severity="warning",
                timeout=20,
            )
            return

        def answered(yes: bool | None) -> None:
            if yes:
                self._start(plan, resume=True)
            else:
                self.notify(
                    f"nothing started: {out} keeps its runs of {name!r};"
                    " to run it afresh, quit and give another --out",
                    severity="warning",
                )

        statuses = sorted(set(held.statuses.values()))
        counts = ", ".join(f"{list(held.statuses.values()).count(s)} {s}" for s in statuses)
        self.push_screen(
            ConfirmDialog(
                f"{out} holds {len(held.statuses)} run(s) of sequence {name!r} already ({counts})."
                " Resume it? Its complete runs and done points are skipped; the prompts before its"
                " unfinished runs are asked again."
            ),
            answered,
        )

    def _start(self, plan: CampaignPlan, *, resume: bool) -> None:
        plan = plan.with_metadata(self.run_metadata)  # what was typed in wins over the files' values
        self.clear_banner()
        self.tripped.clear()
        self.failure = None
        self.main.query_one(ResultsPane).clear_results()
        self.session.start_sequence(plan, resume=resume)
        self.action_pane("run")

    #: Why a request is refused, by action and engine state (others: "the sequence is <state>").
    REFUSED: ClassVar[dict[str, dict[RunState, str]]] = {
        "pause": {
            RunState.PAUSING: "a pause is requested already: the point under way tapers out, then"
            " the sequence waits (r resumes)",
            RunState.PAUSED: "the sequence is paused already: r resumes it, a aborts it",
            RunState.ABORTING: "the sequence is aborting: nothing to pause",
        },
        "resume": {
            RunState.RUNNING: "the sequence is running, not paused: nothing to resume (p pauses)",
            RunState.ABORTING: "the sequence is aborting: it cannot resume",
        },
        "abort": {RunState.ABORTING: "the sequence is aborting already: the excitation tapers out"},
    }

    def _request(self, verb: str, key: str, request) -> None:
        """p, r or a (or F6, F7, F8): request it of the engine, or say why nothing happens."""
        engine = self.session.engine
        if engine is None or not self.session.running.is_set():
            why = "the bench is not open" if engine is None else "no sequence is running"
            self.notify(f"{key}: {why}: nothing to {verb}", severity="warning")
            return
        if request():
            if verb == "pause" and isinstance(self.screen, PromptDialog):
                self.notify("pause requested: it is taken once the prompt is answered")
            self.refresh_live()
            return
        state = engine.state
        why = self.REFUSED[verb].get(state) or (
            f"the sequence is {state.value}: nothing to {verb}"
            if state in ACTIVE
            else f"the sequence is not under way (state {state.value}): nothing to {verb}"
        )
        self.notify(f"{key}: {why}", severity="warning")

    def action_pause(self, key: str = "p") -> None:
        self._request("pause", key, self.session.pause)

    def action_resume(self, key: str = "r") -> None:
        self._request("resume", key, self.session.resume)

    def action_abort(self, key: str = "a") -> None:
        self._request("abort", key, self.session.abort)

    # -- the sequence pane's inputs ---------------------------------------------------------------

    def on_option_list_option_selected(self, event: OptionList.OptionSelected) -> None:
        self._check(shipped_file(str(event.option.prompt)))

    def on_input_submitted(self, event: Input.Submitted) -> None:
        if event.input.id == "seq-path" and event.value.strip():
            self._check(Path(event.value.strip()).expanduser())

    def _check(self, path: Path) -> None:
        self.plan = None
        self.refresh_keys()
        self.main.query_one(SequencePane).show_checking(str(path))
        self.session.check(path)

    # -- what the session reports -----------------------------------------------------------------

    def on_session_message(self, message: SessionMessage) -> None:
        try:
            self._show(message.payload)
            self.refresh_keys()
        except (NoMatches, IndexError, ScreenStackError):  # the app is closing: its screens go first
            return

    def _show(self, p: object) -> None:  # noqa: PLR0912 - one branch a kind
        match p:
            case BenchOpened():
                self.bench_name, self.interlock_names = p.description, p.interlocks
                self.unopened = None
            case BenchUnopened():
                self.unopened = p.reason
                self.show_banner(f"the bench did not open: {p.reason} (b: open it again)")
                self.main.query_one(BenchPane).show_unopened(p.reason)
            case BenchFault():
                self.show_banner(p.reason)
            case CommandFailed():
                self.notify(f"{p.what}: {p.reason}", severity="error")
            case ControllerStatus():
                self.controller = p
            case PlanChecked():
                pane = self.main.query_one(SequencePane)
                if p.plan is None:
                    pane.show_error(str(p.path), p.error)
                else:
                    self.plan = p.plan
                    pane.show_plan(p.plan)
                    if self.pane == "sequence" and self.focused is self.main.query_one("#seq-path"):
                        # the path is checked: g must start it, not go into the field
                        self.screen_stack[0].set_focus(self.main.query_one("#seq-shipped"))
            case PromptRequest():
                self.push_screen(PromptDialog(p.prompt), self.session.answer)
            case PastRuns():
                self.main.query_one(ResultsPane).show_runs(p.runs)
            case RunResult():
                self.main.query_one(ResultsPane).add_result(p.run_id, p.lines, p.bode)
            case SequenceLaunched():
                self.main.query_one(RunPane).launched(p)
            case ev.SequenceStarted():
                self.main.query_one(RunPane).sequence_started(p)
            case ev.PointStarted():
                self.main.query_one(RunPane).point_started(p)
            case ev.GridRefined():
                self.notify(self.main.query_one(RunPane).grid_refined(p), title="adaptive grid")
            case ev.PointDone():
                self.main.query_one(RunPane).point_done(p)
            case ev.InterlockTripped():
                self.tripped[p.name] = p.reason
                self.show_banner(f"INTERLOCK {p.name}: {p.reason}")
            case ev.RunFinished() if p.status == "failed" or (p.status == "interlocked" and not self.tripped):
                self.show_banner(f"run {p.run_id} {p.status}: {p.reason}")
            case ev.StateChanged() if is_reset(p):
                self.tripped.clear()
                self.failure = None
                self.clear_banner()
            case ev.SequenceFinished():
                self._sequence_finished(p)

    def _sequence_finished(self, event: ev.SequenceFinished) -> None:
        if isinstance(self.screen, PromptDialog):  # an abort ended the sequence while it asked
            self.screen.close_unanswered()
        self.main.query_one(RunPane).sequence_finished(event)
        if self.banner_text == QUIT_WHILE_RUNNING:  # it has ended: q quits now
            self.clear_banner()
        why = f": {event.reason}" if event.reason else ""
        if event.status == "complete":
            self.notify(f"sequence complete; file {self.session.out_path}")
            self.action_pane("results")
        elif event.status == "failed":
            self.failure = event.reason
            self.show_banner(f"sequence failed{why} (x on the Bench screen, F2, resets)")
        else:
            self.notify(f"sequence {event.status}{why}", severity="warning")

    # -- the live view ----------------------------------------------------------------------------

    def refresh_live(self) -> None:
        """Redraw what moves: the state line, and the visible pane's values or plots."""
        try:
            self._refresh_live()
        except (NoMatches, IndexError, ScreenStackError):  # the app is closing: its widgets go first
            return
        self.refreshes += 1

    def _state_text(self) -> str:
        engine = self.session.engine
        if engine is not None:
            return engine.state.value
        return "not open" if self.unopened is not None else "opening"

    def _refresh_live(self) -> None:
        engine = self.session.engine
        state = self._state_text()
        running = self.session.running.is_set()
        state_line = self.main.query_one("#state", Static)
        # the state first, in its colour; the bench after it when the line has room for it
        shown = f"[{TONE_STYLES[state_tone(state)]}]{state}[/]"
        if len(state) + 3 + len(self.bench_name) <= state_line.content_region.width:
            shown += f"   {self.bench_name}"
        show_text(state_line, shown)
        trace = self.session.trace
        if self.pane == "run":
            run = self.main.query_one(RunPane)
            run.show_progress(state, self.session.pace)
            if trace is not None:
                run.show_trace(trace)
        elif self.pane == "bench" and engine is not None and self.session.devices is not None:
            devices = self.session.devices
            self.main.query_one(BenchPane).show(
                bench=self.bench_name,
                engine_state=state,
                controller=self.controller,
                actuator_fault=devices.actuator.link_fault(),
                wfs_connected=devices.acquisition.wait_connected(0),
                tripped=self.tripped,
                failure=self.failure,
                interlocks=self.interlock_names,
                trace=trace,
                running=running,
                counters=devices.acquisition.link_counters(),
            )
