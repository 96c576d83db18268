"""The bench configuration: the shipped files, derived limits, and garbage refused with file and key."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from bench.config import (
    ConfigError,
    default_bench_config,
    load_bench_config,
    measured_bench,
    parse_bench_config,
)
from drivers.errors import LimitError
from drivers.setpoints import DwellSetpoint

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


@pytest.mark.parametrize("kind", ["shaker", "four_post"])
def test_shipped_configurations_are_the_simulated_defaults(kind):
    config = load_bench_config(CONFIGS / f"simulated_{kind}.toml")
    assert config.source == str(CONFIGS / f"simulated_{kind}.toml")
    assert dataclasses.replace(config, source="<default>") == default_bench_config(kind)
    assert config.simulated


def test_no_configuration_is_the_simulated_shaker():
    config = load_bench_config(None)
    assert config == default_bench_config("shaker") and config.kind == "shaker"
    assert [a.channel.name for a in config.aux[:3]] == ["z_base_m", "f_plate_n", "a_hub_m_s2"]
    assert np.array_equal(config.calibration.matrix_array(), np.eye(6))
    assert config.actuator.load_register_map().protocol_version == 1


@pytest.mark.parametrize("kind", ["shaker", "four_post"])
def test_the_written_configuration_reads_back_equal(kind):
    config = default_bench_config(kind)
    assert parse_bench_config(config.to_toml(), "<default>") == config


def test_the_limits_are_one_envelope_for_sequences_client_and_interlocks():
    config = parse_bench_config(
        "[limits]\nstroke_mm = 10\nmax_freq_hz = 80\n"
        "displacement_interlock_mm = 12\nforce_interlock_n = 18000\n",
        "lab.toml",
    )
    limits = config.limits
    assert (limits.stroke_mm, limits.max_freq_hz) == (10, 80)
    assert (limits.displacement_interlock_mm, limits.force_interlock_n) == (12, 18000)
    DwellSetpoint(80.0, 10.0, 1.0).registers(limits)
    with pytest.raises(LimitError):
        DwellSetpoint(80.0, 10.5, 1.0).registers(limits)
    with pytest.raises(LimitError, match="stroke"):
        DwellSetpoint(10.0, 6.0, 1.0, mean_mm=5.0).registers(limits)  # |mean| + amplitude > stroke


def test_a_real_bench_with_its_own_register_map(tmp_path):
    (tmp_path / "maps").mkdir()
    default_map = Path(__file__).resolve().parents[1] / "drivers" / "register_map.toml"
    (tmp_path / "maps" / "lab.toml").write_text(default_map.read_text())
    config = parse_bench_config(
        """
        kind = "shaker"
        [actuator]
        transport = "tcp"
        host = "10.0.0.5"
        port = 1502
        register_map = "maps/lab.toml"
        [wfs]
        transport = "serial"
        device = "/dev/ttyUSB1"
        [calibration]
        tare = "once"
        [aux.aux3]
        name = "f_post_n"
        unit = "N"
        scale = 2.5
        """,
        "lab.toml",
        base_dir=tmp_path,
    )
    assert config.actuator.register_map == tmp_path / "maps" / "lab.toml"
    assert (config.actuator.host, config.actuator.port) == ("10.0.0.5", 1502)
    assert config.wfs.device == "/dev/ttyUSB1" and not config.simulated
    assert config.aux[3].channel.name == "f_post_n" and config.aux[3].scale == 2.5
    assert config.calibration.tare == "once"


SINGULAR = "[calibration]\nmatrix = [" + ", ".join(["[1, 0, 0, 0, 0, 0]"] * 6) + "]\n"


@pytest.mark.parametrize(
    ("text", "key", "reason"),
    [
        ('kind = "shaker"\ncolour = "red"\n', "colour", "unknown key; allowed: kind, actuator"),
        ('kind = "bridge"\n', "kind", "'bridge' is not one of ['shaker', 'four_post']"),
        ("[actuator]\nspeed = 3\n", "actuator.speed", "unknown key; allowed: transport"),
        ('[actuator]\nport = "502"\n', "actuator.port", "expected an integer, got '502' (str)"),
        ("[actuator]\nport = 70000\n", "actuator.port", "70000 is above 65535 (allowed 1 <= port <= 65535)"),
        ("[actuator]\ntimeout_s = true\n", "actuator.timeout_s", "expected a number, got True (bool)"),
        ('[actuator]\ntransport = "rtu"\n', "actuator.device", "transport 'rtu' needs the serial device"),
        ('[actuator]\nregister_map = "missing.toml"\n', "actuator.register_map", "cannot read register map"),
        ("[actuator]\nwatchdog_ms = 500\n", "actuator.watchdog_ms", "would trip on one slow reply"),
        ('[wfs]\ntransport = "serial"\n', "wfs.device", "needs the serial device"),
        ('[simulation]\nflow_control = "yes"\n', "simulation.flow_control", "expected true or false"),
        ("[simulation]\nwfs_hold_s = 0\n", "simulation.wfs_hold_s", "allowed 0.01 <= wfs_hold_s <= 60"),
        ('[simulation]\nwfs_hold_s = "5 s"\n', "simulation.wfs_hold_s", "expected a number, got '5 s' (str)"),
        ("[wfs]\nrate_hz = 2000\n", "wfs.rate_hz", "allowed 100 <= rate_hz <= 1440"),
        ("[wfs]\nrate_hz = 1000\nbaudrate = 115200\n", "wfs.rate_hz", "allowed 100 <= rate_hz <= 180"),
        ("[limits]\nstroke_mm = nan\n", "limits.stroke_mm", "nan is not a finite number"),
        ("[limits]\nforce_n = inf\n", "limits.force_n", "inf is not a finite number"),
        (
            "[limits]\nvelocity_mm_s = -5\n",
            "limits.velocity_mm_s",
            "-5 is not above 0 (allowed velocity_mm_s > 0)",
        ),
        ("[limits]\nmin_freq_hz = 50\nmax_freq_hz = 20\n", "limits.max_freq_hz", "not above min_freq_hz"),
        (
            "[limits]\ndisplacement_interlock_mm = 20\n",
            "limits.displacement_interlock_mm",
            "allowed displacement_interlock_mm > 25",
        ),
        (
            "[limits]\nforce_interlock_n = 1000\n",
            "limits.force_interlock_n",
            "allowed force_interlock_n > 15000",
        ),
        ("[calibration]\nmatrix = [[1, 0, 0, 0, 0, 0]]\n", "calibration.matrix", "must be 6x6"),
        ("[calibration]\nmatrix = 1\n", "calibration.matrix", "must be 6x6"),
        (
            "[calibration]\nmatrix = [" + ", ".join(["[1, 0, 0, 0, 0, 0]"] * 5) + ", [1, 0]]\n",
            "calibration.matrix[5]",
            "must be a row of 6 numbers",
        ),
        (
            "[calibration]\nmatrix = [" + ", ".join(["[1, 0, 0, 0, 0, 0]"] * 5) + ", [0, 0, 0, 0, 0, inf]]\n",
            "calibration.matrix[5][5]",
            "inf is not a finite number",
        ),
        (SINGULAR, "calibration.matrix", "is singular"),
        (
            '[calibration]\ntare = "always"\n',
            "calibration.tare",
            "not one of ['before_each_run', 'once', 'never']",
        ),
        (
            "[masses]\nwheel_below_sensor_kg = 0\n",
            "masses.wheel_below_sensor_kg",
            "0 is not above 0 (allowed wheel_below_sensor_kg > 0)",
        ),
        ('[aux]\naux4 = { name = "x" }\n', "aux.aux4", "unknown key; allowed: aux0, aux1, aux2, aux3"),
        ('[aux]\naux1 = { name = "Plate Force" }\n', "aux.aux1.name", "lower case letters"),
        ('[aux]\naux3 = { name = "z_base_m" }\n', "aux.aux3.name", "standard name of the bench_displacement"),
        (
            '[aux]\naux0 = { name = "z_table_m" }\naux3 = { name = "z_table_m" }\n',
            "aux.aux3.name",
            "already the name of aux0",
        ),
        (
            '[aux]\naux2 = { name = "f_second_n", role = "plate_force" }\n',
            "aux.aux2.role",
            "already the role of aux1",
        ),
        (
            '[aux]\naux1 = { name = "f_spare_n", role = "spare" }\n',
            "aux",
            "no input has the role plate_force",
        ),
        ('[aux]\naux0 = { role = "wheel" }\n', "aux.aux0.role", "is not one of"),
        ("[specimen]\ntyre_model = 4\n", "specimen.tyre_model", "allowed 1 <= tyre_model <= 3"),
        ('[specimen]\nnonlinear = "yes"\n', "specimen.nonlinear", "expected true or false"),
        ("[simulation]\nseed = 1.5\n", "simulation.seed", "expected an integer"),
        ("[simulation]\nseed = -1\n", "simulation.seed", "-1 is below 0 (allowed 0 <= seed <= 4294967295)"),
        ('limits = "high"\n', "limits", "must be a table"),
    ],
)
def test_garbage_is_refused_with_file_and_key(text, key, reason):
    with pytest.raises(ConfigError) as info:
        parse_bench_config(text, "lab.toml", base_dir=Path("/nonexistent"))
    first = info.value.problems[0]
    assert first.startswith(f"lab.toml: {key}: "), first
    assert reason in first


@pytest.mark.parametrize("text", ["", "\n", "# nothing configured\n"])
def test_empty_file_is_refused(text):
    with pytest.raises(ConfigError, match=r"^lab.toml: empty file"):
        parse_bench_config(text, "lab.toml")


def test_duplicate_key_is_refused_with_the_key_and_the_line():
    with pytest.raises(ConfigError, match=r"^lab.toml: limits.stroke_mm: line 3: duplicate key"):
        parse_bench_config("[limits]\nstroke_mm = 20\nstroke_mm = 30\n", "lab.toml")


def test_every_problem_is_reported_table_by_table():
    with pytest.raises(ConfigError) as info:
        parse_bench_config('kind = "x"\n[limits]\nstroke_mm = "big"\n[wfs]\nrate_hz = 5\n', "lab.toml")
    assert [p.split(": ")[1] for p in info.value.problems] == ["kind", "wfs.rate_hz", "limits.stroke_mm"]
    assert str(info.value).splitlines()[1] == "  and 2 more:"


def test_missing_file_names_the_path(tmp_path):
    with pytest.raises(ConfigError, match=r"nowhere.toml: cannot read the bench configuration"):
        load_bench_config(tmp_path / "nowhere.toml")


def test_every_engine_timeout_is_a_configuration_key():
    """[timing] sets the engine's timeouts; the WFS silence limit reaches its interlock."""
    from bench.app.devices import open_bench
    from bench.app.engine_build import build_engine
    from bench.engine.interlocks import SerialLinkLost

    # 6 s: above the unpaced simulated bench's own floor (5 s), so the configured limit stands there
    config = parse_bench_config("[timing]\nwfs_silence_s = 6.0\nstatus_period_s = 0.1\n", "lab.toml")
    assert (config.timing.wfs_silence_s, config.timing.status_period_s) == (6.0, 0.1)
    assert parse_bench_config(config.to_toml(), "lab.toml") == config

    with open_bench(config) as devices:  # the simulated lab
        engine = build_engine(config, devices)
    (silence,) = [i for i in engine.interlocks if isinstance(i, SerialLinkLost)]
    assert silence.timeout_s == 6.0 and engine.timing.status_period_s == 0.1
    with pytest.raises(ConfigError, match=r"lab.toml: timing.wfs_silence_s: .*allowed"):
        parse_bench_config("[timing]\nwfs_silence_s = 0\n", "lab.toml")
    with pytest.raises(ConfigError, match=r"lab.toml: timing.link_s: unknown key"):
        parse_bench_config("[timing]\nlink_s = 1\n", "lab.toml")


@pytest.mark.parametrize(("text", "hold_s"), [("", 5.0), ("[simulation]\nwfs_hold_s = 4.5\n", 4.5)])
def test_the_simulated_wfs_hold_reaches_the_device(text, hold_s):
    """[simulation] wfs_hold_s sets how long the simulated WFS holds frames for its host; unset, on
    the unpaced bench, as long as the engine takes the link's silence for its host's (5 s); a resume
    may change it (it shapes no measurement)."""
    from bench.app.devices import open_bench

    config = parse_bench_config('kind = "shaker"\n' + text, "lab.toml")
    assert parse_bench_config(config.to_toml(), "lab.toml") == config
    assert measured_bench(config) == measured_bench(default_bench_config())
    with open_bench(config) as devices:  # the simulated lab, in this process (unpaced)
        assert devices.lab.device.hold_s == hold_s
