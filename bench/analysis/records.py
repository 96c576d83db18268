"""Recorded runs as the analysis takes them: one dwell, one sweep, one hammer blow.

These are the units the run engine and the data store produce: the sampled channels of one
excitation, by name (the bench's channel names, units in the names), with the sample rate and what
the excitation was. Channels a given analysis does not use are ignored (a time axis, a reference
channel of the simulator). Every check names the record, so an error in a campaign of a hundred
dwells says which one is broken.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from bench.analysis.validation import AnalysisInputError, as_sample_rate, as_signals
from sequences.channels import Role, standard_name

if TYPE_CHECKING:
    from bench.analysis.dwell import DwellFit

#: The channels the analysis reads, by their roles' standard names (a file recorded under a lab's
#: own names is read back under these: :mod:`sequences.channels`).
DISPLACEMENT = standard_name(Role.BENCH_DISPLACEMENT)
PLATE_FORCE = standard_name(Role.PLATE_FORCE)
WFS_FORCE = standard_name(Role.WFS_FZ)
HUB_ACCELERATION = standard_name(Role.HUB_ACCELERATION)
HAMMER_FORCE = standard_name(Role.HAMMER_FORCE)

#: Channels of a dwell or sweep with a wheel on the bench, and of a free run (no wheel). A shaker's
#: dwells need no hub acceleration (``SHAKER_CHANNELS``): its hub is clamped.
WHEEL_CHANNELS = (DISPLACEMENT, PLATE_FORCE, WFS_FORCE, HUB_ACCELERATION)
SHAKER_CHANNELS = (DISPLACEMENT, PLATE_FORCE, WFS_FORCE)
FREE_RUN_CHANNELS = (DISPLACEMENT, PLATE_FORCE)

#: Reliable dwell frequencies a tyre fit needs (Model 2 has three parameters; the fourth point leaves
#: a residual to judge it by). With fewer a grid gives its measured ratios only.
MIN_FIT_POINTS = 4
#: Time left for settling at the start of a dwell's hold phase before the analysed window.
DEFAULT_SETTLE_S = 0.2
#: Largest relative difference between a dwell's measured and declared displacement amplitude. A
#: servo-hydraulic actuator follows its command within a few percent over the dwell band (the
#: simulated controller within 1 % to 100 Hz); a record far off did not excite what it claims: the
#: actuator did not move, or the record's amplitude or frequency is mislabelled (a fit at the wrong
#: frequency over whole cycles sees almost none of the signal).
AMPLITUDE_MISMATCH = 0.2
#: A channel carries the excitation when its fundamental exceeds this many standard uncertainties
#: (and the rounding of its own level): otherwise it is dead (zeros) or frozen (a constant).
MIN_SIGNAL_SIGMAS = 5.0
_ROUNDING = 1e-9


@dataclass(frozen=True)
class DwellRecord:
    """One sine dwell: the base moved at ``freq_hz`` with amplitude ``amplitude_m`` (as commanded).

    ``channels``: sampled signals by name at ``sample_rate_hz``, all of one length, time zero at the
    first sample. ``hold_s``: start and end of the constant-amplitude hold in record time (after
    the taper-in, before the taper-out), as the run engine knows it; ``None`` when the whole record
    is the hold. The analysis leaves a settling time at the start of the hold and checks that the
    dwell settled (:func:`bench.analysis.dwell.fit_dwell`). ``nominal_amplitude_m``: the amplitude
    of the grid the dwell belongs to, when a bench limit (velocity, acceleration) lowered this
    dwell's amplitude below it; the dwell is analysed with its grid (``None``: the grid's amplitude
    is ``amplitude_m``). ``sample_offsets``: each sample's offset in sample times from the first,
    from the frame counter, when frames were lost on the link (``None``: the samples are
    contiguous); record time counts sample times, lost ones included.
    """

    freq_hz: float
    amplitude_m: float
    sample_rate_hz: float
    channels: Mapping[str, np.ndarray]
    hold_s: tuple[float, float] | None = None
    nominal_amplitude_m: float | None = None
    sample_offsets: np.ndarray | None = None

    @property
    def grid_amplitude_m(self) -> float:
        """The amplitude of the grid this dwell belongs to."""
        return self.amplitude_m if self.nominal_amplitude_m is None else self.nominal_amplitude_m

    @property
    def label(self) -> str:
        """How errors and reports name this record."""
        return dwell_label(self.freq_hz, self.amplitude_m)


@dataclass(frozen=True)
class SweepRecord:
    """One sine sweep of the base from ``start_hz`` to ``end_hz`` over ``sweep_s`` seconds (as
    commanded, tapers inside) at amplitude ``amplitude_m``; ``channels`` by name at
    ``sample_rate_hz``, all of one length, time zero at the sweep's start. A record shorter than
    ``sweep_s`` did not see the band it claims and is refused by the analysis.
    ``sample_offsets``: each sample's offset in sample times from the first, from the frame
    counter, when frames were lost on the link (``None``: the samples are contiguous)."""

    start_hz: float
    end_hz: float
    sweep_s: float
    amplitude_m: float
    sample_rate_hz: float
    channels: Mapping[str, np.ndarray]
    sample_offsets: np.ndarray | None = None

    @property
    def label(self) -> str:
        return f"sweep {self.start_hz:g}-{self.end_hz:g} Hz at {1e3 * self.amplitude_m:g} mm"

    @property
    def duration_s(self) -> float:
        """The record's length in time (lost frames included)."""
        if self.sample_offsets is not None and len(self.sample_offsets):
            return (int(self.sample_offsets[-1]) + 1) / float(self.sample_rate_hz)
        return len(next(iter(self.channels.values()), ())) / float(self.sample_rate_hz)


@dataclass(frozen=True)
class RoadReplayRecord:
    """One road replay: the post driven by a displacement drive; ``channels`` by name at
    ``sample_rate_hz`` over the drive (its tapers included), time zero at its first sample;
    ``hold_s`` the part between its tapers (s from the record's start); ``source``: where the drive
    came from (the run's ``drive`` attribute)."""

    sample_rate_hz: float
    channels: Mapping[str, np.ndarray]
    hold_s: tuple[float, float]
    source: str = ""

    @property
    def label(self) -> str:
        return f"road replay of {self.source or 'a drive'}"

    @property
    def duration_s(self) -> float:
        return len(next(iter(self.channels.values()), ())) / float(self.sample_rate_hz)


@dataclass(frozen=True)
class HammerRecord:
    """One hammer blow on the bare sensor: the WFS force and, when recorded, the hammer's force,
    at ``sample_rate_hz`` (fast: the sensor rings at kilohertz)."""

    sample_rate_hz: float
    channels: Mapping[str, np.ndarray]

    @property
    def label(self) -> str:
        return f"hammer blow at {self.sample_rate_hz:g} Hz sampling"


def dwell_label(freq_hz: float, amplitude_m: float) -> str:
    """How errors and reports name a dwell."""
    return f"dwell {1e3 * amplitude_m:g} mm at {freq_hz:g} Hz"


def amplitude_label(amplitude_m: float) -> str:
    """How reports name an amplitude group (4 significant digits: equal labels, equal groups)."""
    return f"{1e3 * amplitude_m:.4g} mm"


def dwell_problems(record: DwellRecord, fit: DwellFit, signal_channels: Sequence[str]) -> tuple[str, ...]:
    """Why a fitted dwell cannot be used, if it cannot: the measured displacement amplitude far from
    the declared one (``AMPLITUDE_MISMATCH``), or a channel without signal at the excitation
    frequency (``MIN_SIGNAL_SIGMAS``). Empty when the dwell is usable."""
    problems = []
    z = abs(fit.channels[DISPLACEMENT].amplitude)
    if not abs(z / record.amplitude_m - 1) <= AMPLITUDE_MISMATCH:
        problems.append(
            f"measured displacement amplitude {1e3 * z:.3g} mm against the declared"
            f" {1e3 * record.amplitude_m:g} mm: the actuator did not follow, or the record's frequency"
            " or amplitude is mislabelled"
        )
    for name in signal_channels:
        c = fit.channels[name]
        floor = MIN_SIGNAL_SIGMAS * c.amplitude_sigma + _ROUNDING * (abs(c.offset) + c.residual_rms)
        if not abs(c.amplitude) > floor:
            problems.append(
                f"channel {name!r} carries no signal at {record.freq_hz:g} Hz (fundamental"
                f" {abs(c.amplitude):.3g}, offset {c.offset:.4g}): dead or frozen channel"
            )
    return tuple(problems)


def record_channels(
    record: DwellRecord | SweepRecord | HammerRecord | RoadReplayRecord,
    required: Sequence[str],
    *,
    min_samples: int = 1,
) -> dict[str, np.ndarray]:
    """The ``required`` channels of ``record``, checked (finite, 1-D, equal lengths); every error
    names the record."""
    missing = [name for name in required if name not in record.channels]
    if missing:
        raise AnalysisInputError(
            f"{record.label}: no channel {', '.join(map(repr, missing))} (has {sorted(record.channels)})"
        )
    try:
        as_sample_rate(record.sample_rate_hz)
        return as_signals({name: record.channels[name] for name in required}, min_samples=min_samples)
    except AnalysisInputError as err:
        raise AnalysisInputError(f"{record.label}: {err}") from err


#: The cosine ramp (s) by which :func:`on_true_times` fades a record out before a stretch of lost
#: frames and in after it: smooth enough that the gate's spectrum falls off within a few hertz.
GATE_RAMP_S = 0.05


def on_true_times(
    channels: Mapping[str, np.ndarray], sample_offsets: np.ndarray | None, sample_rate_hz: float
) -> tuple[dict[str, np.ndarray], tuple[tuple[int, int], ...]]:
    """The channels placed on their true sample times, and the stretches (first sample, end
    sample) that a gate closes where frames were lost.

    Every channel is faded to its mean over :data:`GATE_RAMP_S` before a stretch of lost frames and
    in after it, and holds its mean within: one gate, the same for all channels, as a window is (no
    sample is made up, and no channel gets what the others have not). A stretch's ends include
    the ramps. An analysis on the result leaves out what the stretches spoil (the bins a sweep
    excited there, the samples a regression would take from them)."""
    if sample_offsets is None:
        return dict(channels), ()
    k = np.asarray(sample_offsets, dtype=np.int64)
    if k.size and np.any(np.diff(k) <= 0):
        raise AnalysisInputError("sample offsets do not rise from sample to sample")
    n = int(k[-1]) + 1 if k.size else 0
    gate = np.zeros(n)
    gate[k] = 1.0
    ramp = max(round(GATE_RAMP_S * sample_rate_hz), 1)
    fade = 0.5 - 0.5 * np.cos(np.pi * np.arange(1, ramp + 1) / (ramp + 1))
    stretches = []
    for i in np.flatnonzero(np.diff(k) > 1):
        start, end = int(k[i]) + 1, int(k[i + 1])
        before, after = max(start - ramp, 0), min(end + ramp, n)
        gate[before:start] = np.minimum(gate[before:start], fade[::-1][: start - before])
        gate[end:after] = np.minimum(gate[end:after], fade[: after - end])
        stretches.append((before, after))
    placed = {}
    for name, x in channels.items():
        values = np.asarray(x, dtype=float)
        mean = float(np.mean(values)) if values.size else 0.0
        full = np.full(n, mean)
        full[k] = values
        placed[name] = mean + gate * (full - mean)
    return placed, tuple(stretches)


def fit_dwell_record(
    record: DwellRecord, required: Sequence[str], *, settle_s: float = DEFAULT_SETTLE_S
) -> DwellFit:
    """Fit the ``required`` channels of a dwell over its hold, ``settle_s`` after the hold begins."""
    # the fit's scipy modules load here, not with the record types: the store's reader, and the
    # commands that only read a campaign file, need the types alone
    from bench.analysis.dwell import fit_dwell

    if not (np.isfinite(record.freq_hz) and record.freq_hz > 0):
        raise AnalysisInputError(f"{record.label}: frequency must be positive")
    if not (np.isfinite(record.amplitude_m) and record.amplitude_m > 0):
        raise AnalysisInputError(f"{record.label}: amplitude must be positive")
    channels = record_channels(record, required)
    start, stop = record.hold_s if record.hold_s is not None else (0.0, None)
    try:
        return fit_dwell(
            channels,
            record.sample_rate_hz,
            record.freq_hz,
            start_s=start + settle_s,
            stop_s=stop,
            sample_offsets=record.sample_offsets,
        )
    except AnalysisInputError as err:
        raise AnalysisInputError(f"{record.label}: {err}") from err
