"""Bounded weighted least squares with confidence intervals and an honest 'not determined' verdict.

Shared by every identification (tyre models on the shaker, the quarter car on the four-post), so
that all of them state their uncertainty the same way:

- parameters are scaled by their start values (``x = p / scale``) so the solver sees numbers of
  order one; bounds are scaled alike;
- covariance ``s^2 (J^T J)^+`` with ``s^2 = chi^2 / dof`` (the residuals' own scatter, so a model
  error widens the intervals instead of hiding), times ``covariance_factor`` for data whose points
  are correlated: a number, or a function of the final residuals (see
  :func:`correlated_residual_factor`); 95 % half-widths are 1.96 sigma;
- a parameter is *not determined* when its 95 % half-width exceeds its ``resolution`` (a function
  of its name and all fitted values; by default half its value), when it ends on a bound, or when
  it lies in the null space of ``J`` (singular values below 1e-9 of the largest).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

Z95 = 1.959964
UNDETERMINED_RELATIVE_CI = 0.5
_NULL_SPACE = 1e-9
#: A fit is far outside the noise when noise alone would give its chi^2 or more in fewer than one
#: fit in a thousand (:func:`chi2_exceedance`): a model that describes the data reaches it once in a
#: thousand fits.
OUTSIDE_NOISE_QUANTILE = 0.999
#: A chosen fit whose misfit noise alone gives in fewer than 1 % of fits is flagged: what the model
#: leaves out (a non-linear tyre's friction, a wrong sensor) biases its parameters beyond intervals
#: that hold the noise alone. A model that describes the data is flagged once in a hundred fits; a
#: non-linear Model-3 tyre, whose fits noise gives in 2e-6 to 3.5e-3, in every one
#: (``tests/analysis/test_analysis_misfit_flag.py``).
MISFIT_FLAG_EXCEEDANCE = 0.01
#: A misfit that noise alone gives less than once in a million fits cannot be noise: something the
#: model leaves out moved (a free run with the wheel left on reaches probabilities below 1e-100).
BEYOND_NOISE_EXCEEDANCE = 1e-6
#: Grid of the chi^2 distribution :func:`chi2_exceedance` computes (cells up to the value that noise
#: exceeds with probability :data:`_GRID_TAIL`).
_GRID_CELLS = 1 << 14
_GRID_TAIL = 1e-10


@dataclass(frozen=True)
class LsqResult:
    """``values`` and ``ci95`` (95 % half-widths) by parameter name; ``undetermined`` names, in
    fitting order; ``chi2`` over ``n_residuals`` real residuals with ``n_parameters`` parameters;
    ``covariance`` of the values (unscaled units); ``converged``: the solver's verdict."""

    values: dict[str, float]
    ci95: dict[str, float]
    undetermined: tuple[str, ...]
    covariance: np.ndarray
    chi2: float
    n_residuals: int
    n_parameters: int
    converged: bool

    @property
    def reduced_chi2(self) -> float:
        return self.chi2 / max(self.n_residuals - self.n_parameters, 1)


class FitStatistics:
    """The goodness-of-fit figures of a result that holds its :class:`LsqResult` as ``lsq``."""

    lsq: LsqResult

    @property
    def chi2(self) -> float:
        return self.lsq.chi2

    @property
    def n_residuals(self) -> int:
        return self.lsq.n_residuals

    @property
    def n_parameters(self) -> int:
        return self.lsq.n_parameters

    @property
    def converged(self) -> bool:
        return self.lsq.converged

    @property
    def reduced_chi2(self) -> float:
        return self.lsq.reduced_chi2


def chi2_exceedance(chi2: float, dof: int, noise_dof: int) -> float:
    """The probability that noise alone gives a chi^2 of at least ``chi2`` over ``dof`` degrees of
    freedom, when the residuals were whitened in complex pairs (real and imaginary part of one
    point) by variances that were themselves estimated, each with ``noise_dof`` degrees of freedom.

    A point's variance estimated from a few periodogram bins scatters (16 degrees of freedom: 35 %
    rms), so a correct model's chi^2 has a far heavier tail than the chi^2 distribution: each pair
    contributes ``2 F(2, noise_dof)``, not ``chi^2(2)``. Over 5 degrees of freedom (3 points, one
    parameter) and 16 noise degrees of freedom, chi^2 exceeds the chi^2 distribution's 99.9 %
    quantile (20.5) in 1.5 % of fits, not 0.1 %. The distribution of the sum (``dof // 2`` pairs, and
    one ``F(1, noise_dof)`` for an odd ``dof``; the fitted parameters taken from the pairs' count) is
    computed by convolution on a grid (each cell's probability shared between its edges), to within
    1 % of the probability over the range the tests use (``tests/analysis/test_chi2_exceedance.py``)."""
    grid, exceedance = _exceedance_table(max(int(dof), 1), max(int(noise_dof), 5))
    if not chi2 > 0:
        return 1.0
    if chi2 >= grid[-1]:
        return 0.0
    return float(exceedance[int(np.searchsorted(grid, chi2, side="right")) - 1])


@functools.lru_cache(maxsize=64)
def _exceedance_table(dof: int, noise_dof: int) -> tuple[np.ndarray, np.ndarray]:
    """``(grid, P(chi^2 > grid))`` of :func:`chi2_exceedance` (cached: a handful of pairs are used)."""
    from scipy.stats import f as f_distribution

    pairs, single = divmod(dof, 2)
    # noise exceeds the end of the grid with probability below _GRID_TAIL: each term's own tail
    # beyond it, shared among the terms, and the sum's body many standard deviations wide
    per_term = _GRID_TAIL / (pairs + single)
    end = 2 * f_distribution.isf(per_term, 2, noise_dof) + 4 * dof * noise_dof / (noise_dof - 2) + 50
    edges = np.linspace(0.0, end, _GRID_CELLS + 1)

    def cell_probabilities(numerator_dof: int) -> np.ndarray:
        cdf = f_distribution.cdf(edges / numerator_dof, numerator_dof, noise_dof)
        cells = np.diff(cdf)[: _GRID_CELLS - 1]
        mass = np.zeros(_GRID_CELLS)  # each cell's probability shared between its two edges
        mass[:-1] += cells / 2
        mass[1:] += cells / 2
        mass[-1] += 1.0 - cdf[_GRID_CELLS - 1]  # and what lies beyond the grid at its end
        return mass

    spectrum = np.fft.rfft(cell_probabilities(2), 2 * _GRID_CELLS) ** pairs
    if single:
        spectrum = spectrum * np.fft.rfft(cell_probabilities(1), 2 * _GRID_CELLS)
    density = np.fft.irfft(spectrum, 2 * _GRID_CELLS)[:_GRID_CELLS]
    exceedance = np.clip(1.0 - np.cumsum(np.clip(density, 0.0, None)), 0.0, 1.0)
    return edges[:_GRID_CELLS], exceedance


def chi2_far_outside_noise(chi2: float, dof: int, noise_dof: int) -> bool:
    """``chi2`` of residuals whitened by variances estimated with ``noise_dof`` degrees of freedom
    each lies far outside the noise: noise alone gives it in fewer than ``1 - OUTSIDE_NOISE_QUANTILE``
    of fits (:func:`chi2_exceedance`): the residuals are far larger than the data's stated
    uncertainty."""
    return chi2_exceedance(chi2, dof, noise_dof) < 1.0 - OUTSIDE_NOISE_QUANTILE


def chi2_beyond_noise(chi2: float, dof: int, noise_dof: int) -> bool:
    """Noise alone gives ``chi2`` less often than :data:`BEYOND_NOISE_EXCEEDANCE`: no noise explains
    the misfit (see :func:`chi2_exceedance` for the arguments)."""
    return chi2_exceedance(chi2, dof, noise_dof) < BEYOND_NOISE_EXCEEDANCE


def far_outside_noise(fit: LsqResult, noise_dof: int) -> bool:
    """The residuals are far larger than the data's stated uncertainty (estimated with ``noise_dof``
    degrees of freedom per point): the model (or something taken as known, such as a sensor or a
    mass) does not describe the data. A finding, not noise."""
    return chi2_far_outside_noise(fit.chi2, fit.n_residuals - fit.n_parameters, noise_dof)


def relative_resolution(name: str, values: Mapping[str, float]) -> float:
    """The default 'determined' threshold: a 95 % half-width of at most half the value."""
    return UNDETERMINED_RELATIVE_CI * abs(values[name])


def correlated_residual_factor(n_blocks: int, floor: float = 1.0) -> Callable[[np.ndarray], float]:
    """Covariance inflation for residuals correlated along their sequence (neighbouring frequency
    bins): ``(1 + rho) / (1 - rho)``, the ratio of all residuals to the independent ones for a
    first-order autoregressive sequence, with ``rho`` the lag-1 correlation pooled over ``n_blocks``
    equal consecutive blocks (one per FRF and real/imaginary part); at least ``floor``."""

    def factor(residuals: np.ndarray) -> float:
        blocks = residuals.reshape(n_blocks, -1)
        rho = float(np.sum(blocks[:, 1:] * blocks[:, :-1]) / max(np.sum(blocks**2), 1e-300))
        rho = min(max(rho, 0.0), 0.99)
        return max((1 + rho) / (1 - rho), floor)

    return factor


def weighted_fit(
    residuals: Callable[[Mapping[str, float]], np.ndarray],
    start: Mapping[str, float],
    bounds: Mapping[str, tuple[float, float]],
    *,
    scale: Mapping[str, float] | None = None,
    resolution: Callable[[str, Mapping[str, float]], float] = relative_resolution,
    covariance_factor: float | Callable[[np.ndarray], float] = 1.0,
    max_nfev_per_parameter: int = 200,
    jacobian: Callable[[Mapping[str, float]], np.ndarray] | None = None,
) -> LsqResult:
    """Minimise ``sum(residuals(values)^2)`` (real residuals already divided by their standard
    deviation) over the parameters of ``start`` within ``bounds``; see the module docstring.

    ``jacobian``: the derivatives of the residuals, one column per parameter in the order of
    ``start`` (unscaled units); without it the solver differentiates by finite differences,
    at ``p`` residual evaluations per Jacobian."""
    from scipy.optimize import least_squares

    names: Sequence[str] = tuple(start)
    sc = np.array([(scale or {}).get(n, abs(start[n]) or 1.0) for n in names], dtype=float)
    lo, hi = np.array([bounds[n] for n in names], dtype=float).T
    x0 = np.clip(np.array([start[n] for n in names], dtype=float), lo, hi) / sc

    def scaled(x: np.ndarray) -> np.ndarray:
        return residuals(dict(zip(names, x * sc, strict=True)))

    def scaled_jacobian(x: np.ndarray) -> np.ndarray:
        return jacobian(dict(zip(names, x * sc, strict=True))) * sc

    sol = least_squares(
        scaled,
        x0,
        jac="2-point" if jacobian is None else scaled_jacobian,
        bounds=(lo / sc, hi / sc),
        x_scale=1.0,
        max_nfev=max_nfev_per_parameter * len(names),
    )
    values = dict(zip(names, sol.x * sc, strict=True))
    chi2 = float(np.sum(sol.fun**2))
    n_res, p = sol.fun.size, len(names)
    _, sv, vt = np.linalg.svd(sol.jac, full_matrices=False)
    null = sv < sv[0] * _NULL_SPACE
    inv_sv2 = np.where(null, 0.0, 1.0 / np.where(null, 1.0, sv) ** 2)
    inflation = covariance_factor(sol.fun) if callable(covariance_factor) else covariance_factor
    cov_x = (vt.T * inv_sv2) @ vt * (chi2 / max(n_res - p, 1)) * inflation
    cov = cov_x * np.outer(sc, sc)
    half = Z95 * np.sqrt(np.diag(cov))
    in_null = np.any(np.abs(vt[null]) > 0.1, axis=0) if null.any() else np.zeros(p, bool)
    undetermined = tuple(
        n
        for i, n in enumerate(names)
        if in_null[i] or sol.active_mask[i] != 0 or half[i] > resolution(n, values)
    )
    return LsqResult(
        values=values,
        ci95=dict(zip(names, half, strict=True)),
        undetermined=undetermined,
        covariance=cov,
        chi2=chi2,
        n_residuals=n_res,
        n_parameters=p,
        converged=bool(sol.success),
    )
