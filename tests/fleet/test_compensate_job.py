"""``wfsbench compensate CAMPAIGN DIR --out DIR``: many measurements as one job, in this process or
on a local cluster: each output what the command writes for that measurement alone, damaged and
foreign files listed with their errors, unchanged files not read again, a run with nothing to do
starting no process, a measurement larger than the memory allowed compensated block by block."""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import duckdb
import h5py
import numpy as np
import psutil
import pytest

from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from tests.documented import assert_documented
from tests.fleet.roads import road_channels, write_csv, write_mdf4
from tests.waiting import wait_until

#: A long test module: in the validation tier (README.md, *Set up and run the tests*).
pytestmark = pytest.mark.validation

ROOT = Path(__file__).resolve().parents[2]


def _statuses(out: Path) -> dict[str, tuple[str, str | None]]:
    rows = duckdb.sql(f"SELECT path, status, error FROM read_parquet('{out}/summary.parquet')").fetchall()
    return {os.path.relpath(path, out.parent / "roads"): (status, error) for path, status, error in rows}


def _force(path: Path) -> dict[str, np.ndarray]:
    with h5py.File(path, "r") as f:
        return {name: f[name][:] for name in ("t_s", "f_contact_n", "u95_n")}


def test_each_output_of_a_job_is_the_one_measurements_output_and_bad_files_are_listed(
    campaign, roads, tmp_path, capsys
):
    out = tmp_path / "out"
    assert (
        main(
            [
                "compensate",
                str(campaign),
                str(roads),
                "--out",
                str(out),
                "--workers",
                "0",
                "--pressure",
                "2.5",
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith(f"compensate {out}: 6 files found; 0 unchanged, not read;")
    problems = {line.split(": ")[1]: line for line in printed[1:]}
    assert set(problems) == {str(roads / "damaged.mf4"), str(roads / "foreign.csv")}
    assert all(line.startswith("unreadable: ") for line in problems.values())
    for measurement in ("drive-1.csv", "car2/drive-4.mf4"):
        alone = tmp_path / f"{Path(measurement).name}.h5"
        assert (
            main(
                [
                    "compensate",
                    str(campaign),
                    str(roads / measurement),
                    "--out",
                    str(alone),
                    "--pressure",
                    "2.5",
                ]
            )
            == 0
        )
        in_job = _force(out / f"{measurement}.compensated.h5")
        for name, values in _force(alone).items():
            assert np.array_equal(values, in_job[name], equal_nan=True), (measurement, name)
    row = duckdb.sql(
        f"SELECT n_samples, duration_s, f_contact_rms_n, f_contact_max_n, u95_median_n, valid_band_hi_hz,"
        f" assumptions FROM read_parquet('{out}/summary.parquet') WHERE path = '{roads / 'drive-1.csv'}'"
    ).fetchall()[0]
    force = _force(out / "drive-1.csv.compensated.h5")["f_contact_n"]
    assert row[0] == force.size == 20000 and row[1] == pytest.approx(20.0)
    assert row[2] == pytest.approx(np.nanstd(force.astype(float)), rel=1e-6)
    assert row[3] == pytest.approx(np.nanmax(force), rel=1e-6)
    assert row[4] > 0 and row[5] > 10
    assert "hub accelerometer lag" in row[6] and "tyre pressure 2.5 bar" in row[6]


def test_a_rerun_compensates_only_what_changed_and_all_of_it_when_the_identification_changed(
    campaign, roads, tmp_path, capsys
):
    folder, out = tmp_path / "roads", tmp_path / "out"
    shutil.copytree(roads, folder)
    local_campaign = shutil.copy(campaign, tmp_path / "campaign.h5")
    command = [
        "compensate",
        str(local_campaign),
        str(folder),
        "--out",
        str(out),
        "--workers",
        "0",
        "--pressure",
        "2.5",
    ]
    assert main(command) == 0
    capsys.readouterr()
    write_csv(folder / "drive-1.csv", road_channels(11))  # another drive under the same name
    (folder / "car2" / "drive-2.csv").unlink()
    assert main(command) == 0
    assert capsys.readouterr().out.startswith(
        f"compensate {out}: 5 files found; 4 unchanged, not read; read: 1 compensated;"
        " 1 gone from the summary;"
    )
    assert set(_statuses(out)) == {
        "drive-1.csv",
        "drive-3.mf4",
        "car2/drive-4.mf4",
        "damaged.mf4",
        "foreign.csv",
    }
    stat = os.stat(local_campaign)
    os.utime(local_campaign, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))  # a campaign written again
    assert main(command) == 0
    assert (
        "5 files found; 0 unchanged, not read; read: 3 compensated, 2 unreadable;" in capsys.readouterr().out
    )


def test_a_job_refuses_the_options_of_one_measurement_and_paths_that_do_not_exist(
    campaign, roads, tmp_path, capsys
):
    out = str(tmp_path / "out")
    assert main(["compensate", str(campaign), str(roads), "--out", out, "--json"]) == ExitCode.INVALID
    assert "--json" in capsys.readouterr().err
    assert (
        main(["compensate", str(campaign), str(roads / "nothing"), str(roads), "--out", out])
        == ExitCode.INVALID
    )
    assert "no such file or directory" in capsys.readouterr().err
    assert main(["compensate", str(roads / "drive-1.csv"), str(roads), "--out", out]) == ExitCode.INVALID
    assert not (tmp_path / "out").exists()


def _pythons_started(command: list[str]) -> tuple[int, dict[int, str]]:
    """Run ``command`` and watch it to its end; its exit code and the processes of a local cluster it
    started, by their command lines: Python started by ``multiprocessing`` (the cluster's workers and
    their resource tracker). A command's other children are not counted: importing h5py runs
    ``uname -p``, which until it runs that program is a fork of the command itself."""
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    watched, lines = psutil.Process(process.pid), {}

    def ended() -> bool:
        with contextlib.suppress(psutil.NoSuchProcess):
            for child in watched.children(recursive=True):
                if lines.get(child.pid, "?") == "?":
                    lines[child.pid] = _command_line(child)
        return process.poll() is not None

    wait_until(ended, 300, "the command's end")
    return process.returncode, {pid: line for pid, line in lines.items() if "multiprocessing" in line}


def _command_line(process: psutil.Process) -> str:
    try:
        return " ".join(process.cmdline())
    except psutil.Error:
        return "?"


@pytest.mark.validation
def test_a_rerun_over_unchanged_files_starts_no_worker_of_its_local_cluster(campaign, roads, tmp_path):
    folder, out = tmp_path / "roads", tmp_path / "out"
    folder.mkdir()
    shutil.copy(roads / "drive-1.csv", folder)
    command = [
        sys.executable,
        "-m",
        "bench.cli",
        "compensate",
        str(campaign),
        str(folder),
        "--out",
        str(out),
        "--workers",
        "2",
        "--pressure",
        "2.5",
    ]
    code, started = _pythons_started(command)
    # the first run starts its cluster: its processes seen (its workers and their resource tracker;
    # beside four busy processes the job once ended, its one file done in its own process, with only
    # the tracker spawned)
    assert code == 0 and len(started) >= 1
    first = duckdb.sql(f"SELECT path, status, error FROM read_parquet('{out}/summary.parquet')").fetchall()
    assert [status for _, status, _ in first] == ["compensated"], first  # nothing left to try again
    code, started = _pythons_started(command)
    after = duckdb.sql(f"SELECT path, status, error FROM read_parquet('{out}/summary.parquet')").fetchall()
    assert code == 0 and started == {}, (started, first, after)


MEMORY_CHILD = textwrap.dedent(
    """
    import resource, sys
    from bench.cli.main import main

    campaign, small, large, out, limit_mb, mode = sys.argv[1:]
    # imports, the campaign's analysis and a first measurement before the limit: it bounds the work
    options = ["--workers", "0", "--pressure", "2.5"]
    assert main(["compensate", campaign, small, "--out", out + "-warm", *options]) == 0
    status = open("/proc/self/status").read().splitlines()
    data = int(next(line for line in status if line.startswith("VmData")).split()[1]) * 1024
    limit = data + int(limit_mb) * 2**20
    resource.setrlimit(resource.RLIMIT_DATA, (limit, limit))
    if mode == "whole":  # the record read whole, as a reader without blocks would
        from asammdf import MDF
        with MDF(large) as mdf:
            kept = [mdf.get(name) for name in ("fz_wfs_n", "a_hub_m_s2")]
        print("read whole")
    else:
        sys.exit(main(["compensate", campaign, large, "--out", out, *options]))
    """
)


@pytest.mark.validation
def test_a_measurement_larger_than_the_memory_allowed_is_compensated(campaign, roads, tmp_path):
    n_samples, limit_mb = 8_000_000, 120
    minute = road_channels(21, duration_s=60.0)
    repeats = -(-n_samples // minute["fz_wfs_n"].size)
    large = write_mdf4(
        tmp_path / "long.mf4", {name: np.tile(x, repeats)[:n_samples] for name, x in minute.items()}
    )
    whole_mb = n_samples * 8 * 4 / 2**20  # two channels' samples and time stamps, float64
    assert whole_mb > 2 * limit_mb
    assert_documented(
        "docs/compensate.md",
        f"a measurement of {n_samples // 10**6} million samples in a process whose data segment may grow by"
        f" {limit_mb} MB only (`RLIMIT_DATA`), where reading the record whole needs {whole_mb:.0f} MB",
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}

    def child(mode: str) -> subprocess.CompletedProcess:
        arguments = [
            str(campaign),
            str(roads / "drive-1.csv"),
            str(large),
            str(tmp_path / f"out-{mode}"),
            str(limit_mb),
            mode,
        ]
        return subprocess.run(
            [sys.executable, "-c", MEMORY_CHILD, *arguments],
            capture_output=True,
            text=True,
            env=env,
            check=False,
            timeout=600,
        )

    whole = child("whole")  # the limit bites: the record cannot be read whole
    assert whole.returncode != 0 and "MemoryError" in whole.stderr
    done = child("job")
    assert done.returncode == 0, done.stderr
    row = duckdb.sql(
        f"SELECT status, n_samples, f_contact_rms_n FROM read_parquet('{tmp_path}/out-job/summary.parquet')"
    ).fetchall()[0]
    assert row[0] == "compensated" and row[1] == n_samples and np.isfinite(row[2])
    with h5py.File(tmp_path / "out-job" / "long.mf4.compensated.h5", "r") as f:
        assert f["f_contact_n"].shape == (n_samples,)
        assert np.isfinite(f["f_contact_n"][n_samples // 2 : n_samples // 2 + 1000]).all()
