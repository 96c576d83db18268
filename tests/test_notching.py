"""Notching against a response limit on the simulated lab: a sweep and a grid through the tread
resonance, against a plate-force profile set below the response there, are lowered there, never
trip, and record the notch.

Physics (Model 2 at 2.5 bar, docs/physics.md): the plate force is the plate's and the tread's
inertia against the tyre spring, ``|k - (m_plate + m_T) w^2| z``, 740 N per mm at 40 Hz and rising
through the tread resonance (40.6 Hz); the profile allows 400 N (alarm) and 500 N (abort) from 38 to
44 Hz and 5 kN elsewhere, so a 1 mm drive passes it there by up to 2.5x. The notch lowers the drive
until the predicted force is 90 % of the alarm level; the sweep passes the band in 3 s, too fast to
build more than the steady state, and the noise of the load cell (2 N) is far below the margin.
"""

from __future__ import annotations

import numpy as np
import pytest

from bench.store import open_campaign
from sequences import DwellGrid, Hydraulics, Sequence, Sweep
from tests.campaign_lab import bench_config, lab_campaign
from tests.documented import assert_documented

PROFILE = """
[response_limits.plate]
role = "plate_force"
freqs_hz = [1.0, 36.0, 38.0, 44.0, 46.0, 100.0]
alarm = [5000.0, 5000.0, 400.0, 400.0, 5000.0, 5000.0]
abort = [6000.0, 6000.0, 500.0, 500.0, 6000.0, 6000.0]
alarm_action = "indicate"
abort_action = "interlock"
"""
ALARM_N = 400.0


def run_steps(tmp_path, *steps) -> tuple[list, list]:
    sequence = Sequence("notch", "", (Hydraulics("low"), Hydraulics("high"), *steps), "<test>")
    path = tmp_path / "c.h5"
    with lab_campaign(bench_config(tmp_path, PROFILE), sequence, path) as campaign:
        campaign.start()
        assert campaign.wait().status == "complete"
    with open_campaign(path) as f:
        (run,) = f.runs
        channels = {name: np.asarray(run.channels[name]) for name in ("z_base_m", "f_plate_n")}
        return list(run.points), [channels, list(run.events)]


@pytest.fixture(scope="module")
def notched_sweep(tmp_path_factory):
    sweep = Sweep(30.0, 50.0, 10.0, 1.0, taper_in_s=0.5, taper_out_s=0.5)
    return run_steps(tmp_path_factory.mktemp("sweep"), sweep)


def test_a_sweep_through_the_resonance_is_notched_there_and_records_the_notched_span(notched_sweep):
    (point,), (channels, events) = notched_sweep
    assert point.status == "done" and point.notched_by == "plate"
    assert 37.0 < point.notch_start_hz < 38.0 and 44.0 < point.notch_end_hz < 45.0
    assert 0.3 < point.notch_amplitude_mm < 0.45  # 0.9 x 400 N over 740-980 N per mm
    # the span and depth come from the plan's model of the plant, the same on every run
    notch = (
        f"notched from {point.notch_start_hz:.1f} to {point.notch_end_hz:.1f} Hz"
        f" (to {point.notch_amplitude_mm:.2f} mm)"
    )
    print(f"\n  the 1 mm sweep: {notch}")
    assert_documented("docs/engine.md", notch)
    # the amplitude reached within the notch is the notch's: the servo overshoots by 2-3 % at
    # 38-44 Hz, and half the peak-to-peak of the 2 um rms noise adds about 1.5 %
    assert point.achieved_amplitude_mm == pytest.approx(point.notch_amplitude_mm, rel=0.06)
    assert not [e for e in events if e.kind in ("limit", "interlock")]  # never tripped, no alarm
    # the plate force stayed below the alarm level through the notch, and the sweep ran at its
    # amplitude outside it
    z = np.asarray(channels["z_base_m"])
    force = np.asarray(channels["f_plate_n"])
    t = (np.arange(point.start_sample, point.end_sample) - point.start_sample) / 1000.0
    f_hz = 30.0 + 20.0 * t / 10.0
    inside = (f_hz > point.notch_start_hz) & (f_hz < point.notch_end_hz)
    assert np.max(np.abs(force[point.start_sample : point.end_sample][inside])) < ALARM_N
    before = (f_hz > 33.0) & (f_hz < 36.0)
    assert np.ptp(z[point.start_sample : point.end_sample][before]) / 2 == pytest.approx(1e-3, rel=0.03)


def test_a_grid_point_at_the_resonance_is_notched_and_the_others_are_not(tmp_path):
    grid = DwellGrid(
        (30.0, 40.0, 50.0), (1.0,), settle_min_s=0.1, measure_min_s=0.3, taper_in_s=0.2, taper_out_s=0.2
    )
    points, (_, events) = run_steps(tmp_path, grid)
    # (the short holds leave an amplitude update little time: a point may be repeated, notched alike)
    done = [p for p in points if p.status == "done"]
    assert [(p.freq_hz, p.notched_by) for p in done] == [(30.0, ""), (40.0, "plate"), (50.0, "")]
    assert all(p.notched_by == ("plate" if p.freq_hz == 40.0 else "") for p in points)
    notched = done[1]
    assert notched.requested_amplitude_mm == 1.0
    assert notched.amplitude_mm == notched.notch_amplitude_mm == pytest.approx(0.9 * ALARM_N / 740, rel=0.05)
    assert (notched.notch_start_hz, notched.notch_end_hz) == (40.0, 40.0)
    assert notched.achieved_amplitude_mm == pytest.approx(notched.amplitude_mm, rel=0.02)
    assert not [e for e in events if e.kind in ("limit", "interlock")]
