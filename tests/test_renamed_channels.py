"""A lab's own channel names: the aux inputs renamed in the bench configuration (``z_table_m`` for the
bench displacement, ``f_loadcell_n`` for the plate force) are recorded, interlocked, analysed and
reported under those names, each playing its role; a configuration or sequence that leaves a role
unbound, or names a channel the bench does not record, is refused before anything opens."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from bench.cli.exit_codes import ExitCode
from bench.engine import events as ev
from bench.store import open_campaign
from tests.commands import wfsbench
from tests.sequence_texts import sequence_text
from tests.test_campaign_cli import SMOKE
from tests.test_campaign_faults import _check_file, _run_with_fault

H5DUMP = shutil.which("h5dump")
RENAMED = """\
[aux.aux0]
name = "z_table_m"
unit = "m"
[aux.aux1]
name = "f_loadcell_n"
unit = "N"
"""
ADAPTIVE = sequence_text(
    "adaptive",
    """\
[[steps]]
type = "dwell_grid"
freqs_hz = [10.0, 20.0]
amplitudes_mm = [1.0]

[steps.adaptive]
output = "fz_wfs_n"
input = "{input}"
""",
    "an adaptive grid whose FRF names its channels",
)


@pytest.fixture(scope="module")
def renamed_smoke(tmp_path_factory) -> tuple[Path, Path]:
    """The smoke sequence run on the simulated shaker bench with renamed aux inputs."""
    folder = tmp_path_factory.mktemp("renamed")
    config, out = folder / "lab.toml", folder / "smoke.h5"
    config.write_text(RENAMED)
    run = wfsbench("run", str(SMOKE), "--bench", str(config), "--out", str(out))
    assert run.returncode == ExitCode.OK, run.stderr
    assert "smoke: complete" in run.stdout
    return config, out


def test_renamed_channels_are_recorded_under_the_labs_names_with_their_roles(renamed_smoke):
    _, out = renamed_smoke
    with open_campaign(out) as campaign:
        for run in campaign.runs:
            names = {spec.name: spec for spec in run.channel_specs}
            assert "z_table_m" in names and "f_loadcell_n" in names, run.run_id
            assert "z_base_m" not in names and "f_plate_n" not in names
            assert names["z_table_m"].role == "bench_displacement"
            assert names["f_loadcell_n"].role == "plate_force"
            assert names["a_hub_m_s2"].role == "hub_acceleration"
    if H5DUMP is not None:  # the roles as an independent reader sees them
        dump = subprocess.run(
            [H5DUMP, "-a", "/runs/smoke-s003-free_run/channels/f_loadcell_n/role", str(out)],
            capture_output=True,
            text=True,
            timeout=60,
            check=True,
        )
        assert '"plate_force"' in dump.stdout


def test_renamed_channels_are_analysed_and_reported(renamed_smoke, tmp_path):
    """The analysis reads each role's channel whatever it is called: m_comp from the free run, the
    tyre from the grid, as on the default bench (12 kg plate, 390 kN/m at 2.5 bar)."""
    _, out = renamed_smoke
    analysed = wfsbench("analyze", str(out), "--json")
    assert analysed.returncode == 0, analysed.stderr
    doc = json.loads(analysed.stdout)
    (shaker,) = doc["shaker"]
    assert shaker["free_run"]["m_comp_kg"] == pytest.approx(12.0, rel=0.01)
    (amplitude,) = shaker["amplitudes"]
    model2 = next(m for m in amplitude["models"] if m["model"] == 2)
    assert model2["values"]["stiffness_n_per_m"] == pytest.approx(390e3, rel=0.02)
    assert all(run["error"] is None for run in doc["runs"])
    report = wfsbench("report", str(out), "--out", str(tmp_path / "report"))
    assert report.returncode == 0, report.stderr
    assert (tmp_path / "report" / "shaker_2p5bar.png").stat().st_size > 10_000


def test_the_force_interlock_guards_the_renamed_plate_force_channel(tmp_path):
    """As tests/test_campaign_faults.py's force interlock, on a bench whose load cell is
    ``f_loadcell_n``: the engine's 1000 N limit trips in point 1 on that channel."""
    config = RENAMED + "[limits]\nforce_n = 1000.0\n[specimen]\nwheel_fitted = false\n"
    run = _run_with_fault(tmp_path, (10.0, 60.0), lambda c: None, config_text=config)
    assert run.outcome.status == "interlocked", run.outcome
    (tripped,) = run.campaign.of(ev.InterlockTripped)
    assert tripped.name == "force limit" and "f_loadcell_n" in tripped.reason
    _check_file(
        run.path, "interlocked", ("force limit", "f_loadcell_n"), done_before=1, displacement="z_table_m"
    )


def test_a_configuration_without_a_needed_role_is_refused_naming_key_and_role(tmp_path):
    config = tmp_path / "lab.toml"
    config.write_text('[aux.aux1]\nname = "f_spare_n"\nrole = "spare"\n')
    checked = wfsbench("check", str(SMOKE), "--bench", str(config))
    assert checked.returncode == ExitCode.INVALID
    assert f"{config}: aux: no input has the role plate_force" in checked.stderr
    run = wfsbench("run", str(SMOKE), "--bench", str(config), "--out", str(tmp_path / "x.h5"))
    assert run.returncode == ExitCode.INVALID and "plate_force" in run.stderr
    assert not (tmp_path / "x.h5").exists()


def test_a_sequence_whose_analysis_needs_an_unbound_role_is_refused(tmp_path):
    """Without a hub accelerometer a sweep's analysis cannot compensate: refused; the shaker's dwell
    grid (steps[9]) needs none (its hub is clamped)."""
    config = tmp_path / "lab.toml"
    config.write_text('[aux.aux2]\nname = "aux2_v"\nunit = "V"\nrole = "spare"\n')
    checked = wfsbench("check", str(SMOKE), "--bench", str(config))
    assert checked.returncode == ExitCode.INVALID
    assert "steps[10]: its analysis needs a channel with the role hub_acceleration" in checked.stderr
    assert "steps[9]" not in checked.stderr


@pytest.mark.parametrize(
    ("input_channel", "refused"),
    [("f_plate_n", False), ("f_loadcell_n", False), ("f_load_n", True), ("fz_wfs_n", False)],
)
def test_check_refuses_an_adaptive_grid_naming_a_channel_the_bench_does_not_record(
    tmp_path, input_channel, refused
):
    """On the renamed bench, ``f_plate_n`` (the plate force's standard name) and ``f_loadcell_n``
    both mean the load cell; ``f_load_n`` means nothing there."""
    config, sequence = tmp_path / "lab.toml", tmp_path / "adaptive.toml"
    config.write_text(RENAMED)
    sequence.write_text(ADAPTIVE.format(input=input_channel))
    checked = wfsbench("check", str(sequence), "--bench", str(config))
    if refused:
        assert checked.returncode == ExitCode.INVALID
        assert (
            f"{sequence}: steps[2].adaptive.input: the bench records no channel 'f_load_n'" in checked.stderr
        )
    else:
        assert checked.returncode == ExitCode.OK, checked.stderr
