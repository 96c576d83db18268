"""The index read by DuckDB, an independent reader of Parquet: the three questions of
docs/index.md answered by its own SQL, and its columns as documented."""

from __future__ import annotations

import re
from pathlib import Path

import duckdb
import pyarrow.compute as pc
import pytest

from bench.archive import columns as c
from bench.archive.store import read_index
from tests.archive.conftest import COPIES, SIMULATED

#: A long test module: in the validation tier (README.md, *Set up and run the tests*).
pytestmark = pytest.mark.validation

DOC = Path(__file__).resolve().parents[2] / "docs" / "index.md"


def _queries() -> list[str]:
    return re.findall(r"```sql\n(.*?)```", DOC.read_text(), re.DOTALL)


def _run(sql: str, index: Path) -> list[dict]:
    with duckdb.connect() as db:
        result = db.execute(sql.replace("RESULTS", str(index)))
        names = [d[0] for d in result.description]
        return [dict(zip(names, row, strict=True)) for row in result.fetchall()]


def test_docs_list_every_column_in_order():
    documented = re.findall(
        r"^\| `([a-z_0-9]+)` \| ", DOC.read_text().split("### Columns")[1].split("###")[0], re.MULTILINE
    )
    assert tuple(documented) == c.NAMES


def test_duckdb_reads_every_row_as_written(archive_index):
    ours = read_index(archive_index)
    rows = _run(
        'SELECT entry, path, "row", parameter, value, ci95, bench_id, run_started'
        " FROM read_parquet('RESULTS/*.parquet') ORDER BY path, \"row\"",
        archive_index,
    )
    assert len(rows) == ours.num_rows > 3 * 30
    for name in ("entry", "path", "row", "parameter", "value", "ci95", "bench_id"):
        assert [r[name] for r in rows] == ours[name].to_pylist(), name
    assert [r["run_started"] for r in rows] == ours["run_started"].to_pylist()
    with duckdb.connect() as db:
        kv = db.execute(f"SELECT key, value FROM parquet_kv_metadata('{archive_index}/*.parquet')").fetchall()
    assert (c.SCHEMA_KEY, c.INDEX_SCHEMA.encode()) in kv and (c.VERSION_KEY, b"1") in kv


def test_stiffness_of_every_tyre_against_pressure(archive_index):
    stiffness = _run(_queries()[0], archive_index)
    tyres = {SIMULATED.tyre_id, *(copy.tyre_id for copy in COPIES)}
    assert sorted({row["tyre"] for row in stiffness}) == sorted(tyres)
    assert len(stiffness) == 3  # one grid at one amplitude per file
    for row in stiffness:
        assert row["tyre_pressure_bar"] == SIMULATED.pressure_bar and row["amplitude_m"] == 2e-3
        # identification recovers the simulated tyre's stiffness to well under 1 % (README); the copies
        # hold the simulated campaign's measurements: its tyre
        assert row["stiffness_n_per_m"] == pytest.approx(SIMULATED.tyre_stiffness_n_per_m, rel=0.01)
        assert 0 < row["stiffness_ci95_n_per_m"] < 0.01 * row["stiffness_n_per_m"]


def test_sensor_eigenfrequency_since_its_calibration(archive_index):
    (drift,) = _run(_queries()[1], archive_index)
    serial_0001 = [SIMULATED, *(copy for copy in COPIES if copy.sensor_serial == "0001")]
    assert drift["hammer_tests"] == len(serial_0001) == 2
    assert drift["first_test"] < drift["last_test"]
    # the hammer test identifies the eigenfrequency to 0.1 % (README); both files hold one measurement
    assert drift["first_hz"] == pytest.approx(SIMULATED.eigenfrequency_hz, rel=1e-3)
    assert drift["last_hz"] == drift["first_hz"] and drift["drift_hz_per_day"] == pytest.approx(0.0, abs=1e-9)
    table = read_index(archive_index)
    hammer = table.filter(
        pc.and_(pc.equal(table["parameter"], "eigenfrequency_hz"), pc.equal(table["source"], "analysis"))
    )
    assert sorted(hammer["sensor_serial"].to_pylist()) == ["0001", "0001", "0002"]


def test_campaigns_of_bench_2_with_interlocks(archive_index, archive):
    (campaign,) = _run(_queries()[2], archive_index)
    (path,) = [str(p) for p, spec in archive.items() if spec.bench_id == "2"]
    assert campaign["path"] == path and campaign["runs_interlocked"] == 1
    assert campaign["runs"].startswith("archive-s004-dwell_grid: displacement limit")
