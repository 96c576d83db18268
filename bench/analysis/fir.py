"""FIR filters designed by weighted complex least squares, applied offline or as a stream.

A filter ``h`` (``n_taps`` real taps at ``fs``) approximates a target response that includes a
fixed latency ``L`` samples, ``D(f) = G(f) exp(-j 2 pi f L / fs)``::

    min_h  sum_k W_k |sum_n h_n exp(-j 2 pi f_k n / fs) - D(f_k)|^2 + lam ||h||^2

solved as one real linear least-squares problem (real and imaginary rows stacked). A FIR is
stable by construction and causal; the output at sample ``n`` describes the input instant
``n - L``. The small ridge term ``lam`` bounds the taps, so the gain outside the weighted band
stays bounded.

With a ridge the problem is solved through its normal equations ``(B^T B + lam I) h = B^T d``
(Cholesky; ``B^T B`` is Toeplitz, ``sum_k W_k cos(2 pi f_k (n - m) / fs)``): their condition
number is at most ``1 + n_taps / ridge`` (``lam`` is ``ridge`` times the trace of ``B^T B`` over
``n_taps``), so they lose at most that times the machine precision (4e-8 for 160 taps and a ridge
of 1e-6), at a fraction of the cost of the SVD that solves the problem without a ridge, whose
condition nothing bounds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from bench.analysis.validation import AnalysisInputError

#: Where a filter's target has rolled off to zero, as a multiple of its band's upper end: the
#: half-cosine taper between them keeps the taps short and the gain above the band bounded.
STOP_BAND_FACTOR = 1.5


def fir_response(taps: np.ndarray, freq_hz: np.ndarray, fs_hz: float) -> np.ndarray:
    """Complex frequency response of FIR ``taps`` at ``freq_hz`` (:func:`scipy.signal.freqz`)."""
    from scipy.signal import freqz
    f = np.atleast_1d(np.asarray(freq_hz, dtype=float))
    return freqz(np.asarray(taps, dtype=float), 1.0, worN=f, fs=fs_hz)[1].reshape(np.shape(freq_hz))


@lru_cache(maxsize=4)
def _fourier_basis(freq_hz_bytes: bytes, fs_hz: float, n_taps: int) -> np.ndarray:
    """``exp(-j 2 pi f_k n / fs)`` for the frequencies (float64 bytes) and taps ``n``: the same for
    every design on one grid (a compensator's two filters, every compensator at one sample rate),
    so it is computed once per grid; read-only."""
    f = np.frombuffer(freq_hz_bytes, dtype=float)
    basis = np.exp(-2j * np.pi * np.outer(f / fs_hz, np.arange(n_taps)))
    basis.flags.writeable = False
    return basis


def design_fir(
    freq_hz: np.ndarray,
    target: np.ndarray,
    weight: np.ndarray,
    *,
    n_taps: int,
    latency_samples: int,
    fs_hz: float,
    ridge: float = 0.0,
) -> np.ndarray:
    """Taps approximating ``target * exp(-j w latency)`` (see the module docstring).

    ``ridge`` is relative: ``lam = ridge * mean(W)`` times the grid size.
    """
    f = np.asarray(freq_hz, dtype=float)
    if not 0 <= latency_samples < n_taps:
        raise AnalysisInputError(f"latency {latency_samples} must lie within the {n_taps} taps")
    if np.any(f < 0) or np.any(f > fs_hz / 2):
        raise AnalysisInputError("design frequencies must lie in [0, fs/2]")
    d = np.asarray(target, dtype=complex) * np.exp(-2j * np.pi * f * latency_samples / fs_hz)
    w = np.asarray(weight, dtype=float)
    basis = _fourier_basis(f.tobytes(), float(fs_hz), n_taps)
    if ridge > 0:
        from scipy.linalg import cho_factor, cho_solve, toeplitz  # loaded where a filter is designed

        # B^T B sums W_k cos(w_k (n - m)): a Toeplitz matrix, its first column Re(W @ basis)
        gram = toeplitz((w @ basis).real) + ridge * np.mean(w) * f.size * np.eye(n_taps)
        return cho_solve(cho_factor(gram), (np.conj(basis).T @ (w * d)).real)
    sw = np.sqrt(w)
    weighted, d_weighted = basis * sw[:, None], d * sw
    rows = np.vstack([weighted.real, weighted.imag])
    taps, *_ = np.linalg.lstsq(rows, np.concatenate([d_weighted.real, d_weighted.imag]), rcond=None)
    return taps


def half_cosine_rolloff(freq_hz: np.ndarray, pass_hz: float, stop_hz: float) -> np.ndarray:
    """1 up to ``pass_hz``, 0 from ``stop_hz`` on, a half cosine in between (a design target's taper)."""
    f = np.asarray(freq_hz, dtype=float)
    if not 0 < pass_hz < stop_hz:
        raise AnalysisInputError(f"roll-off needs 0 < pass {pass_hz} Hz < stop {stop_hz} Hz")
    x = np.clip((f - pass_hz) / (stop_hz - pass_hz), 0.0, 1.0)
    return 0.5 + 0.5 * np.cos(np.pi * x)


def apply_aligned(taps: np.ndarray, x: np.ndarray, latency_samples: int) -> np.ndarray:
    """Filter a whole record and undo the latency: ``y[n]`` describes instant ``n``.

    Only outputs whose whole input window lies inside the record are finite: the first
    ``n_taps - 1 - latency_samples`` would need input before the record (a filter started from zero
    history is finite but wrong there), the last ``latency_samples`` input after it. Both are NaN,
    never a guess.
    """
    x = np.asarray(x, dtype=float)
    # the FIR from zero history, as lfilter(taps, [1], x): numpy's direct convolution, so that a
    # reader of stored results (the report's traces) needs no signal-processing library
    y = np.convolve(x, np.asarray(taps, dtype=float))[: x.size]
    out = np.full(y.size, np.nan)
    out[: y.size - latency_samples] = y[latency_samples:]
    out[: min(np.asarray(taps).size - 1 - latency_samples, y.size)] = np.nan
    return out


@dataclass
class StreamingFir:
    """A multi-input FIR, ``y = sum_i h_i * x_i``, fed block by block (state kept between blocks).

    Output sample ``n`` of the stream describes the input instant ``n - latency_samples``; the first
    ``n_taps - 1`` outputs start from zero history (the filter's start-up transient).
    """

    taps: Sequence[np.ndarray]
    latency_samples: int
    _zi: list[np.ndarray] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.taps = [np.asarray(t, dtype=float) for t in self.taps]
        self._zi = [np.zeros(t.size - 1) for t in self.taps]

    def process(self, *blocks: np.ndarray) -> np.ndarray:
        from scipy.signal import lfilter
        if len(blocks) != len(self.taps):
            raise AnalysisInputError(f"expected {len(self.taps)} input blocks, got {len(blocks)}")
        sizes = {np.asarray(b).size for b in blocks}
        if len(sizes) != 1:
            raise AnalysisInputError(f"input blocks have different lengths: {sorted(sizes)}")
        out = np.zeros(sizes.pop())
        for i, (h, block) in enumerate(zip(self.taps, blocks, strict=True)):
            x = np.asarray(block, dtype=float)
            if not np.all(np.isfinite(x)):
                raise AnalysisInputError("streaming filter input contains NaN or infinite values")
            y, self._zi[i] = lfilter(h, [1.0], x, zi=self._zi[i])
            out += y
        return out


def double_differentiator(fs_hz: float, *, band_hz: float, n_taps: int = 61) -> tuple[np.ndarray, int]:
    """Taps and latency of ``d^2/dt^2`` accurate over ``[0, band_hz]`` and rolling off above.

    Used to turn a measured displacement into acceleration (plate-mass correction). Above the band
    the target falls to zero with a half-cosine, weighted lightly, so noise is not amplified as w^2.
    """
    latency = (n_taps - 1) // 2
    f = np.linspace(0, fs_hz / 2, 8 * n_taps)
    stop = min(STOP_BAND_FACTOR * band_hz, fs_hz / 2)
    target = -((2 * np.pi * f) ** 2) * half_cosine_rolloff(f, band_hz, stop)
    # relative accuracy in the band: |error|^2 weighted by 1 / |target|^2 (floored below 0.5 Hz)
    w_floor = 2 * np.pi * np.maximum(f, 0.5)
    weight = np.where(f <= band_hz, 1.0, 1e-3) * (2 * np.pi * band_hz / w_floor) ** 4
    taps = design_fir(f, target, weight, n_taps=n_taps, latency_samples=latency, fs_hz=fs_hz)
    return taps, latency
