"""Identification of the paper's tyre Models 1-3 from shaker-bench FRFs.

Data: the dwell FRFs ``F_wfs / Z`` and ``F_contact / Z`` (plate displacement ``Z``, plate-mass
corrected contact force) with their point uncertainties. They carry the same information as the
paper's ratio ``F_wfs / F_contact`` plus the dynamic stiffness ``F_contact / Z`` that fixes the tyre
stiffness and damping (the ratio alone does not depend on them in Model 1, and its uncertainty
explodes where the contact force nearly vanishes). The reported ratio error uses ``F_wfs/F_contact``.

Fit: bounded non-linear least squares (``scipy.optimize.least_squares``) on the real and imaginary
parts of ``(H_model - H_measured) / sigma``, parameters scaled by their start values, with the
closed forms of :mod:`bench.analysis.shaker_models`. The wheel mass (weighed) and the sensor (hammer
test) are known. Start values come from a linear least-squares fit of
``Re(F_contact/Z) = k - m_T w^2`` and ``Im(F_contact/Z) = w d + h``, never from presets.

Uncertainty: covariance ``s^2 (J^T J)^+`` with ``s^2 = chi^2 / dof``; 95 % intervals are 1.96
standard deviations. A parameter is *not determined* when its 95 % half-width exceeds half its
value (or an absolute resolution for the rubber terms), when it ends on a bound, or when it lies
in the null space of ``J``. Models are compared by chi^2, AIC ``= chi^2 + 2 p`` and BIC
``= chi^2 + p ln n``; the lowest BIC is the model the data supports.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from bench.analysis.frf import Frf
from bench.analysis.lsq import relative_resolution, weighted_fit
from bench.analysis.shaker_models import RubberTerms, shaker_response
from bench.analysis.validation import AnalysisInputError
from bench.models.benches import TyreModel
from bench.models.parameters import Tyre, WfsSensor

TYRE_PARAMETERS: dict[TyreModel, tuple[str, ...]] = {
    TyreModel.WHEEL: ("stiffness_n_per_m", "damping_ns_per_m"),
    TyreModel.WHEEL_TREAD: ("stiffness_n_per_m", "damping_ns_per_m", "tread_mass_kg"),
    TyreModel.WHEEL_TREAD_SIDEWALL: (
        "stiffness_n_per_m",
        "damping_ns_per_m",
        "tread_mass_kg",
        "sidewall_mass_kg",
        "sidewall_lower_stiffness_n_per_m",
        "sidewall_upper_stiffness_n_per_m",
    ),
}
RATE, HYST = "stiffness_rise_per_decade", "hysteretic_damping_n_per_m"
#: Relative floor on point uncertainties (model-form and rounding), so that no point gets infinite weight.
RELATIVE_SIGMA_FLOOR = 1e-4


@dataclass(frozen=True)
class TyreFit:
    """One model fitted to one data set.

    ``tyre``/``rubber``: the identified parameters as model objects (the known wheel mass included);
    ``values``/``ci95``: fitted parameters and their 95 % half-widths, by name with units;
    ``undetermined``: parameters the data does not determine; ``chi2`` over ``n_residuals`` real
    residuals with ``n_parameters`` parameters, ``aic``, ``bic``; ``ratio_relative_rms``: rms of
    ``|ratio_model / ratio_measured - 1|`` for ``F_wfs / F_contact``; ``converged``: the solver's verdict.
    """

    model: TyreModel
    tyre: Tyre
    rubber: RubberTerms
    values: dict[str, float]
    ci95: dict[str, float]
    undetermined: tuple[str, ...]
    chi2: float
    n_residuals: int
    n_parameters: int
    aic: float
    bic: float
    ratio_relative_rms: float
    converged: bool

    @property
    def reduced_chi2(self) -> float:
        return self.chi2 / max(self.n_residuals - self.n_parameters, 1)


@dataclass(frozen=True)
class ShakerIdentification:
    """Models 1-3 fitted to one condition; ``best`` has the lowest BIC. ``frequency_dependent_stiffness``
    and ``hysteretic_damping`` say whether the data needed those rubber terms (chosen by BIC on
    Model 2 and kept for all models)."""

    fits: dict[TyreModel, TyreFit]
    best: TyreModel
    frequency_dependent_stiffness: bool
    hysteretic_damping: bool

    @property
    def best_fit(self) -> TyreFit:
        return self.fits[self.best]


@dataclass(frozen=True)
class _Data:
    w: np.ndarray
    freq_hz: np.ndarray
    h: np.ndarray  # stacked [wfs; contact]
    sigma: np.ndarray


def _data(wfs_per_z: Frf, contact_per_z: Frf) -> _Data:
    if wfs_per_z.freq_hz.shape != contact_per_z.freq_hz.shape or np.any(
        wfs_per_z.freq_hz != contact_per_z.freq_hz
    ):
        raise AnalysisInputError("F_wfs/Z and F_contact/Z must share their frequencies")
    use = wfs_per_z.reliable & contact_per_z.reliable
    if use.sum() < 4:
        raise AnalysisInputError(f"only {int(use.sum())} reliable FRF points; at least 4 needed")
    f = wfs_per_z.freq_hz[use]
    h = np.concatenate([wfs_per_z.value[use], contact_per_z.value[use]])
    s = np.concatenate([wfs_per_z.sigma[use], contact_per_z.sigma[use]])
    s = np.sqrt(s**2 + (RELATIVE_SIGMA_FLOOR * np.abs(h)) ** 2)
    return _Data(2 * np.pi * f, f, h, s)


def _start_values(data: _Data, model: TyreModel, names: tuple[str, ...], wheel_mass_kg: float) -> dict:
    """Linear least squares on the dynamic stiffness F_contact/Z (weighted by its uncertainty)."""
    n = data.w.size
    hc, sc = data.h[n:], data.sigma[n:]
    w = data.w
    re_cols = [np.ones(n)] + ([-(w**2)] if model is not TyreModel.WHEEL else [])
    im_cols = [w, np.ones(n)] if HYST in names else [w]
    re = np.linalg.lstsq(np.stack(re_cols, 1) / sc[:, None], hc.real / sc, rcond=None)[0]
    im = np.linalg.lstsq(np.stack(im_cols, 1) / sc[:, None], hc.imag / sc, rcond=None)[0]
    k = max(re[0], 1e3)
    start = {"stiffness_n_per_m": k, "damping_ns_per_m": max(im[0], 1.0)}
    if model is not TyreModel.WHEEL:
        start["tread_mass_kg"] = float(np.clip(re[1], 0.01 * wheel_mass_kg, 0.5 * wheel_mass_kg))
    if model is TyreModel.WHEEL_TREAD_SIDEWALL:
        # A light sidewall, stiff towards the tread and soft towards the rim, keeps the start close to
        # Model 2; the data decides whether they move (often it cannot: "not determined").
        start["sidewall_mass_kg"] = 0.03 * wheel_mass_kg
        start["sidewall_lower_stiffness_n_per_m"] = 3.0 * k
        start["sidewall_upper_stiffness_n_per_m"] = 0.1 * k
        start["stiffness_n_per_m"] = k - 0.1 * k * 3.0 / 3.1
    if RATE in names:
        start[RATE] = 0.0
    if HYST in names:
        start[HYST] = max(im[1], 0.0)
    return start


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
    }[name]


def _resolution(name: str, values: Mapping[str, float]) -> float:
    """Half-width of the 95 % interval above which a parameter counts as not determined."""
    if name == RATE:
        return 0.01
    if name == HYST:
        return max(relative_resolution(name, values), 0.01 * values["stiffness_n_per_m"])
    return relative_resolution(name, values)


def _model_objects(
    model: TyreModel, values: Mapping[str, float], wheel_mass_kg: float
) -> tuple[Tyre, RubberTerms]:
    tyre_kw = {k: v for k, v in values.items() if k not in (RATE, HYST)}
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
) -> TyreFit:
    """Fit one model (optionally with the rubber terms) to shaker FRFs; see the module docstring."""
    model = TyreModel(model)
    data = _data(wfs_per_z, contact_per_z)
    names = TYRE_PARAMETERS[model] + ((RATE,) if stiffness_rise else ()) + ((HYST,) if hysteretic else ())
    start = _start_values(data, model, names, wheel_mass_kg)
    k0 = start["stiffness_n_per_m"]
    scale = {n: abs(start[n]) if abs(start[n]) > 0 else (0.01 if n == RATE else 0.01 * k0) for n in names}
    n_pts = data.w.size

    def residuals(values: Mapping[str, float]) -> np.ndarray:
        tyre, rubber = _model_objects(model, values, wheel_mass_kg)
        wfs, contact = shaker_response(model, tyre, sensor, data.freq_hz, rubber)
        r = (np.concatenate([wfs, contact]) - data.h) / data.sigma * np.sqrt(2.0)
        return np.concatenate([r.real, r.imag])

    fit = weighted_fit(
        residuals,
        start,
        {n: _bounds(n, wheel_mass_kg, k0) for n in names},
        scale=scale,
        resolution=_resolution,
    )
    values, chi2, n_res, p = fit.values, fit.chi2, fit.n_residuals, fit.n_parameters
    tyre, rubber = _model_objects(model, values, wheel_mass_kg)
    wfs, contact = shaker_response(model, tyre, sensor, data.freq_hz, rubber)
    ratio_meas = data.h[:n_pts] / data.h[n_pts:]
    ratio_rel = np.abs((wfs / contact) / ratio_meas - 1)
    return TyreFit(
        model=model,
        tyre=tyre,
        rubber=rubber,
        values=values,
        ci95=fit.ci95,
        undetermined=fit.undetermined,
        chi2=chi2,
        n_residuals=n_res,
        n_parameters=p,
        aic=chi2 + 2 * p,
        bic=chi2 + p * np.log(n_res),
        ratio_relative_rms=float(np.sqrt(np.mean(ratio_rel**2))),
        converged=fit.converged,
    )


def identify_shaker(
    wfs_per_z: Frf, contact_per_z: Frf, *, wheel_mass_kg: float, sensor: WfsSensor
) -> ShakerIdentification:
    """Fit Models 1-3; the rubber terms the data needs are chosen by BIC on Model 2."""
    variants = [(rate, hyst) for rate in (False, True) for hyst in (False, True)]
    m2 = {
        v: fit_tyre_model(
            TyreModel.WHEEL_TREAD,
            wfs_per_z,
            contact_per_z,
            wheel_mass_kg=wheel_mass_kg,
            sensor=sensor,
            stiffness_rise=v[0],
            hysteretic=v[1],
        )
        for v in variants
    }
    rate, hyst = min(m2, key=lambda v: m2[v].bic)
    fits = {TyreModel.WHEEL_TREAD: m2[(rate, hyst)]}
    for model in (TyreModel.WHEEL, TyreModel.WHEEL_TREAD_SIDEWALL):
        fits[model] = fit_tyre_model(
            model,
            wfs_per_z,
            contact_per_z,
            wheel_mass_kg=wheel_mass_kg,
            sensor=sensor,
            stiffness_rise=rate,
            hysteretic=hyst,
        )
    best = min(fits, key=lambda m: fits[m].bic)
    return ShakerIdentification(dict(sorted(fits.items())), best, rate, hyst)


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
) -> AmplitudeDependence:
    """Fit Model 2 to each amplitude's ``(F_wfs/Z, F_contact/Z)`` and tabulate k and damping."""
    amps = sorted(per_amplitude)
    fits = tuple(
        fit_tyre_model(
            TyreModel.WHEEL_TREAD,
            *per_amplitude[a],
            wheel_mass_kg=wheel_mass_kg,
            sensor=sensor,
            stiffness_rise=stiffness_rise,
            hysteretic=hysteretic,
        )
        for a in amps
    )
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
