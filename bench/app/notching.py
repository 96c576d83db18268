"""Notching against the response limits: the drive of a dwell or a sweep lowered where a response
would pass a limit's notch level, predicted by the dry run's model of the bench.

The engine asks before each dwell and each sweep (:class:`bench.engine.contracts.Notching`), with
the conditions the sequence established (the tyre pressure read on the gauge, whether the wheel is
on). The model is the dry run's (:func:`bench.dry_run.bench_model`): the configured specimen, the
non-linear tyre linearised at each operating point. A dwell's amplitude is lowered so that every
limited response is at most its notch level (:data:`~sequences.response_limits.NOTCH_FRACTION` of
the alarm level); a sweep gets one notch spanning every frequency of its band where a response at
its amplitude would pass the notch level (one evaluation step wider on each side, where the true
crossing lies), at the deepest amplitude any of them needs. A sweep passes a resonance too quickly
to build its steady-state response: the steady state predicted is an upper bound.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from bench.config import BenchConfig
from bench.dry_run import bench_model, response_amplitudes
from bench.engine.contracts import Notch
from bench.models.setup import BenchSetup
from sequences import Sweep
from sequences.response_limits import ResponseLimit
from sequences.steps import AMPLITUDE_DECIMALS

#: Frequencies a sweep's band is evaluated at for its notch.
SWEEP_NOTCH_POINTS = 400


class ModelNotching:
    """:class:`~bench.engine.contracts.Notching` by the bench model of ``config`` against the
    limits of ``config.response_limits`` that notch."""

    def __init__(self, config: BenchConfig) -> None:
        self.config = config
        self.limits = tuple(limit for limit in config.response_limits if limit.notch)
        self._setups: dict[tuple[float, bool], BenchSetup] = {}

    def _setup(self, conditions: Mapping[str, Any], specimen: bool) -> BenchSetup:
        pressure = float(conditions.get("tyre_pressure_bar", self.config.specimen.tyre_pressure_bar))
        on = specimen and bool(conditions.get("wheel_fitted", conditions.get("car_on_posts", True)))
        key = (pressure if on else 0.0, on)
        if key not in self._setups:
            self._setups[key] = bench_model(self.config, pressure, specimen=on)
        return self._setups[key]

    def _ratio(
        self, setup: BenchSetup, freq_hz: float, amplitude_mm: float
    ) -> tuple[float, ResponseLimit | None]:
        """The smallest notch level over predicted response of the limits at one operating point
        (above 1: no limit would be passed), and the limit it belongs to."""
        responses = response_amplitudes(setup, freq_hz, amplitude_mm * 1e-3)
        worst, by = np.inf, None
        for limit in self.limits:
            response = responses[limit.role]
            if response > 0:
                ratio = float(limit.notch_level(freq_hz)) / response
                if ratio < worst:
                    worst, by = ratio, limit
        return worst, by

    def dwell(
        self, freq_hz: float, amplitude_mm: float, conditions: Mapping[str, Any], *, specimen: bool
    ) -> Notch | None:
        setup = self._setup(conditions, specimen)
        ratio, limit = self._ratio(setup, freq_hz, amplitude_mm)
        if limit is None or ratio >= 1:
            return None
        lowered = amplitude_mm * ratio
        # the non-linear tyre's response per mm changes with the amplitude: lower once more at the
        # lowered operating point, so that the prediction there is within the notch level
        again, _ = self._ratio(setup, freq_hz, lowered)
        lowered *= min(again, 1.0)
        scale = 10**AMPLITUDE_DECIMALS
        return Notch(limit.name, freq_hz, freq_hz, float(np.floor(lowered * scale) / scale))

    def sweep(self, step: Sweep, conditions: Mapping[str, Any]) -> Notch | None:
        if not self.limits:
            return None
        setup = self._setup(conditions, True)
        lo, hi = sorted((step.start_hz, step.end_hz))
        freqs = np.linspace(lo, hi, SWEEP_NOTCH_POINTS)
        ratios = [self._ratio(setup, float(f), step.amplitude_mm) for f in freqs]
        over = np.flatnonzero([ratio < 1 for ratio, _ in ratios])
        if over.size == 0:
            return None
        deepest = min(over, key=lambda i: ratios[i][0])
        first, last = max(over[0] - 1, 0), min(over[-1] + 1, freqs.size - 1)
        amplitude = step.amplitude_mm * ratios[deepest][0]
        scale = 10**AMPLITUDE_DECIMALS
        limit = ratios[deepest][1]
        assert limit is not None
        depth_mm = float(np.floor(amplitude * scale) / scale)
        return Notch(limit.name, float(freqs[first]), float(freqs[last]), depth_mm)
