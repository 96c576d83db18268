"""The simulated controller measures the achieved amplitude on its own clock: the WFS output rate
and whether the WFS streams play no part. No wall clock: the bench is advanced sample by sample."""

from __future__ import annotations

import math

import pytest

from bench.models.setup import BenchSetup
from drivers.register_map import Command, ControllerState, WaveformCode
from simulators.bench_sim import SimulatedBench
from simulators.plant import PlantSimulator, SensorRealism

FREQ_HZ, AMPLITUDE_MM = 40.0, 0.2


def _dwell_bench(output_rate_hz: float) -> SimulatedBench:
    plant = PlantSimulator(BenchSetup.paper_shaker(), SensorRealism(seed=3))
    bench = SimulatedBench(plant, clock=None)  # the watchdog on the controller's sample clock; no WFS
    bench.set_output_rate(output_rate_hz)
    ctrl = bench.controller
    for command in (Command.HYDRAULICS_LOW, Command.HYDRAULICS_HIGH):
        assert ctrl.command(command) is None
    setpoint = {
        "waveform": WaveformCode.SINE_DWELL, "amplitude_mm": AMPLITUDE_MM, "frequency_hz": FREQ_HZ,
        "taper_in_s": 0.2, "taper_out_s": 0.2, "watchdog_ms": 0,
    }  # fmt: skip
    assert ctrl.write_setpoints(setpoint) is None
    assert ctrl.command(Command.START) is None
    return bench


def _run_s(bench: SimulatedBench, seconds: float) -> None:
    for _ in range(round(seconds * bench.output_rate_hz)):
        bench.advance(1)


@pytest.mark.parametrize("output_rate_hz", [100.0, 1000.0])
def test_achieved_amplitude_does_not_depend_on_the_wfs_output_rate(output_rate_hz):
    bench = _dwell_bench(output_rate_hz)
    _run_s(bench, 0.6)  # taper in (0.2 s) plus 0.4 s of hold: at least two cycles
    assert bench.controller.state == ControllerState.RUNNING
    # the servo-hydraulic actuator's gain at 40 Hz with the wheel as its load (the plant's exact
    # operating point); a 40 Hz sine sampled at 1 kHz may miss its peak by up to
    # 1 - cos(pi * 40 / 1000) = 0.8 %
    expected_mm = AMPLITUDE_MM * abs(bench.plant.base_gain(FREQ_HZ, AMPLITUDE_MM / 1e3))
    peak_miss = 1 - math.cos(math.pi * FREQ_HZ / 1000)
    measured = bench.controller.readback.achieved_amplitude_mm
    assert expected_mm * (1 - peak_miss) - 1e-6 <= measured <= expected_mm + 1e-6


def test_achieved_amplitude_is_the_same_at_every_output_rate():
    readings = []
    for rate_hz in (100.0, 250.0, 1000.0):
        bench = _dwell_bench(rate_hz)
        _run_s(bench, 0.6)
        readings.append(bench.controller.readback.achieved_amplitude_mm)
    assert readings[0] == pytest.approx(readings[1], rel=1e-9)
    assert readings[0] == pytest.approx(readings[2], rel=1e-9)
