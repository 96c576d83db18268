"""``wfsbench analyze`` and ``wfsbench report`` in subprocesses on a campaign the simulated bench
recorded (the smoke sequence through ``wfsbench run``): the text and the versioned JSON, the
re-analysis stored beside the raw data under new names (read back by h5dump), the figures and the
self-contained page, and files that are no campaign refused with exit code 3."""

from __future__ import annotations

import base64
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from bench.cli.exit_codes import ExitCode
from bench.config import default_bench_config
from bench.models.parameters import PAPER_TYRE_STIFFNESS_N_PER_M
from bench.report.analysis_document import GivenDoc
from bench.report.json_out import read_analysis_json
from bench.store import StoreError, add_results, open_campaign
from tests.commands import wfsbench
from tests.test_campaign_cli import ROOT, SMOKE

H5DUMP = shutil.which("h5dump")


@pytest.fixture(scope="module")
def smoke_file(smoke_campaign, tmp_path_factory) -> Path:
    """The smoke sequence recorded on the simulated shaker bench (free run, 2 mm grid, sweep): a copy
    of the session's, which these tests analyse into."""
    out = tmp_path_factory.mktemp("smoke") / "smoke.h5"
    shutil.copyfile(smoke_campaign, out)
    return out


def _raw_digest(path: Path) -> dict[str, tuple[int, float]]:
    """Per run and channel: the length and a checksum of the samples."""
    with open_campaign(path) as campaign:
        return {
            f"{run.run_id}/{name}": (values.size, float(np.sum(np.abs(values.astype(float)))))
            for run in campaign.runs
            for name, values in run.channels.items()
        }


def _free_run_results(path: Path) -> dict[str, float]:
    """m_comp_kg of every result of the free run, as h5dump prints it (17 digits)."""
    dump = subprocess.run(
        [H5DUMP, "-A", "-m", "%.17g", "-g", "/runs", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    ).stdout
    found = re.findall(r'GROUP "([^"]+)" \{\s*ATTRIBUTE "m_comp_kg" \{.*?\(0\): ([-0-9.e+]+)', dump, re.S)
    return {name: float(value) for name, value in found}


@pytest.mark.skipif(H5DUMP is None, reason="h5dump (Debian hdf5-tools) not installed")
def test_analyze_prints_text_and_json_and_stores_new_results_beside_the_raw_data(smoke_file):
    raw_before = _raw_digest(smoke_file)
    # the analysis stored after each run is read back: nothing new, nothing stored
    stored_text = wfsbench("analyze", str(smoke_file))
    assert stored_text.returncode == ExitCode.OK, stored_text.stderr
    assert "\n== analysis as stored after each run by wfs-bench " in stored_text.stdout
    assert "stored as results/" not in stored_text.stdout
    # fitted again on request: the new fit's results stored under new names
    text = wfsbench("analyze", str(smoke_file), "--reanalyse")
    assert text.returncode == ExitCode.OK, text.stderr
    assert "\n== analysis analysed again: asked (--reanalyse)\n" in text.stdout
    assert re.search(
        r"^== \S+ \(free_run: plate_mass; stored as results/plate_mass-reanalysis-1\)$", text.stdout, re.M
    ), text.stdout
    m_comp = r"^m_comp [\d.]+ \+/- \S+ kg \(95 %\) from 3 of 3 free-run dwells 10-60 Hz"
    assert re.search(m_comp, text.stdout, re.M)
    assert "2 mm Model" in text.stdout and "valid band" in text.stdout

    run = wfsbench("analyze", str(smoke_file), "--json", "--reanalyse")
    assert run.returncode == ExitCode.OK, run.stderr
    tree = json.loads(run.stdout)
    assert (tree["schema"], tree["version"]) == ("wfs-bench-analysis", 3)
    doc = read_analysis_json(run.stdout)
    assert doc.file == str(smoke_file) and doc.sequence_name == "smoke"
    masses = default_bench_config("shaker").masses  # the stored configuration is the default one
    assert doc.given == GivenDoc(sensor_mass_kg=masses.sensor_kg, wheel_mass_kg=masses.wheel_below_sensor_kg)
    assert doc.hammer is None and doc.sensor.from_hammer_test is False
    assert doc.four_post is None  # the smoke sweep runs on the shaker bench: recorded, not analysed
    (shaker,) = doc.shaker
    # the simulated plate weighs 12 kg; three settled dwells fix m_comp to well under 1 %
    assert shaker.free_run.m_comp_kg == pytest.approx(masses.plate_kg, rel=0.01)
    (amp,) = shaker.amplitudes
    assert amp.amplitude_m == pytest.approx(2e-3)
    assert amp.n_dwells == 4 and amp.freq_range_hz == (10.0, 50.0)
    # the simulated tyre at 2.5 bar: 390 kN/m, tread mass 6 kg (the demo's tolerances: 2 %, 3 %)
    assert amp.selected_model == 2
    model2 = next(m for m in amp.models if m.model == 2)
    assert not model2.undetermined and set(model2.values) == set(model2.ci95)
    assert model2.values["stiffness_n_per_m"] == pytest.approx(PAPER_TYRE_STIFFNESS_N_PER_M[2.5], rel=0.02)
    assert model2.values["tread_mass_kg"] == pytest.approx(6.0, rel=0.03)
    # raw, the ratio is already 2.4 at 30 Hz (tread resonance near 41 Hz): only 10 Hz passes;
    # compensated, every dwell passes up to the grid's end
    raw, compensated = amp.valid_band_raw, amp.valid_band_compensated
    assert (raw.determined, raw.upper_hz, raw.n_points, raw.limited_by) == (False, None, 1, "amplitude")
    compensated_ends = (compensated.lowest_hz, compensated.upper_hz, compensated.limited_by)
    assert compensated_ends == (10.0, 50.0, "end of data")
    kinds = {r.kind: r for r in doc.runs}
    assert kinds["free_run"].results_name == "plate_mass-reanalysis-2"
    assert kinds["sweep"].analysis == "sweep" and kinds["sweep"].error is None

    # the raw data is untouched; the post-run result and both re-analyses sit side by side, equal
    assert _raw_digest(smoke_file) == raw_before
    stored = _free_run_results(smoke_file)
    assert set(stored) == {"plate_mass", "plate_mass-reanalysis-1", "plate_mass-reanalysis-2"}
    assert len(set(stored.values())) == 1
    assert stored["plate_mass"] == shaker.free_run.m_comp_kg


def test_report_writes_every_figure_and_one_self_contained_page(smoke_file, tmp_path):
    with open_campaign(smoke_file) as campaign:
        names_before = {run.run_id: run.result_names for run in campaign.runs}
    out = tmp_path / "report"
    run = wfsbench("report", str(smoke_file), "--out", str(out))
    assert run.returncode == ExitCode.OK, run.stderr
    figures = [
        Path(line.removeprefix("figure ")) for line in run.stdout.splitlines() if line.startswith("figure ")
    ]
    assert [f.name for f in figures] == ["shaker_2p5bar.png", "shaker_compensated_2p5bar.png"]
    page = out / "report.html"
    assert run.stdout.splitlines()[-1] == f"report {page}"
    assert "replacing" not in run.stdout
    again = wfsbench("report", str(smoke_file), "--out", str(out))  # the same folder: said first
    assert again.returncode == ExitCode.OK and again.stdout.splitlines()[0] == (
        f"replacing the report in {out} (its report.html and the figures of the same names)"
    )
    html = page.read_text(encoding="utf-8")
    for figure in figures:
        png = figure.read_bytes()
        assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 10_000
        assert f'src="data:image/png;base64,{base64.b64encode(png).decode()}"' in html
    # no external reference of any kind: every src is a data URI; no link, script, url() or address
    assert re.findall(r'src="([^"]{0,22})', html) == ["data:image/png;base64,"] * len(figures)
    page_text = re.sub(r'src="data:image/png;base64,[A-Za-z0-9+/=]+"', "", html)
    for external in ("http:", "https:", "//", "<link", "<script", "url(", "@import", "href=", "src="):
        assert external not in page_text, external
    for heading in ("Identified tyre parameters", "Valid bands", "Flags", "Plate masses m_comp"):
        assert f"<h2>{heading}" in html
    # the report analyses in memory: the file gains no result
    with open_campaign(smoke_file) as campaign:
        assert {run.run_id: run.result_names for run in campaign.runs} == names_before


def _garbage(kind: str, tmp_path: Path, smoke_file: Path) -> Path:
    path = tmp_path / f"{kind}.h5"
    if kind == "empty":
        path.write_bytes(b"")
    elif kind == "text":
        path.write_text("time,fz\n0,1\n")
    elif kind == "other_layout":
        with h5py.File(path, "w") as f:
            f.create_dataset("signal", data=np.arange(10.0))
            f.attrs["schema"] = "someone-else"
    elif kind == "truncated":
        data = smoke_file.read_bytes()
        path.write_bytes(data[: len(data) // 2])
    return path  # "missing": never written


@pytest.mark.parametrize("kind", ["empty", "text", "other_layout", "truncated", "missing"])
def test_files_that_are_no_campaign_are_refused_with_exit_3(kind, tmp_path, smoke_file):
    path = _garbage(kind, tmp_path, smoke_file)
    before = path.read_bytes() if path.exists() else None
    for command in (
        ("analyze", str(path)),
        ("analyze", str(path), "--json"),
        ("report", str(path), "--out", str(tmp_path / "out")),
    ):
        run = wfsbench(*command)
        assert run.returncode == ExitCode.INVALID, (command, run.stdout, run.stderr)
        assert run.stdout == ""
        assert run.stderr.startswith(f"error: {path}"), run.stderr
        assert "Traceback" not in run.stderr
    assert not (tmp_path / "out" / "report.html").exists()
    assert (path.read_bytes() if path.exists() else None) == before  # nothing written into it


def test_a_reanalysis_never_overwrites_and_writes_nothing_when_one_name_is_taken(smoke_file, tmp_path):
    path = tmp_path / "copy.h5"
    path.write_bytes(smoke_file.read_bytes())
    with open_campaign(path) as campaign:
        runs = {run.kind: run.run_id for run in campaign.runs}
        names_before = {run.run_id: run.result_names for run in campaign.runs}
    taken = names_before[runs["free_run"]][0]
    with pytest.raises(StoreError, match=f"{re.escape(str(path))}.*{taken}: exists already"):
        add_results(path, {(runs["sweep"], "new"): {"x": 1.0}, (runs["free_run"], taken): {"x": 2.0}})
    with open_campaign(path) as campaign:
        assert {run.run_id: run.result_names for run in campaign.runs} == names_before
    add_results(path, {(runs["sweep"], "new"): {"x": 1.0}})
    with open_campaign(path) as campaign:
        assert campaign.run(runs["sweep"]).results("new") == {"x": 1.0}


def _with_config(smoke_file: Path, path: Path, config_toml: str) -> Path:
    """A copy of the smoke file whose stored bench configuration is ``config_toml``."""
    path.write_bytes(smoke_file.read_bytes())
    with h5py.File(path, "r+") as f:
        f.attrs["config_toml"] = config_toml
    return path


def test_the_masses_come_from_the_configuration_stored_in_the_file(smoke_file, tmp_path):
    text = default_bench_config("shaker").to_toml()
    changed = text.replace("sensor_kg = 3.82", "sensor_kg = 4.1")
    assert changed != text
    path = _with_config(smoke_file, tmp_path / "heavier_sensor.h5", changed)
    run = wfsbench("analyze", str(path), "--json")
    assert run.returncode == ExitCode.OK, run.stderr
    doc = json.loads(run.stdout)
    assert doc["given"]["sensor_mass_kg"] == 4.1 == doc["sensor"]["mass_kg"]

    broken = _with_config(
        smoke_file, tmp_path / "broken_config.h5", text.replace("sensor_kg = 3.82", "sensor_kg = -1")
    )
    run = wfsbench("analyze", str(broken))
    assert run.returncode == ExitCode.INVALID
    assert run.stderr.startswith(f"error: {broken}: the stored bench configuration is invalid")
    assert "sensor_kg" in run.stderr


def test_report_into_a_file_or_under_one_is_refused_with_exit_3_before_the_analysis(smoke_file, tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("keep me\n")
    refusals = ((afile, "exists and is not a directory"), (afile / "sub", f"{afile} is not a directory"))
    for out, why in refusals:
        run = wfsbench("report", str(smoke_file), "--out", str(out))
        assert run.returncode == ExitCode.INVALID, (run.stdout, run.stderr)
        assert run.stdout == ""
        assert run.stderr.startswith(f"error: {out}: ") and why in run.stderr, run.stderr
        assert "Traceback" not in run.stderr
    assert afile.read_text() == "keep me\n"
    # checked before the file is even opened: a file that is no campaign is not what is reported
    garbage = _garbage("text", tmp_path, smoke_file)
    run = wfsbench("report", str(garbage), "--out", str(afile))
    assert run.returncode == ExitCode.INVALID
    assert run.stderr.startswith(f"error: {afile}: exists and is not a directory"), run.stderr


def test_every_sequence_appended_to_a_file_is_listed_in_the_report_and_the_json(tmp_path):
    """The file keeps the first sequence's name only; the later ones are found by their run ids."""
    path = tmp_path / "two.h5"
    for sequence in ("hammer.toml", "smoke.toml"):
        run = wfsbench("run", str(SMOKE.with_name(sequence)), "--out", str(path))
        assert run.returncode == 0, run.stderr
    report = wfsbench("report", str(path), "--out", str(tmp_path / "report"))
    assert report.returncode == ExitCode.OK, report.stderr
    html = (tmp_path / "report" / "report.html").read_text(encoding="utf-8")
    assert "<td>sequence that created the file</td><td>hammer</td>" in html
    assert "<td>sequences run</td><td>hammer (1 run), smoke (3 runs)</td>" in html
    doc = json.loads(wfsbench("analyze", str(path), "--json").stdout)
    assert doc["sequence_name"] == "hammer"
    assert doc["sequences"] == [{"name": "hammer", "runs": 1}, {"name": "smoke", "runs": 3}]


def test_sequences_run_are_named_by_their_run_ids_in_order():
    from bench.app.analyze import sequences_run

    ids = ["paper-shaker-s001-free_run", "paper-shaker-s004-dwell_grid", "four_post-s001-sweep", "odd"]
    assert sequences_run(ids) == (("paper-shaker", 2), ("four_post", 1), ("odd", 1))


def test_a_directory_or_a_text_file_is_refused_in_one_plain_sentence(tmp_path):
    """No dump of HDF5's read (buffer address, sizes, offsets): the file and what it is."""
    folder, text = tmp_path / "adir", tmp_path / "notes.h5"
    folder.mkdir()
    text.write_text("time,fz\n0,1\n")
    run = wfsbench("analyze", str(folder))
    assert run.returncode == ExitCode.INVALID
    assert run.stderr == f"error: {folder}: a directory, not a campaign file (an HDF5 file, docs/hdf5.md)\n"
    run = wfsbench("analyze", str(text))
    assert run.returncode == ExitCode.INVALID
    assert run.stderr == (
        f"error: {text}: not a readable HDF5 file"
        " (Unable to synchronously open file (file signature not found))\n"
    )


def test_a_reader_that_goes_away_ends_the_command_quietly(smoke_file):
    """``wfsbench analyze FILE --json | head -c 600``, the reader gone before the command writes
    (whatever the pipe's buffer holds): no traceback, exit 0."""
    command = [sys.executable, "-m", "bench.cli", "analyze", str(smoke_file), "--json"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
    process.stdout.close()  # the reader has gone
    stderr = process.stderr.read().decode()
    assert process.wait(timeout=120) == ExitCode.OK, stderr
    assert "Traceback" not in stderr and "BrokenPipeError" not in stderr
