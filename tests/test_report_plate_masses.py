"""The report's plate-mass table lists every free run analysed, also in a file whose shaker grids
never completed (a run stopped during the first grid): recorded through ``wfsbench run`` on the
simulated bench, reported by ``wfsbench report`` and the free run's own result read back."""

from __future__ import annotations

import re

from bench.store import open_campaign
from tests.commands import wfsbench
from tests.test_campaign_cli import SMOKE


def _free_run_only(smoke_text: str) -> str:
    """The smoke sequence up to its free run (the wheel removed first): the file holds a plate mass
    and no shaker identification, as a campaign stopped before its first grid completed."""
    end = smoke_text.index('[[steps]]\ntype = "hydraulics"\nlevel = "low"', smoke_text.index("free_run"))
    return smoke_text[:end]


def test_the_plate_mass_of_a_file_without_a_shaker_identification_is_in_the_report(tmp_path):
    sequence = tmp_path / "free_run.toml"
    sequence.write_text(_free_run_only(SMOKE.read_text()))
    campaign_file = tmp_path / "free_run.h5"
    run = wfsbench("run", str(sequence), "--out", str(campaign_file))
    assert run.returncode == 0, run.stderr
    out = tmp_path / "report"
    report = wfsbench("report", str(campaign_file), "--out", str(out))
    assert report.returncode == 0, report.stderr
    html = (out / "report.html").read_text()
    assert "No shaker identification in this file." in html
    with open_campaign(campaign_file) as campaign:
        (free_run,) = [r for r in campaign.runs if r.kind == "free_run"]
        m_comp_kg = free_run.results("plate_mass")["m_comp_kg"]
    table = re.search(r"Plate masses m_comp</h2>(.*?)<h2>", html).group(1)
    assert table != "<p>none</p>"
    row = re.search(r"<tr><td>shaker plate</td><td>([^<]+)</td><td[^>]*>([^<]+)</td>", table)
    assert row is not None, table
    assert row.group(1) == free_run.run_id
    assert abs(float(row.group(2)) - m_comp_kg) <= 1e-4 * m_comp_kg  # printed to 6 digits
