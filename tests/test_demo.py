"""The README's demo command runs and reports measurements that agree with the model."""

import re

from bench.cli import main


def test_demo_measures_what_the_model_predicts(capsys):
    assert main(["demo", "--seed", "4"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.strip().endswith("°")]
    assert len(rows) == 6
    for row in rows:
        measured, model = (float(x) for x in re.findall(r"\s(\d+\.\d\d)(?=\s)", row)[:2])
        assert abs(measured / model - 1) < 0.03, row  # sensor noise and quantisation only
