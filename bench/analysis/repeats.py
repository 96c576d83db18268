"""Repeated dwells: a point measured again at a frequency and amplitude the grid holds already (a
lab's check measurement, or a grid run twice) is a repeat, not an error.

The repeats of a point are combined into one dwell fit, and how far they spread is reported: the
bench's repeatability, which a lab wants to know, against the spread their noise alone explains.

Combination: each repeat ``k`` is brought to the first one's displacement, each channel's phasor
``A_k`` multiplied by ``Z_1 / Z_k`` (for a linear bench every channel scales with the displacement,
so the repeats then measure the same phasors; a repeat that reached a slightly different amplitude,
or started at another phase, costs nothing), and the phasors are averaged with inverse-variance
weights. The displacement's own noise moves into the other channels that way; the combined
displacement keeps it as its uncertainty (``sigma_Z / sqrt(n)`` for equal repeats), which the FRFs
propagate as for any dwell. Repeats that did not settle are left out of the combination unless none
settled (then the combined dwell is not settled either).

Spread: per channel, the repeats' responses to the displacement ``H_k = A_k / Z_k`` about their
weighted mean, as a relative rms, and the chi^2 of those deviations against their standard
uncertainties (``2 |dH|^2 / sigma^2`` per repeat, ``2 (n - 1)`` degrees of freedom). A spread far
outside the noise (:func:`~bench.analysis.lsq.chi2_far_outside_noise`) means the specimen or the
bench changed between the repeats (the tyre's pressure or temperature, a loosened clamp): flagged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from bench.analysis.dwell import NOISE_ESTIMATE_DOF, ChannelFit, DwellFit
from bench.analysis.lsq import chi2_far_outside_noise


@dataclass(frozen=True)
class RepeatSpread:
    """The repeats of one dwell (``label``, at ``freq_hz``): how many were combined (``n``), and per
    response channel (the displacement's ratio ``channel / displacement``) the repeats' relative rms
    spread about their mean (``spread``), the spread their noise alone gives (``noise``, the same
    measure of the standard uncertainties) and whether the spread is far outside it
    (``outside_noise``: the specimen or the bench changed between the repeats)."""

    label: str
    freq_hz: float
    n: int
    spread: dict[str, float]
    noise: dict[str, float]
    outside_noise: bool

    @property
    def largest(self) -> tuple[str, float]:
        """The channel whose repeats spread most, and its relative rms spread."""
        name = max(self.spread, key=self.spread.__getitem__)
        return name, self.spread[name]


def _weighted_mean(values: np.ndarray, sigma: np.ndarray) -> tuple[complex, float]:
    weights = 1.0 / sigma**2
    return complex(np.sum(weights * values) / np.sum(weights)), float(1.0 / np.sqrt(np.sum(weights)))


def _spread(fits: Sequence[DwellFit], channel: str, displacement: str) -> tuple[float, float, float, int]:
    """The relative rms spread of ``channel / displacement`` over the repeats, the rms of its
    relative uncertainties, its chi^2 and degrees of freedom."""
    points = [f.ratio(channel, displacement) for f in fits]
    h = np.array([value for value, _ in points], dtype=complex)
    s = np.array([sigma for _, sigma in points], dtype=float)
    mean, _ = _weighted_mean(h, s)
    scale = abs(mean) or 1.0
    chi2 = float(np.sum(2 * np.abs(h - mean) ** 2 / s**2))
    return (
        float(np.sqrt(np.mean(np.abs(h - mean) ** 2)) / scale),
        float(np.sqrt(np.mean(s**2)) / scale),
        chi2,
        2 * (len(fits) - 1),
    )


def spread_of_repeats(
    label: str, fits: Sequence[DwellFit], displacement: str, responses: Sequence[str]
) -> RepeatSpread:
    """How far the repeats ``fits`` of one dwell spread in each of the ``responses`` channels (those
    that carry the excitation: a clamped hub's acceleration is noise, its spread says nothing; see
    the module docstring)."""
    spread, noise, outside = {}, {}, False
    for channel in responses:
        spread[channel], noise[channel], chi2, dof = _spread(fits, channel, displacement)
        outside = outside or chi2_far_outside_noise(chi2, dof, NOISE_ESTIMATE_DOF)
    return RepeatSpread(label, fits[0].freq_hz, len(fits), spread, noise, outside)


def combine_repeats(fits: Sequence[DwellFit], displacement: str) -> DwellFit:
    """One dwell fit from the repeats ``fits`` of a dwell (see the module docstring)."""
    settled = [f for f in fits if f.settled]
    use = settled or list(fits)
    z_ref = use[0].channels[displacement].amplitude
    scale = np.array([z_ref / f.channels[displacement].amplitude for f in use])
    channels = {}
    for name, first in use[0].channels.items():
        parts = [f.channels[name] for f in use]
        sigma = np.array([p.amplitude_sigma for p in parts]) * np.abs(scale)
        if name == displacement:
            amplitude, sigma_mean = complex(z_ref), float(1.0 / np.sqrt(np.sum(1.0 / sigma**2)))
        else:
            amplitude, sigma_mean = _weighted_mean(np.array([p.amplitude for p in parts]) * scale, sigma)
        channels[name] = ChannelFit(
            amplitude=amplitude,
            amplitude_sigma=sigma_mean,
            harmonics=first.harmonics,
            offset=float(np.mean([p.offset for p in parts])),
            residual_rms=float(np.sqrt(np.mean([p.residual_rms**2 for p in parts]))),
            thd=float(np.mean([p.thd for p in parts])),
            drift=float(max(p.drift for p in parts)),
            settled=all(p.settled for p in parts),
        )
    left_out = len(fits) - len(use)
    note = f"combined from {len(use)} repeats" + (f" ({left_out} not settled, left out)" if left_out else "")
    return replace(
        use[0],
        n_cycles=sum(f.n_cycles for f in use),
        channels=channels,
        settled=bool(settled),
        notes=(*use[0].notes, note),
    )
