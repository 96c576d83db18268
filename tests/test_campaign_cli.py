"""``wfsbench run`` end to end: the smoke sequence into a campaign file that h5dump reads as
docs/hdf5.md lays it out; a sequence the dry run refuses; invalid sequence and configuration files
refused before anything is written to the controller."""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

from bench.app.plan import plan_campaign
from bench.app.run import run_campaign
from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from bench.config import load_bench_config
from bench.store import open_campaign
from sequences import load_sequence
from tests.commands import wfsbench, wfsbench_process
from tests.served_lab import served_lab
from tests.test_store_h5dump import _matches, documented_layout, parse_h5dump

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "sequences" / "files" / "smoke.toml"
H5DUMP = shutil.which("h5dump")


@pytest.mark.slow
@pytest.mark.skipif(H5DUMP is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_smoke_sequence_runs_into_a_file_h5dump_reads_as_documented(tmp_path):
    out = tmp_path / "smoke.h5"
    run = wfsbench_process("run", str(SMOKE), "--out", str(out))  # the console script, as a user runs it
    assert run.returncode == ExitCode.OK, run.stderr
    assert "smoke: complete" in run.stdout

    dump = subprocess.run(
        [H5DUMP, "-H", "-p", str(out)], capture_output=True, text=True, timeout=60, check=True
    )
    objects = parse_h5dump(dump.stdout)
    layout = documented_layout()
    undocumented = [p for p in objects if not any(d.pattern.fullmatch(p) for d in layout)]
    assert not undocumented
    for doc in layout:
        found = {p: o for p, o in objects.items() if doc.pattern.fullmatch(p)}
        # everything documented is there, except a result's free-form contents (these results are flat)
        # and what only some runs have (a road replay's drive: tests/test_store_h5dump.py has one)
        optional = doc.text.endswith("/...") or "(optional)" in doc.types
        assert found or optional, f"docs/hdf5.md documents {doc.text}, h5dump shows none"
        assert all(_matches(doc, o) for o in found.values()), (doc.text, found)

    sequence = load_sequence(SMOKE, load_bench_config(None).limits)
    expected = {  # run id -> points of its step
        f"smoke-s{i:03d}-{step.kind}": 1 if step.kind == "sweep" else len(step.dwells())
        for i, step in enumerate(sequence.steps)
        if step.kind in ("free_run", "dwell_grid", "sweep")
    }
    for run_id in expected:  # each analysis names its run (it may print after the next run started)
        started = run.stdout.index(f"run {run_id} (")
        assert run.stdout.find(f"analysis of run {run_id} (", started) > started, run.stdout
    results = {"free_run": "plate_mass", "dwell_grid": "shaker", "sweep": "sweep"}
    with open_campaign(out) as campaign:
        assert campaign.sequence_name == "smoke"
        assert [r.run_id for r in campaign.runs] == list(expected)
        for run in campaign.runs:
            assert run.status == "complete" and run.reason == ""
            done = [p.index for p in run.points if p.status == "done"]
            assert sorted(done) == list(range(expected[run.run_id])), run.run_id  # each exactly once
            assert {p.status for p in run.points} <= {"done", "repeated"}
            assert all(p.end_sample <= run.n_samples for p in run.points)
            assert run.result_names == (results[run.kind],)  # the analysis, stored beside the run
            result = run.results(results[run.kind])
            assert "error" not in result and "FLAG analysis failed" not in result["summary"]
            assert f"/runs/{run.run_id}/results/{results[run.kind]}" in objects
        assert 11.5 < campaign.run("smoke-s003-free_run").results("plate_mass")["m_comp_kg"] < 12.5


def test_a_point_the_dry_run_refuses_stops_everything_before_it_starts(tmp_path):
    """The smoke grid's 2 mm dwells load the WFS with about 780-800 N (the dry run's bench model); a
    bench whose WFS takes 700 N refuses each of them, naming the point and the limit."""
    config = tmp_path / "low_wfs.toml"
    config.write_text('kind = "shaker"\n[limits]\nwfs_force_n = 700\n')
    out = tmp_path / "refused.h5"
    run = wfsbench("run", str(SMOKE), "--out", str(out), "--bench", str(config))
    assert run.returncode == ExitCode.REFUSED
    refused = [line for line in run.stderr.splitlines() if "beyond the limit" in line]
    assert len(refused) == 4, run.stderr
    for point, freq_hz in enumerate((10, 30, 40, 50)):
        pattern = (
            rf"steps\[9\] point {point} \({freq_hz} Hz, 2 mm\): predicted WFS load [\d.]+ N"
            r" is beyond the limit wfs_force_n = 700 N"
        )
        assert re.fullmatch(pattern, refused[point]), refused[point]
    assert not out.exists()


# -- invalid files: nothing reaches the controller ------------------------------------------------


@pytest.fixture
def lab_devices():
    """A controller served on 127.0.0.1 and a WFS on a pty, outside the command: ``(server, pty)``."""
    with served_lab() as (server, link, _):
        yield server, link.path


HYDRAULICS_ONLY = """\
[sequence]
name = "checked"

[[steps]]
type = "hydraulics"
level = "low"

[[steps]]
type = "hydraulics"
level = "off"
"""
GOOD_SEQUENCE = (
    HYDRAULICS_ONLY
    + """
[[steps]]
type = "sine_dwell"
freq_hz = 40
amplitude_mm = 2
"""
)


def _bench_toml(server, pty: str, limits: str = "") -> str:
    host, port = server.address
    return (
        f'kind = "shaker"\n[actuator]\ntransport = "tcp"\nhost = "{host}"\nport = {port}\n'
        f'[wfs]\ntransport = "serial"\ndevice = "{pty}"\n[limits]\n{limits}'
    )


def _with_line(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new, 1)


@dataclass(frozen=True)
class Invalid:
    """A refused input: the sequence text, the configuration's ``[limits]`` lines, and what stderr
    must name after the temporary directory (the file, the key, the reason)."""

    sequence_text: str
    limits: str
    named: str


SEQ_FREQ = "seq.toml: steps[2].freq_hz"
INVALID = {
    "amplitude out of range": Invalid(
        _with_line(GOOD_SEQUENCE, "amplitude_mm = 2", "amplitude_mm = 60"),
        "",
        "seq.toml: steps[2].amplitude_mm: 60 mm is above the 25 mm stroke",
    ),
    "frequency above the bench": Invalid(
        _with_line(GOOD_SEQUENCE, "freq_hz = 40", "freq_hz = 150"),
        "",
        f"{SEQ_FREQ}: 150 Hz is above the bench's highest frequency (allowed 0.1 <= freq_hz <= 100 Hz)",
    ),
    "unknown key": Invalid(
        GOOD_SEQUENCE + 'colour = "red"\n', "", "seq.toml: steps[2].colour: unknown key for a sine_dwell step"
    ),
    "wrong type": Invalid(
        _with_line(GOOD_SEQUENCE, "amplitude_mm = 2", 'amplitude_mm = "2"'),
        "",
        "seq.toml: steps[2].amplitude_mm: expected a number, got '2' (str)",
    ),
    "duplicate key": Invalid(GOOD_SEQUENCE + "freq_hz = 41\n", "", f"{SEQ_FREQ}: line 16: duplicate key"),
    "empty file": Invalid("", "", "seq.toml: empty file"),
    "config: value out of range": Invalid(
        GOOD_SEQUENCE,
        "stroke_mm = -5\n",
        "bench.toml: limits.stroke_mm: -5 is not above 0 (allowed stroke_mm > 0)",
    ),
    "config: unknown key": Invalid(
        GOOD_SEQUENCE, "strokes_mm = 25\n", "bench.toml: limits.strokes_mm: unknown key"
    ),
    "config: wrong type": Invalid(
        GOOD_SEQUENCE, 'stroke_mm = "25"\n', "bench.toml: limits.stroke_mm: expected a number, got '25' (str)"
    ),
    "config: duplicate key": Invalid(
        GOOD_SEQUENCE,
        "stroke_mm = 25\nstroke_mm = 30\n",
        "bench.toml: limits.stroke_mm: line 11: duplicate key",
    ),
    "frequency above the configured range": Invalid(
        GOOD_SEQUENCE,
        "max_freq_hz = 30\n",
        f"{SEQ_FREQ}: 40 Hz is above the bench's highest frequency (allowed 0.1 <= freq_hz <= 30 Hz)",
    ),
}


@pytest.mark.parametrize("case", INVALID.values(), ids=INVALID.keys())
def test_invalid_files_are_refused_naming_file_key_and_reason_and_nothing_reaches_the_controller(
    tmp_path, lab_devices, capsys, case
):
    server, pty = lab_devices
    sequence, config = tmp_path / "seq.toml", tmp_path / "bench.toml"
    sequence.write_text(case.sequence_text)
    config.write_text(_bench_toml(server, pty, case.limits))
    out = tmp_path / "campaign.h5"
    code = main(["run", str(sequence), "--out", str(out), "--bench", str(config)])
    stderr = capsys.readouterr().err
    assert code == ExitCode.INVALID
    assert f"error: {tmp_path}/{case.named}" in stderr
    assert server.writes_received == 0
    assert not out.exists()


def test_empty_configuration_file_is_refused_by_the_command(tmp_path, lab_devices):
    """The same refusal through the installed command (exit code 3), here for an empty bench file."""
    server, _ = lab_devices
    sequence, config = tmp_path / "seq.toml", tmp_path / "bench.toml"
    sequence.write_text(GOOD_SEQUENCE)
    config.write_text("")
    run = wfsbench("run", str(sequence), "--out", str(tmp_path / "c.h5"), "--bench", str(config))
    assert run.returncode == ExitCode.INVALID
    assert f"error: {config}: empty file" in run.stderr
    assert server.writes_received == 0


class _NoPrompts:
    """An operator for a sequence without prompts."""

    def answer(self, prompt):
        raise AssertionError(f"unexpected prompt {prompt.id}")


def test_a_valid_sequence_on_the_same_configuration_reaches_the_controller(tmp_path, lab_devices):
    """The control for the tests above: a valid sequence (its hydraulics steps) with the same kind of
    configuration plans and runs on the command's own path, and the served controller counts its
    writes."""
    server, pty = lab_devices
    sequence, config = tmp_path / "seq.toml", tmp_path / "bench.toml"
    sequence.write_text(HYDRAULICS_ONLY)
    config.write_text(_bench_toml(server, pty))
    outcome = run_campaign(plan_campaign(sequence, config), tmp_path / "c.h5", operator=_NoPrompts())
    assert outcome.status == "complete", outcome.reason
    assert server.writes_received > 0


def test_a_real_wfs_beside_the_default_simulated_actuator_names_the_simulated_key(tmp_path):
    """Only [wfs] configured as a serial port: the actuator is still the simulated default, and
    the refusal says which key that is; nothing is written."""
    config, out = tmp_path / "lab.toml", tmp_path / "c.h5"
    config.write_text('[wfs]\ntransport = "serial"\ndevice = "/dev/ttyUSB1"\n')
    run = wfsbench("run", str(SMOKE), "--bench", str(config), "--out", str(out))
    assert run.returncode == ExitCode.INVALID
    assert f"{config}: actuator.transport: a simulated device cannot be mixed with real ones" in run.stderr
    assert not out.exists()
