"""``wfsbench trends``: the archive's figures and page from an index."""

from __future__ import annotations

import re

from bench.archive.trends import _dataset, eigenfrequencies, interlocks, one_copy_each, tyre_points
from bench.cli.main import main
from tests.archive.conftest import COPIES, SIMULATED


def test_trends_of_an_index(archive, archive_index, tmp_path, capsys):
    data = _dataset(archive_index)
    points = tyre_points(data)
    assert sorted(p.tyre for p in points) == sorted([SIMULATED.tyre_id, *(c.tyre_id for c in COPIES)])
    assert {p.pressure_bar for p in points} == {SIMULATED.pressure_bar}
    assert [e.serial for e in eigenfrequencies(data)] == ["0001", "0001", "0002"]
    month = SIMULATED.created.strftime("%Y-%m")
    # every file holds the simulated campaign's interlocked grid; the runs began within the month
    expected = {(spec.bench_id, spec.created.strftime("%Y-%m")) for spec in archive.values()}
    assert set(interlocks(data)) == expected and (SIMULATED.bench_id, month) in expected

    out = tmp_path / "trends"
    assert main(["trends", str(archive_index), "--out", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    names = ("tyre_stiffness", "sensor_eigenfrequency", "interlocks")
    assert printed == [*(f"figure {out / name}.png" for name in names), f"trends {out / 'trends.html'}"]
    page = (out / "trends.html").read_text()
    assert len(re.findall(r'<img alt="[^"]+" src="data:image/png;base64,', page)) == 3
    assert 'files indexed</td><td class="num">3<' in page and "http" not in page
    for name in names:
        assert (out / f"{name}.png").read_bytes().startswith(b"\x89PNG")


def test_trends_refuses_an_empty_index(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert main(["trends", str(tmp_path / "empty"), "--out", str(tmp_path / "out")]) == 3
    assert "an empty index" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_campaign_copied_under_another_path_counts_once():
    """The index lists every path (a copy is a file of its own); the trends count each content once,
    under its first path."""
    rows = [
        {"path": "/b/copy.h5", "sha256": "aa", "value": 1.0},
        {"path": "/a/campaign.h5", "sha256": "aa", "value": 1.0},
        {"path": "/a/other.h5", "sha256": "bb", "value": 2.0},
    ]
    assert one_copy_each(rows) == rows[1:]
