"""The operator and notes typed in before a run (m on the Sequence screen) are recorded with it."""

from __future__ import annotations

from pathlib import Path

from bench.store import open_campaign
from bench.tui.app import WfsBenchApp
from bench.tui.dialogs import MetadataDialog
from tests.tui.keys import press
from tests.tui.test_tui import FILES, finished, open_app, text_of, type_path, until


def field_ready(app: WfsBenchApp, field: str) -> bool:
    """The dialog is up with the cursor in ``field``: what a technician waits for before typing."""
    return isinstance(app.screen, MetadataDialog) and app.focused is app.screen.query_one(field)


async def test_operator_and_notes_typed_before_a_run_are_recorded_with_it(
    app: WfsBenchApp, tmp_path: Path
) -> None:
    """m opens the dialog on the Sequence screen; the letters typed there (q and p among them)
    go into its fields, not to quit or pause; Enter keeps both, the screen shows them, and the run
    the sequence then begins records them (the campaign too, being the file's first)."""
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        await press(pilot, "f3")
        await type_path(pilot, app, FILES / "short_dwell.toml")
        await until(pilot, lambda: app.plan is not None, "the short dwell checked")
        app.query_one("#seq-shipped").focus()
        await press(pilot, "m")
        await until(pilot, lambda: field_ready(app, "#meta-operator"), "the operator dialog's cursor")
        await press(pilot, *"qp")  # typed: a text field takes q and p
        assert isinstance(app.screen, MetadataDialog) and app.session.engine.state.value == "idle"
        app.screen.query_one("#meta-operator").value += " Jürgen"
        await press(pilot, "tab")
        await until(pilot, lambda: field_ready(app, "#meta-notes"), "the notes field's cursor")
        app.screen.query_one("#meta-notes").value = "tyre from batch 7"
        await press(pilot, "enter")
        await until(pilot, lambda: not isinstance(app.screen, MetadataDialog), "the dialog closed")
        assert app.run_metadata == {"operator": "qp Jürgen", "notes": "tyre from batch 7"}
        assert "operator: qp Jürgen; notes: tyre from batch 7" in text_of(app, "#seq-metadata")
        await press(pilot, "m")  # Escape keeps what was set
        await until(pilot, lambda: isinstance(app.screen, MetadataDialog), "the dialog again")
        assert app.screen.query_one("#meta-operator").value == "qp Jürgen"
        await press(pilot, "escape")
        await until(pilot, lambda: not isinstance(app.screen, MetadataDialog), "the dialog closed")
        assert app.run_metadata["operator"] == "qp Jürgen"
        await press(pilot, "g")
        await until(pilot, lambda: finished(recorded) is not None, "the sequence's end")
        assert finished(recorded).status == "complete", finished(recorded).reason
    with open_campaign(tmp_path / "campaign.h5") as campaign:
        (run,) = campaign.runs
        assert run.metadata == {"bench_id": "", "operator": "qp Jürgen", "notes": "tyre from batch 7"}
        assert campaign.metadata["operator"] == "qp Jürgen"
        assert campaign.metadata["notes"] == "tyre from batch 7"
