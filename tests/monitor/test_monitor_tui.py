"""``wfsbench tui --monitor``: the terminal UI's session feeds the monitor, which shows what the UI
shows (the bench, the engine's state, the lamps, the point under way, the live values) and follows
a sequence to its end (a long dwell on the paced bench, aborted with ``a``)."""

from __future__ import annotations

import threading
from typing import Any

from bench.app.bench_status import point_text
from bench.engine import events as ev
from bench.monitor.feed import MonitorFeed
from bench.tui.app import WfsBenchApp
from tests.tui.keys import press
from tests.tui.test_tui import FILES, finished, start_long_dwell, text_of, until


class Published:
    """The states the feed publishes, as a server would take them."""

    def __init__(self) -> None:
        self.states: list[dict[str, Any]] = []
        self._lock = threading.Lock()

    def __call__(self, state: dict[str, Any]) -> None:
        with self._lock:
            self.states.append(state)

    def latest(self) -> dict[str, Any]:
        with self._lock:
            return self.states[-1] if self.states else {}


async def test_the_ui_feeds_the_monitor_what_it_shows(tmp_path) -> None:
    published = Published()
    feed = MonitorFeed(published)
    app = WfsBenchApp(FILES / "paced.toml", tmp_path / "campaign.h5", feed)
    try:
        async with app.run_test(size=(120, 40)) as pilot:
            recorded = await start_long_dwell(pilot, app)
            point = recorded.of(ev.PointStarted)[0]
            await until(
                pilot,
                lambda: published.latest().get("state") == "running" and published.latest().get("live"),
                "the monitor showing the dwell live",
            )
            state = published.latest()
            assert state["bench"] == app.bench_name
            assert [lamp["text"] for lamp in state["lamps"]] == list(app.interlock_names)
            assert all(lamp["ok"] for lamp in state["lamps"])
            assert state["step"] == f"{point.run_id}  {point_text(point)}"
            assert point_text(point) in text_of(app, "#run-step")
            assert set(state["live"]["values"]) == {"fz_wfs_n", "f_plate_n", "z_base_m", "a_hub_m_s2"}
            await press(pilot, "a")
            await until(pilot, lambda: finished(recorded) is not None, "the abort")
            end = finished(recorded)
            await until(
                pilot,
                lambda: (published.latest().get("sequence") or {}).get("status") == end.status,
                "the monitor showing the end",
            )
            assert published.latest()["state"] == app.session.engine.state.value
    finally:
        feed.close()
