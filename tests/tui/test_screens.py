"""What the screens show: the state and the keys at 80 x 24, every shipped sequence, the live
values (and their age once the stream has stopped), an unreachable bench and its retry."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from bench.engine import events as ev
from bench.engine.states import RunState
from bench.tui.app import WfsBenchApp
from bench.tui.dialogs import ConfirmDialog, HelpDialog
from sequences import shipped_files
from tests.tui.keys import press
from tests.tui.test_tui import (
    FILES,
    finished,
    open_app,
    screen_lines,
    start_long_dwell,
    text_of,
    type_path,
    until,
)

#: Each screen's footer at 80 x 24: the keys shown there (key and what it does).
FOOTER_KEYS = {
    "f2": ("? Help", "l Hyd. low", "h Hyd. high", "o Hyd. off", "t Tare", "x Reset", "q Quit"),
    "f3": ("? Help", "g Start", "q Quit"),
    "f4": ("? Help", "q Quit"),  # p, r and a while a sequence runs only
    "f5": ("? Help", "q Quit"),
}


async def test_state_screens_and_keys_are_readable_at_80_by_24(app: WfsBenchApp) -> None:
    """At 80 x 24 the top line shows every screen's key, the whole engine state and the e-stop
    key, and each screen's footer shows every key that acts there, none cut."""
    async with app.run_test(size=(80, 24)) as pilot:
        await open_app(pilot, app)
        for key, state in (("l", RunState.HYDRAULICS_LOW), ("h", RunState.HYDRAULICS_HIGH)):
            await press(pilot, key)
            await until(pilot, lambda: isinstance(app.screen, ConfirmDialog), "the confirmation")
            await press(pilot, "y")
            await until(pilot, lambda state=state: app.session.engine.state is state, state.value)
        await press(pilot, "f3")
        app.query_one("#seq-shipped").focus()
        await press(pilot, "enter")  # g acts on the sequence screen once a sequence is checked
        await until(pilot, lambda: app.plan is not None, "the smoke sequence checked")
        for key, shown in FOOTER_KEYS.items():
            await press(pilot, key)

            def drawn(shown=shown) -> bool:
                lines = screen_lines(app)
                top, footer = lines[0], lines[-1]
                return "hydraulics high" in top and all(k in footer for k in shown)

            await until(pilot, drawn, f"the state and the keys of {key} at 80 x 24")
            top = screen_lines(app)[0]
            for word in ("F2 Bench", "F3 Sequence", "F4 Run", "F5 Results", "F12 E-STOP"):
                assert word in top, (word, top)


@pytest.mark.parametrize("size", [(120, 45), (80, 24)])
async def test_every_shipped_sequence_is_listed(app: WfsBenchApp, size: tuple[int, int]) -> None:
    async with app.run_test(size=size) as pilot:
        await open_app(pilot, app)
        await press(pilot, "f3")
        names = sorted(shipped_files())
        assert len(names) >= 5
        await until(
            pilot, lambda: all(n in "\n".join(screen_lines(app)) for n in names), f"{names} all shown"
        )


async def test_live_values_are_live_during_a_run_and_marked_with_their_age_after_it(
    paced_app: WfsBenchApp,
) -> None:
    """Idle before any run: the Bench screen says the WFS streams during runs only. During the
    dwell its values are live; after it they are marked with their age and the run."""
    app = paced_app
    async with app.run_test(size=(120, 40)) as pilot:
        await open_app(pilot, app)
        await until(
            pilot,
            lambda: (
                "no live values while idle: the WFS streams during runs only" in text_of(app, "#bench-values")
            ),
            "the idle line",
        )
        recorded = await start_long_dwell(pilot, app)
        run_id = recorded.of(ev.PointStarted)[0].run_id
        await press(pilot, "f2")
        await until(pilot, lambda: text_of(app, "#bench-values").startswith("live  Fz"), "live values")
        await press(pilot, "a")
        await until(pilot, lambda: finished(recorded) is not None, "the abort")
        await until(
            pilot,
            lambda: f"ago, during {run_id}" in text_of(app, "#bench-values"),
            "the values marked with their age",
        )
        shown = text_of(app, "#bench-values")
        assert (
            shown.startswith("last seen ") and "the WFS streams during runs only" in shown and "Fz" in shown
        )


def closed_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


async def test_an_unreachable_bench_is_named_plainly_and_b_opens_it_again(tmp_path: Path) -> None:
    """A configuration naming a controller nobody answers at: the banner gives the plain message
    (the configuration's keys and the address), no Python class name; once the configuration is
    fixed (here: the simulated bench), b opens the bench."""
    config = tmp_path / "bench.toml"
    port = closed_port()
    config.write_text(
        f'[actuator]\ntransport = "tcp"\nhost = "127.0.0.1"\nport = {port}\n'
        '[wfs]\ntransport = "serial"\ndevice = "/dev/does-not-exist"\n'
    )
    app = WfsBenchApp(config, tmp_path / "campaign.h5")
    async with app.run_test(size=(120, 40)) as pilot:
        await until(pilot, lambda: "did not open" in text_of(app, "#banner"), "the banner")
        banner = text_of(app, "#banner")
        assert f"{config}: actuator.host, actuator.port: cannot reach the actuator controller" in banner
        assert f"127.0.0.1:{port}" in banner and "b: open it again" in banner
        assert "Error" not in banner and "Exception" not in banner, banner
        await until(pilot, lambda: "not open" in screen_lines(app)[0], "the state line")
        await until(pilot, lambda: "b Open the bench again" in screen_lines(app)[-1], "the footer's b")
        config.write_text('kind = "shaker"\n')  # the technician fixes the configuration
        await press(pilot, "b")
        await until(pilot, app.session.opened.is_set, "the bench open")
        await until(pilot, lambda: not app.query_one("#banner").has_class("shown"), "the banner gone")
        await until(pilot, lambda: "controller link up" in text_of(app, "#bench-links"), "the links up")


async def test_the_run_is_counted_while_a_dialog_is_open(paced_app: WfsBenchApp) -> None:
    """The session's messages reach the panes under a dialog: the dwells done while the help is
    open are counted on the Run screen."""
    app = paced_app
    async with app.run_test(size=(120, 40)) as pilot:
        recorded = await open_app(pilot, app)
        await press(pilot, "f3")
        await type_path(pilot, app, FILES / "dwells.toml")
        await until(pilot, lambda: app.plan is not None, "the dwells checked")
        await press(pilot, "g")
        await until(pilot, lambda: recorded.of(ev.PointStarted), "the first dwell")
        await press(pilot, "question_mark")
        await until(pilot, lambda: isinstance(app.screen, HelpDialog), "the help")
        await until(
            pilot,
            lambda: sum(p.status == "done" for p in recorded.of(ev.PointDone)) >= 2 or finished(recorded),
            "2 dwells",
        )
        assert finished(recorded) is None, finished(recorded)  # e.g. an interlock ended it
        await press(pilot, "a")
        await until(pilot, lambda: finished(recorded) is not None, "the abort")
        done = sum(p.status == "done" for p in recorded.of(ev.PointDone))
        assert isinstance(app.screen, HelpDialog)
        await until(pilot, lambda: f"points {done}/20" in text_of(app, "#run-progress"), "the points counted")
        assert app.query_one("#run-points").row_count == len(recorded.of(ev.PointDone))
