"""Keys after a resume and while a run or a prompt is open; what a resume counts and offers."""

from __future__ import annotations

import logging

import pytest

from bench.engine import events as ev
from bench.engine.states import RunState
from bench.tui.app import WfsBenchApp
from bench.tui.dialogs import FIELD_KEYS, ConfirmDialog, HelpDialog
from bench.tui.session import HeldRuns
from tests.tui.keys import press
from tests.tui.test_tui import (
    FILES,
    answer_smoke_prompts,
    check_smoke,
    finished,
    open_app,
    prompt_open,
    screen_lines,
    text_of,
    type_path,
    until,
)


def notes(app: WfsBenchApp) -> list[str]:
    return [n.message for n in app._notifications]


async def noted(pilot, app: WfsBenchApp, *words: str) -> str:
    """The notification that says all ``words`` (once it is posted)."""
    found = [""]

    def said() -> bool:
        hits = [n for n in notes(app) if all(w in n for w in words)]
        found[0] = hits[-1] if hits else ""
        return bool(hits)

    await until(pilot, said, f"a notification saying {words}")
    return found[0]


def done_points(recorded, after: int = 0) -> int:
    return sum(p.status == "done" for p in recorded.of(ev.PointDone)[after:])


@pytest.mark.validation
async def test_keys_act_after_a_sequence_resumed_through_the_dialog(paced_app: WfsBenchApp) -> None:
    """Twenty dwells, aborted after two, resumed through the "Resume it?" dialog: the progress
    counts the file's done points from the start, and ?, p, r, q and a act at once (no F4 first):
    the help opens, the sequence pauses and resumes, q says why it does not quit, a aborts."""
    app = paced_app
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        await press(pilot, "f3")
        await type_path(pilot, app, FILES / "dwells.toml")
        await until(pilot, lambda: app.plan is not None, "the dwells checked")
        await press(pilot, "g")
        await until(pilot, lambda: done_points(recorded) >= 2 or finished(recorded), "two dwells done")
        assert finished(recorded) is None, finished(recorded)  # e.g. an interlock ended it
        await press(pilot, "a")
        await until(pilot, lambda: finished(recorded) is not None, "the abort")
        await until(pilot, lambda: not app.session.running.is_set(), "the sequence's end")
        before = done_points(recorded)

        await press(pilot, "f3", "g")
        await until(pilot, lambda: isinstance(app.screen, ConfirmDialog), "the offer to resume")
        events_before = len(recorded.of(ev.PointDone))  # before the key: the resumed run starts at once
        await press(pilot, "y")
        await until(pilot, lambda: len(recorded.of(ev.PointStarted)) > before + 1, "the resumed dwells")
        assert app.pane == "run" and app.focused is None, app.focused
        await until(
            pilot,
            lambda: (
                f"points {before}/20" in text_of(app, "#run-progress")
                or f"points {before + 1}/20" in text_of(app, "#run-progress")
            ),
            "the file's points counted",
        )
        assert f"({before} done before the resume)" in text_of(app, "#run-progress")

        await press(pilot, "question_mark")
        await until(pilot, lambda: isinstance(app.screen, HelpDialog), "the help")
        await press(pilot, "escape")
        await press(pilot, "p")
        await until(pilot, lambda: app.session.engine.state is RunState.PAUSED, "the pause")
        await press(pilot, "p")
        await noted(pilot, app, "p: the sequence is paused already")
        await press(pilot, "r")
        await until(pilot, lambda: app.session.engine.state is RunState.RUNNING, "the resume")
        await press(pilot, "r")
        await noted(pilot, app, "r: the sequence is running, not paused")
        await press(pilot, "q")
        await until(pilot, lambda: "sequence is under way" in text_of(app, "#banner"), "q's banner")
        await press(pilot, "a")
        await until(pilot, lambda: len(recorded.of(ev.SequenceFinished)) == 2, "the second abort")
        assert recorded.of(ev.SequenceFinished)[1].status == "aborted"
        done_here = done_points(recorded, events_before)
        assert done_here < 20 - before, "a aborted the sequence before its end"
        await until(pilot, lambda: not app.session.running.is_set(), "the sequence's end")
        assert app.session.pace.points_done == before + done_here
        await until(
            pilot, lambda: f"points {before + done_here}/20" in text_of(app, "#run-progress"), "the count"
        )


async def test_p_r_a_answer_from_a_prompts_field_and_say_why_when_they_cannot_act(app: WfsBenchApp) -> None:
    """Nothing running: p says so. In the pressure prompt's field p is typed, and the dialog shows
    that F6 / F7 / F8 act there: F6 pauses, F6 again says a pause is requested already, F7
    withdraws it, F7 again says the sequence runs; F8 aborts."""
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        await press(pilot, "p")
        await noted(pilot, app, "p: no sequence is running: nothing to pause")
        await check_smoke(pilot, app)
        await press(pilot, "g")
        await prompt_open(pilot, app, "remove_wheel")
        await press(pilot, "y")
        await prompt_open(pilot, app, "fit_wheel")
        await press(pilot, "y")
        dialog = await prompt_open(pilot, app, "pressure")
        assert FIELD_KEYS in text_of(dialog, "#prompt-run-keys")
        await press(pilot, "p")
        assert dialog.query_one("#prompt-input").value == "p", "p is typed into the field"
        assert app.session.engine.state is RunState.RUNNING
        await press(pilot, "f6")
        await until(pilot, lambda: app.session.engine.state is RunState.PAUSING, "the pause requested")
        await noted(pilot, app, "pause requested", "once the prompt is answered")
        await press(pilot, "f6")
        await noted(pilot, app, "f6: a pause is requested already")
        await press(pilot, "f7")
        await until(pilot, lambda: app.session.engine.state is RunState.RUNNING, "the pause withdrawn")
        await press(pilot, "f7")
        await noted(pilot, app, "f7: the sequence is running, not paused")
        await press(pilot, "f8")
        await until(pilot, lambda: finished(recorded) is not None, "the abort")
        assert finished(recorded).status == "aborted", finished(recorded).reason
        await until(pilot, lambda: not app.session.running.is_set(), "the sequence's end")
        await press(pilot, "a")
        await noted(pilot, app, "a: no sequence is running: nothing to abort")


@pytest.mark.validation
async def test_a_complete_sequence_is_not_offered_for_resume_and_the_log_tells_the_run(
    app: WfsBenchApp, caplog: pytest.LogCaptureFixture
) -> None:
    """The smoke run to its end; g again: no "Resume it?", a notification says the file holds it
    complete and to give another --out; nothing starts. The UI's log has the run's events."""
    caplog.set_level(logging.INFO, logger="bench.tui.run")
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        await check_smoke(pilot, app)
        await press(pilot, "g")
        await answer_smoke_prompts(pilot, app)
        await until(pilot, lambda: finished(recorded) is not None, "the end of the sequence")
        assert finished(recorded).status == "complete", finished(recorded).reason
        await until(pilot, lambda: not app.session.running.is_set(), "the sequence's end")
        await press(pilot, "f3", "g")
        said = await noted(pilot, app, "nothing to resume")
        assert "holds sequence 'smoke' complete" in said and "another --out" in said
        assert not isinstance(app.screen, ConfirmDialog) and not app.session.running.is_set()
    log = [r.getMessage() for r in caplog.records if r.name == "bench.tui.run"]
    for line in (
        "starting sequence smoke into",
        "sequence smoke: 8 points",
        "run smoke-s003-free_run (free_run)",
        "  point 0 at 10 Hz: done, commanded",
        "prompt remove_wheel: Remove the wheel from the bench -> True",
        "prompt pressure: Set the tyre pressure to 2.5 bar and enter the pressure read on the gauge"
        " -> 2.5 bar",
        "run smoke-s010-sweep: complete",
        "sequence complete",
    ):
        assert any(entry.startswith(line) for entry in log), (line, log)


@pytest.mark.parametrize("size", [(120, 40), (80, 24)])
async def test_the_resume_question_is_shown_whole(app: WfsBenchApp, size: tuple[int, int]) -> None:
    """The "Resume it?" dialog with a long file name: every word of its question is on the
    screen, inside the dialog, at 120 x 40 and at 80 x 24."""
    async with app.run_test(size=size) as pilot:
        await open_app(pilot, app)
        app.session.held_runs = lambda plan: HeldRuns({"smoke-s003-free_run": "aborted"}, complete=False)
        await check_smoke(pilot, app)
        await press(pilot, "g")
        await until(pilot, lambda: isinstance(app.screen, ConfirmDialog), "the offer to resume")
        dialog = app.screen.query_one(".dialog")
        question = app.screen.question
        assert str(app.session.out_path) in question and "Resume it?" in question
        await until(pilot, lambda: dialog.region.height > 0, "the dialog laid out")
        region = dialog.region
        assert region.right <= size[0] and region.bottom <= size[1], region
        rows = screen_lines(app)[region.y : region.bottom]
        shown = "".join(row[region.x : region.right].strip("█▀▄ ") for row in rows)
        # a long file name breaks where the line ends: compared without the spaces and breaks
        assert "".join(question.split()) in "".join(shown.split()), (question, shown)
        assert "y: yes" in shown
