"""Viewers change nothing in the run: a paced smoke run with ``--monitor`` watched by 20 viewers of
the stream (one never reading a byte), under a bounded flood of requests, malformed requests and
refused methods, records what the bench records alone: every point done at its first attempt, every
frame the link delivered recorded, none missing, no host stall. The viewers run as a process of
their own (at another computer in a lab; here at a lower priority, as another computer's would not
take the bench's time) and every reading viewer sees the run's final status. Meanwhile
``wfsbench monitor`` watches the campaign file being recorded and then shows it finished with every
point (its "recording" state, which a run on a busy machine may end before the monitor starts, is
tested on a file held open: tests/monitor/test_monitor_cli.py)."""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys
import time
from pathlib import Path
from urllib.parse import urlsplit

import pytest

from tests.monitor.http import get_json
from tests.monitor.monitored_run import ROOT, assert_untouched, ended, free_port, monitored_run, recorded
from tests.waiting import LineReader, wait_until

pytestmark = [pytest.mark.slow, pytest.mark.validation]

VIEWERS_NICENESS = 10
READERS, SILENT, FLOOD = 19, 1, 400
#: How long the file monitor may take to start: at the viewers' niceness, beside the twenty viewers
#: and their flood and four busy processes, it once took over 60 s (one of three loaded runs).
FILE_MONITOR_START_S = 180


def file_monitor(out: Path) -> tuple[subprocess.Popen, int]:
    """``wfsbench monitor OUT`` (a viewer's tool: at the viewers' priority) once it reads the file."""
    command = ["nice", f"-n{VIEWERS_NICENESS}", sys.executable, "-m", "bench.cli", "monitor", str(out)]
    deadline = time.monotonic() + FILE_MONITOR_START_S
    while True:
        process = subprocess.Popen(
            [*command, "--listen", "127.0.0.1:0"],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        first = LineReader(process.stdout).next(FILE_MONITOR_START_S, "the file monitor's first line")
        if first.startswith("monitor: "):
            return process, int(urlsplit(first.split()[1]).port or 0)
        process.wait(10)  # the file not yet written far enough to be read: again
        assert time.monotonic() < deadline, first


def test_twenty_viewers_a_flood_and_bad_requests_change_nothing(tmp_path) -> None:
    out, port, errors = tmp_path / "smoke.h5", free_port(), tmp_path / "viewers.err"
    with contextlib.ExitStack() as stack:
        viewers = subprocess.Popen(
            [
                "nice",
                f"-n{VIEWERS_NICENESS}",
                sys.executable,
                "-m",
                "tests.monitor.viewers",
                str(port),
                f"--readers={READERS}",
                f"--silent={SILENT}",
                f"--flood={FLOOD}",
                "--bad",
            ],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=stack.enter_context(errors.open("w")),
            text=True,
        )
        stack.callback(ended, viewers)
        seen_lines = LineReader(viewers.stdout)
        assert seen_lines.next(120, "the viewers loaded") == "ready\n"  # then they wait for the monitor
        with monitored_run(out, port=port) as run:
            assert seen_lines.next(120, "the viewers connected") == "watching\n"
            wait_until(out.exists, 60, "the campaign file created")
            watcher, watcher_port = file_monitor(out)  # its "recording" state: test_monitor_cli.py
            stack.callback(ended, watcher)
            said = run.lines.rest(60)
            assert run.process.wait(60) == 0, said
        seen_text = seen_lines.rest(400)
        assert viewers.wait(60) == 0, errors.read_text()
        wait_until(
            lambda: get_json(watcher_port)["state"] == "finished", 30, "the file monitor to see the end"
        )
        finished = get_json(watcher_port)
    assert (finished["points_done"], finished["points_planned"], finished["recorder"]) == (8, 8, None)
    assert [r["status"] for r in finished["runs"]] == ["complete", "complete", "complete"]
    seen = json.loads(seen_text)
    assert "smoke: complete" in said
    assert len(seen["readers"]) == READERS
    for reader in seen["readers"]:
        assert reader.get("status") == "complete", reader
        assert reader["updates"] >= 10, reader  # the stream went on while the run did
    # every request answered as asked (-1: not sent, the flood's time being up; 0: not answered, which
    # a busy machine may leave a few of), most of them in time
    answered = set(seen["flood"])
    assert sum(seen["flood"].values()) == FLOOD and answered <= {"200", "404", "-1", "0"}, seen["flood"]
    assert seen["flood"].get("200", 0) + seen["flood"].get("404", 0) >= FLOOD // 2, seen["flood"]
    assert seen["refused"] == {"POST": 405, "PUT": 405, "DELETE": 405}
    for line in seen["malformed"]:  # refused, or the connection closed unanswered
        assert line == "" or line.split(" ")[1] in ("400", "431", "505"), seen["malformed"]
    assert_untouched(recorded(tmp_path / "smoke.h5"))
