"""Hydraulics come up through low: a sequence that asks for high while they are off is refused by
the validation (``wfsbench check`` and ``wfsbench run`` alike, before anything is opened), as the
controller refuses it; when the controller does refuse a command, the engine words it as the
controller's refusal with its reason, which the host's heartbeat no longer clears before the host
reads it."""

from __future__ import annotations

import struct

from bench.app.devices import open_bench
from bench.app.engine_build import build_engine
from bench.cli.exit_codes import ExitCode
from bench.config import default_bench_config
from drivers.register_map import Command, ErrorCode
from sequences import Hydraulics, Sequence, SineDwell, parse_sequence
from tests.commands import wfsbench
from tests.test_controller_server import _exchange, _mbap

HIGH_FIRST = """\
[sequence]
name = "long"

[[steps]]
type = "hydraulics"
level = "high"

[[steps]]
type = "sine_dwell"
freq_hz = 20
amplitude_mm = 2

[[steps]]
type = "hydraulics"
level = "off"

[[steps]]
type = "hydraulics"
level = "high"
"""
REFUSED = (
    "steps[{i}].level: 'high' while the hydraulics are off: the controller raises the pressure to high"
    ' only from low; allowed here: off, low (put a hydraulics step with level = "low" before it)'
)


def test_check_and_run_refuse_high_while_the_hydraulics_are_off_naming_each_step(tmp_path):
    sequence = tmp_path / "long.toml"
    sequence.write_text(HIGH_FIRST)
    check = wfsbench("check", str(sequence))
    assert check.returncode == ExitCode.INVALID, check.stdout + check.stderr
    first, *rest = check.stderr.splitlines()
    assert first == f"error: {sequence}: {REFUSED.format(i=0)}"
    assert rest[-1].strip() == f"{sequence}: {REFUSED.format(i=3)}"  # after "off", again
    run = wfsbench("run", str(sequence), "--out", str(tmp_path / "long.h5"))
    assert run.returncode == ExitCode.INVALID, run.stdout + run.stderr
    assert run.stderr.splitlines()[0] == first
    assert not (tmp_path / "long.h5").exists()


def test_up_through_low_is_valid():
    ok = HIGH_FIRST.replace(
        'level = "high"', 'level = "low"\n\n[[steps]]\ntype = "hydraulics"\nlevel = "high"'
    )
    sequence = parse_sequence(ok, "<test>", default_bench_config().limits)
    assert [s.level for s in sequence.steps if isinstance(s, Hydraulics)] == [
        "low",
        "high",
        "off",
        "low",
        "high",
    ]


async def test_a_heartbeat_write_keeps_the_reason_of_a_refused_command(controller, bench):
    """Command high with the hydraulics off (refused: exception 6, device busy), then a heartbeat
    write as the host's heartbeat thread sends one, then the read of error_code: the reason stays."""
    holding, inputs = controller.map.holding, controller.map.input
    command = struct.pack(">BHH", 6, holding["command"].address, int(Command.HYDRAULICS_HIGH))
    assert await _exchange(controller, _mbap(command)) == bytes([0x86, 0x06])
    beat = struct.pack(">BHH", 6, holding["heartbeat"].address, 7)
    assert await _exchange(controller, _mbap(beat)) == beat  # accepted: echoed
    read = struct.pack(">BHH", 4, inputs["error_code"].address, 1)
    assert await _exchange(controller, _mbap(read)) == bytes([4, 2]) + struct.pack(
        ">H", int(ErrorCode.NOT_ALLOWED_IN_STATE)
    )
    # any other accepted write clears it, as docs/protocols.md says
    watchdog = struct.pack(">BHH", 6, holding["watchdog_ms"].address, 1500)
    assert await _exchange(controller, _mbap(watchdog)) == watchdog
    assert await _exchange(controller, _mbap(read)) == bytes([4, 2, 0, int(ErrorCode.NONE)])


def test_the_engine_words_a_refused_command_as_the_controller_s_refusal_with_its_reason():
    """A sequence built in Python goes to the engine unvalidated: high with the hydraulics off, on
    the simulated lab (a real Modbus server on 127.0.0.1, the heartbeat running)."""
    config = default_bench_config()
    sequence = Sequence("raw", "", (Hydraulics("high"), SineDwell(20.0, 1.0)), "<test>")
    with open_bench(config) as devices:
        outcome = build_engine(config, devices).run(sequence)
    assert (outcome.status, outcome.reason) == (
        "failed",
        "controller refused HYDRAULICS_HIGH: NOT_ALLOWED_IN_STATE: the controller is in OFF",
    )
