"""Soft limits: every setpoint is checked before it can become register values."""

import math

import pytest

from drivers.errors import LimitError
from drivers.register_map import WaveformCode
from drivers.setpoints import DwellSetpoint, SweepSetpoint
from sequences.limits import BenchLimits

LIMITS = BenchLimits(stroke_mm=5.0, max_freq_hz=70.0, displacement_interlock_mm=8.0)


def test_valid_dwell_gives_register_values():
    values = DwellSetpoint(freq_hz=10.0, amplitude_mm=2.0, dwell_s=5.0).registers(LIMITS)
    assert values["waveform"] == WaveformCode.SINE_DWELL
    assert values["amplitude_mm"] == 2.0
    assert values["frequency_hz"] == 10.0


def test_log_sweep_code():
    values = SweepSetpoint(1.0, 30.0, 20.0, 1.0, spacing="log").registers(LIMITS)
    assert values["waveform"] == WaveformCode.LOG_SWEEP


@pytest.mark.parametrize(
    ("setpoint", "words"),
    [
        (DwellSetpoint(freq_hz=10.0, amplitude_mm=6.0), "amplitude_mm=6.0"),
        (DwellSetpoint(freq_hz=71.0, amplitude_mm=1.0), "freq_hz=71.0"),
        (DwellSetpoint(freq_hz=0.0, amplitude_mm=1.0), "freq_hz=0.0"),
        (DwellSetpoint(freq_hz=10.0, amplitude_mm=-1.0), "amplitude_mm=-1.0"),
        (DwellSetpoint(freq_hz=math.nan, amplitude_mm=1.0), "not a finite number"),
        (DwellSetpoint(freq_hz=10.0, amplitude_mm=1.0, taper_out_s=0.0), "taper_out_s"),
        (DwellSetpoint(freq_hz=10.0, amplitude_mm=1.0, mean_mm=25.0), "mean_mm"),
        (SweepSetpoint(1.0, 80.0, 20.0, 1.0), "end_hz=80.0"),
        (SweepSetpoint(1.0, 30.0, 1.5, 1.0), "do not fit"),
        (SweepSetpoint(1.0, 30.0, 20.0, 1.0, spacing="cubic"), "spacing"),
        (SweepSetpoint(1.0, 30.0, -2.0, 1.0), "duration_s"),
    ],
)
def test_out_of_limit_setpoints_are_refused(setpoint, words):
    with pytest.raises(LimitError, match=words):
        setpoint.registers(LIMITS)
