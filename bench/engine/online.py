"""Online settle and measure verdicts of an adaptive dwell, block by block.

During a dwell's hold every block of samples adds its least-squares normal equations (offset,
fundamental and harmonics at the known frequency, one design shared by the channels) to running
sums kept at block boundaries, so a fit over any run of whole blocks costs a few small matrix
operations, whatever the hold's length: the work per block is O(block).

The FRF point is ``H = output / (input + m w^2 z)``: the WFS force over the contact force when
``input`` is the load cell under a plate of mass ``m`` (:class:`sequences.AdaptiveDwell`). Its
standard uncertainty follows from the fits' residuals: each channel's phasor variance
``s^2 ((X'X)^-1_cc + (X'X)^-1_ss)`` (``s^2`` the residual variance, white noise assumed), combined
relatively, ``r^2 = var_out / |out|^2 + var_in / |in|^2``; the magnitude's relative and the phase's
standard uncertainty are each ``r / sqrt(2)`` (the complex error splits evenly between the radial
and the tangential direction).

- **Settled** at hold time ``t`` (at least two cycles): the FRF point fitted over ``[t - 2L, t - L)``
  and over ``[t - L, t)``, ``L = max(t / 4, one cycle)``, differ by at most ``settle_tolerance``
  of its magnitude plus three standard uncertainties of the difference. The window grows with the
  hold, so a slow transient (a lightly damped mode building up) shows as a change however short the
  blocks are.
  The measured part begins at ``t - 2L``, where the estimate was already steady, but not before
  :data:`MEASURE_AFTER_S`.
- **Measured** when, from there on, the uncertainty is within both targets, the measured part holds
  two whole cycles (:data:`MEASURE_CYCLES`) and the hold reached its minimum length; or **max
  length** when the hold reached its maximum first.

Hold time is true time: every sample's place in the hold comes from its frame counter
(:func:`~bench.numerics.sine_fit.frame_offsets`), so frames lost on the link leave a gap in the
design rather than shifting the samples after it, and every length above counts sample times. A
window that lost more of its frames than :class:`~bench.engine.amplitude.FramesPresent` allows
gives no verdict: the settle test and the measured test wait for windows with their frames.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from bench.engine.amplitude import FramesPresent
from bench.numerics.sine_fit import frame_offsets, harmonic_phasors, sine_design
from sequences import AdaptiveDwell
from sequences.points import Verdict

#: Standard uncertainties of the difference that the settling test allows on top of its tolerance.
SETTLE_SIGMAS = 3.0
#: The measured part begins no earlier in the hold than the analysis's settling allowance
#: (``bench.analysis.records.DEFAULT_SETTLE_S``), and holds at least the two whole cycles its
#: settling check needs, so that the analysis of the file fits the part measured here.
MEASURE_AFTER_S = 0.2
MEASURE_CYCLES = 2


@dataclass(frozen=True)
class DwellVerdict:
    """How an adaptive dwell ended. ``verdict``: "target" (settled and measured to the targets),
    "max length" (settled, targets not reached) or "not settled". Times count from the hold's start
    (s); ``measure_start_s`` is NaN when it never settled (its figures then come from the latter half
    of the hold). ``frf`` is the FRF point, ``displacement_m`` the displacement's phasor, both over
    the measured part, of whose ``span_samples`` sample times ``frames_present`` had their frame."""

    verdict: str
    settle_s: float
    measure_start_s: float
    measure_s: float
    frf: complex
    magnitude_uncertainty_pct: float
    phase_uncertainty_deg: float
    displacement_m: complex
    frames_present: int = 0
    span_samples: int = 0

    @property
    def settled(self) -> bool:
        return self.verdict != Verdict.NOT_SETTLED


@dataclass(frozen=True)
class _WindowFit:
    frf: complex
    frf_sigma: float  # standard uncertainty of the complex FRF point (absolute)
    relative: float  # the magnitude's relative (and the phase's, rad) standard uncertainty
    displacement_m: complex
    frames_present: int
    span_samples: int


class OnlineDwell:
    """Follows one dwell's hold: :meth:`feed` every block, stop when :attr:`done`, then :meth:`verdict`."""

    def __init__(
        self,
        freq_hz: float,
        sample_rate_hz: float,
        plan: AdaptiveDwell,
        displacement: str,
        *,
        n_harmonics: int = 3,
        present: FramesPresent | None = None,
    ) -> None:
        """``present``: how much of a window's frames a verdict needs."""
        self.present = present or FramesPresent()
        self.freq_hz = float(freq_hz)
        self.fs = float(sample_rate_hz)
        self.plan = plan
        self.names = (plan.output, plan.input, displacement)
        self.w = 2 * math.pi * self.freq_hz
        self.n_harm = max(1, min(n_harmonics, math.ceil(self.fs / 2 / self.freq_hz) - 1))
        self.cycle = self.fs / self.freq_hz  # samples per cycle
        self.min_hold = round(plan.min_hold_at_s(self.freq_hz) * self.fs)
        self.max_hold = round(plan.max_hold_s * self.fs)
        p = 2 * self.n_harm + 1
        self._bounds = [0]  # hold sample times at each block boundary
        self._frames = [0]  # frames present in the hold up to each boundary
        self._seq_at_hold: int | None = None  # the frame counter of the hold's first frame
        self._g = [np.zeros((p, p))]  # running sums of X'X, X'Y, Y'Y at the boundaries
        self._b = [np.zeros((p, 3))]
        self._s = [np.zeros(3)]
        self.held = 0  # hold sample times seen (frames lost in the hold count)
        self.settle_at: int | None = None  # hold samples when the settle verdict came
        self._steady_from: float | None = None  # hold samples from which the estimate was steady
        self._result: tuple[str, _WindowFit | None] | None = None

    @property
    def done(self) -> bool:
        return self._result is not None

    def feed(
        self,
        first_sample: int,
        columns: Mapping[str, np.ndarray],
        hold_start: int | None,
        hold_end: int | None,
    ) -> None:
        """Add a block (run samples from ``first_sample``) of which the part in the hold counts."""
        if self.done or hold_start is None or not columns:
            return
        n = len(columns[self.names[0]])
        lo = max(first_sample, hold_start)
        hi = first_sample + n if hold_end is None else min(first_sample + n, hold_end)
        if hi <= lo:
            return
        seq = np.asarray(columns["seq"][lo - first_sample : hi - first_sample])
        if self._seq_at_hold is None:
            self._seq_at_hold = int(seq[0]) - (lo - hold_start)
        k = frame_offsets(seq, self._seq_at_hold)
        if k[-1] + 1 <= self.held:  # a counter gone back (a restart): the time base is lost
            return
        x = sine_design(k / self.fs, self.freq_hz, self.n_harm)
        y = np.stack(
            [np.asarray(columns[c][lo - first_sample : hi - first_sample], float) for c in self.names], 1
        )
        self._g.append(self._g[-1] + x.T @ x)
        self._b.append(self._b[-1] + x.T @ y)
        self._s.append(self._s[-1] + np.sum(y * y, axis=0))
        self.held = int(k[-1]) + 1
        self._bounds.append(self.held)
        self._frames.append(self._frames[-1] + len(k))
        self._judge()

    @property
    def _measure_from(self) -> int | None:
        """The boundary index where the measured part begins (None: not settled yet)."""
        if self._steady_from is None:
            return None
        return bisect.bisect_left(self._bounds, max(self._steady_from, MEASURE_AFTER_S * self.fs) - 0.5)

    def _judge(self) -> None:
        if self._steady_from is None:
            self._settle_test()
        first = self._measure_from
        if first is not None and first < len(self._bounds) - 1:
            fit = self._fit(first, len(self._bounds) - 1)
            measured = self.held - self._bounds[first]
            targets = self._decidable(fit) and (
                100 * fit.relative <= self.plan.magnitude_target_pct
                and math.degrees(fit.relative) <= self.plan.phase_target_deg
            )
            enough = measured >= MEASURE_CYCLES * self.cycle - 0.5
            if targets and enough and self.held >= self.min_hold:
                self._result = (Verdict.TARGET, fit)
                return
        if self.held >= self.max_hold:
            self.finish()

    def _settle_test(self) -> None:
        if self.held < 2 * self.cycle:
            return
        span = max(self.held / 4, self.cycle)
        last = len(self._bounds) - 1
        start = self._boundary(self.held - 2 * span)
        middle = self._boundary(self.held - span)
        if not start < middle < last:
            return
        a, b = self._fit(start, middle), self._fit(middle, last)
        if not (self._decidable(a) and self._decidable(b)):
            return  # too few samples, or frames lost: wait for more
        noise = SETTLE_SIGMAS * math.hypot(a.frf_sigma, b.frf_sigma)
        if abs(b.frf - a.frf) <= self.plan.settle_tolerance * abs(b.frf) + noise:
            self.settle_at = self.held
            self._steady_from = self._bounds[start]

    def _decidable(self, fit: _WindowFit | None) -> bool:
        """Whether a verdict may rest on ``fit``'s window (its frames there: :attr:`present`)."""
        if fit is None:
            return False
        return not self.present.refusal_of(fit.frames_present, fit.span_samples, self.freq_hz, self.fs)

    def _boundary(self, samples: float) -> int:
        """The index of the block boundary nearest ``samples`` of hold."""
        i = bisect.bisect_left(self._bounds, samples)
        if i > 0 and (i == len(self._bounds) or samples - self._bounds[i - 1] < self._bounds[i] - samples):
            i -= 1
        return i

    def _fit(self, i0: int, i1: int) -> _WindowFit | None:
        """The FRF point over the blocks between boundaries ``i0`` and ``i1`` (None: too few samples)."""
        n = self._frames[i1] - self._frames[i0]
        g = self._g[i1] - self._g[i0]
        p = g.shape[0]
        if n < max(2 * p, self.cycle):
            return None
        b = self._b[i1] - self._b[i0]
        g_inv = np.linalg.inv(g)
        coef = g_inv @ b
        rss = np.maximum(self._s[i1] - self._s[i0] - np.sum(coef * b, axis=0), 0.0)
        var = rss / (n - p) * (g_inv[1, 1] + g_inv[2, 2])  # E|dA|^2 of each channel's phasor
        phasor = harmonic_phasors(coef)
        inertia = self.plan.plate_mass_kg * self.w**2
        out, inp = phasor[0], phasor[1] + inertia * phasor[2]
        if out == 0 or inp == 0:
            return None
        var_in = var[1] + inertia**2 * var[2]
        rel2 = var[0] / abs(out) ** 2 + var_in / abs(inp) ** 2
        frf = complex(out / inp)
        span = self._bounds[i1] - self._bounds[i0]
        return _WindowFit(frf, abs(frf) * math.sqrt(rel2), math.sqrt(rel2 / 2), complex(phasor[2]), n, span)

    def finish(self) -> None:
        """End the dwell as it stands (its hold ended or reached the maximum length)."""
        if self.done:
            return
        last = len(self._bounds) - 1
        first = self._measure_from
        if first is not None:
            self._result = (Verdict.MAX_LENGTH, self._fit(first, last) if first < last else None)
        else:
            self._result = (Verdict.NOT_SETTLED, self._fit(self._boundary(self.held / 2), last))

    def verdict(self) -> DwellVerdict:
        """The verdict and its figures (the dwell is finished first if it is not done)."""
        self.finish()
        verdict, fit = self._result
        nan = float("nan")
        first = self._measure_from
        start = nan if first is None else self._bounds[min(first, len(self._bounds) - 1)] / self.fs
        settle = nan if self.settle_at is None else self.settle_at / self.fs
        held_s = self.held / self.fs
        measure_s = held_s - (start if first is not None else held_s / 2)
        if fit is None:
            missing = complex(nan, nan)
            return DwellVerdict(verdict, settle, start, measure_s, missing, nan, nan, missing)
        return DwellVerdict(
            verdict,
            settle,
            start,
            measure_s,
            fit.frf,
            100 * fit.relative,
            math.degrees(fit.relative),
            fit.displacement_m,
            fit.frames_present,
            fit.span_samples,
        )
