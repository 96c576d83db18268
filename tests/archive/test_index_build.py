"""An index run over a mixed directory: a campaign, a file that is not HDF5, a foreign HDF5 file,
a truncated campaign and a campaign a bench is recording into (its writer in another process); the
re-index of the unchanged directory, of a touched file, of one file added; a file that changes
between listing and reading. Nothing stops a run, and no indexed file is written to."""

from __future__ import annotations

import dataclasses
import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import duckdb
import h5py
import numpy as np
import pyarrow.compute as pc
import pytest

from bench.archive import store
from bench.archive.build import FileOutcome, FileStatus, FileTask, build_index, index_file
from bench.archive.files import FileStat
from bench.archive.store import part_paths, read_index
from bench.cli.main import main
from bench.cluster import InProcess
from tests.archive.conftest import SIMULATED
from tests.archive_files import archive_campaign, copy_campaign

#: A bench recording into a campaign file: the writer holds the file's lock until its standard
#: input closes, then finishes the run and closes the file.
RECORDING = """
import sys
import numpy as np
import pyarrow.compute as pc
from bench.store import CampaignWriter
from sequences.channels import Channel

writer = CampaignWriter.create(sys.argv[1], software_version="recording", config_toml="",
                               sequence_toml="", sequence_name="recording")
run = writer.begin_run("rec-s001-free_run", kind="free_run", step={"type": "free_run"},
                       conditions={}, channels=(Channel("z_m", "m"),), sample_rate_hz=1000.0)
run.append({"z_m": np.zeros(2000, "f4")})
writer.flush()
print("recording", flush=True)
sys.stdin.read()
run.finish("aborted", "stopped by the operator")
writer.close()
"""


class Seen:
    """The progress of an index run: the files it listed to read, and each one done."""

    def __init__(self) -> None:
        self.to_read: list[str] = []
        self.outcomes: list[FileOutcome] = []

    def listed(self, path: str, *, to_read: bool) -> None:
        if to_read:
            self.to_read.append(path)

    def done(self, outcome: FileOutcome) -> None:
        self.outcomes.append(outcome)

    @property
    def opened(self) -> list[str]:
        return [o.path for o in self.outcomes if o.opened]


def _index(directory: Path, out: Path, **options) -> tuple[Seen, object]:
    seen = Seen()
    summary = build_index([directory], out, InProcess(), progress=seen, **options)
    return seen, summary


def _file_rows(out: Path) -> dict[str, dict]:
    table = read_index(out)
    return {row["path"]: row for row in table.to_pylist() if row["entry"] == "file"}


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def mixed(archive, tmp_path) -> Path:
    """A directory of one campaign, a text file named .h5, a foreign HDF5 file and a truncated
    campaign (the bench's recording is added by the test)."""
    directory = tmp_path / "mixed"
    source = next(iter(archive))
    shutil.copyfile(source, directory / "good.h5") if directory.mkdir() is None else None
    (directory / "notes.h5").write_text("not a campaign\n")
    with h5py.File(directory / "foreign.hdf5", "w") as file:
        file.attrs["schema"] = "another lab's layout"
        file["data"] = np.arange(10.0)
    data = source.read_bytes()
    (directory / "truncated.h5").write_bytes(data[: len(data) // 2])
    (directory / "readme.txt").write_text("not a candidate: not *.h5\n")
    return directory


def test_mixed_directory_then_reindex_reads_only_what_changed(mixed, tmp_path):
    out = tmp_path / "results"
    recording = mixed / "recording.h5"
    bench = subprocess.Popen(
        [sys.executable, "-c", RECORDING, str(recording)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert bench.stdout.readline() == "recording\n"
        good_sha = _sha256(mixed / "good.h5")
        good_mtime = (mixed / "good.h5").stat().st_mtime_ns
        seen, summary = _index(mixed, out)
        files = _file_rows(out)
        status = {Path(p).name: row["file_status"] for p, row in files.items()}
        assert status == {
            "good.h5": FileStatus.INDEXED,
            "notes.h5": FileStatus.NOT_CAMPAIGN,
            "foreign.hdf5": FileStatus.NOT_CAMPAIGN,
            "truncated.h5": FileStatus.DAMAGED,
            "recording.h5": FileStatus.LOCKED,
        }
        errors = {Path(p).name: row["error"] for p, row in files.items()}
        assert errors["good.h5"] is None
        assert "/@schema" in errors["foreign.hdf5"] and "not a readable HDF5 file" in errors["notes.h5"]
        assert "truncated" in errors["truncated.h5"] or "unreadable" in errors["truncated.h5"]
        assert f"process {bench.pid}" in errors["recording.h5"]  # the recording bench, by its pid
        assert files[str(mixed / "recording.h5")]["sha256"] is None  # skipped unread
        assert sorted(Path(p).name for p, _, _ in summary.problems) == [
            "foreign.hdf5",
            "notes.h5",
            "recording.h5",
            "truncated.h5",
        ]
        # read only: the campaign's bytes and time as they were, its hash the index's
        assert _sha256(mixed / "good.h5") == good_sha == files[str(mixed / "good.h5")]["sha256"]
        assert (mixed / "good.h5").stat().st_mtime_ns == good_mtime
    finally:
        bench.communicate("")  # the bench finishes its run and closes the file
    assert bench.returncode == 0

    seen, summary = _index(mixed, out)  # the locked file is tried again; nothing else is read
    assert seen.opened == [str(recording)] and summary.unchanged == 4
    assert _file_rows(out)[str(recording)]["file_status"] == FileStatus.INDEXED

    parts = {p: p.stat().st_mtime_ns for p in part_paths(out)}
    seen, summary = _index(mixed, out)  # unchanged: nothing read, not even hashed; no part rewritten
    assert seen.to_read == [] and seen.outcomes == [] and summary.unchanged == 5
    assert {p: p.stat().st_mtime_ns for p in part_paths(out)} == parts

    os.utime(mixed / "good.h5", ns=(good_mtime, good_mtime + 10**9))  # touched: same contents
    seen, summary = _index(mixed, out)
    assert seen.to_read == [str(mixed / "good.h5")] and seen.opened == [] and summary.same_contents == 1
    assert _file_rows(out)[str(mixed / "good.h5")]["mtime_ns"] == good_mtime + 10**9

    added = copy_campaign(
        mixed / "good.h5", mixed / "deeper" / "added.h5", dataclasses.replace(SIMULATED, bench_id="9")
    )
    before = read_index(out)
    seen, summary = _index(mixed, out)
    assert seen.opened == [str(added)] and summary.unchanged == 5
    after = read_index(out)
    assert after.filter(pc.not_equal(after["path"], str(added))).equals(before)
    assert {row["bench_id"] for row in after.to_pylist() if row["path"] == str(added)} == {"9"}

    (mixed / "notes.h5").unlink()
    seen, summary = _index(mixed, out)
    assert seen.opened == [] and summary.removed == 1
    assert str(mixed / "notes.h5") not in _file_rows(out)


def test_verify_hashes_every_file_and_finds_a_rewrite_behind_the_same_time(mixed, tmp_path):
    out = tmp_path / "results"
    (mixed / "truncated.h5").unlink()
    _index(mixed, out)
    notes = mixed / "notes.h5"
    stat = notes.stat()
    notes.write_text("NOT a campaign\n")  # the same size, then its old time back
    os.utime(notes, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    seen, _ = _index(mixed, out)
    assert seen.outcomes == []  # size and time alone cannot tell
    seen, summary = _index(mixed, out, verify=True)
    assert sorted(Path(p).name for p in seen.to_read) == ["foreign.hdf5", "good.h5", "notes.h5"]
    assert [Path(o.path).name for o in seen.outcomes if o.rows is not None] == ["notes.h5"]
    assert summary.unchanged == 2
    assert _file_rows(out)[str(notes)]["sha256"] == _sha256(notes)


def test_a_file_changed_since_it_was_listed_is_skipped_unread(archive, tmp_path):
    path = shutil.copyfile(next(iter(archive)), tmp_path / "growing.h5")
    listed = FileStat.of(path)
    with open(path, "ab") as file:
        file.write(b"\0" * 512)  # a writer appends after the listing
    outcome = index_file(FileTask(str(path), listed))
    assert outcome.status == FileStatus.CHANGING and not outcome.opened and outcome.sha256 is None
    assert "changed since it was listed" in outcome.error
    assert outcome.rows.to_pylist()[0]["size_bytes"] == listed.size_bytes + 512


def test_index_command(mixed, tmp_path, capsys):
    out = tmp_path / "results"
    assert (
        main(
            [
                "index",
                str(mixed / "notes.h5"),
                str(mixed / "foreign.hdf5"),
                "--out",
                str(out),
                "--workers",
                "0",
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith(f"index {out}: 2 files found; 0 unchanged, not read; read: 2 not_campaign;")
    assert printed[1] == (
        f"not_campaign: {mixed / 'notes.h5'}: not a readable HDF5 file"
        " (Unable to synchronously open file (file signature not found))"
    )
    assert printed[2].startswith(f"not_campaign: {mixed / 'foreign.hdf5'}: /@schema: ") and len(printed) == 3
    assert main(["index", str(tmp_path / "nowhere"), "--out", str(out), "--workers", "0"]) == 3
    assert "no such file or directory" in capsys.readouterr().err
    (tmp_path / "a-file").write_text("")
    assert main(["index", str(mixed / "notes.h5"), "--out", str(tmp_path / "a-file"), "--workers", "0"]) == 3
    assert "exists and is not a directory" in capsys.readouterr().err


def test_a_fifo_or_a_device_named_like_a_campaign_is_listed_damaged_and_never_read(tmp_path):
    """A FIFO and a link to /dev/zero named ``*.h5``: reading either would never end (a FIFO waits
    for a writer, /dev/zero has no end); each is listed with its error, and the index finishes."""
    directory = tmp_path / "odd"
    directory.mkdir()
    os.mkfifo(directory / "fifo.h5")
    (directory / "zero.h5").symlink_to("/dev/zero")
    _, summary = _index(directory, tmp_path / "results")
    files = _file_rows(tmp_path / "results")
    assert {Path(p).name: row["file_status"] for p, row in files.items()} == {
        "fifo.h5": FileStatus.DAMAGED,
        "zero.h5": FileStatus.DAMAGED,
    }
    assert all("not a regular file" in row["error"] for row in files.values())
    assert sorted(Path(p).name for p, _, _ in summary.problems) == ["fifo.h5", "zero.h5"]


class KilledAfter(Seen):
    """The progress of a run that dies (as a killed process would) after ``n`` files were read."""

    def __init__(self, n: int) -> None:
        super().__init__()
        self.n = n

    def done(self, outcome: FileOutcome) -> None:
        super().done(outcome)
        if len(self.outcomes) == self.n:
            raise KeyboardInterrupt("killed")


def _duckdb_file_rows(out: Path) -> dict[str, int]:
    """Per file path, its file rows as the documented reader sees them: DuckDB over the glob."""
    with duckdb.connect() as db:
        rows = db.execute(
            f"select path, count(*) from read_parquet('{out}/*.parquet') where entry = 'file' group by path"
        ).fetchall()
    return dict(rows)


@pytest.mark.validation
@pytest.mark.slow
def test_a_run_killed_mid_way_leaves_the_index_as_it_was_for_a_reader_of_the_glob(
    archive, tmp_path, monkeypatch
):
    """An incremental run over more files than one part holds (one here, 1,024 in use) dies after
    reading both changed files, before its end: the glob still reads every file once, as before the run;
    the next run removes its temporaries and brings the index up to date."""
    monkeypatch.setattr(store, "FILES_PER_PART", 1)
    source, directory, out = next(iter(archive)), tmp_path / "many", tmp_path / "index"
    for i in range(2):
        copy_campaign(source, directory / f"c{i}.h5", archive_campaign(i))
    _index(directory, out)
    before = _duckdb_file_rows(out)
    assert len(part_paths(out)) == 2 and before == {str(directory / f"c{i}.h5"): 1 for i in range(2)}
    for i in range(2):  # every file's metadata edited: the next run reads all again
        copy_campaign(source, directory / f"c{i}.h5", archive_campaign(i + 2))
    with pytest.raises(KeyboardInterrupt):
        build_index([directory], out, InProcess(), files_per_task=1, progress=KilledAfter(2))
    assert any(name.startswith(".part-") for name in os.listdir(out)), "its parts written, not published"
    assert _duckdb_file_rows(out) == before
    seen, _ = _index(directory, out)
    assert len(seen.opened) == 2 and _duckdb_file_rows(out) == before
    operators = {row["path"]: row["operator"] for row in _file_rows(out).values()}
    assert operators == {str(directory / f"c{i}.h5"): archive_campaign(i + 2).operator for i in range(2)}
    assert not [name for name in os.listdir(out) if name.startswith(".")]
