"""The tracked resonance dwell: the resonance found from a search (against a closed form), then
followed by phase on the simulated lab while the simulated world moves it (a tyre whose stiffness
drifts), until the drift takes it out of its band.

Physics: on the shaker (Model 2, 2.5 bar) ``F_WFS / F_contact`` peaks at the tread resonance,
``sqrt(k / m_T) / 2 pi`` = 40.6 Hz at 390 kN/m and 6 kg, raised a little by the non-linear tyre's
stiffening. The world lowers the stiffness by 0.5 % per second of bench time, so the resonance
falls by about 0.25 % per second (it goes with sqrt(k)): 0.1 Hz/s. The true resonance at each look
is the peak of the plant's own ratio at the stiffness of that moment (the tyre linearised at the
dwell's amplitude, as the simulator does). The drift began when the track's point started: on the
unpaced bench the engine reads the frames a few tenths of a second after the bench made them, so
the looks' times are known to about 0.5 s, 0.05 Hz of drift (0.12 %) at most, inside the 0.5 %
the track must hold.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.analysis.tracking import analyse_track
from bench.engine import events as ev
from bench.engine.tracking import find_resonance
from bench.models.setup import BenchSetup
from bench.store import open_campaign
from sequences import Hydraulics, Sequence, SequenceError, TrackedDwell, parse_sequence
from sequences.limits import BenchLimits
from simulators.world import TyreDrift, drifted, wfs_contact_peak_hz
from tests.campaign_lab import bench_config, lab_campaign

RATE_HZ = 1000.0
DRIFT_PER_S = -0.005
STEP = TrackedDwell(
    34.0, 48.0, 1.0, search_points=8, plate_mass_kg=12.0, track_s=20.0, freq_band_pct=3.0,
    taper_in_s=0.2, taper_out_s=0.2,
)  # fmt: skip


def test_the_resonance_of_a_single_mode_is_found_from_a_coarse_search():
    """``H = 1 / (1 - r^2 + 2 i zeta r)``, f_n 40 Hz, zeta 0.03, searched every 2 Hz: the peak
    (f_n sqrt(1 - 2 zeta^2)) within 0.1 %, zeta within 3 %, the phase held at the peak's."""
    f = np.arange(34.0, 48.1, 2.0)
    r = f / 40.0
    h = 1 / (1 - r**2 + 2j * 0.03 * r)
    found = find_resonance(f, h)
    assert found is not None
    assert found.freq_hz == pytest.approx(40.0 * math.sqrt(1 - 2 * 0.03**2), rel=1e-3)
    assert found.damping_ratio == pytest.approx(0.03, rel=0.03)
    assert math.degrees(found.phase_rad) == pytest.approx(-90.0, abs=3.0)
    assert found.slope_rad_per_hz < 0  # the phase falls through a resonance
    assert find_resonance(f, 1 / (1 + 1j * f)) is None  # no peak within the search


def true_resonance_hz(factor: float) -> float:
    """The peak of the plant's F_WFS / F_contact at stiffness ``factor`` x nominal, at 1 mm."""
    return wfs_contact_peak_hz(drifted(BenchSetup.paper_shaker(2.5), factor), 1e-3, (35.0, 45.0))


@pytest.fixture(scope="module")
def tracked(tmp_path_factory):
    folder = tmp_path_factory.mktemp("track")
    sequence = Sequence("track", "", (Hydraulics("low"), Hydraulics("high"), STEP), "<test>")
    armed = {}
    with lab_campaign(bench_config(folder), sequence, folder / "c.h5") as campaign:
        track_index = len(STEP.search_freqs_hz())
        samples = [0]

        def drift_at_the_track(event: ev.Event) -> None:
            if isinstance(event, ev.SamplesRecorded):
                samples[0] = event.first_sample + len(event)
            if isinstance(event, ev.PointStarted) and event.index == track_index and not armed:
                campaign.lab.world.drift_tyre(TyreDrift(DRIFT_PER_S))
                armed["sample"] = samples[0]

        campaign.engine.bus.subscribe(drift_at_the_track)
        campaign.start()
        assert campaign.wait().status == "complete"
    with open_campaign(folder / "c.h5") as f:
        (run,) = f.runs
        return list(run.points), run.track_record(), armed["sample"]


def test_the_track_follows_the_drifting_resonance_within_half_a_percent(tracked):
    points, record, armed = tracked
    assert [p.status for p in points] == ["done"] * len(points) and len(points) == 9
    assert record.time_s.size >= 8
    # each look's window (update_s long) ends at its time: its middle is where it looked
    middle_s = record.time_s - STEP.update_s / 2 - armed / RATE_HZ
    # the resonance moves smoothly with the stiffness: the peak at five stiffnesses, interpolated
    factors = np.linspace(1 + DRIFT_PER_S * middle_s.max(), 1 + DRIFT_PER_S * middle_s.min(), 5)
    peaks = [true_resonance_hz(factor) for factor in factors]
    truth = np.interp(1 + DRIFT_PER_S * middle_s, factors, peaks)
    errors = record.resonance_hz / truth - 1
    assert np.max(np.abs(errors)) < 0.005, errors
    assert record.resonance_hz[-1] < record.resonance_hz[0] - 0.8  # it did move: about 0.1 Hz/s
    assert np.all(np.abs(record.drive_hz - record.resonance_hz) < 0.01 * truth)  # the drive followed


def test_a_drift_out_of_the_band_stops_the_track_with_the_reason(tracked):
    points, record, _ = tracked
    track = points[-1]
    assert track.verdict == "stopped"
    assert track.note.startswith(f"the resonance at {record.resonance_hz[-1]:.3f} Hz left its band")
    assert abs(record.resonance_hz[-1] / track.freq_hz - 1) > STEP.freq_band_pct / 100
    assert (track.hold_end_sample - track.hold_start_sample) / RATE_HZ < STEP.track_s  # before its end
    result = analyse_track(record)
    assert result.drift_hz_per_s == pytest.approx(-0.1, rel=0.2)  # d f / f = 0.5 x d k / k
    assert result.summary_lines()[-1] == f"FLAG the track stopped: {track.note}"


def test_a_tracked_dwell_is_validated_naming_its_keys():
    text = """[sequence]
name = "t"
description = ""
[[steps]]
type = "tracked_dwell"
search_start_hz = 48.0
search_end_hz = 34.0
amplitude_mm = 1.0
search_points = 2
update_s = 30.0
track_s = 10.0
"""
    with pytest.raises(SequenceError) as refused:
        parse_sequence(text, "t.toml", BenchLimits())
    said = str(refused.value)
    assert "steps[0].search_end_hz: 34 Hz must lie above search_start_hz 48 Hz" in said
    assert "steps[0].search_points" in said and "steps[0].update_s" in said


def test_a_drift_is_seeded_and_deterministic_in_bench_time():
    """The wander is a Brownian path on a fixed 0.1 s grid: asked at any times in any order, one
    seed gives one path; another seed another; without wander the drift is the straight rate."""
    drift = TyreDrift(-0.001, wander_per_sqrt_s=0.002, seed=7)
    times = [0.0, 0.05, 3.33, 12.7, 40.0]
    forward = [drift.factor(t, []) for t in times]
    shared: list[float] = []
    backward = [drift.factor(t, shared) for t in reversed(times)][::-1]
    assert forward == pytest.approx(backward, abs=1e-15)
    assert forward[0] == 1.0
    other = [TyreDrift(-0.001, wander_per_sqrt_s=0.002, seed=8).factor(t, []) for t in times]
    assert other[1:] != pytest.approx(forward[1:], abs=1e-9)
    assert TyreDrift(-0.001).factor(40.0, []) == pytest.approx(0.96)
