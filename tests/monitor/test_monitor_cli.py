"""The monitor's command line: ``--monitor`` of ``run`` and ``tui`` refused with a clear error
before anything opens (an address other than loopback without a token, a token without a monitor,
an address taken), and ``wfsbench monitor FILE`` serving a campaign file read-only, finished or being
recorded."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
from pathlib import Path
from urllib.parse import urlsplit

import pytest

from bench.store import CampaignWriter
from tests.commands import ROOT, wfsbench
from tests.monitor.http import get_json, request
from tests.waiting import LineReader, wait_until

SMOKE = str(ROOT / "sequences" / "files" / "smoke.toml")
TOKEN = "a-token-of-the-lab-0123456"


@pytest.mark.parametrize("command", [("run", SMOKE, "--out", "{out}"), ("tui", "--out", "{out}")])
def test_off_loopback_without_a_token_refused(tmp_path, command) -> None:
    out = str(tmp_path / "c.h5")
    args = [part.format(out=out) for part in command]
    result = wfsbench(*args, "--monitor", "0.0.0.0:8080")
    assert result.returncode == 3, result
    assert "error: --monitor 0.0.0.0:8080: 0.0.0.0 is not a loopback address" in result.stderr
    assert "--monitor-token" in result.stderr
    result = wfsbench(*args, "--monitor-token", TOKEN)
    assert result.returncode == 3 and "--monitor-token: given without --monitor" in result.stderr
    assert not (tmp_path / "c.h5").exists()


def test_short_token_refused_and_never_echoed(tmp_path) -> None:
    out = str(tmp_path / "c.h5")
    result = wfsbench("run", SMOKE, "--out", out, "--monitor", "0.0.0.0:0", "--monitor-token", "abc")
    assert result.returncode == 3 and "the token has 3 characters" in result.stderr
    assert "abc" not in result.stderr.replace("characters", "")


def test_an_address_in_use_is_unavailable(tmp_path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        result = wfsbench("run", SMOKE, "--out", str(tmp_path / "c.h5"), "--monitor", f"127.0.0.1:{port}")
    assert result.returncode == 2, result
    assert f"the monitor cannot listen at 127.0.0.1:{port}" in result.stderr
    assert not (tmp_path / "c.h5").exists()  # nothing was opened or written


def file_monitor(path: Path) -> tuple[subprocess.Popen, LineReader, int]:
    """``wfsbench monitor PATH`` on a free port of 127.0.0.1: the process, its output's lines after
    the first (which gives the address, naming the file) and the port."""
    process = subprocess.Popen(
        [sys.executable, "-m", "bench.cli", "monitor", str(path), "--listen", "127.0.0.1:0"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    lines = LineReader(process.stdout)
    first = lines.next(60, "the monitor's address")
    if not (first.startswith("monitor: http://127.0.0.1:") and str(path) in first):
        process.kill()
        process.wait()
        raise AssertionError(first)
    return process, lines, int(urlsplit(first.split()[1]).port or 0)


def test_monitor_of_a_campaign_file(smoke_campaign) -> None:
    process, lines, port = file_monitor(smoke_campaign)
    try:
        state = get_json(port)
        assert (state["source"], state["state"], state["recorder"]) == ("file", "finished", None)
        assert (state["points_done"], state["points_planned"]) == (8, 8)
        assert [r["status"] for r in state["runs"]] == ["complete", "complete", "complete"]
        analysed = {a["run_id"]: a for a in state["analyses"]}
        assert set(analysed) == {"smoke-s003-free_run", "smoke-s009-dwell_grid", "smoke-s010-sweep"}
        for analysis in analysed.values():  # each flag with its code, as the analysis JSON lists them
            flagged = [line for line in analysis["summary"] if line.startswith("FLAG")]
            assert [f["flag"] for f in analysis["flags"]] == flagged
            assert all(f["code"] for f in analysis["flags"])
        assert state["counters"]["frames_missing"] == 0 and state["live"] is None
        assert request(port, "POST", "/api/state")[0] == 405
        assert request(port, "GET", "/")[0] == 200
        json.dumps(state, allow_nan=False)  # strict JSON
        process.send_signal(signal.SIGTERM)
        assert process.wait(30) == 0
        assert "monitor ended" in lines.rest(10)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def test_monitor_of_a_file_being_recorded_names_its_recorder_and_follows_it_to_the_end(
    smoke_campaign, tmp_path
) -> None:
    """A campaign file a writer holds (as ``run`` holds it while it records: here this process,
    appending to a copy of the smoke campaign) is shown recording, with the writer's process; once
    the writer closes, finished."""
    path = tmp_path / "recording.h5"
    shutil.copyfile(smoke_campaign, path)
    writer = CampaignWriter.open_append(path)
    process, _, port = file_monitor(path)
    try:
        recording = get_json(port)
        assert recording["state"] == "recording" and f"process {os.getpid()}" in recording["recorder"]
        assert recording["points_done"] == 8
        writer.close()
        wait_until(lambda: get_json(port)["state"] == "finished", 30, "the monitor to see the writer close")
        assert get_json(port)["recorder"] is None
        process.send_signal(signal.SIGTERM)
        assert process.wait(30) == 0
    finally:
        writer.close()
        if process.poll() is None:
            process.kill()
            process.wait()


@pytest.mark.parametrize(
    ("given", "code", "said"),
    [
        (["{missing}"], 3, "no such file"),
        (["{campaign}", "--listen", "0.0.0.0:0"], 3, "not a loopback address"),
        (["{campaign}", "--listen", "127.0.0.1:http"], 3, "the port 'http' is not a number"),
    ],
)
def test_monitor_refusals(smoke_campaign, tmp_path, given, code, said) -> None:
    args = [a.format(missing=tmp_path / "none.h5", campaign=smoke_campaign) for a in given]
    result = wfsbench("monitor", *args)
    assert result.returncode == code, result
    assert said in result.stderr
