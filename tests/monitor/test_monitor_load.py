"""Viewers change nothing in the run: a paced smoke run with ``--monitor`` watched by 20 viewers of
the stream (one never reading a byte), under a bounded flood of requests, malformed requests and
refused methods, records what the bench records alone: every point done at its first attempt, every
frame the link delivered recorded, none missing, no host stall. The viewers run as a process of
their own (at another computer in a lab; here at a lower priority, as another computer's would not
take the bench's time) and every reading viewer sees the run's final status."""

from __future__ import annotations

import json
import subprocess
import sys
from urllib.parse import urlsplit

import pytest

from tests.monitor.monitored_run import ROOT, assert_untouched, monitored_run, recorded

pytestmark = pytest.mark.slow

VIEWERS_NICENESS = 10
READERS, SILENT, FLOOD = 19, 1, 400


def test_twenty_viewers_a_flood_and_bad_requests_change_nothing(tmp_path) -> None:
    with monitored_run(tmp_path / "smoke.h5") as run:
        viewers = subprocess.run(
            [
                "nice",
                f"-n{VIEWERS_NICENESS}",
                sys.executable,
                "-m",
                "tests.monitor.viewers",
                str(urlsplit(run.url).port),
                f"--readers={READERS}",
                f"--silent={SILENT}",
                f"--flood={FLOOD}",
                "--bad",
            ],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=400,
            check=False,
        )
        said = run.lines.rest(60)
        assert run.process.wait(60) == 0, said
    assert viewers.returncode == 0, viewers.stderr
    seen = json.loads(viewers.stdout)
    assert "smoke: complete" in said
    assert len(seen["readers"]) == READERS
    for reader in seen["readers"]:
        assert reader.get("status") == "complete", reader
        assert reader["updates"] >= 10, reader  # the stream went on while the run did
    assert sum(seen["flood"].values()) == FLOOD and set(seen["flood"]) <= {"200", "404"}, seen["flood"]
    assert seen["flood"].get("200", 0) >= FLOOD // 2, seen["flood"]
    assert seen["refused"] == {"POST": 405, "PUT": 405, "DELETE": 405}
    for line in seen["malformed"]:  # refused, or the connection closed unanswered
        assert line == "" or line.split(" ")[1] in ("400", "431", "505"), seen["malformed"]
    assert_untouched(recorded(tmp_path / "smoke.h5"))
