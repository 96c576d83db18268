"""Amplitude control: the measured amplitude against a closed form, and the correction rule."""

from __future__ import annotations

import numpy as np
import pytest

from bench.engine.amplitude import AmplitudeControl, achieved_amplitude_mm


@pytest.mark.parametrize("freq_hz", [0.5, 7.3, 40.0, 70.0])
def test_achieved_amplitude_is_the_fundamental_over_whole_cycles(freq_hz):
    """A 2 mm sine with an offset, a 10 % third harmonic and seeded noise, on a window that is not
    a whole number of cycles: the fundamental's amplitude to the noise's standard error."""
    rate_hz = 1000.0
    t = np.arange(round(4.37 * rate_hz)) / rate_hz
    rng = np.random.default_rng(3)
    z = 1e-3 + 2e-3 * np.sin(2 * np.pi * freq_hz * t + 0.7) + 2e-4 * np.sin(6 * np.pi * freq_hz * t)
    z += 1e-6 * rng.standard_normal(t.size)
    assert achieved_amplitude_mm(z, rate_hz, freq_hz) == pytest.approx(2.0, abs=1e-4)


def test_a_window_shorter_than_a_cycle_measures_nothing():
    assert np.isnan(achieved_amplitude_mm(np.ones(100), 1000.0, 5.0))


def test_the_command_is_scaled_by_target_over_achieved_within_bounds():
    control = AmplitudeControl(tolerance=0.02, max_corrections=2, max_command_mm=5.0)
    assert control.decide(2.0, 2.0, 2.03, 0).keep
    repeat = control.decide(2.0, 2.0, 1.8, 0)
    assert not repeat.keep and repeat.corrected_mm == pytest.approx(2.0 / 0.9)
    assert control.decide(2.0, 2.0, 0.5, 0).corrected_mm == pytest.approx(3.0)  # at most 1.5x per step
    spent = control.decide(2.0, 2.2, 1.8, 2)
    assert spent.keep and "after 2 corrections" in spent.note
    beyond = control.decide(4.0, 4.5, 3.5, 0)
    assert beyond.keep and "exceeds the 5 mm limit" in beyond.note
    dead = control.decide(2.0, 2.0, 0.0, 0)
    assert dead.keep and "no displacement" in dead.note
