"""One fit of a sine at a known frequency, on the samples' true times.

A window of WFS samples is not always a contiguous run of time: frames lost on the link (a USB
adapter's hiccup, a cable, noise) or to a host that left its port unread are absent, and the
frame counter ``seq`` that every frame carries shows where and how many. Fitting the samples on
both sides of a gap as if they were contiguous reads a wrong amplitude and phase (the two pieces
are out of phase with each other): a 1 mm plate read 0.33-0.70 mm that way, and the command was
raised on it. Every fit of a sine at a known frequency (the engine's amplitude checks and in-dwell
updates, its settle verdicts and its resonance track, the analysis of a dwell) therefore takes the
samples' times from the counter (:func:`frame_offsets`), builds its design on them
(:func:`sine_design`), and says how much of its window was missing (:class:`SineFit`).

Conventions: a channel's fitted model is ``offset + sum_k (a_k cos(k w t) + b_k sin(k w t))``, its
phasor at harmonic ``k`` is ``a_k - j b_k`` (so ``x = Re(A exp(j k w t))``), ``t`` in seconds from
the window's reference sample. Offsets count samples at the acquisition's rate.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

#: The frame counter counts modulo 2^32.
SEQ_MODULUS = 1 << 32


def frame_offsets(seq: np.ndarray, reference: int | None = None) -> np.ndarray:
    """Each frame's true sample offset (int64) from the frame whose counter is ``reference`` (the
    first frame's by default), from the frame counter ``seq`` unwrapped modulo 2^32.

    A step of the counter that goes backwards (a device restart: the parser reports it, and nothing
    can be said of the time across it) counts as one sample, as does a repeated value (never
    delivered: the parser drops duplicates)."""
    s = np.asarray(seq, dtype=np.int64)
    if s.size == 0:
        return np.zeros(0, np.int64)
    steps = np.diff(s) % SEQ_MODULUS
    steps[(steps == 0) | (steps > SEQ_MODULUS // 2)] = 1
    offsets = np.empty(s.size, np.int64)
    offsets[0] = 0
    np.cumsum(steps, out=offsets[1:])
    if reference is not None:
        first = (int(s[0]) - int(reference)) % SEQ_MODULUS
        offsets += first - SEQ_MODULUS if first > SEQ_MODULUS // 2 else first
    return offsets


def sine_design(t_s: np.ndarray, freq_hz: float, n_harmonics: int = 1) -> np.ndarray:
    """The least-squares design at times ``t_s`` (s): columns offset, then ``cos(k w t)`` and
    ``sin(k w t)`` of each harmonic ``k = 1..n_harmonics``."""
    t = np.asarray(t_s, dtype=float)
    w = 2 * np.pi * float(freq_hz)
    columns = [np.ones_like(t)]
    for k in range(1, n_harmonics + 1):
        columns += [np.cos(k * w * t), np.sin(k * w * t)]
    return np.stack(columns, axis=1)


def harmonic_phasors(coef: np.ndarray, k: int = 1) -> np.ndarray:
    """Phasor of harmonic ``k`` from coefficients of :func:`sine_design`: ``a cos + b sin =
    Re((a - j b) exp(j k w t))``."""
    return coef[2 * k - 1] - 1j * coef[2 * k]


@dataclass(frozen=True)
class SineFit:
    """A fit of one or more channels at ``freq_hz`` over a window of ``span_samples`` sample times
    (first to last sample, both included) of which ``frames_present`` frames were there.

    ``phasors``: each channel's fundamental (channel units, ``t`` from the window's first sample);
    ``means``: each channel's fitted offset (its mean); ``residual_rms``: what the fit leaves, per channel."""

    freq_hz: float
    sample_rate_hz: float
    phasors: np.ndarray
    means: np.ndarray
    residual_rms: np.ndarray
    frames_present: int
    span_samples: int

    @property
    def frames_missing(self) -> int:
        return self.span_samples - self.frames_present

    @property
    def cycles_present(self) -> float:
        """How many cycles' worth of frames the window holds."""
        return self.frames_present * self.freq_hz / self.sample_rate_hz

    @property
    def amplitude(self) -> float:
        """The first channel's fundamental amplitude (channel units)."""
        return float(abs(self.phasors[0]))


def fit_sine(
    values: np.ndarray,
    offsets: np.ndarray,
    sample_rate_hz: float,
    freq_hz: float,
    *,
    n_harmonics: int = 1,
) -> SineFit:
    """Fit ``values`` (samples, or samples x channels) at their true sample ``offsets`` with an
    offset, the fundamental and ``n_harmonics - 1`` harmonics at the known ``freq_hz``.

    Raises ValueError when the window holds fewer frames than the fit has unknowns."""
    y = np.asarray(values, dtype=float)
    y = y[:, None] if y.ndim == 1 else y
    k = np.asarray(offsets, dtype=np.int64)
    if len(k) != len(y):
        raise ValueError(f"{len(y)} samples but {len(k)} offsets")
    p = 2 * n_harmonics + 1
    if len(k) < p + 1:
        raise ValueError(f"a sine fit of {p} unknowns needs more than {len(k)} samples")
    design = sine_design((k - k[0]) / sample_rate_hz, freq_hz, n_harmonics)
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    residual = y - design @ coef
    return SineFit(
        float(freq_hz),
        float(sample_rate_hz),
        harmonic_phasors(coef, 1),
        coef[0].copy(),
        np.sqrt(np.mean(residual**2, axis=0)),
        len(k),
        int(k[-1] - k[0]) + 1,
    )


def fit_latest_cycles(
    values: np.ndarray,
    offsets: np.ndarray,
    sample_rate_hz: float,
    freq_hz: float,
    *,
    start: int | None = None,
    end: int | None = None,
) -> SineFit | None:
    """The fit (:func:`fit_sine`, the fundamental alone) over the latest whole cycles of *time* in
    the window from offset ``start`` (the first sample's by default) to ``end`` (exclusive; after
    the last sample by default): the fit's window ends at ``end`` and reaches back a whole number
    of cycles, and whatever is missing inside it, at its ends included, counts as missing. None
    when the window holds no whole cycle, or too few samples to fit."""
    k = np.asarray(offsets, dtype=np.int64)
    if len(k) == 0:
        return None
    start = int(k[0]) if start is None else start
    end = int(k[-1]) + 1 if end is None else end
    cycle = sample_rate_hz / freq_hz
    n_cycles = int(np.floor((end - start) / cycle + 1e-9))
    if n_cycles < 1:
        return None
    first = end - round(n_cycles * cycle)
    inside = (k >= first) & (k < end)
    try:
        fit = fit_sine(np.asarray(values)[inside], k[inside], sample_rate_hz, freq_hz)
    except ValueError:
        return None
    # the window's span is the whole cycles of time, whether or not its first frames came
    return replace(fit, span_samples=round(n_cycles * cycle))
