"""Identification of the paper's tyre Models 1-3 from shaker-bench FRFs.

Data: the dwell FRFs ``F_wfs / Z`` and ``F_contact / Z`` (plate displacement ``Z``, plate-mass
corrected contact force) with their point uncertainties. They carry the same information as the
paper's ratio ``F_wfs / F_contact`` plus the dynamic stiffness ``F_contact / Z`` that fixes the tyre
stiffness and damping (the ratio alone does not depend on them in Model 1, and its uncertainty
explodes where the contact force nearly vanishes). The reported ratio error uses ``F_wfs/F_contact``.

Fit: bounded non-linear least squares (``scipy.optimize.least_squares``) on the real and imaginary
parts of the whitened misfit ``L^-1 (H_model - H_measured)``, parameters scaled by their start
values, with the closed forms of :mod:`bench.analysis.shaker_models` and their exact derivatives
(the Jacobian; the whitening is linear). The wheel mass (weighed) and the sensor (hammer test)
are known. Start values come from a linear least-squares fit of
``Re(F_contact/Z) = k - m_T w^2`` and ``Im(F_contact/Z) = w d + h``, never from presets; Model 3
is searched from several starts (sidewall modes across the band and above it), the best kept.

Correlated errors (:class:`ShakerErrors`): the displacement's error is shared by ``F_wfs/Z`` and
``F_contact/Z`` of one dwell (``L``: the Cholesky factor of each dwell's 2x2 complex covariance),
and m_comp's error is common to every ``F_contact/Z`` point: it is a fitted nuisance offset
``w^2 dm`` with the free run's interval as its prior, so its uncertainty reaches m_T through the
covariance instead of being averaged away as independent noise.

Uncertainty: covariance ``s^2 (J^T J)^+`` with ``s^2 = chi^2 / dof``; 95 % intervals are 1.96
standard deviations. A parameter is *not determined* when its 95 % half-width exceeds half its
value (or an absolute resolution for the rubber terms), when it ends on a bound, or when it lies
in the null space of ``J``. Models are compared by chi^2, AIC ``= chi^2 + 2 p`` and BIC
``= chi^2 + p ln n``. Model choice (:data:`MODEL_CHOICE`): the lowest BIC among the fits within
the noise with every parameter determined, else with all but Model 3's sidewall determined (a
sidewall mode just above the band: the data fix combinations of the sidewall's parameters, not
each, and Model 2 misses them by far), else the same two kinds outside the noise (BIC alone
preferred a Model 3 with four undetermined parameters, the air spring among them, whenever the
given sensor was off); a chosen fit outside the noise (noise alone gives its chi^2 in fewer than
:data:`~bench.analysis.lsq.MISFIT_FLAG_EXCEEDANCE` of fits) is a finding for the user: its
parameters may be biased beyond their intervals.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import NamedTuple, TypeVar

import numpy as np

from bench.analysis.dwell import NOISE_ESTIMATE_DOF
from bench.analysis.frf import Frf
from bench.analysis.lsq import (
    MISFIT_FLAG_EXCEEDANCE,
    OUTSIDE_NOISE_QUANTILE,
    Z95,
    FitStatistics,
    LsqResult,
    chi2_exceedance,
    far_outside_noise,
    relative_resolution,
    weighted_fit,
)
from bench.analysis.plate_mass import ShakerErrors
from bench.analysis.records import MIN_FIT_POINTS
from bench.analysis.shaker_models import (
    MODEL_PARAMETERS,
    RUBBER_PARAMETERS,
    RubberTerms,
    shaker_response,
    shaker_response_derivatives,
)
from bench.analysis.validation import AnalysisInputError
from bench.models.benches import TyreModel
from bench.models.parameters import Tyre, WfsSensor

RATE, HYST = RUBBER_PARAMETERS
#: Nuisance parameter: m_comp used for F_contact/Z minus the true m_comp (kg), with the free run's
#: interval as its prior, so that its error is common to all points instead of independent noise.
PLATE_MASS_OFFSET = "plate_mass_offset_kg"
#: Relative floor on point uncertainties (model-form and rounding), so that no point gets infinite weight.
RELATIVE_SIGMA_FLOOR = 1e-5
#: Resolution of the rubber terms (95 % half-widths above it: not determined): a stiffness rise of
#: 1 % per decade (2 % over the 0.5-70 Hz grid, the tolerance on k), a hysteretic loss of 1 % of k.
#: A stiffness rise smaller than its resolution is not worth a parameter either.
RATE_RESOLUTION = 0.01
HYST_RESOLUTION = 0.01
#: Smallest hysteretic loss worth a parameter, as a loss factor h / k (the simulated rubber's friction
#: gives 2e-3 to 7e-3 over 1-5 mm; a smaller one changes the tread peak by well under 1 %).
MIN_LOSS_FACTOR = 1e-3
#: Model 3 starts: sidewall modes at these fractions of the highest data frequency (and one above the
#: band), sidewall mass as a fraction of the wheel mass, and the ratio of its lower to upper stiffness.
SIDEWALL_START_MODES = (0.3, 0.55, 0.8, 1.0)
SIDEWALL_START_MASS_FRACTION = 0.03
SIDEWALL_START_STIFFNESS_RATIO = 30.0
#: Solver evaluations per parameter: a short search from each start, the full budget for the best.
SEARCH_BUDGET = 15
FULL_BUDGET = 200
#: Log-spaced points on which the model's ratio peak is first located (then refined by Brent's method).
PEAK_GRID_POINTS = 400


@dataclass(frozen=True)
class TyreFit(FitStatistics):
    """One model fitted to one data set.

    ``tyre``/``rubber``: the identified parameters as model objects (the known wheel mass included);
    ``lsq``: the least-squares result (its ``values``/``ci95``, ``undetermined``, ``chi2`` over
    ``n_residuals`` with ``n_parameters``, ``converged`` are also properties of the fit, without the
    nuisance offset of m_comp); ``aic``, ``bic``; ``ratio_relative_rms``: rms of
    ``|ratio_model / ratio_measured - 1|`` for ``F_wfs / F_contact`` over the reliable points, the
    measured ratio with the free run's m_comp (not moved by the fitted offset); ``n_starts``: how many start
    values the search tried (Model 3: several sidewall modes).
    """

    model: TyreModel
    tyre: Tyre
    rubber: RubberTerms
    lsq: LsqResult
    aic: float
    bic: float
    ratio_relative_rms: float
    n_starts: int = 1

    @property
    def values(self) -> dict[str, float]:
        return {n: v for n, v in self.lsq.values.items() if n != PLATE_MASS_OFFSET}

    @property
    def ci95(self) -> dict[str, float]:
        return {n: v for n, v in self.lsq.ci95.items() if n != PLATE_MASS_OFFSET}

    @property
    def undetermined(self) -> tuple[str, ...]:
        return tuple(n for n in self.lsq.undetermined if n != PLATE_MASS_OFFSET)

    @property
    def determined(self) -> bool:
        """Every parameter determined and the solver converged: a fit whose numbers can be used."""
        return not self.undetermined and self.lsq.converged

    @property
    def outside_noise(self) -> bool:
        """The fit misses the data by far more than its noise (see :func:`far_outside_noise`)."""
        return self.misfit_exceedance < 1.0 - OUTSIDE_NOISE_QUANTILE

    @property
    def misfit_exceedance(self) -> float:
        """How often noise alone gives the fit's chi^2 or more (:func:`chi2_exceedance`)."""
        lsq = self.lsq
        return chi2_exceedance(lsq.chi2, lsq.n_residuals - lsq.n_parameters, NOISE_ESTIMATE_DOF)


@dataclass(frozen=True)
class ShakerIdentification:
    """Models 1-3 fitted to one condition. ``best``: the model chosen by :data:`MODEL_CHOICE` (the
    lowest BIC overall, flagged, when no fit is of its kinds), and ``selection``: the kind that
    chose it, as reports word it;
    ``frequency_dependent_stiffness`` and ``hysteretic_damping`` say whether the data needed those
    rubber terms (chosen on Model 2, or on Model 3 when it is the best, and kept for all models);
    ``findings``: what the user must know about the chosen fit (none determined, outside its noise:
    its parameters may be biased beyond their intervals); ``tried``: every fit made on the way, by
    model and rubber terms ``(model, stiffness rise, hysteretic)`` (Model 2 with each of the four
    combinations among them)."""

    fits: dict[TyreModel, TyreFit]
    best: TyreModel
    frequency_dependent_stiffness: bool
    hysteretic_damping: bool
    selection: str
    findings: tuple[str, ...] = ()
    tried: dict[tuple[TyreModel, bool, bool], TyreFit] = field(default_factory=dict)

    @property
    def best_fit(self) -> TyreFit:
        return self.fits[self.best]


@dataclass(frozen=True)
class _Data:
    """Reliable points, and the whitening of each dwell's pair of errors ``(e_wfs, e_contact)``:
    their 2x2 complex covariance ``C = L L^H`` with ``L = [[l11, 0], [l21, l22]]``."""

    w: np.ndarray
    freq_hz: np.ndarray
    h_wfs: np.ndarray
    h_contact: np.ndarray
    l11: np.ndarray
    l21: np.ndarray
    l22: np.ndarray
    plate_mass_sigma_kg: float

    def whitened(self, wfs: np.ndarray, contact: np.ndarray) -> np.ndarray:
        """Real residuals of unit variance: ``L^-1 (model - data)``, real and imaginary parts."""
        y1 = (wfs - self.h_wfs) / self.l11
        y2 = (contact - self.h_contact - self.l21 * y1) / self.l22
        r = np.concatenate([y1, y2]) * np.sqrt(2.0)
        return np.concatenate([r.real, r.imag])

    def whitened_derivative(self, d_wfs: np.ndarray, d_contact: np.ndarray) -> np.ndarray:
        """The derivatives of :meth:`whitened` for model derivatives with one row per parameter:
        ``L^-1`` applied to them (the data drop out), one row per parameter."""
        y1 = d_wfs / self.l11
        y2 = (d_contact - self.l21 * y1) / self.l22
        r = np.concatenate([y1, y2], axis=1) * np.sqrt(2.0)
        return np.concatenate([r.real, r.imag], axis=1)


def _data(wfs_per_z: Frf, contact_per_z: Frf, errors: ShakerErrors | None) -> _Data:
    if wfs_per_z.freq_hz.shape != contact_per_z.freq_hz.shape or np.any(
        wfs_per_z.freq_hz != contact_per_z.freq_hz
    ):
        raise AnalysisInputError("F_wfs/Z and F_contact/Z must share their frequencies")
    use = wfs_per_z.reliable & contact_per_z.reliable
    if use.sum() < MIN_FIT_POINTS:
        raise AnalysisInputError(
            f"only {int(use.sum())} reliable FRF points; at least {MIN_FIT_POINTS} needed"
        )
    f = wfs_per_z.freq_hz[use]
    h_w, h_c = wfs_per_z.value[use], contact_per_z.value[use]
    if errors is None:  # independent points: the FRFs' own sigmas
        s_w, s_c, rel_z, sigma_m = wfs_per_z.sigma[use], contact_per_z.sigma[use], np.zeros(f.size), 0.0
        h_p = h_c
    else:
        s_w, s_c = errors.wfs_sigma[use], errors.plate_sigma[use]
        rel_z, sigma_m = errors.displacement_relative_sigma[use], errors.plate_mass_sigma_kg
        h_p = h_c - errors.plate_mass_kg * (2 * np.pi * f) ** 2  # F_shaker / Z
    var_w = s_w**2 + (RELATIVE_SIGMA_FLOOR * np.abs(h_w)) ** 2 + (np.abs(h_w) * rel_z) ** 2
    var_c = s_c**2 + (RELATIVE_SIGMA_FLOOR * np.abs(h_c)) ** 2 + (np.abs(h_p) * rel_z) ** 2
    cov_cw = h_p * np.conj(h_w) * rel_z**2  # d(F/Z) = dF/Z - (F/Z) dZ/Z: one dZ for both
    dead = (var_w <= 0) | (var_c <= 0)
    if dead.any():
        raise AnalysisInputError(
            f"F_wfs/Z or F_contact/Z is exactly zero with zero uncertainty at {f[dead].tolist()} Hz:"
            " a dead or frozen channel"
        )
    l11 = np.sqrt(var_w)
    l21 = cov_cw / l11
    l22 = np.sqrt(np.maximum(var_c - np.abs(l21) ** 2, 1e-30 * var_c))
    return _Data(2 * np.pi * f, f, h_w, h_c, l11, l21, l22, float(sigma_m))


@dataclass(frozen=True)
class _Misfit:
    """The whitened misfit of one model to the data as a function of the fitted values (names of
    :data:`MODEL_PARAMETERS`, the rubber terms and :data:`PLATE_MASS_OFFSET`), and its Jacobian."""

    model: TyreModel
    data: _Data
    sensor: WfsSensor
    wheel_mass_kg: float

    def residuals(self, values: Mapping[str, float]) -> np.ndarray:
        data = self.data
        tyre, rubber = _model_objects(self.model, values, self.wheel_mass_kg)
        wfs, contact = shaker_response(self.model, tyre, self.sensor, data.freq_hz, rubber)
        if data.plate_mass_sigma_kg == 0:
            return data.whitened(wfs, contact)
        # the measured F_contact/Z holds w^2 (m_comp,used - m_comp,true); its prior: the free run
        offset = values[PLATE_MASS_OFFSET]
        return np.append(data.whitened(wfs, contact + data.w**2 * offset), offset / data.plate_mass_sigma_kg)

    def jacobian(self, values: Mapping[str, float]) -> np.ndarray:
        """``d residuals / d values``, one column per value: the whitening is linear, so it maps the
        model's exact derivatives; the offset moves F_contact/Z by ``w^2`` and its prior by
        ``1 / sigma_m``."""
        data = self.data
        tyre, rubber = _model_objects(self.model, values, self.wheel_mass_kg)
        names = tuple(values)
        physical = [i for i, n in enumerate(names) if n != PLATE_MASS_OFFSET]
        d_wfs = np.zeros((len(names), data.w.size), complex)
        d_contact = np.zeros((len(names), data.w.size), complex)
        *_, d_wfs[physical], d_contact[physical] = shaker_response_derivatives(
            self.model, tyre, self.sensor, data.freq_hz, rubber, names=tuple(names[i] for i in physical)
        )
        if data.plate_mass_sigma_kg == 0:
            return data.whitened_derivative(d_wfs, d_contact).T
        offset = names.index(PLATE_MASS_OFFSET)
        d_contact[offset] = data.w**2
        prior = np.zeros((1, len(names)))
        prior[0, offset] = 1 / data.plate_mass_sigma_kg
        return np.vstack([data.whitened_derivative(d_wfs, d_contact).T, prior])


def _start_values(data: _Data, model: TyreModel, names: tuple[str, ...], wheel_mass_kg: float) -> dict:
    """Linear least squares on the dynamic stiffness F_contact/Z (weighted by its uncertainty)."""
    n = data.w.size
    hc, sc = data.h_contact, np.hypot(np.abs(data.l21), data.l22)
    w = data.w
    re_cols = [np.ones(n)] + ([-(w**2)] if model is not TyreModel.WHEEL else [])
    im_cols = [w, np.ones(n)] if HYST in names else [w]
    re = np.linalg.lstsq(np.stack(re_cols, 1) / sc[:, None], hc.real / sc, rcond=None)[0]
    im = np.linalg.lstsq(np.stack(im_cols, 1) / sc[:, None], hc.imag / sc, rcond=None)[0]
    k = max(re[0], 1e3)
    start = {"stiffness_n_per_m": k, "damping_ns_per_m": max(im[0], 1.0)}
    if model is not TyreModel.WHEEL:
        start["tread_mass_kg"] = float(np.clip(re[1], 0.01 * wheel_mass_kg, 0.5 * wheel_mass_kg))
    if RATE in names:
        start[RATE] = 0.0
    if HYST in names:
        start[HYST] = max(im[1], 0.0)
    if data.plate_mass_sigma_kg > 0:
        start[PLATE_MASS_OFFSET] = 0.0
    return start


def _sidewall_starts(start: dict, wheel_mass_kg: float, top_hz: float) -> list[dict]:
    """Model 3 start values: one per sidewall mode ``sqrt((L + U) / m_sw)`` tried, first one above
    the band (close to Model 2), then modes inside the band: from the first alone the fit stops in
    a local minimum when the mode lies in the band. A light sidewall, stiff towards the tread
    (``L = 30 U``); the air spring keeps the static stiffness of the linear start."""
    k = start["stiffness_n_per_m"]
    m_sw = SIDEWALL_START_MASS_FRACTION * wheel_mass_kg
    modes_hz = [np.sqrt(3.1 * k / m_sw) / (2 * np.pi)] + [f * top_hz for f in SIDEWALL_START_MODES]
    starts = []
    for mode_hz in modes_hz:
        total = m_sw * (2 * np.pi * mode_hz) ** 2
        upper = total / (1 + SIDEWALL_START_STIFFNESS_RATIO)
        lower = total - upper
        air = k - lower * upper / total
        if air > 0.05 * k:
            starts.append(
                {
                    **start,
                    "stiffness_n_per_m": air,
                    "sidewall_mass_kg": m_sw,
                    "sidewall_lower_stiffness_n_per_m": lower,
                    "sidewall_upper_stiffness_n_per_m": upper,
                }
            )
    return starts


def _bounds(name: str, wheel_mass_kg: float, k: float) -> tuple[float, float]:
    return {
        "stiffness_n_per_m": (1e3, 1e8),
        "damping_ns_per_m": (0.0, 1e5),
        "tread_mass_kg": (0.0, 0.6 * wheel_mass_kg),
        "sidewall_mass_kg": (0.0, 0.3 * wheel_mass_kg),
        "sidewall_lower_stiffness_n_per_m": (1e2, 1e9),
        "sidewall_upper_stiffness_n_per_m": (1e2, 1e9),
        RATE: (-0.3, 0.5),
        HYST: (0.0, 2.0 * k),
        PLATE_MASS_OFFSET: (-np.inf, np.inf),
    }[name]


def _resolution(name: str, values: Mapping[str, float]) -> float:
    """Half-width of the 95 % interval above which a parameter counts as not determined."""
    if name == RATE:
        return RATE_RESOLUTION
    if name == HYST:
        return max(relative_resolution(name, values), HYST_RESOLUTION * values["stiffness_n_per_m"])
    if name == PLATE_MASS_OFFSET:
        return np.inf  # a nuisance: its prior is the free run's interval
    return relative_resolution(name, values)


def _model_objects(
    model: TyreModel, values: Mapping[str, float], wheel_mass_kg: float
) -> tuple[Tyre, RubberTerms]:
    tyre_kw = {k: v for k, v in values.items() if k not in (RATE, HYST, PLATE_MASS_OFFSET)}
    tyre_kw.setdefault("tread_mass_kg", 0.0)
    tyre_kw.setdefault("sidewall_mass_kg", 0.0)
    tyre = Tyre(wheel_mass_kg=wheel_mass_kg, **tyre_kw)
    return tyre, RubberTerms(values.get(RATE, 0.0), values.get(HYST, 0.0))


def fit_tyre_model(
    model: TyreModel,
    wfs_per_z: Frf,
    contact_per_z: Frf,
    *,
    wheel_mass_kg: float,
    sensor: WfsSensor,
    stiffness_rise: bool = False,
    hysteretic: bool = False,
    errors: ShakerErrors | None = None,
    near: Mapping[str, float] | None = None,
) -> TyreFit:
    """Fit one model (optionally with the rubber terms) to shaker FRFs; see the module docstring.
    ``errors``: the errors the points share (propagated); ``None`` takes the points as independent.
    ``near``: the values of a fit of the same model with other rubber terms, the one start of the
    search (a rubber term it lacks starts at the linear start's value): the other terms move a
    fit little, so the search from the sidewall starts need not be made again."""
    model = TyreModel(model)
    data = _data(wfs_per_z, contact_per_z, errors)
    names = MODEL_PARAMETERS[model] + ((RATE,) if stiffness_rise else ()) + ((HYST,) if hysteretic else ())
    linear_start = _start_values(data, model, names, wheel_mass_kg)
    k0 = linear_start["stiffness_n_per_m"]
    if near is not None:
        starts = [
            {n: near[n] if n in near else linear_start[n] for n in dict.fromkeys((*names, *linear_start))}
        ]
    elif model is TyreModel.WHEEL_TREAD_SIDEWALL:
        starts = _sidewall_starts(linear_start, wheel_mass_kg, float(data.freq_hz[-1]))
    else:
        starts = [linear_start]
    sigma_m = data.plate_mass_sigma_kg

    misfit = _Misfit(model, data, sensor, wheel_mass_kg)

    def scale_of(start: dict) -> dict:
        small = {RATE: 0.01, PLATE_MASS_OFFSET: sigma_m}
        return {n: abs(v) if abs(v) > 0 else small.get(n, 0.01 * k0) for n, v in start.items()}

    def solve(start: dict, budget: int) -> LsqResult:
        return weighted_fit(
            misfit.residuals,
            start,
            {n: _bounds(n, wheel_mass_kg, k0) for n in start},
            scale=scale_of(start),
            resolution=_resolution,
            max_nfev_per_parameter=budget,
            jacobian=misfit.jacobian,
        )

    fit = solve(starts[0], FULL_BUDGET)
    if len(starts) > 1 and far_outside_noise(fit, NOISE_ESTIMATE_DOF):
        # the first start stopped far from the data: a short search from the others, the best
        # of them to convergence, kept if it does better
        found = min((solve(s, SEARCH_BUDGET) for s in starts[1:]), key=lambda f: f.chi2)
        fit = min(fit, solve(found.values, FULL_BUDGET), key=lambda f: f.chi2)
    tyre, rubber = _model_objects(model, fit.values, wheel_mass_kg)
    wfs, contact = shaker_response(model, tyre, sensor, data.freq_hz, rubber)
    # against the measured ratio (m_comp of the free run), not one corrected by the fitted offset:
    # the offset can carry a tread mass, and the figure would then measure the fit against itself
    ratio_rel = np.abs((wfs / contact) / (data.h_wfs / data.h_contact) - 1)
    p, n_res = fit.n_parameters, fit.n_residuals
    return TyreFit(
        model=model,
        tyre=tyre,
        rubber=rubber,
        lsq=fit,
        aic=fit.chi2 + 2 * p,
        bic=fit.chi2 + p * np.log(n_res),
        ratio_relative_rms=float(np.sqrt(np.mean(ratio_rel**2))),
        n_starts=len(starts),
    )


def _rubber_terms_relevant(fit: TyreFit) -> bool:
    """Every rubber term of the fit is determined and large enough to matter: a stiffness rise of
    at least ``RATE_RESOLUTION`` per decade, a hysteretic loss of at least ``MIN_LOSS_FACTOR`` k.
    A smaller term only absorbs a model error (a wrong sensor bends F_wfs/Z as a slight rise would)."""
    if any(n in fit.undetermined for n in (RATE, HYST)):
        return False
    rate_ok = RATE not in fit.values or abs(fit.values[RATE]) >= RATE_RESOLUTION
    hyst_ok = HYST not in fit.values or fit.values[HYST] >= MIN_LOSS_FACTOR * fit.values["stiffness_n_per_m"]
    return rate_ok and hyst_ok


_Key = TypeVar("_Key")


def _within_noise(fit: TyreFit) -> bool:
    """The fit converged and describes the data within their noise (not far outside it)."""
    return fit.lsq.converged and not fit.outside_noise


#: Model 3's own parameters: those of the sidewall, which a sidewall mode above the band leaves
#: partly unseen.
SIDEWALL_PARAMETERS = tuple(
    n
    for n in MODEL_PARAMETERS[TyreModel.WHEEL_TREAD_SIDEWALL]
    if n not in MODEL_PARAMETERS[TyreModel.WHEEL_TREAD]
)


def _tyre_determined(fit: TyreFit) -> bool:
    """Every parameter but the sidewall's determined, the solver converged: a Model 3 whose
    sidewall mode lies above the band sees only the mode's low-frequency side, which fixes some
    combinations of the sidewall's mass and stiffnesses and not each of them (the tyre's stiffness,
    damping and tread mass must be determined: a Model 3 that absorbs a wrong sensor has its air
    spring undetermined)."""
    return fit.lsq.converged and set(fit.undetermined) <= set(SIDEWALL_PARAMETERS)


#: The model choice, in order of preference, with how reports word each: the lowest BIC among the
#: fits of the first kind that any fit is. A Model 3 whose sidewall is not determined comes before
#: determined models farther from the data (Model 2 missing a sidewall mode just above the band).
MODEL_CHOICE: tuple[tuple[Callable[[TyreFit], bool], str], ...] = (
    (lambda f: f.determined and _within_noise(f), "lowest BIC with every parameter determined"),
    (
        lambda f: _tyre_determined(f) and _within_noise(f),
        "lowest BIC within the noise, the sidewall not determined; no model with every parameter"
        " determined lies within the noise",
    ),
    (lambda f: f.determined, "lowest BIC with every parameter determined; none within the noise"),
    (_tyre_determined, "lowest BIC with the sidewall not determined; none within the noise"),
)
#: When no fit is of any kind of :data:`MODEL_CHOICE`.
LOWEST_BIC = "lowest BIC; no model has every parameter determined"


def _choose(
    fits: Mapping[_Key, TyreFit], kinds: tuple[tuple[Callable[[TyreFit], bool], str], ...]
) -> tuple[_Key, str]:
    """The key of the lowest-BIC fit of the first kind (a predicate) that any fit is (the lowest
    overall if none), and the wording of that kind."""
    for keep, wording in kinds:
        accepted = [key for key, fit in fits.items() if keep(fit)]
        if accepted:
            return min(accepted, key=lambda key: fits[key].bic), wording
    return min(fits, key=lambda key: fits[key].bic), LOWEST_BIC


def identify_shaker(
    wfs_per_z: Frf,
    contact_per_z: Frf,
    *,
    wheel_mass_kg: float,
    sensor: WfsSensor,
    errors: ShakerErrors | None = None,
) -> ShakerIdentification:
    """Fit Models 1-3 and choose one by :data:`MODEL_CHOICE` (see the module docstring).

    The rubber terms are chosen on Model 2, by the same rules, among the variants whose terms are
    determined and large enough to matter; Models 1 and 3 are fitted with them. When Model 3 is
    chosen, or Model 2 lies far outside the noise (a Model 2 far from the data is no judge of
    them), the rubber terms are chosen again on Model 3's variants and kept when with them Model 3
    is the choice.
    """
    tried: dict[tuple[TyreModel, bool, bool], TyreFit] = {}

    def fit(model: TyreModel, rate: bool, hyst: bool, near: Mapping[str, float] | None = None) -> TyreFit:
        """Each model and rubber-term variant is fitted once (``near``: see :func:`fit_tyre_model`)."""
        if (model, rate, hyst) not in tried:
            tried[(model, rate, hyst)] = fit_tyre_model(
                model,
                wfs_per_z,
                contact_per_z,
                wheel_mass_kg=wheel_mass_kg,
                sensor=sensor,
                stiffness_rise=rate,
                hysteretic=hyst,
                errors=errors,
                near=near,
            )
        return tried[(model, rate, hyst)]

    def variants(
        model: TyreModel, near: Mapping[str, float] | None = None
    ) -> dict[tuple[bool, bool], TyreFit]:
        return {(r, h): fit(model, r, h, near) for r in (False, True) for h in (False, True)}

    def rubber_choice(fits: dict[tuple[bool, bool], TyreFit]) -> tuple[bool, bool]:
        """The variant chosen as models are, among those whose rubber terms are relevant (the
        variant without them always is)."""
        return _choose({k: f for k, f in fits.items() if _rubber_terms_relevant(f)}, MODEL_CHOICE)[0]

    def fits_with(terms: tuple[bool, bool]) -> dict[TyreModel, TyreFit]:
        return {model: fit(model, *terms) for model in TyreModel}

    terms = rubber_choice(variants(TyreModel.WHEEL_TREAD))
    fits = fits_with(terms)
    best, selection = _choose(fits, MODEL_CHOICE)
    if best is TyreModel.WHEEL_TREAD_SIDEWALL or all(
        fits[model].outside_noise for model in (TyreModel.WHEEL_TREAD, TyreModel.WHEEL_TREAD_SIDEWALL)
    ):
        # Model 3 judges the rubber terms when it is chosen, or when neither Model 2 nor Model 3
        # with Model 2's terms is within the noise (a Model 2 far from the data is no judge of them:
        # a sidewall mode just above the band, fitted without the loss the rubber needs, ended in a
        # local minimum with an undetermined sidewall, and the flagged Model 2 was chosen); each
        # variant starts from that Model 3, and the terms are kept if they make Model 3 the choice
        m3_terms = rubber_choice(
            variants(TyreModel.WHEEL_TREAD_SIDEWALL, fits[TyreModel.WHEEL_TREAD_SIDEWALL].values)
        )
        m3_fits = fits_with(m3_terms)
        m3_best, m3_selection = _choose(m3_fits, MODEL_CHOICE)
        if TyreModel.WHEEL_TREAD_SIDEWALL in (best, m3_best):
            terms, fits, best, selection = m3_terms, m3_fits, m3_best, m3_selection
    rate, hyst = terms
    chosen = fits[best]
    findings = []
    if selection == LOWEST_BIC:
        findings.append(
            f"no model has every parameter determined; Model {int(best)} (lowest BIC) is shown"
            f" with {', '.join(chosen.undetermined) or 'a fit that did not converge'}"
        )
    if (exceedance := chosen.misfit_exceedance) < MISFIT_FLAG_EXCEEDANCE:
        findings.append(
            f"Model {int(best)} misses the data {'far ' if chosen.outside_noise else ''}outside its"
            f" noise (reduced chi^2 {chosen.reduced_chi2:.3g}; noise alone gives that in"
            f" {_share(exceedance)} of fits): a value taken as known (the sensor, the wheel mass,"
            " m_comp) may be wrong, or the tyre is not one of Models 1-3 (a non-linear tyre); its"
            " parameters may be biased beyond their 95 % intervals, which hold the noise alone"
        )
    return ShakerIdentification(
        dict(sorted(fits.items())), best, rate, hyst, selection, tuple(findings), tried
    )


def _share(probability: float) -> str:
    """A small probability as a percentage: ``0.348 %``, ``4.3e-04 %``, ``fewer than 1e-08 %``
    (:func:`chi2_exceedance` computes none smaller than 1e-10)."""
    if probability <= 0:
        return "fewer than 1e-08 %"
    percent = 100 * probability
    return f"{percent:.3g} %" if percent >= 0.01 else f"{percent:.1e} %"


@dataclass(frozen=True)
class AmplitudeDependence:
    """Model-2 parameters fitted per excitation amplitude (ascending), and their change against the
    smallest amplitude. ``equivalent_damping_ns_per_m`` is ``d + h / w`` at each fit's tread
    resonance ``sqrt(k / m_T)``, the damping that sets the peak of ``F_wfs / F_contact``."""

    amplitude_m: np.ndarray
    fits: tuple[TyreFit, ...]
    stiffness_n_per_m: np.ndarray
    stiffness_ci95_n_per_m: np.ndarray
    equivalent_damping_ns_per_m: np.ndarray
    tread_mass_kg: np.ndarray
    stiffness_change: np.ndarray
    damping_change: np.ndarray

    def rows(self) -> Iterator[AmplitudeRow]:
        """One row per amplitude, ascending."""
        for columns in zip(
            self.amplitude_m,
            self.stiffness_n_per_m,
            self.stiffness_ci95_n_per_m,
            self.stiffness_change,
            self.equivalent_damping_ns_per_m,
            self.damping_change,
            strict=True,
        ):
            yield AmplitudeRow(*(float(c) for c in columns))


class AmplitudeRow(NamedTuple):
    """:class:`AmplitudeDependence` at one amplitude."""

    amplitude_m: float
    stiffness_n_per_m: float
    stiffness_ci95_n_per_m: float
    stiffness_change: float
    equivalent_damping_ns_per_m: float
    damping_change: float


def tread_resonance_hz(fit: TyreFit) -> float:
    """``sqrt(k / m_T) / 2 pi`` of a fit with a tread mass (the peak of ``F_wfs / F_contact``)."""
    if fit.tyre.tread_mass_kg <= 0:
        raise AnalysisInputError("a model without tread mass has no tread resonance")
    return float(np.sqrt(fit.tyre.stiffness_n_per_m / fit.tyre.tread_mass_kg) / (2 * np.pi))


def amplitude_dependence(
    per_amplitude: Mapping[float, tuple[Frf, Frf]],
    *,
    wheel_mass_kg: float,
    sensor: WfsSensor,
    stiffness_rise: bool,
    hysteretic: bool,
    errors: Mapping[float, ShakerErrors] | None = None,
) -> AmplitudeDependence:
    """Fit Model 2 to each amplitude's ``(F_wfs/Z, F_contact/Z)`` and tabulate k and damping;
    ``errors``: each amplitude's shared errors (propagated), ``None`` for independent points."""
    return tabulate_amplitude_dependence(
        {
            a: fit_tyre_model(
                TyreModel.WHEEL_TREAD,
                *frfs,
                wheel_mass_kg=wheel_mass_kg,
                sensor=sensor,
                stiffness_rise=stiffness_rise,
                hysteretic=hysteretic,
                errors=None if errors is None else errors[a],
            )
            for a, frfs in per_amplitude.items()
        }
    )


def tabulate_amplitude_dependence(model2_fits: Mapping[float, TyreFit]) -> AmplitudeDependence:
    """:class:`AmplitudeDependence` of Model-2 fits already made, by amplitude (m), with the same
    rubber terms (for instance those :func:`identify_shaker` tried on each amplitude)."""
    amps = sorted(model2_fits)
    fits = tuple(model2_fits[a] for a in amps)
    if any(f.model is not TyreModel.WHEEL_TREAD for f in fits):
        raise AnalysisInputError("the amplitude dependence tabulates Model 2 fits only")
    k = np.array([f.tyre.stiffness_n_per_m for f in fits])
    d = np.array([float(f.rubber.equivalent_damping_ns_per_m(f.tyre, tread_resonance_hz(f))) for f in fits])
    return AmplitudeDependence(
        amplitude_m=np.array(amps, dtype=float),
        fits=fits,
        stiffness_n_per_m=k,
        stiffness_ci95_n_per_m=np.array([f.ci95["stiffness_n_per_m"] for f in fits]),
        equivalent_damping_ns_per_m=d,
        tread_mass_kg=np.array([f.tyre.tread_mass_kg for f in fits]),
        stiffness_change=k / k[0] - 1,
        damping_change=d / d[0] - 1,
    )


@dataclass(frozen=True)
class RatioPeak:
    """The peak of ``|F_wfs / F_contact|`` of an identified model: ``freq_hz`` and ``height`` with
    their 95 % half-widths (the fit's covariance propagated). A dwell grid can miss the peak: its
    largest measured point is only a lower bound."""

    freq_hz: float
    freq_ci95_hz: float
    height: float
    height_ci95: float


def _peak(
    model: TyreModel,
    values: Mapping[str, float],
    wheel_mass_kg: float,
    sensor: WfsSensor,
    band: tuple[float, float],
) -> tuple[float, float]:
    """Frequency and height of the largest ``|F_wfs / F_contact|`` of the model in ``band``."""
    from scipy.optimize import minimize_scalar

    tyre, rubber = _model_objects(model, values, wheel_mass_kg)

    def magnitude(f_hz: float | np.ndarray) -> np.ndarray:
        wfs, contact = shaker_response(model, tyre, sensor, np.atleast_1d(f_hz), rubber)
        return np.abs(wfs / contact)

    grid = np.geomspace(band[0], band[1], PEAK_GRID_POINTS)
    i = int(np.argmax(magnitude(grid)))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    best = minimize_scalar(
        lambda f: -magnitude(f)[0], bounds=(lo, hi), method="bounded", options={"xatol": 1e-9 * hi}
    )
    return float(best.x), float(-best.fun)


def ratio_peak(fit: TyreFit, sensor: WfsSensor, band_hz: tuple[float, float]) -> RatioPeak:
    """Peak of the model's ``|F_wfs / F_contact|`` in ``band_hz`` (see :class:`RatioPeak`); 95 %
    half-widths ``1.96 sqrt(g^T C g)`` with ``g`` the central-difference gradient over the fitted
    parameters."""
    names = [n for n in fit.lsq.values if n != PLATE_MASS_OFFSET]
    index = [list(fit.lsq.values).index(n) for n in names]
    cov = fit.lsq.covariance[np.ix_(index, index)]
    wheel = fit.tyre.wheel_mass_kg
    f0, h0 = _peak(fit.model, fit.lsq.values, wheel, sensor, band_hz)
    grad = np.zeros((2, len(names)))
    for j, name in enumerate(names):
        step = 1e-4 * abs(fit.lsq.values[name]) or 1e-6
        up = _peak(fit.model, {**fit.lsq.values, name: fit.lsq.values[name] + step}, wheel, sensor, band_hz)
        down = _peak(fit.model, {**fit.lsq.values, name: fit.lsq.values[name] - step}, wheel, sensor, band_hz)
        grad[:, j] = (np.array(up) - np.array(down)) / (2 * step)
    half = Z95 * np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", grad, cov, grad), 0.0))
    return RatioPeak(f0, float(half[0]), h0, float(half[1]))
