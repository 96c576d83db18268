"""Adaptive stepped sine on the simulated lab (controller over Modbus TCP, WFS over a pty).

Truth is the plant's closed-form response (``bench.models``) of the tyre on the bench; the tyres
are linear here so that the truth is exact. Each grid starts coarse (8 frequencies 5-70 Hz at 1 mm,
10 Hz apart around any tread resonance) and must find the peak of ``|F_WFS / F_contact|`` within
2 % in height and 0.5 Hz in frequency with its measured points alone, read back from the file.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bench.analysis.interpolation import grid_error
from bench.analysis.plate_mass import PlateMass, shaker_frfs
from bench.analysis.records import WHEEL_CHANNELS, fit_dwell_record
from bench.analysis.runs import analyse_shaker_campaign
from bench.engine import events as ev
from bench.models.benches import TyreModel
from bench.models.parameters import Tyre, WfsSensor, paper_tyre
from bench.models.setup import BenchKind, BenchSetup
from bench.report.text import summary_lines
from bench.store import open_campaign
from sequences import AdaptiveDwell, DwellGrid, FreeRun, Hydraulics, Prompt, Sequence
from tests.campaign_lab import bench_config, lab_campaign

COARSE_HZ = (5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0)
PLATE_KG = 12.0  # the simulated rig's plate (m_comp)
PLAN = AdaptiveDwell(plate_mass_kg=PLATE_KG, min_hold_cycles=2, max_added_points=10)
#: Tread mass 6 kg on a spring that puts its resonance at 60 Hz (a stiff, high-pressure tyre).
TYRE_60_HZ = Tyre(stiffness_n_per_m=6.0 * (2 * math.pi * 60.0) ** 2)


def adaptive_grid(freqs_hz: tuple[float, ...] = COARSE_HZ) -> DwellGrid:
    return DwellGrid(freqs_hz=freqs_hz, amplitudes_mm=(1.0,), taper_in_s=0.2, taper_out_s=0.2, adaptive=PLAN)


def true_ratio(tyre: Tyre, freq_hz: np.ndarray) -> np.ndarray:
    response = BenchSetup(BenchKind.SHAKER, TyreModel.WHEEL_TREAD, tyre).network().frequency_response(freq_hz)
    return response["f_wfs"] / response["f_contact"]


def run_adaptive(tmp_path: Path, tyre: Tyre) -> tuple[Path, list[ev.Event]]:
    config = bench_config(tmp_path, "[specimen]\nnonlinear = false\n")
    sequence = Sequence("adaptive", "", (Hydraulics("low"), Hydraulics("high"), adaptive_grid()), "<test>")
    path = tmp_path / "campaign.h5"
    with lab_campaign(config, sequence, path) as campaign:
        campaign.lab.bench.mount(BenchSetup(BenchKind.SHAKER, TyreModel.WHEEL_TREAD, tyre))
        campaign.start()
        assert campaign.wait().status == "complete"
    return path, campaign.events


@pytest.mark.parametrize(
    "tyre",
    [
        pytest.param(paper_tyre(1.5), marks=pytest.mark.validation),
        pytest.param(paper_tyre(3.5), marks=pytest.mark.validation),
        TYRE_60_HZ,
    ],
    ids=["paper 1.5 bar", "paper 3.5 bar", "peak 60 Hz"],
)
def test_adaptive_grid_finds_the_peak_of_wfs_over_contact_force(tmp_path: Path, tyre: Tyre) -> None:
    path, events = run_adaptive(tmp_path, tyre)
    with open_campaign(path) as campaign:
        run = campaign.runs[0]
        rows = [p for p in run.points if p.status == "done"]
        logged = [(e.fields["freq_hz"], e.text) for e in run.events if e.kind == "refined"]
        fits = [fit_dwell_record(r, WHEEL_CHANNELS) for r in run.dwell_records()]
    frf = shaker_frfs(fits, PlateMass(PLATE_KG, 0.0, 0.0, 0)).wfs_per_contact
    band = np.linspace(COARSE_HZ[0], COARSE_HZ[-1], 6501)
    error = grid_error(frf.freq_hz, frf.value, band, true_ratio(tyre, band))
    assert abs(error.peak_height) <= 0.02, error
    assert abs(error.peak_hz) <= 0.5, error

    # every added point was announced with its reason, and its row keeps that reason
    refined = [added for e in events if isinstance(e, ev.GridRefined) for added in e.added]
    added_rows = sorted((p for p in rows if p.index >= len(COARSE_HZ)), key=lambda p: p.index)
    assert refined and len(refined) <= PLAN.max_added_points
    assert [(p.freq_hz, p.added_reason) for p in added_rows] == refined
    assert [f for f, _ in logged] == [f for f, _ in refined]  # the file's run events keep them too
    assert all(reason in text for (_, reason), (_, text) in zip(refined, logged, strict=True))
    assert all(reason.startswith(("model peak", "steep")) for _, reason in refined)
    assert all(p.added_reason == "" for p in rows if p.index < len(COARSE_HZ))
    # every point ended by its verdicts, within the plan's lengths, and well before the longest
    holds_s = [(p.hold_end_sample - p.hold_start_sample) / run.sample_rate_hz for p in rows]
    assert np.median(holds_s) < 0.2 * PLAN.max_hold_s
    for p in rows:
        hold_s = (p.hold_end_sample - p.hold_start_sample) / run.sample_rate_hz
        assert p.verdict in ("target", "max length"), p
        assert PLAN.min_hold_at_s(p.freq_hz) - 0.01 <= hold_s <= PLAN.max_hold_s + 0.01
        assert p.hold_start_sample <= p.measure_start_sample < p.hold_end_sample
        assert p.settled and math.isfinite(p.settle_s)
        if p.verdict == "target":
            assert p.magnitude_uncertainty_pct <= PLAN.magnitude_target_pct
            assert p.phase_uncertainty_deg <= PLAN.phase_target_deg


def test_adaptive_runs_are_ordinary_dwells_for_the_analysis(tmp_path: Path) -> None:
    """A free run with fixed timing then an adaptive grid, analysed from the file as any campaign:
    m_comp, Model 1-3 identification and the peak come out of the unchanged analysis."""
    config = bench_config(tmp_path, "[specimen]\nnonlinear = false\ntyre_pressure_bar = 1.5\n")
    free_run = FreeRun(
        DwellGrid(freqs_hz=(5.0, 20.0, 40.0, 70.0), amplitudes_mm=(1.0,), taper_in_s=0.2, taper_out_s=0.2)
    )
    steps = (
        Hydraulics("low"),
        Prompt("remove_wheel", "Remove the wheel", action="remove_wheel"),
        Hydraulics("high"),
        free_run,
        Hydraulics("low"),
        Prompt("fit_wheel", "Fit the wheel", action="fit_wheel"),
        Hydraulics("high"),
        adaptive_grid(),
    )
    path = tmp_path / "campaign.h5"
    with lab_campaign(config, Sequence("adaptive", "", steps, "<test>"), path) as campaign:
        campaign.start()
        assert campaign.wait().status == "complete"
    with open_campaign(path) as f:
        free, grid = f.runs
        result = analyse_shaker_campaign(
            grid.dwell_records(), free.dwell_records(), wheel_mass_kg=29.0, sensor=WfsSensor()
        )
    assert result.free_run.plate.mass_kg == pytest.approx(PLATE_KG, rel=0.02)
    amplitude = result.nearest(1e-3)
    # the analysis flags a settled dwell with a 1 % false-alarm rate: one flag in the grid is chance
    assert len(amplitude.unsettled) <= 1, amplitude.unsettled
    best = amplitude.identification.best_fit
    assert best.tyre.stiffness_n_per_m == pytest.approx(250e3, rel=0.03)
    assert any("peak" in line for line in summary_lines(result))
