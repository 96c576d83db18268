"""The paced simulated lab in a process of its own (bench/app/lab_process.py): the bench reaches its
devices over the real transports and its world over the child's pipes; garbage on those pipes is
refused with a clear error and the lab goes on; Ctrl-C at the terminal does not reach it; a lab
process that is killed leaves its pty link, which the next lab removes."""

from __future__ import annotations

import asyncio
import dataclasses
import os
import signal
import tempfile
from pathlib import Path

import pytest

from bench.app.devices import open_bench
from bench.app.lab_process import LabProcess, LabProcessError, _read_reply
from bench.app.plan import plan_campaign
from bench.app.run import run_campaign
from bench.app.simulated import SimulatedLabSettings
from bench.config import default_bench_config
from bench.models.parameters import Rig
from drivers.actuator import ActuatorClient
from drivers.register_map import ControllerState
from tests.sequence_texts import sequence_text

PACED = "[simulation]\npaced = true\n"
FREE_RUN = sequence_text(
    "lab_process",
    """[[steps]]
type = "hydraulics"
level = "low"

[[steps]]
type = "prompt"
id = "remove_wheel"
text = "Remove the wheel from the bench"
answer = "confirm"
action = "remove_wheel"

[[steps]]
type = "hydraulics"
level = "high"

[[steps]]
type = "free_run"
label = "free run"
freqs_hz = [20, 40]
amplitudes_mm = [1]
settle_cycles = 2
settle_min_s = 0.1
measure_cycles = 2
measure_min_s = 0.5
taper_in_s = 0.2
taper_out_s = 0.2
""",
)
#: the simulated shaker's plate above its load cell, m_comp (bench/models/parameters.py, ``Rig``)
PLATE_MASS_KG = Rig().plate_mass_kg


def test_a_paced_run_reaches_the_lab_in_its_own_process_and_the_operators_answers_reach_its_world(tmp_path):
    """`wfsbench run --realtime`: the lab runs in another process; the remove_wheel answer is
    applied there, so the free run weighs the bare plate (with the wheel left on, m_comp would be
    the plate and the wheel: tests/test_free_run_wheel_on.py)."""
    sequence, config = tmp_path / "seq.toml", tmp_path / "paced.toml"
    sequence.write_text(FREE_RUN)
    config.write_text(PACED)
    plan = plan_campaign(sequence, config)
    assert plan.config.simulation.in_own_process
    lab_pids: list[int] = []
    links_before = set(Path(tempfile.gettempdir()).glob("wfs-pty-*"))  # an earlier test's may remain

    def note_lab(engine) -> None:
        made = set(Path(tempfile.gettempdir()).glob("wfs-pty-*")) - links_before
        lab_pids.extend(int(d.name.split("-")[2]) for d in made)

    outcome = run_campaign(plan, tmp_path / "campaign.h5", on_engine=note_lab)
    assert outcome.status == "complete", outcome.reason
    assert lab_pids and os.getpid() not in lab_pids  # the pty link is made by another process
    (analysis,) = [a for a in outcome.analyses if a.name == "plate_mass"]
    assert not any(line.startswith("FLAG") for line in analysis.summary), analysis.summary
    assert analysis.results["m_comp_kg"] == pytest.approx(PLATE_MASS_KG, rel=0.02)


def test_the_lab_process_refuses_garbage_requests_and_goes_on():
    with LabProcess(SimulatedLabSettings(paced=True)) as lab:
        process = lab._process
        assert process is not None
        assert os.getsid(process.pid) != os.getsid(0)  # Ctrl-C at the bench's terminal does not reach it
        with pytest.raises(ValueError, match="unknown operator action 'dance'"):
            lab.operator.apply("dance", True)
        with pytest.raises(ValueError, match="neither apply, drop_controller_link nor link"):
            lab.request({"nonsense": 1})
        for garbage in ("}{\x00\xff not json", '{"apply": 5}', '{"apply": ["set_tyre_pressure"]}', "[1, 2]"):
            process.stdin.write(garbage + "\n")
            process.stdin.flush()
            reply = _read_reply(process.stdout, 10.0)
            assert "refused" in reply["error"], (garbage, reply)
        lab.operator.apply("set_tyre_pressure", 1.5)  # still serving
        assert lab.bytes_overrun() == 0  # nobody reads its WFS, which is not streaming
        assert asyncio.run(_controller_state(lab.address)) == ControllerState.OFF  # Modbus TCP answers


async def _controller_state(address: tuple[str, int]) -> ControllerState:
    client = ActuatorClient.tcp(*address)
    try:
        return (await client.connect()).state
    finally:
        await client.close()


@pytest.mark.parametrize(
    "line, message",
    [
        ("", "ended without a word"),
        ("\x00\x01garbage\n", "answered garbage"),
        ("[1, 2]\n", r"answered \[1, 2\]"),
    ],
)
def test_garbage_from_the_lab_process_is_a_clear_error(tmp_path, line, message):
    stream = tmp_path / "reply.txt"
    stream.write_text(line)
    with stream.open() as replies, pytest.raises(LabProcessError, match=message):
        _read_reply(replies, 5.0)


def test_a_killed_lab_process_ends_the_bench_with_a_clear_error_and_its_link_is_removed_next_time():
    settings = SimulatedLabSettings(paced=True)
    lab = LabProcess(settings).__enter__()
    process = lab._process
    assert process is not None
    link_dir = Path(lab.wfs_port).parent
    os.kill(process.pid, signal.SIGKILL)
    process.wait(10)
    with pytest.raises(LabProcessError, match=r"gone|without a word|did not close"):
        lab.operator.apply("remove_wheel", True)
    with pytest.raises(LabProcessError):
        lab.__exit__(None, None, None)
    assert link_dir.exists()  # the killed process could not remove its pty link
    with LabProcess(settings):
        assert not link_dir.exists()  # the next lab removed the dead one's link


def test_the_bench_opens_the_paced_lab_in_its_own_process_and_closes_it():
    config = default_bench_config("shaker")
    config = dataclasses.replace(config, simulation=dataclasses.replace(config.simulation, paced=True))
    with open_bench(config) as devices:
        assert isinstance(devices.lab, LabProcess)
        process = devices.lab._process
        assert process is not None and process.poll() is None
        assert devices.actuator.read_status().status.state == ControllerState.OFF
    assert process.poll() == 0  # ended in order: its input closed, its devices stopped
