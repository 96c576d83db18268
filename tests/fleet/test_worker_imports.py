"""What a job's worker imports: each job names the modules its first file imports
(``WORKER_IMPORTS``), and a local cluster's workers start with them imported, forked from one
process that imported them once (:mod:`bench.cluster`). A module left off the list costs every
worker its import at its first task; these tests keep the lists whole and show the workers have
them before any task."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tests.archive_files import write_archive
from tests.fleet.roads import road_channels, write_mdf4

#: Each test starts a fresh interpreter (and one a cluster): with the fleet's jobs on a cluster, in
#: the validation tier.
pytestmark = pytest.mark.validation

ROOT = Path(__file__).resolve().parents[2]
#: The packages of the project: imported lazily at a first file is cheap; what is listed is not.
OWN_PACKAGES = {"bench", "drivers", "sequences", "simulators"}

#: In a fresh interpreter: the job's work module and its worker imports, then one file done; the
#: modules of other packages than the standard library's and the project's imported by the file.
FIRST_FILE = textwrap.dedent(
    """
    import importlib, json, sys
    from pathlib import Path

    job, path, campaign, out = sys.argv[1:5]
    work_module = {"index": "bench.archive.build", "compensate": "bench.fleet.worker"}[job]
    module = importlib.import_module(work_module)
    for name in module.WORKER_IMPORTS:
        importlib.import_module(name)
    before = set(sys.modules)
    if job == "index":
        from bench.archive.files import FileStat
        outcome = module.index_file(module.FileTask(path, FileStat.of(path)))
    else:
        from bench.cluster import InProcess
        from bench.fleet.job import compensate_many, identification
        from dataclasses import replace
        settings = module.Settings(campaign, "", pressure_bar=2.5)
        settings = replace(settings, identification=identification(settings))
        outcome = compensate_many([Path(path).parent], Path(out), settings, InProcess())
    own = {"bench", "drivers", "sequences", "simulators"}
    new = sorted(
        name for name in set(sys.modules) - before
        if name.split(".")[0] not in sys.stdlib_module_names | own and not name.startswith("_")
    )
    print(json.dumps({"statuses": str(outcome.statuses if job != "index" else outcome.status), "new": new}))
    """
)


def _fresh(script: str, *args: str) -> dict:
    """``script`` run in a fresh interpreter with ``args``: the JSON of its last line."""
    command = [sys.executable, "-c", script, *args]
    done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


def _first_file(job: str, path: Path, campaign: Path, out: Path) -> dict:
    return _fresh(FIRST_FILE, job, str(path), str(campaign), str(out))


def _packages(modules: list[str]) -> str:
    return f"imported at the first file: {sorted({name.split('.')[0] for name in modules})}"


def test_indexing_a_first_file_imports_no_package_beyond_the_index_worker_imports(tmp_path):
    (path,) = write_archive(tmp_path / "archive", 1)
    seen = _first_file("index", path, path, tmp_path / "out")
    assert seen["statuses"] == "indexed"
    assert seen["new"] == [], _packages(seen["new"])


def test_compensating_a_first_measurement_imports_no_package_beyond_the_compensation_worker_imports(
    campaign, tmp_path
):
    path = write_mdf4(tmp_path / "roads" / "drive.mf4", road_channels(3))
    seen = _first_file("compensate", path, campaign, tmp_path / "out")
    assert "compensated" in seen["statuses"]
    assert seen["new"] == [], _packages(seen["new"])


#: In a fresh interpreter: a local cluster started for the index's work; what each worker has
#: imported before its first task, and which process it was forked from.
WORKERS_BEFORE_A_TASK = textwrap.dedent(
    """
    import json, os, sys
    from bench.archive.build import WORKER_IMPORTS
    from bench.cluster import local_cluster
    from dask.distributed import Client

    wanted = ["bench.archive.build", *WORKER_IMPORTS]
    with local_cluster(2, wanted) as cluster, Client(cluster) as client:
        imported = lambda: [m for m in wanted if m in sys.modules]  # noqa: E731
        seen = client.run(lambda: {"imported": imported(), "parent": os.getppid()})
    print(json.dumps({"client": os.getpid(), "workers": list(seen.values()), "wanted": wanted}))
    """
)


def test_a_local_clusters_workers_start_with_the_jobs_modules_imported_forked_from_one_process():
    seen = _fresh(WORKERS_BEFORE_A_TASK)
    assert len(seen["workers"]) == 2
    for worker in seen["workers"]:
        assert worker["imported"] == seen["wanted"]  # before any task
    parents = {worker["parent"] for worker in seen["workers"]}
    assert len(parents) == 1 and seen["client"] not in parents  # both forked from the one server
