"""Road profiles of ISO 8608 classes as a displacement drive: a road at a speed, seeded.

ISO 8608 describes a road's vertical profile by its displacement power spectral density over the
spatial frequency ``n`` (cycles/m), ``Gd(n) = Gd(n0) (n / n0)^-w`` with ``n0 = 0.1`` cycles/m and
waviness ``w = 2``; a class is named by ``Gd(n0)``, the geometric mean of its range (class A 16e-6
m^3 for a very good road, each class four times the one before). Driven at speed ``v`` (m/s), a
spatial frequency ``n`` is heard at the temporal frequency ``f = v n`` and the temporal one-sided
density is ``G(f) = Gd(f / v) / v``.

The profile is a sample of the stationary Gaussian process with that density, band-limited to
``[n_low, n_high]`` (the standard's band 0.011-2.83 cycles/m by default: wavelengths from 0.35 m,
about a contact patch's length, to 90 m): each DFT bin of the record gets a complex Gaussian
coefficient whose expected power is the density's (``E|X_k|^2 = G(n_k) N / (2 dx)`` for a record
of ``N`` samples spaced ``dx``), the rest zero, and the inverse DFT gives the profile. So a
periodogram of it scatters about the closed form as a chi-square with two degrees of freedom per
bin, which is what a test of it can rely on. The record is periodic over its length.

What comes out is a :class:`RoadDrive`: displacement samples at a rate, which the simulated
quarter car takes as its post's (the contact's) motion and which a four-post bench can play as
its posts' displacement drive. Pure numpy: no device, no plant.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np

#: ISO 8608's reference spatial frequency (cycles/m) and waviness (the exponent of its density).
REFERENCE_CYCLES_PER_M = 0.1
WAVINESS = 2.0
#: The spatial band ISO 8608 classifies a road over (cycles/m): wavelengths 0.35-90 m.
ISO_BAND_CYCLES_PER_M = (0.011, 2.83)


class RoadClass(StrEnum):
    """ISO 8608 road classes, A (very good) to H (very poor)."""

    A = "A"
    B = "B"
    C = "C"
    D = "D"
    E = "E"
    F = "F"
    G = "G"
    H = "H"

    @property
    def reference_psd_m3(self) -> float:
        """``Gd(n0)`` in m^3 (m^2 per cycle/m): the geometric mean of the class's range, 16e-6 m^3
        for class A and four times more per class."""
        return 16e-6 * 4.0 ** list(RoadClass).index(self)


def displacement_psd_m3(road_class: RoadClass, n_cycles_per_m: np.ndarray) -> np.ndarray:
    """The class's one-sided displacement density ``Gd(n)`` (m^3) at spatial frequencies ``n > 0``."""
    n = np.asarray(n_cycles_per_m, dtype=float)
    if np.any(n <= 0):
        raise ValueError("ISO 8608's density is defined for spatial frequencies above 0")
    return RoadClass(road_class).reference_psd_m3 * (n / REFERENCE_CYCLES_PER_M) ** -WAVINESS


@dataclass(frozen=True)
class RoadDrive:
    """A displacement drive: ``displacement_m`` sampled at ``sample_rate_hz`` from t = 0 (the road
    under a wheel, or a post's command). ``road_class``, ``speed_m_s``, ``band_cycles_per_m`` and
    ``seed`` say how it was made."""

    displacement_m: np.ndarray
    sample_rate_hz: float
    road_class: RoadClass
    speed_m_s: float
    band_cycles_per_m: tuple[float, float]
    seed: int

    @property
    def duration_s(self) -> float:
        return self.displacement_m.size / self.sample_rate_hz

    @property
    def band_hz(self) -> tuple[float, float]:
        """The temporal band the drive excites at its speed, ``v n_low`` to ``v n_high``."""
        low, high = self.band_cycles_per_m
        return self.speed_m_s * low, self.speed_m_s * high

    def temporal_psd_m2_per_hz(self, freq_hz: np.ndarray) -> np.ndarray:
        """The closed-form one-sided density of the drive over time, ``Gd(f / v) / v`` (m^2/Hz),
        inside its band and 0 outside."""
        f = np.asarray(freq_hz, dtype=float)
        low, high = self.band_hz
        inside = (f >= low) & (f <= high)
        psd = np.zeros(f.shape)
        psd[inside] = displacement_psd_m3(self.road_class, f[inside] / self.speed_m_s) / self.speed_m_s
        return psd


def road_drive(
    road_class: RoadClass | str,
    *,
    speed_km_h: float,
    duration_s: float,
    sample_rate_hz: float,
    seed: int,
    band_cycles_per_m: tuple[float, float] = ISO_BAND_CYCLES_PER_M,
) -> RoadDrive:
    """A road of ``road_class`` driven at ``speed_km_h`` for ``duration_s``, sampled at
    ``sample_rate_hz`` (see the module docstring); the same seed gives the same road.

    ValueError when the band does not fit the record: its top above the Nyquist frequency at that
    speed, or its bottom below the record's frequency resolution (a record shorter than the longest
    wavelength asked for)."""
    road_class = RoadClass(road_class)
    if not (speed_km_h > 0 and duration_s > 0 and sample_rate_hz > 0):
        raise ValueError(
            f"speed {speed_km_h} km/h, duration {duration_s} s and sample rate {sample_rate_hz} Hz"
            " must be positive"
        )
    low, high = band_cycles_per_m
    if not 0 < low < high:
        raise ValueError(f"band {low}-{high} cycles/m: need 0 < low < high")
    speed_m_s = speed_km_h / 3.6
    n_samples = round(duration_s * sample_rate_hz)
    dx_m = speed_m_s / sample_rate_hz
    if high * speed_m_s >= sample_rate_hz / 2:
        raise ValueError(
            f"the band's top, {high:g} cycles/m at {speed_km_h:g} km/h, is {high * speed_m_s:.4g} Hz:"
            f" at or above half the sample rate ({sample_rate_hz / 2:g} Hz)"
        )
    resolution = 1 / (n_samples * dx_m)
    if low < resolution:
        raise ValueError(
            f"the band's bottom, {low:g} cycles/m, is below the record's resolution {resolution:.4g}"
            f" cycles/m ({n_samples * dx_m:.4g} m of road): drive longer or start the band higher"
        )
    n = np.fft.rfftfreq(n_samples, dx_m)
    inside = (n >= low) & (n <= high)
    rng = np.random.default_rng(seed)
    coefficients = np.zeros(n.size, dtype=complex)
    scale = np.sqrt(displacement_psd_m3(road_class, n[inside]) * n_samples / (4 * dx_m))
    coefficients[inside] = scale * (rng.standard_normal(scale.size) + 1j * rng.standard_normal(scale.size))
    displacement = np.fft.irfft(coefficients, n_samples)
    return RoadDrive(displacement, float(sample_rate_hz), road_class, speed_m_s, (low, high), seed)
