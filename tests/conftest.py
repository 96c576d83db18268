"""Shared fixtures: a simulated bench with its runner, the controller served on 127.0.0.1, the
smoke sequence's campaign file."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

import bench as _wfs_bench  # noqa: F401 - first: it sets the BLAS thread limit before numpy loads
from drivers.actuator import ActuatorClient
from sequences.limits import BenchLimits
from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.controller_server import ControllerServer
from tests.made_once import made_once

#: The test modules' code as rewritten for pytest's assertions is kept beside them (in __pycache__)
#: where PYTHONDONTWRITEBYTECODE is set too: each test worker would otherwise rewrite every module
#: again, 9.5 s of processor time per worker on a 2-core machine (the modules themselves are compiled
#: by .ci/setup, which also writes this cache once before the suite's first run).
sys.dont_write_bytecode = False


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The longest tests first on every test worker: the slow ones (whole campaigns; in the
    validation tier, the coverage over many seeds and the paper's campaign), then the terminal
    UI's (seconds each, waiting on the app's refreshes), then the rest in their order. The
    scheduler (work stealing) hands each worker a contiguous share of the list and steals from
    the shares' ends, so the long tests are dealt to the shares in turn, each followed by its part
    of the rest, kept in file order: each worker starts on its part of the long tests, no long
    test is left to run alone at the end while the others idle, and a module's tests stay
    together with the fixtures they share."""

    def rank(item: pytest.Item) -> int:
        if item.get_closest_marker("slow") or item.get_closest_marker("validation"):
            return 0
        return 1 if item.path.parent.name == "tui" else 2

    items.sort(key=rank)  # stable: each group keeps its order
    workers = getattr(config, "workerinput", {}).get("workercount", 1)
    long = [item for item in items if rank(item) < 2]
    rest = items[len(long) :]
    cuts = [len(rest) * share // workers for share in range(workers + 1)]
    items[:] = [
        item
        for share in range(workers)
        for item in (*long[share::workers], *rest[cuts[share] : cuts[share + 1]])
    ]


@pytest.fixture
def bench():
    """A paper shaker bench advanced in real time (the controller's tapers run at wall-clock pace)."""
    bench = SimulatedBench.paper_shaker(seed=1)
    runner = BenchRunner(bench, paced=True)
    runner.start()
    yield bench
    runner.stop()
    assert runner.error is None


@pytest.fixture
async def controller(bench):
    server = ControllerServer(bench)
    host, port = await server.serve_tcp("127.0.0.1", 0)
    server.address = (host, port)
    yield server
    await server.close()


@pytest.fixture
async def client(controller):
    host, port = controller.address
    client = ActuatorClient.tcp(host, port, limits=BenchLimits(), timeout_s=0.3)
    await client.connect()
    # the watchdog is armed at power-up; tests that are not about it run with it off (as a lab may
    # set it), so that a loaded machine cannot trip a dwell that no heartbeat keeps alive
    with controller.bench.lock:
        assert controller.bench.controller.write_setpoints({"watchdog_ms": 0}) is None
    yield client
    await client.close()


@pytest.fixture(scope="session")
def shared_folder(tmp_path_factory, worker_id) -> Path:
    """A folder every test worker of this test run shares (for files made once per run:
    :func:`tests.made_once.made_once`)."""
    base = tmp_path_factory.getbasetemp()
    return base if worker_id == "master" else base.parent  # the test workers' folders share a parent


@pytest.fixture(scope="session")
def smoke_campaign(shared_folder) -> Path:
    """The shipped smoke sequence run on the unpaced simulated bench into a campaign file, once per
    test run (read it, do not change it)."""
    from bench.app.plan import plan_campaign
    from bench.app.run import run_campaign

    def record(path: Path) -> None:
        sequence = Path(__file__).resolve().parents[1] / "sequences" / "files" / "smoke.toml"
        outcome = run_campaign(plan_campaign(sequence), path)
        assert outcome.status == "complete", outcome.reason

    return made_once(shared_folder, "smoke.h5", record)
