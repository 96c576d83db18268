"""After a crash the bench says what to do: a controller its watchdog left interlocked (what a
``kill -9`` of ``wfsbench run`` mid-dwell leaves) refuses the next run's first command, and the run
names the controller's state, its interlock and the way out; ``wfsbench actuator reset`` resets it
once the operator confirms, and says when there is nothing to reset.

The devices stand outside the run, as a lab's hardware does (the served simulated lab: the
controller on Modbus TCP on 127.0.0.1, the WFS on a pty)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from drivers.register_map import ControllerState, InterlockFlag
from sequences import Hydraulics, Sequence, dump_sequence
from tests.served_lab import served_lab
from tests.test_campaign_cli import ROOT, _bench_toml

HYDRAULICS = dump_sequence(Sequence("after_crash", "", (Hydraulics("low"), Hydraulics("high")), "<test>"))


def wfsbench(*args: str, answer: str = "") -> subprocess.CompletedProcess:
    script = Path(sys.executable).with_name("wfsbench")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "bench.cli"]
    return subprocess.run(
        [*command, *args], input=answer, capture_output=True, text=True, timeout=120, cwd=ROOT, check=False
    )


@pytest.mark.validation
@pytest.mark.slow
def test_a_run_names_the_interlock_and_the_reset_brings_the_controller_back(tmp_path):
    with served_lab() as (server, link, _device):
        with server.bench.lock:  # the watchdog tripped under a run that was killed
            server.bench.controller.flags = InterlockFlag.WATCHDOG
            server.bench.controller.state = ControllerState.INTERLOCK
        config, sequence = tmp_path / "lab.toml", tmp_path / "seq.toml"
        config.write_text(_bench_toml(server, link.path))
        sequence.write_text(HYDRAULICS)
        run = wfsbench("run", str(sequence), "--bench", str(config), "--out", str(tmp_path / "c.h5"))
        assert run.returncode == 1, run.stdout + run.stderr
        said = run.stdout + run.stderr
        refused = "controller refused HYDRAULICS_LOW: NOT_ALLOWED_IN_STATE: the controller is in INTERLOCK"
        assert refused in said
        assert "(watchdog)" in said and "`wfsbench actuator reset`, or x in the terminal UI" in said

        port = str(server.address[1])
        declined = wfsbench("actuator", "reset", "--port", port, answer="n\n")
        assert declined.returncode == 1 and "not reset" in declined.stdout, declined.stdout
        assert server.bench.controller.state is ControllerState.INTERLOCK
        reset = wfsbench("actuator", "reset", "--port", port, answer="y\n")
        assert reset.returncode == 0, reset.stdout + reset.stderr
        assert reset.stdout.splitlines()[0] == "the controller is in INTERLOCK (watchdog)"
        assert reset.stdout.splitlines()[-1].endswith("? [y/N] reset: the controller is in HYDRAULICS_LOW")
        again = wfsbench("actuator", "reset", "--port", port, "--yes")
        assert again.returncode == 0
        assert again.stdout == "the controller is in HYDRAULICS_LOW (no interlock flag): nothing to reset\n"

        after = wfsbench("run", str(sequence), "--bench", str(config), "--out", str(tmp_path / "after.h5"))
        assert after.returncode == 0, after.stdout + after.stderr
