"""Opening the bench brings the WFS acquisition to a known state: a stream left running (a run that
lost the WFS link before it could stop it) is stopped, so the next run's RATE is accepted.

The devices stand outside the run, as a lab's hardware does (``wfsbench sim serve``): the WFS over
a real pseudo-terminal, the controller on Modbus TCP. Before the fix every later run failed with
``WFS refused RATE 1000: stop first`` (exit 2)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.app.devices import open_bench
from bench.config import parse_bench_config
from simulators.wfs_device import WfsDevice
from tests.commands import wfsbench
from tests.served_lab import served_lab
from tests.test_campaign_cli import SMOKE, _bench_toml
from tests.test_run_unattended import SMOKE_ANSWERS
from tests.waiting import wait_until


@pytest.fixture
def lab():
    """The controller on 127.0.0.1 and the WFS on a pty, outside the run: ``(server, link, device)``."""
    with served_lab() as (server, link, device):
        yield server, link, device


def _left_streaming(device: WfsDevice) -> None:
    """What a run that lost the link leaves behind: the device streaming, nobody reading."""
    device.execute("START", [])
    before = device.frames_sent
    wait_until(lambda: device.frames_sent > before + 100, 10, "the stream left running")


def test_opening_the_bench_stops_a_stream_left_running(lab, tmp_path):
    server, link, device = lab
    _left_streaming(device)
    config = parse_bench_config(_bench_toml(server, link.path), str(tmp_path / "lab.toml"))
    with open_bench(config) as devices:
        assert not device.streaming
        assert devices.acquisition.rate_hz() == config.wfs.rate_hz
        # the bench is usable: a stream started now counts its samples from its START. ``seq``
        # counts every frame since power-up, so each frame of the new stream is ``seq - sample``
        # frames after the old stream's first; the old stream's own frames would give 0. (Which
        # frame arrives first depends on the load: a host not scheduled in time loses the first.)
        sub = devices.acquisition.subscribe(lossless=True)
        devices.acquisition.start_stream()
        block = sub.read_frames(50, timeout_s=10)
        devices.acquisition.stop_stream()
        sub.close()
    started_at_seq = block.frames["seq"].astype(np.int64) - block.frames["sample"].astype(np.int64)
    assert np.all(started_at_seq == started_at_seq[0])
    assert started_at_seq[0] > 100  # the frames of the stream left running came before


@pytest.mark.validation
@pytest.mark.slow
def test_the_run_after_a_wfs_link_loss_works(lab, tmp_path):
    """The link is pulled and plugged back while the device streams; the next run completes. (The
    served world cannot remove the wheel, so the smoke sequence's free run is left out: a free run
    with the wheel on would stop the sequence before its grid, docs/engine.md.)"""
    server, link, device = lab
    _left_streaming(device)
    device.disconnect()  # the adapter pulled: the run that was reading ends, the device streams on
    device.reconnect()
    config, answers, out = tmp_path / "lab.toml", tmp_path / "ok.toml", tmp_path / "next.h5"
    sequence = tmp_path / "smoke_without_free_run.toml"
    config.write_text(_bench_toml(server, link.path))
    answers.write_text(SMOKE_ANSWERS)
    text = SMOKE.read_text()
    free_run = text[
        text.index('[[steps]]\ntype = "free_run"') : text.index("[[steps]]", text.index('type = "free_run"'))
    ]
    sequence.write_text(text.replace(free_run, ""))
    run = wfsbench("run", str(sequence), "--bench", str(config), "--out", str(out), "--answers", str(answers))
    assert run.returncode == 0, run.stdout + run.stderr
    assert "stop first" not in run.stdout + run.stderr
    assert not device.streaming  # the run stopped its stream at its end
