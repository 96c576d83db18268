"""The CLI pieces against a ``wfsbench sim serve`` process."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest


@pytest.fixture
def sim_process():
    proc = subprocess.Popen(
        [sys.executable, "-m", "bench.cli", "sim", "serve", "--port", "0"],
        stdout=subprocess.PIPE,
        text=True,
    )
    lines = [proc.stdout.readline(), proc.stdout.readline()]
    tcp = re.search(r"modbus tcp ([\d.]+):(\d+)", lines[0])
    pty = re.search(r"serial (\S+)", lines[1])
    assert tcp and pty, lines
    yield tcp.group(1), tcp.group(2), pty.group(1)
    proc.terminate()
    assert proc.wait(timeout=10) == 0


def _cli(*args: str) -> str:
    out = subprocess.run(
        [sys.executable, "-m", "bench.cli", *args], check=False, capture_output=True, text=True, timeout=30
    )
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_actuator_status_and_wfs_monitor_against_sim_serve(sim_process):
    host, port, pty = sim_process
    status = _cli("actuator", "status", "--host", host, "--port", port)
    assert re.search(r"protocol_version\s+1", status)
    assert re.search(r"state\s+OFF", status)
    monitor = _cli("wfs", "monitor", "--port", pty, "--interval", "0.3", "--duration", "0.5")
    assert "identity: WFSBENCH,SIM-WFS6" in monitor
    assert re.search(r"missing 0 crc 0", monitor)


def test_actuator_status_on_a_closed_port_is_a_clear_error():
    out = subprocess.run(
        [sys.executable, "-m", "bench.cli", "actuator", "status", "--port", "1"],
        check=False, capture_output=True, text=True, timeout=30,
    )  # fmt: skip
    assert out.returncode == 2
    assert "cannot connect" in out.stderr
