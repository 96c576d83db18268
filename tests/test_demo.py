"""The README's demo: the paper's whole campaign run through the engine over Modbus TCP and a pty
into one campaign file, with results that match the simulator's truth (the tolerances are the
analysis tests': k 2 %, tread mass 3 %, eigenfrequency 1 %)."""

import json
import re

import pytest

from bench.cli.main import main
from bench.models.parameters import PAPER_TYRE_STIFFNESS_N_PER_M, Suspension
from bench.store import open_campaign
from simulators.world import DAMPER_SETTINGS_NS_PER_M

ROW = re.compile(
    r"^\s*(?P<p>\d\.\d) bar\s+(?P<a>\d) mm\s+(?P<k>[\d.]+)\s+(?P<mt>[\d.]+)\s+(?P<d>[\d.]+)\s+"
    r"(?P<peak>[\d.]+)\s+(?P<raw>[\d.]+) Hz\s+(?P<comp>[\d.]+) Hz$"
)


@pytest.mark.validation
def test_demo_campaign_recovers_the_simulated_tyres(capsys, tmp_path):
    (tmp_path / "campaign.h5").write_bytes(b"an earlier demo's file")  # replaced, and said so first
    assert main(["demo", "--seed", "2", "--out", str(tmp_path)]) == 0
    out, err = capsys.readouterr()
    assert err == ""  # the links' warnings, if any, go to campaign.h5.log, never to the terminal
    assert out.splitlines()[0] == (
        f"replacing {tmp_path / 'campaign.h5'} and {tmp_path / 'report'}/ of an earlier demo: their runs"
        " and analyses are not kept (--out DIR writes elsewhere)"
    )
    with open_campaign(tmp_path / "campaign.h5") as campaign:
        assert campaign.runs
    rows = [m.groupdict() for m in map(ROW.match, out.splitlines()) if m]
    assert len(rows) == 9  # 3 pressures x 3 amplitudes
    for row in rows:
        k_true = PAPER_TYRE_STIFFNESS_N_PER_M[float(row["p"])]
        assert float(row["k"]) * 1e3 == pytest.approx(k_true, rel=0.02), row
        assert float(row["mt"]) == pytest.approx(6.0, rel=0.03), row
        assert float(row["raw"]) < 15.0 < float(row["comp"]) == 70.0, row
    eigen = float(re.search(r"hammer: eigenfrequency ([\d.]+) Hz", out).group(1))
    assert eigen == pytest.approx(2200.0, rel=0.01)
    bands = re.search(
        r"raw [\d.]+-([\d.]+) Hz.*hub-acceleration compensated [\d.]+-([\d.]+) Hz.*"
        r"model-compensated [\d.]+-([\d.]+) Hz",
        out,
    )
    raw, accel, model = (float(x) for x in bands.groups())
    assert raw <= 6.0 and accel >= 12.0 and model >= 25.0
    # the report of the whole file, beside it: every figure as a PNG, embedded in the page
    page = tmp_path / "report" / "report.html"
    assert out.rstrip().splitlines()[-1] == f"report (9 figures): {page}"
    html = page.read_text()
    shaker = [f"shaker{kind}_{p}bar" for kind in ("", "_compensated") for p in ("1p5", "2p5", "3p5")]
    for name in ["hammer", *shaker, "four_post_ratios", "four_post_hub"]:
        assert (tmp_path / "report" / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
        assert f'<figure id="{name}"><img' in html, name
    # the report again: every figure as the post-run analysis drew it beside its run, none drawn
    assert main(["report", str(tmp_path / "campaign.h5"), "--out", str(tmp_path / "again")]) == 0
    assert "9 figures as the post-run analysis drew them, 0 drawn" in capsys.readouterr().out.splitlines()
    # no address outside the embedded figures (whose base64 may spell anything by chance)
    page_text = re.sub(r'src="data:image/png;base64,[A-Za-z0-9+/=]+"', "", html)
    assert "http" not in page_text and 'src="data:image/png;base64,' in html

    # the analysis the campaign stored, read back, and the whole file fitted again (any writer's
    # file without records takes this path) find what the campaign found
    assert main(["analyze", str(tmp_path / "campaign.h5"), "--json"]) == 0
    stored = json.loads(capsys.readouterr().out)
    assert stored["analysis_source"].startswith("as stored after each run by wfs-bench ")
    assert main(["analyze", str(tmp_path / "campaign.h5"), "--json", "--reanalyse"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["analysis_source"] == "analysed again: asked (--reanalyse)"
    four_post_run = next(r for r in doc["runs"] if r["analysis"] == "four_post")
    assert four_post_run["results_name"] == "four_post-reanalysis-1"
    assert next(r for r in stored["runs"] if r["analysis"] == "four_post")["results_name"] is None
    for key in ("hammer", "shaker", "four_post", "runs"):  # to the last digit, but the stored names
        if key == "runs":
            assert [{**r, "results_name": None} for r in doc[key]] == stored[key]
        else:
            assert doc[key] == stored[key], key
    assert doc["hammer"]["eigenfrequency_hz"] == pytest.approx(eigen, abs=0.05)
    assert [s["tyre_pressure_bar"] for s in doc["shaker"]] == [1.5, 2.5, 3.5]
    for shaker in doc["shaker"]:
        k_true = PAPER_TYRE_STIFFNESS_N_PER_M[shaker["tyre_pressure_bar"]]
        for amp in shaker["amplitudes"]:
            model2 = next(m for m in amp["models"] if m["model"] == 2)
            assert model2["values"]["stiffness_n_per_m"] == pytest.approx(k_true, rel=0.02)
    car = doc["four_post"]
    assert car["m_wheel_kg"] == pytest.approx(29.0, rel=0.01)  # the simulated wheel below the sensor
    assert car["valid_band_model_compensated"]["upper_hz"] == pytest.approx(model, abs=0.01)
    assert not car["quarter_car"]["undetermined"]
    truth = Suspension(damping_ns_per_m=DAMPER_SETTINGS_NS_PER_M["medium"])
    assert car["quarter_car"]["values"]["body_mass_kg"] == pytest.approx(truth.body_mass_kg, rel=0.02)
    with open_campaign(tmp_path / "campaign.h5") as campaign:
        run = campaign.run(four_post_run["run_id"])
        assert run.results("four_post")["m_wheel_kg"] == car["m_wheel_kg"]  # same data, same analysis
