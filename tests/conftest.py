"""Shared fixtures: a simulated bench with its runner, the controller served on 127.0.0.1, the
smoke sequence's campaign file."""

from __future__ import annotations

import fcntl
from pathlib import Path

import pytest

import bench as _wfs_bench  # noqa: F401 - first: it sets the BLAS thread limit before numpy loads
from drivers.actuator import ActuatorClient
from sequences.limits import BenchLimits
from simulators.bench_sim import BenchRunner, SimulatedBench
from simulators.controller_server import ControllerServer


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The longest tests first: the slow ones (whole campaigns; in the validation tier, the
    coverage over many seeds and the paper's campaign), then the terminal UI's (seconds each,
    waiting on the app's refreshes), then the rest in their order. The test workers take tests in
    this order, so a long test is not left to run alone at the end while the other workers idle."""

    def rank(item: pytest.Item) -> int:
        if item.get_closest_marker("slow") or item.get_closest_marker("validation"):
            return 0
        return 1 if item.path.parent.name == "tui" else 2

    items.sort(key=rank)  # stable: each group keeps its order


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
def smoke_campaign(tmp_path_factory, worker_id) -> Path:
    """The shipped smoke sequence run on the unpaced simulated bench into a campaign file, once per
    test run: the first test worker to ask records it (the others wait on its lock), all read it
    (read it, do not change it)."""
    from bench.app.plan import plan_campaign
    from bench.app.run import run_campaign

    shared = tmp_path_factory.getbasetemp()
    if worker_id != "master":  # the test workers' folders share a parent
        shared = shared.parent
    path = shared / "smoke-campaign" / "smoke.h5"
    path.parent.mkdir(exist_ok=True)
    with open(shared / "smoke-campaign.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not path.exists():
            sequence = Path(__file__).resolve().parents[1] / "sequences" / "files" / "smoke.toml"
            recording = path.with_name("recording.h5")
            outcome = run_campaign(plan_campaign(sequence), recording)
            assert outcome.status == "complete", outcome.reason
            recording.rename(path)
    return path
