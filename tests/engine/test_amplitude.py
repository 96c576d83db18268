"""Amplitude control: the measured amplitude against a closed form, and the correction rule with
its bounds (the step, the command's margin over its target, a window that lost its frames)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.engine.amplitude import AmplitudeControl, FramesPresent, amplitude_mm
from bench.numerics.sine_fit import fit_latest_cycles


@pytest.mark.parametrize("freq_hz", [0.5, 7.3, 40.0, 70.0])
def test_achieved_amplitude_is_the_fundamental_over_whole_cycles(freq_hz):
    """A 2 mm sine with an offset, a 10 % third harmonic and seeded noise, on a window that is not
    a whole number of cycles: the fundamental's amplitude to the noise's standard error."""
    rate_hz = 1000.0
    t = np.arange(round(4.37 * rate_hz)) / rate_hz
    rng = np.random.default_rng(3)
    z = 1e-3 + 2e-3 * np.sin(2 * np.pi * freq_hz * t + 0.7) + 2e-4 * np.sin(6 * np.pi * freq_hz * t)
    z += 1e-6 * rng.standard_normal(t.size)
    fit = fit_latest_cycles(z, np.arange(t.size), rate_hz, freq_hz)
    assert amplitude_mm(fit) == pytest.approx(2.0, abs=1e-4)
    assert fit.frames_missing == 0


def test_a_window_shorter_than_a_cycle_measures_nothing():
    assert fit_latest_cycles(np.ones(100), np.arange(100), 1000.0, 5.0) is None
    assert np.isnan(amplitude_mm(None))


def test_the_command_is_scaled_by_target_over_achieved_within_bounds():
    control = AmplitudeControl(tolerance=0.02, max_corrections=2, max_command_mm=5.0, max_step_factor=1.5)
    assert control.decide(2.0, 2.0, 2.03, 0).keep
    repeat = control.decide(2.0, 2.0, 1.8, 0)
    assert not repeat.keep and repeat.corrected_mm == pytest.approx(2.0 / 0.9)
    assert control.decide(2.0, 2.0, 0.5, 0).keep  # 1.5x would pass the 25 % margin over the target
    spent = control.decide(2.0, 2.2, 1.8, 2)
    assert spent.keep and "after 2 corrections" in spent.note
    beyond = control.decide(4.0, 4.5, 3.5, 0)
    assert beyond.keep and "exceeds the 5 mm limit" in beyond.note
    dead = control.decide(2.0, 2.0, 0.0, 0)
    assert dead.keep and "no displacement" in dead.note


def test_one_step_is_bounded_by_its_factor():
    """A reading of a third of the target scales the command by the step's bound alone."""
    control = AmplitudeControl(max_step_factor=1.15, command_margin=0.5)
    step = control.decide(1.0, 1.0, 0.33, 0)
    assert not step.keep and step.corrected_mm == pytest.approx(1.15)
    down = control.decide(1.0, 1.0, 3.0, 0)
    assert down.corrected_mm == pytest.approx(1 / 1.15)


def test_a_command_beyond_its_margin_over_the_target_ends_the_point_flagged():
    control = AmplitudeControl(max_step_factor=1.15, command_margin=0.25)
    assert control.command_cap_mm(1.0) == pytest.approx(1.25)
    flagged = control.decide(1.0, 1.2, 0.9, 0)  # 1.2 x 1.11 = 1.33 mm for a 1 mm target
    assert flagged.keep and flagged.corrected_mm is None
    assert "bench model's 1 mm for the target by more than 25 %" in flagged.note


def test_a_window_that_lost_its_frames_is_measured_again_at_the_same_command():
    control = AmplitudeControl(max_corrections=2)
    again = control.decide(1.0, 1.1, 0.4, 0, refusal="missed 350 of its 1000 frames")
    assert not again.keep and again.corrected_mm == 1.1  # never scaled on what the bench did not see
    assert "measured again at the same command" in again.note
    spent = control.decide(1.0, 1.1, 0.4, 2, refusal="missed 350 of its 1000 frames")
    assert spent.keep and spent.corrected_mm is None and "amplitude not verified" in spent.note


def test_frames_present_refuses_a_window_that_lost_more_than_allowed():
    """A 10 Hz window of 4 cycles (400 sample times): 20 frames lost is 5 % (allowed), 21 is not;
    a window with fewer than one cycle of frames present is never decided on."""
    rule = FramesPresent(max_missing_fraction=0.05, min_cycles=1.0)
    fs, f = 1000.0, 10.0
    k = np.arange(400)
    z = np.sin(2 * np.pi * f * k / fs)
    allowed = np.r_[k[:100], k[120:]]
    assert rule.refusal(fit_latest_cycles(z[allowed], allowed, fs, f, start=0, end=400)) == ""
    lost = np.r_[k[:100], k[121:]]
    refusal = rule.refusal(fit_latest_cycles(z[lost], lost, fs, f, start=0, end=400))
    assert "missed 21 of its 400 frames" in refusal
    short = FramesPresent(max_missing_fraction=0.9, min_cycles=1.0)
    assert "cycles of frames" in short.refusal(fit_latest_cycles(z[:60], k[:60], fs, f, start=0, end=400))


def test_an_excursion_beyond_the_target_is_named():
    control = AmplitudeControl(excursion_tolerance=0.1)
    assert control.excursion(1.0, 1.09) == ""
    assert "exceeds the 1 mm target by 71 %" in control.excursion(1.0, 1.71)
    assert control.excursion(1.0, float("nan")) == ""
