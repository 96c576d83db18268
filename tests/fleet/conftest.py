"""The compensation job's fixtures: the paper's campaign at 2.5 bar, a folder of road measurements
(MDF4 and CSV, one damaged, one foreign), and a ``dask.distributed`` cluster of a scheduler and two
workers started as separate processes with Dask's own commands on 127.0.0.1."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.campaign_files import paper_corner_runs, write_analysed_campaign
from tests.fleet.roads import CAR, road_channels, write_csv, write_mdf4
from tests.made_once import made_once
from tests.waiting import wait_until

DASK = str(Path(sys.executable).with_name("dask"))


@pytest.fixture(scope="session")
def campaign(shared_folder) -> Path:
    """The paper's procedure at 2.5 bar: free run, grids at 1 / 2 / 5 mm, the four-post sweep, with
    its analysis stored as the bench stores it after each run (once per test run: read it, do not
    change it)."""
    return made_once(
        shared_folder, "fleet-campaign.h5", lambda path: write_analysed_campaign(path, paper_corner_runs(CAR))
    )


@pytest.fixture(scope="session")
def roads(tmp_path_factory) -> Path:
    """A folder of measurements: two CSV and two MDF4 drives (one in a sub-folder), an MDF4 file
    cut short in copying (damaged), and a CSV file of another logger's layout (foreign)."""
    folder = tmp_path_factory.mktemp("roads")
    (folder / "car2").mkdir()
    write_csv(folder / "drive-1.csv", road_channels(1))
    write_csv(folder / "car2" / "drive-2.csv", road_channels(2))
    write_mdf4(folder / "drive-3.mf4", road_channels(3))
    write_mdf4(folder / "car2" / "drive-4.mf4", road_channels(4))
    whole = (folder / "drive-3.mf4").read_bytes()
    (folder / "damaged.mf4").write_bytes(whole[: len(whole) // 3])
    (folder / "foreign.csv").write_text("Zeit;Kraft\n0,0;12,5\n")
    return folder


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory) -> str:
    """A scheduler and two one-thread workers, each a process of its own started with ``dask
    scheduler`` and ``dask worker`` on 127.0.0.1; the scheduler's address."""
    from dask.distributed import Client

    folder = tmp_path_factory.mktemp("cluster")
    scheduler_file = folder / "scheduler.json"
    logs = [(folder / f"{name}.log").open("w") for name in ("scheduler", "worker-1", "worker-2")]
    processes = [
        subprocess.Popen(
            [
                DASK,
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                "0",
                "--no-dashboard",
                "--scheduler-file",
                str(scheduler_file),
            ],
            stdout=logs[0],
            stderr=subprocess.STDOUT,
        )
    ]
    try:
        wait_until(scheduler_file.exists, 60, "the scheduler's file")
        for log in logs[1:]:
            processes.append(
                subprocess.Popen(
                    [
                        DASK,
                        "worker",
                        "--scheduler-file",
                        str(scheduler_file),
                        "--host",
                        "127.0.0.1",
                        "--nthreads",
                        "1",
                        "--no-dashboard",
                    ],
                    stdout=log,
                    stderr=subprocess.STDOUT,
                )
            )
        with Client(scheduler_file=str(scheduler_file)) as client:
            address = client.scheduler.address
            wait_until(lambda: len(client.scheduler_info(n_workers=-1)["workers"]) == 2, 120, "two workers")
        yield address
    finally:
        for process in reversed(processes):
            process.terminate()
        for process in processes:
            try:
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        for log in logs:
            log.close()
        shutil.rmtree(folder, ignore_errors=True)
