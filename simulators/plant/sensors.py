"""How the bench's sensors distort the true signals: filters, quantisation, noise, offsets.

All effects are on by default and each can be switched off; all noise comes from one seeded
generator so a simulated run is reproducible sample for sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import firwin

from bench.models.linear_system import LinearSystem

#: WFS Fz range and resolution (paper, Table 1): +-24 kN, 1/4000.
WFS_RANGE_N = 24_000.0
WFS_RESOLUTION_STEPS = 4000


@dataclass(frozen=True)
class SensorRealism:
    """Which sensor effects the simulated bench applies, and how strong they are.

    - ``decimation``: the WFS converts at the internal rate (10 kHz) and a linear-phase FIR
      anti-alias filter decimates to the output rate; all channels share the acquisition, so they
      share the filter and stay mutually aligned. Off: plain subsampling.
    - ``quantisation``: WFS forces quantised in steps of ``WFS_RANGE_N / WFS_RESOLUTION_STEPS``
      at the internal rate (the converter's resolution).
    - ``noise``: white noise on every measured channel. The WFS noise is the converter's, at the
      internal rate before quantisation (it dithers the quantiser); the other levels are rms at
      the output rate, as a data sheet states them for the acquisition bandwidth.
    - ``accelerometer_dynamics``: the mass-production hub accelerometer is a second-order
      Butterworth low-pass at ``accelerometer_bandwidth_hz`` with a constant offset.
    """

    seed: int | None = 0
    decimation: bool = True
    quantisation: bool = True
    noise: bool = True
    accelerometer_dynamics: bool = True
    wfs_noise_n: float = 3.0
    load_cell_noise_n: float = 2.0
    displacement_noise_m: float = 2e-6
    accelerometer_noise_m_s2: float = 0.05
    accelerometer_offset_m_s2: float = 0.15
    accelerometer_bandwidth_hz: float = 600.0

    @classmethod
    def ideal(cls) -> SensorRealism:
        """Every effect off: the sensors read the plant's signals exactly (subsampled)."""
        return cls(decimation=False, quantisation=False, noise=False, accelerometer_dynamics=False)

    @property
    def wfs_step_n(self) -> float:
        return WFS_RANGE_N / WFS_RESOLUTION_STEPS

    @property
    def accelerometer_lag_s(self) -> float:
        """The hub accelerometer's lag well below its bandwidth: the group delay of its second-order
        Butterworth at low frequency, ``sqrt 2 / (2 pi f_c)`` (0.375 ms at 600 Hz); 0 without its
        dynamics."""
        if not self.accelerometer_dynamics:
            return 0.0
        return math.sqrt(2) / (2 * math.pi * self.accelerometer_bandwidth_hz)


def accelerometer_system(bandwidth_hz: float) -> LinearSystem:
    """Second-order Butterworth low-pass from the true hub acceleration to the sensor reading."""
    w = 2 * math.pi * bandwidth_hz
    zeta = math.sqrt(0.5)
    return LinearSystem(
        A=np.array([[0.0, 1.0], [-(w**2), -2 * zeta * w]]),
        B=np.array([[0.0], [w**2]]),
        C=np.array([[1.0, 0.0]]),
        D=np.zeros((1, 1)),
        inputs=("a_hub",),
        outputs=("a_hub_sensor",),
        states=("accel_x", "accel_v"),
    )


class Decimator:
    """Streaming linear-phase FIR decimation of several channels by an integer factor.

    The filter has ``2 * latency_samples * factor + 1`` taps, so its group delay is exactly
    ``latency_samples`` output samples: output k of a stream describes the input instant of output
    sample ``k - latency_samples``. The history of each channel is kept between blocks.
    """

    def __init__(self, factor: int, n_channels: int, latency_samples: int = 8, filtered: bool = True):
        if factor < 1:
            raise ValueError("decimation factor must be >= 1")
        self.factor = factor
        self.filtered = filtered
        self.latency_samples = latency_samples if filtered and factor > 1 else 0
        n_taps = 2 * self.latency_samples * factor + 1
        if n_taps > 1:
            # Pass band flat to well above 100 Hz at 1 kHz output; the transition ends at the output
            # Nyquist frequency, so nothing aliases below 0.5 * output rate * (1 - 0.1).
            self.taps = firwin(n_taps, 0.8 / factor, window=("kaiser", 7.0))
        else:
            self.taps = np.ones(1)
        self._reversed_taps = np.ascontiguousarray(self.taps[::-1])
        self._history = np.zeros((n_channels, n_taps - 1))

    def with_factor(self, factor: int) -> Decimator:
        """A decimator by ``factor`` for the same channels that continues this one's input history.

        The new filter's history is filled with the most recent input samples (the oldest one
        repeated if this history is shorter), so a rate change does not restart the filter from zero.
        An unfiltered decimator keeps no history: after it the new filter starts from zero.
        """
        new = Decimator(factor, self._history.shape[0], filtered=self.filtered)
        if self._history.shape[1] == 0 or new._history.shape[1] == 0:
            return new
        keep = min(self._history.shape[1], new._history.shape[1])
        new._history[:, -keep:] = self._history[:, -keep:]
        new._history[:, :-keep] = self._history[:, -keep : -keep + 1]
        return new

    def __call__(self, block: np.ndarray) -> np.ndarray:
        """Decimate ``block`` (channels x samples, samples a multiple of ``factor``)."""
        n = block.shape[1]
        if n % self.factor:
            raise ValueError(f"block of {n} samples is not a multiple of {self.factor}")
        if self.taps.size == 1:
            return block[:, :: self.factor].copy()
        data = np.concatenate([self._history, block], axis=1)
        self._history = data[:, n:]
        # Output k is the window of len(taps) samples starting at data[factor * k] (ending at block
        # sample factor * k), dotted with the reversed taps: a strided view BLAS reads in place.
        n_out, step = n // self.factor, data.strides[1]
        out = np.empty((data.shape[0], n_out))
        for channel, row in enumerate(data):
            windows = np.lib.stride_tricks.as_strided(
                row, shape=(n_out, self.taps.size), strides=(self.factor * step, step), writeable=False
            )
            np.dot(windows, self._reversed_taps, out=out[channel])
        return out
