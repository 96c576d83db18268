"""Frequency response functions, ratios of phasors with their uncertainty, and the valid band.

Conventions: a channel oscillating at circular frequency w is ``x(t) = Re(X exp(j w t))``; ``X`` is
its complex amplitude (phasor). An FRF value is the ratio of two phasors. ``sigma`` is the standard
uncertainty of a complex value, ``sqrt(E |error|^2)``; each of its real and imaginary parts has the
standard deviation ``sigma / sqrt(2)`` when the error is circular.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.analysis.validation import AnalysisInputError

#: Default valid-band tolerances: | |H| - 1 | <= 10 % and |phase H| <= 10 degrees.
AMPLITUDE_TOLERANCE = 0.10
PHASE_TOLERANCE_DEG = 10.0
#: A point fails a tolerance only when it misses it by more than this many standard uncertainties;
#: a closer miss is too uncertain to judge (like a point whose uncertainty is above half the tolerance).
FAIL_SIGMAS = 2.0


@dataclass(frozen=True)
class Frf:
    """A frequency response ``output / input`` sampled at ``freq_hz``.

    ``value`` is complex (output units per input unit), ``sigma`` its standard uncertainty (same
    units, ``sqrt(E|error|^2)``), ``reliable`` marks the points the data supports (a dwell that
    settled, a sweep bin with excitation energy and coherence).
    """

    freq_hz: np.ndarray
    value: np.ndarray
    sigma: np.ndarray
    reliable: np.ndarray
    output: str
    input: str

    def __post_init__(self) -> None:
        n = np.asarray(self.freq_hz).size
        for name in ("value", "sigma", "reliable"):
            if np.asarray(getattr(self, name)).shape != (n,):
                raise AnalysisInputError(f"Frf.{name} must have shape ({n},)")

    @property
    def magnitude(self) -> np.ndarray:
        return np.abs(self.value)

    @property
    def phase_deg(self) -> np.ndarray:
        return np.degrees(np.angle(self.value))


def phasor_ratio(
    num: np.ndarray | complex, num_sigma: np.ndarray | float, den: np.ndarray | complex, den_sigma
) -> tuple[np.ndarray, np.ndarray]:
    """``num / den`` and its standard uncertainty by first-order propagation (independent errors).

    ``d(N/D) = (dN - H dD) / D``, so ``sigma_H^2 = (sigma_N^2 + |H|^2 sigma_D^2) / |D|^2``.
    """
    num, den = np.asarray(num, dtype=complex), np.asarray(den, dtype=complex)
    if np.any(den == 0):
        raise AnalysisInputError("ratio with a zero denominator phasor")
    h = num / den
    sigma = np.sqrt(np.asarray(num_sigma) ** 2 + np.abs(h) ** 2 * np.asarray(den_sigma) ** 2) / np.abs(den)
    return h, sigma


@dataclass(frozen=True)
class ValidBand:
    """The band in which a measured force ratio (measured / true contact force) can be trusted.

    ``lowest_hz`` is the lowest reliable point (where the data begins to say anything: with a
    ``sigma``, a point is reliable only if its standard uncertainty is at most half the tolerances,
    so that noise alone can neither pass nor fail it); ``starts_at`` says why the band starts there:
    ``"start of data"`` or how many unreliable points lie below it.
    ``upper_hz`` is the highest frequency up to which every point from ``lowest_hz`` on keeps
    ``| |H| - 1 | <= amplitude_tolerance`` and ``|phase H| <= phase_tolerance_deg``; it is the last
    point that passes (no interpolation: conservative). ``n_points``: how many points pass from
    ``lowest_hz`` on. One point is no band: with fewer than two the band is not ``determined`` and
    ``upper_hz`` is 0.0. ``limited_by`` says what ended the band: ``"amplitude"``, ``"phase"``,
    ``"unreliable point"`` or ``"end of data"`` (the band may extend beyond the data).
    ``skipped_hz``: unreliable points inside the band that did not end it (runs of at most
    ``max_gap_points`` between passing points: one noisy sweep bin is not the end of a band).
    """

    upper_hz: float
    lowest_hz: float
    limited_by: str
    amplitude_tolerance: float
    phase_tolerance_deg: float
    n_points: int
    starts_at: str = "start of data"
    skipped_hz: tuple[float, ...] = ()

    @property
    def determined(self) -> bool:
        """At least two points pass: the band has a width."""
        return self.n_points >= 2


def valid_band(
    freq_hz: np.ndarray,
    ratio: np.ndarray,
    reliable: np.ndarray | None = None,
    *,
    amplitude_tolerance: float = AMPLITUDE_TOLERANCE,
    phase_tolerance_deg: float = PHASE_TOLERANCE_DEG,
    sigma: np.ndarray | None = None,
    max_gap_points: int = 0,
) -> ValidBand:
    """Valid band of a force ratio sampled at ascending ``freq_hz`` (see :class:`ValidBand`)."""
    f = np.asarray(freq_hz, dtype=float)
    h = np.asarray(ratio, dtype=complex)
    ok_points = np.ones(f.size, bool) if reliable is None else np.asarray(reliable, bool)
    if f.size == 0 or f.shape != h.shape or f.shape != ok_points.shape:
        raise AnalysisInputError("valid band needs equal-length, non-empty frequency and ratio arrays")
    given = ok_points
    amp_excess = np.abs(np.abs(h) - 1.0) - amplitude_tolerance
    phase_excess = np.abs(np.degrees(np.angle(h))) - phase_tolerance_deg
    amp_bad, phase_bad = ~(amp_excess <= 0), ~(phase_excess <= 0)
    if sigma is not None:
        relative = np.asarray(sigma, dtype=float) / np.abs(h)
        determined = (relative <= 0.5 * amplitude_tolerance) & (
            np.degrees(relative) <= 0.5 * phase_tolerance_deg
        )
        # a point that misses a tolerance by less than FAIL_SIGMAS of its uncertainty is no verdict
        unsure = (amp_bad & (amp_excess < FAIL_SIGMAS * relative)) | (
            phase_bad & (phase_excess < FAIL_SIGMAS * np.degrees(relative))
        )
        ok_points = ok_points & determined & ~unsure
    if np.any(np.diff(f) <= 0):
        raise AnalysisInputError("valid band needs strictly ascending frequencies")
    if not ok_points.any():
        raise AnalysisInputError("valid band needs at least one reliable point")
    start = int(np.argmax(ok_points))  # the band begins at the lowest reliable point
    if start == 0:
        starts_at = "start of data"
    elif given[start - 1]:  # reliable data whose uncertainty is too large to judge it
        starts_at = f"the {start} points below too uncertain to judge"
    else:
        starts_at = f"{start} unreliable points below"
    f, h, ok_points = f[start:], h[start:], ok_points[start:]
    amp_bad, phase_bad = amp_bad[start:], phase_bad[start:]
    end, limited_by, gap, skipped = f.size, "end of data", 0, []
    for i in range(f.size):
        if not ok_points[i]:
            gap += 1
            if gap > max_gap_points:
                end, limited_by = i - gap + 1, "unreliable point"
                break
            continue
        if amp_bad[i] or phase_bad[i]:
            end, limited_by = i - gap, "amplitude" if amp_bad[i] else "phase"
            break
        skipped += [float(x) for x in f[i - gap : i]]
        gap = 0
    else:
        end -= gap  # trailing unreliable points are not part of the band
    n_pass = end - len(skipped)
    upper = float(f[end - 1]) if n_pass >= 2 else 0.0
    return ValidBand(
        upper,
        float(f[0]),
        limited_by,
        amplitude_tolerance,
        phase_tolerance_deg,
        n_pass,
        starts_at,
        tuple(skipped),
    )
