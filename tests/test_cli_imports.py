"""The offline commands start light: ``check``, ``analyze``, ``report``, ``import-csv``, ``--help`` and
``--version`` import neither the device clients (pymodbus), nor the simulators, nor the run engine,
nor matplotlib (``report`` draws, so it alone may import matplotlib).

Each command runs in a fresh interpreter, as a user runs it, which then lists the modules it loaded;
nothing here is timed (``benchmarks/cli_startup.py`` measures the start-up).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from bench.cli.exit_codes import ExitCode
from bench.cli.main import main
from sequences import shipped_file
from tests.test_csv_import import GOOD_CSV, MAPPING

ROOT = Path(__file__).resolve().parents[1]

#: What an offline command must not load: the Modbus client library, the simulated devices, the run
#: engine, and the plotting library (``report`` excepted).
HEAVY = ("pymodbus", "simulators", "bench.engine.engine", "matplotlib")
DRAWS = ("matplotlib",)
FOUR_POST_CONFIG = "configs/simulated_four_post.toml"

#: Runs ``bench.cli.main`` with the arguments given (JSON) and writes the exit code and the heavy
#: modules then loaded (JSON) to the file named last.
PROBE = """
import json, sys
args, result, heavy = json.loads(sys.argv[1]), sys.argv[2], json.loads(sys.argv[3])
from bench.cli.main import main
try:
    code = main(args)
except SystemExit as exit:
    code = exit.code
with open(result, "w") as f:
    json.dump({"code": code, "loaded": [m for m in heavy if m in sys.modules]}, f)
"""


def run_offline(tmp_path: Path, *args: str) -> tuple[int, list[str]]:
    """Run ``wfsbench ARGS`` in a fresh interpreter: its exit code and which of :data:`HEAVY` it loaded."""
    result = tmp_path / "probe.json"
    done = subprocess.run(
        [sys.executable, "-c", PROBE, json.dumps(args), str(result), json.dumps(HEAVY)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    probe = json.loads(result.read_text())
    return probe["code"], probe["loaded"]


@pytest.fixture(scope="module")
def imported_campaign(tmp_path_factory) -> Path:
    """A campaign file with one complete free run, written by ``import-csv`` (no engine, no device)."""
    folder = tmp_path_factory.mktemp("imported")
    (folder / "mapping.toml").write_text(MAPPING)
    (folder / "free.csv").write_text(GOOD_CSV)
    out = folder / "campaign.h5"
    assert main(["import-csv", str(folder / "mapping.toml"), "--out", str(out)]) == ExitCode.OK
    return out


@pytest.mark.parametrize(
    ("args", "code"),
    [
        (["--help"], 0),
        (["--version"], 0),
        (["run", "--help"], 0),
        (["check", str(shipped_file("smoke.toml"))], 0),
        (["check", str(shipped_file("paper_shaker_adaptive.toml"))], 0),
        (["check", str(shipped_file("paper_four_post.toml")), "--bench", FOUR_POST_CONFIG], 0),
        (["check", "missing.toml"], ExitCode.INVALID),
        (["analyze", "missing.h5"], ExitCode.INVALID),
        (["analyze", "--json", "missing.h5"], ExitCode.INVALID),
        (["import-csv", "missing.toml", "--out", "never.h5"], ExitCode.INVALID),
        (["show", "missing.h5"], ExitCode.INVALID),
    ],
    ids=lambda value: " ".join(Path(a).name for a in value) if isinstance(value, list) else None,
)
def test_an_offline_command_loads_no_device_client_simulator_engine_or_plotting(tmp_path, args, code):
    assert run_offline(tmp_path, *args) == (code, [])


def test_import_csv_of_a_garbage_mapping_loads_none_of_them(tmp_path):
    mapping = tmp_path / "mapping.toml"
    mapping.write_text('[source]\nname = "lab_b"\nnot toml at all [[\n')
    out = tmp_path / "x.h5"
    assert run_offline(tmp_path, "import-csv", str(mapping), "--out", str(out)) == (ExitCode.INVALID, [])
    assert not out.exists()


def test_import_csv_of_good_files_loads_none_of_them(tmp_path):
    (tmp_path / "mapping.toml").write_text(MAPPING)
    (tmp_path / "free.csv").write_text(GOOD_CSV)
    out = tmp_path / "imported.h5"
    assert run_offline(tmp_path, "import-csv", str(tmp_path / "mapping.toml"), "--out", str(out)) == (0, [])
    assert out.exists()


@pytest.mark.parametrize("json_out", [False, True], ids=["text", "json"])
def test_analyze_of_a_campaign_file_loads_none_of_them(tmp_path, imported_campaign, json_out):
    args = ["analyze", *(["--json"] if json_out else []), str(imported_campaign)]
    # the imported free run is three samples long: its analysis fails, so the exit code is partial's
    assert run_offline(tmp_path, *args) == (ExitCode.INCOMPLETE, [])


def test_report_loads_only_the_plotting_library_of_them(tmp_path, imported_campaign):
    code, loaded = run_offline(tmp_path, "report", str(imported_campaign), "--out", str(tmp_path / "report"))
    assert code == 0
    assert [m for m in loaded if m not in DRAWS] == []
    assert (tmp_path / "report" / "report.html").exists()


def test_report_of_a_missing_file_loads_no_device_client_simulator_or_engine(tmp_path):
    code, loaded = run_offline(tmp_path, "report", "missing.h5", "--out", str(tmp_path / "report"))
    assert code == ExitCode.INVALID
    assert [m for m in loaded if m not in DRAWS] == []


def test_the_probe_sees_what_a_command_that_opens_the_bench_loads(tmp_path):
    """The check above is not vacuous: ``run`` loads the clients and the simulators (here it stops
    at the refused sequence file, after the imports the run needs)."""
    code, loaded = run_offline(tmp_path, "run", "missing.toml", "--out", str(tmp_path / "x.h5"))
    assert code == ExitCode.INVALID
    assert {"pymodbus", "simulators", "bench.engine.engine"} <= set(loaded)
