"""Response limits and graded actions in the bench configuration, and the notch's setpoint on the
client and the controller: each refusal names the key (or the register) and why."""

from __future__ import annotations

import re

import pytest

from bench.config import ConfigError, parse_bench_config
from drivers.errors import LimitError, RegisterMapError
from drivers.register_map import Command, ErrorCode, WaveformCode, default_map_path, load_register_map
from drivers.setpoints import SweepNotch, SweepSetpoint
from sequences.limits import BenchLimits
from sequences.response_limits import LimitAction
from simulators.controller_model import ControllerModel

LIMIT = """
[response_limits.fz]
role = "wfs_fz"
freqs_hz = [1.0, 40.0, 70.0]
alarm = [3000.0, 2000.0, 2000.0]
abort = [3500.0, 2500.0, 2500.0]
alarm_action = "hold"
abort_action = "stop"
notch = false
"""


def test_a_limit_and_the_graded_actions_read_and_write_back():
    config = parse_bench_config(f'kind = "shaker"\n[actions]\nwfs_overload = "hold"\n{LIMIT}', "bench.toml")
    (limit,) = config.response_limits
    assert (limit.name, limit.role.value, limit.alarm_action, limit.abort_action, limit.notch) == (
        "fz",
        "wfs_fz",
        LimitAction.HOLD,
        LimitAction.STOP,
        False,
    )
    assert float(limit.alarm.at(20.0)) == pytest.approx(3000.0 - 1000.0 * 19.0 / 39.0)
    assert config.actions.wfs_overload is LimitAction.HOLD
    assert config.actions.force_limit is LimitAction.INTERLOCK
    assert parse_bench_config(config.to_toml(), "bench.toml") == config


@pytest.mark.parametrize(
    ("change", "problem"),
    [
        (
            ("alarm = [3000.0, 2000.0, 2000.0]", "alarm = [3000.0, 2500.0, 2000.0]"),
            "response_limits.fz.alarm: must lie below abort at every frequency; not at [40.0] Hz",
        ),
        (
            ("freqs_hz = [1.0, 40.0, 70.0]", "freqs_hz = [1.0, 70.0, 40.0]"),
            "response_limits.fz.freqs_hz: [1.0, 70.0, 40.0] must ascend",
        ),
        (
            ("freqs_hz = [1.0, 40.0, 70.0]", "freqs_hz = [1.0, 40.0]"),
            "response_limits.fz: freqs_hz, alarm and abort must be as long: 2, 3, 3",
        ),
        (
            ('alarm_action = "hold"', 'alarm_action = "pause"'),
            "response_limits.fz.alarm_action: 'pause' is not one of",
        ),
        (('role = "wfs_fz"', 'role = "body"'), "response_limits.fz.role: 'body' is not one of"),
        (
            ("abort = [3500.0, 2500.0, 2500.0]", "abort = [3500.0, -1.0, 2500.0]"),
            "response_limits.fz.abort: expected a non-empty list of positive numbers",
        ),
    ],
)
def test_a_bad_limit_is_refused_naming_its_key(change, problem):
    with pytest.raises(ConfigError) as refused:
        parse_bench_config(LIMIT.replace(*change), "bench.toml")
    assert f"bench.toml: {problem}" in str(refused.value)


def test_a_limit_on_a_role_no_channel_plays_is_refused():
    aux = '[aux]\naux2 = { name = "spare2", unit = "V", role = "spare" }\n'
    text = LIMIT.replace('role = "wfs_fz"', 'role = "hub_acceleration"')
    with pytest.raises(ConfigError, match=r"response_limits\.fz\.role: no recorded channel plays hub_"):
        parse_bench_config(aux + text, "bench.toml")


def test_an_unknown_graded_interlock_is_refused():
    with pytest.raises(ConfigError, match=r"actions\.link_lost: unknown key"):
        parse_bench_config('[actions]\nlink_lost = "indicate"\n', "bench.toml")


def test_a_map_naming_part_of_the_notch_is_refused(tmp_path):
    path = tmp_path / "map.toml"
    path.write_text(re.sub(r"\[holding\.notch_end_hz\][^\[]*", "", default_map_path().read_text()))
    with pytest.raises(RegisterMapError, match=r"sweep_notch needs all of"):
        load_register_map(path)


def test_a_notch_outside_the_sweep_or_above_it_is_refused_before_a_write():
    limits = BenchLimits()
    with pytest.raises(LimitError, match="not within the sweep's 30-50"):
        SweepSetpoint(30.0, 50.0, 10.0, 1.0, notch=SweepNotch(25.0, 40.0, 0.5)).registers(limits)
    with pytest.raises(LimitError, match=r"outside 0\.\.1\.0 mm"):
        SweepSetpoint(30.0, 50.0, 10.0, 1.0, notch=SweepNotch(35.0, 40.0, 1.5)).registers(limits)
    notched = SweepSetpoint(30.0, 50.0, 10.0, 1.0, notch=SweepNotch(35.0, 40.0, 0.5, 0.2))
    registers = notched.registers(limits)
    window = (registers["notch_start_hz"], registers["notch_end_hz"], registers["notch_amplitude_mm"])
    assert window == (35.0, 40.0, 0.5)


def test_the_controller_refuses_to_start_a_sweep_whose_notch_lies_outside_it():
    model = ControllerModel(10_000.0)
    for command in (Command.HYDRAULICS_LOW, Command.HYDRAULICS_HIGH):
        assert model.command(command) is None
    sweep = {
        "waveform": WaveformCode.LINEAR_SWEEP, "amplitude_mm": 1.0, "sweep_start_hz": 30.0,
        "sweep_end_hz": 50.0, "sweep_duration_s": 10.0, "taper_in_s": 0.5, "taper_out_s": 0.5,
        "notch_start_hz": 45.0, "notch_end_hz": 60.0, "notch_amplitude_mm": 0.5,
    }  # fmt: skip
    assert model.write_setpoints(sweep) is None
    assert model.command(Command.START) == ErrorCode.INVALID_SETPOINT
    assert model.write_setpoints({"notch_end_hz": 48.0}) is None
    assert model.command(Command.START) is None
