"""Input checks shared by the estimators: a bad record raises a clear error, never a silent number."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np


class AnalysisInputError(ValueError):
    """The data cannot support the requested analysis (NaNs, too short, mismatched, no energy)."""


def as_signal(name: str, values: np.ndarray | list[float], min_samples: int = 1) -> np.ndarray:
    """A finite 1-D float array of at least ``min_samples`` samples."""
    x = np.asarray(values, dtype=float)
    if x.ndim != 1:
        raise AnalysisInputError(f"channel {name!r} must be 1-D, got shape {x.shape}")
    if x.size < min_samples:
        raise AnalysisInputError(f"channel {name!r} has {x.size} samples, at least {min_samples} needed")
    bad = ~np.isfinite(x)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise AnalysisInputError(
            f"channel {name!r} has {int(bad.sum())} non-finite samples (first at index {first})"
        )
    return x


def as_signals(channels: Mapping[str, np.ndarray], min_samples: int = 1) -> dict[str, np.ndarray]:
    """Checked channels of one record: all finite, 1-D and of equal length."""
    if not channels:
        raise AnalysisInputError("no channels given")
    out = {name: as_signal(name, values, min_samples) for name, values in channels.items()}
    lengths = {name: x.size for name, x in out.items()}
    if len(set(lengths.values())) != 1:
        raise AnalysisInputError(f"channels have different lengths: {lengths}")
    return out


def as_sample_rate(fs_hz: float) -> float:
    fs = float(fs_hz)
    if not (np.isfinite(fs) and fs > 0):
        raise AnalysisInputError(f"sample rate must be positive and finite, got {fs_hz}")
    return fs
