"""The CLI pieces against a ``wfsbench sim serve`` process."""

from __future__ import annotations

import itertools
import os
import re
import subprocess
import sys

import pytest

from bench.models.parameters import Rig
from bench.store import open_campaign
from tests.test_lab_process import FREE_RUN
from tests.waiting import LineReader


@pytest.fixture
def sim_process():
    proc = subprocess.Popen(
        [sys.executable, "-m", "bench.cli", "sim", "serve", "--port", "0"],
        stdout=subprocess.PIPE,
        text=True,
    )
    output = LineReader(proc.stdout)
    lines = [output.next(60.0, "the served bench's addresses") for _ in range(3)]
    tcp = re.fullmatch(r"actuator controller: modbus tcp (127\.0\.0\.1):(\d+)\n", lines[0])
    rtu = re.fullmatch(r"actuator controller: modbus rtu (/\S+) \(8N1\)\n", lines[1])
    wfs = re.fullmatch(r"wfs acquisition: serial (/\S+)\n", lines[2])
    assert tcp and rtu and wfs, lines
    yield {"host": tcp.group(1), "port": tcp.group(2), "rtu": rtu.group(1), "wfs": wfs.group(1)}
    proc.terminate()
    assert proc.wait(timeout=10) == 0
    assert not os.path.exists(rtu.group(1)) and not os.path.exists(wfs.group(1))  # cleaned up


def _cli(*args: str) -> str:
    out = subprocess.run(
        [sys.executable, "-m", "bench.cli", *args], check=False, capture_output=True, text=True, timeout=30
    )
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_actuator_status_over_tcp_and_rtu_and_wfs_monitor_against_sim_serve(sim_process):
    status = _cli("actuator", "status", "--host", sim_process["host"], "--port", sim_process["port"])
    assert re.search(r"protocol_version\s+1", status)
    assert re.search(r"state\s+OFF", status)
    status = _cli("actuator", "status", "--serial", sim_process["rtu"])
    assert re.search(r"protocol_version\s+1", status)
    assert re.search(r"state\s+OFF", status)
    monitor = _cli("wfs", "monitor", "--port", sim_process["wfs"], "--interval", "0.3", "--duration", "0.5")
    assert "identity: WFSBENCH,SIM-WFS6" in monitor
    assert re.search(r"missing 0 crc 0", monitor)


def test_actuator_status_on_a_closed_port_is_a_clear_error():
    out = subprocess.run(
        [sys.executable, "-m", "bench.cli", "actuator", "status", "--port", "1"],
        check=False, capture_output=True, text=True, timeout=30,
    )  # fmt: skip
    assert out.returncode == 2
    assert "cannot connect" in out.stderr


def test_wfs_monitor_shows_duration_over_interval_lines_of_interval_seconds_each(sim_process):
    """``--duration 2 --interval 0.5``: 4 lines, each 0.5 s of frames later than the one before at
    the rate the device reports (1000 Hz), so 2 s of the stream; it showed 5 lines (2.5 s)."""
    monitor = _cli("wfs", "monitor", "--port", sim_process["wfs"], "--interval", "0.5", "--duration", "2")
    samples = [int(m) for m in re.findall(r"^sample\s+(\d+) ", monitor, re.M)]
    assert len(samples) == 4, monitor
    assert [b - a for a, b in itertools.pairwise(samples)] == [500, 500, 500], monitor


@pytest.mark.validation
@pytest.mark.slow
def test_sim_serve_takes_the_operators_actions_on_its_standard_input(tmp_path):
    """The wheel removed at the served bench's terminal: a free run recorded against it through
    `wfsbench run --bench` weighs the bare plate (with the wheel left on, m_comp is flagged:
    tests/test_free_run_wheel_on.py); garbage and unknown actions are refused and it goes on."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "bench.cli", "sim", "serve", "--port", "0", "--fast"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        output = LineReader(proc.stdout)
        lines = [output.next(60.0, "the served bench's addresses") for _ in range(3)]
        host, port = re.fullmatch(r"actuator controller: modbus tcp (\S+):(\d+)\n", lines[0]).groups()
        wfs = re.fullmatch(r"wfs acquisition: serial (/\S+)\n", lines[2]).group(1)
        for typed, answer in (
            ("dance", "operator: refused: unknown operator action 'dance'"),
            ("set_tyre_pressure lots", "operator: refused: could not convert string to float: 'lots'"),
            ("\x00\xff", "operator: refused: unknown operator action"),
            ("remove_wheel", "operator: remove_wheel: done"),
        ):
            proc.stdin.write(typed + "\n")
            proc.stdin.flush()
            assert output.next(60.0, f"the answer to {typed!r}").startswith(answer), typed
        sequence, config, answers = tmp_path / "seq.toml", tmp_path / "bench.toml", tmp_path / "answers.toml"
        sequence.write_text(FREE_RUN)
        config.write_text(
            f'kind = "shaker"\n[actuator]\ntransport = "tcp"\nhost = "{host}"\nport = {port}\n'
            f'[wfs]\ntransport = "serial"\ndevice = "{wfs}"\n'
        )
        answers.write_text("remove_wheel = true\n")
        out = tmp_path / "campaign.h5"
        run = subprocess.run(
            [sys.executable, "-m", "bench.cli", "run", str(sequence), "--out", str(out),
             "--bench", str(config), "--answers", str(answers)],
            capture_output=True, text=True, timeout=120, check=False,
        )  # fmt: skip
        assert run.returncode == 0, run.stderr
    finally:
        proc.terminate()
        assert proc.wait(timeout=10) == 0
    with open_campaign(out) as campaign:
        (free_run,) = campaign.runs
        m_comp_kg = free_run.results("plate_mass")["m_comp_kg"]
    assert m_comp_kg == pytest.approx(Rig().plate_mass_kg, rel=0.02)
    assert "FLAG" not in run.stdout
