"""``wfsbench show``: what a campaign file holds, as text and JSON, read without changing a byte of
it (nor its modification time, nor leaving a lock file); no campaign file exits 3 naming it; a file
a process is writing is refused with exit 2. ``analyze --no-store`` leaves the file as it was too."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import pytest

from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from bench.locks import LOCK_DIR_ENV

ROOT = Path(__file__).resolve().parents[1]


def _state(path: Path) -> tuple[str, int, int]:
    """What must not change: the file's sha256, its modification time (ns) and its size."""
    stat = path.stat()
    return hashlib.sha256(path.read_bytes()).hexdigest(), stat.st_mtime_ns, stat.st_size


@pytest.fixture
def campaign(smoke_campaign: Path, tmp_path: Path, monkeypatch) -> Path:
    """A copy of the session's smoke campaign with test metadata, as a run stating it records it;
    the lock directory points at a directory that does not exist yet."""
    path = tmp_path / "data" / "smoke.h5"
    path.parent.mkdir()
    shutil.copyfile(smoke_campaign, path)
    with h5py.File(path, "r+") as file:
        file.attrs.update({"tyre_id": "T-0815", "operator": "Jürgen", "notes": "new tyre\nrun in"})
        file["runs/smoke-s009-dwell_grid"].attrs.update({"operator": "Ann", "notes": "after lunch"})
    monkeypatch.setenv(LOCK_DIR_ENV, str(tmp_path / "locks"))
    return path


def test_show_tells_what_the_campaign_holds_and_changes_nothing(campaign: Path, capsys) -> None:
    before = _state(campaign)
    assert main(["show", str(campaign)]) == ExitCode.OK
    text = capsys.readouterr().out
    assert main(["show", str(campaign), "--json"]) == ExitCode.OK
    doc = json.loads(capsys.readouterr().out)
    assert _state(campaign) == before  # not a byte, not the modification time
    assert not (campaign.parent.parent / "locks").exists()  # no lock file, not even its directory
    assert sorted(p.name for p in campaign.parent.iterdir()) == ["smoke.h5"]  # nothing beside it

    assert (doc["schema"], doc["version"], doc["schema_version"]) == ("wfs-bench-show", 1, 2)
    assert doc["metadata"]["tyre_id"] == "T-0815" and doc["metadata"]["sensor_serial"] == ""
    assert doc["specimen"]["tyre_model"] == 2 and doc["specimen"]["bench"] == "shaker"
    runs = doc["runs"]
    assert [(r["run_id"], r["kind"], r["status"], r["reason"]) for r in runs] == [
        ("smoke-s003-free_run", "free_run", "complete", ""),
        ("smoke-s009-dwell_grid", "dwell_grid", "complete", ""),
        ("smoke-s010-sweep", "sweep", "complete", ""),
    ]
    # sequences/files/smoke.toml: 3 free-run dwells 10-60 Hz at 2 mm, the wheel removed; 4 dwells
    # 10-50 Hz at 2 mm at the 2.5 bar the simulated operator answered; a 1-30 Hz sweep at 1 mm
    assert [(r["points_done"], r["points_planned"]) for r in runs] == [(3, 3), (4, 4), (1, 1)]
    assert [(r["freq_span_hz"], r["amplitudes_mm"]) for r in runs] == [
        ([10, 60], [2]),
        ([10, 50], [2]),
        ([1, 30], [1]),
    ]
    assert [(r["tyre_pressure_bar"], r["wheel_fitted"]) for r in runs] == [
        (None, False),
        (2.5, True),
        (2.5, True),
    ]
    assert runs[1]["metadata"] == {"bench_id": "", "operator": "Ann", "notes": "after lunch"}
    assert [[a["name"] for a in r["analyses"]] for r in runs] == [["plate_mass"], ["shaker"], ["sweep"]]
    assert all(r["analyses"][0]["stored"].startswith("20") for r in runs)

    lines = text.splitlines()
    assert lines[0].startswith(f"{campaign}: campaign file, schema version 2, written by wfs-bench ")
    assert "  tyre identifier  T-0815" in lines and "                   run in" in lines
    stored = runs[0]["analyses"][0]["stored"]
    for expected in (
        "  smoke-s003-free_run  free_run  complete",
        "    points 3 of 3 done; 10-60 Hz, at 2 mm, tyre pressure not recorded, wheel removed",
        "    points 4 of 4 done; 10-50 Hz, at 2 mm, tyre 2.5 bar, wheel fitted",
        "    points 1 of 1 done; 1-30 Hz, at 1 mm, tyre 2.5 bar, wheel fitted",
        "    operator Ann",
        "    notes: after lunch",
        f"    analyses stored: plate_mass ({stored})",
    ):
        assert expected in lines, (expected, text)


def test_analyze_no_store_prints_and_leaves_the_file_as_it_was(campaign: Path, capsys) -> None:
    """The analysis with the campaign's metadata, as JSON, text and the report's heading; with
    --no-store nothing of the file changes."""
    from bench.app.analyze import analyze_campaign
    from bench.report.html import report_html

    before = _state(campaign)
    assert main(["analyze", str(campaign), "--no-store", "--json"]) == ExitCode.OK
    doc = json.loads(capsys.readouterr().out)
    assert [run["results_name"] for run in doc["runs"]] == [None, None, None]
    assert doc["metadata"]["operator"] == "Jürgen" and doc["metadata"]["notes"] == "new tyre\nrun in"
    assert main(["analyze", str(campaign), "--no-store"]) == ExitCode.OK
    text = capsys.readouterr().out.splitlines()
    assert text[:5] == [
        f"== test metadata of {campaign}",
        "  tyre identifier  T-0815",
        "  operator         Jürgen",
        "  notes            new tyre",
        "                   run in",
    ]
    assert text[5].startswith("== analysis as stored after each run by wfs-bench ")
    assert text[6] == "== smoke-s003-free_run (free_run: plate_mass)"  # no "stored as"
    assert _state(campaign) == before
    assert not (campaign.parent.parent / "locks").exists()
    page = report_html(analyze_campaign(campaign), ())
    heading = page[page.index("<h1>") : page.index("<h2>")]
    assert heading.startswith(
        '<h1>wfs-bench report: smoke.h5</h1>'
        '<table class="metadata"><tr><th>tyre identifier</th><td>T-0815</td></tr>'
        "<tr><th>operator</th><td>Jürgen</td></tr><tr><th>notes</th><td>new tyre<br>run in</td></tr></table>"
    )


def _damaged(kind: str, tmp_path: Path, smoke_campaign: Path) -> Path:
    path = tmp_path / "file.h5"
    if kind == "directory":
        path.mkdir()
    elif kind == "fifo":
        os.mkfifo(path)  # opened, it would wait for a writer forever
    elif kind == "text":
        path.write_text("time,fz\n0,1\n")
    elif kind == "truncated":
        path.write_bytes(smoke_campaign.read_bytes()[: smoke_campaign.stat().st_size * 2 // 3])
    elif kind == "superblock overwritten":
        data = bytearray(smoke_campaign.read_bytes())
        data[:64] = bytes(64)
        path.write_bytes(bytes(data))
    elif kind == "another layout":
        with h5py.File(path, "w") as file:
            file["x"] = [1.0, 2.0]
    return path


@pytest.mark.parametrize(
    ("kind", "says"),
    [
        ("missing", "no such file"),
        ("directory", "a directory, not a campaign file"),
        ("fifo", "not a regular file, not a campaign file"),
        ("text", "not a readable HDF5 file"),
        ("truncated", "not a readable HDF5 file"),
        ("superblock overwritten", "not a readable HDF5 file"),
        ("another layout", "/@schema: is None, not a 'wfs-bench campaign' file"),
    ],
)
def test_a_file_that_is_no_campaign_exits_3_naming_it(kind, says, tmp_path, smoke_campaign, capsys) -> None:
    path = _damaged(kind, tmp_path, smoke_campaign)
    assert main(["show", str(path), "--json"]) == ExitCode.INVALID
    out, err = capsys.readouterr()
    assert out == "" and err.startswith(f"error: {path}: ") and says in err, err


#: A writer of a campaign file that holds it open until its standard input closes.
WRITER = """
import sys
from bench.store import CampaignWriter
writer = CampaignWriter.create(
    sys.argv[1], software_version="t", config_toml="", sequence_toml="", sequence_name="held"
)
print("open", flush=True)
sys.stdin.read()
writer.close()
"""


def test_a_file_being_written_is_refused_and_shown_once_closed(tmp_path: Path, monkeypatch, capsys) -> None:
    """Refused with exit 2 while a process writes it (by show and by every command that reads a
    campaign file): named by its writer lock, and, where that lock is not seen (another lock
    directory), by HDF5's own lock; shown once the writer closed."""
    path = tmp_path / "held.h5"
    locks = tmp_path / "locks"
    env = {**os.environ, LOCK_DIR_ENV: str(locks)}
    writer = subprocess.Popen(
        [sys.executable, "-c", WRITER, str(path)],
        cwd=ROOT,
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert writer.stdout.readline() == "open\n"
        monkeypatch.setenv(LOCK_DIR_ENV, str(locks))
        assert main(["show", str(path)]) == ExitCode.UNAVAILABLE
        out, err = capsys.readouterr()
        assert out == "" and err.startswith(f"error: {path}: in use: being written by process {writer.pid} (")
        assert err.rstrip().endswith("show it once that has finished")
        readers = (  # every command that reads a campaign file: the same code as show
            ["analyze", str(path), "--no-store"],
            ["report", str(path), "--out", str(tmp_path / "report")],
            ["export", str(path), "--format", "mdf4", "--out", str(tmp_path / "held.mf4")],
        )
        for command in readers:
            assert main(command) == ExitCode.UNAVAILABLE, command
            said = capsys.readouterr().err
            assert f"error: {path}: in use: being written by process {writer.pid} (" in said
        monkeypatch.setenv(LOCK_DIR_ENV, str(tmp_path / "other-locks"))
        assert main(["show", str(path)]) == ExitCode.UNAVAILABLE
        assert f"{path}: in use: being written by another process" in capsys.readouterr().err
    finally:
        writer.communicate("", timeout=60)
    assert writer.returncode == 0
    assert main(["show", str(path)]) == ExitCode.OK
    assert "runs: none" in capsys.readouterr().out
    # closed, it holds no run: nothing analysed is no complete analysis
    assert main(["analyze", str(path), "--no-store"]) == ExitCode.INCOMPLETE
    out = capsys.readouterr().out
    assert out.splitlines()[-1] == "== analysis incomplete: the file holds no complete run to analyse"


def test_a_run_whose_step_is_no_sequence_step_is_shown_from_its_points(tmp_path: Path, capsys) -> None:
    """Another writer's step (here: a grid whose frequencies are no list) plans nothing known; the
    run's excitation is read from the points it did (the nominal amplitude where a limit lowered it)."""
    from bench.store import CampaignWriter
    from sequences.channels import Channel
    from sequences.points import PointAttempt

    path = tmp_path / "other.h5"
    with CampaignWriter.create(
        path, software_version="t", config_toml="", sequence_toml="", sequence_name="other"
    ) as writer:
        run = writer.begin_run(
            "r1",
            kind="dwell_grid",
            step={"type": "dwell_grid", "freqs_hz": 5, "amplitudes_mm": [1]},
            conditions={"tyre_pressure_bar": float("nan")},
            channels=(Channel("fz_wfs_n", "N"),),
            sample_rate_hz=1e3,
        )
        run.append({"fz_wfs_n": [0.0] * 3000})
        run.add_point(PointAttempt(0, 5.0, 1.0, 0, 100, 900, 1000))
        run.add_point(PointAttempt(1, 40.0, 0.5, 1000, 1100, 1900, 2000, requested_amplitude_mm=1.0))
        run.finish("complete")
    assert main(["show", str(path), "--json"]) == ExitCode.OK
    (shown,) = json.loads(capsys.readouterr().out)["runs"]
    assert (shown["points_done"], shown["points_planned"]) == (2, None)
    assert (shown["freq_span_hz"], shown["amplitudes_mm"]) == ([5, 40], [1])
    assert shown["conditions"] == {"tyre_pressure_bar": None} and shown["tyre_pressure_bar"] is None
    assert main(["show", str(path)]) == ExitCode.OK
    assert "    points 2 done (planned: not recorded); 5-40 Hz, at 1 mm," in capsys.readouterr().out
