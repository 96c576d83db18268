"""A tracked resonance dwell's drift: the resonance frequency, the ratio and the damping as they
moved during the track (a tyre warming up), from the looks the engine recorded.

Each look (a run event of kind ``track``, docs/hdf5.md) holds the resonance estimated at the end of
one window (run sample), the drive frequency, the ratio's magnitude and phase, and the damping
ratio. The drift rate is the least-squares slope of the resonance frequency over time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.analysis.flags import FlagCode, flag


@dataclass(frozen=True)
class TrackRecord:
    """The looks of one track: ``time_s`` from the run's start, and per look the drive and the
    resonance frequency (Hz), the ratio's magnitude and phase (degrees), the damping ratio;
    ``verdict`` how the track ended (``tracked``, or ``stopped`` with ``reason``)."""

    time_s: np.ndarray
    drive_hz: np.ndarray
    resonance_hz: np.ndarray
    ratio: np.ndarray
    phase_deg: np.ndarray
    damping_ratio: np.ndarray
    verdict: str = ""
    reason: str = ""


@dataclass(frozen=True)
class TrackResult:
    """The resonance at the track's first and last look, its drift rate, the ratio and damping
    ranges, and how the track ended."""

    looks: int
    first_hz: float
    last_hz: float
    drift_hz_per_s: float
    ratio_range: tuple[float, float]
    damping_range: tuple[float, float]
    verdict: str
    reason: str

    def summary_lines(self) -> list[str]:
        lines = [
            f"tracked resonance: {self.first_hz:.3f} Hz -> {self.last_hz:.3f} Hz over {self.looks} looks"
            f" (drift {self.drift_hz_per_s * 60:+.3f} Hz/min)",
            f"ratio {self.ratio_range[0]:.4g}-{self.ratio_range[1]:.4g},"
            f" damping ratio {self.damping_range[0]:.4f}-{self.damping_range[1]:.4f}",
        ]
        if self.reason:
            lines.append(flag(FlagCode.TRACK_STOPPED, f"the track stopped: {self.reason}"))
        return lines


def analyse_track(record: TrackRecord) -> TrackResult:
    """The drift of a tracked resonance; ValueError when the track made no look."""
    if record.time_s.size == 0:
        raise ValueError("the track made no look at its resonance (it ended before its first window)")
    slope = 0.0
    if record.time_s.size > 1:
        slope = float(np.polyfit(record.time_s, record.resonance_hz, 1)[0])
    return TrackResult(
        int(record.time_s.size),
        float(record.resonance_hz[0]),
        float(record.resonance_hz[-1]),
        slope,
        (float(np.min(record.ratio)), float(np.max(record.ratio))),
        (float(np.min(record.damping_ratio)), float(np.max(record.damping_ratio))),
        record.verdict,
        record.reason,
    )
