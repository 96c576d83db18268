"""The raised-cosine taper every excitation starts and stops with, as a function of time: the
controller's generator (:mod:`simulators.plant.excitation`) plays it and the dry run
(:mod:`bench.dry_run`) predicts a drive with it."""

from __future__ import annotations

import numpy as np


def taper_envelope(t_s: np.ndarray, total_s: float, taper_in_s: float, taper_out_s: float) -> np.ndarray:
    """Raised-cosine ramps at both ends of ``[0, total_s]``, 1 in between, 0 outside.

    A raised cosine has zero slope at its ends, so neither velocity nor acceleration jumps when an
    excitation starts or stops: every start and stop tapers.
    """
    t = np.asarray(t_s, dtype=float)
    env = ((t >= 0) & (t <= total_s)).astype(float)
    if taper_in_s > 0:
        ramp = np.flatnonzero((t >= 0) & (t < taper_in_s))
        env[ramp] = 0.5 - 0.5 * np.cos(np.pi * t[ramp] / taper_in_s)
    if taper_out_s > 0:
        ramp = np.flatnonzero((t <= total_s) & (t > total_s - taper_out_s))
        env[ramp] = np.minimum(env[ramp], 0.5 - 0.5 * np.cos(np.pi * (total_s - t[ramp]) / taper_out_s))
    return env
