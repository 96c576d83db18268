"""``wfsbench check`` says before anything runs which analyses the sequence's runs will not allow:
a lab's own small test (a pressure prompt and three dwells at 2 mm, no free run) is told that m_comp
will be the configured plate mass, nominal, and that three frequencies give no tyre fit; a grid
without a pressure prompt is told it gets no analysis; the smoke sequence only that its shaker sweep
is recorded, not analysed."""

from __future__ import annotations

from sequences import shipped_file
from tests.sequence_texts import sequence_text
from tests.test_check_cli import check

PRESSURE = """[[steps]]
type = "prompt"
id = "pressure"
text = "Set the tyre pressure to 2.5 bar"
answer = "number"
unit = "bar"
minimum = 0.5
maximum = 4.5
action = "set_tyre_pressure"
target = 2.5

"""
FREE_RUN = """[[steps]]
type = "free_run"
freqs_hz = [10, 30, 60]
amplitudes_mm = [2]

"""
GRID = """[[steps]]
type = "dwell_grid"
freqs_hz = [10, 30, 50]
amplitudes_mm = [2]

"""


def _limits(out: str) -> list[str]:
    return [line.removeprefix("  - ") for line in out.splitlines() if line.startswith("  - ")]


def test_a_small_test_without_a_free_run_is_told_what_its_analysis_will_lack(tmp_path):
    sequence = tmp_path / "small.toml"
    sequence.write_text(sequence_text("small", PRESSURE + GRID))
    result = check(str(sequence))
    assert result.returncode == 0, result.stderr
    assert "ANALYSIS LIMITED (2): what the runs will not let the analysis give:" in result.stdout
    assert _limits(result.stdout) == [
        "steps[3] dwell_grid: no free run before it: m_comp will be the configured plate mass 12 kg"
        " (masses.plate_kg), nominal, not measured, unless the campaign file it runs into holds one already",
        "steps[3] at 2.5 bar, 2 mm: 3 frequencies: no tyre fit (at least 4 needed): the measured ratios"
        " only (grids at this pressure already in the campaign file count too)",
    ]


def test_a_grid_without_a_pressure_prompt_is_told_it_gets_no_analysis(tmp_path):
    sequence = tmp_path / "no_pressure.toml"
    sequence.write_text(sequence_text("no_pressure", GRID))
    result = check(str(sequence))
    assert result.returncode == 0, result.stderr
    assert _limits(result.stdout) == [
        "steps[2] dwell_grid: no analysis: no set_tyre_pressure prompt before it (the tyre fit needs the"
        " tyre's pressure)"
    ]


def test_the_shipped_shaker_campaign_is_analysed_in_full_and_the_smoke_sweep_is_not():
    paper = check(str(shipped_file("paper_shaker.toml")))
    assert "analysis: every run can be analysed in full" in paper.stdout.splitlines()
    smoke = check(str(shipped_file("smoke.toml")))
    assert _limits(smoke.stdout) == [
        "steps[10] sweep: recorded, not analysed (the sweep analysis is the four-post bench's)"
    ]


def test_a_grid_on_a_bench_without_a_hub_accelerometer_is_told_what_its_analysis_takes(tmp_path):
    sequence = tmp_path / "grid.toml"
    sequence.write_text(
        sequence_text("grid", PRESSURE + FREE_RUN + GRID.replace("[10, 30, 50]", "[10, 20, 30, 50]"))
    )
    bench = tmp_path / "lab.toml"
    bench.write_text('[aux.aux2]\nname = "aux2_v"\nunit = "V"\nrole = "spare"\n')
    result = check(str(sequence), "--bench", str(bench))
    assert result.returncode == 0, result.stderr
    assert _limits(result.stdout) == [
        "steps[4] dwell_grid: the bench records no hub acceleration: the clamped hub is taken as not moving"
        " (the compensated ratio without its hub term); whether it moved is not checked"
    ]
