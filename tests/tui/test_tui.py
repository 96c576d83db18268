"""The terminal UI driven by keys through ``App.run_test()`` on the simulated bench: the smoke
sequence with its prompts (a bad answer refused), pause and resume, abort, an e-stop read back from
the controller over Modbus TCP, a bad sequence file, a link lost mid-run; SVG screenshots of every
screen and dialog."""

from __future__ import annotations

import asyncio
import threading
from pathlib import Path

import numpy as np
import pytest
from rich.text import Text

from bench.app.analysis_plan import analysis_limits
from bench.app.pace import SequencePace
from bench.engine import events as ev
from bench.engine.engine import GO_ON_DESPITE
from bench.engine.states import RunState
from bench.store import open_campaign
from bench.tui.app import SessionMessage, WfsBenchApp
from bench.tui.dialogs import HELP_TEXT, ConfirmDialog, HelpDialog, PromptDialog
from bench.tui.session import BodeCurves, PastRun, PastRuns, RunResult
from drivers.actuator import ActuatorClient
from drivers.register_map import Command, ControllerState
from drivers.wfs_frame import Status
from tests.tui.keys import press
from tests.waiting import async_wait_until

FILES = Path(__file__).parent / "files"
#: Bound of every wait (s): generous for a busy machine; the waits end on events, not on time. The
#: prompt after a free run waits for the engine's run gate, which waits for the free run's analysis
#: in its child process: beside four busy processes and two other test workers (whose tests start
#: processes of their own) that took over 60 s in 2 of 6 full runs of the suite.
TIMEOUT_S = 120.0


class Recorded:
    """The engine's events, recorded from its thread."""

    def __init__(self) -> None:
        self.events: list[ev.Event] = []
        self._lock = threading.Lock()

    def __call__(self, event: ev.Event) -> None:
        if not isinstance(event, ev.SamplesRecorded):
            with self._lock:
                self.events.append(event)

    def of(self, kind: type) -> list:
        with self._lock:
            return [e for e in self.events if isinstance(e, kind)]


async def until(pilot, condition, what: str) -> None:
    async def check():
        await asyncio.sleep(0.02)
        return condition()

    await async_wait_until(check, TIMEOUT_S, what)


async def open_app(pilot, app: WfsBenchApp) -> Recorded:
    await until(pilot, lambda: app.session.opened.is_set() or app.unopened, "the bench to open")
    assert app.unopened is None, f"the bench did not open: {app.unopened}"
    recorded = Recorded()
    app.session.engine.bus.subscribe(recorded)
    return recorded


async def check_smoke(pilot, app: WfsBenchApp) -> None:
    await press(pilot, "f3")
    app.query_one("#seq-shipped").focus()
    await press(pilot, "enter")  # smoke.toml is the first shipped sequence
    await until(pilot, lambda: app.plan is not None, "the smoke sequence checked")


async def type_path(pilot, app: WfsBenchApp, path: Path) -> None:
    """A sequence file's path into the path field, then Enter. The text is set at once: each
    simulated key press waits for the app to look idle, which a live 10 Hz view never is."""
    field = app.query_one("#seq-path")
    field.focus()
    field.value = str(path)
    await press(pilot, "enter")


async def screenshot(pilot, app: WfsBenchApp, name: str, shots: Path, words: tuple[str, ...]) -> str:
    """Save an SVG of the screen once it shows ``words`` (a screen just switched to, or a dialog
    just opened, is drawn at the app's next refresh, later on a loaded machine); returns its path."""
    await until(pilot, lambda: all(w in app.export_screenshot() for w in words), f"{name} drawn")
    return app.save_screenshot(name, str(shots))


async def screenshot_text(pilot, app: WfsBenchApp, words: tuple[str, ...]) -> str:
    """The first screenshot (SVG text) that shows ``words``: the frame drawn after what was posted."""
    shown = [""]

    def drawn() -> bool:
        shown[0] = app.export_screenshot()
        return all(w in shown[0] for w in words)

    await until(pilot, drawn, f"{words} drawn")
    return shown[0]


async def prompt_open(pilot, app: WfsBenchApp, prompt_id: str) -> PromptDialog:
    await until(
        pilot,
        lambda: (
            isinstance(app.screen, PromptDialog)
            and app.screen.prompt.id == prompt_id
            and bool(app.screen.query("#prompt-text"))  # composed: it takes keys
            # an answer typed in goes into the field once the cursor is there, as a technician sees
            and (
                app.screen.prompt.answer == "confirm" or app.focused is app.screen.query_one("#prompt-input")
            )
        ),
        f"prompt {prompt_id}",
    )
    return app.screen


def finished(recorded: Recorded) -> ev.SequenceFinished | None:
    done = recorded.of(ev.SequenceFinished)
    return done[0] if done else None


#: The reply timeout of the test's own client of the controller: a peer on a machine as busy as a
#: test run beside four busy processes (the bench's own client keeps its 0.3 s).
SIDE_TIMEOUT_S = 5.0


def side_client(app: WfsBenchApp) -> ActuatorClient:
    """A client of the simulated controller of the test's own, beside the bench's."""
    return ActuatorClient.tcp(*app.session.devices.lab.address, timeout_s=SIDE_TIMEOUT_S)


async def controller_state(app: WfsBenchApp) -> ControllerState:
    """The simulated controller's state, read over Modbus TCP by a client of its own."""
    client = side_client(app)
    try:
        return (await client.connect()).state
    finally:
        await client.close()


def text_of(node, selector: str) -> str:
    """The text a widget under ``node`` (the app or a dialog) shows."""
    return str(node.query_one(selector).render())


def screen_lines(app: WfsBenchApp) -> list[str]:
    """The terminal's rows as plain text, as drawn now (the dialog above the panes included)."""
    return [strip.text for strip in app.screen._compositor.render_strips()]


async def test_smoke_sequence_through_the_ui(app: WfsBenchApp, tmp_path: Path) -> None:
    """Prompts answered in dialogs (a bad pressure refused and asked again), a pause and a resume,
    the sequence to its end and its results; an SVG of every screen and dialog on the way."""
    shots = tmp_path / "shots"
    shots.mkdir()
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        await until(pilot, lambda: app.controller is not None, "the controller status read")
        await pilot.pause()
        bench_words = ("interlocks", "controller", "hydraulics")
        bench_svg = await screenshot(pilot, app, "bench.svg", shots, bench_words)
        await press(pilot, "question_mark")
        await until(pilot, lambda: isinstance(app.screen, HelpDialog), "the help")
        help_svg = await screenshot(pilot, app, "help.svg", shots, ("E-STOP", "Keys"))
        await press(pilot, "escape")
        await check_smoke(pilot, app)
        sequence_svg = await screenshot(pilot, app, "sequence.svg", shots, ("smoke", "valid", "points"))
        await press(pilot, "g")

        dialog = await prompt_open(pilot, app, "remove_wheel")
        prompt_svg = await screenshot(pilot, app, "prompt.svg", shots, ("Remove", "E-STOP"))
        await press(pilot, "p")  # the pause is taken at the checkpoint after the answer
        await press(pilot, "y")
        await until(pilot, lambda: app.session.engine.state is RunState.PAUSED, "the pause")
        # the progress line follows the engine at the live view's next refresh (10 Hz)
        await until(pilot, lambda: "paused" in text_of(app, "#run-progress"), "the pause shown")
        await press(pilot, "r")
        await until(pilot, lambda: app.session.engine.state is not RunState.PAUSED, "the resume")

        dialog = await prompt_open(pilot, app, "fit_wheel")
        run_svg = await screenshot(pilot, app, "run.svg", shots, ("commanded", "displacement", "forces"))
        await press(pilot, "y")
        dialog = await prompt_open(pilot, app, "pressure")
        await press(pilot, *"9.9", "enter")
        await until(pilot, lambda: "9.9" in text_of(dialog, "#prompt-error"), "the refusal of 9.9 bar")
        assert app.screen is dialog, "a pressure beyond 0.5..4.5 bar must not close the dialog"
        assert "0.5..4.5" in text_of(dialog, "#prompt-error")
        await press(pilot, *"2.5", "enter")

        await until(pilot, lambda: finished(recorded) is not None, "the end of the sequence")
        assert finished(recorded).status == "complete", finished(recorded).reason
        await until(pilot, lambda: app.pane == "results", "the results screen")
        await until(
            pilot, lambda: app.query_one("#results-runs").row_count == 3, "the runs of the file listed"
        )
        results_svg = await screenshot(
            pilot, app, "results.svg", shots, ("F_wfs/F_contact", "phase", "complete")
        )
        table = app.query_one("#results-runs")
        assert [table.get_row_at(i)[2] for i in range(3)] == ["complete"] * 3
        lines = text_of(app, "#results-lines")
        assert "m_comp" in lines and "Model 2" in lines
        assert app.query_one("#bode-mag").series, "the Bode plot of the grid is drawn"
        assert "compensated" in text_of(app, "#results-bands")

    asked = [e.prompt_id for e in recorded.of(ev.PromptAsked)]
    assert asked == ["remove_wheel", "fit_wheel", "pressure"], "a refused answer never reaches the engine"
    assert [e.answer for e in recorded.of(ev.PromptAnswered)] == [True, True, 2.5]
    assert recorded.of(ev.StateChanged)[0].new is RunState.RUNNING
    assert any(e.new is RunState.PAUSED for e in recorded.of(ev.StateChanged))
    with open_campaign(tmp_path / "campaign.h5") as campaign:
        grid = campaign.run("smoke-s009-dwell_grid")
        assert grid.status == "complete"
        assert grid.conditions["tyre_pressure_bar"] == 2.5 and grid.conditions["pressure"] == 2.5
    expected = {
        bench_svg: ("interlocks", "controller", "hydraulics"),
        help_svg: ("E-STOP", "Keys"),
        sequence_svg: ("smoke", "valid", "points"),
        prompt_svg: ("Remove", "E-STOP"),
        run_svg: ("commanded", "displacement", "forces"),
        results_svg: ("F_wfs/F_contact", "phase", "complete"),
    }
    for path, words in expected.items():
        svg = Path(path).read_text()
        assert svg.startswith("<svg"), path
        for word in words:
            assert word in svg, f"{Path(path).name} lacks {word!r}"


async def start_long_dwell(pilot, app: WfsBenchApp) -> Recorded:
    """The long dwell typed in as an own file, started; returns once its point runs."""
    recorded = await open_app(pilot, app)
    await press(pilot, "f3")
    await type_path(pilot, app, FILES / "long_dwell.toml")
    await until(pilot, lambda: app.plan is not None, "the long dwell checked")
    app.query_one("#seq-shipped").focus()
    await press(pilot, "g")
    await until(pilot, lambda: recorded.of(ev.PointStarted), "the dwell started")
    return recorded


async def test_abort_mid_run_keeps_the_data(paced_app: WfsBenchApp, tmp_path: Path) -> None:
    """a during the dwell tapers it out and ends the sequence as aborted; the samples stay."""
    app = paced_app
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await start_long_dwell(pilot, app)
        await press(pilot, "a")
        await until(pilot, lambda: finished(recorded) is not None, "the end of the sequence")
        assert finished(recorded).status == "aborted", finished(recorded).reason
        assert "aborted" in text_of(app, "#run-progress") or app.session.engine.state.value == "aborted"
    with open_campaign(tmp_path / "campaign.h5") as campaign:
        (run,) = campaign.runs
        assert run.status == "aborted" and run.n_samples > 0


async def test_abort_while_a_prompt_waits(app: WfsBenchApp) -> None:
    """a with a prompt's dialog open: no answer is given, the sequence ends as aborted and the
    dialog closes."""
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        await check_smoke(pilot, app)
        await press(pilot, "g")
        await prompt_open(pilot, app, "remove_wheel")
        await press(pilot, "a")
        await until(pilot, lambda: finished(recorded) is not None, "the end of the sequence")
        assert finished(recorded).status == "aborted", finished(recorded).reason
        assert "remove_wheel" in finished(recorded).reason
        await until(pilot, lambda: not isinstance(app.screen, PromptDialog), "the dialog closed")
        assert not recorded.of(ev.PromptAnswered)


async def test_q_while_a_sequence_runs_says_so_and_quits_nothing(app: WfsBenchApp) -> None:
    """q with the sequence waiting at a prompt: the banner says how to end it, the UI stays, the
    Run screen says the operator is awaited. Once the sequence is aborted, the screen says it ended:
    the banner gone, the clocks stopped, no point under way, empty plots, no p / r / a offered;
    q quits."""
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        await check_smoke(pilot, app)
        await press(pilot, "g")
        await prompt_open(pilot, app, "remove_wheel")
        await press(pilot, "q")
        main = app.screen_stack[0]
        await until(pilot, lambda: "sequence is under way" in text_of(main, "#banner"), "the banner")
        assert app.is_running and isinstance(app.screen, PromptDialog)
        assert app.pane == "run"
        await until(pilot, lambda: "waiting for the operator" in text_of(main, "#run-progress"), "the wait")
        await press(pilot, "a")
        await until(pilot, lambda: finished(recorded) is not None, "the end of the sequence")
        await until(pilot, lambda: not app.session.running.is_set(), "the session idle")
        await until(pilot, lambda: not main.query_one("#banner").has_class("shown"), "the banner gone")
        step = text_of(main, "#run-step")
        assert step.startswith("smoke aborted: ") and step.endswith("; no point under way"), step
        assert all(not main.query_one(p).series for p in ("#plot-force", "#plot-disp"))
        assert not app.check_action("pause", ()) and not app.check_action("abort", ())
        # the progress line follows at the live view's next refresh (10 Hz)
        await until(pilot, lambda: text_of(main, "#run-progress").endswith("aborted"), "the line's end")
        ended = text_of(main, "#run-progress")
        redraws = app.refreshes
        await until(pilot, lambda: app.refreshes >= redraws + 5, "five redraws of the live view")
        assert text_of(main, "#run-progress") == ended  # the elapsed clock stopped at the end
        await press(pilot, "q")
        await until(pilot, lambda: not app.is_running, "the UI to quit")


async def test_estop_mid_run_stops_the_controller(paced_app: WfsBenchApp) -> None:
    """F12 during a point: the simulated controller reads back e-stop over Modbus TCP at once; x
    (confirmed) resets, and the sequence runs again."""
    app = paced_app
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await start_long_dwell(pilot, app)
        await press(pilot, "f12")
        assert await controller_state(app) is ControllerState.ESTOP  # read right after the key
        assert "E-STOP" in text_of(app, "#banner")
        await until(pilot, lambda: finished(recorded) is not None, "the end of the sequence")
        assert finished(recorded).status == "e-stopped", finished(recorded).reason

        await until(pilot, lambda: not app.session.running.is_set(), "the sequence's end")
        await press(pilot, "f2", "x")  # reset, confirmed
        await until(pilot, lambda: isinstance(app.screen, ConfirmDialog), "the confirmation")
        await press(pilot, "y")
        await until(pilot, lambda: app.session.engine.state is RunState.HYDRAULICS_LOW, "the reset")
        # the UI hears of the state change by a message after the engine's state has changed
        await until(pilot, lambda: not app.query_one("#banner").has_class("shown"), "the banner gone")
        app.session.out_path = app.session.out_path.with_name("after-reset.h5")
        points = len(recorded.of(ev.PointStarted))
        await press(pilot, "f3", "g")  # the checked dwell again: it starts once the controller is ready
        await until(pilot, lambda: len(recorded.of(ev.PointStarted)) > points, "the dwell after the reset")
        await press(pilot, "a")
        await until(pilot, lambda: len(recorded.of(ev.SequenceFinished)) == 2, "the second sequence's end")
        assert recorded.of(ev.SequenceFinished)[1].status == "aborted"


async def test_estop_from_a_dialog(app: WfsBenchApp) -> None:
    """F12 works while a confirmation dialog waits for y / n; the dialog's own question is not
    answered by it."""
    async with app.run_test(size=(120, 40)) as pilot:
        await open_app(pilot, app)
        await press(pilot, "l")  # hydraulics low: asks first
        await until(pilot, lambda: isinstance(app.screen, ConfirmDialog), "the confirmation")
        await press(pilot, "f12")
        assert await controller_state(app) is ControllerState.ESTOP  # read right after the key
        assert app.session.engine.state is RunState.ESTOPPED
        assert isinstance(app.screen, ConfirmDialog)
        await press(pilot, "n")
        assert not isinstance(app.screen, ConfirmDialog)


async def test_estop_while_a_prompt_waits(app: WfsBenchApp) -> None:
    """F12 in a prompt's dialog stops the controller at once; the answer then given ends the
    sequence as e-stopped (the simulated world is not touched while stopped)."""
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        await check_smoke(pilot, app)
        await press(pilot, "g")
        dialog = await prompt_open(pilot, app, "remove_wheel")
        await press(pilot, "f12")
        assert await controller_state(app) is ControllerState.ESTOP  # read right after the key
        assert app.screen is dialog
        await press(pilot, "y")
        await until(pilot, lambda: finished(recorded) is not None, "the end of the sequence")
        assert finished(recorded).status == "e-stopped", finished(recorded).reason
        assert app.session.devices.lab.world.specimen_mounted


async def test_bad_sequence_file_shows_key_and_range(app: WfsBenchApp, tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(
        '[sequence]\nname = "bad"\n\n[[steps]]\ntype = "sine_dwell"\nfreq_hz = 900\namplitude_mm = 2\n'
    )
    async with app.run_test(size=(120, 40)) as pilot:
        await open_app(pilot, app)
        await press(pilot, "f3")
        await type_path(pilot, app, bad)
        await until(pilot, lambda: "cannot run" in text_of(app, "#seq-report"), "the refusal")
        report = text_of(app, "#seq-report")
        assert str(bad) in report
        assert "steps[0].freq_hz" in report and "0.1 <= freq_hz <= 100 Hz" in report
        app.query_one("#seq-shipped").focus()
        await press(pilot, "g")
        said = "g: no valid sequence is checked (choose one, or fix the one shown): nothing started"
        await until(pilot, lambda: any(n.message == said for n in app._notifications), "g's answer")
        assert not app.session.running.is_set(), "nothing starts until the sequence is valid"


async def test_link_lost_mid_run_shows_a_banner(paced_app: WfsBenchApp) -> None:
    """The Modbus link dropped during the dwell: an interlock banner with the reason."""
    app = paced_app
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await start_long_dwell(pilot, app)
        app.session.devices.lab.drop_controller_link()
        await until(pilot, lambda: finished(recorded) is not None, "the end of the sequence")
        assert finished(recorded).status == "interlocked", finished(recorded).reason
        await until(pilot, lambda: app.query_one("#banner").has_class("shown"), "the banner")
        banner = text_of(app, "#banner")
        assert "INTERLOCK actuator link lost" in banner
        assert "Traceback" not in banner


async def test_points_an_adaptive_grid_adds_are_told_with_their_reason(app: WfsBenchApp) -> None:
    """GridRefined: the technician is told which point is added and why; the total grows and the
    points table shows the reason beside the added point."""
    async with app.run_test(size=(120, 40)) as pilot:
        await open_app(pilot, app)
        run_id = "adaptive-s003-dwell_grid"
        pace = app.session.pace = SequencePace()

        def deliver(event: ev.Event) -> None:  # as the session does: to the pace, then to the app
            pace(event)
            app.post_message(SessionMessage(event))

        deliver(ev.SequenceStarted("adaptive", "", "", 9, 60.0))
        deliver(ev.GridRefined(run_id, 2.0, ((40.8, "model peak"),)))
        done = ev.PointDone(
            9,
            40.8,
            2.0,
            0,
            100,
            900,
            1000,
            status="done",
            attempt=1,
            requested_amplitude_mm=2.0,
            commanded_amplitude_mm=2.0,
            achieved_amplitude_mm=2.0,
            added_reason="model peak",
            run_id=run_id,
        )
        deliver(done)
        await press(pilot, "f4")
        await until(pilot, lambda: app.query_one("#run-points").row_count == 1, "the added point's row")
        notes = [n.message for n in app._notifications]
        assert f"{run_id}: point added at 2 mm: 40.8 Hz (model peak)" in notes
        row = app.query_one("#run-points").get_row_at(0)
        assert row[1:4] == ["9", "40.8", "done"] and row[-1] == "model peak"
        await until(pilot, lambda: "points 1/10" in text_of(app, "#run-progress"), "the grown total")


class PauseInTheSweep:
    """Requests a pause through the session (what `p` does) from the engine's thread, once the
    sweep's frames show the controller's hold output: the sweep is then surely under way."""

    def __init__(self, app: WfsBenchApp, run_id: str) -> None:
        self.app, self.run_id = app, run_id
        self.requested = False

    def __call__(self, event: ev.Event) -> None:
        if self.requested or not isinstance(event, ev.SamplesRecorded) or event.run_id != self.run_id:
            return
        if (np.asarray(event.columns["status"]) & int(Status.AMPLITUDE_HOLD)).any():
            self.requested = True
            self.app.session.pause()


async def answer_smoke_prompts(pilot, app: WfsBenchApp) -> None:
    await prompt_open(pilot, app, "remove_wheel")
    await press(pilot, "y")
    await prompt_open(pilot, app, "fit_wheel")
    await press(pilot, "y")
    await prompt_open(pilot, app, "pressure")
    await press(pilot, *"2.5", "enter")


@pytest.mark.validation
async def test_a_pause_during_the_sweep_repeats_it_on_resume(app: WfsBenchApp, tmp_path: Path) -> None:
    """p while the smoke's sweep runs: the engine waits paused, r runs the sweep again from its
    start, and the sequence completes; the file holds the sweep once interrupted, once done."""
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        pause = PauseInTheSweep(app, "smoke-s010-sweep")
        app.session.engine.bus.subscribe(pause)
        await check_smoke(pilot, app)
        await press(pilot, "g")
        await answer_smoke_prompts(pilot, app)
        await until(
            pilot,
            lambda: app.session.engine.state is RunState.PAUSED or finished(recorded),
            "the pause in the sweep",
        )
        assert finished(recorded) is None, finished(recorded)
        assert pause.requested
        await press(pilot, "r")
        await until(pilot, lambda: finished(recorded) is not None, "the end of the sequence")
        assert (finished(recorded).status, finished(recorded).reason) == ("complete", "")
        assert not app.query_one("#banner").has_class("shown")
    sweep = [p for p in recorded.of(ev.PointDone) if p.run_id == "smoke-s010-sweep"]
    assert [(p.status, p.attempt) for p in sweep] == [("interrupted", 1), ("done", 2)]
    with open_campaign(tmp_path / "campaign.h5") as campaign:
        run = campaign.run("smoke-s010-sweep")
        assert run.status == "complete"
        assert [p.status for p in run.points] == ["interrupted", "done"]


async def switch_controller_off(app: WfsBenchApp) -> None:
    """The hydraulics switched off at the controller itself (its own panel), over Modbus TCP by a
    client of its own: the engine is not told."""
    client = side_client(app)
    try:
        await client.connect()
        await client.command(Command.HYDRAULICS_OFF)
    finally:
        await client.close()


async def test_a_reset_after_a_refused_command_readies_the_bench_again(app: WfsBenchApp) -> None:
    """The controller refuses the smoke's hydraulics high (switched off at its panel meanwhile):
    the sequence fails, the banner and a lamp say why and that x resets; x (confirmed) brings the
    controller to hydraulics low and the engine with it, and the sequence starts again."""
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        await check_smoke(pilot, app)
        await press(pilot, "g")
        await prompt_open(pilot, app, "remove_wheel")
        await switch_controller_off(app)
        await press(pilot, "y")
        await until(pilot, lambda: finished(recorded) is not None, "the end of the sequence")
        assert finished(recorded).status == "failed", finished(recorded).reason
        assert "HYDRAULICS_HIGH" in finished(recorded).reason
        await until(pilot, lambda: not app.session.running.is_set(), "the sequence's end")
        assert app.session.engine.state is RunState.FAILED
        assert "x on the Bench screen" in text_of(app, "#banner")

        await press(pilot, "f2")
        await until(pilot, lambda: "sequence failed" in text_of(app, "#bench-lamps"), "the failure lamp")
        await press(pilot, "x")
        await until(pilot, lambda: isinstance(app.screen, ConfirmDialog), "the confirmation")
        await press(pilot, "y")
        await until(pilot, lambda: app.session.engine.state is RunState.HYDRAULICS_LOW, "the reset")
        assert await controller_state(app) is ControllerState.HYDRAULICS_LOW
        await until(pilot, lambda: not app.query_one("#banner").has_class("shown"), "the banner gone")
        await until(pilot, lambda: "sequence failed" not in text_of(app, "#bench-lamps"), "the lamp off")

        app.session.out_path = app.session.out_path.with_name("after-reset.h5")
        await press(pilot, "f3", "g")
        await prompt_open(pilot, app, "remove_wheel")
        await press(pilot, "a")
        await until(pilot, lambda: len(recorded.of(ev.SequenceFinished)) == 2, "the second sequence's end")
        assert recorded.of(ev.SequenceFinished)[1].status == "aborted"


async def test_a_file_that_is_no_campaign_file_is_named_once(tmp_path: Path) -> None:
    out = tmp_path / "not.h5"
    out.write_text("not HDF5\n")
    app = WfsBenchApp(None, out)
    async with app.run_test(size=(120, 40)) as pilot:
        await open_app(pilot, app)
        await until(pilot, lambda: app.query_one("#banner").has_class("shown"), "the banner")
        banner = text_of(app, "#banner")
        assert banner.startswith(f"{out}: not a readable HDF5 file")
        assert banner.count(str(out)) == 1


class AbortInTheFreeRun:
    """Aborts through the session (what `a` does) from the engine's thread as the free run's
    second point starts: the file then holds the free run, incomplete."""

    def __init__(self, app: WfsBenchApp) -> None:
        self.app = app
        self.requested = False

    def __call__(self, event: ev.Event) -> None:
        if not self.requested and isinstance(event, ev.PointStarted) and event.index == 1:
            self.requested = True
            self.app.session.abort()


@pytest.mark.validation
async def test_g_offers_to_resume_a_sequence_the_file_holds_runs_of(app: WfsBenchApp, tmp_path: Path) -> None:
    """After an abort, g asks whether to resume the sequence in the same file: n starts nothing,
    y resumes it (the free run's done point skipped) to its end, as wfsbench run --resume does."""
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        abort = AbortInTheFreeRun(app)
        app.session.engine.bus.subscribe(abort)
        await check_smoke(pilot, app)
        await press(pilot, "g")
        await prompt_open(pilot, app, "remove_wheel")
        await press(pilot, "y")
        await until(pilot, lambda: finished(recorded) is not None, "the abort")
        assert finished(recorded).status == "aborted", finished(recorded).reason
        await until(pilot, lambda: not app.session.running.is_set(), "the sequence's end")

        await press(pilot, "f3", "g")
        await until(pilot, lambda: isinstance(app.screen, ConfirmDialog), "the offer to resume")
        question = text_of(app.screen, "#confirm-question")
        assert "holds 1 run(s) of sequence 'smoke'" in question and "Resume it" in question
        await press(pilot, "n")
        def told() -> bool:
            return any("nothing started" in n.message for n in app._notifications)

        await until(pilot, told, "n's answer")
        assert not app.session.running.is_set()

        await press(pilot, "g")
        await until(pilot, lambda: isinstance(app.screen, ConfirmDialog), "the offer again")
        await press(pilot, "y")
        await answer_smoke_prompts(pilot, app)
        await until(pilot, lambda: len(recorded.of(ev.SequenceFinished)) == 2, "the resumed sequence's end")
        assert recorded.of(ev.SequenceFinished)[1].status == "complete"
        assert not app.query_one("#banner").has_class("shown")
        await until(
            pilot, lambda: app.query_one("#results-runs").row_count == 3, "the runs of the file listed"
        )
    free_run = [p for p in recorded.of(ev.PointDone) if p.run_id == "smoke-s003-free_run"]
    assert sorted(p.index for p in free_run if p.status == "done") == [0, 1, 2]
    with open_campaign(tmp_path / "campaign.h5") as campaign:
        assert {r.run_id: r.status for r in campaign.runs} == {
            "smoke-s003-free_run": "complete",
            "smoke-s009-dwell_grid": "complete",
            "smoke-s010-sweep": "complete",
        }
        assert campaign.run("smoke-s003-free_run").completed_point_indices() == {0, 1, 2}


async def test_g_into_a_file_that_is_no_campaign_file_says_so_and_starts_nothing(tmp_path: Path) -> None:
    out = tmp_path / "not.h5"
    out.write_text("not HDF5\n")
    app = WfsBenchApp(None, out)
    async with app.run_test(size=(120, 40)) as pilot:
        await open_app(pilot, app)
        await check_smoke(pilot, app)
        await press(pilot, "g")
        await until(pilot, lambda: "did not start" in text_of(app, "#banner"), "the refusal")
        assert not app.session.running.is_set()
        banner = text_of(app, "#banner")
        assert banner.startswith(f"the sequence did not start: {out}: not a readable HDF5 file")
        assert "Error" not in banner.split(":")[1]


async def test_g_starts_a_typed_path_once_checked(paced_app: WfsBenchApp) -> None:
    """The path typed, Enter: once "g: start this sequence" shows, g starts it (it does not go
    into the path field)."""
    app = paced_app
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        await press(pilot, "f3")
        await type_path(pilot, app, FILES / "long_dwell.toml")
        await until(pilot, lambda: "start this sequence" in text_of(app, "#seq-report"), "the check")
        await press(pilot, "g")
        await until(pilot, lambda: recorded.of(ev.PointStarted), "the dwell started")
        assert app.query_one("#seq-path").value == str(FILES / "long_dwell.toml")
        await press(pilot, "a")
        await until(pilot, lambda: finished(recorded) is not None, "the end of the sequence")


async def test_the_help_breaks_no_line_at_120_by_40(app: WfsBenchApp) -> None:
    """Every line of the help fits the dialog's width, so none is split mid-phrase."""
    async with app.run_test(size=(120, 40)) as pilot:
        await open_app(pilot, app)
        await press(pilot, "question_mark")
        await until(pilot, lambda: isinstance(app.screen, HelpDialog), "the help")
        text = app.screen.query_one("#help-text")
        await until(pilot, lambda: text.content_region.width > 0, "the help laid out")
        lines = [Text.from_markup(line) for line in HELP_TEXT.split("\n")]
        widest = max(line.cell_len for line in lines)
        assert widest <= text.content_region.width, (widest, text.content_region.width)
        assert text.content_region.height == len(lines)  # as many rows as lines: none wrapped
        assert "x: reset an interlock or e-stop" in HELP_TEXT and "checked and dry-run" in HELP_TEXT


async def test_results_keep_the_plot_and_the_runs_in_view_below_a_long_analysis(app: WfsBenchApp) -> None:
    """An analysis longer than the screen (40 lines, as many flags would give) scrolls in its own
    box: the Bode plot's titles and every run of the file stay on the screen below it."""
    runs = tuple(PastRun(f"past-s{i:03d}-dwell_grid", "dwell_grid", "complete", "", 1000) for i in range(3))
    freq_hz = np.array([10.0, 20.0, 30.0, 40.0])
    curves = BodeCurves("2 mm", freq_hz, 1.0 + 0.01j * freq_hz, np.ones(4, complex), ("raw: 10-40 Hz",))
    lines = tuple(f"FLAG finding-{i:02d}" for i in range(40))
    async with app.run_test(size=(120, 40)) as pilot:
        await open_app(pilot, app)
        await press(pilot, "f5")
        app.post_message(SessionMessage(PastRuns(runs)))
        await screenshot_text(pilot, app, (runs[-1].run_id,))
        app.post_message(SessionMessage(RunResult("new-s001-dwell_grid", "shaker", lines, (curves,))))
        shown = await screenshot_text(pilot, app, ("finding-00",))
        assert "finding-39" not in shown, "the analysis is longer than its box: the test means something"
        for word in ("|F_wfs/F_contact|", "phase", *(r.run_id for r in runs)):
            assert word in shown, f"{word!r} scrolled out of view by the analysis text"


async def test_a_free_run_not_to_be_trusted_is_put_to_the_technician(app: WfsBenchApp, tmp_path: Path):
    """The smoke sequence without "Remove the wheel": the free run shakes the plate with the tyre on
    it. Before "Fit the wheel" is asked, the UI puts the reason to the technician; a no ends the
    sequence, aborted, naming the question, and the grid never starts."""
    smoke = (Path(__file__).parents[2] / "sequences" / "files" / "smoke.toml").read_text()
    sequence = tmp_path / "wheel_left_on.toml"
    sequence.write_text(smoke.replace('action = "remove_wheel"', 'action = "fit_wheel"'))
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        await press(pilot, "f3")
        await type_path(pilot, app, sequence)
        await until(pilot, lambda: "start this sequence" in text_of(app, "#seq-report"), "the check")
        await press(pilot, "g")
        await prompt_open(pilot, app, "remove_wheel")  # its action now leaves the wheel on
        await press(pilot, "y")
        dialog = await prompt_open(pilot, app, GO_ON_DESPITE)
        assert "m_comp not to be trusted" in text_of(dialog, "#prompt-text")
        await press(pilot, "n")
        await until(pilot, lambda: finished(recorded) is not None, "the end of the sequence")
        done = finished(recorded)
        assert done.status == "aborted"
        assert done.reason.startswith("the operator declined: Before smoke-s009-dwell_grid: the free run")
        assert [e.kind for e in recorded.of(ev.RunStarted)] == ["free_run"]
        assert not [e for e in recorded.of(ev.PromptAsked) if e.prompt_id == "fit_wheel"]


async def test_the_sequence_screen_says_what_the_analysis_will_lack_as_check_does(app: WfsBenchApp) -> None:
    """The UI's check of a sequence lists the same analysis limits as ``wfsbench check`` (a dwell
    with no pressure asked before it cannot be fitted), before g starts it."""
    async with app.run_test(size=(120, 40)) as pilot:
        await open_app(pilot, app)
        await press(pilot, "f3")
        await type_path(pilot, app, FILES / "long_dwell.toml")
        await until(pilot, lambda: app.plan is not None, "the long dwell checked")
        report = text_of(app, "#seq-report")
        limits = analysis_limits(app.plan.sequence, app.plan.config)
        assert limits and "no set_tyre_pressure prompt before it" in limits[0]
        assert f"analysis limited ({len(limits)}): what the runs will not let the analysis give:" in report
        assert all(f"- {limit}" in report for limit in limits), report
