"""The monitor's page in a real browser (headless Chromium driven by Selenium with Debian's
chromium-driver) during a paced smoke run with ``--monitor``: the state, the points done and the
live Fz shown change as the run goes, and the page ends at the run's final status.

A lab's viewer sits at another computer; here the browser shares the bench's two cores, so it runs
at a lower priority (niceness 10), and the bench is set up as for a busy PC
(``files/paced_busy_host.toml``): the page is the subject here, not the bench's timing."""

from __future__ import annotations

import functools
import os
import shutil
import time
from pathlib import Path

import pytest

from tests.monitor.monitored_run import SMOKE_POINTS, monitored_run, recorded

BUSY_HOST = Path(__file__).with_name("files") / "paced_busy_host.toml"

pytestmark = [pytest.mark.slow, pytest.mark.validation]

#: The longest the paced smoke run may take here (about 30 s of bench time, busy machine).
RUN_DEADLINE_S = 180.0
#: How often the test reads the page (s): the page takes 5 updates a second at most.
SAMPLE_PERIOD_S = 0.2
#: The browser's niceness (the bench's processes keep 0).
BROWSER_NICENESS = 10


@pytest.fixture
def browser():
    """Headless Chromium; skipped only where Debian's chromium or chromium-driver is absent (.ci/setup
    installs both)."""
    chromium, driver_path = shutil.which("chromium"), shutil.which("chromedriver")
    if chromium is None or driver_path is None:
        pytest.skip("Debian's chromium and chromium-driver are not installed (bash .ci/setup installs them)")
    from selenium import webdriver

    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for argument in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"):
        options.add_argument(argument)
    service = webdriver.ChromeService(
        executable_path=driver_path, popen_kw={"preexec_fn": functools.partial(os.nice, BROWSER_NICENESS)}
    )
    driver = webdriver.Chrome(options=options, service=service)
    yield driver
    driver.quit()


def shown(driver) -> dict[str, str]:
    """What the page shows now, by element."""
    return driver.execute_script(
        "const ids = ['state', 'points', 'fz', 'sequence-status', 'step', 'seq', 'connection'];"
        "return Object.fromEntries(ids.map((id) => [id, document.getElementById(id).textContent]));"
    )


def test_page_follows_a_paced_run_to_its_end(browser, tmp_path) -> None:
    with monitored_run(tmp_path / "smoke.h5", "--bench", str(BUSY_HOST)) as run:
        browser.get(run.url)
        seen: list[dict[str, str]] = []
        deadline = time.monotonic() + RUN_DEADLINE_S
        while not seen or seen[-1]["sequence-status"] in ("", "running"):
            assert time.monotonic() < deadline, f"the page did not show the end: {seen[-1:]}"
            seen.append(shown(browser))
            time.sleep(SAMPLE_PERIOD_S)  # the page's pace of sampling; the end is waited for above
        said = run.lines.rest(60)
        assert run.process.wait(60) == 0, said
    assert "smoke: complete" in said
    final = seen[-1]
    assert final["sequence-status"] == "complete"
    assert final["points"] == f"{SMOKE_POINTS}/{SMOKE_POINTS}"
    assert final["state"] == "finished"
    states = [s["state"] for s in seen]
    assert "running" in states and states.index("running") < len(states) - 1
    points = [s["points"] for s in seen]
    assert len(set(points)) >= 4, set(points)  # counted up as the points were done
    assert [int(p.split("/")[0]) for p in points] == sorted(int(p.split("/")[0]) for p in points)
    live_fz = {s["fz"] for s in seen if s["state"] == "running" and s["fz"] != "-"}
    assert len(live_fz) >= 10, live_fz  # the live Fz moved
    assert len({s["seq"] for s in seen}) >= 10
    assert browser.find_element("id", "sequence-name").text == "smoke"
    assert recorded(tmp_path / "smoke.h5").statuses == ("complete", "complete", "complete")
